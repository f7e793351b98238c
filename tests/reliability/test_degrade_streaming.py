"""`evids degrade` streams frame-local specs: peak memory does not grow with the sequence length
(issue 15 measured ~8.3 MB per 640x512 frame before), and the stored copy is deterministic.

The input sequences are miniatures written here from the native format facts (docs/NATIVE_FORMAT.md:
rgb/, thermal/ 16-bit counts, thermal_agc/, masks/{rgb,thermal}/, labels.json, meta.json), not renders."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from tests.reliability.helpers import ROOT, tree_digest


def write_sequence(folder: Path, n_frames: int, width: int = 320, height: int = 256) -> Path:
    """A minimal native sequence: a warm square on a 280 K sky, one drone label per frame."""
    rng = np.random.default_rng(np.random.SeedSequence([7, n_frames]))
    for sub in ("rgb", "thermal", "thermal_agc", "masks/rgb", "masks/thermal"):
        (folder / sub).mkdir(parents=True, exist_ok=True)
    frames = []
    for i in range(n_frames):
        name = f"{i + 1:06d}.png"
        mask = np.zeros((height, width), np.uint8)
        mask[100:110, 150:162] = 1
        rgb = rng.integers(0, 255, (height, width, 3), dtype=np.uint8)
        counts = np.where(mask > 0, 29500, 28000).astype(np.uint16)
        cv2.imwrite(str(folder / "rgb" / name), rgb)
        cv2.imwrite(str(folder / "thermal" / name), counts)
        cv2.imwrite(str(folder / "thermal_agc" / name), (mask * 255).astype(np.uint8))
        cv2.imwrite(str(folder / "masks" / "rgb" / name), mask)
        cv2.imwrite(str(folder / "masks" / "thermal" / name), mask)
        box = [150, 100, 12, 10]
        frames.append({"index": i, "time_s": round(i / 30.0, 6), "rgb": [{"id": 1, "name": "drone", "exist": 1, "box": box}],
                       "thermal": [{"id": 1, "name": "drone", "exist": 1, "box": box}]})
    (folder / "labels.json").write_text(json.dumps({"objects": [{"id": 1, "name": "drone"}], "frames": frames}))
    (folder / "meta.json").write_text(json.dumps({
        "format_version": 1, "scenario_name": folder.name, "seed": 0, "n_frames": n_frames, "frame_rate_hz": 30.0,
        "cameras": {"rgb": {"width_px": width, "height_px": height},
                    "thermal": {"width_px": width, "height_px": height, "netd_k": 0.05, "kelvin_per_count": 0.01}}}))
    return folder


_MEASURE = textwrap.dedent("""
    import json, resource, sys
    sys.path.insert(0, {root!r})
    from degradations.spec import load_spec
    from simulator.dataset.degrade import degrade_sequence
    spec = load_spec(sys.argv[2])
    import numpy, cv2  # imported before the baseline
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    degrade_sequence(sys.argv[1], spec, sys.argv[3], 0)
    after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(json.dumps({{"before_mb": before / 1024, "after_mb": after / 1024}}))
""")

SPEC = {"version": 1, "degradations": [{"name": "video.gaussian_noise", "severity": 2},
                                       {"name": "thermal.netd_noise", "severity": 2}],
        "programs": [{"name": "ir_blind", "onset_s": 0.2, "duration_s": 0.5}]}


def _peak_mb(tmp_path: Path, n_frames: int) -> dict:
    seq = write_sequence(tmp_path / f"seq{n_frames}", n_frames)
    spec = tmp_path / "spec.yaml"
    spec.write_text(yaml.safe_dump(SPEC))
    out = subprocess.run([sys.executable, "-c", _MEASURE.format(root=str(ROOT)), str(seq), str(spec),
                          str(tmp_path / f"out{n_frames}")], capture_output=True, text=True, check=True,
                         env={**os.environ, "OMP_NUM_THREADS": "1"})
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="ru_maxrss in KB is Linux")
def test_peak_memory_does_not_grow_with_the_sequence_length(tmp_path):
    short, long = _peak_mb(tmp_path, 8), _peak_mb(tmp_path, 64)
    # 56 more 320x256 frames held in memory would cost >= 56 x (rgb + float32 thermal + mask) ~ 44 MB
    # before any float work copy; streamed, the peak moves by a few MB of record and allocator noise.
    growth = long["after_mb"] - short["after_mb"]
    assert growth < 15.0, (short, long)


def test_streamed_copy_is_deterministic_and_flags_the_conflict(tmp_path):
    from degradations.spec import parse_spec
    from simulator.dataset.degrade import degrade_sequence

    seq = write_sequence(tmp_path / "seq", 30)
    spec = parse_spec(SPEC)
    a = degrade_sequence(seq, spec, tmp_path / "a", 5)
    b = degrade_sequence(seq, spec, tmp_path / "b", 5)
    assert tree_digest(a) == tree_digest(b)
    record = json.loads((a / "degradation_record.json").read_text())
    t = np.asarray(record["t_s"])
    assert record["streamed"] is True and len(t) == 30
    assert np.array_equal(record["compromised"]["thermal"], (t >= 0.2 - 1e-9) & (t < 0.7 - 1e-9))
    assert not any(record["compromised"]["rgb"])
    assert (cv2.imread(str(a / "rgb" / "000001.png")) != cv2.imread(str(seq / "rgb" / "000001.png"))).any()
    assert (cv2.imread(str(a / "masks" / "thermal" / "000001.png")) == cv2.imread(
        str(seq / "masks" / "thermal" / "000001.png"))).all()


def test_a_clip_level_spec_still_works_in_memory(tmp_path):
    from degradations.spec import parse_spec
    from simulator.dataset.degrade import degrade_sequence

    seq = write_sequence(tmp_path / "seq", 12)
    spec = parse_spec({"version": 1, "degradations": [{"name": "video.frame_drop", "severity": 3}]})
    out = degrade_sequence(seq, spec, tmp_path / "out", 0)
    assert json.loads((out / "degradation_record.json").read_text())["streamed"] is False
