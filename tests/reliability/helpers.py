"""Shared helpers of the reliability tests: run the CLI in a subprocess, digest a tree."""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def evids(*args: str, cwd: Path | None = None, timeout: float = 600,
          env: dict | None = None) -> subprocess.CompletedProcess:
    """`evids ARGS` in a fresh interpreter with this tree first on the path."""
    full_env = {**os.environ, "PYTHONPATH": str(ROOT), **(env or {})}
    full_env.pop("EVIDS_DEBUG", None)
    return subprocess.run([sys.executable, "-c", "from harness.cli import main; main()", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd, timeout=timeout, env=full_env)


def tree_digest(folder: Path) -> dict[str, str]:
    """sha256 of every file (hidden ones included) by relative path; links by target."""
    out = {}
    for p in sorted(Path(folder).rglob("*")):
        rel = p.relative_to(folder).as_posix()
        if p.is_symlink():
            out[rel] = "link:" + os.readlink(p)
        elif p.is_file():
            out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out
