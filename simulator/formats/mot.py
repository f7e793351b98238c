"""MM-UAV (MOT-style) layout and the MOTChallenge evaluation layout: writer, reader and spec
(docs/FORMATS.md, "MM-UAV").

Dataset layout, per split: ``<split>/<NNNN>/rgb_frame/0001.jpg``, ``ir_frame/0001.jpg`` (4 digits,
1-based), ``gt_rgb/gt.txt``, ``gt_ir/gt.txt``, ``seqinfo-rgb.ini``, ``seqinfo-ir.ini``.

Evaluation layout (what the MM-UAV toolkit, a TrackEval fork, reads as downloaded):
``gt/<BENCH>-<split>/<NNNN>/gt/gt.txt`` + ``seqinfo.ini`` and ``gt/seqmaps/<BENCH>-<split>.txt``
(``name`` header, one sequence per line) with BENCH ``MMMUAVrgb`` / ``MMMUAVir``; tracker results go to
``trackers/<tracker>/track_results_{rgb,ir}/<NNNN>.txt`` (the fork has no split level there).

gt.txt rows: ``frame,id,left,top,w,h,consider,class,visibility`` (1-based frame and id, pixels).
Classes are MM-UAV's: 0 ``drone``, 1 ``not_drone``. Distractors (birds, aircraft) are selectable:
``none`` (left out, the default: exactly MM-UAV), ``class`` (rows with consider 1, class 1, which the
toolkit treats as distractors: tracker boxes on them are neither TP nor FP), or ``file`` (drone-only
gt.txt plus the class-1 rows in ``distractors.txt`` beside it).

Reading validates every row: 6 to 10 numeric columns, integral frame within 1..seqLength, integral
id >= 1, finite box with w, h > 0, consider in {0, 1}, integral class >= 0, visibility in [0, 1],
(frame, id) unique; and the seqinfo: numeric seqLength/imWidth/imHeight/frameRate, the image
folder holding exactly seqLength files with the declared ``imExt`` and consecutive 1-based names.
``strict=False`` skips bad rows and records them in ``track.skipped``.
"""
from __future__ import annotations

import configparser
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from simulator.files import atomic_folder
from simulator.formats.native import (
    frame_name,
    load_labels,
    load_meta,
    read_image,
    write_jpeg,
)
from simulator.formats.validation import Checker, FormatError, Skipped, integral, read_text

MMUAV_CLASS_IDS = {"drone": 0, "not_drone": 1}
Distractors = Literal["none", "class", "file"]
DISTRACTOR_MODES = ("none", "class", "file")
DISTRACTOR_FILE = "distractors.txt"
MODALITIES = {"rgb": ("rgb_frame", "gt_rgb", "seqinfo-rgb.ini"), "thermal": ("ir_frame", "gt_ir", "seqinfo-ir.ini")}
BENCHMARKS = {"rgb": "MMMUAVrgb", "thermal": "MMMUAVir"}
TRACKER_SUB_FOLDERS = {"rgb": "track_results_rgb", "thermal": "track_results_ir"}


def mot_frame_name(index0: int) -> str:
    return f"{index0 + 1:04d}.jpg"


def distractor_mode(value: bool | str | None) -> str:
    """Normalise the distractor option: False/None -> 'none', True -> 'class', or a mode name."""
    if value is None or value is False:
        return "none"
    if value is True:
        return "class"
    if value not in DISTRACTOR_MODES:
        raise ValueError(f"distractors must be one of {', '.join(DISTRACTOR_MODES)}, got {value!r}")
    return str(value)


def gt_rows(labels: dict, camera: str, *, annotate_every: int = 1, distractors: bool | str = "none") -> list[str]:
    """gt.txt lines (sorted by frame, then id) for frames f with (f - 1) % annotate_every == 0.

    Drones: ``...,1,0,1``; with ``distractors='class'`` birds and aircraft too, as ``...,1,1,1``."""
    keep_distractors = distractor_mode(distractors) == "class"
    rows = []
    for frame in labels["frames"]:
        number = frame["index"] + 1
        if (number - 1) % annotate_every:
            continue
        for rec in sorted(frame[camera], key=lambda r: r["id"]):
            if not rec["exist"]:
                continue
            is_drone = rec["class"] == "drone"
            if not is_drone and not keep_distractors:
                continue
            x, y, w, h = rec["box"]
            cls = MMUAV_CLASS_IDS["drone" if is_drone else "not_drone"]
            rows.append(f"{number},{rec['id']},{x},{y},{w},{h},1,{cls},1")
    return rows


def seqinfo_text(name: str, im_dir: str, frame_rate_hz: float, length: int, width: int, height: int) -> str:
    return (f"[Sequence]\nname={name}\nimDir={im_dir}\nframeRate={int(round(frame_rate_hz))}\nseqLength={length}\n"
            f"imWidth={width}\nimHeight={height}\nimExt=.jpg\n")


def _lines(rows: list[str]) -> str:
    return "".join(r + "\n" for r in rows)


def export_mmuav(sequence_dir: Path, out_dir: Path, name: str, *, annotate_every: int = 1,
                 distractors: bool | str = "none") -> Path:
    """Write ``<out_dir>/<name>/`` in the MM-UAV dataset layout (atomically); returns it."""
    if annotate_every < 1:
        raise ValueError(f"annotate_every must be >= 1, got {annotate_every}")
    mode = distractor_mode(distractors)
    sequence_dir = Path(sequence_dir)
    meta, labels = load_meta(sequence_dir), load_labels(sequence_dir)
    n = meta["n_frames"]
    final = Path(out_dir) / name
    with atomic_folder(final) as tmp:
        for camera, (im_dir, gt_dir, ini) in MODALITIES.items():
            source = "rgb" if camera == "rgb" else "thermal_agc"
            for i in range(n):
                write_jpeg(tmp / im_dir / mot_frame_name(i), read_image(sequence_dir / source / frame_name(i, "png")))
            (tmp / gt_dir).mkdir(parents=True, exist_ok=True)
            (tmp / gt_dir / "gt.txt").write_text(_lines(gt_rows(labels, camera, annotate_every=annotate_every,
                                                                 distractors=mode)))
            if mode == "file":
                drone = set(gt_rows(labels, camera, annotate_every=annotate_every))
                extra = [r for r in gt_rows(labels, camera, annotate_every=annotate_every, distractors="class")
                         if r not in drone]
                (tmp / gt_dir / DISTRACTOR_FILE).write_text(_lines(extra))
            cam = meta["cameras"][camera]
            (tmp / ini).write_text(seqinfo_text(name, im_dir, meta["frame_rate_hz"], n, cam["width_px"],
                                                cam["height_px"]))
    return final


def write_eval_layout(dataset_root: Path, out: Path, splits: dict[str, list[str]]) -> Path:
    """The MOTChallenge evaluation layout under ``out/gt`` for MM-UAV sequences already written under
    ``dataset_root/<split>/<NNNN>/`` (``splits`` maps split -> sequence names); returns ``out/gt``."""
    gt_root = Path(out) / "gt"
    for split, names in sorted(splits.items()):
        for camera, (_, gt_dir, ini) in MODALITIES.items():
            bench = f"{BENCHMARKS[camera]}-{split}"
            for name in names:
                seq = Path(dataset_root) / split / name
                dest = gt_root / bench / name
                (dest / "gt").mkdir(parents=True, exist_ok=True)
                (dest / "gt" / "gt.txt").write_bytes((seq / gt_dir / "gt.txt").read_bytes())
                (dest / "seqinfo.ini").write_bytes((seq / ini).read_bytes())
            (gt_root / "seqmaps").mkdir(parents=True, exist_ok=True)
            (gt_root / "seqmaps" / f"{bench}.txt").write_text(_lines(["name", *names]))
    return gt_root


def tracker_rows(track: "MotTrack", *, every: int = 1, considered_only: bool = True) -> list[str]:
    """Tracker-result lines ``frame,id,x,y,w,h,1,-1,-1,-1`` from a track's drone gt rows (class 0)
    on frames f with (f - 1) % every == 0: the "ground truth as tracker" check."""
    rows = []
    for r in track.gt:
        if int(r[7]) != MMUAV_CLASS_IDS["drone"] or (considered_only and r[6] == 0) or (int(r[0]) - 1) % every:
            continue
        rows.append(f"{int(r[0])},{int(r[1])},{r[2]:g},{r[3]:g},{r[4]:g},{r[5]:g},1,-1,-1,-1")
    return rows


# --------------------------------------------------------------------------------------------
# Reader
# --------------------------------------------------------------------------------------------

MMUAV_MODALITIES = {"rgb": ("rgb_frame", "gt_rgb", "seqinfo-rgb.ini"), "ir": ("ir_frame", "gt_ir", "seqinfo-ir.ini"),
                    "event": ("event_frame", "gt_event", "seqinfo-event.ini")}
GT_COLUMNS = ("frame", "id", "left", "top", "width", "height", "consider", "class", "visibility")
_DEFAULTS = (1.0, 0.0, 1.0)        # consider, class, visibility of 6-column rows
_NUMBER_RE = re.compile(r"(\d+)$")


@dataclass
class MotTrack:
    """One modality of a sequence: seqinfo fields, frame paths, and gt rows (N, 9) float64.

    ``distractors`` holds the rows of ``distractors.txt`` when present; ``skipped`` the rows a
    non-strict read left out."""

    name: str
    modality: str
    seqinfo: dict[str, str]
    frames: list[Path]
    gt: np.ndarray
    annotated_frames: list[int] = field(default_factory=list)
    distractors: np.ndarray = field(default_factory=lambda: np.zeros((0, 9)))
    skipped: Skipped = field(default_factory=Skipped)

    def boxes(self, frame: int, *, considered_only: bool = True) -> dict[int, list[float]]:
        """{id: [left, top, w, h]} on 1-based ``frame``."""
        rows = self.gt[self.gt[:, 0] == frame]
        if considered_only:
            rows = rows[rows[:, 6] != 0]
        return {int(r[1]): [float(v) for v in r[2:6]] for r in rows}


def _row_problem(values: list[float], seq_length: int | None) -> str | None:
    frame, ident, _, _, w, h, consider, cls, vis = values
    if not integral(frame) or frame < 1:
        return f"frame must be an integer >= 1, got {frame:g}"
    if seq_length is not None and frame > seq_length:
        return f"frame {frame:g} is beyond seqLength {seq_length}"
    if not integral(ident) or ident < 1:
        return f"id must be an integer >= 1, got {ident:g}"
    if not all(np.isfinite(values[2:6])):
        return "box values must be finite"
    if w <= 0 or h <= 0:
        return f"box width and height must be > 0, got {w:g} x {h:g}"
    if consider not in (0.0, 1.0):
        return f"consider (column 7) must be 0 or 1, got {consider:g}"
    if not integral(cls) or cls < 0:
        return f"class (column 8) must be an integer >= 0, got {cls:g}"
    if not 0.0 <= vis <= 1.0:
        return f"visibility (column 9) must be in [0, 1], got {vis:g}"
    return None


def read_gt(path: Path, *, seq_length: int | None = None, strict: bool = True,
            skipped: Skipped | None = None) -> np.ndarray:
    """gt.txt as an (N, 9) float64 array (6-column rows get consider 1, class 0, visibility 1),
    every row checked against the spec (see the module docstring)."""
    check = Checker(path, strict, skipped)
    rows, seen = [], set()
    for number, line in enumerate(read_text(path).splitlines(), start=1):
        line = line.strip()
        if not line:
            continue
        fields = [v for v in re.split(r"[,\s]+", line) if v != ""]
        if not 6 <= len(fields) <= 10:
            check.bad_row(f"line {number}", f"expected 6 to 10 comma-separated values, got {len(fields)}")
            continue
        try:
            values = [float(v) for v in fields]
        except ValueError:
            check.bad_row(f"line {number}", f"values must be numbers, got {line[:60]!r}")
            continue
        values = (values + list(_DEFAULTS[len(values) - 6:]))[:9] if len(values) < 9 else values[:9]
        problem = _row_problem(values, seq_length)
        if problem is None and (values[0], values[1]) in seen:
            problem = f"id {values[1]:g} appears twice on frame {values[0]:g}"
        if problem is not None:
            check.bad_row(f"line {number}", problem)
            continue
        seen.add((values[0], values[1]))
        rows.append(values)
    check.finish()
    return np.asarray(rows, dtype=np.float64).reshape(-1, 9)


def read_seqinfo(path: Path) -> dict[str, str]:
    """The ``[Sequence]`` section of a seqinfo*.ini, with numeric fields checked."""
    parser = configparser.ConfigParser()
    parser.optionxform = str  # type: ignore[assignment,method-assign]  # keep keys' case (documented use)
    try:
        parser.read_string(read_text(path))
    except configparser.Error as exc:
        raise FormatError(path, "", f"not a valid ini file ({str(exc).splitlines()[0]})") from None
    if not parser.sections():
        raise FormatError(path, "", "no [Sequence] section")
    section = "Sequence" if parser.has_section("Sequence") else parser.sections()[0]
    info = dict(parser[section])
    for key in ("seqLength", "imWidth", "imHeight"):
        if key in info and not (info[key].strip().isdigit() and int(info[key]) > 0):
            raise FormatError(path, f"key '{key}'", f"must be a positive integer, got {info[key]!r}")
    if "frameRate" in info:
        try:
            ok = float(info["frameRate"]) > 0
        except ValueError:
            ok = False
        if not ok:
            raise FormatError(path, "key 'frameRate'", f"must be a positive number, got {info['frameRate']!r}")
    return info


def _frames(folder: Path, info: dict[str, str], ini: Path) -> list[Path]:
    """Frames with the declared imExt, consecutive 1-based, as many as seqLength (when given)."""
    if not folder.is_dir():
        return []
    ext = info.get("imExt", ".jpg")
    files = [p for p in folder.iterdir() if p.is_file() and not p.name.startswith(".")]
    frames = [p for p in files if p.name.endswith(ext)]
    if files and not frames:
        found = sorted({p.suffix for p in files})
        raise FormatError(ini, "key 'imExt'", f"is {ext!r} but {folder.name}/ holds {', '.join(found)} files")
    indexed = []
    for p in frames:
        m = _NUMBER_RE.search(p.name[: -len(ext)])
        if m is None:
            raise FormatError(p, "file name", "frame name must be its 1-based number (0001.jpg)")
        indexed.append((int(m.group(1)), p))
    indexed.sort()
    for expected, (i, p) in enumerate(indexed, start=1):
        if i != expected:
            raise FormatError(folder, "frame numbers", f"frame {expected} is missing (next file is {p.name})")
    if "seqLength" in info and indexed and len(indexed) != int(info["seqLength"]):
        raise FormatError(ini, "key 'seqLength'",
                          f"is {info['seqLength']} but {folder.name}/ holds {len(indexed)} frames")
    return [p for _, p in indexed]


def load_sequence(folder: Path, *, strict: bool = True) -> dict[str, MotTrack]:
    """Tracks of one MM-UAV (or plain MOT / evaluation-layout) sequence folder by modality
    ('rgb', 'ir', 'event', or 'img1' for ``gt/gt.txt`` + ``seqinfo.ini``)."""
    folder = Path(folder)
    out: dict[str, MotTrack] = {}
    layouts = dict(MMUAV_MODALITIES)
    layouts["img1"] = ("img1", "gt", "seqinfo.ini")
    for modality, (im_dir, gt_dir, ini) in layouts.items():
        gt_path = folder / gt_dir / "gt.txt"
        if not (folder / im_dir).is_dir() and not gt_path.is_file():
            continue
        info = read_seqinfo(folder / ini) if (folder / ini).is_file() else {}
        image_dir = folder / info.get("imDir", im_dir) if modality == "img1" else folder / im_dir
        frames = _frames(image_dir, info, folder / ini)
        length = int(info["seqLength"]) if "seqLength" in info else None
        skipped = Skipped()
        gt = read_gt(gt_path, seq_length=length, strict=strict,
                     skipped=skipped) if gt_path.is_file() else np.zeros((0, 9))
        extra_path = folder / gt_dir / DISTRACTOR_FILE
        extra = (read_gt(extra_path, seq_length=length, strict=strict, skipped=skipped) if extra_path.is_file()
                 else np.zeros((0, 9)))
        out[modality] = MotTrack(folder.name, modality, info, frames, gt, sorted({int(f) for f in gt[:, 0]}),
                                 extra, skipped)
    if not out:
        raise FileNotFoundError(f"{folder}: not an MM-UAV/MOT sequence folder")
    return out


def find_sequences(root: Path, *, include_eval_copy: bool = False) -> list[Path]:
    """Sequence folders under ``root`` (any depth), identified by a seqinfo*.ini file. The evaluation
    copy our export writes under ``root/gt/`` (next to ``gt/seqmaps/``) is left out unless asked for
    or unless it is all there is (an evaluation layout on its own)."""
    root = Path(root)
    found = sorted({p.parent for p in root.rglob("seqinfo*.ini")})
    if include_eval_copy or not (root / "gt" / "seqmaps").is_dir():
        return found
    rest = [p for p in found if p.relative_to(root).parts[0] != "gt"]
    return rest or found


def load_dataset(root: Path, *, strict: bool = True, include_eval_copy: bool = False) -> dict[str, dict[str, MotTrack]]:
    """Every sequence under ``root`` keyed by its relative path (``test/0001``)."""
    root = Path(root)
    return {p.relative_to(root).as_posix(): load_sequence(p, strict=strict)
            for p in find_sequences(root, include_eval_copy=include_eval_copy)}
