"""Apply a degradation spec to native sequences and write degraded copies (the stored-copy path of
`evids degrade`; the usual path applies specs at load time with degradations.spec.apply_spec).

Streaming: a spec whose entries all act on each frame alone (:func:`degradations.spec.frame_local`:
noise, blur, glare, crossover, ...) is applied frame by frame (read one frame, degrade it, write
it), so memory stays constant whatever the sequence length; per-frame random draws are keyed by the
frame index. A spec with clip-level entries (frame drop/freeze, desync, decoy tracks) needs the
whole clip and is applied in memory (documented in docs/RELIABILITY.md).

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
    """Meta and row times of ``frames`` (a slice of frame indices) for apply_spec."""
    idx = range(*frames.indices(info["n_frames"]))
    mask = np.stack([load_mask(sequence, "thermal", i) for i in idx]) > 0
    rows = [labels["frames"][i] for i in idx]
    times = np.array([f["time_s"] for f in rows], dtype=np.float64)
    boxes = np.array([[*(f["rgb"][0]["box"] or [0, 0, 0, 0])] for f in rows], dtype=np.float64)
    meta = {"fps": info["frame_rate_hz"], "thermal_mask": mask, "rgb_boxes": boxes,
            "thermal_netd_k": info["cameras"]["thermal"]["netd_k"]}
    return meta, times


def _write_frames(tmp: Path, start: int, rgb: np.ndarray, kelvin: np.ndarray, kpc: float) -> None:
    if rgb.dtype != np.uint8:
        rgb = np.clip(np.rint(rgb * 255.0), 0, 255).astype(np.uint8)
    kelvin = np.asarray(kelvin, dtype=np.float32)
    for k in range(rgb.shape[0]):
        i = start + k
        write_png(tmp / "rgb" / frame_name(i, "png"), rgb[k])
        write_png(tmp / "thermal" / frame_name(i, "png"), kelvin_to_counts(kelvin[k], kpc))
        write_png(tmp / "thermal_agc" / frame_name(i, "png"), agc_8bit(kelvin[k])[0])


def _merge_records(parts: list[dict]) -> dict:
    """One record from per-frame records (rows concatenated, runs shifted to whole-stream indices)."""
    first = parts[0]
    merged = {k: first[k] for k in ("seed", "modalities", "compromised_at")}
    merged["t_s"] = [t for r in parts for t in r["t_s"]]
    for key in ("severity", "compromised", "missing"):
        merged[key] = {m: [v for r in parts for v in r[key][m]] for m in first["modalities"]}
    merged["conflict"] = [v for r in parts for v in r["conflict"]]
    applied = [{**a, "runs": []} for a in first["applied"]]
    for offset, r in enumerate(parts):
        for slot, a in zip(applied, r["applied"]):
            for run in a["runs"]:
                slot["runs"].append({**run, "start": run["start"] + offset, "stop": run["stop"] + offset})
    merged["applied"] = applied
    merged["skipped"] = first["skipped"]
    merged["streamed"] = True
    return merged


def degrade_sequence(sequence: Path, spec, out_dir: Path, seed: int, *, overwrite: bool = False) -> Path:
    """Write ``out_dir/<name>/``: the sequence with degraded rgb/thermal frames and the record."""
    from degradations.spec import apply_spec, frame_local

    sequence = Path(sequence)
    check_output(Path(out_dir) / sequence.name, inputs=[sequence], overwrite=overwrite)
    final = Path(out_dir) / sequence.name
    inside(final, Path(out_dir))
    info, labels = load_meta(sequence), load_labels(sequence)
    n = int(info["n_frames"])
    kpc = info["cameras"]["thermal"]["kelvin_per_count"]
    skip = {HASH_FILE} | {p.relative_to(sequence).as_posix() for d in _REWRITTEN if (sequence / d).is_dir()
                          for p in (sequence / d).iterdir()}
    with atomic_folder(final, overwrite=overwrite, kind="degrade") as tmp:
        copy_tree_no_symlinks(sequence, tmp, skip=skip)
        if frame_local(spec):
            parts = []
            for i in range(n):
                meta, times = _frame_meta(info, labels, sequence, slice(i, i + 1))
                streams = {"rgb": load_rgb(sequence, i)[None], "thermal": load_thermal_kelvin(sequence, i)[None]}
                degraded, record = apply_spec(spec, streams, meta, seed, times, frame_offset=i)
                _write_frames(tmp, i, np.asarray(degraded["rgb"]), degraded["thermal"], kpc)
                parts.append({k: v for k, v in record.items() if k != "meta"})
            public = _merge_records(parts)
        else:
            meta, times = _frame_meta(info, labels, sequence, slice(0, n))
            streams = {"rgb": np.stack([load_rgb(sequence, i) for i in range(n)]),
                       "thermal": np.stack([load_thermal_kelvin(sequence, i) for i in range(n)])}
            degraded, record = apply_spec(spec, streams, meta, seed, times)
            _write_frames(tmp, 0, np.asarray(degraded["rgb"]), degraded["thermal"], kpc)
            public = {k: v for k, v in record.items() if k != "meta"}
            public["streamed"] = False
        write_json(tmp / RECORD_FILE, json.loads(json.dumps(public, default=_jsonable)))
        write_hashes(tmp)
    return final


def _jsonable(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON-serialisable: {type(value).__name__}")
