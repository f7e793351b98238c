import math

import pytest
import torch
import torch.nn.functional as F
from hypothesis import given, settings
from hypothesis import strategies as st

from evids.heads import (
    BaselineHead,
    EvidentialHead,
    belief_masses,
    check_alpha,
    dirichlet_strength,
    evidence,
    expected_probability,
    opinion_to_alpha,
    predictive_entropy,
    vacuity,
)


def test_head_is_softplus_plus_one():
    head = EvidentialHead(3, 2)
    with torch.no_grad():
        head.linear.weight.copy_(torch.tensor([[1.0, -2.0, 0.5], [0.0, 1.0, -1.0]]))
        head.linear.bias.copy_(torch.tensor([0.1, -0.3]))
    z = torch.tensor([[1.0, 2.0, 3.0]])
    # Wz + b = [1 - 4 + 1.5 + 0.1, 0 + 2 - 3 - 0.3] = [-1.4, -1.3]
    expected = F.softplus(torch.tensor([[-1.4, -1.3]])) + 1
    assert torch.allclose(head(z), expected, atol=1e-6)
    gen = torch.Generator().manual_seed(0)
    assert (head(torch.randn(50, 3, generator=gen) * 100).min() >= 1.0).item()


def test_k1_raises_pointing_to_k2():
    with pytest.raises(ValueError, match="num_classes=2"):
        EvidentialHead(8, 1)
    with pytest.raises(ValueError):
        EvidentialHead(8, 0)
    with pytest.raises(ValueError):
        EvidentialHead(0, 2)


def test_hand_values_k2():
    alpha = torch.tensor([[3.0, 1.0]])
    # S = 4, p = [3/4, 1/4], u = 2/4, e = [2, 0]
    assert torch.allclose(dirichlet_strength(alpha), torch.tensor([4.0]))
    assert torch.allclose(expected_probability(alpha), torch.tensor([[0.75, 0.25]]))
    assert torch.allclose(vacuity(alpha), torch.tensor([0.5]))
    assert torch.allclose(evidence(alpha), torch.tensor([[2.0, 0.0]]))
    b, u = belief_masses(alpha, "canonical")  # e/S = [0.5, 0]
    assert torch.allclose(b, torch.tensor([[0.5, 0.0]])) and torch.allclose(u, torch.tensor([0.5]))
    b, u = belief_masses(alpha, "scaled")  # p(1-u) = [0.375, 0.125]
    assert torch.allclose(b, torch.tensor([[0.375, 0.125]])) and torch.allclose(u, torch.tensor([0.5]))


alpha_rows = st.lists(st.floats(1.0, 1e6, allow_nan=False), min_size=2, max_size=6)


@settings(max_examples=80, deadline=None)
@given(alpha_rows, st.sampled_from(["canonical", "scaled"]))
def test_masses_sum_to_one_and_round_trip(row, construction):
    alpha = torch.tensor([row], dtype=torch.float64)
    b, u = belief_masses(alpha, construction)
    assert (b >= 0).all()
    assert torch.allclose(b.sum(-1) + u, torch.ones(1, dtype=torch.float64), atol=1e-12)
    back, p = opinion_to_alpha(b, u, construction)
    assert torch.allclose(back, alpha, rtol=1e-9)
    assert torch.allclose(p, expected_probability(alpha), rtol=1e-9)


def test_entropy_values():
    p = torch.tensor([[0.5, 0.5], [1.0, 0.0], [0.25, 0.75]])
    h = predictive_entropy(p)
    expected = [math.log(2), 0.0, -(0.25 * math.log(0.25) + 0.75 * math.log(0.75))]
    assert torch.allclose(h, torch.tensor(expected), atol=1e-6)
    assert torch.allclose(predictive_entropy(p, normalise=True)[0], torch.tensor(1.0))


def test_baseline_head():
    head = BaselineHead(4, 1, activation="sigmoid")
    z = torch.zeros(2, 4)
    logits = head(z)
    assert logits.shape == (2, 1)
    assert torch.allclose(head.probabilities(logits), torch.sigmoid(logits))
    sm = BaselineHead(4, 3)
    assert torch.allclose(sm.probabilities(sm(z)).sum(-1), torch.ones(2))
    with pytest.raises(ValueError, match="softmax"):
        BaselineHead(4, 1, activation="softmax")


@pytest.mark.parametrize(
    "bad, msg",
    [
        (torch.tensor([[0.5, 2.0]]), ">= 1"),
        (torch.tensor([[float("nan"), 2.0]]), "non-finite"),
        (torch.tensor([[1, 2]]), "floating"),
    ],
)
def test_check_alpha_rejects(bad, msg):
    with pytest.raises(ValueError, match=msg):
        check_alpha(bad)
