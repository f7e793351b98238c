"""Known answers of the pseudo-triplet conflict study (`harness.experiments.realbench.conflict`): the
coarsening of a K-class Dirichlet opinion to {not drone, drone}, per-clip aggregation, triplet and
twin draws, a twin swap under each fusion rule, and the inert flag. No model is trained."""
from __future__ import annotations

import numpy as np
import pytest

from harness.experiments.realbench import conflict as C


def test_coarsening_recovers_the_dirichlet_opinion_and_sums_to_one():
    alpha = np.array([[1.0, 1.0, 9.0, 1.0], [3.0, 2.0, 1.0, 1.0]])      # drone = index 2
    s = alpha.sum(1)
    op = C.binary_opinion(alpha / s[:, None], 4.0 / s, drone_index=2)
    # row 0: S 12, u 1/3, b = (0, 0, 8/12, 0); row 1: S 7, u 4/7, b = (2/7, 1/7, 0, 0)
    assert op[0] == pytest.approx([0.0, 2 / 3, 1 / 3])
    assert op[1] == pytest.approx([3 / 7, 0.0, 4 / 7])
    assert op.sum(1) == pytest.approx([1.0, 1.0])
    assert C.to_alpha(op[0]) == pytest.approx([1.0, 5.0])                 # S = 2 / u = 6, alpha = 6 b + 1
    assert C.votes(op).tolist() == [1, 0]
    with pytest.raises(ValueError):
        C.binary_opinion(alpha / s[:, None], 4.0 / s, drone_index=4)


def test_clip_opinion_is_the_mean_over_rows_and_seeds():
    p = np.array([[0.1, 0.9], [0.3, 0.7], [0.8, 0.2]])
    preds = {("a_real", "evidential", 0): {"real": {"clean": (p, np.array([0.2, 0.4, 0.2]))}},
             ("a_real", "evidential", 1): {"real": {"clean": (p, np.array([0.2, 0.2, 0.4]))}},
             ("a_real", "softmax", 0): {"real": {"clean": (p, None)}}}
    t = C.clip_opinions(preds, {"real": np.array(["x", "x", "y"])}, {"x": "DRONE", "y": "BIRD"}, 1, [0, 1])["real"]
    assert t["clip"].tolist() == ["x", "y"] and t["cls"].tolist() == ["DRONE", "BIRD"]
    assert list(t["opinion"]) == ["a_real"]                                  # evidential head only
    # clip x, b = p - u/2: seed 0 rows (0, .8, .2), (.1, .5, .4); seed 1 rows (0, .8, .2), (.2, .6, .2)
    assert t["opinion"]["a_real"][0] == pytest.approx([0.075, 0.675, 0.25])
    assert t["opinion"]["a_real"].sum(1) == pytest.approx([1.0, 1.0])


DRONE = (0.05, 0.85, 0.10)
NOT = (0.85, 0.05, 0.10)


def test_swapping_one_of_three_confident_sensors_keeps_the_majority():
    ops = np.array([[DRONE], [DRONE], [DRONE]])
    rows = C.program_rows(ops, 2, np.array([NOT]), np.array([1]), c_max=0.95)
    assert rows["sensor_flip"].tolist() == [1.0]
    for r in C.RULES:                                  # DS, gated DS, discounted, average: still drone
        assert rows[f"{r}/flip"].tolist() == [0.0], r
        assert rows[f"{r}/correct"].tolist() == [1.0] and rows[f"{r}/correct_clean"].tolist() == [1.0], r
    # DS of the two agreeing sensors: C 0.085, b = (0.0125, 0.8925, 0.01) / 0.915; with the twin:
    # C = 0.97541 * 0.85 + 0.013661 * 0.05 = 0.82978 (< c_max: no fallback)
    assert rows["ds_conflict"][0] == pytest.approx(0.82978, abs=1e-4)
    assert rows["ds_conflict_clean"][0] == pytest.approx(2 * 0.05 * 0.85, abs=1e-9)
    # average: p = (alpha / S) with alpha = 20 b + 1: drone 0.9, 0.9, 0.1 -> 0.633
    votes, _ = C.fuse(np.array([[DRONE], [DRONE], [NOT]]), c_max=0.95)
    assert votes["average"].tolist() == [1]


def test_c_max_fallback_follows_the_first_most_certain_sensor():
    ops = np.array([[DRONE], [DRONE], [DRONE]])
    # C 0.83 > c_max 0.5: every sensor has u = 0.1, the first (the swapped one) is taken
    rows = C.program_rows(ops, 0, np.array([NOT]), np.array([1]), c_max=0.5)
    assert rows["ds/flip"].tolist() == [0.0] and rows["ds_c_max/flip"].tolist() == [1.0]
    assert rows["ds_c_max/correct"].tolist() == [0.0]


def test_a_twin_with_the_same_vote_is_flagged_inert():
    ops = np.array([[DRONE, NOT], [DRONE, NOT], [DRONE, NOT]])
    label = np.array([1, 0])
    twin_same_vote = np.array([(0.2, 0.6, 0.2), (0.6, 0.2, 0.2)])          # model wrong on both twins
    rows = C.program_rows(ops, 1, twin_same_vote, label, c_max=0.95)
    w = C.bootstrap_weights(label, np.random.default_rng(0), 30)
    flip = C.means(rows["sensor_flip"], w)
    assert flip[0] == 0.0
    assert C.is_inert({"estimate": float(flip[0]), "ci_low": 0.0, "ci_high": 0.0})
    assert C.is_inert({"estimate": 0.05, "ci_low": 0.01, "ci_high": 0.1})      # below 0.1
    assert C.is_inert({"estimate": 0.3, "ci_low": 0.0, "ci_high": 0.6})        # interval reaches 0
    assert not C.is_inert({"estimate": 0.5, "ci_low": 0.4, "ci_high": 0.6})
    assert not C.is_inert({"estimate": 1.0, "ci_low": 1.0, "ci_high": 1.0})


def _tables(rng: np.random.Generator) -> dict[str, dict[str, dict]]:
    """Per sensor and domain, clip tables whose model is right with confidence (audio: 3 classes)."""
    def table(names: list[str], classes: list[str]) -> dict:
        cls = np.array(classes)
        op = np.where((cls == "DRONE")[:, None], DRONE, NOT) + rng.uniform(-0.01, 0.01, (len(cls), 1)) * [1, -1, 0]
        return {"clip": np.array(names), "cls": cls, "opinion": {c: op for c in ("a_real", "b_synthetic", "c_both")}}

    vis_cls = ["AIRPLANE", "BIRD", "DRONE", "HELICOPTER"]
    out: dict[str, dict[str, dict]] = {}
    for s, tag in (("ir", "IR"), ("visible", "V")):
        real = sorted((f"{tag}_{c}_{n:03d}", c) for c in vis_cls for n in (2, 4))
        syn = sorted((f"{c}/seq{n:06d}", c) for c in vis_cls for n in (2, 4, 6))
        out[s] = {"real": table(*map(list, zip(*real))), "synthetic": table(*map(list, zip(*syn)))}
    aud = sorted((f"{c}_{n:03d}", c) for c in ("BACKGROUND", "DRONE", "HELICOPTER") for n in (2, 4))
    out["audio"] = {d: table(*map(list, zip(*aud))) for d in ("real", "synthetic")}
    return out


def test_triplets_are_class_matched_balanced_and_synthetic_ones_synchronised():
    tabs = _tables(np.random.default_rng(0))
    for domain, sync in (("real", False), ("synthetic", True)):
        t = {s: tabs[s][domain] for s in C.SENSORS}
        trip = C.draw_triplets(t, 41, sync, np.random.default_rng(1))
        assert trip["n"] == 41 and trip["label"].sum() == 20
        assert (trip["label"] == (trip["cls"] == "DRONE")).all()
        for s in ("ir", "visible"):
            assert (t[s]["cls"][trip["index"][s]] == trip["cls"]).all()
        audio = t["audio"]["cls"][trip["index"]["audio"]]
        assert (audio == [C.AUDIO_CLASS[c] for c in trip["cls"]]).all()
        assert set(audio[trip["cls"] == "BIRD"]) == {"BACKGROUND"}
        same = t["ir"]["clip"][trip["index"]["ir"]] == t["visible"]["clip"][trip["index"]["visible"]]
        assert same.all() if sync else not same.all()
        again = C.draw_triplets(t, 41, sync, np.random.default_rng(1))
        assert all((again["index"][s] == trip["index"][s]).all() for s in C.SENSORS)
        twins = C.draw_twins(t["audio"], trip["label"], np.random.default_rng(2))
        assert ((t["audio"]["cls"][twins] == "DRONE") != (trip["label"] == 1)).all()
    no_drone = {s: {k: (v[tabs[s]["real"]["cls"] != "DRONE"] if k != "opinion" else v)
                    for k, v in tabs[s]["real"].items()} for s in C.SENSORS}
    assert C.draw_triplets(no_drone, 10, False, np.random.default_rng(1))["n"] == 0


def test_run_conflict_reports_every_program_rule_and_the_domain_difference():
    res = C.run_conflict(_tables(np.random.default_rng(0)), seed=3, n_triplets=30, n_boot=40, c_max=0.95)
    assert res["programs"] == ["blind_ir", "blind_visible", "blind_audio"] and res["note"] == C.NOT_SYNCHRONISED
    for reading in ("own_domain", "mixed"):
        out = res["readings"][reading]
        for domain in C.DOMAINS:
            d = out[domain]
            assert d["n_triplets"] == 30
            assert d["clean"]["accuracy"]["ds"]["estimate"] == 1.0
            for name in res["programs"]:
                p = d["programs"][name]
                assert p["sensor_flip_rate"]["estimate"] == 1.0 and not p["inert"]     # every twin flips the vote
                assert set(p["rules"]) == set(C.RULES)
                assert p["rules"]["ds"]["fused_flip_rate"]["estimate"] == 0.0          # two of three still agree
        diff = out["real_minus_synthetic_fused_flip_rate"]
        assert set(diff) == set(res["programs"]) and set(diff["blind_ir"]) == set(C.RULES)
        assert "mde" in diff["blind_ir"]["ds"]
    assert any("blind_audio" in line for line in C.format_lines(res))
    only_ir = C.run_conflict({"ir": _tables(np.random.default_rng(0))["ir"]}, seed=3, n_triplets=10, n_boot=5,
                             c_max=0.95)
    assert only_ir["status"].startswith("not run")
