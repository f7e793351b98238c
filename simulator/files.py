"""How the project touches disk: atomic files and folders, content hashes, and the package
versions recorded beside every written dataset or run.

One home for these so that every writer (formats, datasets, run folders) gets the same crash
safety: a file or folder appears under its final name only when complete.
"""
from __future__ import annotations

import hashlib
import os
import platform
import shutil
from contextlib import contextmanager
from importlib import metadata
from pathlib import Path
from typing import Iterator

HASH_FILE = "files.sha256"


def write_atomic(path: Path, data: str | bytes) -> None:
    """Write via a temporary sibling and rename (no half-written file on failure)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    if isinstance(data, bytes):
        tmp.write_bytes(data)
    else:
        tmp.write_text(data)
    os.replace(tmp, path)


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
    try:
        lines = listed_file.read_text().splitlines()
    except UnicodeDecodeError:
        return [HASH_FILE]
    for number, line in enumerate(lines, start=1):
        digest, sep, rel = line.partition("  ")
        if not sep or len(digest) != 64 or any(c not in "0123456789abcdef" for c in digest) or not rel:
            return [f"{HASH_FILE} (line {number} is not '<sha256>  <path>')"]
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


RENDER_PACKAGES = ("evids", "mitsuba", "drjit", "numpy", "colour-science", "opencv-python-headless")


def package_versions(packages: tuple[str, ...] = RENDER_PACKAGES) -> dict[str, str]:
    """Python and distribution versions, recorded in every written dataset or run."""
    out = {"python": platform.python_version()}
    for dist in packages:
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = "not installed"
    return out


