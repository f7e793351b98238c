"""MM-UAV / MOT loaders: ``<seq>/{rgb_frame,ir_frame}/0001.jpg``, ``gt_rgb/gt.txt``, ``gt_ir/gt.txt``,
``seqinfo-rgb.ini``, ``seqinfo-ir.ini`` (also plain MOT ``img1/``, ``gt/gt.txt``, ``seqinfo.ini``).

gt.txt rows: ``frame,id,left,top,w,h,consider,class,visibility`` (1-based frame and id; MM-UAV
drones are class 0; evids exports distractors as consider 0, class 1 bird / 2 aircraft).
"""
from __future__ import annotations

import configparser
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

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
