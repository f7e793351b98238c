"""Scores of the real-benchmark track with clip-bootstrap intervals.

Resampling: clips are drawn with replacement within each class (so every resample keeps every class
and a balanced accuracy stays defined), every row of a drawn clip kept as often as it was drawn
(``evids.metrics.bootstrap.clustered_resample``). The same draws serve every model and condition of a
test set, so differences are paired. Minimum detectable difference = (z_0.975 + z_0.8) x the bootstrap
standard deviation of the difference (``sim2real.classify.Z_MDE``). Metrics are means over training
seeds.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from evids.metrics import ece, uauc
from evids.metrics.bootstrap import clustered_resample
from harness.experiments.sim2real.classify import Z_MDE, balanced_accuracy

METRICS = ("balanced_accuracy", "ece", "uauc_vacuity", "uauc_entropy", "uauc_confidence")


def stratified_draws(clip: np.ndarray, y: np.ndarray, rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """``n`` resamples of clip ids: per class, as many clips as it has, drawn with replacement."""
    ids = np.unique(clip)
    cls_of = {c: int(y[np.flatnonzero(clip == c)[0]]) for c in ids}
    groups = [np.array([c for c in ids if cls_of[c] == k]) for k in sorted(set(cls_of.values()))]
    return [np.concatenate([g[rng.integers(0, g.size, g.size)] for g in groups]) for _ in range(n)]


def _entropy(p: np.ndarray) -> np.ndarray:
    q = np.clip(p, 1e-12, 1.0)
    return -(p * np.log(q)).sum(axis=1)


def metrics_of(y: np.ndarray, probs: list[np.ndarray], vac: list[np.ndarray] | None,
               bins: int = 15) -> dict[str, float]:
    """Seed-mean metrics of one model: balanced accuracy, ECE, and the UAUC (errors vs uncertainty) of
    vacuity (evidential only), entropy and 1 - max probability."""
    rows: dict[str, list[float]] = {m: [] for m in METRICS}
    for s, p in enumerate(probs):
        pred = p.argmax(1)
        err = pred != y
        rows["balanced_accuracy"].append(balanced_accuracy(y, pred))
        rows["ece"].append(ece(p, y, n_bins=bins))
        rows["uauc_entropy"].append(uauc(_entropy(p), err))
        rows["uauc_confidence"].append(uauc(1.0 - p.max(1), err))
        rows["uauc_vacuity"].append(uauc(vac[s], err) if vac is not None else float("nan"))
    return {m: float(np.nanmean(v)) if np.isfinite(v).any() else float("nan") for m, v in rows.items()}


def interval(est: float, boot: np.ndarray) -> dict[str, float]:
    """Estimate with the 2.5 / 97.5 % percentiles of its finite bootstrap values."""
    b = boot[np.isfinite(boot)]
    if b.size < 3 or not np.isfinite(est):
        return {"estimate": est, "ci_low": float("nan"), "ci_high": float("nan")}
    lo, hi = np.quantile(b, [0.025, 0.975])
    return {"estimate": est, "ci_low": float(lo), "ci_high": float(hi)}


def format_interval(r: dict | None, fmt: str = "{:.3f}", mde_fmt: str = "{:.3f}") -> str:
    """``estimate [low, high]`` (and `` MDE m`` when the interval carries one) for printed summaries;
    ``-`` when there is no finite estimate."""
    if not r or r.get("estimate") is None or not np.isfinite(r["estimate"]):
        return "-"
    s = f"{fmt.format(r['estimate'])} [{fmt.format(r['ci_low'])}, {fmt.format(r['ci_high'])}]"
    return s + (" MDE " + mde_fmt.format(r["mde"]) if r.get("mde") is not None and np.isfinite(r["mde"]) else "")


def difference(est: float, boot: np.ndarray) -> dict[str, float]:
    """A difference's estimate and interval (:func:`interval`) with its MDE = Z_MDE x the bootstrap SD."""
    d = interval(est, boot)
    b = boot[np.isfinite(boot)]
    d["mde"] = float(Z_MDE * b.std(ddof=1)) if b.size > 2 else float("nan")
    return d


def score_models(y: np.ndarray, clip: np.ndarray, models: dict[str, tuple[list[np.ndarray], list[np.ndarray] | None]],
                 pairs: dict[str, tuple[str, str]], *, n_boot: int, rng: np.random.Generator) -> dict[str, Any]:
    """Every model's metrics with 95 % clip-bootstrap intervals, and paired differences
    ``pairs[name] = (minuend, subtrahend)`` of every metric with their MDE."""
    est = {k: metrics_of(y, p, v) for k, (p, v) in models.items()}
    boot = {k: {m: np.empty(n_boot) for m in METRICS} for k in models}
    for b, draw in enumerate(stratified_draws(clip, y, rng, n_boot)):
        idx = clustered_resample(clip, draw)
        for k, (p, v) in models.items():
            r = metrics_of(y[idx], [q[idx] for q in p], None if v is None else [u[idx] for u in v])
            for m in METRICS:
                boot[k][m][b] = r[m]
    out: dict[str, Any] = {"models": {k: {m: interval(est[k][m], boot[k][m]) for m in METRICS} for k in models},
                           "differences": {}}
    for name, (a, c) in pairs.items():
        if a in models and c in models:
            out["differences"][name] = {m: difference(est[a][m] - est[c][m], boot[a][m] - boot[c][m]) for m in METRICS}
    return out


# ---------------------------------------------------------------------------------------------
# Sweep: per-clip sums, so every resample is a weighted sum


class CellTable:
    """Per clip and cell: rows, correct predictions (seed mean) and vacuity sum (seed mean) of one domain."""

    def __init__(self, y: np.ndarray, clip: np.ndarray, cells: list[str]):
        self.clips, inv = np.unique(clip, return_inverse=True)
        self.inv = inv
        self.cls = np.array([int(y[np.flatnonzero(inv == i)[0]]) for i in range(self.clips.size)])
        self.n = np.bincount(inv, minlength=self.clips.size).astype(np.float64)
        self.cells = list(cells)
        self.correct = {h: np.zeros((self.clips.size, len(cells))) for h in ("softmax", "evidential")}
        self.vacuity = np.zeros((self.clips.size, len(cells)))

    def add(self, head: str, cell: str, correct: np.ndarray, vac: np.ndarray | None, n_seeds: int) -> None:
        j = self.cells.index(cell)
        self.correct[head][:, j] += np.bincount(self.inv, weights=correct.astype(np.float64),
                                                minlength=self.clips.size) / n_seeds
        if vac is not None:
            self.vacuity[:, j] += np.bincount(self.inv, weights=vac, minlength=self.clips.size) / n_seeds

    def weights(self, rng: np.random.Generator, n_boot: int) -> np.ndarray:
        """(1 + n_boot, n_clips) multiplicities: row 0 the data itself, then stratified resamples."""
        w = np.zeros((n_boot + 1, self.clips.size))
        w[0] = 1.0
        groups = [np.flatnonzero(self.cls == k) for k in np.unique(self.cls)]
        for b in range(n_boot):
            for g in groups:
                np.add.at(w[b + 1], g[rng.integers(0, g.size, g.size)], 1.0)
        return w

    def balanced_accuracy(self, w: np.ndarray, head: str) -> np.ndarray:
        """(1 + n_boot, cells) balanced accuracy."""
        parts = []
        for k in np.unique(self.cls):
            m = self.cls == k
            parts.append((w[:, m] @ self.correct[head][m]) / (w[:, m] @ self.n[m])[:, None])
        return np.mean(parts, axis=0)

    def mean_vacuity(self, w: np.ndarray) -> np.ndarray:
        return (w @ self.vacuity) / (w @ self.n)[:, None]


def sweep_effects(table: CellTable, clean: str, w: np.ndarray) -> dict[str, dict[str, np.ndarray]]:
    """Per head: accuracy drop in points (clean - cell) and, evidential, vacuity change (cell - clean);
    arrays (1 + n_boot, cells)."""
    j = table.cells.index(clean)
    out: dict[str, dict[str, np.ndarray]] = {}
    for head in ("softmax", "evidential"):
        acc = table.balanced_accuracy(w, head)
        out[head] = {"drop_points": 100.0 * (acc[:, [j]] - acc)}
    vac = table.mean_vacuity(w)
    out["evidential"]["vacuity_change"] = vac - vac[:, [j]]
    return out


def agreement(real: dict[str, np.ndarray], synthetic: dict[str, np.ndarray], cells: list[str],
              labels: dict[str, str]) -> dict[str, Any]:
    """Sweep agreement over the degraded cells: Spearman of the drops, median |drop_real - drop_synth|
    (points), fraction of cells whose vacuity change has the same sign; 95 % intervals from the
    paired rows of independent real and synthetic resamples (row 0 = the data). Cells whose
    drop difference interval excludes 0 are listed as disagreeing."""
    from scipy.stats import spearmanr

    dr, ds = real["drop_points"], synthetic["drop_points"]
    vr, vs = real.get("vacuity_change"), synthetic.get("vacuity_change")
    n = min(dr.shape[0], ds.shape[0])
    rho = np.array([spearmanr(dr[b], ds[b]).statistic if np.ptp(dr[b]) > 0 and np.ptp(ds[b]) > 0 else np.nan
                    for b in range(n)])
    med = np.median(np.abs(dr[:n] - ds[:n]), axis=1)
    out: dict[str, Any] = {"n_cells": len(cells), "spearman": interval(float(rho[0]), rho[1:]),
                           "median_abs_drop_difference_points": interval(float(med[0]), med[1:])}
    if vr is not None and vs is not None:
        same = np.mean(np.sign(vr[:n]) == np.sign(vs[:n]), axis=1)
        out["vacuity_same_sign_fraction"] = interval(float(same[0]), same[1:])
    cells_out = []
    for j, cell in enumerate(cells):
        d = difference(float(dr[0, j] - ds[0, j]), dr[1:n, j] - ds[1:n, j])
        row = {"cell": cell, "label": labels.get(cell, cell), "drop_real": interval(float(dr[0, j]), dr[1:, j]),
               "drop_synthetic": interval(float(ds[0, j]), ds[1:, j]), "drop_difference": d,
               "disagree": bool(np.isfinite(d["ci_low"]) and (d["ci_low"] > 0 or d["ci_high"] < 0))}
        if vr is not None and vs is not None:
            row["vacuity_change_real"] = interval(float(vr[0, j]), vr[1:, j])
            row["vacuity_change_synthetic"] = interval(float(vs[0, j]), vs[1:, j])
        cells_out.append(row)
    out["cells"] = cells_out
    out["disagreeing_cells"] = [r["label"] for r in cells_out if r["disagree"]]
    return out


def inert(effects: dict[str, np.ndarray], cells: list[str], top: dict[str, str]) -> list[str]:
    """Degradations (keys of ``top``: degradation -> its highest-severity cell) whose top-severity
    accuracy drop and vacuity change both have a 95 % interval containing 0 (no measurable effect)."""
    out = []
    for deg, cell in top.items():
        j = cells.index(cell)
        zero = []
        for key in ("drop_points", "vacuity_change"):
            if key in effects:
                r = interval(float(effects[key][0, j]), effects[key][1:, j])
                zero.append(r["ci_low"] <= 0.0 <= r["ci_high"])
        if zero and all(zero):
            out.append(deg)
    return out
