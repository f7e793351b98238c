"""`evids export` options for the interoperability formats and `evids verify` on a broken hash file, from the shell."""
import json
import subprocess
import sys

from tests.simulator.dataset.gen_helpers import write_tiny


def _evids(*args):
    return subprocess.run([sys.executable, "-c", "from harness.cli import main; main()", *args],
                          capture_output=True, text=True, timeout=600)


def test_export_options_and_verify_garbage(tmp_path):
    out = tmp_path / "ds"
    assert _evids("generate", str(write_tiny(tmp_path, sequences=2, frames=2)), "--out", str(out), "--seed", "1",
                  "--quiet").returncode == 0
    exp = tmp_path / "exp"
    result = _evids("export", str(out), "--format", "mot,coco,antiuav_rgbt,webdataset", "--out", str(exp),
                    "--distractors", "--distractors-as", "file", "--coco-naming", "mmuav", "--quiet")
    assert result.returncode == 0, result.stderr
    assert list((exp / "mot").glob("*/0*/gt_rgb/distractors.txt")) and (exp / "mot" / "gt" / "seqmaps").is_dir()
    assert list((exp / "coco" / "annotations").glob("*-ir.json")) and list((exp / "webdataset").glob("*/*.tar"))
    assert list((exp / "antiuav_rgbt").glob("*/*/infrared/infraredI0000.jpg"))
    for args, message in ((["--format", "yolo"], "yolo"),
                          (["--format", "mot", "--distractors-as", "x"], "--distractors-as"),
                          (["--format", "coco", "--coco-naming", "x"], "--coco-naming"),
                          (["--format", "trident"], "--format must be one of")):
        bad = _evids("export", str(out), *args, "--out", str(tmp_path / "bad"), "--quiet")
        assert bad.returncode == 2 and message in bad.stderr and "Traceback" not in bad.stderr, bad.stderr
    hashes = out / "sequences" / "seq000001" / "files.sha256"
    hashes.write_text(hashes.read_text() + "garbage\n")
    result = _evids("verify", str(out))
    assert (result.returncode == 1 and "corrupt: seq000001 (files.sha256 (line" in result.stdout
            and "Traceback" not in result.stderr)
    manifest = json.loads((out / "manifest.json").read_text())
    del manifest["sequences"]
    (out / "manifest.json").write_text(json.dumps(manifest))
    result = _evids("verify", str(out))
    assert result.returncode == 2 and "'sequences'" in result.stderr and "Traceback" not in result.stderr
