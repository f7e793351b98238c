"""evids.data loaders on hand-written files in the public releases' own conventions (no render)."""
import json

import numpy as np
import pytest

from evids.data import antiuav, coco, mot


def _touch_frames(folder, n, digits=6, ext=".jpg"):
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(1, n + 1):
        (folder / f"{i:0{digits}d}{ext}").write_bytes(b"")


def test_antiuav_410_accepts_empty_and_zero_absent_markers(tmp_path):
    seq = tmp_path / "test" / "20190925_101846_1_1"
    _touch_frames(seq, 4)
    (seq / "IR_label.json").write_text(json.dumps({"exist": [1, 0, 0, 1], "gt_rect": [[10, 20, 5, 4], [], [0], [11.5, 20, 5, 4]]}))
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
    with pytest.raises(ValueError, match="gt.txt:1"):
        mot.read_gt(path)


def test_coco_video_tracks_follow_frame_ids_and_skip_flagged_distractors(tmp_path):
    data = {
        "images": [{"id": 11, "file_name": "0001/ir_frame/0002.jpg", "frame_id": 2, "video_id": 1, "prev_image_id": 10,
                    "next_image_id": -1, "width": 640, "height": 512},
                   {"id": 10, "file_name": "0001/ir_frame/0001.jpg", "frame_id": 1, "video_id": 1, "prev_image_id": -1,
                    "next_image_id": 11, "width": 640, "height": 512}],
        "annotations": [{"id": 1, "image_id": 10, "category_id": 1, "track_id": 4, "bbox": [1, 2, 3, 4], "area": 12, "iscrowd": 0},
                        {"id": 2, "image_id": 11, "category_id": 1, "track_id": 4, "bbox": [2, 2, 3, 4], "area": 12, "iscrowd": 0},
                        {"id": 3, "image_id": 11, "category_id": 2, "track_id": 5, "bbox": [9, 9, 2, 2], "area": 4, "iscrowd": 0}],
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
