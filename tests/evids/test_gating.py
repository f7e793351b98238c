import numpy as np
import pytest
import torch

from evids.fusion import dempster_shafer
from evids.gating import (
    GateParams,
    HysteresisGate,
    simulate_gate,
    subset_fusion_table,
    sweep_gates,
)

LOW = 0.05  # a second modality that is always confident, so the "one modality on" rule stays idle


def _run(params, u0, u1=None):
    u1 = [LOW] * len(u0) if u1 is None else u1
    return simulate_gate(np.array([u0, u1]), params)


def test_streak_resets_when_u_falls_back():
    p = GateParams(tau_high=0.6, tau_low=0.2, n=3, mode="streak")
    #        t: 0    1    2    3    4    5    6    7    8
    u0 = [0.9, 0.9, 0.1, 0.9, 0.9, 0.9, 0.5, 0.5, 0.1]
    # streak 1, 2, reset at t=2, then 1, 2, 3 -> closed at t=5; 0.5 is inside the hysteresis band
    # so it stays closed; 0.1 < tau_low reopens at t=8. A gate that never resets its streak would
    # close at t=3 (4th high value).
    evaluated, fused, _, stats = _run(p, u0)
    assert fused[0].tolist() == [True, True, True, True, True, False, False, False, True]
    assert evaluated.all()  # the streak form keeps evaluating (no compute saving)
    assert stats.skip_rate == 0.0
    assert stats.exclusion_rate_per_modality == pytest.approx([3 / 9, 0.0])


def test_window_form_crafted_sequence():
    p = GateParams(tau_high=0.6, tau_low=0.2, n=2, mode="window")
    #        t: 0    1    2    3    4    5    6    7    8
    u0 = [0.1, 0.9, 0.0, 0.0, 0.5, 0.0, 0.0, 0.1, 0.1]
    # t1: u > tau_high -> excluded, skipped at t2, t3; t4: 0.5 in the band -> stays closed for
    # another window (t5, t6); t7: 0.1 < tau_low -> open. Values at skipped steps are never read.
    evaluated, fused, _, stats = _run(p, u0)
    assert evaluated[0].tolist() == [True, True, False, False, True, False, False, True, True]
    assert fused[0].tolist() == [True, False, False, False, False, False, False, True, True]
    assert stats.skip_rate_per_modality == pytest.approx([4 / 9, 0.0])
    assert stats.skip_rate == pytest.approx(2 / 9)


def test_window_reads_u_only_when_evaluated():
    p = GateParams(0.6, 0.2, 2)
    a = _run(p, [0.9, 0.0, 0.0, 0.1])[1]
    b = _run(p, [0.9, 0.99, 0.99, 0.1])[1]
    assert np.array_equal(a, b)


def test_at_least_one_modality_is_fused():
    p = GateParams(0.6, 0.2, 2, mode="window")
    u = np.array([[0.9, 0.9, 0.9, 0.9], [0.8, 0.95, 0.95, 0.95]])
    evaluated, fused, _, stats = simulate_gate(u, p)
    assert fused.sum(0).min() >= 1
    # t0: both high, modality 1 (u=0.8) is the most certain -> forced on and kept open
    assert fused[:, 0].tolist() == [False, True]
    assert evaluated[:, 1].tolist() == [False, True]
    assert stats.forced == 4


def test_forced_modality_stays_evaluated():
    gate = HysteresisGate(2, GateParams(0.6, 0.2, 3))
    gate.plan()
    # both high: modality 0 (0.7) forced on and kept open, modality 1 closed for 3 steps
    assert gate.update([0.7, 0.9]) == [True, False]
    assert gate.plan() == [True, False]
    assert gate.update([0.3, 0.9]) == [True, False]
    with pytest.raises(ValueError, match="without a preceding plan"):
        gate.update([0.3, 0.9])


def test_state_is_per_track():
    p = GateParams(0.6, 0.2, 2, mode="streak")
    gate = HysteresisGate(2, p)
    for _ in range(2):
        gate.step([0.9, LOW], key="a")
        gate.step([0.1, LOW], key="b")
    assert gate.step([0.1, LOW], key="b").fused == (True, True)
    assert gate.step([0.1, LOW], key="a").fused == (True, True)  # closed at 2nd step, 0.1 reopens
    gate2 = HysteresisGate(2, p)
    gate2.step([0.9, LOW], key="a")
    gate2.step([0.9, LOW], key="b")
    assert gate2.step([0.9, LOW], key="a").fused == (False, True)  # streak of 2 on track a only
    assert gate2.step([0.1, LOW], key="b").fused == (True, True)


def test_abstain_after_patience():
    p = GateParams(0.6, 0.2, 5, mode="streak", tau_fused=0.3, abstain_patience=2)
    gate = HysteresisGate(2, p)
    fused_u = iter([0.5, 0.5, 0.5, 0.1, 0.5])
    out = [gate.step([0.1, 0.1], fused_u=lambda m: next(fused_u)).abstain for _ in range(5)]
    assert out == [False, True, True, False, False]
    assert gate.stats.abstain_rate == pytest.approx(2 / 5)


def test_params_validation():
    with pytest.raises(ValueError, match="tau_low must be < tau_high"):
        GateParams(0.3, 0.3, 2)
    with pytest.raises(ValueError, match="n must be"):
        GateParams(0.6, 0.2, 0)
    with pytest.raises(ValueError, match="mode"):
        GateParams(0.6, 0.2, 2, mode="fixed")


def _cached(seed=0, m=3, clips=6, steps=20):
    gen = torch.Generator().manual_seed(seed)
    n = clips * steps
    labels = torch.randint(0, 2, (n,), generator=gen)
    strength = 10 ** (torch.rand(m, n, 1, generator=gen, dtype=torch.float64) * 2)
    right = torch.rand(m, n, generator=gen) < 0.8
    target = torch.where(right, labels, 1 - labels)
    alphas = 1 + strength * torch.nn.functional.one_hot(target, 2).double() + torch.rand(m, n, 2, generator=gen,
                                                                                         dtype=torch.float64)
    ids = np.repeat(np.arange(clips), steps)
    return alphas, labels.numpy(), ids


def test_subset_table_matches_masked_fusion():
    alphas, _, _ = _cached()
    pred, u = subset_fusion_table(alphas)
    mask = torch.tensor([True, False, True]).unsqueeze(-1).expand(3, alphas.shape[1])
    r = dempster_shafer(alphas, available=mask)
    assert np.array_equal(pred[0b101], r.p.argmax(-1).numpy())
    assert np.allclose(u[0b101], r.u.numpy())
    assert np.array_equal(pred[0b010], alphas[1].argmax(-1).numpy())


def test_sweep_table():
    alphas, labels, ids = _cached()
    rows = sweep_gates(alphas, labels, tau_high=[0.3, 1.0], tau_low=[0.05, 0.3], n=[1, 3], sequence_ids=ids)
    # (0.3, 0.3) is skipped (tau_low must be < tau_high): 2 * 2 * 2 - 2 rows
    assert len(rows) == 6
    assert {"tau_high", "tau_low", "n", "accuracy", "skip_rate", "skip_rate_per_modality",
            "abstain_rate"} <= set(rows[0])
    full = dempster_shafer(alphas).p.argmax(-1).numpy()
    never = [r for r in rows if r["tau_high"] == 1.0]
    for r in never:  # u never exceeds 1: identical to ungated DS
        assert r["accuracy"] == pytest.approx(float((full == labels).mean()))
        assert r["skip_rate"] == 0.0 and r["delta_accuracy"] == 0.0
    active = [r for r in rows if r["tau_high"] == 0.3 and r["n"] == 3]
    assert all(r["skip_rate"] > 0 for r in active)
    # recompute one row by hand from the simulator
    r0 = active[0]
    u_mod = (2 / alphas.sum(-1)).numpy()
    _, fused, _, stats = simulate_gate(u_mod, GateParams(0.3, r0["tau_low"], 3), ids)
    pred, _ = subset_fusion_table(alphas)
    subset = (fused * np.array([[1], [2], [4]])).sum(0)
    assert r0["accuracy"] == pytest.approx(float((pred[subset, np.arange(len(labels))] == labels).mean()))
    assert r0["skip_rate"] == pytest.approx(stats.skip_rate)
