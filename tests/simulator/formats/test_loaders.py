"""Loaders on hand-written miniatures of the public layouts (no render), and table-driven corrupt inputs:
every bad file raises one FormatError naming the file, the row or key and the rule; strict=False skips
and counts."""
import json

import numpy as np
import pytest

from simulator.formats import antiuav, coco, mot


def _touch_frames(folder, n, digits=6, ext=".jpg"):
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(1, n + 1):
        (folder / f"{i:0{digits}d}{ext}").write_bytes(b"")


def test_antiuav_410_accepts_empty_and_zero_absent_markers(tmp_path):
    seq = tmp_path / "test" / "20190925_101846_1_1"
    _touch_frames(seq, 4)
    (seq / "IR_label.json").write_text(json.dumps({"exist": [1, 0, 0, 1],
                                                   "gt_rect": [[10, 20, 5, 4], [], [0], [11.5, 20, 5, 4]]}))
    track = antiuav.load_sequence(seq)["infrared"]
    assert track.exist.tolist() == [1, 0, 0, 1]
    assert track.boxes == [[10.0, 20.0, 5.0, 4.0], None, None, [11.5, 20.0, 5.0, 4.0]]
    assert len(track) == 4 and track.frames[0].name == "000001.jpg"
    assert list(antiuav.load_dataset(tmp_path)) == ["test/20190925_101846_1_1"]


def test_antiuav_rgbt_layout_and_mismatched_lengths(tmp_path):
    seq = tmp_path / "seqA"
    _touch_frames(seq / "visible", 2)
    _touch_frames(seq / "infrared", 2)
    (seq / "visible.json").write_text(json.dumps({"exist": [1, 1], "gt_rect": [[1, 2, 3, 4], [2, 2, 3, 4]]}))
    (seq / "infrared.json").write_text(json.dumps({"exist": [1, 0], "gt_rect": [[5, 6, 7, 8], []]}))
    tracks = antiuav.load_sequence(seq)
    assert tracks["visible"].boxes[1] == [2.0, 2.0, 3.0, 4.0] and tracks["infrared"].boxes[1] is None
    assert tracks["infrared"].frames[1].parent.name == "infrared"
    assert list(antiuav.load_dataset(tmp_path)) == ["seqA"]
    (seq / "infrared.json").write_text(json.dumps({"exist": [1, 0, 1], "gt_rect": [[5, 6, 7, 8], []]}))
    with pytest.raises(ValueError, match="3 exist flags but 2 gt_rect"):
        antiuav.load_sequence(seq)


def test_mmuav_sequence_with_every_20th_frame_annotated(tmp_path):
    seq = tmp_path / "test" / "0007"
    _touch_frames(seq / "rgb_frame", 41, digits=4)
    _touch_frames(seq / "ir_frame", 41, digits=4)
    for gt_dir, rows in (("gt_rgb", "1,1,100,50,20,10,1,0,1\n21,1,104,52,20,10,1,0,1\n41,2,5,6,7,8,1,0,1\n"),
                         ("gt_ir", "1,1,80,40,16,8,1,0,1\n")):
        (seq / gt_dir).mkdir()
        (seq / gt_dir / "gt.txt").write_text(rows)
    (seq / "seqinfo-rgb.ini").write_text("[Sequence]\nname=0007\nimDir=rgb_frame\nframeRate=30\nseqLength=41\n"
                                         "imWidth=640\nimHeight=360\nimExt=.jpg\n")
    (seq / "seqinfo-ir.ini").write_text("[Sequence]\nname=0007\nimDir=ir_frame\nframeRate=30\nseqLength=41\n"
                                        "imWidth=640\nimHeight=512\nimExt=.jpg\n")
    tracks = mot.load_dataset(tmp_path)["test/0007"]
    rgb, ir = tracks["rgb"], tracks["ir"]
    assert rgb.annotated_frames == [1, 21, 41] and len(rgb.frames) == 41
    assert rgb.boxes(21) == {1: [104.0, 52.0, 20.0, 10.0]} and rgb.boxes(2) == {}
    assert ir.seqinfo["imHeight"] == "512" and ir.gt.shape == (1, 9)


def test_mot_gt_short_rows_get_default_flags_and_bad_rows_name_the_line(tmp_path):
    path = tmp_path / "gt.txt"
    path.write_text("1, 3, 10, 20, 30, 40\n\n2,3,11,20,30,40,0,1,0.5\n")
    gt = mot.read_gt(path)
    np.testing.assert_array_equal(gt, [[1, 3, 10, 20, 30, 40, 1, 0, 1], [2, 3, 11, 20, 30, 40, 0, 1, 0.5]])
    path.write_text("1,2,3\n")
    with pytest.raises(ValueError, match="gt.txt: line 1: expected 6 to 10"):
        mot.read_gt(path)


def test_coco_video_tracks_follow_frame_ids_and_skip_flagged_distractors(tmp_path):
    data = {
        "images": [{"id": 11, "file_name": "0001/ir_frame/0002.jpg", "frame_id": 2, "video_id": 1, "prev_image_id": 10,
                    "next_image_id": -1, "width": 640, "height": 512},
                   {"id": 10, "file_name": "0001/ir_frame/0001.jpg", "frame_id": 1, "video_id": 1, "prev_image_id": -1,
                    "next_image_id": 11, "width": 640, "height": 512}],
        "annotations": [{"id": 1, "image_id": 10, "category_id": 1, "track_id": 4, "bbox": [1, 2, 3, 4], "area": 12,
                         "iscrowd": 0},
                        {"id": 2, "image_id": 11, "category_id": 1, "track_id": 4, "bbox": [2, 2, 3, 4], "area": 12,
                         "iscrowd": 0},
                        {"id": 3, "image_id": 11, "category_id": 2, "track_id": 5, "bbox": [9, 9, 2, 2], "area": 4,
                         "iscrowd": 0}],
        "videos": [{"id": 1, "file_name": "0001"}],
        "categories": [{"id": 1, "name": "drone"}, {"id": 2, "name": "bird", "distractor": True}],
    }
    path = tmp_path / "val.json"
    path.write_text(json.dumps(data))
    video = coco.load_coco(path, image_root=tmp_path)
    assert [im["id"] for im in video.frames(1)] == [10, 11]
    assert video.tracks(1) == {4: {1: [1.0, 2.0, 3.0, 4.0], 2: [2.0, 2.0, 3.0, 4.0]}, 5: {2: [9.0, 9.0, 2.0, 2.0]}}
    assert set(video.tracks(1, include_distractors=False)) == {4}
    assert video.image_path(video.frames(1)[0]) == tmp_path / "0001/ir_frame/0001.jpg"
    path.write_text(json.dumps({"images": []}))
    with pytest.raises(ValueError, match="annotations"):
        coco.load_coco(path)


# --------------------------------------------------------------------------------------------
# Corrupt and inconsistent inputs (issue 15): one error naming file, row/key and rule
# --------------------------------------------------------------------------------------------

from simulator.formats.validation import FormatError, SkippedRowsWarning  # noqa: E402

ANTIUAV_BAD = [
    ("exist 1 with a None box", {"exist": [1, 1], "gt_rect": [[1, 2, 3, 4], None]},
     "gt_rect\\[1\\]: exist is 1 but box"),
    ("exist 1 with []", {"exist": [1, 1], "gt_rect": [[1, 2, 3, 4], []]}, "gt_rect\\[1\\]"),
    ("exist 7", {"exist": [1, 7], "gt_rect": [[1, 2, 3, 4], [1, 2, 3, 4]]}, "exist\\[1\\]: must be 0 or 1, got 7"),
    ("exist -1", {"exist": [-1, 1], "gt_rect": [[1, 2, 3, 4], [1, 2, 3, 4]]}, "exist\\[0\\]: must be 0 or 1, got -1"),
    ("exist true", {"exist": [True, 1], "gt_rect": [[1, 2, 3, 4], [1, 2, 3, 4]]}, "exist\\[0\\]"),
    ("NaN box", {"exist": [1, 1], "gt_rect": [[1, 2, 3, 4], [1, float("nan"), 3, 4]]}, "finite numbers"),
    ("negative width", {"exist": [1, 1], "gt_rect": [[1, 2, -3, 4], [1, 2, 3, 4]]}, "width and height must be > 0"),
    ("string box", {"exist": [1, 1], "gt_rect": [[1, 2, 3, 4], ["1", 2, 3, 4]]}, "finite numbers"),
]


def _antiuav_seq(tmp_path, labels, n=2):
    seq = tmp_path / "seq"
    _touch_frames(seq, n)
    text = labels if isinstance(labels, str) else json.dumps(labels)
    (seq / "IR_label.json").write_text(text)
    return seq


@pytest.mark.parametrize("name,labels,message", ANTIUAV_BAD, ids=[c[0] for c in ANTIUAV_BAD])
def test_antiuav_bad_rows(tmp_path, name, labels, message):
    seq = _antiuav_seq(tmp_path, labels)
    with pytest.raises(FormatError, match=message) as err:
        antiuav.load_sequence(seq)
    assert str(seq / "IR_label.json") in str(err.value)
    with pytest.warns(SkippedRowsWarning, match="skipped 1 bad row"):
        track = antiuav.load_sequence(seq, strict=False)["infrared"]
    assert len(track.skipped) == 1 and len(track) == 2 and track.boxes[0 if "-1" in name or "true" in name or
                                                                      "width" in name else 1] is None


ANTIUAV_BROKEN = [
    ("corrupt JSON", '{"exist": [1, ', "line 1 column .*: not valid JSON"),
    ("not an object", "[1, 2]", "top level: expected an object"),
    ("missing gt_rect", '{"exist": [1, 1]}', "key 'gt_rect': missing"),
    ("exist not a list", '{"exist": 1, "gt_rect": []}', "key 'exist': must be a list"),
    ("length mismatch", '{"exist": [1, 0, 1], "gt_rect": [[1, 2, 3, 4], []]}', "3 exist flags but 2 gt_rect entries"),
    ("labels vs frames", '{"exist": [1, 0, 0], "gt_rect": [[1, 2, 3, 4], [], []]}',
     "frame count: 2 frames but 3 labels"),
]


@pytest.mark.parametrize("name,text,message", ANTIUAV_BROKEN, ids=[c[0] for c in ANTIUAV_BROKEN])
def test_antiuav_broken_files(tmp_path, name, text, message):
    seq = _antiuav_seq(tmp_path, text)
    with pytest.raises(FormatError, match=message):
        antiuav.load_sequence(seq, strict=False)            # structure errors are errors even when not strict


def test_antiuav_non_utf8_and_missing_frame(tmp_path):
    seq = _antiuav_seq(tmp_path, {"exist": [1, 0, 0], "gt_rect": [[1, 2, 3, 4], [], []]}, n=3)
    (seq / "000002.jpg").unlink()
    with pytest.raises(FormatError, match="frame 2 is missing"):
        antiuav.load_sequence(seq)
    (seq / "IR_label.json").write_bytes(b"\xff\xfe{not utf8")
    with pytest.raises(FormatError, match="not UTF-8"):
        antiuav.load_sequence(seq)


def test_antiuav_rgbt_public_miniature(tmp_path):
    """RGB-T as the public release names it: infrared/infraredI0000.jpg (0-based, 4 digits)."""
    seq = tmp_path / "20190925_111757_1_4"
    for modality in ("infrared", "visible"):
        (seq / modality).mkdir(parents=True)
        for i in range(3):
            (seq / modality / f"{modality}I{i:04d}.jpg").write_bytes(b"")
        (seq / f"{modality}.json").write_text(json.dumps({"exist": [1, 0, 1],
                                                          "gt_rect": [[1, 2, 3, 4], [], [2, 2, 3, 4]]}))
    tracks = antiuav.load_dataset(tmp_path)["20190925_111757_1_4"]
    assert [p.name for p in tracks["infrared"].frames] == ["infraredI0000.jpg", "infraredI0001.jpg",
                                                           "infraredI0002.jpg"]
    assert tracks["visible"].boxes == [[1.0, 2.0, 3.0, 4.0], None, [2.0, 2.0, 3.0, 4.0]]
    (seq / "infrared" / "infraredI0001.jpg").unlink()
    with pytest.raises(FormatError, match="frame 1 is missing"):
        antiuav.load_sequence(seq)


MOT_BAD = [
    ("frame 0", "0,1,10,20,5,5,1,0,1", "frame must be an integer >= 1, got 0"),
    ("frame 1.7", "1.7,1,10,20,5,5,1,0,1", "frame must be an integer >= 1, got 1.7"),
    ("frame 999 beyond seqLength", "999,1,10,20,5,5,1,0,1", "frame 999 is beyond seqLength 4"),
    ("id 0", "2,0,10,20,5,5,1,0,1", "id must be an integer >= 1"),
    ("NaN box", "2,1,nan,20,5,5,1,0,1", "box values must be finite"),
    ("negative height", "2,1,10,20,5,-5,1,0,1", "width and height must be > 0"),
    ("consider 2", "2,1,10,20,5,5,2,0,1", "consider .* must be 0 or 1"),
    ("class 0.5", "2,1,10,20,5,5,1,0.5,1", "class .* must be an integer >= 0"),
    ("visibility 3", "2,1,10,20,5,5,1,0,3", "visibility .* must be in \\[0, 1\\]"),
    ("text", "2,1,ten,20,5,5,1,0,1", "values must be numbers"),
    ("too few columns", "2,1,10", "expected 6 to 10"),
    ("duplicate id", "1,1,10,20,5,5,1,0,1", "id 1 appears twice on frame 1"),
]


def _mot_seq(tmp_path, extra_row, n=4, ext=".jpg", im_ext=".jpg", length=None):
    seq = tmp_path / "0001"
    _touch_frames(seq / "ir_frame", n, digits=4, ext=ext)
    (seq / "gt_ir").mkdir()
    (seq / "gt_ir" / "gt.txt").write_text("1,1,10,20,5,5,1,0,1\n" + extra_row + "\n3,1,11,20,5,5,1,0,1\n")
    (seq / "seqinfo-ir.ini").write_text("[Sequence]\nname=0001\nimDir=ir_frame\nframeRate=30\nseqLength="
                                        f"{length or n}\n"
                                        f"imWidth=640\nimHeight=512\nimExt={im_ext}\n")
    return seq


@pytest.mark.parametrize("name,row,message", MOT_BAD, ids=[c[0] for c in MOT_BAD])
def test_mot_bad_rows(tmp_path, name, row, message):
    seq = _mot_seq(tmp_path, row)
    with pytest.raises(FormatError, match=message) as err:
        mot.load_sequence(seq)
    assert f"{seq / 'gt_ir' / 'gt.txt'}: line 2" in str(err.value)
    with pytest.warns(SkippedRowsWarning, match="skipped 1 bad row"):
        track = mot.load_sequence(seq, strict=False)["ir"]
    assert track.gt[:, 0].tolist() == [1, 3] and len(track.skipped) == 1


def test_mot_seqinfo_against_the_frames(tmp_path):
    seq = _mot_seq(tmp_path, "2,1,10,20,5,5,1,0,1", im_ext=".png")
    with pytest.raises(FormatError, match="imExt.*'.png' but ir_frame/ holds .jpg"):
        mot.load_sequence(seq)
    seq = _mot_seq(tmp_path / "b", "2,1,10,20,5,5,1,0,1", n=6, length=10)
    with pytest.raises(FormatError, match="seqLength.*is 10 but ir_frame/ holds 6 frames"):
        mot.load_sequence(seq)
    (seq / "seqinfo-ir.ini").write_text("[Sequence]\nseqLength=ten\n")
    with pytest.raises(FormatError, match="seqLength.*positive integer"):
        mot.load_sequence(seq)
    (seq / "seqinfo-ir.ini").write_text("seqLength=10\n")
    with pytest.raises(FormatError, match="not a valid ini"):
        mot.load_sequence(seq)


def test_mot_evaluation_layout_miniature(tmp_path):
    """The toolkit's own layout: gt/MMMUAVir-test/0001/gt/gt.txt + seqinfo.ini + seqmaps (no images)."""
    seq = tmp_path / "gt" / "MMMUAVir-test" / "0001"
    (seq / "gt").mkdir(parents=True)
    (seq / "gt" / "gt.txt").write_text("1,1,274,187,18,10,1,0,1\n21,1,280,187,18,10,1,0,1\n")
    (seq / "seqinfo.ini").write_text("[Sequence]\nname=0001\nimDir=ir_frame\nframeRate=30\nseqLength=30\n"
                                     "imWidth=640\nimHeight=512\nimExt=.jpg\n")
    (tmp_path / "gt" / "seqmaps").mkdir()
    (tmp_path / "gt" / "seqmaps" / "MMMUAVir-test.txt").write_text("name\n0001\n")
    track = mot.load_dataset(tmp_path)["gt/MMMUAVir-test/0001"]["img1"]
    assert track.annotated_frames == [1, 21] and track.frames == []


COCO_BAD = [
    ("dangling image id", lambda d: d["annotations"][0].update(image_id=99),
     "annotations\\[0\\].image_id: 99 names no image"),
    ("duplicate image id", lambda d: d["images"][1].update(id=10), "images\\[1\\].id: duplicate id 10"),
    ("duplicate annotation id", lambda d: d["annotations"][1].update(id=1), "annotations\\[1\\].id: duplicate id 1"),
    ("unknown category", lambda d: d["annotations"][0].update(category_id=7), "category_id: 7 names no category"),
    ("NaN bbox", lambda d: d["annotations"][0].update(bbox=[1, 2, float("nan"), 4]), "bbox: box values must be finite"),
    ("negative bbox", lambda d: d["annotations"][0].update(bbox=[1, 2, -3, 4]), "width and height must be > 0"),
    ("frame_id 0", lambda d: d["images"][0].update(frame_id=0), "images\\[0\\].frame_id: must be an integer >= 1"),
    ("unknown video", lambda d: d["images"][0].update(video_id=5), "images\\[0\\].video_id: 5 names no video"),
    ("string id", lambda d: d["images"][0].update(id="10"), "images\\[0\\].id: must be an integer"),
]


def _coco_data():
    return {
        "images": [{"id": 10, "file_name": "0001/ir_frame/0001.jpg", "frame_id": 1, "video_id": 1},
                   {"id": 11, "file_name": "0001/ir_frame/0002.jpg", "frame_id": 2, "video_id": 1}],
        "annotations": [{"id": 1, "image_id": 10, "category_id": 1, "track_id": 4, "bbox": [1, 2, 3, 4]},
                        {"id": 2, "image_id": 11, "category_id": 1, "track_id": 4, "bbox": [2, 2, 3, 4]}],
        "videos": [{"id": 1, "file_name": "0001"}], "categories": [{"id": 1, "name": "drone"}],
    }


@pytest.mark.parametrize("name,corrupt,message", COCO_BAD, ids=[c[0] for c in COCO_BAD])
def test_coco_bad_rows(tmp_path, name, corrupt, message):
    data = _coco_data()
    corrupt(data)
    path = tmp_path / "val.json"
    path.write_text(json.dumps(data))
    with pytest.raises(FormatError, match=message) as err:
        coco.load_coco(path)
    assert str(path) in str(err.value)
    with pytest.warns(SkippedRowsWarning, match="skipped"):
        video = coco.load_coco(path, strict=False)
    assert len(video.skipped) >= 1
    ids = [a["image_id"] for a in video.data["annotations"]]
    assert set(ids) <= {im["id"] for im in video.images}


def test_coco_broken_files(tmp_path):
    path = tmp_path / "val.json"
    path.write_text('{"images": [], "annotations": [')
    with pytest.raises(FormatError, match="not valid JSON"):
        coco.load_coco(path)
    path.write_text('{"images": {}, "annotations": []}')
    with pytest.raises(FormatError, match="key 'images': must be a list of objects"):
        coco.load_coco(path, strict=False)


def test_antiuav2021_video_miniature(tmp_path):
    """The 2021 challenge layout: IR.mp4 / RGB.mp4 beside IR_label.json / RGB_label.json."""
    import cv2

    seq = tmp_path / "test-dev" / "20190925_124000_1_1"
    seq.mkdir(parents=True)
    for video, size, n in (("IR.mp4", (64, 48), 3), ("RGB.mp4", (96, 54), 3)):
        writer = cv2.VideoWriter(str(seq / video), cv2.VideoWriter_fourcc(*"mp4v"), 25.0, size)
        for i in range(n):
            writer.write(np.full((size[1], size[0], 3), 40 * i, np.uint8))
        writer.release()
    (seq / "IR_label.json").write_text(json.dumps({"exist": [1, 1, 0], "gt_rect": [[1, 2, 3, 4], [2, 2, 3, 4], [0]]}))
    (seq / "RGB_label.json").write_text(json.dumps({"exist": [1, 0, 0], "gt_rect": [[5, 6, 7, 8], [], []]}))
    tracks = antiuav.load_dataset(tmp_path)["test-dev/20190925_124000_1_1"]
    assert tracks["infrared"].video.name == "IR.mp4" and tracks["infrared"].boxes[2] is None
    assert tracks["visible"].video.name == "RGB.mp4" and tracks["visible"].exist.tolist() == [1, 0, 0]
    (seq / "RGB_label.json").write_text(json.dumps({"exist": [1, 0], "gt_rect": [[5, 6, 7, 8], []]}))
    with pytest.raises(FormatError, match="3 video frames but 2 labels"):
        antiuav.load_sequence(seq)


def test_coco_in_mmuav_converter_style(tmp_path):
    """MM-UAV's converter: annotations/val-ir.json, file_name from the root ('test/0001/...'), one category, conf."""
    (tmp_path / "test" / "0001" / "ir_frame").mkdir(parents=True)
    (tmp_path / "test" / "0001" / "ir_frame" / "0001.jpg").write_bytes(b"")
    data = {"images": [{"file_name": "test/0001/ir_frame/0001.jpg", "id": 1, "frame_id": 1, "prev_image_id": -1,
                        "next_image_id": -1, "video_id": 1, "height": 512, "width": 640}],
            "annotations": [{"id": 1, "category_id": 1, "image_id": 1, "track_id": 1, "bbox": [274, 187, 18, 10],
                             "conf": 1.0, "iscrowd": 0, "area": 180}],
            "videos": [{"id": 1, "file_name": "0001"}], "categories": [{"id": 1, "name": "drone"}]}
    (tmp_path / "annotations").mkdir()
    (tmp_path / "annotations" / "val-ir.json").write_text(json.dumps(data))
    video = coco.load_coco(tmp_path / "annotations" / "val-ir.json")
    assert video.image_root == tmp_path and video.image_path(video.images[0]).is_file()
    assert video.tracks(1) == {1: {1: [274.0, 187.0, 18.0, 10.0]}}
