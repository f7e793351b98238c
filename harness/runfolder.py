"""Run-folder I/O shared by the experiment runners (which write) and the report (which reads): the
one checked way a command creates its run folder, JSON and CSV written atomically, and the
per-stage record in ``run.json`` (with the environment: git commit, lock hash, numeric dependency
versions; see simulator.files.environment_record)."""
from __future__ import annotations

import csv
import io
import json
import time
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from simulator.files import check_output, environment_record, write_atomic, write_marker


def create_run_folder(out: Path, *, inputs: Iterable[Path] = (), kind: str = "run") -> Path:
    """Create (or resume) a command's run folder the one checked way: the safe-output rule
    (``simulator.files.check_output``: new, empty or an earlier evids run; never the current
    folder, home, a root or anything overlapping ``inputs``; UserInputError otherwise), then the
    folder and its evids marker. Every command that writes a run folder starts here."""
    out = Path(out)
    check_output(out, inputs=inputs, allow_resume=True)
    out.mkdir(parents=True, exist_ok=True)
    write_marker(out, kind)
    return out


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        return float(x) if np.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def write_json(path: Path, obj: Any) -> None:
    write_atomic(path, json.dumps(_jsonable(obj), indent=1))


def write_csv(path: Path, rows: Sequence[Mapping[str, Any]]) -> None:
    buf = io.StringIO()
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    w = csv.DictWriter(buf, fieldnames=keys)
    w.writeheader()
    for r in rows:
        w.writerow({k: (json.dumps(_jsonable(v)) if isinstance(v, (list, tuple, dict)) else v) for k, v in r.items()})
    write_atomic(path, buf.getvalue())


def read_run(run_dir: Path) -> dict:
    p = run_dir / "run.json"
    return json.loads(p.read_text()) if p.is_file() else {"stages": {}}


def mark_stage(run_dir: Path, stage: str, seconds: float, extra: dict | None = None) -> None:
    run = read_run(run_dir)
    run.setdefault("stages", {})[stage] = {"seconds": round(seconds, 2), "finished_utc": time.strftime(
        "%Y-%m-%dT%H:%M:%SZ", time.gmtime()), **(extra or {})}
    run["environment"] = environment_record()  # every run folder (train, demo, detect) marks stages
    write_json(run_dir / "run.json", run)


