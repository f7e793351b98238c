import math

import pytest
import torch
import torch.nn.functional as F

from evids.losses import (
    annealing_coefficient,
    bce_loss,
    ce_loss,
    dirichlet_kl_uniform,
    edl_loss,
)


def test_kl_exactly_zero_at_alpha_one():
    for k in (2, 3, 10):
        for dtype in (torch.float32, torch.float64):
            kl = dirichlet_kl_uniform(torch.ones(4, k, dtype=dtype))
            assert torch.equal(kl, torch.zeros(4, dtype=dtype))


def test_kl_hand_value():
    # KL(Dir(1,2) || Dir(1,1)) = lgamma(3) - lgamma(2) - lgamma(1) - lgamma(2) + 1*(psi(2) - psi(3))
    #                          = log 2 - 1/2
    kl = dirichlet_kl_uniform(torch.tensor([[1.0, 2.0]], dtype=torch.float64))
    assert kl.item() == pytest.approx(math.log(2) - 0.5, abs=1e-12)


def test_edl_hand_values():
    alpha = torch.tensor([[3.0, 2.0]], dtype=torch.float64)
    y = torch.tensor([0])
    # digamma risk: psi(5) - psi(3) = 1/3 + 1/4; alpha~ = [1, 2] -> KL = log 2 - 1/2; lambda = 5/10
    risk = 1 / 3 + 1 / 4
    kl = math.log(2) - 0.5
    assert edl_loss(alpha, y, 5, 10).item() == pytest.approx(risk + 0.5 * kl, abs=1e-12)
    assert edl_loss(alpha, y, 0, 10).item() == pytest.approx(risk, abs=1e-12)
    assert edl_loss(alpha, y, 30, 10).item() == pytest.approx(risk + kl, abs=1e-12)
    # log risk: log 5 - log 3
    assert edl_loss(alpha, y, 0, 10, kind="log").item() == pytest.approx(math.log(5 / 3), abs=1e-12)
    # mse risk: p = [0.6, 0.4]: 0.4^2 + 0.4^2 + 2 * 0.6 * 0.4 / 6 = 0.4
    assert edl_loss(alpha, y, 0, 10, kind="mse").item() == pytest.approx(0.4, abs=1e-12)


def test_one_hot_and_index_targets_agree():
    gen = torch.Generator().manual_seed(1)
    alpha = 1 + torch.rand(8, 3, generator=gen, dtype=torch.float64) * 5
    y = torch.randint(0, 3, (8,), generator=gen)
    for kind in ("digamma", "log", "mse"):
        a = edl_loss(alpha, y, 3, 10, kind=kind, reduction="none")
        b = edl_loss(alpha, F.one_hot(y, 3).double(), 3, 10, kind=kind, reduction="none")
        assert torch.allclose(a, b)


@pytest.mark.parametrize("kind", ["digamma", "log", "mse"])
def test_gradcheck(kind):
    gen = torch.Generator().manual_seed(2)
    raw = torch.randn(5, 3, generator=gen, dtype=torch.float64, requires_grad=True)
    y = torch.tensor([0, 1, 2, 1, 0])

    def f(r):
        return edl_loss(F.softplus(r) + 1, y, 4, 10, kind=kind)

    assert torch.autograd.gradcheck(f, (raw,), eps=1e-6, atol=1e-5)


def test_fp32_safe_large_alpha():
    alpha32 = torch.tensor([[1e8, 1.0], [1.0, 1e8], [5e7, 3e7], [1.0, 1.0]], dtype=torch.float32, requires_grad=True)
    y = torch.tensor([0, 0, 1, 1])
    for kind in ("digamma", "log", "mse"):
        loss = edl_loss(alpha32, y, 10, 10, kind=kind, reduction="none")
        ref = edl_loss(alpha32.detach().double(), y, 10, 10, kind=kind, reduction="none")
        assert loss.dtype == torch.float32 and torch.isfinite(loss).all()
        assert torch.allclose(loss.double(), ref, rtol=1e-5, atol=1e-5)
        (g,) = torch.autograd.grad(loss.sum(), alpha32)
        assert torch.isfinite(g).all()


def test_validation():
    a = torch.tensor([[2.0, 1.0]])
    with pytest.raises(ValueError, match="K=1"):
        edl_loss(torch.tensor([[2.0]]), torch.tensor([0]), 1, 10)
    with pytest.raises(ValueError, match="kind"):
        edl_loss(a, torch.tensor([0]), 1, 10, kind="l2")
    with pytest.raises(ValueError, match="anneal_epochs"):
        edl_loss(a, torch.tensor([0]), 1, 0)
    with pytest.raises(ValueError, match="class indices"):
        edl_loss(a, torch.tensor([2]), 1, 10)
    with pytest.raises(ValueError, match=">= 1"):
        edl_loss(torch.tensor([[0.5, 1.0]]), torch.tensor([0]), 1, 10)
    assert annealing_coefficient(3, 12) == 0.25


def test_baseline_losses():
    logits = torch.tensor([0.3, -1.2])
    t = torch.tensor([1.0, 0.0])
    manual = -(torch.log(torch.sigmoid(logits[0])) + torch.log(1 - torch.sigmoid(logits[1]))) / 2
    assert torch.allclose(bce_loss(logits, t), manual)
    lg = torch.tensor([[1.0, 2.0, 0.5]])
    manual_ce = -torch.log_softmax(lg, -1)[0, 1]
    assert torch.allclose(ce_loss(lg, torch.tensor([1])), manual_ce)
    with pytest.raises(ValueError):
        ce_loss(lg, torch.tensor([3]))
