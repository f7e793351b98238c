"""Uncertainty-driven temporal sensor gating with hysteresis (paper Sec. "Temporal Sensor Gating").

Two forms, chosen by ``GateParams.mode``:

- ``"window"`` (paper Eq. gating, E2): a modality evaluated at step t with ``u > tau_high`` is
  excluded from fusion at t and is neither evaluated nor fused at t+1..t+N. When the window ends it
  is evaluated again: ``u < tau_low`` reopens it, ``u > tau_high`` or a value in the hysteresis band
  ``[tau_low, tau_high]`` keeps it closed for another N steps (``g_{t+1:t+N} = g_t``).
- ``"streak"`` (E3): an open gate closes only after N *consecutive* steps with ``u > tau_high``; any
  step with ``u <= tau_high`` resets the streak to 0. A closed gate stays closed (the modality is
  still evaluated, but not fused) until ``u < tau_low``.

Constraints: at least one modality is fused at every step: if every evaluated modality is excluded,
the one with the smallest current u is fused and, in window form, kept open, so it is evaluated at
the next step too (hence some modality is always evaluated). Abstain: when the
fused uncertainty exceeds ``tau_fused`` for ``abstain_patience`` consecutive steps the step is
flagged as abstained (e.g. the tracker coasts on its motion model).

State is kept per modality and per key (a track or sequence id), so interleaved tracks do not
share streaks or windows.
"""
from __future__ import annotations

import itertools
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass, field
from typing import Literal, TypedDict

import numpy as np
import torch

from evids.fusion import FUSION_RULES
from evids.heads import Construction, check_alpha

GateMode = Literal["window", "streak"]

__all__ = [
    "GateParams",
    "GateStats",
    "GateStep",
    "GateSweepRow",
    "HysteresisGate",
    "simulate_gate",
    "subset_fusion_table",
    "sweep_gates",
]


@dataclass(frozen=True)
class GateParams:
    """Gate hyper-parameters; ``tau_fused=None`` disables abstention."""

    tau_high: float
    tau_low: float
    n: int
    mode: GateMode = "window"
    tau_fused: float | None = None
    abstain_patience: int = 1

    def __post_init__(self) -> None:
        for name in ("tau_high", "tau_low"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0:
                raise ValueError(f"{name} must be a number in [0, 1], got {v!r}")
        if not self.tau_low < self.tau_high:
            raise ValueError(f"tau_low must be < tau_high for hysteresis, got tau_low={self.tau_low!r}, "
                             f"tau_high={self.tau_high!r}")
        if not isinstance(self.n, (int, np.integer)) or isinstance(self.n, bool) or self.n < 1:
            raise ValueError(f"n must be an int >= 1, got {self.n!r}")
        if self.mode not in ("window", "streak"):
            raise ValueError(f"mode must be 'window' or 'streak', got {self.mode!r}")
        if self.tau_fused is not None and (not isinstance(self.tau_fused, (int, float))
                                           or not 0.0 <= self.tau_fused <= 1.0):
            raise ValueError(f"tau_fused must be None or a number in [0, 1], got {self.tau_fused!r}")
        if not isinstance(self.abstain_patience, int) or self.abstain_patience < 1:
            raise ValueError(f"abstain_patience must be an int >= 1, got {self.abstain_patience!r}")


@dataclass
class _ModalityState:
    closed: bool = False
    remaining: int = 0
    streak: int = 0
    last_u: float = float("inf")


@dataclass
class _KeyState:
    modalities: list[_ModalityState]
    planned: list[bool] | None = None
    high_fused_run: int = 0


@dataclass
class GateStats:
    """Counters for skip-rate accounting (all steps of all keys)."""

    num_modalities: int
    steps: int = 0
    evaluated: list[int] = field(default_factory=list)
    fused: list[int] = field(default_factory=list)
    abstained: int = 0
    forced: int = 0

    def __post_init__(self) -> None:
        if not self.evaluated:
            self.evaluated = [0] * self.num_modalities
        if not self.fused:
            self.fused = [0] * self.num_modalities

    @property
    def skip_rate_per_modality(self) -> list[float]:
        """Fraction of steps each modality was not evaluated (the realisable compute saving)."""
        return [1.0 - e / self.steps if self.steps else 0.0 for e in self.evaluated]

    @property
    def skip_rate(self) -> float:
        """Mean over modalities of :attr:`skip_rate_per_modality`."""
        r = self.skip_rate_per_modality
        return sum(r) / len(r)

    @property
    def exclusion_rate_per_modality(self) -> list[float]:
        """Fraction of steps each modality was left out of fusion (skipped or gated off)."""
        return [1.0 - f / self.steps if self.steps else 0.0 for f in self.fused]

    @property
    def exclusion_rate(self) -> float:
        r = self.exclusion_rate_per_modality
        return sum(r) / len(r)

    @property
    def abstain_rate(self) -> float:
        return self.abstained / self.steps if self.steps else 0.0


class GateSweepRow(TypedDict):
    """One grid point of :func:`sweep_gates` (a plain dict at run time)."""

    tau_high: float
    tau_low: float
    n: int
    mode: GateMode
    accuracy: float
    delta_accuracy: float
    skip_rate: float
    skip_rate_per_modality: tuple[float, ...]
    exclusion_rate: float
    abstain_rate: float
    accuracy_answered: float
    forced: int


@dataclass(frozen=True)
class GateStep:
    """Outcome of one step: which modalities were evaluated and fused, and whether to abstain."""

    evaluated: tuple[bool, ...]
    fused: tuple[bool, ...]
    abstain: bool
    forced: bool
    fused_u: float | None


class HysteresisGate:
    """Streaming hysteresis gate over M modalities with state per key (track / sequence id).

    Online use: ``plan(key)`` says which modalities to run this step; run them; ``update(u, key)``
    with their vacuities (other entries are ignored) returns the fusion mask; ``abstain(fused_u,
    key)`` flags abstention. ``step`` does all three when every u is already known (offline).
    """

    def __init__(self, num_modalities: int, params: GateParams) -> None:
        if not isinstance(num_modalities, int) or num_modalities < 1:
            raise ValueError(f"num_modalities must be an int >= 1, got {num_modalities!r}")
        if not isinstance(params, GateParams):
            raise ValueError(f"params must be a GateParams, got {type(params).__name__}")
        self.num_modalities = num_modalities
        self.params = params
        self.stats = GateStats(num_modalities)
        self._state: dict[Hashable, _KeyState] = {}
        self._last: tuple[tuple[bool, ...], tuple[bool, ...], bool] = ((), (), False)

    def _key(self, key: Hashable) -> _KeyState:
        st = self._state.get(key)
        if st is None:
            st = _KeyState([_ModalityState() for _ in range(self.num_modalities)])
            self._state[key] = st
        return st

    def reset(self, key: Hashable | None = None) -> None:
        """Forget the state of one key, or of every key when ``key`` is None (stats are kept)."""
        if key is None:
            self._state.clear()
        else:
            self._state.pop(key, None)

    def plan(self, key: Hashable = None) -> list[bool]:
        """Begin a step for ``key``: return which modalities must be evaluated now."""
        st = self._key(key)
        if st.planned is not None:
            raise ValueError(f"plan() called twice for key {key!r} without update()")
        if self.params.mode == "streak":
            evaluate = [True] * self.num_modalities
        else:
            evaluate = []
            for m in st.modalities:
                if m.remaining > 0:
                    m.remaining -= 1
                    evaluate.append(False)
                else:
                    evaluate.append(True)
        st.planned = evaluate
        return list(evaluate)

    def update(self, u: Sequence[float], key: Hashable = None) -> list[bool]:
        """Feed the vacuities of this step (entries not planned are ignored); return the fusion mask."""
        st = self._key(key)
        if st.planned is None:
            raise ValueError(f"update() called for key {key!r} without a preceding plan()")
        if len(u) != self.num_modalities:
            raise ValueError(f"u must have {self.num_modalities} entries, got {len(u)}")
        p = self.params
        evaluate, st.planned = st.planned, None
        fused = [False] * self.num_modalities
        for i, (m, ev) in enumerate(zip(st.modalities, evaluate)):
            if not ev:
                continue
            ui = float(u[i])
            if not np.isfinite(ui):
                raise ValueError(f"u[{i}] must be finite for an evaluated modality, got {u[i]!r}")
            m.last_u = ui
            if p.mode == "window":
                if ui > p.tau_high:
                    m.closed = True
                elif ui < p.tau_low:
                    m.closed = False
                if m.closed:
                    m.remaining = p.n
                fused[i] = not m.closed
            else:
                if not m.closed:
                    m.streak = m.streak + 1 if ui > p.tau_high else 0
                    if m.streak >= p.n:
                        m.closed = True
                        m.streak = 0
                elif ui < p.tau_low:
                    m.closed = False
                fused[i] = not m.closed
        forced = False
        if not any(fused):
            cand = [i for i in range(self.num_modalities) if evaluate[i]]
            best = min(cand, key=lambda i: float(u[i]))
            fused[best] = True
            st.modalities[best].remaining = 0
            forced = True
        s = self.stats
        s.steps += 1
        s.forced += int(forced)
        for i in range(self.num_modalities):
            s.evaluated[i] += int(evaluate[i])
            s.fused[i] += int(fused[i])
        self._last = (tuple(evaluate), tuple(fused), forced)
        return fused

    def abstain(self, fused_u: float, key: Hashable = None) -> bool:
        """True when the fused uncertainty has exceeded ``tau_fused`` for ``abstain_patience`` steps."""
        if self.params.tau_fused is None:
            return False
        st = self._key(key)
        st.high_fused_run = st.high_fused_run + 1 if fused_u > self.params.tau_fused else 0
        out = st.high_fused_run >= self.params.abstain_patience
        self.stats.abstained += int(out)
        return out

    def step(
        self,
        u: Sequence[float],
        key: Hashable = None,
        fused_u: Callable[[Sequence[bool]], float] | None = None,
    ) -> GateStep:
        """One offline step with all vacuities known; ``fused_u(mask)`` gives the fused u of a mask."""
        evaluate = self.plan(key)
        fused = self.update(u, key)
        fu = fused_u(fused) if fused_u is not None else None
        ab = self.abstain(fu, key) if fu is not None else False
        return GateStep(tuple(evaluate), tuple(fused), ab, self._last[2], fu)


def subset_fusion_table(
    alphas: torch.Tensor | Sequence[torch.Tensor],
    rule: str = "dempster_shafer",
    **rule_kwargs: object,
) -> tuple[np.ndarray, np.ndarray]:
    """Fuse every non-empty subset of modalities once, vectorised over samples.

    Returns ``(pred, u)`` of shape ``(2**M, N)``: row ``s`` is the fused argmax class and fused
    uncertainty when exactly the modalities in bit mask ``s`` are fused (row 0 is unused). This is
    what makes an offline gate sweep cheap: the gate only chooses a row per sample.
    """
    if rule not in FUSION_RULES:
        raise ValueError(f"rule must be one of {sorted(FUSION_RULES)}, got {rule!r}")
    stacked: torch.Tensor = torch.stack(list(alphas)) if isinstance(alphas, (list, tuple)) else alphas
    check_alpha(stacked, "alphas", min_classes=2)
    if stacked.dim() != 3:
        raise ValueError(f"alphas must have shape (M, N, K), got {tuple(stacked.shape)}")
    m, n, _ = stacked.shape
    pred = np.full((2**m, n), -1, dtype=np.int64)
    unc = np.full((2**m, n), np.nan, dtype=np.float64)
    fn = FUSION_RULES[rule]
    for s in range(1, 2**m):
        bits = [(s >> i) & 1 == 1 for i in range(m)]
        if sum(bits) == 1:
            a = stacked[bits.index(True)]
            p = a / a.sum(-1, keepdim=True)
            u = a.shape[-1] / a.sum(-1)
        else:
            mask = torch.tensor(bits).unsqueeze(-1).expand(m, n)
            r = fn(stacked, available=mask, **rule_kwargs)
            p, u = r.p, r.u
        pred[s] = p.argmax(-1).numpy()
        unc[s] = u.double().numpy()
    return pred, unc


def simulate_gate(
    u_modalities: np.ndarray,
    params: GateParams,
    sequence_ids: Sequence[Hashable] | np.ndarray | None = None,
    fused_u_table: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, GateStats]:
    """Run a gate over cached per-modality vacuities ``(M, N)`` (rows of a sequence in time order).

    Returns ``(evaluated (M, N) bool, fused (M, N) bool, abstain (N,) bool, stats)``.
    ``fused_u_table`` (``(2**M, N)`` from :func:`subset_fusion_table`) enables abstention.
    """
    u_arr = np.asarray(u_modalities, dtype=np.float64)
    if u_arr.ndim != 2:
        raise ValueError(f"u_modalities must have shape (M, N), got {u_arr.shape}")
    m, n = u_arr.shape
    ids = np.zeros(n, dtype=np.int64) if sequence_ids is None else np.asarray(sequence_ids)
    if ids.shape != (n,):
        raise ValueError(f"sequence_ids must have shape ({n},), got {ids.shape}")
    if fused_u_table is not None and fused_u_table.shape != (2**m, n):
        raise ValueError(f"fused_u_table must have shape {(2**m, n)}, got {fused_u_table.shape}")
    gate = HysteresisGate(m, params)
    evaluated = np.zeros((m, n), dtype=bool)
    fused = np.zeros((m, n), dtype=bool)
    abstain = np.zeros(n, dtype=bool)
    weights = [1 << i for i in range(m)]
    cols = u_arr.T.tolist()
    id_list = ids.tolist()
    for t in range(n):
        ev = gate.plan(id_list[t])
        fm = gate.update(cols[t], id_list[t])
        evaluated[:, t] = ev
        fused[:, t] = fm
        if fused_u_table is not None:
            s = sum(w for w, f in zip(weights, fm) if f)
            abstain[t] = gate.abstain(float(fused_u_table[s, t]), id_list[t])
    return evaluated, fused, abstain, gate.stats


def sweep_gates(
    alphas: torch.Tensor | Sequence[torch.Tensor],
    labels: np.ndarray | torch.Tensor,
    tau_high: Sequence[float],
    tau_low: Sequence[float],
    n: Sequence[int],
    sequence_ids: Sequence[Hashable] | np.ndarray | None = None,
    mode: GateMode = "window",
    tau_fused: float | None = None,
    abstain_patience: int = 1,
    rule: str = "dempster_shafer",
    construction: Construction = "canonical",
) -> list[GateSweepRow]:
    """Offline sweep over the ``tau_high x tau_low x n`` grid on cached per-modality alphas (M, N, K).

    Combinations with ``tau_low >= tau_high`` are skipped. Each row: the parameters, ``accuracy``
    (fused prediction on every step), ``delta_accuracy`` vs. fusing all modalities, ``skip_rate``
    and ``skip_rate_per_modality`` (not evaluated), ``exclusion_rate`` (not fused),
    ``abstain_rate``, ``accuracy_answered`` (on non-abstained steps; NaN if none) and ``forced``.
    """
    stacked: torch.Tensor = torch.stack(list(alphas)) if isinstance(alphas, (list, tuple)) else alphas
    check_alpha(stacked, "alphas", min_classes=2)
    if stacked.dim() != 3:
        raise ValueError(f"alphas must have shape (M, N, K), got {tuple(stacked.shape)}")
    m, num, k = stacked.shape
    y = np.asarray(labels.numpy() if isinstance(labels, torch.Tensor) else labels)
    if y.shape != (num,):
        raise ValueError(f"labels must have shape ({num},), got {y.shape}")
    kwargs: dict[str, object] = {}
    if rule != "average":
        kwargs["construction"] = construction
    pred_table, u_table = subset_fusion_table(stacked, rule, **kwargs)
    u_mod = (k / stacked.sum(-1)).double().numpy()
    cols = np.arange(num)
    full = 2**m - 1
    base_acc = float((pred_table[full] == y).mean()) if num else float("nan")
    rows: list[GateSweepRow] = []
    for th, tl, nn_ in itertools.product(tau_high, tau_low, n):
        if not tl < th:
            continue
        params = GateParams(float(th), float(tl), int(nn_), mode, tau_fused, abstain_patience)
        _, fused, abstain, stats = simulate_gate(u_mod, params, sequence_ids, u_table if tau_fused is not None
                                                 else None)
        subset = (fused.astype(np.int64) * (1 << np.arange(m))[:, None]).sum(0)
        correct = pred_table[subset, cols] == y
        acc = float(correct.mean()) if num else float("nan")
        answered = ~abstain
        rows.append(
            {
                "tau_high": float(th),
                "tau_low": float(tl),
                "n": int(nn_),
                "mode": mode,
                "accuracy": acc,
                "delta_accuracy": acc - base_acc,
                "skip_rate": stats.skip_rate,
                "skip_rate_per_modality": tuple(stats.skip_rate_per_modality),
                "exclusion_rate": stats.exclusion_rate,
                "abstain_rate": stats.abstain_rate,
                "accuracy_answered": float(correct[answered].mean()) if answered.any() else float("nan"),
                "forced": stats.forced,
            }
        )
    return rows
