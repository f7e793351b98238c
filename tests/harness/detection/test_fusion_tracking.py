"""Per-location fusion against the scalar DS of evids.fusion, box matching for offset cameras, the
gate's at-least-one rule, and the tracker's hand-over rule on a crafted sequence."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from evids.fusion import average, dempster_shafer
from harness.experiments.detection.conditions import StreamMaps, fuse_maps, fused_matched, gate_mask, match_peaks
from harness.experiments.detection.tracking import FrameDetections, run_tracker, tracking_on_absence


def _maps(alpha: torch.Tensor) -> StreamMaps:
    t, h, w, _ = alpha.shape
    return StreamMaps(alpha[..., 0] / alpha.sum(-1), torch.zeros(t, 4, h, w), alpha, None)


def test_per_location_ds_equals_scalar_ds_at_every_location():
    g = torch.Generator().manual_seed(0)
    a = 1 + 20 * torch.rand(2, 3, 4, 2, generator=g, dtype=torch.float64)
    b = 1 + 20 * torch.rand(2, 3, 4, 2, generator=g, dtype=torch.float64)
    p, u, c = fuse_maps(_maps(a), _maps(b), "ds")
    for t in range(2):
        for i in range(3):
            for j in range(4):
                r = dempster_shafer([a[t, i, j][None], b[t, i, j][None]])
                assert float(p[t, i, j]) == pytest.approx(float(r.p[0, 0]), rel=1e-6)
                assert float(u[t, i, j]) == pytest.approx(float(r.u[0]), rel=1e-6)
                assert float(c[t, i, j]) == pytest.approx(float(r.conflict[0, 0]), rel=1e-6)
    pa, ua, _ = fuse_maps(_maps(a), _maps(b), "average")
    ref = average([a.reshape(-1, 2), b.reshape(-1, 2)])
    np.testing.assert_allclose(pa.numpy().reshape(-1), ref.p[:, 0].numpy(), rtol=1e-6)


def test_ds_hand_computed_location():
    # alpha_rgb = (9, 1): b = (8/10, 0), u = 0.2; alpha_th = (1, 4): b = (0, 3/5), u = 0.4
    # C = 0.8 * 0.6 = 0.48; b_t = (0 + 0.8*0.4 + 0) / 0.52; u = 0.08 / 0.52
    a = torch.tensor([[[[9.0, 1.0]]]], dtype=torch.float64)
    b = torch.tensor([[[[1.0, 4.0]]]], dtype=torch.float64)
    p, u, c = fuse_maps(_maps(a), _maps(b), "ds")
    assert float(c) == pytest.approx(0.48, rel=1e-6)
    assert float(u) == pytest.approx(0.08 / 0.52, rel=1e-5)
    bt, bb = 0.32 / 0.52, 0.12 / 0.52
    s = 2 / (0.08 / 0.52)
    assert float(p) == pytest.approx((bt * s + 1) / (bt * s + 1 + bb * s + 1), rel=1e-5)


def test_gated_off_stream_is_the_identity():
    a = 1 + 5 * torch.rand(3, 2, 2, 2, dtype=torch.float64, generator=torch.Generator().manual_seed(1))
    b = 1 + 5 * torch.rand(3, 2, 2, 2, dtype=torch.float64, generator=torch.Generator().manual_seed(2))
    avail = np.array([[True, False], [False, True], [True, True]])
    p, u, _ = fuse_maps(_maps(a), _maps(b), "ds", avail)
    torch.testing.assert_close(p[0].double(), a[0, ..., 0] / a[0].sum(-1), rtol=1e-6, atol=1e-6)
    torch.testing.assert_close(p[1].double(), b[1, ..., 0] / b[1].sum(-1), rtol=1e-6, atol=1e-6)


def test_match_peaks_hungarian_with_gate():
    rgb = np.array([[10, 10, 4, 4], [100, 100, 4, 4]], float)
    th = np.array([[105, 98, 4, 4], [13, 11, 4, 4], [300, 300, 4, 4]], float)
    assert sorted(match_peaks(rgb, th, 24.0)) == [(0, 1), (1, 0)]
    assert match_peaks(rgb, th, 2.0) == []


def test_fused_matched_keeps_unmatched_with_own_opinion():
    alpha_r = torch.ones(1, 4, 4, 2, dtype=torch.float64)
    alpha_t = torch.ones(1, 4, 4, 2, dtype=torch.float64)
    alpha_r[0, 1, 1] = torch.tensor([9.0, 1.0])
    alpha_t[0, 1, 2] = torch.tensor([9.0, 1.0])  # 4 px to the right: matched
    alpha_t[0, 3, 3] = torch.tensor([4.0, 1.0])  # far away: unmatched, thermal only
    r, t = _maps(alpha_r), _maps(alpha_t)
    frames, decoded = fused_matched(r, t, "ds", 0.6, 10, 6.0)
    ref = dempster_shafer([torch.tensor([[9.0, 1.0]]), torch.tensor([[9.0, 1.0]])])
    assert frames[0].scores[0] == pytest.approx(float(ref.p[0, 0]))
    assert frames[0].scores[1] == pytest.approx(0.8)  # thermal alone: 4 / 5
    assert len(frames[0].scores) == 2


def test_gate_keeps_one_stream_and_skips_evaluations():
    u_r = np.array([0.9, 0.9, 0.9, 0.9, 0.1])
    u_t = np.array([0.1, 0.1, 0.1, 0.1, 0.1])
    fused, evaluated = gate_mask(u_r, u_t, 0.5, 0.2, 2)
    assert fused.any(axis=1).all()
    assert fused[0].tolist() == [False, True]
    assert evaluated[:, 0].tolist() == [True, False, False, True, False]


def _det(x: float, score: float, unc: float) -> FrameDetections:
    return FrameDetections(np.array([[x, 50.0, 8.0, 8.0]]), np.array([score]), np.array([unc]))


def test_tracker_keeps_present_frames_and_hands_over_on_absence():
    present = [_det(100 + 2 * t, 0.9, 0.05) for t in range(5)]
    absent = [FrameDetections.empty() for _ in range(3)]
    uncertain = [_det(116, 0.9, 0.05), _det(118, 0.9, 0.6), _det(120, 0.9, 0.05)]
    steps = run_tracker(present + absent + uncertain, det_threshold=0.5, theta=0.3, search_px=10.0)
    modes = [s.in_control for s in steps]
    # frame 0 detection starts the track; frames 1-4 the tracker holds
    assert modes[:5] == ["detector", "tracker", "tracker", "tracker", "tracker"]
    # absent: the tracker hands over on the first absent frame; the detector finds nothing
    assert modes[5:8] == ["detector"] * 3 and steps[5].handed_over and steps[5].box is None
    assert all(s.box is None for s in steps[5:8])
    # re-detection, then an uncertain match (u = 0.6 > theta) hands over and re-detects at once
    assert modes[8] == "detector" and steps[8].box is not None
    assert modes[9] == "detector" and steps[9].handed_over and steps[9].track_id == steps[8].track_id + 1
    assert modes[10] == "tracker"
    exist = np.array([True] * 5 + [False] * 3 + [True] * 3)
    assert tracking_on_absence(steps, exist) == 0.0


def test_tracker_holding_a_decoy_counts_as_tracking_on_absence():
    frames = [_det(100, 0.9, 0.05), _det(101, 0.9, 0.05), _det(102, 0.3, 0.1)]
    steps = run_tracker(frames, 0.5, 0.3, 10.0)
    assert tracking_on_absence(steps, np.array([True, False, False])) == 1.0
    assert np.isnan(tracking_on_absence(steps, np.array([True, True, True])))  # no absent frame: undefined


def test_tau_det_suppresses_uncertain_redetections():
    frames = [_det(100, 0.9, 0.7), _det(100, 0.9, 0.1)]
    steps = run_tracker(frames, 0.5, 0.3, 10.0, tau_det=0.5)
    assert steps[0].box is None and steps[1].box is not None
