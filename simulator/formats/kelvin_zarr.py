"""Thermal kelvin stacks as chunked Zarr v3 arrays (the optional ``zarr`` extra): spec, writer, reader.

Why: the native layout stores thermal frames as lossless 16-bit count PNGs (one file per frame);
array tools (xarray, dask, napari) read a whole kelvin stack, or any frame range, faster from one
chunked array. ``evids export DATASET --format zarr --out X`` writes, per sequence::

    X/<split>/<sequence>.zarr    Zarr v3 array, float32 kelvin, shape (frames, height, width),
                                 one chunk per frame, zstd (level 3) compressed
      attributes: sequence, split, frame_rate_hz, kelvin_per_count, source

The values equal :func:`simulator.formats.native.load_thermal_kelvin` exactly (counts x
kelvin_per_count in float32), so the export loses nothing the native layout holds. Writing is
deterministic: the same dataset gives byte-identical stores.
"""
from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

SPEC = {
    "layout": "<split>/<sequence>.zarr",
    "array": "float32 kelvin (frames, height, width), Zarr v3, one chunk per frame, zstd level 3",
    "attributes": ("sequence", "split", "frame_rate_hz", "kelvin_per_count", "source"),
}
ZSTD_LEVEL = 3


def _zarr():
    try:
        import zarr
    except ImportError:
        from scenes.errors import UserInputError

        raise UserInputError("--format zarr needs the optional zarr extra: pip install -e '.[zarr]'") from None
    return zarr


def write_kelvin_stack(sequence_dir: Path, out_path: Path, *, sequence: str, split: str) -> Path:
    """One native sequence's thermal frames as a float32 kelvin Zarr array at ``out_path``."""
    from simulator.formats.native import load_labels, load_meta, load_thermal_kelvin

    zarr = _zarr()
    from zarr.codecs import ZstdCodec

    meta, labels = load_meta(sequence_dir), load_labels(sequence_dir)
    kpc = meta["cameras"]["thermal"]["kelvin_per_count"]
    indices = [f["index"] for f in labels["frames"]]
    frames = (load_thermal_kelvin(sequence_dir, index, kpc) for index in indices)
    first = next(frames)
    array = zarr.create_array(store=str(out_path), shape=(len(indices), *first.shape), dtype="float32",
                              chunks=(1, *first.shape), compressors=ZstdCodec(level=ZSTD_LEVEL),
                              fill_value=0.0, zarr_format=3)
    array[0] = first
    for k, kelvin in enumerate(frames, start=1):
        array[k] = kelvin
    array.attrs.update({"sequence": sequence, "split": split, "frame_rate_hz": meta["frame_rate_hz"],
                        "kelvin_per_count": kpc,
                        "source": "native thermal/ 16-bit counts x kelvin_per_count (float32)"})
    return out_path


def read_kelvin_stack(path: Path, frames: slice | None = None) -> tuple[np.ndarray, dict[str, Any]]:
    """(kelvin (frames, height, width) float32, attributes) of one exported stack; ``frames``
    reads only that range (one chunk per frame)."""
    zarr = _zarr()
    array = zarr.open_array(str(path), mode="r")
    if array.ndim != 3 or array.dtype != np.float32:
        raise ValueError(f"{path}: not a kelvin stack (expected float32 (frames, height, width), "
                         f"got {array.dtype} {array.shape})")
    return np.asarray(array[frames if frames is not None else slice(None)]), dict(array.attrs)


def export_kelvin_zarr(entries: Iterable[dict[str, Any]], out: Path, *, progress: bool = False) -> Path:
    """Kelvin stacks of native manifest entries (name, split, path) under ``out``."""
    _zarr()  # fail before writing anything when the extra is missing
    items = list(entries)
    if progress:
        from rich.progress import track

        items = list(track(items, description="export zarr"))
    for e in items:
        (Path(out) / e["split"]).mkdir(parents=True, exist_ok=True)
        write_kelvin_stack(Path(e["path"]), Path(out) / e["split"] / f"{e['name']}.zarr",
                           sequence=e["name"], split=e["split"])
    return Path(out)
