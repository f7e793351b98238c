"""COCO-video export in the MM-UAV baseline's style, from native sequences: writer, reader and spec
(docs/FORMATS.md, "COCO").

Images: ``<out>/<split>/<NNNN>/{rgb_frame,ir_frame}/0001.jpg`` (the MM-UAV image layout).
Annotation files, by ``naming``:

* ``evids`` (default): ``<out>/annotations/<split>_{rgb,ir}.json``, ``file_name`` relative to
  ``<out>/<split>/`` (``0001/ir_frame/0001.jpg``);
* ``mmuav`` (MM-UAV's converter): ``<out>/annotations/<split>-{rgb,ir}.json``, ``file_name`` relative
  to ``<out>`` (``train/0001/ir_frame/0001.jpg``) and a ``conf`` of 1 on every annotation.

Every file has ``info``, ``licenses``, ``images`` (id, file_name, frame_id 1-based, video_id,
prev_image_id / next_image_id (-1 at the ends), width, height), ``annotations`` (id, image_id,
category_id, track_id, bbox [x, y, w, h], area, iscrowd 0), ``videos`` (id, file_name) and
``categories``: drone = 1, plus bird = 2 and aircraft = 3 flagged ``"distractor": true`` (left out
with ``distractors=False``).

Reading validates: ``images``/``annotations`` are lists of objects; image and annotation ids are
unique integers; every annotation's ``image_id`` names an image, its ``category_id`` a category
(when categories are given) and its ``bbox`` is four finite numbers with w, h > 0; ``frame_id`` is
an integer >= 1 and ``video_id`` names a video (when videos are given). ``strict=False`` skips bad
annotations (and duplicate images) and records them in ``skipped``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, TypeGuard

from simulator.formats.mot import mot_frame_name
from simulator.formats.native import (
    frame_name,
    load_labels,
    load_meta,
    read_image,
    write_jpeg,
    write_json,
)
from simulator.formats.validation import Checker, Skipped, box_problem, read_json

CATEGORIES = [{"id": 1, "name": "drone"}, {"id": 2, "name": "bird", "distractor": True},
              {"id": 3, "name": "aircraft", "distractor": True}]
CATEGORY_IDS = {c["name"]: c["id"] for c in CATEGORIES}
_CAMERAS = {"rgb": ("rgb_frame", "rgb"), "ir": ("ir_frame", "thermal")}
NAMINGS = ("evids", "mmuav")
INFO = {"description": "evids synthetic counter-drone data (COCO-video, MM-UAV image layout)",
        "url": "", "version": "1", "year": 0, "contributor": "evids", "date_created": ""}
LICENSES: list[dict[str, Any]] = []


def annotation_file_name(split: str, modality: str, naming: str = "evids") -> str:
    """``train_ir.json`` (evids) or ``train-ir.json`` (MM-UAV's converter)."""
    if naming not in NAMINGS:
        raise ValueError(f"naming must be one of {', '.join(NAMINGS)}, got {naming!r}")
    return f"{split}{'-' if naming == 'mmuav' else '_'}{modality}.json"


def coco_video_json(sequences: list[tuple[str, Path]], modality: str, *, distractors: bool = True,
                    prefix: str = "", conf: bool = False) -> dict[str, Any]:
    """The COCO dict for (video name, native sequence dir) pairs; modality 'rgb' or 'ir'.

    ``prefix`` goes before every ``file_name`` (``"train/"`` for MM-UAV's convention); ``conf`` adds
    MM-UAV's ``conf: 1`` key to annotations."""
    im_dir, camera = _CAMERAS[modality]
    images, annotations, videos = [], [], []
    image_id = ann_id = 0
    for video_id, (video_name, seq) in enumerate(sequences, start=1):
        meta, labels = load_meta(seq), load_labels(seq)
        cam = meta["cameras"][camera]
        videos.append({"id": video_id, "file_name": video_name})
        n = meta["n_frames"]
        for frame in labels["frames"]:
            image_id += 1
            i = frame["index"]
            images.append({"id": image_id, "file_name": f"{prefix}{video_name}/{im_dir}/{mot_frame_name(i)}",
                           "frame_id": i + 1, "video_id": video_id, "prev_image_id": image_id - 1 if i > 0 else -1,
                           "next_image_id": image_id + 1 if i < n - 1 else -1,
                           "width": cam["width_px"], "height": cam["height_px"]})
            for rec in sorted(frame[camera], key=lambda r: r["id"]):
                if not rec["exist"] or (rec["class"] != "drone" and not distractors):
                    continue
                ann_id += 1
                x, y, w, h = rec["box"]
                ann = {"id": ann_id, "image_id": image_id, "category_id": CATEGORY_IDS[rec["class"]],
                       "track_id": rec["id"], "bbox": [x, y, w, h], "area": w * h, "iscrowd": 0}
                if conf:
                    ann["conf"] = 1.0
                annotations.append(ann)
    categories = CATEGORIES if distractors else CATEGORIES[:1]
    return {"info": dict(INFO), "licenses": list(LICENSES), "images": images, "annotations": annotations,
            "videos": videos, "categories": categories}


def export_coco(entries: Iterable[dict[str, Any]], out: Path, *, distractors: bool = True, progress: bool = False,
                naming: str = "evids") -> Path:
    """Write images and per-split annotation files for manifest entries (name, index, split, path)."""
    annotation_file_name("train", "ir", naming)         # validates naming before any work
    out = Path(out)
    by_split: dict[str, list[tuple[str, Path]]] = {}
    items = list(entries)
    if progress:
        from rich.progress import track

        items = list(track(items, description="export coco"))
    for e in items:
        video = f"{e['index'] + 1:04d}"
        seq = Path(e["path"])
        n = load_meta(seq)["n_frames"]
        for im_dir, camera in _CAMERAS.values():
            source = "rgb" if camera == "rgb" else "thermal_agc"
            for i in range(n):
                write_jpeg(out / e["split"] / video / im_dir / mot_frame_name(i),
                           read_image(seq / source / frame_name(i, "png")))
        by_split.setdefault(e["split"], []).append((video, seq))
    for split, seqs in sorted(by_split.items()):
        for modality in _CAMERAS:
            data = coco_video_json(seqs, modality, distractors=distractors,
                                   prefix=f"{split}/" if naming == "mmuav" else "", conf=naming == "mmuav")
            write_json(out / "annotations" / annotation_file_name(split, modality, naming), data)
    return out


# --------------------------------------------------------------------------------------------
# Reader
# --------------------------------------------------------------------------------------------

@dataclass
class CocoVideo:
    """One COCO annotation file; ``image_root`` is where ``file_name`` paths resolve; ``skipped``
    lists what a non-strict read left out."""

    data: dict[str, Any]
    image_root: Path | None = None
    skipped: Skipped = field(default_factory=Skipped)

    @property
    def images(self) -> list[dict[str, Any]]:
        return self.data["images"]

    @property
    def categories(self) -> dict[int, dict[str, Any]]:
        return {c["id"]: c for c in self.data.get("categories", [])}

    @property
    def videos(self) -> dict[int, dict[str, Any]]:
        return {v["id"]: v for v in self.data.get("videos", [])}

    def annotations_by_image(self) -> dict[int, list[dict[str, Any]]]:
        out: dict[int, list[dict[str, Any]]] = {im["id"]: [] for im in self.images}
        for ann in self.data["annotations"]:
            out.setdefault(ann["image_id"], []).append(ann)
        return out

    def frames(self, video_id: int) -> list[dict[str, Any]]:
        """Images of one video in frame order."""
        return sorted((im for im in self.images if im.get("video_id") == video_id),
                      key=lambda im: im.get("frame_id", im["id"]))

    def tracks(self, video_id: int, *, include_distractors: bool = True) -> dict[int, dict[int, list[float]]]:
        """{track_id: {frame_id: [x, y, w, h]}} of one video."""
        cats = self.categories
        by_image = self.annotations_by_image()
        out: dict[int, dict[int, list[float]]] = {}
        for im in self.frames(video_id):
            for ann in by_image.get(im["id"], []):
                if not include_distractors and cats.get(ann["category_id"], {}).get("distractor"):
                    continue
                track = out.setdefault(int(ann.get("track_id", -1)), {})
                track[int(im.get("frame_id", im["id"]))] = [float(v) for v in ann["bbox"]]
        return out

    def image_path(self, image: dict[str, Any]) -> Path:
        if self.image_root is None:
            raise ValueError("image_root is unknown; pass it to load_coco")
        return self.image_root / image["file_name"]


def _is_id(value: Any) -> TypeGuard[int]:
    return isinstance(value, int) and not isinstance(value, bool)


def _objects(check: Checker, data: dict, key: str, required: bool) -> list:
    if key not in data:
        if required:
            check.fail(f"key '{key}'", "missing (a COCO file has 'images' and 'annotations')")
        return []
    value = data[key]
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        check.fail(f"key '{key}'", "must be a list of objects")
    return value


def _unique(check: Checker, items: list[dict], key: str) -> list[dict]:
    """Items with a unique integer ``id`` (later duplicates are bad rows)."""
    seen: set[int] = set()
    kept = []
    for k, item in enumerate(items):
        ident = item.get("id")
        if not _is_id(ident):
            check.bad_row(f"{key}[{k}].id", f"must be an integer, got {ident!r}")
        elif ident in seen:
            check.bad_row(f"{key}[{k}].id", f"duplicate id {ident}")
        else:
            seen.add(ident)
            kept.append(item)
    return kept


def validate_coco(data: Any, path: Path, *, strict: bool = True, skipped: Skipped | None = None) -> dict[str, Any]:
    """The COCO dict with its references checked (see the module docstring); bad rows dropped when not strict."""
    check = Checker(path, strict, skipped)
    if not isinstance(data, dict):
        check.fail("top level", f"expected an object, got {type(data).__name__}")
    images = _unique(check, _objects(check, data, "images", True), "images")
    categories = _unique(check, _objects(check, data, "categories", False), "categories")
    videos = _unique(check, _objects(check, data, "videos", False), "videos")
    image_ids = {im["id"] for im in images}
    category_ids = {c["id"] for c in categories}
    video_ids = {v["id"] for v in videos}
    kept_images = []
    for k, im in enumerate(images):
        frame = im.get("frame_id")
        if "frame_id" in im and (not _is_id(frame) or frame < 1):
            check.bad_row(f"images[{k}].frame_id", f"must be an integer >= 1, got {frame!r}")
        elif videos and "video_id" in im and not (_is_id(im["video_id"]) and im["video_id"] in video_ids):
            check.bad_row(f"images[{k}].video_id", f"{im['video_id']!r} names no video")
        elif not isinstance(im.get("file_name", ""), str):
            check.bad_row(f"images[{k}].file_name", "must be a string")
        else:
            kept_images.append(im)
    image_ids = {im["id"] for im in kept_images}
    annotations = _unique(check, _objects(check, data, "annotations", True), "annotations")
    kept_anns = []
    for k, ann in enumerate(annotations):
        problem = None
        if not (_is_id(ann.get("image_id")) and ann["image_id"] in image_ids):
            problem = (f"annotations[{k}].image_id", f"{ann.get('image_id')!r} names no image")
        elif categories and not (_is_id(ann.get("category_id")) and ann["category_id"] in category_ids):
            problem = (f"annotations[{k}].category_id", f"{ann.get('category_id')!r} names no category")
        elif (why := box_problem(ann.get("bbox"))) is not None:
            problem = (f"annotations[{k}].bbox", why)
        if problem is not None:
            check.bad_row(*problem)
            continue
        kept_anns.append(ann)
    check.finish()
    return {**data, "images": kept_images, "annotations": kept_anns, "categories": categories, "videos": videos}


def load_coco(path: Path, image_root: Path | None = None, *, strict: bool = True) -> CocoVideo:
    """Read and validate a COCO(-video) JSON. For evids exports (``<root>/annotations/<split>_<mod>.json``)
    the image root defaults to ``<root>/<split>/``; for MM-UAV naming (``<split>-<mod>.json``) to ``<root>``."""
    path = Path(path)
    skipped = Skipped()
    data = validate_coco(read_json(path), path, strict=strict, skipped=skipped)
    if image_root is None and path.parent.name == "annotations":
        root = path.parent.parent
        if "-" in path.stem and "_" not in path.stem:
            image_root = root
        else:
            candidate = root / path.stem.rsplit("_", 1)[0]
            image_root = candidate if candidate.is_dir() else None
    return CocoVideo(data, image_root, skipped)
