"""The native per-sequence layout (documented in docs/NATIVE_FORMAT.md): writer and reader.

Files are written deterministically (sorted JSON keys, rounded floats, fixed PNG settings) so the
same scenario and seed give byte-identical folders. A sequence is written into a temporary sibling
folder and renamed into place only when complete.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

FORMAT_VERSION = 1
HASH_FILE = "files.sha256"


def frame_name(index0: int, ext: str) -> str:
    """Native and Anti-UAV frame files are 1-based, 6 digits: 000001.png."""
    return f"{index0 + 1:06d}.{ext}"


def write_png(path: Path, image: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    if not cv2.imwrite(str(path), image, [cv2.IMWRITE_PNG_COMPRESSION, 3]):
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


def hash_tree(folder: Path) -> dict[str, str]:
    """sha256 of every file under folder (except the hash file), keyed by posix relative path."""
    out = {}
    for path in sorted(p for p in folder.rglob("*") if p.is_file() and p.name != HASH_FILE):
        out[path.relative_to(folder).as_posix()] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def write_hashes(folder: Path) -> str:
    """Write files.sha256 (sha256sum format) and return the sequence content hash."""
    hashes = hash_tree(folder)
    lines = "".join(f"{digest}  {rel}\n" for rel, digest in hashes.items())
    (folder / HASH_FILE).write_text(lines)
    return hashlib.sha256(lines.encode()).hexdigest()


def verify_hashes(folder: Path) -> list[str]:
    """Relative paths that are missing, extra or whose bytes changed; empty when intact."""
    listed_file = folder / HASH_FILE
    if not listed_file.is_file():
        return [HASH_FILE]
    listed = {}
    for line in listed_file.read_text().splitlines():
        digest, rel = line.split("  ", 1)
        listed[rel] = digest
    actual = hash_tree(folder)
    return sorted(rel for rel in set(listed) | set(actual) if listed.get(rel) != actual.get(rel))


@contextmanager
def atomic_folder(final: Path, *, overwrite: bool = True) -> Iterator[Path]:
    """Yield a temporary sibling folder; on success rename it to ``final`` (replacing it if
    ``overwrite``); on any error remove it and leave ``final`` untouched."""
    final = Path(final)
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = final.parent / f".tmp-{final.name}-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if final.exists():
        if not overwrite:
            shutil.rmtree(tmp, ignore_errors=True)
            raise FileExistsError(f"{final} already exists")
        old = final.parent / f".old-{final.name}-{os.getpid()}"
        final.rename(old)
        tmp.rename(final)
        shutil.rmtree(old, ignore_errors=True)
    else:
        tmp.rename(final)


def load_meta(sequence_dir: Path) -> dict:
    return json.loads((Path(sequence_dir) / "meta.json").read_text())


def load_labels(sequence_dir: Path) -> dict:
    return json.loads((Path(sequence_dir) / "labels.json").read_text())


def load_thermal_kelvin(sequence_dir: Path, index0: int) -> np.ndarray:
    """float32 radiometric temperature of frame index0 (0-based) from the 16-bit counts."""
    meta = load_meta(sequence_dir)
    counts = read_image(Path(sequence_dir) / "thermal" / frame_name(index0, "png"))
    return counts.astype(np.float32) * np.float32(meta["cameras"]["thermal"]["kelvin_per_count"])


def load_rgb(sequence_dir: Path, index0: int) -> np.ndarray:
    return read_image(Path(sequence_dir) / "rgb" / frame_name(index0, "png"))


def load_mask(sequence_dir: Path, camera: str, index0: int) -> np.ndarray:
    return read_image(Path(sequence_dir) / "masks" / camera / frame_name(index0, "png"))
