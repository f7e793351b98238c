import simulator.render.mitsuba_setup as setup


def test_llvm_major_version_parsing():
    assert setup._major_version("/usr/lib/x86_64-linux-gnu/libLLVM-19.so") == 19
    assert setup._major_version("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1") == 19
    assert setup._major_version("/usr/lib/llvm-17/lib/libLLVM.so") == 17
    assert setup._major_version("/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1") == 15


def test_old_llvm_is_never_chosen(monkeypatch):
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    fake = {"/usr/lib/x86_64-linux-gnu/libLLVM*.so*": ["/usr/lib/x86_64-linux-gnu/libLLVM-14.so",
                                                       "/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1"]}
    monkeypatch.setattr(setup.glob, "glob", lambda pattern: fake.get(pattern, []))
    assert setup.find_libllvm() is None
    fake["/usr/lib/llvm-*/lib/libLLVM*.so*"] = ["/usr/lib/llvm-16/lib/libLLVM-16.so",
                                                "/usr/lib/llvm-19/lib/libLLVM-19.so"]
    assert setup.find_libllvm() == "/usr/lib/llvm-19/lib/libLLVM-19.so"
