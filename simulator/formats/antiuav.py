"""Anti-UAV layouts: writer, reader and spec (docs/FORMATS.md, "Anti-UAV").

Three layouts, all single-object (the first drone-class target of a native sequence):

* **410/600 thermal** (``antiuav``): ``<seq>/000001.jpg`` ... (6 digits, 1-based) + ``IR_label.json``;
  we also write the RGB camera into a sibling ``<seq>_visible/`` with ``visible.json`` (read by our
  loader only; no public code reads it).
* **RGB-T** (``antiuav_rgbt``, the public RGB-T release): ``<seq>/infrared/infraredI0000.jpg`` ...,
  ``<seq>/visible/visibleI0000.jpg`` ... (0-based, 4 digits, modality name + ``I`` before the index),
  ``<seq>/infrared.json`` and ``<seq>/visible.json``.
* **2021 challenge** (``antiuav2021``): ``<seq>/IR.mp4``, ``<seq>/RGB.mp4`` (MPEG-4 Part 2 via OpenCV),
  ``<seq>/IR_label.json``, ``<seq>/RGB_label.json``.

Label JSON: ``{"exist": [0|1 per frame], "gt_rect": [[x, y, w, h] per frame]}`` in pixels (top-left
corner + size). We write ``[]`` for absent frames; readers accept ``[]``, ``[0]`` and any box there.

Reading validates each label file: ``exist`` and ``gt_rect`` are lists of equal length, every
``exist`` is 0 or 1, a frame with ``exist`` 1 has a box of four finite numbers with w, h > 0, the
number of frames (images, or video frames) equals the number of labels, and frame indices are
consecutive. ``strict=False`` turns a bad frame into an unlabelled one (exist 0, box None) and
records it in ``track.skipped``.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from simulator.files import atomic_folder
from simulator.formats.native import (
    frame_name,
    load_labels,
    load_meta,
    load_rgb,
    load_thermal_kelvin,
    write_jpeg,
    write_json,
)
from simulator.formats.validation import Checker, FormatError, Skipped, box_problem, read_json
from simulator.sensors.encode import agc_8bit

RGBT_MODALITIES = ("infrared", "visible")
VIDEO_FOURCC = "mp4v"


def primary_target_id(labels: dict) -> int:
    """Anti-UAV is single-object: the first drone-class target (else the first target)."""
    for obj in labels["objects"]:
        if obj["class"] == "drone":
            return obj["id"]
    return labels["objects"][0]["id"]


def rgbt_frame_name(modality: str, index0: int) -> str:
    """Public RGB-T frame name: ``infraredI0000.jpg`` (0-based, 4 digits)."""
    return f"{modality}I{index0:04d}.jpg"


def _label_file(labels: dict, camera: str, target_id: int) -> dict:
    exist, rects = [], []
    for frame in labels["frames"]:
        rec = next(r for r in frame[camera] if r["id"] == target_id)
        exist.append(int(rec["exist"]))
        rects.append(list(rec["box"]) if rec["exist"] else [])
    return {"exist": exist, "gt_rect": rects}


def _thermal_8bit(sequence_dir: Path, i: int) -> np.ndarray:
    return agc_8bit(load_thermal_kelvin(sequence_dir, i))[0]


def export_antiuav(sequence_dir: Path, out_dir: Path, name: str | None = None) -> tuple[Path, Path]:
    """Write `<out>/<name>/` (thermal, IR_label.json) and `<out>/<name>_visible/` (RGB, visible.json)."""
    sequence_dir, out_dir = Path(sequence_dir), Path(out_dir)
    meta, labels = load_meta(sequence_dir), load_labels(sequence_dir)
    name = name or meta["scenario_name"]
    target_id = primary_target_id(labels)
    n = meta["n_frames"]
    ir_dir, vis_dir = out_dir / name, out_dir / f"{name}_visible"
    with atomic_folder(ir_dir) as tmp:
        for i in range(n):
            write_jpeg(tmp / frame_name(i, "jpg"), _thermal_8bit(sequence_dir, i))
        write_json(tmp / "IR_label.json", _label_file(labels, "thermal", target_id))
    with atomic_folder(vis_dir) as tmp:
        for i in range(n):
            write_jpeg(tmp / frame_name(i, "jpg"), load_rgb(sequence_dir, i))
        write_json(tmp / "visible.json", _label_file(labels, "rgb", target_id))
    return ir_dir, vis_dir


def export_antiuav_rgbt(sequence_dir: Path, out_dir: Path, name: str | None = None) -> Path:
    """Anti-UAV RGB-T: `<out>/<name>/infrared/infraredI0000.jpg`..., `visible/visibleI0000.jpg`...,
    `infrared.json`, `visible.json`."""
    sequence_dir, out_dir = Path(sequence_dir), Path(out_dir)
    meta, labels = load_meta(sequence_dir), load_labels(sequence_dir)
    name = name or meta["scenario_name"]
    target_id = primary_target_id(labels)
    final = out_dir / name
    with atomic_folder(final) as tmp:
        for i in range(meta["n_frames"]):
            write_jpeg(tmp / "infrared" / rgbt_frame_name("infrared", i), _thermal_8bit(sequence_dir, i))
            write_jpeg(tmp / "visible" / rgbt_frame_name("visible", i), load_rgb(sequence_dir, i))
        write_json(tmp / "infrared.json", _label_file(labels, "thermal", target_id))
        write_json(tmp / "visible.json", _label_file(labels, "rgb", target_id))
    return final


def _write_video(path: Path, frames, frame_rate_hz: float, size_wh: tuple[int, int]) -> None:
    """MPEG-4 video of RGB (or grey) uint8 frames through OpenCV's FFmpeg backend."""
    import cv2

    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*VIDEO_FOURCC), float(frame_rate_hz), size_wh)
    if not writer.isOpened():
        raise OSError(f"OpenCV cannot write {path} (no {VIDEO_FOURCC} encoder)")
    try:
        for frame in frames:
            image = np.repeat(frame[..., None], 3, axis=-1) if frame.ndim == 2 else frame
            writer.write(np.ascontiguousarray(image[..., ::-1]))
    finally:
        writer.release()


def export_antiuav2021(sequence_dir: Path, out_dir: Path, name: str | None = None) -> Path:
    """Anti-UAV 2021 challenge layout: `<out>/<name>/IR.mp4`, `RGB.mp4`, `IR_label.json`, `RGB_label.json`."""
    sequence_dir, out_dir = Path(sequence_dir), Path(out_dir)
    meta, labels = load_meta(sequence_dir), load_labels(sequence_dir)
    name = name or meta["scenario_name"]
    target_id = primary_target_id(labels)
    n, fps = meta["n_frames"], meta["frame_rate_hz"]
    cams = meta["cameras"]
    final = out_dir / name
    with atomic_folder(final) as tmp:
        _write_video(tmp / "IR.mp4", (_thermal_8bit(sequence_dir, i) for i in range(n)), fps,
                     (cams["thermal"]["width_px"], cams["thermal"]["height_px"]))
        _write_video(tmp / "RGB.mp4", (load_rgb(sequence_dir, i) for i in range(n)), fps,
                     (cams["rgb"]["width_px"], cams["rgb"]["height_px"]))
        write_json(tmp / "IR_label.json", _label_file(labels, "thermal", target_id))
        write_json(tmp / "RGB_label.json", _label_file(labels, "rgb", target_id))
    return final


# --------------------------------------------------------------------------------------------
# Reader
# --------------------------------------------------------------------------------------------

LABEL_FILES = ("IR_label.json", "infrared.json", "visible.json", "RGB_label.json")
IMAGE_EXTS = (".jpg", ".jpeg", ".png")
_INDEX_RE = re.compile(r"(\d+)$")


@dataclass
class AntiUAVTrack:
    """One camera of one sequence: frame paths (or a video), exist flags (int 0/1), boxes or None.

    ``skipped`` lists the frames a non-strict read turned into unlabelled ones (empty when strict)."""

    name: str
    modality: str
    frames: list[Path]
    exist: np.ndarray
    boxes: list[list[float] | None]
    video: Path | None = None
    skipped: Skipped = field(default_factory=Skipped)

    def __len__(self) -> int:
        return len(self.exist)


def read_label_file(path: Path, *, strict: bool = True,
                    skipped: Skipped | None = None) -> tuple[np.ndarray, list[list[float] | None]]:
    """exist flags and boxes (None when absent) of an Anti-UAV label JSON, checked against the spec."""
    check = Checker(path, strict, skipped)
    data = read_json(path)
    if not isinstance(data, dict):
        check.fail("top level", f"expected an object with 'exist' and 'gt_rect', got {type(data).__name__}")
    for key in ("exist", "gt_rect"):
        if key not in data:
            check.fail(f"key '{key}'", "missing (an Anti-UAV label file has 'exist' and 'gt_rect')")
        if not isinstance(data[key], list):
            check.fail(f"key '{key}'", f"must be a list, got {type(data[key]).__name__}")
    flags, rects = data["exist"], data["gt_rect"]
    if len(flags) != len(rects):
        check.fail("keys 'exist'/'gt_rect'", f"{len(flags)} exist flags but {len(rects)} gt_rect entries")
    exist = np.zeros(len(flags), dtype=np.int64)
    boxes: list[list[float] | None] = [None] * len(flags)
    for i, (flag, rect) in enumerate(zip(flags, rects)):
        if isinstance(flag, bool) or flag not in (0, 1):
            check.bad_row(f"exist[{i}]", f"must be 0 or 1, got {flag!r}")
            continue
        valid = box_problem(rect)
        if flag == 1 and valid is not None:
            check.bad_row(f"gt_rect[{i}]", f"exist is 1 but {valid}")
            continue
        exist[i] = int(flag)
        boxes[i] = [float(v) for v in rect] if valid is None else None
    check.finish()
    return exist, boxes


def _frames(folder: Path, label: Path) -> list[Path]:
    """Image files sorted by their trailing index (``000001``, ``infraredI0000``); indices consecutive."""
    indexed = []
    for p in folder.iterdir():
        if p.suffix.lower() in IMAGE_EXTS:
            m = _INDEX_RE.search(p.stem)
            if m is None:
                raise FormatError(p, "file name", "frame name must end with its index (000001.jpg, infraredI0000.jpg)")
            indexed.append((int(m.group(1)), p))
    indexed.sort()
    idx = [i for i, _ in indexed]
    if idx:
        start = idx[0]
        if start not in (0, 1):
            raise FormatError(folder, "frame indices", f"must start at 0 or 1, first is {indexed[0][1].name}")
        for expected, (i, p) in enumerate(indexed, start=start):
            if i != expected:
                raise FormatError(folder, "frame indices", f"frame {expected} is missing (next file is {p.name}); "
                                  f"{label.name} needs one image per label")
    return [p for _, p in indexed]


def _video_frames(path: Path) -> int:
    import cv2

    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened():
            raise FormatError(path, "", "OpenCV cannot open this video")
        return int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    finally:
        cap.release()


_VIDEO_OF = {"IR_label.json": "IR.mp4", "RGB_label.json": "RGB.mp4"}


def load_track(folder: Path, label_file: str | None = None, image_dir: str | None = None, *,
               strict: bool = True) -> AntiUAVTrack:
    """A track from a folder holding a label JSON and frames (or frames under ``image_dir``, or the
    2021 layout's ``IR.mp4`` / ``RGB.mp4`` beside ``IR_label.json`` / ``RGB_label.json``)."""
    folder = Path(folder)
    names = [label_file] if label_file else [n for n in LABEL_FILES if (folder / n).is_file()]
    if not names or not (folder / names[0]).is_file():
        raise FileNotFoundError(f"{folder}: no Anti-UAV label file ({', '.join(LABEL_FILES)})")
    label = folder / names[0]
    skipped = Skipped()
    exist, boxes = read_label_file(label, strict=strict, skipped=skipped)
    modality = "visible" if names[0] in ("visible.json", "RGB_label.json") else "infrared"
    video = folder / _VIDEO_OF[names[0]] if names[0] in _VIDEO_OF else None
    frames: list[Path] = []
    if video is not None and video.is_file():
        count = _video_frames(video)
        if count != len(exist):
            raise FormatError(video, "frame count", f"{count} video frames but {len(exist)} labels in {label.name}")
    else:
        video = None
        frames = _frames(folder / image_dir if image_dir else folder, label)
        if frames and len(frames) != len(exist):
            raise FormatError(label, "frame count", f"{len(frames)} frames but {len(exist)} labels")
    return AntiUAVTrack(folder.name, modality, frames, exist, boxes, video, skipped)


def load_sequence(folder: Path, *, strict: bool = True) -> dict[str, AntiUAVTrack]:
    """Tracks of one sequence by modality ('infrared', 'visible').

    RGB-T layout: ``visible/`` + ``infrared/`` image folders next to the JSONs. 2021 layout:
    ``IR.mp4``/``RGB.mp4`` + ``IR_label.json``/``RGB_label.json``. 410/600 layout: ``IR_label.json``
    in the folder, plus our ``<name>_visible/`` sibling when present.
    """
    folder = Path(folder)
    out: dict[str, AntiUAVTrack] = {}
    if (folder / "infrared").is_dir() or (folder / "visible").is_dir():
        for modality in RGBT_MODALITIES:
            if (folder / f"{modality}.json").is_file():
                track = load_track(folder, f"{modality}.json", modality if (folder / modality).is_dir() else None,
                                   strict=strict)
                out[modality] = track
        if not out:
            raise FileNotFoundError(f"{folder}: RGB-T image folders but no infrared.json / visible.json")
        return out
    if (folder / "IR_label.json").is_file():
        out["infrared"] = load_track(folder, "IR_label.json", strict=strict)
        sibling = folder.parent / f"{folder.name}_visible"
        if (folder / "RGB_label.json").is_file():
            out["visible"] = load_track(folder, "RGB_label.json", strict=strict)
        elif (sibling / "visible.json").is_file():
            track = load_track(sibling, "visible.json", strict=strict)
            track.name = folder.name
            out["visible"] = track
    elif (folder / "visible.json").is_file():
        out["visible"] = load_track(folder, "visible.json", strict=strict)
    if not out:
        raise FileNotFoundError(f"{folder}: not an Anti-UAV sequence folder")
    return out


def find_sequences(root: Path) -> list[Path]:
    """Sequence folders under ``root`` (any depth, e.g. train/val/test), sorted; ``*_visible``
    siblings are part of their thermal sequence."""
    root = Path(root)
    found = set()
    for name in LABEL_FILES:
        for label in root.rglob(name):
            folder = label.parent
            if folder.name.endswith("_visible") and (folder.parent / folder.name[: -len("_visible")]
                                                     / "IR_label.json").is_file():
                continue
            found.add(folder)
    return sorted(found)


def load_dataset(root: Path, *, strict: bool = True) -> dict[str, dict[str, AntiUAVTrack]]:
    """Every sequence under ``root``, keyed by the folder path relative to root (e.g. 'test/seq000001')."""
    root = Path(root)
    return {p.relative_to(root).as_posix(): load_sequence(p, strict=strict) for p in find_sequences(root)}
