"""degradations.stream: a spec applied to frame streams one frame at a time equals apply_spec.

Clip-level entries (retimes, misalignment, dropout, decoys) must give exactly apply_spec's
in-memory frames and runs; frame-local entries exactly the frame-by-frame path (apply_spec on one
frame with frame_offset=i). Clips are in-memory arrays here; tests/reliability/test_degrade_streaming.py
covers the on-disk path and its memory."""
from __future__ import annotations

import json

import numpy as np
import pytest

from degradations.base import Degradation
from degradations.errors import DegradationError
from degradations.registry import REGISTRY
from degradations.spec import apply_spec, parse_spec
from degradations.stream import UNMEASURED, _measure_kind, plan_frames

T, H, W, FPS = 24, 64, 80, 30.0
CLIP_META = {"fps": FPS, "thermal_netd_k": 0.05}


def _clip(seed: int = 0) -> dict:
    """rgb noise and a thermal scene whose warm target moves 2 px a frame (so retimes show)."""
    rng = np.random.default_rng([seed, 11])
    rgb = rng.integers(0, 256, (T, H, W, 3), dtype=np.uint8)
    thermal = (280.0 + rng.normal(0, 0.3, (T, H, W))).astype(np.float32)
    mask = np.zeros((T, H, W), bool)
    boxes = np.zeros((T, 4))
    for t in range(T):
        c = 10 + 2 * t
        mask[t, 28:36, c:c + 10] = True
        boxes[t] = [c, 28, 10, 8]
    thermal[mask] += 2.0
    return {"rgb": rgb, "thermal": thermal, "mask": mask, "boxes": boxes, "t_s": np.arange(T) / FPS}


def _meta(c: dict, a: int = 0, b: int = T) -> dict:
    return {**CLIP_META, "thermal_mask": c["mask"][a:b], "rgb_boxes": c["boxes"][a:b]}


def _streamed(spec, seed: int, c: dict) -> tuple[dict, dict]:
    plan = plan_frames(spec, seed, c["t_s"], CLIP_META, {"rgb": (H, W, 3), "thermal": (H, W)})

    def read(m, j):
        return c[m][j:j + 1]

    def frame_meta(m, j):
        return {"rgb_boxes": c["boxes"][j:j + 1]} if m == "rgb" else {"thermal_mask": c["mask"][j:j + 1]}
    out = {"rgb": [], "thermal": []}
    for i, frames in plan.frames(read, frame_meta):
        assert i == len(out["rgb"])
        for m in out:
            out[m].append(frames[m])
    return {m: np.concatenate(v) for m, v in out.items()}, plan.record()


def _in_memory(spec, seed: int, c: dict) -> tuple[dict, dict]:
    y, record = apply_spec(spec, {"rgb": c["rgb"], "thermal": c["thermal"]}, _meta(c), seed, c["t_s"])
    record.pop("meta")
    return y, record


def _plain(x):
    return json.loads(json.dumps(x, default=lambda v: v.tolist() if hasattr(v, "tolist") else v))


def _step(*events):
    return {"kind": "step", "events": [{"onset_s": a, "duration_s": d} for a, d in events]}


#: one table row per clip-level entry (runs that start mid-clip exercise the in-run offsets), and a
#: mixed spec whose frame-local entries draw nothing (so per-frame and per-run params coincide)
CLIP_SPECS = {
    "frame_drop": [{"name": "video.frame_drop", "severity": 4}],
    "frame_freeze": [{"name": "video.frame_freeze", "severity": 4, "schedule": _step((0.1, 0.5))}],
    "desync": [{"name": "crossmodal.desync", "stream": "thermal", "severity": 3, "schedule": _step((0.2, 0.5))}],
    "frame_rate_mismatch": [{"name": "crossmodal.frame_rate_mismatch", "stream": "rgb", "severity": 5}],
    "misalignment": [{"name": "crossmodal.misalignment", "severity": 5}],
    "dropout": [{"name": "crossmodal.dropout", "stream": "thermal", "schedule": _step((0.1, 0.2))}],
    "rgb_decoy": [{"name": "video.decoy_bird", "severity": 5, "schedule": _step((0.1, 0.3), (0.5, 0.2))}],
    "thermal_decoy": [{"name": "thermal.decoy_bird", "severity": 5, "schedule": _step((0.2, 0.4))}],
    "mixed": [{"name": "crossmodal.desync", "stream": "thermal", "severity": 3, "schedule": _step((0.1, 0.4))},
              {"name": "crossmodal.misalignment", "severity": 4},
              {"name": "thermal.crossover", "severity": 4},
              {"name": "video.frame_freeze", "severity": 3},
              {"name": "video.defocus_blur", "severity": 2},
              {"name": "video.decoy_bird", "severity": 5, "schedule": _step((0.2, 0.4))},
              {"name": "video.frame_drop", "severity": 2},
              {"name": "crossmodal.dropout", "stream": "rgb", "schedule": _step((0.7, 0.1))}],
}
_ROWS = ("t_s", "seed", "modalities", "compromised_at", "severity", "compromised", "missing", "conflict", "skipped")


@pytest.mark.parametrize("name", sorted(CLIP_SPECS))
def test_clip_level_entries_stream_to_exactly_the_in_memory_result(name):
    spec = parse_spec({"version": 1, "degradations": CLIP_SPECS[name]})
    c = _clip()
    got, rec = _streamed(spec, 4, c)
    want, ref = _in_memory(spec, 4, c)
    for m in ("rgb", "thermal"):
        assert got[m].dtype == want[m].dtype and np.array_equal(got[m], want[m]), m
    rec, ref = _plain(rec), _plain(ref)
    assert {k: rec[k] for k in _ROWS} == {k: ref[k] for k in _ROWS}
    for a, b in zip(rec["applied"], ref["applied"]):
        clip_level = REGISTRY[a["name"]].needs_clip or REGISTRY[a["name"]].changes_meta
        if clip_level:  # frame-local entries are recorded per frame when streamed (the next test)
            assert a == b
    # the degradation did something (the comparison is not between two untouched clips)
    assert any(not np.array_equal(got[m], c[m]) for m in ("rgb", "thermal"))


@pytest.mark.parametrize("name", ["rgb_decoy", "thermal_decoy"])
def test_a_decoy_run_starting_mid_clip_continues_its_track_frame_by_frame(name):
    """Frame k of a run is drawn at track position k (meta['run_offset']), not restarted per frame."""
    cls = REGISTRY[CLIP_SPECS[name][0]["name"]]
    deg = cls(5.0)
    params = deg.sample_params(np.random.default_rng(3), dict(CLIP_META))
    c = _clip()
    x = c["rgb"][:8] if cls.modality == "rgb" else c["thermal"][:8]
    whole = deg.apply(x, params, {})
    parts = [deg.apply(x[k:k + 1], params, {"run_offset": k}) for k in range(8)]
    restarted = [deg.apply(x[k:k + 1], params, {}) for k in range(8)]
    assert np.array_equal(np.concatenate(parts), whole)
    assert not np.array_equal(np.concatenate(restarted), whole)
    boxes = [deg.update_meta(params, {"run_offset": k}, x[k:k + 1].shape)["decoy_boxes"][0] for k in range(8)]
    assert np.allclose(boxes, deg.update_meta(params, {}, x.shape)["decoy_boxes"])


FRAME_LOCAL_SPECS = {
    "noise_ir_blind": {"degradations": [{"name": "video.gaussian_noise", "severity": 2},
                                        {"name": "thermal.netd_noise", "severity": 2}],
                       "programs": [{"name": "ir_blind", "onset_s": 0.2, "duration_s": 0.3}]},
    "static_and_ramp": {"degradations": [{"name": "video.smoke"}, {"name": "video.jpeg", "severity": 3},
                                         {"name": "thermal.fixed_pattern", "schedule": {
                                             "kind": "ramp", "start_s": 0.1, "end_s": 0.6}}]},
}


def _frame_by_frame(spec, seed: int, c: dict) -> tuple[dict, list[dict]]:
    """The previous streaming path: apply_spec on each frame alone, keyed by frame_offset=i."""
    out, runs = {"rgb": [], "thermal": []}, None
    for i in range(T):
        y, r = apply_spec(spec, {m: c[m][i:i + 1] for m in out}, _meta(c, i, i + 1), seed, c["t_s"][i:i + 1],
                          frame_offset=i)
        for m in out:
            out[m].append(y[m])
        runs = [[] for _ in r["applied"]] if runs is None else runs
        for slot, a in zip(runs, r["applied"]):
            slot += [{**run, "start": run["start"] + i, "stop": run["stop"] + i} for run in a["runs"]]
    return {m: np.concatenate(v) for m, v in out.items()}, runs


@pytest.mark.parametrize("name", sorted(FRAME_LOCAL_SPECS))
def test_frame_local_specs_give_the_frame_by_frame_bytes_and_runs(name):
    spec = parse_spec({"version": 1, **FRAME_LOCAL_SPECS[name]})
    c = _clip()
    got, rec = _streamed(spec, 9, c)
    want, runs = _frame_by_frame(spec, 9, c)
    for m in ("rgb", "thermal"):
        assert np.array_equal(got[m], want[m]), m
    assert _plain([a["runs"] for a in rec["applied"]]) == _plain(runs)
    assert len(rec["applied"][0]["runs"]) == T  # one run per frame, as the frame-by-frame record had


def test_frame_local_entries_keep_per_frame_draws_when_mixed_with_retimes():
    """noise (per frame, keyed by its frame index) then a retime: the retime shows noisy frames."""
    first = [{"name": "video.gaussian_noise", "severity": 3}, {"name": "thermal.netd_noise", "severity": 3}]
    second = [{"name": "video.frame_drop", "severity": 5},
              {"name": "crossmodal.desync", "stream": "thermal", "severity": 4}]
    c = _clip()
    got, _ = _streamed(parse_spec({"version": 1, "degradations": first + second}), 2, c)
    noisy, _ = _frame_by_frame(parse_spec({"version": 1, "degradations": first}), 2, c)
    want, _ = _in_memory(parse_spec({"version": 1, "degradations": second}), 2, {**c, **noisy})
    for m in ("rgb", "thermal"):
        assert np.array_equal(got[m], want[m]), m


def test_every_clip_level_image_transform_can_stream():
    """A new clip-level rgb/thermal class must be a retime or frame-separable (else degrade refuses it)."""
    names = {name for name, cls in REGISTRY.items() if (cls.needs_clip or cls.changes_meta)
             and name.split(".")[0] in ("video", "thermal", "crossmodal")}
    assert {"video.frame_drop", "video.frame_freeze", "crossmodal.desync", "crossmodal.frame_rate_mismatch",
            "crossmodal.misalignment", "crossmodal.dropout", "video.decoy_bird", "thermal.decoy_bird"} <= names
    for name in names:
        cls = REGISTRY[name]
        assert cls.retimes or cls.frame_separable, name


@pytest.mark.parametrize("name", ["video.frame_drop", "video.frame_freeze", "crossmodal.desync",
                                  "crossmodal.frame_rate_mismatch"])
def test_retime_maps_are_monotone_so_one_frame_per_stage_suffices(name):
    for seed in range(20):
        for sev in (1.0, 2.5, 5.0):
            deg = REGISTRY[name](sev) if not name.startswith("crossmodal.") else REGISTRY[name](sev, stream="rgb")
            p = deg.sample_params(np.random.default_rng(seed), dict(CLIP_META))
            idx = deg.frame_index(T, p)
            assert np.all(np.diff(idx) >= 0) and idx.min() >= 0 and idx.max() < T, (seed, sev)


class _Whole(Degradation):
    """A clip-level rgb transform whose output frame depends on the whole run (not streamable)."""
    name = "video.test_whole_run"
    modality = "rgb"
    needs_clip = True
    table = {"amount": (0.1, 0.2, 0.3, 0.4, 0.5)}
    identity = {"amount": 0.0}

    def _apply(self, x, params, meta):
        return np.broadcast_to(x.mean(axis=0, keepdims=True), x.shape).copy()


class _SeparableClipMeasure(_Whole):
    """Frame-separable, but with a measure that needs the whole run."""
    name = "video.test_clip_measure"
    frame_separable = True

    def _apply(self, x, params, meta):
        return 1.0 - x

    def measure(self, x, y, params, meta=None):
        return {"temporal_std": float(np.std(np.asarray(y, np.float64).mean(axis=(1, 2, 3))))}


def test_measures_are_accumulated_or_declared_not_computed(monkeypatch):
    assert _measure_kind(REGISTRY["video.frame_drop"]) == "index"
    assert _measure_kind(REGISTRY["video.decoy_bird"]) == "sums"
    assert _measure_kind(_SeparableClipMeasure) == "clip"
    monkeypatch.setitem(REGISTRY, _SeparableClipMeasure.name, _SeparableClipMeasure)
    spec = parse_spec({"version": 1, "degradations": [{"name": _SeparableClipMeasure.name, "severity": 2}]})
    got, rec = _streamed(spec, 0, _clip())
    run = rec["applied"][0]["runs"][0]
    assert run["unmeasured"] == UNMEASURED and "temporal_std" not in run
    assert np.array_equal(got["rgb"], 255 - _clip()["rgb"])


def test_a_transform_needing_the_whole_run_is_refused(monkeypatch):
    monkeypatch.setitem(REGISTRY, _Whole.name, _Whole)
    spec = parse_spec({"version": 1, "degradations": [{"name": _Whole.name, "severity": 2}]})
    with pytest.raises(DegradationError, match="neither a retime nor frame-separable"):
        plan_frames(spec, 0, _clip()["t_s"], CLIP_META, {"rgb": (H, W, 3)})


def test_a_frame_of_another_size_is_refused():
    spec = parse_spec({"version": 1, "degradations": [{"name": "crossmodal.misalignment", "severity": 2}]})
    c = _clip()
    plan = plan_frames(spec, 0, c["t_s"], CLIP_META, {"thermal": (H, W)})
    with pytest.raises(DegradationError, match="shape"):
        list(plan.frames(lambda m, j: c["thermal"][j:j + 1, :, :-1], lambda m, j: {}))


def test_change_measures_are_the_same_summed_per_frame_or_over_the_run():
    deg = REGISTRY["crossmodal.misalignment"](4.0)
    p = deg.sample_params(np.random.default_rng(1), {})
    x = _clip()["thermal"]
    y = deg.apply(x, p, {})
    whole = deg.measure(x, y, p, {})
    assert whole["changed_frame_fraction"] == 1.0
    assert whole["mean_abs_change"] == pytest.approx(float(np.mean(np.abs(y.astype(np.float64) - x))), rel=1e-12)


def _peak_streaming_bytes(spec, n: int) -> int:
    """tracemalloc peak while streaming an ``n``-frame clip whose frames are made on demand and dropped."""
    import tracemalloc

    t_s = np.arange(n) / FPS

    def read(m, j):
        rng = np.random.default_rng([j, 5])
        if m == "rgb":
            return rng.integers(0, 256, (1, H, W, 3), dtype=np.uint8)
        return (280.0 + rng.normal(0, 0.3, (1, H, W))).astype(np.float32)

    def frame_meta(m, j):
        if m == "rgb":
            return {"rgb_boxes": np.array([[10.0, 28.0, 10.0, 8.0]])}
        mask = np.zeros((1, H, W), bool)
        mask[0, 28:36, 10:20] = True
        return {"thermal_mask": mask}

    tracemalloc.start()
    try:
        plan = plan_frames(spec, 4, t_s, CLIP_META, {"rgb": (H, W, 3), "thermal": (H, W)})
        count = sum(1 for _ in plan.frames(read, frame_meta))
        plan.record()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert count == plan.n
    return peak


def test_streaming_a_long_clip_holds_frames_not_the_clip():
    """The mixed clip-level spec (retimes, a decoy track, misalignment, dropout) over 600 frames (20 s):
    tracemalloc's peak is a small part of the clip (~21 MB), and what grows with the length is the plan
    and the per-frame record (measured ~1.3 KB a frame), not frames (35 KB each)."""
    spec = parse_spec({"version": 1, "degradations": CLIP_SPECS["mixed"]})
    frame_bytes = H * W * 3 + H * W * 4  # one rgb uint8 + one thermal float32 frame
    short, long = _peak_streaming_bytes(spec, 60), _peak_streaming_bytes(spec, 600)
    assert long < 600 * frame_bytes / 10, (short, long)
    assert (long - short) / (600 - 60) < frame_bytes / 10, (short, long)
