"""Known answers for the E2 report's headline (the sentences that state the paper's answers), and
the comparison ids it looks up: they must be ids the harness writes."""
import re

import pytest

from harness.experiments.runner import COMPARISONS, comparison_id
from harness.report.html import headline


def _comp(name, delta, lo, hi, mde, p=0.004, n=12, id=None):
    row = {"comparison": name, "delta_accuracy": delta, "ci_low": lo, "ci_high": hi, "p_permutation": p,
           "mde": mde, "n_clusters": n}
    return row if id is None else {**row, "id": id}


@pytest.mark.parametrize("with_ids", [True, False], ids=["ids", "run folder from before the ids"])
def test_headline_sentences_by_hand(with_ids):
    ids = ("d vs b", "e vs d", "g vs d_prime") if with_ids else (None, None, None)
    names = ("renamed 1", "renamed 2", "renamed 3") if with_ids else (
        "EDL + average (d) vs Late Fusion (b)", "DS (e) vs average (d), standard noise",
        "DS (g) vs average (d'), all modalities noisy")
    ev = {"conditions": [{"key": "b", "accuracy": 0.80}, {"key": "d", "accuracy": 0.85},
                         {"key": "e", "accuracy": 0.86}, {"key": "g", "accuracy": 0.70},
                         {"key": "d_prime", "accuracy": 0.75}],
          "comparisons": [_comp(names[0], 0.05, 0.02, 0.08, 0.03, id=ids[0]),            # beats
                          _comp(names[1], 0.01, -0.01, 0.02, 0.03, p=0.3, id=ids[1]),    # inside
                          _comp(names[2], -0.05, -0.09, 0.01, 0.04, id=ids[2])]}
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
    # the report finds comparisons by id: an id the harness does not write would silently drop an answer
    import inspect

    import harness.report.html as H

    src = inspect.getsource(H.headline)
    read = set(re.findall(r'(?:name|n2) = "([^"]+)"', src)) | {f"a_edl_{m} vs a_{m}" for m in ("audio", "video", "rf")}
    assert len(read) == 8 and "a_edl_{m} vs a_{m}" in src
    written = {comparison_id(a, b) for a, b, _ in COMPARISONS}
    assert read <= written, read - written
    assert set(H._IDS_OF_OLD_NAMES) <= {name for _, _, name in COMPARISONS}
    assert set(H._IDS_OF_OLD_NAMES.values()) == read
