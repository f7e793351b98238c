"""MM-UAV (MOT-style) layout from a native sequence.

``<out>/<NNNN>/rgb_frame/0001.jpg``, ``ir_frame/0001.jpg`` (4 digits, 1-based), ``gt_rgb/gt.txt``
and ``gt_ir/gt.txt`` with rows ``frame,id,left,top,w,h,consider,class,visibility`` (drones:
``...,1,0,1``), ``seqinfo-rgb.ini`` and ``seqinfo-ir.ini``. Distractors (birds, aircraft), when
kept, are rows with consider 0 and class 1 (bird) / 2 (aircraft), which MM-UAV tools ignore.

Reading: MM-UAV / MOT loaders: ``<seq>/{rgb_frame,ir_frame}/0001.jpg``, ``gt_rgb/gt.txt``, ``gt_ir/gt.txt``,
``seqinfo-rgb.ini``, ``seqinfo-ir.ini`` (also plain MOT ``img1/``, ``gt/gt.txt``, ``seqinfo.ini``).

gt.txt rows: ``frame,id,left,top,w,h,consider,class,visibility`` (1-based frame and id; MM-UAV
drones are class 0; evids exports distractors as consider 0, class 1 bird / 2 aircraft).
"""
from __future__ import annotations

import configparser
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from simulator.files import atomic_folder
from simulator.formats.native import (
    frame_name,
    load_labels,
    load_meta,
    read_image,
    write_jpeg,
)

MOT_CLASS_IDS = {"drone": 0, "bird": 1, "aircraft": 2}
MODALITIES = {"rgb": ("rgb_frame", "gt_rgb", "seqinfo-rgb.ini"), "thermal": ("ir_frame", "gt_ir", "seqinfo-ir.ini")}


def mot_frame_name(index0: int) -> str:
    return f"{index0 + 1:04d}.jpg"


def gt_rows(labels: dict, camera: str, *, annotate_every: int = 1, distractors: bool = False) -> list[str]:
    """gt.txt lines (sorted by frame, then id) for frames f with (f - 1) % annotate_every == 0."""
    rows = []
    for frame in labels["frames"]:
        number = frame["index"] + 1
        if (number - 1) % annotate_every:
            continue
        for rec in sorted(frame[camera], key=lambda r: r["id"]):
            if not rec["exist"]:
                continue
            is_drone = rec["class"] == "drone"
            if not is_drone and not distractors:
                continue
            x, y, w, h = rec["box"]
            rows.append(f"{number},{rec['id']},{x},{y},{w},{h},{1 if is_drone else 0},{MOT_CLASS_IDS[rec['class']]},1")
    return rows


def seqinfo_text(name: str, im_dir: str, frame_rate_hz: float, length: int, width: int, height: int) -> str:
    return (f"[Sequence]\nname={name}\nimDir={im_dir}\nframeRate={int(round(frame_rate_hz))}\nseqLength={length}\n"
            f"imWidth={width}\nimHeight={height}\nimExt=.jpg\n")


def export_mmuav(sequence_dir: Path, out_dir: Path, name: str, *, annotate_every: int = 1,
                 distractors: bool = False) -> Path:
    """Write ``<out_dir>/<name>/`` in the MM-UAV layout (atomically); returns it."""
    if annotate_every < 1:
        raise ValueError(f"annotate_every must be >= 1, got {annotate_every}")
    sequence_dir = Path(sequence_dir)
    meta, labels = load_meta(sequence_dir), load_labels(sequence_dir)
    n = meta["n_frames"]
    final = Path(out_dir) / name
    with atomic_folder(final) as tmp:
        for camera, (im_dir, gt_dir, ini) in MODALITIES.items():
            source = "rgb" if camera == "rgb" else "thermal_agc"
            for i in range(n):
                write_jpeg(tmp / im_dir / mot_frame_name(i), read_image(sequence_dir / source / frame_name(i, "png")))
            rows = gt_rows(labels, camera, annotate_every=annotate_every, distractors=distractors)
            (tmp / gt_dir).mkdir(parents=True, exist_ok=True)
            (tmp / gt_dir / "gt.txt").write_text("".join(r + "\n" for r in rows))
            cam = meta["cameras"][camera]
            (tmp / ini).write_text(seqinfo_text(name, im_dir, meta["frame_rate_hz"], n, cam["width_px"], cam["height_px"]))
    return final


# --------------------------------------------------------------------------------------------
# Reader
# --------------------------------------------------------------------------------------------

MMUAV_MODALITIES = {"rgb": ("rgb_frame", "gt_rgb", "seqinfo-rgb.ini"), "ir": ("ir_frame", "gt_ir", "seqinfo-ir.ini"),
                    "event": ("event_frame", "gt_event", "seqinfo-event.ini")}
GT_COLUMNS = ("frame", "id", "left", "top", "width", "height", "consider", "class", "visibility")


@dataclass
class MotTrack:
    """One modality of a sequence: seqinfo fields, frame paths, and gt rows (N, 9) float64."""

    name: str
    modality: str
    seqinfo: dict[str, str]
    frames: list[Path]
    gt: np.ndarray
    annotated_frames: list[int] = field(default_factory=list)

    def boxes(self, frame: int, *, considered_only: bool = True) -> dict[int, list[float]]:
        """{id: [left, top, w, h]} on 1-based ``frame``."""
        rows = self.gt[self.gt[:, 0] == frame]
        if considered_only:
            rows = rows[rows[:, 6] != 0]
        return {int(r[1]): [float(v) for v in r[2:6]] for r in rows}


def read_gt(path: Path) -> np.ndarray:
    """gt.txt as an (N, 9) float64 array (missing trailing columns filled with 1, 0, 1)."""
    rows = []
    for number, line in enumerate(Path(path).read_text().splitlines(), start=1):
        line = line.strip()
        if not line:
            continue
        values = [float(v) for v in line.replace(" ", "").split(",")]
        if len(values) < 6:
            raise ValueError(f"{path}:{number}: expected at least 6 comma-separated values, got {len(values)}")
        values = (values + [1.0, 0.0, 1.0][len(values) - 6:])[:9] if len(values) < 9 else values[:9]
        rows.append(values)
    return np.asarray(rows, dtype=np.float64).reshape(-1, 9)


def read_seqinfo(path: Path) -> dict[str, str]:
    parser = configparser.ConfigParser()
    parser.optionxform = str
    parser.read_string(Path(path).read_text())
    section = "Sequence" if parser.has_section("Sequence") else parser.sections()[0]
    return dict(parser[section])


def load_sequence(folder: Path) -> dict[str, MotTrack]:
    """Tracks of one MM-UAV (or plain MOT) sequence folder by modality ('rgb', 'ir', 'event' / 'img1')."""
    folder = Path(folder)
    out: dict[str, MotTrack] = {}
    layouts = dict(MMUAV_MODALITIES)
    layouts["img1"] = ("img1", "gt", "seqinfo.ini")
    for modality, (im_dir, gt_dir, ini) in layouts.items():
        gt_path = folder / gt_dir / "gt.txt"
        if not (folder / im_dir).is_dir() and not gt_path.is_file():
            continue
        info = read_seqinfo(folder / ini) if (folder / ini).is_file() else {}
        ext = info.get("imExt", ".jpg")
        frames = sorted((folder / im_dir).glob(f"*{ext}")) if (folder / im_dir).is_dir() else []
        gt = read_gt(gt_path) if gt_path.is_file() else np.zeros((0, 9))
        out[modality] = MotTrack(folder.name, modality, info, frames, gt, sorted({int(f) for f in gt[:, 0]}))
    if not out:
        raise FileNotFoundError(f"{folder}: not an MM-UAV/MOT sequence folder")
    return out


def find_sequences(root: Path) -> list[Path]:
    """Sequence folders under ``root`` (any depth), identified by a seqinfo*.ini file."""
    return sorted({p.parent for p in Path(root).rglob("seqinfo*.ini")})


def load_dataset(root: Path) -> dict[str, dict[str, MotTrack]]:
    root = Path(root)
    return {p.relative_to(root).as_posix(): load_sequence(p) for p in find_sequences(root)}
