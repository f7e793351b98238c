"""Anti-UAV 410/600 layout from a native sequence: thermal `000001.jpg`... + `IR_label.json`, and the
RGB camera in a sibling folder `<name>_visible/` with `visible.json` (same fields).

Reading: Anti-UAV loaders: the 410/600 thermal layout (``<seq>/000001.jpg`` + ``IR_label.json``), its
``<seq>_visible/`` + ``visible.json`` sibling, and the RGB-T layout (``<seq>/{visible,infrared}/``
+ ``visible.json`` / ``infrared.json``). Works on downloaded releases and generated exports.

Absent frames may hold ``[]`` or ``[0]`` in ``gt_rect``; both load as ``None``.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
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
from simulator.sensors.encode import agc_8bit


def primary_target_id(labels: dict) -> int:
    """Anti-UAV is single-object: the first drone-class target (else the first target)."""
    for obj in labels["objects"]:
        if obj["class"] == "drone":
            return obj["id"]
    return labels["objects"][0]["id"]


def _label_file(labels: dict, camera: str, target_id: int) -> dict:
    exist, rects = [], []
    for frame in labels["frames"]:
        rec = next(r for r in frame[camera] if r["id"] == target_id)
        exist.append(int(rec["exist"]))
        rects.append(list(rec["box"]) if rec["exist"] else [])
    return {"exist": exist, "gt_rect": rects}


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
            image, _ = agc_8bit(load_thermal_kelvin(sequence_dir, i))
            write_jpeg(tmp / frame_name(i, "jpg"), image)
        write_json(tmp / "IR_label.json", _label_file(labels, "thermal", target_id))
    with atomic_folder(vis_dir) as tmp:
        for i in range(n):
            write_jpeg(tmp / frame_name(i, "jpg"), load_rgb(sequence_dir, i))
        write_json(tmp / "visible.json", _label_file(labels, "rgb", target_id))
    return ir_dir, vis_dir


def read_antiuav_labels(path: Path) -> tuple[np.ndarray, list[list[float] | None]]:
    """Read IR_label.json / visible.json: exist flags and boxes (None when absent; accepts [] and [0])."""
    import json

    data = json.loads(Path(path).read_text())
    exist = np.asarray(data["exist"], dtype=np.int64)
    rects = [list(map(float, r)) if isinstance(r, list) and len(r) == 4 else None for r in data["gt_rect"]]
    if len(rects) != len(exist):
        raise ValueError(f"{path}: {len(exist)} exist flags but {len(rects)} gt_rect entries")
    return exist, rects


def export_antiuav_rgbt(sequence_dir: Path, out_dir: Path, name: str | None = None) -> Path:
    """Anti-UAV (RGB-T, the 300-sequence release's layout): `<out>/<name>/visible/000001.jpg`,
    `infrared/000001.jpg`, `visible.json`, `infrared.json` (same fields as IR_label.json)."""
    sequence_dir, out_dir = Path(sequence_dir), Path(out_dir)
    meta, labels = load_meta(sequence_dir), load_labels(sequence_dir)
    name = name or meta["scenario_name"]
    target_id = primary_target_id(labels)
    final = out_dir / name
    with atomic_folder(final) as tmp:
        for i in range(meta["n_frames"]):
            image, _ = agc_8bit(load_thermal_kelvin(sequence_dir, i))
            write_jpeg(tmp / "infrared" / frame_name(i, "jpg"), image)
            write_jpeg(tmp / "visible" / frame_name(i, "jpg"), load_rgb(sequence_dir, i))
        write_json(tmp / "infrared.json", _label_file(labels, "thermal", target_id))
        write_json(tmp / "visible.json", _label_file(labels, "rgb", target_id))
    return final


# --------------------------------------------------------------------------------------------
# Reader
# --------------------------------------------------------------------------------------------

LABEL_FILES = ("IR_label.json", "infrared.json", "visible.json")
IMAGE_EXTS = (".jpg", ".jpeg", ".png")


@dataclass
class AntiUAVTrack:
    """One camera of one sequence: frame paths, exist flags (int 0/1) and boxes [x, y, w, h] or None."""

    name: str
    modality: str
    frames: list[Path]
    exist: np.ndarray
    boxes: list[list[float] | None]

    def __len__(self) -> int:
        return len(self.exist)


def read_label_file(path: Path) -> tuple[np.ndarray, list[list[float] | None]]:
    """exist flags and boxes (None when absent) of an Anti-UAV label JSON."""
    data = json.loads(Path(path).read_text())
    if "exist" not in data or "gt_rect" not in data:
        raise ValueError(f"{path}: expected keys 'exist' and 'gt_rect'")
    exist = np.asarray(data["exist"], dtype=np.int64)
    boxes = [list(map(float, r)) if isinstance(r, list) and len(r) == 4 else None for r in data["gt_rect"]]
    if len(boxes) != len(exist):
        raise ValueError(f"{path}: {len(exist)} exist flags but {len(boxes)} gt_rect entries")
    return exist, boxes


def _frames(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_EXTS)


def load_track(folder: Path, label_file: str | None = None, image_dir: str | None = None) -> AntiUAVTrack:
    """A track from a folder holding a label JSON and frames (or frames under ``image_dir``)."""
    folder = Path(folder)
    names = [label_file] if label_file else [n for n in LABEL_FILES if (folder / n).is_file()]
    if not names or not (folder / names[0]).is_file():
        raise FileNotFoundError(f"{folder}: no Anti-UAV label file ({', '.join(LABEL_FILES)})")
    exist, boxes = read_label_file(folder / names[0])
    frames = _frames(folder / image_dir if image_dir else folder)
    if frames and len(frames) != len(exist):
        raise ValueError(f"{folder}: {len(frames)} frames but {len(exist)} labels")
    modality = "visible" if names[0] == "visible.json" else "infrared"
    return AntiUAVTrack(folder.name, modality, frames, exist, boxes)


def load_sequence(folder: Path) -> dict[str, AntiUAVTrack]:
    """Tracks of one sequence by modality ('infrared', 'visible').

    RGB-T layout: ``visible/`` + ``infrared/`` image folders next to the JSONs. 410/600 layout:
    ``IR_label.json`` in the folder, plus the ``<name>_visible/`` sibling when present.
    """
    folder = Path(folder)
    out: dict[str, AntiUAVTrack] = {}
    if (folder / "infrared").is_dir() or (folder / "visible").is_dir():
        for modality in ("infrared", "visible"):
            if (folder / f"{modality}.json").is_file():
                track = load_track(folder, f"{modality}.json", modality if (folder / modality).is_dir() else None)
                track.name = folder.name
                out[modality] = track
        return out
    if (folder / "IR_label.json").is_file():
        out["infrared"] = load_track(folder, "IR_label.json")
        sibling = folder.parent / f"{folder.name}_visible"
        if (sibling / "visible.json").is_file():
            track = load_track(sibling, "visible.json")
            track.name = folder.name
            out["visible"] = track
    elif (folder / "visible.json").is_file():
        out["visible"] = load_track(folder, "visible.json")
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
            if folder.name.endswith("_visible") and (folder.parent / folder.name[: -len("_visible")] / "IR_label.json").is_file():
                continue
            found.add(folder)
    return sorted(found)


def load_dataset(root: Path) -> dict[str, dict[str, AntiUAVTrack]]:
    """Every sequence under ``root``, keyed by the folder path relative to root (e.g. 'test/seq000001')."""
    root = Path(root)
    return {p.relative_to(root).as_posix(): load_sequence(p) for p in find_sequences(root)}
