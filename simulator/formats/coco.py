"""COCO-video export in the MM-UAV baseline's style, from native sequences.

``<out>/<split>/<NNNN>/{rgb_frame,ir_frame}/0001.jpg`` (the MM-UAV image layout) and
``<out>/annotations/<split>_{rgb,ir}.json`` with ``images`` (id, file_name relative to
``<out>/<split>/``, frame_id 1-based, video_id, prev_image_id / next_image_id (-1 at the ends),
width, height), ``annotations`` (id, image_id, category_id, track_id, bbox [x, y, w, h], area,
iscrowd 0), ``videos`` (id, file_name) and ``categories``: drone = 1, plus bird = 2 and
aircraft = 3 flagged ``"distractor": true`` (left out with ``distractors=False``).

Reading: COCO-video loader (the MM-UAV baseline's style): images with frame_id / video_id /
prev_image_id / next_image_id, annotations with track_id, ``videos`` and ``categories``.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable

from simulator.formats.mot import mot_frame_name
from simulator.formats.native import (
    frame_name,
    load_labels,
    load_meta,
    read_image,
    write_jpeg,
    write_json,
)

CATEGORIES = [{"id": 1, "name": "drone"}, {"id": 2, "name": "bird", "distractor": True},
              {"id": 3, "name": "aircraft", "distractor": True}]
CATEGORY_IDS = {c["name"]: c["id"] for c in CATEGORIES}
_CAMERAS = {"rgb": ("rgb_frame", "rgb"), "ir": ("ir_frame", "thermal")}


def coco_video_json(sequences: list[tuple[str, Path]], modality: str, *, distractors: bool = True) -> dict[str, Any]:
    """The COCO dict for (video name, native sequence dir) pairs; modality 'rgb' or 'ir'."""
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
            images.append({"id": image_id, "file_name": f"{video_name}/{im_dir}/{mot_frame_name(i)}", "frame_id": i + 1,
                           "video_id": video_id, "prev_image_id": image_id - 1 if i > 0 else -1,
                           "next_image_id": image_id + 1 if i < n - 1 else -1,
                           "width": cam["width_px"], "height": cam["height_px"]})
            for rec in sorted(frame[camera], key=lambda r: r["id"]):
                if not rec["exist"] or (rec["class"] != "drone" and not distractors):
                    continue
                ann_id += 1
                x, y, w, h = rec["box"]
                annotations.append({"id": ann_id, "image_id": image_id, "category_id": CATEGORY_IDS[rec["class"]],
                                    "track_id": rec["id"], "bbox": [x, y, w, h], "area": w * h, "iscrowd": 0})
    categories = CATEGORIES if distractors else CATEGORIES[:1]
    return {"images": images, "annotations": annotations, "videos": videos, "categories": categories}


def export_coco(entries: Iterable[dict[str, Any]], out: Path, *, distractors: bool = True, progress: bool = False) -> Path:
    """Write images and per-split annotation files for manifest entries (name, index, split, path)."""
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
        for modality, (im_dir, camera) in _CAMERAS.items():
            source = "rgb" if camera == "rgb" else "thermal_agc"
            for i in range(n):
                write_jpeg(out / e["split"] / video / im_dir / mot_frame_name(i), read_image(seq / source / frame_name(i, "png")))
        by_split.setdefault(e["split"], []).append((video, seq))
    for split, seqs in sorted(by_split.items()):
        for modality in _CAMERAS:
            write_json(out / "annotations" / f"{split}_{modality}.json", coco_video_json(seqs, modality, distractors=distractors))
    return out


# --------------------------------------------------------------------------------------------
# Reader
# --------------------------------------------------------------------------------------------

@dataclass
class CocoVideo:
    """One COCO annotation file; ``image_root`` is where ``file_name`` paths resolve."""

    data: dict[str, Any]
    image_root: Path | None = None

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
        """Images of one video in frame order (following prev/next links when present)."""
        return sorted((im for im in self.images if im.get("video_id") == video_id), key=lambda im: im.get("frame_id", im["id"]))

    def tracks(self, video_id: int, *, include_distractors: bool = True) -> dict[int, dict[int, list[float]]]:
        """{track_id: {frame_id: [x, y, w, h]}} of one video."""
        cats = self.categories
        by_image = self.annotations_by_image()
        out: dict[int, dict[int, list[float]]] = {}
        for im in self.frames(video_id):
            for ann in by_image.get(im["id"], []):
                if not include_distractors and cats.get(ann["category_id"], {}).get("distractor"):
                    continue
                out.setdefault(int(ann.get("track_id", -1)), {})[int(im.get("frame_id", im["id"]))] = [float(v) for v in ann["bbox"]]
        return out

    def image_path(self, image: dict[str, Any]) -> Path:
        if self.image_root is None:
            raise ValueError("image_root is unknown; pass it to load_coco")
        return self.image_root / image["file_name"]


def load_coco(path: Path, image_root: Path | None = None) -> CocoVideo:
    """Read a COCO(-video) JSON. For evids exports (``<root>/annotations/<split>_<mod>.json``)
    the image root defaults to ``<root>/<split>/``."""
    path = Path(path)
    data = json.loads(path.read_text())
    for key in ("images", "annotations"):
        if key not in data:
            raise ValueError(f"{path}: missing '{key}'")
    if image_root is None and path.parent.name == "annotations":
        candidate = path.parent.parent / path.stem.rsplit("_", 1)[0]
        image_root = candidate if candidate.is_dir() else None
    return CocoVideo(data, image_root)
