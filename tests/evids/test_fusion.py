import math

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from evids.fusion import (
    FUSION_RULES,
    GMU,
    LateFusion,
    average,
    averaging_fusion,
    cumulative_fusion,
    dempster_shafer,
    discounted_belief_fusion,
    yager,
)

D = torch.float64
A1 = torch.tensor([[3.0, 1.0]], dtype=D)  # e=[2,0], S=4: b=[1/2, 0], u=1/2
A2 = torch.tensor([[1.0, 3.0]], dtype=D)  # b=[0, 1/2], u=1/2

# Hand-worked results of each rule on the conflicting pair (A1, A2):
HAND = {
    # DS: C = 1/2 * 1/2 = 1/4; b_k = (0 + 1/2*1/2 + 0) / (3/4) = 1/3; u = (1/4)/(3/4) = 1/3;
    # S = 2 / (1/3) = 6, e = b S = [2, 2], alpha = [3, 3]
    "dempster_shafer": dict(alpha=[3.0, 3.0], u=1 / 3, conflict=0.25),
    # Yager: b_k = 1/4, u = u1 u2 + C = 1/4 + 1/4 = 1/2; S = 4, e = [1, 1]
    "yager": dict(alpha=[2.0, 2.0], u=0.5, conflict=0.25),
    # cumulative: e = e1 + e2 = [2, 2]
    "cumulative": dict(alpha=[3.0, 3.0], u=1 / 3),
    # averaging: e = (e1 + e2) / 2 = [1, 1]
    "averaging": dict(alpha=[2.0, 2.0], u=0.5),
    # discounted: P1 = [3/4, 1/4], P2 = [1/4, 3/4], PD = 1/2, CC = 1/4, DC = 1/8, t = 7/8;
    # b' = [7/16, 0], u' = 1 - 7/8 * 1/2 = 9/16; cumulative: 1/u = 1 + 2 (16/9 - 1) = 23/9,
    # b = 9/23 * (7/16)/(9/16) = 7/23 per class; S = 2 * 23/9 = 46/9, e = b S = 14/9
    "discounted": dict(alpha=[1 + 14 / 9, 1 + 14 / 9], u=9 / 23, conflict=0.125),
    # average: p = mean([3/4, 1/4], [1/4, 3/4]) = [1/2, 1/2], alpha = mean = [2, 2], u = 2/4
    "average": dict(alpha=[2.0, 2.0], u=0.5),
}


def test_every_registered_rule_has_a_hand_case():
    assert set(FUSION_RULES) == set(HAND)


@pytest.mark.parametrize("name", sorted(HAND))
def test_hand_values(name):
    r = FUSION_RULES[name]([A1, A2])
    h = HAND[name]
    assert torch.allclose(r.alpha, torch.tensor([h["alpha"]], dtype=D), atol=1e-12)
    assert r.u.item() == pytest.approx(h["u"], abs=1e-12)
    if name == "average":
        assert torch.allclose(r.p, torch.tensor([[0.5, 0.5]], dtype=D))
    if "conflict" in h:
        assert r.conflict.reshape(-1)[0].item() == pytest.approx(h["conflict"], abs=1e-12)
    assert torch.allclose(r.belief.sum(-1) + r.u, torch.ones(1, dtype=D), atol=1e-12)


def test_ds_scaled_construction_hand():
    # scaled: b1 = p(1-u) = [3/8, 1/8], b2 = [1/8, 3/8], u = 1/2
    # C = (1/2)(1/2) - (3/64 + 3/64) = 5/32; 1 - C = 27/32
    # b_0 = (3/64 + 3/16 + 1/16) / (27/32) = (19/64) * (32/27) = 19/54, u = (1/4) / (27/32) = 8/27
    # inverse: p = b / (1 - u) = [1/2, 1/2], S = 2 / u = 27/4, alpha = p S = [27/8, 27/8]
    r = dempster_shafer([A1, A2], construction="scaled")
    assert r.conflict.item() == pytest.approx(5 / 32, abs=1e-12)
    assert r.u.item() == pytest.approx(8 / 27, abs=1e-12)
    assert torch.allclose(r.belief, torch.tensor([[19 / 54, 19 / 54]], dtype=D))
    assert torch.allclose(r.alpha, torch.tensor([[27 / 8, 27 / 8]], dtype=D))


def test_ds_hides_conflict_reference_example():
    # (1000,1,1) vs (1,1000,1): u_i = 3/1002, C = (999/1002)^2, fused u = u1/(2 - u1) = 3/2001
    a = torch.tensor([[1000.0, 1.0, 1.0]], dtype=D)
    b = torch.tensor([[1.0, 1000.0, 1.0]], dtype=D)
    r = dempster_shafer([a, b])
    assert r.conflict.item() == pytest.approx((999 / 1002) ** 2, rel=1e-12)
    assert r.u.item() == pytest.approx(3 / 2001, rel=1e-12)


def test_fallback_to_most_certain():
    # b1 = [99/101, 0] (u = 2/101), b2 = [0, 9/11] (u = 2/11): C = 891/1111 ~ 0.802
    a = torch.tensor([[100.0, 1.0], [2.0, 2.0]], dtype=D)
    b = torch.tensor([[1.0, 10.0], [2.0, 2.0]], dtype=D)
    r = dempster_shafer([b, a], c_max=0.5)
    assert r.conflict[0, 0].item() == pytest.approx(891 / 1111, rel=1e-12)
    assert r.fallback.tolist() == [True, False]
    assert torch.equal(r.alpha[0], a[0]) and r.u[0].item() == pytest.approx(2 / 101)
    no_fb = dempster_shafer([b, a], c_max=0.9)
    assert no_fb.fallback.tolist() == [False, False]
    assert torch.allclose(no_fb.alpha, dempster_shafer([b, a]).alpha)


def test_fallback_skips_missing_modality():
    a = torch.tensor([[100.0, 1.0]], dtype=D)
    b = torch.tensor([[1.0, 10.0]], dtype=D)
    c = torch.tensor([[1000.0, 1.0]], dtype=D)  # most certain but missing
    mask = torch.tensor([[True], [True], [False]])
    r = dempster_shafer([a, b, c], c_max=0.5, available=mask)
    assert r.fallback.item() and torch.equal(r.alpha, a)


def _alpha_strategy(n=3, k=3, hi=1e4):
    return st.lists(
        st.lists(st.floats(0.0, math.log10(hi)), min_size=k, max_size=k), min_size=n, max_size=n
    ).map(lambda rows: 10 ** torch.tensor(rows, dtype=D))


@settings(max_examples=60, deadline=None)
@given(_alpha_strategy(2), st.sampled_from(["canonical", "scaled"]))
def test_ds_commutative(alphas, construction):
    a, b = alphas[0:1], alphas[1:2]
    r1 = dempster_shafer([a, b], construction=construction)
    r2 = dempster_shafer([b, a], construction=construction)
    assert torch.equal(r1.belief, r2.belief) and torch.equal(r1.u, r2.u)
    assert torch.equal(r1.conflict, r2.conflict)


@settings(max_examples=60, deadline=None)
@given(_alpha_strategy(3), st.sampled_from(["canonical", "scaled"]))
def test_ds_associative(alphas, construction):
    a, b, c = (alphas[i : i + 1] for i in range(3))
    left = dempster_shafer([a, b, c], construction=construction)
    bc = dempster_shafer([b, c], construction=construction)
    # the scaled inverse alpha = p K / u can round to 1 - 1e-16 where an input class had alpha = 1
    assert bc.alpha.min() > 1 - 1e-9
    right = dempster_shafer([a, bc.alpha.clamp(min=1.0)], construction=construction)
    assert torch.allclose(left.belief, right.belief, rtol=1e-7, atol=1e-12)
    assert torch.allclose(left.u, right.u, rtol=1e-7, atol=1e-15)


@settings(max_examples=60, deadline=None)
@given(_alpha_strategy(1), st.sampled_from(["canonical", "scaled"]),
       st.sampled_from(["dempster_shafer", "yager", "cumulative"]))
def test_vacuous_is_identity(alphas, construction, rule):
    a = alphas[0:1]
    vac = torch.ones_like(a)
    for order in ([a, vac], [vac, a]):
        r = FUSION_RULES[rule](order, construction=construction)
        assert torch.allclose(r.alpha, a, rtol=1e-9)


@settings(max_examples=60, deadline=None)
@given(_alpha_strategy(3, k=2, hi=1e8), st.sampled_from(sorted(FUSION_RULES)), st.sampled_from(["canonical", "scaled"]))
def test_masses_sum_to_one_no_nan_float32(alphas, rule, construction):
    a32 = alphas.float().unsqueeze(1)  # (M=3, N=1, K=2), values up to 1e8
    kwargs = {} if rule == "average" else {"construction": construction}
    r = FUSION_RULES[rule](a32, **kwargs)
    for t in (r.alpha, r.p, r.u, r.belief):
        assert torch.isfinite(t).all()
    assert (r.u > 0).all() and (r.u <= 1).all()
    if rule != "average":
        assert torch.allclose(r.belief.sum(-1) + r.u, torch.ones(1), atol=1e-5)
    if r.conflict is not None:
        assert ((r.conflict >= 0) & (r.conflict <= 1)).all()


def test_total_conflict_limit_is_finite():
    # C -> 1: both modalities maximally certain of different classes, in float32.
    for big in (1e4, 1e6, 1e8):
        a = torch.tensor([[big, 1.0]], dtype=torch.float32)
        b = torch.tensor([[1.0, big]], dtype=torch.float32)
        r = dempster_shafer([a, b, a], c_max=None)
        assert torch.isfinite(r.alpha).all() and torch.isfinite(r.u).all()
        assert r.conflict[0].item() == pytest.approx(1.0, abs=1e-3)
        fb = dempster_shafer([a, b], c_max=0.99)
        assert fb.fallback.all() and torch.equal(fb.alpha, a)


@pytest.mark.parametrize("rule", ["cumulative", "averaging", "discounted", "average"])
def test_order_invariant_rules(rule):
    gen = torch.Generator().manual_seed(3)
    a = 1 + torch.rand(3, 20, 4, generator=gen, dtype=D) * 50
    r = FUSION_RULES[rule](a)
    r2 = FUSION_RULES[rule](a[[2, 0, 1]])
    assert torch.allclose(r.alpha, r2.alpha, rtol=1e-12) and torch.allclose(r.p, r2.p, rtol=1e-12)


@pytest.mark.parametrize("rule", sorted(FUSION_RULES))
def test_missing_modality_equals_fusing_the_rest(rule):
    gen = torch.Generator().manual_seed(4)
    a = 1 + torch.rand(3, 6, 2, generator=gen, dtype=D) * 20
    mask = torch.ones(3, 6, dtype=torch.bool)
    mask[1, :3] = False
    r = FUSION_RULES[rule](a, available=mask)
    ref = FUSION_RULES[rule](a[[0, 2], :3])
    assert torch.allclose(r.alpha[:3], ref.alpha, rtol=1e-12)
    assert torch.allclose(r.u[:3], ref.u, rtol=1e-12)
    full = FUSION_RULES[rule](a[:, 3:])
    assert torch.allclose(r.alpha[3:], full.alpha, rtol=1e-12)


def test_ds_mask_exact_identity_and_conflict_zero():
    a = torch.tensor([[[5.0, 1.0]], [[1.0, 7.0]]], dtype=torch.float32)
    mask = torch.tensor([[False], [True]])
    r = dempster_shafer(a, available=mask)
    assert torch.equal(r.alpha, a[1]) and r.conflict.item() == 0.0


def test_list_and_tensor_inputs_agree_and_validation():
    gen = torch.Generator().manual_seed(5)
    a = 1 + torch.rand(3, 4, 2, generator=gen)
    assert torch.equal(dempster_shafer(a).alpha, dempster_shafer(list(a)).alpha)
    with pytest.raises(ValueError, match="M >= 2"):
        dempster_shafer(a[:1])
    with pytest.raises(ValueError, match="one shape"):
        dempster_shafer([a[0], a[1, :2]])
    with pytest.raises(ValueError, match="available"):
        dempster_shafer(a, available=torch.ones(3, 5, dtype=torch.bool))
    with pytest.raises(ValueError, match="c_max"):
        dempster_shafer(a, c_max=1.5)
    with pytest.raises(ValueError, match="construction"):
        yager(a, construction="other")
    with pytest.raises(ValueError, match=">= 1"):
        cumulative_fusion(a - 1)


def test_discounted_reduces_to_base_under_agreement():
    a = torch.tensor([[[5.0, 1.0]], [[5.0, 1.0]]], dtype=D)
    # identical opinions: PD = 0, so DC = 0 and t = 1
    r = discounted_belief_fusion(a)
    assert torch.allclose(r.alpha, cumulative_fusion(a).alpha)
    assert torch.equal(r.discount, torch.ones(2, 1, dtype=D))
    r2 = discounted_belief_fusion(a, base="averaging")
    assert torch.allclose(r2.alpha, averaging_fusion(a).alpha)


def test_average_with_no_modality_is_uniform():
    a = torch.tensor([[[5.0, 1.0]], [[2.0, 1.0]]], dtype=D)
    r = average(a, available=torch.zeros(2, 1, dtype=torch.bool))
    assert torch.allclose(r.p, torch.tensor([[0.5, 0.5]], dtype=D)) and r.u.item() == 1.0


def test_late_fusion():
    lf = LateFusion(3)
    logits = torch.tensor([[0.0, 2.0], [1.0, -1.0], [-3.0, 0.5]])
    assert torch.allclose(lf(logits), torch.sigmoid(logits).mean(0))
    with torch.no_grad():
        lf.theta.copy_(torch.log(torch.tensor([0.5, 0.3, 0.2])))
    expected = (torch.tensor([0.5, 0.3, 0.2])[:, None] * torch.sigmoid(logits)).sum(0)
    assert torch.allclose(lf(list(logits)), expected)
    mask = torch.tensor([[True, True], [False, True], [True, False]])
    out = lf(logits, available=mask)
    s = torch.sigmoid(logits)
    assert torch.allclose(out[0], (0.5 * s[0, 0] + 0.2 * s[2, 0]) / 0.7)
    assert torch.allclose(out[1], (0.5 * s[0, 1] + 0.3 * s[1, 1]) / 0.8)
    with pytest.raises(ValueError):
        LateFusion(1)


def test_gmu_matches_manual_computation():
    gen = torch.Generator().manual_seed(6)
    gmu = GMU([3, 2], hidden_dim=4, num_outputs=1)
    x1, x2 = torch.randn(5, 3, generator=gen), torch.randn(5, 2, generator=gen)
    z = torch.sigmoid(gmu.gate_layer(torch.cat([x1, x2], -1))).view(5, 2, 4)
    h = z[:, 0] * torch.tanh(gmu.proj[0](x1)) + z[:, 1] * torch.tanh(gmu.proj[1](x2))
    assert torch.allclose(gmu([x1, x2]), gmu.out(h))
    soft = GMU([3, 2], hidden_dim=4, gate="softmax")
    assert torch.allclose(soft.gates([x1, x2]).sum(1), torch.ones(5, 4))
    gmu([x1, x2]).sum().backward()
    assert gmu.gate_layer.weight.grad is not None
    with pytest.raises(ValueError, match="shape"):
        gmu([x1, x1])
