"""Known answers for the E2 report's headline (the sentences that state the paper's answers), and
the comparison names it looks up: they must be names the harness writes."""
from harness.experiments.runner import COMPARISONS
from harness.report.html import headline


def _comp(name, delta, lo, hi, mde, p=0.004, n=12):
    return {"comparison": name, "delta_accuracy": delta, "ci_low": lo, "ci_high": hi, "p_permutation": p,
            "mde": mde, "n_clusters": n}


def test_headline_sentences_by_hand():
    ev = {"conditions": [{"key": "b", "accuracy": 0.80}, {"key": "d", "accuracy": 0.85},
                         {"key": "e", "accuracy": 0.86}, {"key": "g", "accuracy": 0.70},
                         {"key": "d_prime", "accuracy": 0.75}],
          "comparisons": [_comp("EDL + average (d) vs Late Fusion (b)", 0.05, 0.02, 0.08, 0.03),       # beats
                          _comp("DS (e) vs average (d), standard noise", 0.01, -0.01, 0.02, 0.03, p=0.3),  # inside
                          _comp("DS (g) vs average (d'), all modalities noisy", -0.05, -0.09, 0.01, 0.04)]}
    out = headline(ev, None, None)
    assert out == [
        "<b>EDL + average vs sigmoid Late Fusion (fitted on noisy validation outputs):</b> 85.00% vs 80.00% under "
        "the standard noise protocol: EDL + average beats Late Fusion; &Delta; = +5.00 pp, 95% CI [+2.00, +8.00] pp, "
        "permutation p = 0.004, MDE(80%) = 3.00 pp, 12 scenes.",
        "<b>DS vs averaging, no controlled conflict:</b> DS 86.00% vs average 85.00%: no difference between DS and "
        "averaging; &Delta; = +1.00 pp, 95% CI [-1.00, +2.00] pp, permutation p = 0.300, MDE(80%) = 3.00 pp, "
        "12 scenes.",
        "<b>All modalities noisy:</b> DS 70.00% vs average 75.00%: DS vs averaging: undecided; &Delta; = -5.00 pp, "
        "95% CI [-9.00, +1.00] pp, permutation p = 0.004, MDE(80%) = 4.00 pp, 12 scenes.",
    ]


def test_a_missing_comparison_is_said_not_invented():
    ev = {"conditions": [{"key": "b", "accuracy": 0.8}, {"key": "d", "accuracy": 0.9}], "comparisons": []}
    (line,) = headline(ev, None, None)
    assert line.endswith("EDL + average vs Late Fusion: no test available; (no test available).")


def test_every_comparison_the_report_reads_is_one_the_harness_writes():
    # the report finds comparisons by their name: a rename on one side only would silently drop an answer
    read = {"EDL + average (d) vs Late Fusion (b)", "EDL + average (d) vs clean-fitted Late Fusion (control)",
            "DS (e) vs average (d), standard noise", "DS (g) vs average (d'), all modalities noisy",
            "DS + gating (f) vs DS (e)", *(f"objective: EDL vs sigmoid head, {m}" for m in ("audio", "video", "rf"))}
    assert read <= {name for _, _, name in COMPARISONS}
    import inspect

    import harness.report.html as H

    src = inspect.getsource(H)
    assert all(n in src for n in read if "objective" not in n) and "objective: EDL vs sigmoid head, {m}" in src
