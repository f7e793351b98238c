"""Clip-level significance and power for paired comparisons on clustered data.

With segments of one clip (or scene) nearly perfectly correlated, the independent unit is the
cluster. :func:`paired_permutation_test` compares two systems on per-cluster mean differences with
a sign-flip permutation test (exact under the null when differences are symmetric about 0: it
enumerates all 2^n sign patterns when that is at most ``n_permutations``, else draws them);
:func:`minimum_detectable_difference` is the paired-t approximation ``(t_{1-a/2} + t_power) s / sqrt(n)``
(about 2.8 s / sqrt(n) at two-sided alpha 0.05 and 80 % power; t quantiles with n - 1 df).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import stats

from evids.metrics._arrays import as_numpy


@dataclass(frozen=True)
class PermutationResult:
    """Mean per-cluster difference, two-sided p-value, MDE and the counts behind them."""

    estimate: float
    p_value: float
    mde: float
    sd: float
    n_clusters: int
    n_permutations: int
    exact: bool


def cluster_means(values: Any, clusters: Any) -> tuple[np.ndarray, np.ndarray]:
    """(cluster keys, mean of ``values`` per cluster) in sorted key order."""
    v = as_numpy(values, "values").astype(np.float64).ravel()
    c = np.asarray(clusters).ravel()
    if c.shape[0] != v.shape[0]:
        raise ValueError(f"clusters must have {v.shape[0]} entries, got {c.shape[0]}")
    keys, inv = np.unique(c.astype(str), return_inverse=True)
    sums = np.bincount(inv, weights=v, minlength=keys.size)
    counts = np.bincount(inv, minlength=keys.size)
    return keys, sums / counts


def minimum_detectable_difference(sd: float, n: int, alpha: float = 0.05, power: float = 0.8) -> float:
    """Smallest true mean paired difference detected with ``power`` at two-sided ``alpha``:
    ``(t_{n-1,1-a/2} + t_{n-1,power}) sd / sqrt(n)`` (about 2.8 sd / sqrt(n) for large n; the t
    quantiles keep it honest at a handful of clusters)."""
    if n < 2 or not np.isfinite(sd):
        return float("nan")
    df = n - 1
    return float((stats.t.ppf(1 - alpha / 2, df) + stats.t.ppf(power, df)) * sd / np.sqrt(n))


def sign_flip_p_value(d: np.ndarray, rng: np.random.Generator, n_permutations: int = 10000) -> tuple[float, bool, int]:
    """Two-sided sign-flip p-value of mean(d) = 0 over per-cluster differences ``d``."""
    d = np.asarray(d, np.float64)
    n = d.size
    observed = abs(d.mean())
    tol = 1e-12 * max(1.0, float(np.abs(d).max(initial=0.0)))
    if n <= 20 and 2 ** n <= n_permutations:
        signs = ((np.arange(2 ** n)[:, None] >> np.arange(n)) & 1) * 2 - 1
        means = np.abs(signs @ d) / n
        return float(np.mean(means >= observed - tol)), True, int(2 ** n)
    signs = rng.integers(0, 2, size=(n_permutations, n), dtype=np.int8) * 2 - 1
    means = np.abs(signs @ d) / n
    return float((1 + np.sum(means >= observed - tol)) / (n_permutations + 1)), False, int(n_permutations)


def paired_permutation_test(correct_a: Any, correct_b: Any, clusters: Any, rng: np.random.Generator,
                            n_permutations: int = 10000, alpha: float = 0.05, power: float = 0.8) -> PermutationResult:
    """Paired test of accuracy A - B: per-cluster mean of (correct_a - correct_b), sign flips.

    ``correct_*`` are per-row 0/1 (or any per-row score); rows of a cluster are averaged first, so
    each cluster counts once however many segments it has.
    """
    a = as_numpy(correct_a, "correct_a").astype(np.float64).ravel()
    b = as_numpy(correct_b, "correct_b").astype(np.float64).ravel()
    if a.shape != b.shape:
        raise ValueError(f"correct_a and correct_b must have the same shape, got {a.shape} and {b.shape}")
    _, d = cluster_means(a - b, clusters)
    n = d.size
    if n < 2:
        return PermutationResult(float(d.mean()) if n else float("nan"), float("nan"), float("nan"),
                                 float("nan"), n, 0, False)
    sd = float(d.std(ddof=1))
    p, exact, k = sign_flip_p_value(d, rng, n_permutations)
    return PermutationResult(float(d.mean()), p, minimum_detectable_difference(sd, n, alpha, power), sd, n, k, exact)


def null_rejection_rate(n_clusters: int, n_simulations: int, rng: np.random.Generator, alpha: float = 0.05,
                        n_permutations: int = 999, segments_per_cluster: int = 40,
                        accuracy: float = 0.8, icc: float = 0.97) -> float:
    """Fraction of simulated true-null paired comparisons the permutation test rejects at ``alpha``.

    Each cluster draws one latent correctness per system pair (with probability ``icc`` a segment
    copies the cluster's value, else an independent draw), systems A and B identically distributed,
    so every rejection is a type-I error.
    """
    rejections = 0
    for _ in range(n_simulations):
        rows = []
        for _system in range(2):
            base = rng.random(n_clusters) < accuracy
            copy = rng.random((n_clusters, segments_per_cluster)) < icc
            own = rng.random((n_clusters, segments_per_cluster)) < accuracy
            rows.append(np.where(copy, base[:, None], own).astype(np.float64))
        d = (rows[0] - rows[1]).mean(axis=1)
        if np.allclose(d, 0.0):
            continue
        p, _, _ = sign_flip_p_value(d, rng, n_permutations)
        rejections += p <= alpha
    return rejections / n_simulations


# ---- the one verdict rule for every comparison (docs/EXPERIMENTS.md, "Verdict rule") ----------

A_BEATS_B, B_BEATS_A, NO_DIFFERENCE, UNDECIDED = "A beats B", "B beats A", "no difference", "undecided"


def comparison_verdict(effect: float | None, ci_low: float | None, ci_high: float | None,
                       mde: float | None) -> str:
    """The verdict on a difference A - B with confidence interval [ci_low, ci_high] and minimum
    detectable effect ``mde`` (all in the same unit):

    - "A beats B" / "B beats A" only when the CI excludes zero and |effect| >= MDE;
    - "no difference" only when the CI lies inside [-MDE, +MDE];
    - "undecided" otherwise, and whenever a number is missing or not finite.
    """
    numbers = [float(v) for v in (effect, ci_low, ci_high, mde) if v is not None]
    if len(numbers) < 4 or not all(np.isfinite(v) for v in numbers):
        return UNDECIDED
    effect, ci_low, ci_high, mde = numbers
    if (ci_low > 0 or ci_high < 0) and abs(effect) >= mde:
        return A_BEATS_B if effect > 0 else B_BEATS_A
    if -mde <= ci_low and ci_high <= mde:
        return NO_DIFFERENCE
    return UNDECIDED


def verdict_sentence(verdict: str, a: str, b: str) -> str:
    """The verdict in words with the compared things named: "A beats B" -> "DS beats averaging"."""
    return {A_BEATS_B: f"{a} beats {b}", B_BEATS_A: f"{b} beats {a}",
            NO_DIFFERENCE: f"no difference between {a} and {b}"}.get(verdict, f"{a} vs {b}: undecided")


def separating_digits(value: float, reference: float, digits: int = 3, most: int = 8) -> str:
    """``value`` with at least ``digits`` decimals, more when fewer would print it equal to
    ``reference`` although it is not (50.004 vs 50 prints "50.004", not "50.00"): printed numbers
    then agree with the label computed from the unrounded ones."""
    for d in range(digits, most + 1):
        text = f"{value:.{d}f}"
        if value == reference or float(text) != reference:
            return text
    return f"{value:.{most}f}"
