"""Exporters round-trip through the simulator.formats readers: native labels -> Anti-UAV (thermal and
RGB-T), MM-UAV (every frame and every k-th frame, with/without distractors), COCO-video."""
import json

import numpy as np
import pytest

from simulator.dataset.exporters import export_dataset
from simulator.dataset.generate import generate_dataset, load_manifest
from simulator.formats import antiuav as antiuav_loader
from simulator.formats import coco as coco_loader
from simulator.formats import mot as mot_loader
from simulator.formats.antiuav import primary_target_id
from simulator.formats.native import load_labels, read_image
from tests.simulator.dataset.gen_helpers import write_tiny

CAMERA = {"infrared": "thermal", "visible": "rgb", "ir": "thermal", "rgb": "rgb"}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    base = tmp_path_factory.mktemp("exp")
    out = base / "ds"
    generate_dataset(write_tiny(base, sequences=3, frames=4), out, 9, progress=False)
    entries = load_manifest(out)["sequences"]
    labels = {e["name"]: load_labels(out / "sequences" / e["name"]) for e in entries}
    has_distractor = any(o["class"] != "drone" for lab in labels.values() for o in lab["objects"])
    has_visible_distractor = any(r["exist"] and r["class"] != "drone" for lab in labels.values()
                                 for f in lab["frames"] for r in f["rgb"])
    assert has_distractor and has_visible_distractor, "the tiny config must produce visible distractors"
    return out, entries, labels


def _antiuav_truth(labels, camera):
    tid = primary_target_id(labels)
    recs = [next(r for r in f[camera] if r["id"] == tid) for f in labels["frames"]]
    return [r["exist"] for r in recs], [list(map(float, r["box"])) if r["exist"] else None for r in recs]


FRAME_NAMES = {
    ("antiuav", "infrared"): ["000001.jpg", "000002.jpg", "000003.jpg", "000004.jpg"],
    ("antiuav", "visible"): ["000001.jpg", "000002.jpg", "000003.jpg", "000004.jpg"],
    ("antiuav_rgbt", "infrared"): ["infraredI0000.jpg", "infraredI0001.jpg", "infraredI0002.jpg", "infraredI0003.jpg"],
    ("antiuav_rgbt", "visible"): ["visibleI0000.jpg", "visibleI0001.jpg", "visibleI0002.jpg", "visibleI0003.jpg"],
}


@pytest.mark.parametrize("fmt", ["antiuav", "antiuav_rgbt", "antiuav2021"])
def test_antiuav_round_trip(dataset, tmp_path, fmt):
    out, entries, labels = dataset
    root = export_dataset(out, fmt, tmp_path / fmt, progress=False)
    loaded = antiuav_loader.load_dataset(root)
    assert sorted(loaded) == sorted(f"{e['split']}/{e['name']}" for e in entries)
    for e in entries:
        seq = loaded[f"{e['split']}/{e['name']}"]
        assert set(seq) == {"infrared", "visible"}
        for modality, track in seq.items():
            exist, boxes = _antiuav_truth(labels[e["name"]], CAMERA[modality])
            assert track.exist.tolist() == exist and track.boxes == boxes
            if fmt == "antiuav2021":
                assert track.frames == [] and track.video.name == {"infrared": "IR.mp4", "visible": "RGB.mp4"}[modality]
                assert track.video.parent.name == e["name"]
                continue
            assert [p.name for p in track.frames] == FRAME_NAMES[(fmt, modality)]
            assert read_image(track.frames[0]).shape[:2] == (80, 96)
    if fmt == "antiuav_rgbt":
        seq_dir = root / entries[0]["split"] / entries[0]["name"]
        assert sorted(p.name for p in seq_dir.iterdir()) == ["infrared", "infrared.json", "visible", "visible.json"]
        # the public RGB-T loader's sort key: int(name.split(model + 'I')[-1].strip('.jpg'))
        names = [p.name for p in (seq_dir / "infrared").iterdir()]
        assert sorted(int(n.split("infraredI")[-1].strip(".jpg")) for n in names) == [0, 1, 2, 3]


def test_antiuav2021_videos_hold_every_frame(dataset, tmp_path):
    import cv2

    out, entries, _ = dataset
    root = export_dataset(out, "antiuav2021", tmp_path / "a21", progress=False)
    seq_dir = root / entries[0]["split"] / entries[0]["name"]
    assert sorted(p.name for p in seq_dir.iterdir()) == ["IR.mp4", "IR_label.json", "RGB.mp4", "RGB_label.json"]
    for video in ("IR.mp4", "RGB.mp4"):
        cap = cv2.VideoCapture(str(seq_dir / video))
        frames = []
        while True:
            ok, frame = cap.read()
            if not ok:
                break
            frames.append(frame)
        cap.release()
        assert len(frames) == 4 and frames[0].shape == (80, 96, 3)
    # the thermal video decodes close to the exported JPEG frames (lossy codecs, same content)
    jpeg_root = export_dataset(out, "antiuav", tmp_path / "a410", progress=False)
    ir_jpeg = read_image(jpeg_root / entries[0]["split"] / entries[0]["name"] / "000001.jpg")
    cap = cv2.VideoCapture(str(seq_dir / "IR.mp4"))
    ok, first = cap.read()
    cap.release()
    assert ok and abs(first[..., 0].astype(float) - ir_jpeg.astype(float)).mean() < 8


def _native_rows(labels, camera, every=1, distractors=False, drones=True):
    """gt rows in MM-UAV's classes: drones 0, every distractor 1 (not_drone), consider 1."""
    rows = []
    for f in labels["frames"]:
        if f["index"] % every:
            continue
        for r in f[camera]:
            drone = r["class"] == "drone"
            if r["exist"] and ((drone and drones) or (not drone and distractors)):
                rows.append([f["index"] + 1, r["id"], *r["box"], 1, 0 if drone else 1, 1])
    return sorted(rows)


@pytest.mark.parametrize("every,distractors", [(1, "none"), (2, "class"), (1, "file")])
def test_mmuav_round_trip(dataset, tmp_path, every, distractors):
    out, entries, labels = dataset
    root = export_dataset(out, "mot", tmp_path / "mot", annotate_every=every, distractors=distractors, progress=False)
    loaded = mot_loader.load_dataset(root)
    assert sorted(loaded) == sorted(f"{e['split']}/{e['index'] + 1:04d}" for e in entries)
    for e in entries:
        folder = root / e["split"] / f"{e['index'] + 1:04d}"
        seq = loaded[f"{e['split']}/{e['index'] + 1:04d}"]
        assert set(seq) == {"rgb", "ir"}
        for modality, track in seq.items():
            truth = _native_rows(labels[e["name"]], CAMERA[modality], every, distractors == "class")
            assert sorted(track.gt.tolist()) == truth
            if distractors == "file":
                assert sorted(track.distractors.tolist()) == _native_rows(labels[e["name"]], CAMERA[modality], every,
                                                                          True, drones=False)
            assert [p.name for p in track.frames] == ["0001.jpg", "0002.jpg", "0003.jpg", "0004.jpg"]
            assert track.seqinfo == {"name": folder.name, "imDir": f"{modality}_frame", "frameRate": "25",
                                     "seqLength": "4", "imWidth": "96", "imHeight": "80", "imExt": ".jpg"}
        text = (folder / "gt_rgb" / "gt.txt").read_text()
        classes = {line.split(",")[7] for line in text.splitlines()}
        assert classes <= ({"0", "1"} if distractors == "class" else {"0"})       # MM-UAV's {drone, not_drone}
        assert all(int(line.split(",")[0]) % every == 1 % every for line in text.splitlines())
    # the MOTChallenge evaluation layout the toolkit reads, beside the dataset layout
    for split in {e["split"] for e in entries}:
        names = sorted(f"{e['index'] + 1:04d}" for e in entries if e["split"] == split)
        for bench, gt_dir, ini in (("MMMUAVrgb", "gt_rgb", "seqinfo-rgb.ini"), ("MMMUAVir", "gt_ir", "seqinfo-ir.ini")):
            assert (root / "gt" / "seqmaps" / f"{bench}-{split}.txt").read_text().splitlines() == ["name", *names]
            for name in names:
                seq = root / "gt" / f"{bench}-{split}" / name
                assert (seq / "gt" / "gt.txt").read_bytes() == (root / split / name / gt_dir / "gt.txt").read_bytes()
                assert (seq / "seqinfo.ini").read_bytes() == (root / split / name / ini).read_bytes()
    assert any(k.startswith("gt/") for k in mot_loader.load_dataset(root, include_eval_copy=True))


def test_mmuav_ground_truth_scores_perfect(dataset, tmp_path):
    """Ground truth as tracker results, scored through trackeval: HOTA = MOTA = IDF1 = 1 on every sequence."""
    from evids.metrics import track_scores

    out, entries, _ = dataset
    root = export_dataset(out, "mot", tmp_path / "mot", annotate_every=2, progress=False)
    scored = 0
    for key, seq in mot_loader.load_dataset(root).items():
        for track in seq.values():
            n = int(track.seqinfo["seqLength"])
            hyp_rows = [list(map(float, r.split(","))) for r in mot_loader.tracker_rows(track)]
            per_frame = []
            for f in range(1, n + 1, 2):
                g = track.gt[(track.gt[:, 0] == f) & (track.gt[:, 7] == 0)]
                h = [r for r in hyp_rows if r[0] == f]
                per_frame.append(((g[:, 1].astype(int).tolist(), g[:, 2:6].reshape(-1, 4)),
                                  ([int(r[1]) for r in h], [r[2:6] for r in h] or np.zeros((0, 4)))))
            if not any(len(g[0]) for g, _ in per_frame):
                continue
            s = track_scores([g for g, _ in per_frame], [h for _, h in per_frame])
            assert s["hota"] == pytest.approx(1.0) and s["mota"] == 1.0 and s["idf1"] == 1.0, key
            scored += 1
    assert scored >= 2


def test_coco_round_trip_with_flagged_distractors(dataset, tmp_path):
    out, entries, labels = dataset
    root = export_dataset(out, "coco", tmp_path / "coco", progress=False)
    for split in sorted({e["split"] for e in entries}):
        split_entries = [e for e in entries if e["split"] == split]
        for modality in ("rgb", "ir"):
            data = coco_loader.load_coco(root / "annotations" / f"{split}_{modality}.json")
            assert data.image_root == root / split
            cats = data.categories
            assert cats[1]["name"] == "drone" and "distractor" not in cats[1]
            assert cats[2] == {"id": 2, "name": "bird", "distractor": True} and cats[3]["distractor"] is True
            assert [v["file_name"] for v in data.videos.values()] == [f"{e['index'] + 1:04d}" for e in split_entries]
            for video_id, e in zip(data.videos, split_entries):
                frames = data.frames(video_id)
                assert [im["frame_id"] for im in frames] == [1, 2, 3, 4]
                assert frames[0]["prev_image_id"] == -1 and frames[-1]["next_image_id"] == -1
                assert all(a["next_image_id"] == b["id"] and b["prev_image_id"] == a["id"]
                           for a, b in zip(frames, frames[1:]))
                assert data.image_path(frames[2]).is_file()
                truth = {}
                for f in labels[e["name"]]["frames"]:
                    for r in f[CAMERA[modality]]:
                        if r["exist"]:
                            truth.setdefault(r["id"], {})[f["index"] + 1] = list(map(float, r["box"]))
                assert data.tracks(video_id) == truth
                drones = {o["id"] for o in labels[e["name"]]["objects"] if o["class"] == "drone"}
                assert set(data.tracks(video_id, include_distractors=False)) == drones & set(truth)
            for ann in data.data["annotations"]:
                assert ann["area"] == ann["bbox"][2] * ann["bbox"][3] and ann["iscrowd"] == 0


def test_export_of_an_incomplete_dataset_is_refused(dataset, tmp_path):
    import shutil

    from scenes.errors import UserInputError

    out, _, _ = dataset
    copy = tmp_path / "incomplete"
    shutil.copytree(out, copy, ignore=shutil.ignore_patterns("antiuav*", "mot", "coco"))
    manifest = json.loads((copy / "manifest.json").read_text())
    manifest["complete"] = False
    (copy / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(UserInputError, match="incomplete"):
        export_dataset(copy, "mot", tmp_path / "mot", progress=False)
    assert not (tmp_path / "mot").exists()


def test_coco_mmuav_naming_info_licenses_and_pycocotools(dataset, tmp_path):
    """MM-UAV's converter naming (train-ir.json, file_name from the root); pycocotools scores GT as detections AP 1."""
    import contextlib
    import io

    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    out, entries, _ = dataset
    root = export_dataset(out, "coco", tmp_path / "coco", coco_naming="mmuav", progress=False)
    split = entries[0]["split"]
    path = root / "annotations" / f"{split}-ir.json"
    data = json.loads(path.read_text())
    assert {"info", "licenses", "images", "annotations", "videos", "categories"} <= set(data)
    assert all(im["file_name"].startswith(f"{split}/") for im in data["images"])
    assert all(a["conf"] == 1.0 for a in data["annotations"])
    video = coco_loader.load_coco(path)
    assert video.image_root == root and video.image_path(video.images[0]).is_file()
    with contextlib.redirect_stdout(io.StringIO()):
        gt = COCO(str(path))
        dets = gt.loadRes([{"image_id": a["image_id"], "category_id": a["category_id"], "bbox": a["bbox"],
                            "score": 1.0} for a in data["annotations"]])
        ev = COCOeval(gt, dets, "bbox")
        ev.evaluate(), ev.accumulate(), ev.summarize()
    assert ev.stats[0] == pytest.approx(1.0) and ev.stats[8] == pytest.approx(1.0)     # AP, AR@100


def test_webdataset_round_trip_and_byte_identical(dataset, tmp_path):
    from simulator.formats import webdataset as wdsfmt

    out, entries, labels = dataset
    a = export_dataset(out, "webdataset", tmp_path / "a", progress=False)
    b = export_dataset(out, "webdataset", tmp_path / "b", shard_mb=0.001, progress=False)
    for split in {e["split"] for e in entries}:
        shards_a, shards_b = wdsfmt.shards(a, split), wdsfmt.shards(b, split)
        samples = list(wdsfmt.iter_samples(shards_a))
        assert len(shards_a) == 1 and len(shards_b) == len(samples)          # 1 kB shards: one sample each
        assert samples == list(wdsfmt.iter_samples(shards_b))
        mine = [e for e in entries if e["split"] == split]
        assert [s["__key__"] for s in samples] == [f"{e['name']}_{i:06d}" for e in mine for i in range(1, 5)]
        for s in samples:
            name, number = s["__key__"].rsplit("_", 1)
            i = int(number) - 1
            seq = out / "sequences" / name
            assert s["rgb.png"] == (seq / "rgb" / f"{i + 1:06d}.png").read_bytes()
            assert s["thermal.png"] == (seq / "thermal" / f"{i + 1:06d}.png").read_bytes()
            assert s["json"]["thermal"] == labels[name]["frames"][i]["thermal"] and s["json"]["split"] == split
    again = export_dataset(out, "webdataset", tmp_path / "c", progress=False)
    assert [p.read_bytes() for p in sorted(a.rglob("*.tar"))] == [p.read_bytes() for p in sorted(again.rglob("*.tar"))]


def test_zarr_kelvin_stacks_equal_the_native_reader_and_are_byte_identical(dataset, tmp_path):
    from simulator.formats.kelvin_zarr import read_kelvin_stack
    from simulator.formats.native import load_meta, load_thermal_kelvin

    out, entries, labels = dataset
    a = export_dataset(out, "zarr", tmp_path / "a", progress=False)
    for e in entries:
        seq = out / "sequences" / e["name"]
        kelvin, attrs = read_kelvin_stack(a / e["split"] / f"{e['name']}.zarr")
        n = len(labels[e["name"]]["frames"])
        assert kelvin.shape[0] == n and kelvin.dtype == np.float32
        for i in range(n):
            np.testing.assert_array_equal(kelvin[i], load_thermal_kelvin(seq, i))
        assert attrs["kelvin_per_count"] == load_meta(seq)["cameras"]["thermal"]["kelvin_per_count"]
        assert attrs["sequence"] == e["name"] and attrs["split"] == e["split"]
        part, _ = read_kelvin_stack(a / e["split"] / f"{e['name']}.zarr", slice(1, 3))
        np.testing.assert_array_equal(part, kelvin[1:3])
    b = export_dataset(out, "zarr", tmp_path / "b", progress=False)
    files_a = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file() and p.name != ".evids-output.json")
    files_b = sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file() and p.name != ".evids-output.json")
    assert files_a == files_b and files_a
    assert all((a / f).read_bytes() == (b / f).read_bytes() for f in files_a)
