"""`evids degrade` streams every spec: peak memory does not grow with the sequence length (issue 15
measured ~8.3 MB per 640x512 frame held in memory), for frame-local specs and for each clip-level
entry (frame drop/freeze, desync, frame-rate mismatch, misalignment, dropout, decoys); the stored
copy equals the in-memory apply_spec result where the semantics are the same, and is deterministic.

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
    """A minimal native sequence: a warm square moving 2 px a frame (8-frame cycle) on a 280 K sky,
    one drone label per frame (so a retime of the thermal stream shows in its pixels)."""
    rng = np.random.default_rng(np.random.SeedSequence([7, n_frames]))
    for sub in ("rgb", "thermal", "thermal_agc", "masks/rgb", "masks/thermal"):
        (folder / sub).mkdir(parents=True, exist_ok=True)
    frames = []
    for i in range(n_frames):
        name = f"{i + 1:06d}.png"
        mask = np.zeros((height, width), np.uint8)
        c = 150 + 2 * (i % 8)
        mask[100:110, c:c + 12] = 1
        rgb = rng.integers(0, 255, (height, width, 3), dtype=np.uint8)
        counts = np.where(mask > 0, 29500, 28000).astype(np.uint16)
        cv2.imwrite(str(folder / "rgb" / name), rgb)
        cv2.imwrite(str(folder / "thermal" / name), counts)
        cv2.imwrite(str(folder / "thermal_agc" / name), (mask * 255).astype(np.uint8))
        cv2.imwrite(str(folder / "masks" / "rgb" / name), mask)
        cv2.imwrite(str(folder / "masks" / "thermal" / name), mask)
        box = [c, 100, 12, 10]
        frames.append({"index": i, "time_s": round(i / 30.0, 6),
                       "rgb": [{"id": 1, "name": "drone", "exist": 1, "box": box}],
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


def _step(*events):
    return {"kind": "step", "events": [{"onset_s": t, "duration_s": d} for t, d in events]}


#: one spec per clip-level entry and a mixed one: (spec, does the seed change the output?)
CLIP_SPECS = {
    "frame_drop": ({"degradations": [{"name": "video.frame_drop", "severity": 4}]}, True),
    "frame_freeze": ({"degradations": [{"name": "video.frame_freeze", "severity": 4}]}, True),
    "desync": ({"degradations": [{"name": "crossmodal.desync", "stream": "thermal", "severity": 3}]}, True),
    # ratio 0.8 (at 0.5, level 5, the drawn phase never changes floor((t + phase) * ratio))
    "frame_rate_mismatch": ({"degradations": [{"name": "crossmodal.frame_rate_mismatch", "stream": "rgb",
                                               "severity": 3}]}, True),
    "misalignment": ({"degradations": [{"name": "crossmodal.misalignment", "severity": 4}]}, True),
    "dropout": ({"degradations": [{"name": "crossmodal.dropout", "stream": "thermal",
                                   "schedule": _step((0.1, 0.1))}]}, False),
    "rgb_decoy": ({"degradations": [{"name": "video.decoy_bird", "severity": 5, "schedule": _step((0.1, 0.2))}]}, True),
    "thermal_decoy": ({"degradations": [{"name": "thermal.decoy_bird", "severity": 5,
                                         "schedule": _step((0.05, 0.2))}]}, True),
    "mixed": ({"degradations": [{"name": "crossmodal.desync", "stream": "thermal", "severity": 2},
                                {"name": "crossmodal.misalignment", "severity": 3},
                                {"name": "thermal.crossover", "severity": 4},
                                {"name": "video.frame_freeze", "severity": 3},
                                {"name": "video.defocus_blur", "severity": 2}],
               "programs": [{"name": "decoy", "onset_s": 0.1, "duration_s": 0.15}]}, True),
}
ALL_SPECS = {"frame_local": SPEC, **{k: {"version": 1, **v[0]} for k, v in CLIP_SPECS.items()}}


@pytest.fixture(scope="module")
def sequences(tmp_path_factory) -> dict[int, Path]:
    root = tmp_path_factory.mktemp("seqs")
    return {n: write_sequence(root / f"seq{n}", n) for n in (8, 64)}


def _peak_mb(tmp_path: Path, seq: Path, spec_dict: dict) -> dict:
    spec = tmp_path / "spec.yaml"
    spec.write_text(yaml.safe_dump(spec_dict))
    out = subprocess.run([sys.executable, "-c", _MEASURE.format(root=str(ROOT)), str(seq), str(spec),
                          str(tmp_path / f"out{seq.name}")], capture_output=True, text=True, check=True,
                         env={**os.environ, "OMP_NUM_THREADS": "1"})
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="ru_maxrss in KB is Linux")
@pytest.mark.parametrize("name", sorted(ALL_SPECS))
def test_peak_memory_does_not_grow_with_the_sequence_length(tmp_path, sequences, name):
    short, long = (_peak_mb(tmp_path, sequences[n], ALL_SPECS[name]) for n in (8, 64))
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


def test_a_frame_without_the_target_gives_null_contrast_not_a_crash(tmp_path):
    """Crossover measures the target/ring contrast; with the target out of view it is NaN, which the
    strict-JSON record writer used to refuse (ValueError: the whole degrade failed)."""
    from degradations.spec import parse_spec
    from simulator.dataset.degrade import degrade_sequence

    seq = write_sequence(tmp_path / "seq", 12, width=96, height=80)  # the square lies outside 96x80
    out = degrade_sequence(seq, parse_spec(SPEC), tmp_path / "out", 0)
    record = json.loads((out / "degradation_record.json").read_text())
    runs = [r for a in record["applied"] if a["name"] == "thermal.crossover" for r in a["runs"]]
    assert runs and all(r["contrast_k_before"] == [None] and r["contrast_k_after"] == [None] for r in runs)


def _reference(seq: Path, spec, seed: int, folder: Path) -> dict:
    """The previous in-memory path: every frame loaded, apply_spec on the whole clip, frames written."""
    from degradations.spec import apply_spec
    from simulator.dataset.degrade import _frame_meta, _write_frames
    from simulator.formats.native import load_labels, load_meta, load_rgb, load_thermal_kelvin

    info = load_meta(seq)
    n = info["n_frames"]
    meta, times = _frame_meta(info, load_labels(seq), seq, slice(0, n))
    streams = {"rgb": np.stack([load_rgb(seq, i) for i in range(n)]),
               "thermal": np.stack([load_thermal_kelvin(seq, i) for i in range(n)])}
    y, record = apply_spec(spec, streams, meta, seed, times)
    for sub in ("rgb", "thermal", "thermal_agc"):
        (folder / sub).mkdir(parents=True)
    _write_frames(folder, 0, y["rgb"], y["thermal"], info["cameras"]["thermal"]["kelvin_per_count"])
    record.pop("meta")
    return json.loads(json.dumps(record, default=lambda v: v.tolist() if hasattr(v, "tolist") else v))


def _frames_digest(folder: Path) -> dict[str, str]:
    return {k: v for k, v in tree_digest(folder).items() if k.split("/")[0] in ("rgb", "thermal", "thermal_agc")}


@pytest.mark.parametrize("name", sorted(CLIP_SPECS))
def test_a_clip_level_spec_is_streamed_and_equals_the_in_memory_result(tmp_path, name):
    from degradations.registry import REGISTRY
    from degradations.spec import parse_spec
    from simulator.dataset.degrade import degrade_sequence

    seq = write_sequence(tmp_path / "seq", 12)
    spec = parse_spec({"version": 1, **CLIP_SPECS[name][0]})
    out = degrade_sequence(seq, spec, tmp_path / "out", 3)
    ref = _reference(seq, spec, 3, tmp_path / "ref")
    assert _frames_digest(out) == _frames_digest(tmp_path / "ref")
    assert _frames_digest(out) != _frames_digest(seq)  # it degraded something
    record = json.loads((out / "degradation_record.json").read_text())
    assert record.pop("streamed") is True
    for key in ("t_s", "severity", "compromised", "missing", "conflict", "skipped"):
        assert record[key] == ref[key], key
    clip_level = [(a, b) for a, b in zip(record["applied"], ref["applied"])
                  if REGISTRY[a["name"]].needs_clip or REGISTRY[a["name"]].changes_meta]
    assert clip_level and all(a == b for a, b in clip_level)


@pytest.mark.parametrize("name", sorted(CLIP_SPECS))
def test_a_clip_level_copy_is_byte_identical_for_a_seed_and_follows_the_seed(tmp_path, name):
    from degradations.spec import parse_spec
    from simulator.dataset.degrade import degrade_sequence

    seq = write_sequence(tmp_path / "seq", 12)
    spec = parse_spec({"version": 1, **CLIP_SPECS[name][0]})
    a = degrade_sequence(seq, spec, tmp_path / "a", 5)
    b = degrade_sequence(seq, spec, tmp_path / "b", 5)
    assert tree_digest(a) == tree_digest(b)
    others = [_frames_digest(degrade_sequence(seq, spec, tmp_path / f"s{s}", s)) for s in (6, 7, 8)]
    seeded = CLIP_SPECS[name][1]
    # a seeded entry changes the frames for some other seed (desync draws only a sign: one of three
    # seeds must differ); dropout draws nothing, so every seed gives the same frames
    assert any(o != _frames_digest(a) for o in others) is seeded
