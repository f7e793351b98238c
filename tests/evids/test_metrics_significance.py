"""Sign-flip permutation test: exact p on a hand case, calibrated type-I error at the demo's cluster
count (null simulation), MDE formula; log-domain entropies keep saturated predictions apart;
temperature fits at a bound are flagged."""
from __future__ import annotations

import numpy as np
import pytest

from evids.metrics import (
    entropy_from_log_probs,
    fit_temperature_flagged,
    minimum_detectable_difference,
    null_rejection_rate,
    paired_permutation_test,
    uauc,
)


def test_exact_sign_flip_p_value_by_hand():
    # 3 clusters with differences +1, +1, +1: of the 8 sign patterns only +++ and --- reach |mean| = 1
    a = np.array([1, 1, 1, 1, 1, 1], float)
    b = np.zeros(6)
    r = paired_permutation_test(a, b, ["x", "x", "y", "y", "z", "z"], np.random.default_rng(0))
    assert r.exact and r.n_permutations == 8 and r.p_value == pytest.approx(2 / 8) and r.estimate == 1.0
    # rows are averaged within a cluster first: a 10-row cluster counts once
    r2 = paired_permutation_test(np.r_[np.ones(10), 0, 0], np.r_[np.zeros(10), 1, 1], ["x"] * 10 + ["y", "z"],
                                 np.random.default_rng(0))
    assert r2.estimate == pytest.approx((1 - 1 - 1) / 3)


def test_mde_formula():
    # t quantiles, 32 df: t_0.975 = 2.036933, t_0.8 = 0.852998
    assert minimum_detectable_difference(0.2, 33) == pytest.approx((2.036933 + 0.852998) * 0.2 / np.sqrt(33), rel=1e-5)
    assert minimum_detectable_difference(0.2, 10000) == pytest.approx(2.8016 * 0.2 / 100, rel=1e-3)
    assert np.isnan(minimum_detectable_difference(0.2, 1))


def test_null_rejection_rate_is_calibrated_at_33_clusters():
    rate = null_rejection_rate(33, 2000, np.random.default_rng(np.random.SeedSequence([20261201, 33])),
                               n_permutations=999, segments_per_cluster=40, accuracy=0.8, icc=0.97)
    assert 0.035 <= rate <= 0.065, rate


def test_permutation_rejects_a_real_difference():
    rng = np.random.default_rng(1)
    clusters = np.repeat(np.arange(33), 40)
    a = (rng.random(33 * 40) < 0.9).astype(float)
    b = (rng.random(33 * 40) < 0.6).astype(float)
    assert paired_permutation_test(a, b, clusters, rng, 2000).p_value < 0.01


def test_log_domain_entropy_keeps_saturated_predictions_apart():
    z = np.array([40.0, 60.0, 80.0])                    # sigmoid(z) == 1.0 exactly in float64
    lp = np.stack([-np.logaddexp(0, z), -np.logaddexp(0, -z)], 1)
    assert (np.exp(lp[:, 1]) == 1.0).all()
    h = entropy_from_log_probs(lp)
    assert h[0] > h[1] > h[2] > 0
    assert uauc(h, np.array([True, False, False])) == 1.0         # no ties: the error ranks first
    naive = -(np.clip(np.exp(lp), 1e-12, 1) * np.log(np.clip(np.exp(lp), 1e-12, 1))).sum(1)
    assert naive[1] == naive[2]                                    # what the old clip-based entropy did


def test_temperature_at_a_bound_is_flagged():
    z = np.array([5.0, -5.0] * 20)
    y = np.array([1, 0] * 20)                      # perfectly separable: NLL falls as T -> 0
    t, flag = fit_temperature_flagged(z, y, 0.05, 20.0)
    assert flag == "lower" and t == pytest.approx(0.05, rel=0.02)
    rng = np.random.default_rng(0)
    z2 = rng.normal(0, 1, 400)
    y2 = (rng.random(400) < 1 / (1 + np.exp(-z2))).astype(int)
    t2, flag2 = fit_temperature_flagged(z2, y2, 0.05, 20.0)
    assert flag2 is None and 0.6 < t2 < 1.6


# ---- the one verdict rule (known answers) ----------------------------------------------------

from evids.metrics.significance import comparison_verdict, separating_digits, verdict_sentence  # noqa: E402


@pytest.mark.parametrize("effect, lo, hi, mde, expected", [
    (0.05, 0.02, 0.08, 0.04, "A beats B"),         # CI excludes 0, |effect| >= MDE
    (-0.05, -0.08, -0.02, 0.04, "B beats A"),
    (0.044, 0.005, 0.083, 0.060, "undecided"),      # the EDL+average vs Late Fusion: +4.4 < MDE 6.0
    # the DS vs average, all noisy: CI excludes 0, not inside +-MDE
    (0.014, 0.0003, 0.0273, 0.02, "undecided"),
    (0.014, 0.0003, 0.0273, 0.03, "no difference"),  # the same CI inside +-3 pp: practically equivalent
    (0.01, -0.01, 0.03, 0.05, "no difference"),     # CI covers 0 and lies inside +-MDE
    (0.01, -0.06, 0.08, 0.05, "undecided"),         # CI covers 0 but reaches past the MDE
    (0.04, 0.01, 0.07, 0.04, "A beats B"),          # |effect| == MDE counts
    (0.0, -0.05, 0.05, 0.05, "no difference"),      # CI exactly on +-MDE counts as inside
    (None, 0.0, 0.1, 0.05, "undecided"),
    (0.05, 0.02, 0.08, float("nan"), "undecided"),
])
def test_comparison_verdict_known_answers(effect, lo, hi, mde, expected):
    assert comparison_verdict(effect, lo, hi, mde) == expected


def test_verdict_sentence_names_the_winner():
    assert verdict_sentence("A beats B", "DS", "averaging") == "DS beats averaging"
    assert verdict_sentence("B beats A", "DS", "averaging") == "averaging beats DS"
    assert verdict_sentence("no difference", "DS", "averaging") == "no difference between DS and averaging"
    assert verdict_sentence("undecided", "DS", "averaging") == "DS vs averaging: undecided"


def test_separating_digits_prints_what_the_label_saw():
    assert separating_digits(50.004, 50.0, digits=2) == "50.004"   # the "50.00" drone-signal row
    assert separating_digits(50.0, 50.0, digits=2) == "50.00"
    assert separating_digits(0.4999, 0.5) == "0.4999"
    assert separating_digits(0.61234, 0.5) == "0.612"
