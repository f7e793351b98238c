"""The native per-sequence layout (documented in docs/NATIVE_FORMAT.md): writer and reader.

Files are written deterministically (sorted JSON keys, rounded floats, fixed PNG settings) so the
same scenario and seed give byte-identical folders. A sequence is written into a temporary sibling
folder and renamed into place only when complete.
"""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

FORMAT_VERSION = 1
# PNG encoder settings, measured on rendered frames (docs/BENCHMARKS.md, "PNG level" and "PNG row
# filter and zlib strategy"; benchmarks/png_encode.py): zlib level 1 (levels >= 6 cost 2-30x more
# for < 25 % smaller files), zlib's run-length strategy (string matching finds little in sensor
# noise; runs of equal bytes are what filtered sky and masks hold) and one fixed row filter instead
# of libpng's per-row trial of all five: Sub for colour (neighbouring pixels), Up for single-channel
# images (the row above). Half the encode time of libpng's adaptive choice and smaller files.
# Lossless either way: the pixels are the same whatever the settings, only the file bytes change.
PNG_COMPRESSION = 1
PNG_STRATEGY = cv2.IMWRITE_PNG_STRATEGY_RLE
PNG_FILTER_COLOUR = cv2.IMWRITE_PNG_FILTER_SUB
PNG_FILTER_SINGLE_CHANNEL = cv2.IMWRITE_PNG_FILTER_UP


def frame_name(index0: int, ext: str) -> str:
    """Native and Anti-UAV frame files are 1-based, 6 digits: 000001.png."""
    return f"{index0 + 1:06d}.{ext}"


#: per-frame image folders of a native sequence (one PNG per frame in each)
FRAME_FOLDERS = ("rgb", "thermal", "thermal_agc", "masks/rgb", "masks/thermal")
#: per-sequence files of a native sequence (besides files.sha256)
SEQUENCE_FILES = ("labels.json", "meta.json", "scenario.yaml", "timeline.npz")


def sequence_files(n_frames: int) -> list[str]:
    """Every file a complete native sequence of ``n_frames`` holds (posix relative paths)."""
    return list(SEQUENCE_FILES) + [f"{d}/{frame_name(i, 'png')}" for d in FRAME_FOLDERS for i in range(n_frames)]


def png_params(image: np.ndarray) -> list[int]:
    """cv2.imwrite/imencode parameters of the native PNG settings for this image (the strategy after
    the level: OpenCV resets the strategy when it reads a level)."""
    row_filter = PNG_FILTER_COLOUR if image.ndim == 3 else PNG_FILTER_SINGLE_CHANNEL
    return [cv2.IMWRITE_PNG_COMPRESSION, PNG_COMPRESSION, cv2.IMWRITE_PNG_STRATEGY, PNG_STRATEGY,
            cv2.IMWRITE_PNG_FILTER, row_filter]


def write_png(path: Path, image: np.ndarray) -> None:
    """An RGB (H, W, 3) or single-channel 8/16-bit image as PNG with the native settings."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    if not cv2.imwrite(str(path), image, png_params(image)):
        raise OSError(f"could not write {path}")


def write_jpeg(path: Path, image: np.ndarray, quality: int = 95) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    if not cv2.imwrite(str(path), image, [cv2.IMWRITE_JPEG_QUALITY, quality]):
        raise OSError(f"could not write {path}")


def read_image(path: Path) -> np.ndarray:
    """Read PNG/JPEG unchanged (16-bit stays 16-bit); colour images come back as RGB."""
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise OSError(f"could not read image {path}")
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
    return image


def write_json(path: Path, data) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, sort_keys=True, indent=1, allow_nan=False) + "\n")


def load_meta(sequence_dir: Path) -> dict:
    return json.loads((Path(sequence_dir) / "meta.json").read_text())


def load_labels(sequence_dir: Path) -> dict:
    return json.loads((Path(sequence_dir) / "labels.json").read_text())


def load_thermal_kelvin(sequence_dir: Path, index0: int, kelvin_per_count: float | None = None) -> np.ndarray:
    """float32 radiometric temperature of frame index0 (0-based) from the 16-bit counts
    (``kelvin_per_count``: the sequence's scale when the caller has read meta.json already)."""
    if kelvin_per_count is None:
        kelvin_per_count = load_meta(sequence_dir)["cameras"]["thermal"]["kelvin_per_count"]
    counts = read_image(Path(sequence_dir) / "thermal" / frame_name(index0, "png"))
    return counts.astype(np.float32) * np.float32(kelvin_per_count)


def load_rgb(sequence_dir: Path, index0: int) -> np.ndarray:
    return read_image(Path(sequence_dir) / "rgb" / frame_name(index0, "png"))


def load_mask(sequence_dir: Path, camera: str, index0: int) -> np.ndarray:
    return read_image(Path(sequence_dir) / "masks" / camera / frame_name(index0, "png"))
