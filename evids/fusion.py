"""Decision-level fusion of per-modality Dirichlet opinions, plus learned (non-evidential) baselines.

Inputs: ``alphas`` is a list of M >= 2 tensors of shape ``(N, K)`` (any common batch shape works) or
one tensor ``(M, N, K)``; ``available`` is an optional boolean mask ``(M, N)``. A missing modality is
the identity of every rule here: the DS-family rules treat it as the vacuous opinion (alpha = 1,
b = 0, u = 1), the averaging rules leave it out of the average.

All rules work on subjective-logic opinions ``(b, u)`` with ``sum(b) + u = 1`` built from alpha by
:func:`evids.heads.belief_masses` (``"canonical"`` ``b = e/S`` or ``"scaled"`` ``b = p(1-u)``) and
map the fused opinion back with :func:`evids.heads.opinion_to_alpha`. Everything is vectorised over
samples; the only Python loops run over modalities.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Literal, NamedTuple, Union

import torch
from torch import Tensor, nn

from evids.heads import (
    Construction,
    _check_construction,
    belief_masses,
    check_alpha,
    opinion_to_alpha,
)

Alphas = Union[Tensor, Sequence[Tensor]]
Mask = Union[Tensor, Sequence[Tensor], None]

__all__ = [
    "FUSION_RULES",
    "GMU",
    "FusionResult",
    "LateFusion",
    "average",
    "averaging_fusion",
    "cumulative_fusion",
    "dempster_shafer",
    "discounted_belief_fusion",
    "stack_modalities",
    "yager",
]


class FusionResult(NamedTuple):
    """Fused opinion and diagnostics.

    ``alpha``, ``p``, ``belief``: ``(N, K)``; ``u``: ``(N,)``.
    ``conflict``: DS/Yager: conflict C of each fold step ``(M-1, N)`` (0 where a step had a missing
    modality); discounted fusion: each modality's mean degree of conflict with the others ``(M, N)``;
    ``None`` for rules without a conflict term.
    ``fallback``: DS only, ``(N,)`` True where C > c_max sent the sample to its most certain modality.
    ``discount``: discounted fusion only, the trust factor applied to each modality ``(M, N)``.

    Under the ``"scaled"`` construction the fused ``alpha = p K / u`` is a valid Dirichlet
    parameter (> 0) but can fall below 1 (e.g. Yager or discounted fusion with a large fused u), so
    it is not evidence + 1 and cannot be fed back into these rules: fuse all modalities in one call.
    """

    alpha: Tensor
    p: Tensor
    u: Tensor
    belief: Tensor
    conflict: Tensor | None = None
    fallback: Tensor | None = None
    discount: Tensor | None = None


def stack_modalities(alphas: Alphas, available: Mask = None) -> tuple[Tensor, Tensor | None]:
    """Validate and stack inputs to ``(M, *batch, K)`` and the mask to ``(M, *batch)``."""
    if isinstance(alphas, Tensor):
        if alphas.dim() < 3:
            raise ValueError(
                f"alphas as a single tensor must have shape (M, N, K), got shape {tuple(alphas.shape)}; "
                "pass a list of (N, K) tensors for one tensor per modality"
            )
        stacked = alphas
    elif isinstance(alphas, (list, tuple)):
        if not all(isinstance(a, Tensor) for a in alphas):
            raise ValueError("alphas must be a list of torch.Tensor of identical shape (N, K)")
        shapes = {tuple(a.shape) for a in alphas}
        if len(shapes) > 1:
            raise ValueError(f"all modalities in alphas must share one shape, got shapes {sorted(shapes)}")
        if len(alphas) and alphas[0].dim() < 1:
            raise ValueError("each modality's alpha must have shape (N, K)")
        stacked = torch.stack(list(alphas)) if len(alphas) else torch.empty(0)
    else:
        raise ValueError(f"alphas must be a tensor (M, N, K) or a list of (N, K) tensors, got {type(alphas).__name__}")
    if stacked.shape[0] < 2:
        raise ValueError(f"fusion needs M >= 2 modalities, got M={stacked.shape[0]}")
    check_alpha(stacked, "alphas", min_classes=2)

    if available is None:
        return stacked, None
    mask = torch.stack(list(available)) if isinstance(available, (list, tuple)) else available
    if not isinstance(mask, Tensor):
        raise ValueError("available must be a bool tensor (M, N) or a list of (N,) tensors, got "
                         f"{type(available).__name__}")
    if mask.dtype != torch.bool:
        if mask.is_floating_point() or not bool(((mask == 0) | (mask == 1)).all()):
            raise ValueError(f"available must be boolean (or 0/1 integers), got dtype {mask.dtype}")
        mask = mask.bool()
    if tuple(mask.shape) != tuple(stacked.shape[:-1]):
        raise ValueError(
            f"available must have shape {tuple(stacked.shape[:-1])} (M, N), got {tuple(mask.shape)}"
        )
    return stacked, mask


def _opinions(stacked: Tensor, mask: Tensor | None, construction: Construction) -> tuple[Tensor, Tensor]:
    _check_construction(construction)
    b, u = belief_masses(stacked, construction)
    if mask is not None:
        b = torch.where(mask.unsqueeze(-1), b, torch.zeros((), dtype=b.dtype))
        u = torch.where(mask, u, torch.ones((), dtype=u.dtype))
    return b, u


def _result(b: Tensor, u: Tensor, construction: Construction, **diag: Tensor | None) -> FusionResult:
    alpha, p = opinion_to_alpha(b, u, construction)
    return FusionResult(alpha=alpha, p=p, u=u, belief=b, **diag)


def _opinions_cm(stacked: Tensor, mask: Tensor | None, construction: Construction) -> tuple[Tensor, Tensor]:
    """Opinions in class-major layout, ``b`` (M, K, *batch) and ``u`` (M, *batch): the same
    arithmetic as :func:`evids.heads.belief_masses`, laid out so that every per-class operation of
    the fold runs on contiguous sample vectors (reductions over small K are slow on the last dim)."""
    _check_construction(construction)
    x = stacked.movedim(-1, 1).contiguous()
    if x.data_ptr() == stacked.data_ptr():
        x = x.clone()
    k = x.shape[1]
    s = x.sum(dim=1)
    u = k / s
    if construction == "canonical":
        b = x.sub_(1.0).div_(s.unsqueeze(1))
    else:
        b = x.div_(s.unsqueeze(1)).mul_((1.0 - u).unsqueeze(1))
    if mask is not None:
        b = torch.where(mask.unsqueeze(1), b, torch.zeros((), dtype=b.dtype))
        u = torch.where(mask, u, torch.ones((), dtype=u.dtype))
    return b, u


def _result_cm(b: Tensor, u: Tensor, construction: Construction) -> tuple[Tensor, Tensor, Tensor]:
    """Class-major fused opinion -> ``(alpha, p, belief)`` as contiguous (..., K) tensors
    (the inverse of :func:`evids.heads.belief_masses`, see :func:`evids.heads.opinion_to_alpha`)."""
    k = b.shape[0]
    tiny = torch.finfo(b.dtype).tiny
    s = k / u.clamp(min=tiny, max=1.0)
    if construction == "canonical":
        alpha = (b * s).add_(1.0)
        p = alpha / alpha.sum(dim=0)
    else:
        mass = b.sum(dim=0)
        safe = mass > tiny
        p = torch.where(safe, b / torch.where(safe, mass, torch.ones((), dtype=b.dtype)),
                        torch.full((), 1.0 / k, dtype=b.dtype))
        alpha = p * s
    return tuple(t.movedim(0, -1).contiguous() for t in (alpha, p, b))


def _ds_step(b1: Tensor, u1: Tensor, b2: Tensor, u2: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """Dempster's rule on two class-major opinions (b: (K, *batch), u: (*batch)).

    ``C = sum_{i != j} b1_i b2_j = sum(b1) sum(b2) - sum_k b1_k b2_k``. ``1 - C`` is evaluated as
    ``u1 + u2 - u1 u2 + sum_k b1_k b2_k`` (algebraically equal because ``sum b + u = 1``): a sum of
    non-negative terms, so it never cancels to 0 or goes negative as C -> 1, and it is exactly
    symmetric in the two arguments.
    """
    prod = b1 * b2
    agree = prod.sum(dim=0)
    c = b1.sum(dim=0).mul_(b2.sum(dim=0)).sub_(agree).clamp_(0.0, 1.0)
    uu = u1 * u2
    one_minus_c = (u1 + u2).sub_(uu).add_(agree).clamp_(min=torch.finfo(b1.dtype).tiny)
    cross = (b1 * u2).add_(b2 * u1)
    b = prod.add_(cross).div_(one_minus_c)
    u = uu.div_(one_minus_c)
    return b, u, c


def _yager_step(b1: Tensor, u1: Tensor, b2: Tensor, u2: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """Yager's rule on class-major opinions: the conjunctive masses without normalisation, the
    conflict mass added to u."""
    prod = b1 * b2
    c = (b1.sum(dim=0) * b2.sum(dim=0) - prod.sum(dim=0)).clamp_(0.0, 1.0)
    b = prod + (b1 * u2 + b2 * u1)
    u = u1 * u2 + c
    return b, u, c


def _fold(
    step: Callable[[Tensor, Tensor, Tensor, Tensor], tuple[Tensor, Tensor, Tensor]],
    b: Tensor,
    u: Tensor,
    mask: Tensor | None,
) -> tuple[Tensor, Tensor, Tensor]:
    """Left fold of a binary rule over modalities (class-major ``b`` (M, K, *batch)); a missing
    modality leaves the running opinion unchanged bit for bit, and a sample's first available
    modality is taken as is."""
    fb, fu = b[0], u[0]
    seen: Tensor = mask[0] if mask is not None else None  # read only when a mask is given
    conflicts = []
    for m in range(1, b.shape[0]):
        nb, nu, c = step(fb, fu, b[m], u[m])
        if mask is not None:
            avail = mask[m]
            take_new = avail & ~seen
            nb = torch.where(take_new, b[m], nb)
            nu = torch.where(take_new, u[m], nu)
            keep = ~avail
            nb = torch.where(keep, fb, nb)
            nu = torch.where(keep, fu, nu)
            c = torch.where(avail & seen, c, torch.zeros((), dtype=c.dtype))
            seen = seen | avail
        fb, fu = nb, nu
        conflicts.append(c)
    return fb, fu, torch.stack(conflicts)


def dempster_shafer(
    alphas: Alphas,
    c_max: float | None = None,
    construction: Construction = "canonical",
    available: Mask = None,
) -> FusionResult:
    """Dempster's rule over M >= 2 modalities, folded left to right (paper Eqs. belief mass/DS).

    Per step: ``C = sum_{i!=j} b1_i b2_j``, ``b_k = (b1_k b2_k + b1_k u2 + b2_k u1) / (1 - C)``,
    ``u = u1 u2 / (1 - C)``; then ``S = K / u`` and alpha from the construction's inverse.
    With ``c_max`` set, samples whose largest step conflict exceeds it fall back to the available
    modality with the smallest u (first such modality on ties); ``fallback`` marks them.
    """
    stacked, mask = stack_modalities(alphas, available)
    if c_max is not None and not (isinstance(c_max, (int, float)) and 0.0 <= c_max <= 1.0):
        raise ValueError(f"c_max must be None or a number in [0, 1], got {c_max!r}")
    b, u = _opinions_cm(stacked, mask, construction)
    fb, fu, conflict = _fold(_ds_step, b, u, mask)
    alpha, p, belief = _result_cm(fb, fu, construction)
    fallback = None
    if c_max is not None:
        fallback = conflict.amax(dim=0) > c_max
        flat_fb = fallback.reshape(-1)
        rows = flat_fb.nonzero().squeeze(1)
        if rows.numel():
            k = stacked.shape[-1]
            flat_alpha = stacked.reshape(stacked.shape[0], -1, k)[:, rows]
            flat_u = u.reshape(u.shape[0], -1)[:, rows]
            if mask is not None:
                flat_u_rank = torch.where(mask.reshape(mask.shape[0], -1)[:, rows], flat_u,
                                          torch.full((), float("inf"), dtype=u.dtype))
            else:
                flat_u_rank = flat_u
            best_alpha, rank = flat_alpha[0], flat_u_rank[0]
            for m in range(1, flat_alpha.shape[0]):
                better = flat_u_rank[m] < rank
                rank = torch.where(better, flat_u_rank[m], rank)
                best_alpha = torch.where(better.unsqueeze(-1), flat_alpha[m], best_alpha)
            best_b, best_u = belief_masses(best_alpha, construction)
            alpha.view(-1, k)[rows] = best_alpha
            p.view(-1, k)[rows] = best_alpha / best_alpha.sum(dim=-1, keepdim=True)
            belief.view(-1, k)[rows] = best_b
            fu = fu.clone()
            fu.view(-1)[rows] = best_u
    return FusionResult(alpha=alpha, p=p, u=fu, belief=belief, conflict=conflict, fallback=fallback)


def yager(alphas: Alphas, construction: Construction = "canonical", available: Mask = None) -> FusionResult:
    """Yager's rule (Yager 1987), folded left to right: ``b_k = b1_k b2_k + b1_k u2 + b2_k u1``,
    ``u = u1 u2 + C``. Conflict becomes uncertainty instead of being renormalised away, so two
    confident, contradicting modalities yield a vacuous-leaning result. Commutative, not associative.
    """
    stacked, mask = stack_modalities(alphas, available)
    b, u = _opinions_cm(stacked, mask, construction)
    fb, fu, conflict = _fold(_yager_step, b, u, mask)
    alpha, p, belief = _result_cm(fb, fu, construction)
    return FusionResult(alpha=alpha, p=p, u=fu, belief=belief, conflict=conflict)


def _cumulative(b: Tensor, u: Tensor) -> tuple[Tensor, Tensor]:
    """Multi-source aleatory cumulative fusion in ratio form: ``1/u = 1 + sum_i (1/u_i - 1)``,
    ``b = u sum_i b_i / u_i``. A vacuous input contributes exactly nothing."""
    inv_u = 1.0 / u
    fu = 1.0 / (1.0 + (inv_u - 1.0).sum(dim=0))
    fb = fu.unsqueeze(-1) * (b * inv_u.unsqueeze(-1)).sum(dim=0)
    return fb, fu


def _averaging(b: Tensor, u: Tensor, mask: Tensor | None) -> tuple[Tensor, Tensor]:
    """Multi-source averaging fusion over available sources: ``b = sum b_i/u_i / sum 1/u_i``,
    ``u = n / sum 1/u_i``; vacuous when no source is available."""
    inv_u = 1.0 / u
    if mask is not None:
        inv_u = torch.where(mask, inv_u, torch.zeros((), dtype=u.dtype))
        n = mask.sum(dim=0).to(u.dtype)
    else:
        n = torch.full(u.shape[1:], float(u.shape[0]), dtype=u.dtype)
    denom = inv_u.sum(dim=0)
    has = n > 0
    safe = torch.where(has, denom, torch.ones((), dtype=u.dtype))
    fb = (b * inv_u.unsqueeze(-1)).sum(dim=0) / safe.unsqueeze(-1)
    fu = torch.where(has, n / safe, torch.ones((), dtype=u.dtype))
    fb = torch.where(has.unsqueeze(-1), fb, torch.zeros((), dtype=b.dtype))
    return fb, fu


def cumulative_fusion(
    alphas: Alphas, construction: Construction = "canonical", available: Mask = None
) -> FusionResult:
    """Subjective-logic aleatory cumulative belief fusion (Jøsang, *Subjective Logic*, 2016), for
    M sources at once: ``b = (sum_i b_i / u_i) / (1 + sum_i (1/u_i - 1))``,
    ``u = 1 / (1 + sum_i (1/u_i - 1))`` (the two-source form is
    ``b = (b1 u2 + b2 u1) / (u1 + u2 - u1 u2)``). In the canonical construction this is exactly
    evidence addition, ``e = sum_i e_i``. Order-invariant and associative."""
    stacked, mask = stack_modalities(alphas, available)
    b, u = _opinions(stacked, mask, construction)
    fb, fu = _cumulative(b, u)
    return _result(fb, fu, construction)


def averaging_fusion(
    alphas: Alphas, construction: Construction = "canonical", available: Mask = None
) -> FusionResult:
    """Subjective-logic averaging belief fusion (Jøsang 2016) for M sources:
    ``b = (sum_i b_i / u_i) / (sum_i 1/u_i)``, ``u = M / (sum_i 1/u_i)`` (two sources:
    ``b = (b1 u2 + b2 u1) / (u1 + u2)``, ``u = 2 u1 u2 / (u1 + u2)``). Canonical: ``e = mean_i e_i``.
    Missing modalities are left out of the average (a vacuous source would halve the evidence)."""
    stacked, mask = stack_modalities(alphas, available)
    b, u = _opinions(stacked, mask, construction)
    fb, fu = _averaging(b, u, mask)
    return _result(fb, fu, construction)


def discounted_belief_fusion(
    alphas: Alphas,
    construction: Construction = "canonical",
    available: Mask = None,
    base: Literal["cumulative", "averaging"] = "cumulative",
) -> FusionResult:
    """Conflict-discounted belief fusion, order-invariant.

    Built from Jøsang's subjective-logic primitives (*Subjective Logic*, Springer 2016):
    1. degree of conflict between sources i, j: ``DC_ij = PD_ij * CC_ij`` with projected distance
       ``PD_ij = 0.5 sum_k |P_i(k) - P_j(k)|`` (``P = b + u/K``, uniform base rate) and
       conjunctive certainty ``CC_ij = (1 - u_i)(1 - u_j)``;
    2. trust factor ``t_i = 1 - mean_{j != i, j available} DC_ij`` (1 with no other source);
    3. trust discounting ``b_i' = t_i b_i``, ``u_i' = 1 - t_i (1 - u_i)``;
    4. multi-source cumulative (default) or averaging fusion of the discounted opinions.
    Every step is symmetric in the sources, so the result does not depend on their order. Under
    agreement (DC = 0) it reduces to the base rule; under strong conflict the evidence of every
    conflicting source shrinks and the fused u rises instead of hiding the conflict.
    ``conflict`` holds each source's mean DC, ``discount`` the trust factors t.
    """
    if base not in ("cumulative", "averaging"):
        raise ValueError(f"base must be 'cumulative' or 'averaging', got {base!r}")
    stacked, mask = stack_modalities(alphas, available)
    b, u = _opinions(stacked, mask, construction)
    m, k = b.shape[0], b.shape[-1]
    proj = b + (u / k).unsqueeze(-1)
    pd = 0.5 * (proj.unsqueeze(0) - proj.unsqueeze(1)).abs().sum(dim=-1)
    cert = 1.0 - u
    dc = pd * (cert.unsqueeze(0) * cert.unsqueeze(1))
    pair = ~torch.eye(m, dtype=torch.bool).reshape(m, m, *([1] * (b.dim() - 2)))
    if mask is not None:
        pair = pair & mask.unsqueeze(0) & mask.unsqueeze(1)
    pair = pair.expand_as(dc)
    n_other = pair.sum(dim=1).to(b.dtype)
    mean_dc = torch.where(pair, dc, torch.zeros((), dtype=b.dtype)).sum(dim=1) / n_other.clamp(min=1.0)
    t = (1.0 - mean_dc).clamp(0.0, 1.0)
    bd = t.unsqueeze(-1) * b
    ud = (1.0 - t) + t * u          # = 1 - t (1 - u), without cancelling u to 0 in float32 when t = 1
    if base == "cumulative":
        fb, fu = _cumulative(bd, ud)
    else:
        fb, fu = _averaging(bd, ud, mask)
    return _result(fb, fu, construction, conflict=mean_dc, discount=t)


def average(alphas: Alphas, available: Mask = None) -> FusionResult:
    """Parameter-free averaging baseline: ``p`` is the mean of the available modalities' ``alpha/S``.

    ``alpha`` is the mean of the available alphas (averaged evidence), ``u = K / sum(alpha)`` its
    vacuity, ``belief`` its canonical belief masses. Note ``p`` is the mean of probabilities, which
    in general differs from ``alpha / S`` of the averaged alpha. No modality available: uniform.
    """
    stacked, mask = stack_modalities(alphas, available)
    k = stacked.shape[-1]
    probs = stacked / stacked.sum(dim=-1, keepdim=True)
    if mask is None:
        p = probs.mean(dim=0)
        alpha = stacked.mean(dim=0)
    else:
        w = mask.to(stacked.dtype).unsqueeze(-1)
        n = w.sum(dim=0)
        has = n > 0
        safe = torch.where(has, n, torch.ones((), dtype=n.dtype))
        p = torch.where(has, (probs * w).sum(dim=0) / safe, torch.full((), 1.0 / k, dtype=stacked.dtype))
        alpha = torch.where(has, (stacked * w).sum(dim=0) / safe, torch.ones((), dtype=stacked.dtype))
    s = alpha.sum(dim=-1)
    return FusionResult(alpha=alpha, p=p, u=k / s, belief=(alpha - 1.0) / s.unsqueeze(-1))


FUSION_RULES: dict[str, Callable[..., FusionResult]] = {
    "average": average,
    "dempster_shafer": dempster_shafer,
    "yager": yager,
    "cumulative": cumulative_fusion,
    "averaging": averaging_fusion,
    "discounted": discounted_belief_fusion,
}


def _stack_logits(logits: Tensor | Sequence[Tensor], m: int) -> Tensor:
    x = torch.stack(list(logits)) if isinstance(logits, (list, tuple)) else logits
    if not isinstance(x, Tensor) or not x.is_floating_point() or x.dim() != 2 or x.shape[0] != m:
        shape = tuple(x.shape) if isinstance(x, Tensor) else type(x).__name__
        raise ValueError(f"logits must be a float tensor (M={m}, N) or a list of {m} (N,) tensors, got {shape}")
    return x


class LateFusion(nn.Module):
    """Learned late fusion of per-modality sigmoid outputs (TRIDENT baseline).

    ``p = sum_m w_m sigmoid(logit_m)`` with ``w = softmax(theta)`` learned (convex weights keep p a
    probability). Missing modalities (``available``) are dropped and the weights renormalised.
    ``forward`` returns the fused drone probability ``(N,)``; train it with ``F.binary_cross_entropy``.
    """

    def __init__(self, num_modalities: int) -> None:
        super().__init__()
        if not isinstance(num_modalities, int) or num_modalities < 2:
            raise ValueError(f"num_modalities must be an int >= 2, got {num_modalities!r}")
        self.num_modalities = num_modalities
        self.theta = nn.Parameter(torch.zeros(num_modalities))

    @property
    def weights(self) -> Tensor:
        return torch.softmax(self.theta, dim=0)

    def forward(self, logits: Tensor | Sequence[Tensor], available: Tensor | None = None) -> Tensor:
        x = _stack_logits(logits, self.num_modalities)
        w = self.weights.to(x.dtype).unsqueeze(-1).expand_as(x)
        if available is not None:
            if tuple(available.shape) != tuple(x.shape):
                raise ValueError(f"available must have shape {tuple(x.shape)}, got {tuple(available.shape)}")
            w = w * available.to(x.dtype)
            total = w.sum(dim=0, keepdim=True)
            if bool((total <= 0).any()):
                raise ValueError("available leaves a sample with no modality; LateFusion needs at least one")
            w = w / total
        return (w * torch.sigmoid(x)).sum(dim=0)


class GMU(nn.Module):
    """Gated Multimodal Unit (Arevalo et al., 2017, "Gated Multimodal Units for Information Fusion").

    ``h_m = tanh(W_m x_m)``, gates ``z_m = sigmoid(W_z,m [x_1; ...; x_M])`` (or a softmax across
    modalities with ``gate="softmax"``), ``h = sum_m z_m * h_m``, logits ``= V h``.
    ``forward`` takes a list of per-modality feature tensors ``(N, d_m)`` and returns logits
    ``(N, num_outputs)``; :meth:`gates` returns ``z`` ``(N, M, hidden_dim)`` for inspection.
    """

    def __init__(
        self,
        input_dims: Sequence[int],
        hidden_dim: int,
        num_outputs: int = 1,
        gate: Literal["sigmoid", "softmax"] = "sigmoid",
    ) -> None:
        super().__init__()
        dims = list(input_dims)
        if len(dims) < 2 or not all(isinstance(d, int) and d > 0 for d in dims):
            raise ValueError(f"input_dims must list >= 2 positive ints, got {input_dims!r}")
        if not isinstance(hidden_dim, int) or hidden_dim < 1:
            raise ValueError(f"hidden_dim must be a positive int, got {hidden_dim!r}")
        if not isinstance(num_outputs, int) or num_outputs < 1:
            raise ValueError(f"num_outputs must be a positive int, got {num_outputs!r}")
        if gate not in ("sigmoid", "softmax"):
            raise ValueError(f"gate must be 'sigmoid' or 'softmax', got {gate!r}")
        self.input_dims = dims
        self.hidden_dim = hidden_dim
        self.gate = gate
        self.proj = nn.ModuleList(nn.Linear(d, hidden_dim, bias=False) for d in dims)
        self.gate_layer = nn.Linear(sum(dims), len(dims) * hidden_dim)
        self.out = nn.Linear(hidden_dim, num_outputs)

    def _check(self, xs: Sequence[Tensor]) -> None:
        if len(xs) != len(self.input_dims):
            raise ValueError(f"expected {len(self.input_dims)} modality inputs, got {len(xs)}")
        for i, (x, d) in enumerate(zip(xs, self.input_dims)):
            if x.dim() != 2 or x.shape[1] != d or x.shape[0] != xs[0].shape[0]:
                raise ValueError(f"input {i} must have shape (N, {d}), got {tuple(x.shape)}")

    def gates(self, xs: Sequence[Tensor]) -> Tensor:
        """Gate activations ``z`` of shape ``(N, M, hidden_dim)``."""
        self._check(xs)
        raw = self.gate_layer(torch.cat(list(xs), dim=-1)).view(-1, len(self.input_dims), self.hidden_dim)
        return torch.sigmoid(raw) if self.gate == "sigmoid" else torch.softmax(raw, dim=1)

    def forward(self, xs: Sequence[Tensor]) -> Tensor:
        z = self.gates(xs)
        h = torch.stack([torch.tanh(p(x)) for p, x in zip(self.proj, xs)], dim=1)
        return self.out((z * h).sum(dim=1))
