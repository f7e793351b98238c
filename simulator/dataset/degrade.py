"""Apply a degradation spec to native sequences and write degraded copies (the stored-copy path of
`evids degrade`; the usual path applies specs at load time with degradations.spec.apply_spec).

Streaming, for every spec (:mod:`degradations.stream`): the spec is planned from the sequence's
metadata alone (row times, fps, frame size, seed), then each output frame is computed and written
in turn, so memory stays constant whatever the sequence length. Frame-local entries (noise, blur,
glare, crossover, ...) act on each frame with per-frame draws keyed by the frame index; clip-level
entries (frame drop/freeze, desync, frame-rate mismatch, misalignment, dropout, decoy tracks) have
per-run params as in apply_spec: a retime reads the input frame it shows (a frozen frame is held
one deep), a decoy is drawn at the frame's place on its run's track. Masks and boxes follow each
frame through the stages. The record says ``"streamed": true``.

Each output sequence is written into a temporary sibling, completed with ``degradation_record.json``,
``files.sha256`` and the evids marker, and only then renamed into place (the completion marker);
links inside the input are refused, never followed.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from scenes.errors import UserInputError
from simulator.files import HASH_FILE, atomic_folder, check_output, copy_tree_no_symlinks, inside, write_hashes
from simulator.formats.native import (
    frame_name,
    load_labels,
    load_mask,
    load_meta,
    load_rgb,
    load_thermal_kelvin,
    write_json,
    write_png,
)
from simulator.sensors.encode import agc_8bit, kelvin_to_counts

RECORD_FILE = "degradation_record.json"
#: folders rewritten with degraded frames (not copied from the input)
_REWRITTEN = ("rgb", "thermal", "thermal_agc")


def find_sequences(dataset: Path) -> list[Path]:
    """A native sequence folder itself, or every sequence folder directly below ``dataset``."""
    dataset = Path(dataset)
    if (dataset / "meta.json").is_file():
        return [dataset]
    found = sorted(p.parent for p in dataset.glob("*/meta.json") if not p.parent.is_symlink())
    if not found:
        raise UserInputError(f"{dataset}: no native sequence here (expected meta.json in it or in its sub-folders)")
    return found


def _frame_meta(info: dict, labels: dict, sequence: Path, frames: slice) -> tuple[dict, np.ndarray]:
    """Meta and row times of ``frames`` (a slice of frame indices) for apply_spec (the in-memory
    reference of benchmarks/degrade_memory.py and the tests)."""
    idx = range(*frames.indices(info["n_frames"]))
    mask = np.stack([load_mask(sequence, "thermal", i) for i in idx]) > 0
    rows = [labels["frames"][i] for i in idx]
    meta = {**_clip_meta(info), "thermal_mask": mask, "rgb_boxes": _boxes(rows)}
    return meta, _times(rows)


def _clip_meta(info: dict) -> dict:
    """The sequence's shared (not per-frame) meta keys."""
    return {"fps": info["frame_rate_hz"], "thermal_netd_k": info["cameras"]["thermal"]["netd_k"]}


def _times(rows: list[dict]) -> np.ndarray:
    return np.array([f["time_s"] for f in rows], dtype=np.float64)


def _boxes(rows: list[dict]) -> np.ndarray:
    return np.array([[*(f["rgb"][0]["box"] or [0, 0, 0, 0])] for f in rows], dtype=np.float64)


def _write_frames(tmp: Path, start: int, rgb: np.ndarray, kelvin: np.ndarray, kpc: float) -> None:
    if rgb.dtype != np.uint8:
        rgb = np.clip(np.rint(rgb * 255.0), 0, 255).astype(np.uint8)
    kelvin = np.asarray(kelvin, dtype=np.float32)
    for k in range(rgb.shape[0]):
        i = start + k
        write_png(tmp / "rgb" / frame_name(i, "png"), rgb[k])
        write_png(tmp / "thermal" / frame_name(i, "png"), kelvin_to_counts(kelvin[k], kpc))
        write_png(tmp / "thermal_agc" / frame_name(i, "png"), agc_8bit(kelvin[k])[0])


def degrade_sequence(sequence: Path, spec, out_dir: Path, seed: int, *, overwrite: bool = False) -> Path:
    """Write ``out_dir/<name>/``: the sequence with degraded rgb/thermal frames and the record."""
    from degradations.stream import plan_frames

    sequence = Path(sequence)
    check_output(Path(out_dir) / sequence.name, inputs=[sequence], overwrite=overwrite)
    final = Path(out_dir) / sequence.name
    inside(final, Path(out_dir))
    info, labels = load_meta(sequence), load_labels(sequence)
    n = int(info["n_frames"])
    kpc = info["cameras"]["thermal"]["kelvin_per_count"]
    rows = labels["frames"][:n]
    if len(rows) != n:
        raise UserInputError(f"{sequence}: labels.json has {len(labels['frames'])} frames, meta.json n_frames {n}")
    boxes = _boxes(rows)

    def read(stream: str, i: int) -> np.ndarray:
        return (load_rgb(sequence, i) if stream == "rgb" else load_thermal_kelvin(sequence, i, kpc))[None]

    def frame_meta(stream: str, i: int) -> dict:
        if stream == "rgb":
            return {"rgb_boxes": boxes[i:i + 1]}
        return {"thermal_mask": load_mask(sequence, "thermal", i)[None] > 0}

    shapes = {m: read(m, 0).shape[1:] for m in ("rgb", "thermal")}
    plan = plan_frames(spec, seed, _times(rows), _clip_meta(info), shapes)
    skip = {HASH_FILE} | {p.relative_to(sequence).as_posix() for d in _REWRITTEN if (sequence / d).is_dir()
                          for p in (sequence / d).iterdir()}
    with atomic_folder(final, overwrite=overwrite, kind="degrade") as tmp:
        copy_tree_no_symlinks(sequence, tmp, skip=skip)
        for i, frame in plan.frames(read, frame_meta):
            _write_frames(tmp, i, np.asarray(frame["rgb"]), frame["thermal"], kpc)
        public = {**plan.record(), "streamed": True}
        write_json(tmp / RECORD_FILE, _finite_or_null(json.loads(json.dumps(public, default=_jsonable))))
        write_hashes(tmp)
    return final


def _finite_or_null(value):
    """The record with NaN/inf measures as None (JSON null): e.g. crossover's contrast on a frame where
    the target is out of view is NaN, which strict JSON cannot hold."""
    if isinstance(value, float):
        return value if np.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite_or_null(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite_or_null(v) for v in value]
    return value


def _jsonable(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON-serialisable: {type(value).__name__}")
