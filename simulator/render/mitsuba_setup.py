"""Load Mitsuba safely: find a libLLVM >= 16 for Dr.Jit's LLVM backend, else fall back to scalar.

libLLVM 14/15 crash Dr.Jit at JIT time, so an unsuitable library is never handed to it. Import
Mitsuba only through ``load_mitsuba()``; nothing outside simulator.render.renderer needs it.
``EVIDS_MITSUBA_VARIANT=llvm_ad_rgb|scalar_rgb`` forces a variant (unset: the fastest usable).
"""
from __future__ import annotations

import glob
import os
import re
import warnings
from functools import lru_cache

MIN_LLVM_MAJOR = 16
FAST_VARIANT = "llvm_ad_rgb"
FALLBACK_VARIANT = "scalar_rgb"
VARIANT_ENV = "EVIDS_MITSUBA_VARIANT"
VARIANTS = (FAST_VARIANT, FALLBACK_VARIANT)
_SEARCH_GLOBS = (
    "/usr/lib/x86_64-linux-gnu/libLLVM*.so*",
    "/usr/lib/aarch64-linux-gnu/libLLVM*.so*",
    "/usr/lib/llvm-*/lib/libLLVM*.so*",
    "/usr/lib64/libLLVM*.so*",
    "/usr/local/lib/libLLVM*.so*",
    "/opt/homebrew/opt/llvm/lib/libLLVM.dylib",
    "/usr/local/opt/llvm/lib/libLLVM.dylib",
)


def _major_version(path: str) -> int | None:
    name = os.path.basename(path)
    match = (re.search(r"libLLVM-(\d+)", name) or re.search(r"libLLVM\.so\.(\d+)", name)
             or re.search(r"llvm-(\d+)", path))
    return int(match.group(1)) if match else None


def find_libllvm() -> str | None:
    """Path of the newest libLLVM with major version >= 16, or None."""
    env = os.environ.get("DRJIT_LIBLLVM_PATH")
    if env and os.path.exists(env) and (_major_version(env) or MIN_LLVM_MAJOR) >= MIN_LLVM_MAJOR:
        return env
    candidates = []
    for pattern in _SEARCH_GLOBS:
        for path in glob.glob(pattern):
            major = _major_version(path)
            if major is not None and major >= MIN_LLVM_MAJOR:
                candidates.append((major, path))
    return max(candidates)[1] if candidates else None


def requested_variant() -> str | None:
    """The variant forced by EVIDS_MITSUBA_VARIANT, None when unset; UserInputError (exit 2 at the
    CLI, one line naming the variable and the allowed values) for anything else."""
    value = os.environ.get(VARIANT_ENV, "").strip()
    if not value:
        return None
    if value not in VARIANTS:
        from scenes.errors import UserInputError, short_repr

        raise UserInputError(f"{VARIANT_ENV}={short_repr(value, 40)} is not a Mitsuba variant evids renders with; "
                             f"allowed: {', '.join(VARIANTS)} (or unset for the fastest usable)")
    return value


@lru_cache(maxsize=1)
def load_mitsuba():
    """Import Mitsuba with the requested variant (EVIDS_MITSUBA_VARIANT) or else the fastest usable
    CPU variant; warn once when falling back to scalar without being asked to."""
    requested = requested_variant()
    libllvm = find_libllvm()
    if requested == FAST_VARIANT and libllvm is None:
        from scenes.errors import UserInputError

        raise UserInputError(f"{VARIANT_ENV}={FAST_VARIANT} needs libLLVM >= 16 and none was found: install LLVM 16+ "
                             "(Debian/Ubuntu: `apt-get install libllvm19`), set DRJIT_LIBLLVM_PATH, or use scalar_rgb")
    if libllvm is not None:
        os.environ["DRJIT_LIBLLVM_PATH"] = libllvm
    import mitsuba as mi

    if requested == FALLBACK_VARIANT:
        mi.set_variant(FALLBACK_VARIANT)
    elif libllvm is not None and FAST_VARIANT in mi.variants():
        mi.set_variant(FAST_VARIANT)
    else:
        warnings.warn(
            "No libLLVM >= 16 found: rendering with Mitsuba's scalar variant, about 20x slower. "
            "Fix: install LLVM 16+ (Debian/Ubuntu: `apt-get install libllvm19`) or set "
            "DRJIT_LIBLLVM_PATH to its libLLVM.so.",
            RuntimeWarning,
            stacklevel=2,
        )
        mi.set_variant(FALLBACK_VARIANT)
    return mi
