"""Fuzzing the readers: whatever the bytes, a reader returns data within the spec's domains or raises
FormatError (never a raw JSONDecodeError/TypeError/KeyError/ValueError/UnicodeDecodeError)."""
from __future__ import annotations

import json
import math

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from simulator.formats import antiuav, coco, mot
from simulator.formats.validation import FormatError

SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

number = st.one_of(st.integers(-5, 50), st.floats(allow_nan=True, allow_infinity=True, width=32),
                   st.sampled_from(["1", "x", "", "nan"]))
json_value = st.recursive(st.one_of(st.none(), st.booleans(), st.integers(-3, 9), st.floats(allow_nan=False),
                                    st.text(max_size=3)),
                          lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                  st.dictionaries(st.text(max_size=3), inner,
                                                                                                 max_size=3)),
                          max_leaves=12)


@SETTINGS
@given(rows=st.lists(st.lists(number, min_size=0, max_size=11), max_size=6), seq_length=st.integers(1, 30))
def test_mot_gt_fuzz(tmp_path_factory, rows, seq_length):
    path = tmp_path_factory.mktemp("g") / "gt.txt"
    path.write_text("".join(",".join(str(v) for v in r) + "\n" for r in rows))
    try:
        gt = mot.read_gt(path, seq_length=seq_length)
    except FormatError as err:
        assert str(path) in str(err)
        return
    assert gt.shape[1] == 9 and np.isfinite(gt).all()
    assert ((gt[:, 0] >= 1) & (gt[:, 0] <= seq_length) & (gt[:, 0] == np.round(gt[:, 0]))).all()
    assert ((gt[:, 1] >= 1) & (gt[:, 4] > 0) & (gt[:, 5] > 0)).all()
    assert len({(f, i) for f, i in gt[:, :2].tolist()}) == len(gt)


@SETTINGS
@given(data=json_value)
def test_antiuav_label_fuzz(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("a") / "IR_label.json"
    path.write_text(json.dumps(data))
    try:
        exist, boxes = antiuav.read_label_file(path)
    except FormatError as err:
        assert str(path) in str(err)
        return
    assert set(exist.tolist()) <= {0, 1} and len(boxes) == len(exist)
    for e, b in zip(exist, boxes):
        if e:
            assert b is not None and all(math.isfinite(v) for v in b) and b[2] > 0 and b[3] > 0


@SETTINGS
@example(data={"images": [{"id": 1}], "annotations": [{"id": 1, "image_id": [1], "bbox": [1, 2, 3, 4]}]})
@example(data={"images": [{"id": 1, "video_id": {}}], "annotations": [], "videos": [{"id": 1}]})
@example(data={"images": [{"id": 1}],
               "annotations": [{"id": 1, "image_id": 1, "category_id": [1], "bbox": [1, 2, 3, 4]}],
               "categories": [{"id": 1}]})
@given(data=st.fixed_dictionaries({"images": st.lists(st.dictionaries(st.sampled_from(["id", "frame_id", "video_id"]),
                                                                        json_value, max_size=3), max_size=3),
                                    "annotations": st.lists(st.dictionaries(
                                        st.sampled_from(["id", "image_id", "category_id", "bbox"]), json_value,
                                        max_size=4), max_size=3)}))
def test_coco_fuzz(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("c") / "x.json"
    path.write_text(json.dumps(data))
    try:
        video = coco.load_coco(path)
    except FormatError as err:
        assert str(path) in str(err)
        return
    ids = [im["id"] for im in video.images]
    assert len(set(ids)) == len(ids)
    for ann in video.data["annotations"]:
        assert ann["image_id"] in ids
        video.annotations_by_image()


@SETTINGS
@given(raw=st.binary(max_size=64))
def test_raw_bytes_never_escape_as_other_errors(tmp_path_factory, raw):
    folder = tmp_path_factory.mktemp("b")
    for name, read in (("gt.txt", mot.read_gt), ("IR_label.json", antiuav.read_label_file), ("c.json", coco.load_coco)):
        (folder / name).write_bytes(raw)
        try:
            read(folder / name)
        except FormatError:
            pass
