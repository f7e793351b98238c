"""Exporters round-trip through the evids.data loaders: native labels -> Anti-UAV (thermal and
RGB-T), MM-UAV (every frame and every k-th frame, with/without distractors), COCO-video."""
import json

import pytest

from evids.data import antiuav as antiuav_loader
from evids.data import coco as coco_loader
from evids.data import mot as mot_loader
from simulator.dataset.generate import export_dataset, generate_dataset, load_manifest
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


@pytest.mark.parametrize("fmt", ["antiuav", "antiuav_rgbt"])
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
            assert [p.name for p in track.frames] == ["000001.jpg", "000002.jpg", "000003.jpg", "000004.jpg"]
            assert read_image(track.frames[0]).shape[:2] == (80, 96)


def _native_rows(labels, camera, every=1, distractors=False):
    rows = []
    for f in labels["frames"]:
        if f["index"] % every:
            continue
        for r in f[camera]:
            if r["exist"] and (r["class"] == "drone" or distractors):
                drone = r["class"] == "drone"
                rows.append([f["index"] + 1, r["id"], *r["box"], 1 if drone else 0,
                             {"drone": 0, "bird": 1, "aircraft": 2}[r["class"]], 1])
    return sorted(rows)


@pytest.mark.parametrize("every,distractors", [(1, False), (2, True)])
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
            truth = _native_rows(labels[e["name"]], CAMERA[modality], every, distractors)
            assert sorted(track.gt.astype(int).tolist()) == truth
            assert [p.name for p in track.frames] == ["0001.jpg", "0002.jpg", "0003.jpg", "0004.jpg"]
            assert track.seqinfo == {"name": folder.name, "imDir": f"{modality}_frame", "frameRate": "25",
                                     "seqLength": "4", "imWidth": "96", "imHeight": "80", "imExt": ".jpg"}
        text = (folder / "gt_rgb" / "gt.txt").read_text()
        if not distractors:
            assert all(line.endswith(",1,0,1") for line in text.splitlines())
        assert all(int(line.split(",")[0]) % every == 1 % every for line in text.splitlines())


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
                assert all(a["next_image_id"] == b["id"] and b["prev_image_id"] == a["id"] for a, b in zip(frames, frames[1:]))
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
