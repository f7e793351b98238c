"""COCO-video loader (the MM-UAV baseline's style): images with frame_id / video_id /
prev_image_id / next_image_id, annotations with track_id, ``videos`` and ``categories``."""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any


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
