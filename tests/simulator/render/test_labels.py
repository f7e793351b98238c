"""pad_labels: annotator-style margins around the exact label boxes (scene field label_margin_px)."""
import pytest

from scenes.schema import Scenario
from simulator.render.labels import pad_labels


def _rec(box: list[int]) -> dict:
    return {"id": 1, "exist": int(bool(box)), "box": box, "truncated": False}


def test_margin_grows_the_box_and_keeps_the_exact_one():
    (rec,) = pad_labels([_rec([100, 50, 4, 2])], (6, 5), 320, 256)
    assert rec["box"] == [94, 45, 16, 12]
    assert rec["box_tight"] == [100, 50, 4, 2]


def test_margin_is_clipped_to_the_frame():
    (rec,) = pad_labels([_rec([2, 250, 4, 6])], (6, 5), 320, 256)
    assert rec["box"] == [0, 245, 12, 11]


def test_absent_target_and_zero_margin():
    (rec,) = pad_labels([_rec([])], (6, 5), 320, 256)
    assert rec["box"] == [] and rec["box_tight"] == []
    records = [_rec([1, 2, 3, 4])]
    assert pad_labels(records, (0, 0), 320, 256) is records          # default: labels untouched


def test_negative_margin_is_refused_naming_the_field():
    data = {"name": "m", "targets": [{"name": "d", "kind": "quadcopter", "size_m": 0.4,
                                      "trajectory": {"kind": "hover", "center_m": [0, 50, 10]}}],
            "camera_rig": {"position_m": [0, 0, 1.5], "thermal": {"label_margin_px": [-1, 0]}}}
    with pytest.raises(ValueError, match="label_margin_px"):
        Scenario.model_validate(data)
