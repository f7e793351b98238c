"""Apply a degradation spec to native sequences and write degraded copies (the stored-copy path of
`evids degrade`; the usual path applies specs at load time with degradations.spec.apply_spec)."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np

from scenes.errors import UserInputError
from simulator.files import atomic_folder, write_hashes
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


def find_sequences(dataset: Path) -> list[Path]:
    """A native sequence folder itself, or every sequence folder directly below ``dataset``."""
    dataset = Path(dataset)
    if (dataset / "meta.json").is_file():
        return [dataset]
    found = sorted(p.parent for p in dataset.glob("*/meta.json"))
    if not found:
        raise UserInputError(f"{dataset}: no native sequence here (expected meta.json in it or in its sub-folders)")
    return found


def _streams(sequence: Path) -> tuple[dict, dict, np.ndarray]:
    meta, labels = load_meta(sequence), load_labels(sequence)
    n = meta["n_frames"]
    rgb = np.stack([load_rgb(sequence, i) for i in range(n)])
    kelvin = np.stack([load_thermal_kelvin(sequence, i) for i in range(n)])
    mask = np.stack([load_mask(sequence, "thermal", i) for i in range(n)]) > 0
    times = np.array([f["time_s"] for f in labels["frames"]], dtype=np.float64)
    boxes = np.array([[*(f["rgb"][0]["box"] or [0, 0, 0, 0])] for f in labels["frames"]], dtype=np.float64)
    extra = {"fps": meta["frame_rate_hz"], "thermal_mask": mask, "rgb_boxes": boxes,
             "thermal_netd_k": meta["cameras"]["thermal"]["netd_k"]}
    return {"rgb": rgb, "thermal": kelvin}, extra, times


def degrade_sequence(sequence: Path, spec, out_dir: Path, seed: int) -> Path:
    """Write ``out_dir/<name>/``: the sequence with degraded rgb/thermal frames and the record."""
    from degradations.spec import apply_spec

    sequence = Path(sequence)
    streams, meta, times = _streams(sequence)
    degraded, record = apply_spec(spec, streams, meta, seed, times)
    info = load_meta(sequence)
    kpc = info["cameras"]["thermal"]["kelvin_per_count"]
    final = Path(out_dir) / sequence.name
    if final.resolve() == sequence.resolve():
        raise UserInputError(f"--out must differ from the dataset folder ({sequence})")
    with atomic_folder(final) as tmp:
        shutil.copytree(sequence, tmp, dirs_exist_ok=True)
        rgb = np.asarray(degraded["rgb"])
        if rgb.dtype != np.uint8:
            rgb = np.clip(np.rint(rgb * 255.0), 0, 255).astype(np.uint8)
        kelvin = np.asarray(degraded["thermal"], dtype=np.float32)
        for i in range(info["n_frames"]):
            write_png(tmp / "rgb" / frame_name(i, "png"), rgb[i])
            write_png(tmp / "thermal" / frame_name(i, "png"), kelvin_to_counts(kelvin[i], kpc))
            write_png(tmp / "thermal_agc" / frame_name(i, "png"), agc_8bit(kelvin[i])[0])
        public = {k: v for k, v in record.items() if k != "meta"}
        write_json(tmp / RECORD_FILE, json.loads(json.dumps(public, default=_jsonable)))
        write_hashes(tmp)
    return final


def _jsonable(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON-serialisable: {type(value).__name__}")
