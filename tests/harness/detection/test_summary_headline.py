"""Known answers for the code that decides the detection experiment's answers: summarise() on
hand-built per-sequence rows and headline() on a hand-built summary (numbers worked out by hand)."""
import math

import numpy as np
import pytest

from harness.experiments.detection.config import TINY_CONFIG, load_detection_config
from harness.experiments.detection.summary import headline, summarise


def _cfg(conditions):
    return load_detection_config({**TINY_CONFIG, "conditions": conditions})


def _seq(set_name, seq, key, acc, blind=float("nan")):
    return {"set": set_name, "sequence": seq, "key": key, "state_acc": acc, "state_acc_penalised": acc - 0.1,
            "acc_thermal_blind": blind, "acc_rgb_blind": float("nan"), "trk_on_abs": 0.0, "absent_frames": 0,
            "handovers": 0, "tracker_share": 0.5}


def test_summarise_table_means_and_the_paired_comparison_by_hand():
    cfg = _cfg(["d_average", "e_ds"])
    ds = [0.9, 0.8, 0.7]             # e_ds per sequence
    av = [0.8, 0.6, 0.4]             # d_average: differences 0.1, 0.2, 0.3
    per_seq = ([_seq("crossover", f"s{k}", "e_ds/fused", a) for k, a in enumerate(ds)]
               + [_seq("crossover", f"s{k}", "d_average/fused", a) for k, a in enumerate(av)])
    s = summarise(cfg, per_seq, [], [], [], {"crossover|e_ds/fused": 0.5}, {}, {}, None)
    rows = {(r["set"], r["key"]): r for r in s["table"]}
    assert rows[("crossover", "e_ds/fused")]["state_acc"] == pytest.approx(0.8)
    assert rows[("all", "d_average/fused")]["state_acc_penalised"] == pytest.approx(0.5)
    assert rows[("crossover", "e_ds/fused")]["ap50"] == 0.5 and "ap50" not in rows[("all", "e_ds/fused")]
    assert math.isnan(rows[("crossover", "d_average/fused")]["ap50"])
    comps = [c for c in s["comparisons"] if c["a"] == "e_ds/fused" and c["b"] == "d_average/fused"]
    assert [(c["set"], c["metric"]) for c in comps] == [("crossover", "state_acc"), ("crossover", "acc_thermal_blind"),
                                                        ("all", "state_acc"), ("all", "acc_thermal_blind")]
    blind = comps[1]                                      # every thermal-blind value is NaN: nothing to compare
    assert blind["n"] == 0 and math.isnan(blind["diff"]) and math.isnan(blind["mde"])
    c = comps[0]
    assert c["diff"] == pytest.approx(0.2) and c["n"] == 3
    assert c["p"] == pytest.approx(2 / 8)                 # exact sign-flip: only all-plus and all-minus reach 0.2
    assert c["mde"] == pytest.approx(2.8 * 0.1 / np.sqrt(3))
    assert c["ci_low"] <= 0.2 <= c["ci_high"]
    assert s["conditions"] == {"d_average": "(d) evidential + decision-level average of the two streams",
                               "e_ds": "(e) evidential + Dempster-Shafer fusion of the two streams"}
    # fewer than two common sequences: no comparison at all
    few = summarise(cfg, per_seq[:1] + per_seq[3:4], [], [], [], {}, {}, {}, None)
    assert few["comparisons"] == []


def _comp(set_name, a, b, diff, lo, hi, mde, metric="state_acc", p=0.01, n=8):
    return {"set": set_name, "a": a, "b": b, "metric": metric, "diff": diff, "ci_low": lo, "ci_high": hi,
            "p": p, "n": n, "mde": mde}


def test_headline_answers_by_hand():
    cfg = _cfg(["b_evidential", "d_average", "e_ds", "f_ds_gated", "g_feature_fusion"])
    summary = {
        "comparisons": [
            _comp("crossover", "e_ds/fused", "d_average/fused", 0.10, 0.05, 0.15, 0.04),     # beats: CI > 0, >= MDE
            _comp("crossover", "e_ds/fused", "g_feature_fusion/fused", -0.01, -0.02, 0.01, 0.05),  # inside +-MDE
            _comp("crossover", "e_ds/fused", "d_average/fused", 0.02, -0.01, 0.05, 0.03, "acc_thermal_blind"),
            _comp("all", "f_ds_gated/fused", "e_ds/fused", -0.05, -0.08, -0.02, 0.03, p=0.004, n=12),
        ],
        "vacuity_vs_contrast": {"spearman_u": {"rho": -0.5, "ci_low": -0.7, "ci_high": -0.3, "n": 40,
                                               "n_clusters": 4}},
        "uncertainty": [
            {"level": "anchor", "key": "b_evidential/rgb", "score": "vacuity", "stratum": "all", "uauc": 0.4,
             "ci_low": 0.35, "ci_high": 0.45, "n": 100, "n_error": 30},
            {"level": "crop", "key": "b_evidential/rgb", "score": "crop_u", "stratum": "all", "uauc": 0.6,
             "ci_low": 0.55, "ci_high": 0.65, "n": 50, "n_error": 10},
        ],
        "gate_timing": {"full_s_per_frame": 0.010, "gated_s_per_frame": 0.006, "saving": 0.4,
                        "evaluated_fraction": 0.55, "loadavg_1m": 2.0},
    }
    h = headline(summary, cfg)
    assert h["q1_ds_through_crossover"] == (
        "State accuracy on the 'crossover' set. "
        "DS - average = +10.00 pp (sequence-bootstrap 95% CI [+5.00, +15.00], sign-flip p = 0.010, n = 8 sequences, "
        "MDE 4.00 pp): DS beats average. "
        "DS - feature fusion = -1.00 pp (sequence-bootstrap 95% CI [-2.00, +1.00], sign-flip p = 0.010, "
        "n = 8 sequences, MDE 5.00 pp): no difference between DS and feature fusion. "
        "On thermal-blind frames only: DS - average = +2.00 pp (sequence-bootstrap 95% CI [-1.00, +5.00], "
        "sign-flip p = 0.010, n = 8 sequences, MDE 3.00 pp): DS vs average: undecided.")
    assert h["q2_thermal_vacuity_vs_dT"].endswith("over 40 frames / 4 sequences: vacuity rises as |dT| falls "
                                                  "toward the NETD.")
    q3 = h["q3_anchor_inversion_crop_recovery"]
    assert q3.startswith("rgb: anchor-level vacuity UAUC 0.400 [0.350, 0.450] (n = 100, 30 errors) (inverted); "
                         "crop-level 0.600 [0.550, 0.650] (n = 50, 10 errors) (recovered (CI above 0.5)).")
    assert q3.endswith("thermal: anchor-level vacuity UAUC not estimable (one class missing) (no inversion "
                       "established); crop-level not estimable (one class missing) (not recovered (CI includes or "
                       "is below 0.5)).")
    assert h["q4_gating_saves_cpu"] == (
        "Batch-1 CPU time per frame: 10.0 ms without the gate, 6.0 ms with it (saving 40.0 %, 55.0 % of stream "
        "forwards run; load average 2.0). Accuracy cost: gated - ungated = -5.00 pp (sequence-bootstrap 95% CI "
        "[-8.00, -2.00], sign-flip p = 0.004, n = 12 sequences, MDE 3.00 pp): ungated beats gated.")


def test_headline_without_the_measurements_says_so():
    h = headline({"comparisons": [], "uncertainty": []}, _cfg(["a_sigmoid"]))
    assert h["q1_ds_through_crossover"].endswith("not measured not measured On thermal-blind frames only: "
                                                 "not measured")
    assert h["q2_thermal_vacuity_vs_dT"] == "not measured (no evidential thermal condition)"
    assert h["q4_gating_saves_cpu"] == "not measured (condition f not run)"
    # vacuity that falls as |dT| falls (CI above 0) is reported as not rising
    h = headline({"comparisons": [], "uncertainty": [], "vacuity_vs_contrast": {"spearman_u": {
        "rho": 0.4, "ci_low": 0.2, "ci_high": 0.6, "n": 10}}}, _cfg(["a_sigmoid"]))
    assert h["q2_thermal_vacuity_vs_dT"].endswith("10 frames / ? sequences: vacuity does not rise as |dT| falls "
                                                  "(the CI does not lie below 0).")
