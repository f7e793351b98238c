"""Spec files: validation errors name field and value; apply_spec records the conflict labels."""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from degradations.errors import DegradationError, SpecError
from degradations.spec import apply_spec, load_spec, parse_spec
from tests.degradations.conftest import target_mask

FPS = 10.0
T = 30  # 3 s
SR = 8000


def _streams(seed=0):
    rng = np.random.default_rng(seed)
    th = (280 + rng.normal(0, 0.3, (T, 64, 80))).astype(np.float32)
    th[:, target_mask()] += 2.0
    return {
        "rgb": (rng.random((T, 64, 80, 3)) * 255).astype(np.uint8),
        "thermal": th,
        "audio": (0.1 * rng.normal(size=3 * SR)).astype(np.float32),
        "rf_iq": (rng.normal(size=3 * SR) + 1j * rng.normal(size=3 * SR)).astype(np.complex64),
        "rf_spec": (-80 + 5 * rng.normal(size=(32, T))).astype(np.float32),
    }


META = {"fps": FPS, "thermal_mask": target_mask(), "audio_sample_rate_hz": SR, "rf_iq_sample_rate_hz": SR,
        "rgb_boxes": np.tile([[10.0, 10, 5, 5]], (T, 1))}
TS = np.arange(T) / FPS


def test_errors_name_field_path_and_value():
    bad = {"degradations": [{"name": "video.gaussian_noise", "severity": 9},
                            {"name": "audio.white_noise", "params": {"snr": 3}},
                            {"name": "video.fog",
                             "schedule": {"kind": "step", "events": [{"onset_s": -1, "duration_s": 1}]}}],
           "programs": [{"name": "ir_blind", "onset_s": 1.0}], "colour": 1}
    with pytest.raises(SpecError) as ei:
        parse_spec(bad)
    msg = str(ei.value)
    for part in ("degradations[0].severity", "(got 9)", "degradations[1]", "snr",
                 "degradations[2].schedule.events[0].onset_s",
                 "(got -1)", "programs[0]", "colour"):
        assert part in msg, (part, msg)
    assert isinstance(ei.value, ValueError)


def test_load_yaml_and_json(tmp_path):
    data = {"degradations": [{"name": "video.fog", "severity": 2}],
            "programs": [{"name": "decoy", "onset_s": 0.5, "duration_s": 1}]}
    (tmp_path / "s.json").write_text(json.dumps(data))
    (tmp_path / "s.yaml").write_text("degradations:\n  - name: video.fog\n    severity: 2\nprograms:\n"
                                     "  - {name: decoy, onset_s: 0.5, duration_s: 1}\n")
    assert load_spec(tmp_path / "s.json") == load_spec(tmp_path / "s.yaml")
    (tmp_path / "bad.yaml").write_text("degradations: [\n")
    with pytest.raises(SpecError, match="not valid YAML"):
        load_spec(tmp_path / "bad.yaml")
    with pytest.raises(SpecError, match="cannot read"):
        load_spec(tmp_path / "missing.yaml")


@pytest.mark.parametrize("program, hit", [
    ("ir_blind", {"thermal"}), ("rgb_blind", {"rgb"}), ("audio_masked", {"audio"}),
    ("rf_silent", {"rf_iq", "rf_spec"}), ("decoy", {"rgb", "thermal"})])
def test_conflict_programs_label_exact_rows(program, hit):
    spec = parse_spec({"programs": [{"name": program, "onset_s": 1.0, "duration_s": 0.8}]})
    streams = _streams()
    out, rec = apply_spec(spec, streams, META, seed=5, t_s=TS)
    rows = np.zeros(T, bool)
    rows[10:18] = True  # [1.0, 1.8) at 10 fps
    for m in rec["modalities"]:
        expected = rows if m in hit else np.zeros(T, bool)
        np.testing.assert_array_equal(rec["compromised"][m], expected, err_msg=m)
    np.testing.assert_array_equal(rec["conflict"], rows)
    for m in hit:  # degraded exactly inside the event, untouched outside
        ax = 1 if m == "rf_spec" else 0
        n = streams[m].shape[ax]
        changed = np.any(np.moveaxis(out[m] != streams[m], ax, 0).reshape(n, -1), axis=1)
        t_el = np.arange(n) / (SR if m in ("audio", "rf_iq") else FPS)
        np.testing.assert_array_equal(changed[(t_el < 1.0) | (t_el >= 1.8)], False)
        assert changed[(t_el >= 1.0) & (t_el < 1.8)].mean() > 0.9
    if program == "decoy":
        assert (np.isfinite(rec["meta"]["rgb_decoy_boxes"][12]).all()
                and np.isnan(rec["meta"]["rgb_decoy_boxes"][0]).all())


def test_apply_spec_deterministic_and_stages_do_not_shift_streams():
    a = parse_spec({"degradations": [{"name": "video.gaussian_noise", "severity": 2},
                                     {"name": "thermal.netd_noise", "severity": 2}]})
    b = parse_spec({"degradations": [{"name": "audio.white_noise", "severity": 2},
                                     {"name": "video.gaussian_noise", "severity": 2},
                                     {"name": "thermal.netd_noise", "severity": 2}]})
    s = _streams()
    oa, ra = apply_spec(a, s, META, seed=1, t_s=TS)
    oa2, _ = apply_spec(a, s, META, seed=1, t_s=TS)
    ob, _ = apply_spec(b, s, META, seed=1, t_s=TS)
    oc, _ = apply_spec(a, s, META, seed=2, t_s=TS)
    for m in ("rgb", "thermal"):
        assert np.array_equal(oa[m], oa2[m]) and np.array_equal(oa[m], ob[m])
        assert not np.array_equal(oa[m], oc[m])
    json.dumps({k: v for k, v in ra.items() if k != "meta"})  # the record is JSON-serialisable


def test_ramp_record_and_audio_segments():
    spec = parse_spec({"degradations": [{"name": "audio.white_noise",
                                         "schedule": {"kind": "ramp", "start_s": 1.0, "end_s": 2.0,
                                                      "to_severity": 5}}]})
    s = _streams()
    out, rec = apply_spec(spec, {"audio": s["audio"]}, META, seed=0, t_s=TS)
    sev = np.array(rec["severity"]["audio"])
    assert np.all(sev[:10] == 0) and np.all(np.diff(sev) >= 0) and sev[-1] == 5.0
    noise = [np.std(out["audio"][k * SR // 10:(k + 1) * SR // 10] - s["audio"][k * SR // 10:(k + 1) * SR // 10])
             for k in range(T)]
    assert noise[5] == 0 and noise[12] < noise[18] < noise[25]  # noise grows along the ramp
    assert rec["compromised"]["audio"][25] and not rec["compromised"]["audio"][11]


def test_dropout_missing_flag_and_torch_streams():
    spec = parse_spec({"degradations": [{"name": "crossmodal.dropout", "stream": "thermal",
                                         "schedule": {"kind": "step",
                                                      "events": [{"onset_s": 0.5, "duration_s": 0.5}]}}]})
    s = _streams()
    out, rec = apply_spec(spec, {"thermal": torch.from_numpy(s["thermal"])}, META, seed=0, t_s=TS)
    assert isinstance(out["thermal"], torch.Tensor)
    np.testing.assert_array_equal(np.flatnonzero(rec["missing"]["thermal"]), np.arange(5, 10))
    assert float(out["thermal"][6].abs().max()) == 0.0


def test_apply_spec_input_errors():
    spec = parse_spec({"degradations": [{"name": "audio.white_noise", "severity": 1}]})
    with pytest.raises(SpecError, match="sample_rate_hz"):
        apply_spec(spec, {"audio": np.zeros(100, np.float32)}, {}, seed=0, t_s=TS)
    with pytest.raises(SpecError, match="unknown modality"):
        apply_spec(spec, {"lidar": np.zeros(3)}, {}, seed=0, t_s=TS)
    with pytest.raises(SpecError, match="t_s"):
        apply_spec(spec, {}, {}, seed=0, t_s=[0.0, 0.0])


def test_an_entry_after_a_retime_does_not_retime_the_shown_index_again():
    """A decoy after a retime (a desync) copies meta['frame_index_shown'] along; only retimes compose
    it (a decoy run over part of the clip used to raise an IndexError)."""
    streams = _streams()
    meta = {"fps": FPS, "thermal_mask": np.broadcast_to(target_mask(), (T, 64, 80))}
    t = np.arange(T) / FPS
    retime = {"name": "crossmodal.desync", "stream": "rgb", "severity": 5, "params": {"direction": 1}}
    decoy = {"name": "video.decoy_bird", "schedule": {"kind": "step", "events": [{"onset_s": 1.0, "duration_s": 1.0}]}}
    _, alone = apply_spec(parse_spec({"version": 1, "degradations": [retime]}), {"rgb": streams["rgb"]}, meta, 1, t)
    _, both = apply_spec(parse_spec({"version": 1, "degradations": [retime, decoy]}), {"rgb": streams["rgb"]},
                         meta, 1, t)
    shown = alone["meta"]["rgb_frame_index_shown"]
    assert shown != list(range(T))
    assert both["meta"]["rgb_frame_index_shown"] == shown


def test_the_default_stream_is_the_degradations_own_modality():
    """Read off each registered degradation (its modality; cross-modal ones their spec_stream or the
    entry's stream parameter), not off its name: the hand table is the prefix rule it replaced."""
    from degradations.registry import REGISTRY
    from degradations.spec import default_stream

    def by_prefix(name):
        prefix = name.split(".")[0]
        if prefix == "crossmodal":
            return "thermal" if name == "crossmodal.misalignment" else "rgb"
        if prefix == "rf":
            return "rf_spec" if name.startswith("rf.spec_") else "rf_iq"
        return {"video": "rgb", "thermal": "thermal", "audio": "audio"}[prefix]

    assert len(REGISTRY) > 40
    assert {n: default_stream(n) for n in REGISTRY} == {n: by_prefix(n) for n in REGISTRY}
    assert default_stream("crossmodal.dropout", {"stream": "audio"}) == "audio"
    with pytest.raises(DegradationError, match="unknown degradation"):
        default_stream("video.nothing_of_the_kind")
