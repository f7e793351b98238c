"""One dataset driver for every dataset kind: safe output, lock, resume, executor, hashes, manifest.

A *dataset kind* (native sequences in :mod:`simulator.dataset.generate`, TRIDENT clips in
:mod:`simulator.dataset.trident`) says what its units are and how one unit is written, checked and
hashed; :func:`drive` owns everything around them, the same for every kind:

* the output rules: a missing or empty folder, or the same dataset (resumed), or a different one
  replaced only with ``overwrite`` (``simulator.files.check_output``);
* the dataset lock (one writer; a dead writer's stale lock and temporaries are cleared);
* the manifest as the journal: written first with ``"complete": false``, rewritten with the content
  hashes of the units finished so far (at most every ``JOURNAL_INTERVAL_S``, and whenever the run
  stops: done, a failure or Ctrl-C; a SIGKILL loses at most the last interval's records, whose units
  are written again), so a resumed run keeps every unit it recorded; last with
  ``"complete": true``; no timestamps, so a resumed run ends byte-identical to an
  uninterrupted one;
* the executor (:mod:`simulator.jobs`) with failures collected per unit: the other units finish and
  :class:`GenerationFailed` names the failed ones.
"""
from __future__ import annotations

import hashlib
import json
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Protocol

from scenes.errors import UserInputError
from simulator.files import LEASE_FILE, LOCK_FILE, DatasetLock, check_output, write_atomic

MANIFEST = "manifest.json"
JOURNAL_INTERVAL_S = 2.0   # at most one journal rewrite of the manifest per this many seconds (and one at the end)


class GenerationFailed(RuntimeError):
    """Some units failed; the others are complete and intact. ``failures`` maps name -> message."""

    def __init__(self, failures: dict[str, str], noun: str = "sequence"):
        self.failures = dict(failures)
        lines = [f"{len(failures)} {noun}(s) failed (the others are complete; re-run to retry):"]
        lines += [f"  {name}: {msg}" for name, msg in sorted(failures.items())]
        super().__init__("\n".join(lines))


@dataclass
class GenerationResult:
    out_dir: Path
    rendered: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    exports: dict[str, Path] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    linked: list[str] = field(default_factory=list)   # units hard-linked from an earlier dataset (``reuse_from``)


@dataclass
class VerifyReport:
    """What ``evids verify`` found: units absent, units whose files differ, a run not finished."""

    checked: int = 0
    missing: list[str] = field(default_factory=list)
    corrupt: dict[str, list[str]] = field(default_factory=dict)
    incomplete: bool = False
    noun: str = "sequence"

    @property
    def ok(self) -> bool:
        return not self.missing and not self.corrupt and not self.incomplete


@dataclass(frozen=True)
class Unit:
    """One independently written part of a dataset (a native sequence, a TRIDENT clip)."""

    name: str        # unique within the dataset; the manifest's key for its hash
    payload: Any     # what the kind's writer needs (picklable for process pools)


class DatasetKind(Protocol):
    """What :func:`drive` needs of a dataset kind."""

    noun: str        # "sequence", "clip": for messages

    @property
    def label(self) -> str:
        """Progress-bar label."""
        ...

    def identity(self) -> str:
        """sha256 naming this exact dataset (config, seed, plan): a folder holding another is refused."""
        ...

    def units(self) -> list[Unit]:
        """Every planned unit, in plan order."""
        ...

    def prepare(self, out: Path) -> None:
        """Create the layout's folders and remove what no planned unit owns (runs under the lock)."""
        ...

    def unit_ok(self, out: Path, unit: Unit, recorded_hash: str | None) -> bool:
        """True if the unit on disk is complete and intact (equal to ``recorded_hash`` when one is given)."""
        ...

    def unit_hash(self, out: Path, unit: Unit) -> str:
        """Content hash of the unit's files on disk."""
        ...

    def run(self, out: Path, todo: list[Unit], *, workers: int, progress: bool) -> Iterator[dict[str, Any]]:
        """Write the units of ``todo``; yield ``{"name", ["error"], ["notes"]}`` per unit as it finishes."""
        ...

    def manifest(self, units: list[Unit], hashes: dict[str, str], complete: bool, out: Path) -> dict[str, Any]:
        """The manifest (``dataset_id`` and ``complete`` included) with the hashes known so far."""
        ...


def write_manifest(out_dir: Path, manifest: dict[str, Any]) -> None:
    """Atomic: write a temporary file, then rename over manifest.json."""
    write_atomic(Path(out_dir) / MANIFEST, json.dumps(manifest, sort_keys=True, indent=1, allow_nan=False) + "\n")


def read_old_manifest(out: Path) -> dict[str, Any]:
    """The manifest already in ``out`` ({} when none or unreadable)."""
    try:
        old = json.loads((out / MANIFEST).read_text())
    except (OSError, ValueError):
        return {}
    return old if isinstance(old, dict) else {}


def clean_stale(folder: Path) -> None:
    """Remove temporary folders/files of killed runs (hidden .tmp-*/.old-*/.native-*). Called only by
    the holder of the dataset lock: every other writer of this dataset is then dead."""
    if not folder.is_dir():
        return
    for child in folder.iterdir():
        if child.name.startswith((".tmp-", ".old-", ".native-", f".{MANIFEST}.tmp-")):
            if child.is_dir():
                shutil.rmtree(child, ignore_errors=True)
            else:
                child.unlink(missing_ok=True)


def canonical_sha256(data: Any) -> str:
    """sha256 of ``data`` as canonical JSON (sorted keys, no spaces, no NaN)."""
    return hashlib.sha256(json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=False).encode()
                          ).hexdigest()


def drive(kind: DatasetKind, out_dir: str | Path, *, inputs: Iterable[Path] = (), overwrite: bool = False,
          workers: int = 1, progress: bool = True,
          finish: Callable[[GenerationResult], None] | None = None) -> GenerationResult:
    """Generate (or finish) the dataset ``kind`` plans into ``out_dir``; see the module docstring.

    Units already present and intact are kept; missing or corrupt ones are (re)written. Raises
    :class:`GenerationFailed` naming the failed units (the rest stay complete and recorded).
    ``finish`` runs on the complete dataset while the lock is still held (exports)."""
    out = Path(out_dir)
    if out.is_dir() and not (out / LOCK_FILE).exists() and any(out.iterdir()) and not (out / MANIFEST).is_file():
        raise UserInputError(f"output folder {str(out)!r} is not empty and holds no evids dataset; choose another "
                             "--out")
    check_output(out, inputs=inputs, overwrite=overwrite, allow_resume=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    lock = DatasetLock(out, "generate").acquire()
    try:
        result = _drive_locked(kind, out, lock, overwrite=overwrite, workers=workers, progress=progress)
        if finish is not None:
            finish(result)
        return result
    finally:
        lock.release()


def _drive_locked(kind: DatasetKind, out: Path, lock: DatasetLock, *, overwrite: bool, workers: int,
                  progress: bool) -> GenerationResult:
    notes = []
    if lock.stale:
        notes.append(f"removed a stale lock left by a dead run (pid {lock.stale.get('pid', '?')} on host "
                     f"{lock.stale.get('host', '?')}); its unfinished work is redone")
    identity = kind.identity()
    units = kind.units()
    recorded: dict[str, str] = {}
    if (out / MANIFEST).is_file():
        old = read_old_manifest(out)
        if old.get("dataset_id") != identity:
            if not overwrite:
                raise UserInputError(
                    f"output folder {str(out)!r} holds a different dataset (its {MANIFEST} was made from another "
                    "config, seed or size); use a new --out, or --overwrite to replace it")
            for child in out.iterdir():  # everything but our own lock
                if child.name not in (LOCK_FILE, LEASE_FILE):
                    shutil.rmtree(child) if child.is_dir() and not child.is_symlink() else child.unlink()
        else:
            recorded = recorded_hashes(old)
    out.mkdir(parents=True, exist_ok=True)
    clean_stale(out)
    kind.prepare(out)
    todo = [u for u in units if not kind.unit_ok(out, u, recorded.get(u.name))]
    hashes = {u.name: recorded[u.name] for u in units if u not in todo and u.name in recorded}
    write_manifest(out, kind.manifest(units, hashes, False, out))
    result = GenerationResult(out_dir=out, skipped=[u.name for u in units if u not in todo], notes=notes)
    failures: dict[str, str] = {}
    unit_notes: dict[str, list[str]] = {}
    finished: set[str] = set()
    by_name = {u.name: u for u in todo}
    last_journal = time.monotonic()
    try:
        for r in kind.run(out, todo, workers=workers, progress=progress):
            finished.add(r["name"])
            if "error" in r:
                failures[r["name"]] = r["error"]
                continue
            hashes[r["name"]] = kind.unit_hash(out, by_name[r["name"]])
            unit_notes[r["name"]] = list(r.get("notes", []))
            if time.monotonic() - last_journal >= JOURNAL_INTERVAL_S:   # a large manifest is not rewritten per unit
                write_manifest(out, kind.manifest(units, hashes, False, out))  # the journal a resumed run reads
                last_journal = time.monotonic()
    finally:  # whatever ended the loop (done, a failure, Ctrl-C), what finished is recorded
        write_manifest(out, kind.manifest(units, hashes, False, out))
    failures.update({u.name: "no result from the executor" for u in todo if u.name not in finished})
    if failures:
        raise GenerationFailed(failures, kind.noun)
    result.rendered = [u.name for u in todo]
    result.notes += [f"{name}: {note}" for name in sorted(unit_notes) for note in unit_notes[name]]
    hashes = {u.name: hashes.get(u.name) or kind.unit_hash(out, u) for u in units}
    write_manifest(out, kind.manifest(units, hashes, True, out))
    return result


def recorded_hashes(manifest: dict[str, Any]) -> dict[str, str]:
    """name -> content hash of every unit a manifest records (native ``sequences``, TRIDENT ``clips``)."""
    entries = manifest.get("sequences", manifest.get("clips", []))
    if not isinstance(entries, list):
        return {}
    return {str(e["name"]): e["content_sha256"] for e in entries if isinstance(e, dict) and "name" in e
            and isinstance(e.get("content_sha256"), str)}
