"""The ablation conditions (paper E2 (a)-(g), plus (h) conflict-aware rules, (i) I/Q-level RF
noise and a temperature-scaled sigmoid control) computed from cached per-modality outputs, and the
per-condition metrics."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from evids.fusion import FusionResult, average, dempster_shafer, discounted_belief_fusion, yager
from evids.gating import GateParams, simulate_gate, subset_fusion_table
from evids.heads import Construction
from evids.metrics import (
    accuracy,
    brier,
    ece,
    entropy_from_log_probs,
    macro_f1,
    nll,
    uauc,
)
from evids.modalities import MODALITIES
from harness.experiments.config import GateConfig
from harness.experiments.pipeline import Models, Outputs, gmu_logit


@dataclass(frozen=True)
class Condition:
    key: str
    label: str
    variant: str          # input variant: clean | standard | all_spec | iq
    rule: str             # how outputs are turned into a prediction
    modality: str | None = None


CONDITIONS: tuple[Condition, ...] = (
    *(Condition(f"a_{m}", f"(a) unimodal {m} (sigmoid)", "standard", "sigmoid", m) for m in MODALITIES),
    *(Condition(f"a_edl_{m}", f"(a') unimodal {m} (EDL)", "standard", "edl", m) for m in MODALITIES),
    *(Condition(f"a_T_{m}", f"(a+T) unimodal {m} (sigmoid + temperature)", "standard", "sigmoid_temp", m)
      for m in MODALITIES),
    Condition("b", "(b) Late Fusion (sigmoid), fitted on noisy val", "standard", "late"),
    Condition("b_temp", "(b+T) Late Fusion + temperature", "standard", "late_temp"),
    Condition("b_clean_fit", "(b, control) Late Fusion fitted on clean train", "standard", "late_clean"),
    Condition("c", "(c) GMU (sigmoid), fitted on noisy val", "standard", "gmu"),
    Condition("c_temp", "(c+T) GMU + temperature", "standard", "gmu_temp"),
    Condition("c_clean_fit", "(c, control) GMU fitted on clean train", "standard", "gmu_clean"),
    Condition("d", "(d) EDL + average", "standard", "average"),
    Condition("d_prime", "(d') EDL + average, all modalities noisy", "all_spec", "average"),
    Condition("e", "(e) EDL + DS", "standard", "ds"),
    Condition("f", "(f) EDL + DS + gating", "standard", "ds_gate"),
    Condition("g", "(g) EDL + DS, RF spectrogram noise (all noisy)", "all_spec", "ds"),
    Condition("h_yager", "(h) EDL + Yager", "standard", "yager"),
    Condition("h_discounted", "(h) EDL + discounted belief fusion", "standard", "discounted"),
    Condition("h_yager_all", "(h) EDL + Yager, all noisy", "all_spec", "yager"),
    Condition("h_discounted_all", "(h) EDL + discounted, all noisy", "all_spec", "discounted"),
    Condition("i", "(i) EDL + DS, RF noise on I/Q before the STFT", "iq", "ds"),
    Condition("i_avg", "(i) EDL + average, RF noise on I/Q", "iq", "average"),
    Condition("clean_b", "clean reference: Late Fusion", "clean", "late"),
    Condition("clean_d", "clean reference: EDL + average", "clean", "average"),
    Condition("clean_e", "clean reference: EDL + DS", "clean", "ds"),
)
METRICS = ("accuracy", "macro_f1", "ece", "nll", "brier", "uauc_entropy", "uauc_vacuity")


@dataclass
class Prediction:
    """(N, 2) probabilities plus uncertainty diagnostics."""

    probs: np.ndarray
    vacuity: np.ndarray | None = None
    conflict: np.ndarray | None = None     # DS: largest step conflict per sample
    fallback: np.ndarray | None = None
    skip_rate: float | None = None
    log_probs: np.ndarray | None = None    # exact (N, 2) log-probabilities (entropies without ties)


def _modality(cond: Condition) -> str:
    """The modality of a unimodal condition (its rule reads one modality's outputs)."""
    if cond.modality is None:
        raise ValueError(f"condition {cond.key!r}: rule {cond.rule!r} needs a modality")
    return cond.modality


def _conflict(r: FusionResult) -> torch.Tensor:
    """The rule's conflict term (DS, Yager and discounted fusion always return one)."""
    if r.conflict is None:
        raise ValueError("this fusion rule returned no conflict term")
    return r.conflict


def _from_logit(z: np.ndarray) -> Prediction:
    """Sigmoid P(class 1) = sigmoid(z) with exact log-probabilities."""
    z = np.asarray(z, np.float64)
    lp = np.stack([-np.logaddexp(0.0, z), -np.logaddexp(0.0, -z)], axis=1)
    return Prediction(np.exp(lp), log_probs=lp)


def _late_log_probs(models: Models, out: Outputs, clean_fit: bool = False) -> np.ndarray:
    """log [P0, P1] of Late Fusion p1 = sum_m w_m sigmoid(z_m), in the log domain."""
    head = models.late_head(clean_fit)
    logw = np.log(head.weights.detach().double().numpy())[:, None]
    z = out.logit
    from scipy.special import logsumexp

    lp0 = logsumexp(logw - np.logaddexp(0.0, z), axis=0)
    lp1 = logsumexp(logw - np.logaddexp(0.0, -z), axis=0)
    return np.stack([lp0, lp1], axis=1)


def _alpha_log_probs(alpha: np.ndarray) -> np.ndarray:
    return np.log(alpha) - np.log(alpha.sum(-1, keepdims=True))


def fuse(rule: str, alpha: np.ndarray, c_max: float, construction: Construction) -> Prediction:
    """Fuse (3, N, 2) alphas with one rule."""
    a = torch.from_numpy(alpha)
    if rule == "average":
        from scipy.special import logsumexp

        r = average(a)
        lp = logsumexp(_alpha_log_probs(alpha), axis=0) - np.log(alpha.shape[0])
        return Prediction(r.p.numpy(), r.u.numpy(), log_probs=lp)
    if rule == "ds":
        r = dempster_shafer(a, c_max=c_max, construction=construction)
        if r.fallback is None:
            raise ValueError("dempster_shafer returned no fallback record")
        return Prediction(r.p.numpy(), r.u.numpy(), _conflict(r).amax(dim=0).numpy(), r.fallback.numpy())
    if rule == "yager":
        r = yager(a, construction=construction)
        return Prediction(r.p.numpy(), r.u.numpy(), _conflict(r).amax(dim=0).numpy())
    if rule == "discounted":
        r = discounted_belief_fusion(a, construction=construction)
        return Prediction(r.p.numpy(), r.u.numpy(), _conflict(r).amax(dim=0).numpy())
    raise ValueError(f"unknown fusion rule {rule!r}")


def gated_ds(alpha: np.ndarray, params: GateParams, clip_ids: np.ndarray, c_max: float,
             construction: Construction) -> Prediction:
    """DS with the hysteresis gate simulated per clip (rows in time order within each clip)."""
    a = torch.from_numpy(alpha)
    u_mod = (2.0 / alpha.sum(-1))
    _, fused, _, stats = simulate_gate(u_mod, params, clip_ids)
    subset = (fused.astype(np.int64) * (1 << np.arange(3))[:, None]).sum(0)
    n = alpha.shape[1]
    probs = np.zeros((n, 2))
    vac = np.zeros(n)
    for s in np.unique(subset):
        rows = subset == s
        bits = [(int(s) >> i) & 1 == 1 for i in range(3)]
        sel = a[:, torch.from_numpy(rows)]
        if sum(bits) == 1:
            al = sel[bits.index(True)]
            probs[rows] = (al / al.sum(-1, keepdim=True)).numpy()
            vac[rows] = (2.0 / al.sum(-1)).numpy()
        else:
            mask = torch.tensor(bits).unsqueeze(-1).expand(3, int(rows.sum()))
            r = dempster_shafer(sel, c_max=c_max, construction=construction, available=mask)
            probs[rows], vac[rows] = r.p.numpy(), r.u.numpy()
    return Prediction(probs, vac, skip_rate=float(stats.skip_rate))


def predict_condition(cond: Condition, models: Models, out: Outputs, clip_ids: np.ndarray, c_max: float,
                      construction: Construction, gate: GateParams | None) -> Prediction:
    """The condition's prediction from cached outputs of its input variant."""
    if cond.rule in ("sigmoid", "sigmoid_temp"):
        modality = _modality(cond)
        m = MODALITIES.index(modality)
        t = models.temperatures.get(modality, 1.0) if cond.rule == "sigmoid_temp" else 1.0
        return _from_logit(out.logit[m] / t)
    if cond.rule == "edl":
        al = out.alpha[MODALITIES.index(_modality(cond))]
        return Prediction(al / al.sum(-1, keepdims=True), 2.0 / al.sum(-1), log_probs=_alpha_log_probs(al))
    if cond.rule in ("late", "late_clean"):
        lp = _late_log_probs(models, out, cond.rule == "late_clean")
        return Prediction(np.exp(lp), log_probs=lp)
    if cond.rule == "late_temp":
        lp = _late_log_probs(models, out)
        return _from_logit((lp[:, 1] - lp[:, 0]) / models.temperatures.get("late", 1.0))
    if cond.rule in ("gmu", "gmu_clean", "gmu_temp"):
        z = gmu_logit(models, out, cond.rule == "gmu_clean")
        return _from_logit(z / (models.temperatures.get("gmu", 1.0) if cond.rule == "gmu_temp" else 1.0))
    if cond.rule == "ds_gate":
        if gate is None:
            raise ValueError("condition (f) needs gate parameters")
        return gated_ds(out.alpha, gate, clip_ids, c_max, construction)
    return fuse(cond.rule, out.alpha, c_max, construction)


def entropy(probs: np.ndarray) -> np.ndarray:
    p = np.clip(probs, 1e-12, 1.0)
    return -(p * np.log(p)).sum(axis=1)


def _safe(v: float | None) -> float | None:
    return None if v is None or not np.isfinite(v) else float(v)


def metrics_of(pred: Prediction, labels: np.ndarray, ece_bins: int) -> dict[str, float | None]:
    """Accuracy, macro-F1, ECE, NLL, Brier, entropy-UAUC and (evidential only) vacuity-UAUC."""
    p = pred.probs
    err = p.argmax(1) != labels
    out = {
        "accuracy": accuracy(p, labels), "macro_f1": macro_f1(p, labels, num_classes=2),
        "ece": ece(p, labels, n_bins=ece_bins), "nll": nll(p, labels), "brier": brier(p, labels),
        "uauc_entropy": _safe(uauc(entropy_from_log_probs(pred.log_probs) if pred.log_probs is not None
                                   else entropy(p), err)),
        "saturated_fraction": float(np.mean((p == 0.0) | (p == 1.0))),
        "uauc_vacuity": _safe(uauc(pred.vacuity, err)) if pred.vacuity is not None else None,
    }
    if pred.conflict is not None:
        out["mean_conflict"] = float(np.mean(pred.conflict))
    if pred.fallback is not None:
        out["fallback_rate"] = float(np.mean(pred.fallback))
    if pred.skip_rate is not None:
        out["skip_rate"] = pred.skip_rate
    return {k: _safe(v) if isinstance(v, float) else v for k, v in out.items()}


def choose_gate(alpha_val: np.ndarray, y_val: np.ndarray, clip_ids_val: np.ndarray, grid: GateConfig,
                max_drop: float, construction: Construction) -> tuple[GateParams, dict]:
    """Gate operating point chosen on the validation split only (see GateConfig)."""
    from evids.gating import sweep_gates

    rows = sweep_gates(torch.from_numpy(alpha_val), y_val, grid.tau_high, grid.tau_low, grid.n,
                       sequence_ids=clip_ids_val, construction=construction)
    pred_t, _ = subset_fusion_table(torch.from_numpy(alpha_val), "dempster_shafer", construction=construction)
    base = float((pred_t[7] == y_val).mean())
    ok = [r for r in rows if r["accuracy"] >= base - max_drop]
    best = max(ok, key=lambda r: (r["skip_rate"], -r["tau_high"], r["tau_low"], -r["n"])) if ok else None
    if best is None:
        params = GateParams(0.35, 0.05, 10)
        info = {"chosen_on": "val", "fallback_to_paper_values": True}
    else:
        params = GateParams(best["tau_high"], best["tau_low"], best["n"])
        info = {"chosen_on": "val", "val_accuracy": best["accuracy"], "val_ungated_accuracy": base,
                "val_skip_rate": best["skip_rate"], "fallback_to_paper_values": False}
    info.update({"tau_high": params.tau_high, "tau_low": params.tau_low, "n": params.n, "mode": params.mode})
    return params, info
