"""The ablation conditions (paper E2 (a)-(g), plus (h) conflict-aware rules, (i) I/Q-level RF
noise and a temperature-scaled sigmoid control) computed from cached per-modality outputs, and the
per-condition metrics."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from evids.experiments.pipeline import Models, Outputs, gmu_logit, late_probs
from evids.fusion import average, dempster_shafer, discounted_belief_fusion, yager
from evids.gating import GateParams, simulate_gate, subset_fusion_table
from evids.metrics import accuracy, brier, ece, macro_f1, nll, uauc
from evids.models.backbones import MODALITIES


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
    Condition("b", "(b) Late Fusion (sigmoid)", "standard", "late"),
    Condition("b_temp", "(b+T) Late Fusion + temperature (control)", "standard", "late_temp"),
    Condition("c", "(c) GMU (sigmoid)", "standard", "gmu"),
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


def _two(p1: np.ndarray) -> np.ndarray:
    p1 = np.clip(np.asarray(p1, np.float64), 0.0, 1.0)
    return np.stack([1.0 - p1, p1], axis=1)


def fuse(rule: str, alpha: np.ndarray, c_max: float, construction: str) -> Prediction:
    """Fuse (3, N, 2) alphas with one rule."""
    a = torch.from_numpy(alpha)
    if rule == "average":
        r = average(a)
        return Prediction(r.p.numpy(), r.u.numpy())
    if rule == "ds":
        r = dempster_shafer(a, c_max=c_max, construction=construction)
        return Prediction(r.p.numpy(), r.u.numpy(), r.conflict.amax(dim=0).numpy(), r.fallback.numpy())
    if rule == "yager":
        r = yager(a, construction=construction)
        return Prediction(r.p.numpy(), r.u.numpy(), r.conflict.amax(dim=0).numpy())
    if rule == "discounted":
        r = discounted_belief_fusion(a, construction=construction)
        return Prediction(r.p.numpy(), r.u.numpy(), r.conflict.amax(dim=0).numpy())
    raise ValueError(f"unknown fusion rule {rule!r}")


def gated_ds(alpha: np.ndarray, params: GateParams, clip_ids: np.ndarray, c_max: float,
             construction: str) -> Prediction:
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
                      construction: str, gate: GateParams | None) -> Prediction:
    """The condition's prediction from cached outputs of its input variant."""
    if cond.rule == "sigmoid":
        m = MODALITIES.index(cond.modality)
        return Prediction(_two(1.0 / (1.0 + np.exp(-out.logit[m]))))
    if cond.rule == "edl":
        al = out.alpha[MODALITIES.index(cond.modality)]
        return Prediction(al / al.sum(-1, keepdims=True), 2.0 / al.sum(-1))
    if cond.rule == "late":
        return Prediction(_two(late_probs(models, out)))
    if cond.rule == "late_temp":
        p = np.clip(late_probs(models, out), 1e-9, 1 - 1e-9)
        z = np.log(p / (1 - p)) / models.temperature
        return Prediction(_two(1.0 / (1.0 + np.exp(-z))))
    if cond.rule == "gmu":
        return Prediction(_two(1.0 / (1.0 + np.exp(-gmu_logit(models, out)))))
    if cond.rule == "ds_gate":
        if gate is None:
            raise ValueError("condition (f) needs gate parameters")
        return gated_ds(out.alpha, gate, clip_ids, c_max, construction)
    return fuse(cond.rule, out.alpha, c_max, construction)


def entropy(probs: np.ndarray) -> np.ndarray:
    p = np.clip(probs, 1e-12, 1.0)
    return -(p * np.log(p)).sum(axis=1)


def _safe(v: float) -> float | None:
    return None if v is None or not np.isfinite(v) else float(v)


def metrics_of(pred: Prediction, labels: np.ndarray, ece_bins: int) -> dict[str, float | None]:
    """Accuracy, macro-F1, ECE, NLL, Brier, entropy-UAUC and (evidential only) vacuity-UAUC."""
    p = pred.probs
    err = p.argmax(1) != labels
    out = {
        "accuracy": accuracy(p, labels), "macro_f1": macro_f1(p, labels, num_classes=2),
        "ece": ece(p, labels, n_bins=ece_bins), "nll": nll(p, labels), "brier": brier(p, labels),
        "uauc_entropy": _safe(uauc(entropy(p), err)),
        "uauc_vacuity": _safe(uauc(pred.vacuity, err)) if pred.vacuity is not None else None,
    }
    if pred.conflict is not None:
        out["mean_conflict"] = float(np.mean(pred.conflict))
    if pred.fallback is not None:
        out["fallback_rate"] = float(np.mean(pred.fallback))
    if pred.skip_rate is not None:
        out["skip_rate"] = pred.skip_rate
    return {k: _safe(v) if isinstance(v, float) else v for k, v in out.items()}


def choose_gate(alpha_val: np.ndarray, y_val: np.ndarray, clip_ids_val: np.ndarray, grid, max_drop: float,
                construction: str) -> tuple[GateParams, dict]:
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
