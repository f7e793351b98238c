"""Generate a native dataset from a generation config: resumable, local process pool or Ray.

Layout (docs/DATASETS.md)::

    DIR/manifest.json             resolved config, seed, versions, per-sequence seed/split/hash
    DIR/sequences/seq000001/      native layout (docs/NATIVE_FORMAT.md), renamed into place whole
    DIR/<format>/                 optional exports (antiuav, antiuav_rgbt, antiuav2021, mot, coco, webdataset, zarr)

The manifest is written first with ``"complete": false`` and no hashes (so a resumed run can check
it is the same dataset), and rewritten at the end with the hashes; it holds no timestamps, so an
interrupted-and-resumed run ends byte-identical to an uninterrupted one.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

from scenes.errors import UserInputError, short_repr
from simulator.dataset.config import (
    GenerationConfig,
    load_generation_config,
    randomised_scenario,
    sequence_name,
    sequence_seed,
    split_assignment,
)
from simulator.files import (
    HASH_FILE,
    LEASE_FILE,
    LOCK_FILE,
    DatasetLock,
    check_output,
    check_plain_name,
    inside,
    verify_hashes,
    write_atomic,
)
from simulator.jobs import JobError, Start, iter_jobs, threads_per_worker

MANIFEST = "manifest.json"
SEQUENCES_DIR = "sequences"
DATASET_FORMAT = "evids-native-dataset"
EXPORT_FORMATS = ("antiuav", "antiuav_rgbt", "antiuav2021", "mot", "coco", "webdataset", "zarr")
TRIDENT_EXPORT_FORMATS = ("trident", "webdataset")     # formats a TRIDENT clip dataset exports to
EXECUTORS = ("local", "ray")


class GenerationFailed(RuntimeError):
    """Some sequences failed; the others are complete and intact. ``failures`` maps name -> message."""

    def __init__(self, failures: dict[str, str]):
        self.failures = dict(failures)
        lines = [f"{len(failures)} sequence(s) failed (the others are complete; re-run to retry):"]
        lines += [f"  {name}: {msg}" for name, msg in sorted(failures.items())]
        super().__init__("\n".join(lines))


@dataclass
class GenerationResult:
    out_dir: Path
    rendered: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    exports: dict[str, Path] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def _canonical(data: Any) -> str:
    return json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=False)


def plan_dataset(config: GenerationConfig, seed: int, base_dir: Path | None = None) -> list[dict[str, Any]]:
    """One task per sequence: name, index, mixture source, render seed, split, resolved scenario."""
    splits = split_assignment(config.splits, config.sequences)
    tasks = []
    for index in range(config.sequences):
        source, scenario = randomised_scenario(config, seed, index, base_dir)
        tasks.append({"index": index, "name": sequence_name(index), "source": source,
                      "seed": sequence_seed(seed, index),
                      "split": splits[index], "n_frames": config.frames, "scenario": scenario.model_dump(mode="json")})
    return tasks


def dataset_identity(config: GenerationConfig, seed: int, tasks: list[dict[str, Any]]) -> str:
    """sha256 over the resolved config, seed and every sequence's scenario/seed/split."""
    return hashlib.sha256(_canonical({"config": config.model_dump(mode="json"), "seed": int(seed),
                                      "tasks": tasks}).encode()).hexdigest()


def sequence_hash(sequence_dir: Path) -> str:
    """Content hash of a native sequence: sha256 of its files.sha256 (what write_hashes returns)."""
    return hashlib.sha256((Path(sequence_dir) / HASH_FILE).read_bytes()).hexdigest()


def _manifest(config: GenerationConfig, seed: int, tasks: list[dict[str, Any]], identity: str,
              hashes: dict[str, str] | None) -> dict[str, Any]:
    from simulator.files import package_versions

    sequences = []
    for t in tasks:
        sequences.append({"name": t["name"], "index": t["index"], "source": t["source"], "seed": t["seed"],
                          "split": t["split"], "n_frames": t["n_frames"],
                          "content_sha256": None if hashes is None else hashes[t["name"]]})
    return {
        "format": DATASET_FORMAT, "format_version": 1, "dataset_id": identity, "complete": hashes is not None,
        "config": config.model_dump(mode="json"), "seed": int(seed), "versions": package_versions(),
        "splits": {s: [t["name"] for t in tasks if t["split"] == s] for s in ("train", "val", "test")},
        "sequences": sequences,
    }


def write_manifest(out_dir: Path, manifest: dict[str, Any]) -> None:
    """Atomic: write a temporary file, then rename over manifest.json."""
    write_atomic(out_dir / MANIFEST, json.dumps(manifest, sort_keys=True, indent=1, allow_nan=False) + "\n")


def load_manifest(dataset_dir: Path) -> dict[str, Any]:
    path = Path(dataset_dir) / MANIFEST
    if not path.is_file():
        raise UserInputError(f"{dataset_dir} is not an evids dataset (no {MANIFEST})")
    try:
        manifest = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise UserInputError(f"{path}: not valid JSON: {exc}") from None
    if not isinstance(manifest, dict):
        raise UserInputError(f"{path}: expected a JSON object, got {type(manifest).__name__}")
    if manifest.get("format") != DATASET_FORMAT:
        raise UserInputError(f"{path}: format is {manifest.get('format')!r}, expected {DATASET_FORMAT!r}")
    return manifest


def missing_planned_files(seq_dir: Path, n_frames: int) -> list[str]:
    """Files the native layout says a sequence of ``n_frames`` must have that its files.sha256 does
    not list (so a sequence missing frames can never be certified, whatever its hash file says)."""
    from simulator.formats.native import sequence_files

    listed_file = Path(seq_dir) / HASH_FILE
    if not listed_file.is_file():
        return [HASH_FILE]
    listed = {line.split("  ", 1)[1] for line in listed_file.read_text(errors="replace").splitlines() if "  " in line}
    return sorted(set(sequence_files(n_frames)) - listed)


def _sequence_ok(seq_dir: Path, task: dict[str, Any], recorded_hash: str | None) -> bool:
    if (not (seq_dir / "meta.json").is_file() or verify_hashes(seq_dir)
        or missing_planned_files(seq_dir, task["n_frames"])):
        return False
    try:
        meta = json.loads((seq_dir / "meta.json").read_text())
    except json.JSONDecodeError:
        return False
    if meta.get("seed") != task["seed"] or meta.get("n_frames") != task["n_frames"]:
        return False
    return recorded_hash is None or sequence_hash(seq_dir) == recorded_hash


def _clean_stale(folder: Path) -> None:
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


# --------------------------------------------------------------------------------------------
# The task (runs in a worker process, a Ray worker, or in-process)
# --------------------------------------------------------------------------------------------

def render_task(task: dict[str, Any], sequences_dir: str, threads: int | None = None) -> dict[str, Any]:
    """Render one sequence; never raises: returns {"name", "hash"} or {"name", "error"}."""
    try:
        from scenes.schema import Scenario
        from simulator.dataset.sequence import WRITER_THREADS, render_sequence

        if threads is not None:
            from simulator.render.mitsuba_setup import load_mitsuba

            load_mitsuba()
            import drjit as dr

            dr.set_thread_count(int(threads))
            import cv2

            cv2.setNumThreads(int(threads))
        scenario = Scenario.model_validate(task["scenario"])
        cpu0 = time.process_time()
        # a worker limited to N threads also writes its PNGs on N threads (no oversubscription)
        writer_threads = WRITER_THREADS if threads is None else max(1, int(threads))
        render_ahead = threads is None or int(threads) > 1    # likewise: no render thread beside a 1-thread worker
        from simulator.dataset.sequence import PassTimes

        stages = PassTimes()
        wall0 = time.perf_counter()
        notes: list[str] = []
        written = render_sequence(scenario, task["seed"], Path(sequences_dir), n_frames=task["n_frames"],
                                  progress=False,
                                  times=stages, overwrite=True, notes=notes, writer_threads=writer_threads,
                                  render_ahead=render_ahead)
        stages.seconds["setup + metadata (rest)"] = time.perf_counter() - wall0 - sum(stages.seconds.values())
        return {"name": task["name"], "hash": sequence_hash(written["native"]), "cpu_s": time.process_time() - cpu0,
                "peak_rss_mb": _peak_rss_mb(), "pid": os.getpid(), "stage_s": stages.seconds,
                "notes": notes}
    except Exception as exc:  # reported per sequence by the driver; other sequences continue
        last = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
        where = f" at {Path(last.filename).name}:{last.lineno}" if last else ""
        return {"name": task["name"], "error": f"{type(exc).__name__}: {exc}{where}"}


def _peak_rss_mb() -> float:
    """Peak resident memory of this process in MB (Linux reports KB, macOS bytes)."""
    import resource
    import sys

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024 * 1024) if sys.platform == "darwin" else peak / 1024


def run_tasks(tasks: list[dict[str, Any]], sequences_dir: Path, *, workers: int = 1, executor: str = "local",
              ray_address: str | None = None, progress: bool = True, label: str = "generate",
              force_pool: bool = False) -> dict[str, dict[str, Any]]:
    """Run render tasks on the chosen executor with a driver-side progress bar; results by name.

    Local with one worker renders in-process (Dr.Jit uses every core); ``force_pool`` uses a
    one-process pool with 1 Dr.Jit thread per worker instead (for scaling benchmarks)."""
    if executor not in EXECUTORS:
        raise UserInputError(f"--executor must be one of {', '.join(EXECUTORS)}, got {executor!r}")
    start: Start
    if executor == "ray":
        start, threads = "ray", 1 if ray_address else threads_per_worker(workers)
    elif workers <= 1 and not force_pool:
        start, threads = "inline", None  # in-process: Dr.Jit uses every core
    else:
        start, threads = "forkserver", 1 if force_pool else threads_per_worker(workers)
    calls = [(t, str(sequences_dir), threads) for t in tasks]
    results: dict[str, dict[str, Any]] = {}
    for i, result in iter_jobs(render_task, calls, workers=workers, start=start, on_error="collect",
                               progress=label if progress else None, ray_address=ray_address):
        if isinstance(result, JobError):  # render_task never raises: its worker died, or Ray failed
            why = f"Ray task failed: {result.message}" if start == "ray" else f"worker process died ({result.error})"
            result = {"name": tasks[i]["name"], "error": why}
        results[result["name"]] = result
    return results


# --------------------------------------------------------------------------------------------
# Driver
# --------------------------------------------------------------------------------------------

def generate_dataset(config_or_name: str | Path | dict | GenerationConfig, out_dir: str | Path, seed: int, *,
                     sequences: int | None = None, frames: int | None = None, workers: int = 1,
                     executor: str = "local", ray_address: str | None = None, formats: Iterable[str] = ("native",),
                     overwrite: bool = False, progress: bool = True) -> GenerationResult:
    """Generate (or finish) the dataset in ``out_dir``; see the module docstring.

    Sequences already present and intact are kept; missing or corrupt ones are (re)rendered. An
    ``out_dir`` holding a different dataset is refused unless ``overwrite``. Raises
    :class:`GenerationFailed` naming the failed sequences (the rest stay complete).
    """
    if seed < 0:
        raise UserInputError(f"--seed must be >= 0, got {seed}")
    if workers < 1:
        raise UserInputError(f"--workers must be >= 1, got {workers}")
    if executor not in EXECUTORS:
        raise UserInputError(f"--executor must be one of {', '.join(EXECUTORS)}, got {executor!r}")
    formats = tuple(formats)
    bad = [f for f in formats if f != "native" and f not in EXPORT_FORMATS]
    if bad:
        raise UserInputError(f"--format: unknown format(s) {bad}; valid: native, {', '.join(EXPORT_FORMATS)}")
    config = load_generation_config(config_or_name)
    base_dir = (Path(config_or_name).resolve().parent if isinstance(config_or_name, (str, Path))
                and Path(config_or_name).is_file() else None)
    updates: dict[str, Any] = {}
    if sequences is not None:
        updates["sequences"] = sequences
    if frames is not None:
        updates["frames"] = frames
    if updates:
        from scenes.loader import validate_mapping

        config = validate_mapping(GenerationConfig, {**config.model_dump(mode="json"), **updates}, "command line")
    tasks = plan_dataset(config, seed, base_dir)
    identity = dataset_identity(config, seed, tasks)

    out = Path(out_dir)
    config_file = ([Path(config_or_name)] if isinstance(config_or_name, (str, Path)) and Path(config_or_name).is_file()
                   else [])
    if out.is_dir() and not (out / LOCK_FILE).exists() and any(out.iterdir()) and not (out / MANIFEST).is_file():
        raise UserInputError(f"output folder {str(out)!r} is not empty and holds no evids dataset; choose another "
                             "--out")
    check_output(out, inputs=config_file, overwrite=overwrite, allow_resume=True)
    lock = DatasetLock(out, "generate").acquire()
    try:
        return _generate_locked(out, config, seed, tasks, identity, lock, workers=workers, executor=executor,
                                ray_address=ray_address, formats=formats, overwrite=overwrite, progress=progress)
    finally:
        lock.release()


def _generate_locked(out: Path, config: GenerationConfig, seed: int, tasks: list[dict[str, Any]], identity: str,
                     lock: DatasetLock, *, workers: int, executor: str, ray_address: str | None,
                     formats: tuple[str, ...], overwrite: bool, progress: bool) -> GenerationResult:
    """The body of :func:`generate_dataset`, run while holding the dataset lock."""
    notes = []
    if lock.stale:
        notes.append(f"removed a stale lock left by a dead run (pid {lock.stale.get('pid', '?')} on host "
                     f"{lock.stale.get('host', '?')}); its unfinished work is redone")
    recorded: dict[str, str] = {}
    if (out / MANIFEST).is_file():
        try:
            old = json.loads((out / MANIFEST).read_text())
        except json.JSONDecodeError:
            old = {}
        if not isinstance(old, dict):
            old = {}
        if old.get("dataset_id") != identity:
            if not overwrite:
                raise UserInputError(
                    f"output folder {str(out)!r} holds a different dataset (manifest {MANIFEST} was made from another "
                    "config, seed, --sequences or --frames); use a new --out, or --overwrite to replace it")
            for child in out.iterdir():  # everything but our own lock
                if child.name not in (LOCK_FILE, LEASE_FILE):
                    shutil.rmtree(child) if child.is_dir() and not child.is_symlink() else child.unlink()
        else:
            entries = old.get("sequences", [])
            recorded = {s["name"]: s["content_sha256"] for s in entries if isinstance(s, dict)
                        and s.get("content_sha256")}
    out.mkdir(parents=True, exist_ok=True)
    seq_root = out / SEQUENCES_DIR
    seq_root.mkdir(exist_ok=True)
    _clean_stale(out)
    _clean_stale(seq_root)
    write_manifest(out, _manifest(config, seed, tasks, identity, None))

    wanted = {t["name"] for t in tasks}
    for child in seq_root.iterdir():
        if child.is_symlink():  # never followed: the link goes, its target stays
            child.unlink()
        elif child.is_dir() and child.name not in wanted:
            shutil.rmtree(child)
    todo = [t for t in tasks if not _sequence_ok(seq_root / t["name"], t, recorded.get(t["name"]))]
    result = GenerationResult(out_dir=out, skipped=[t["name"] for t in tasks if t not in todo], notes=notes)
    results = run_tasks(todo, seq_root, workers=workers, executor=executor, ray_address=ray_address,
                        progress=progress, label=f"generate {config.name}")
    failures = {name: r["error"] for name, r in results.items() if "error" in r}
    missing = [t["name"] for t in todo if t["name"] not in results]
    failures.update({name: "no result from the executor" for name in missing})
    if failures:
        raise GenerationFailed(failures)
    result.rendered = [t["name"] for t in todo]
    result.notes += [f"{name}: {note}" for name, r in sorted(results.items()) for note in r.get("notes", [])]
    hashes = {t["name"]: sequence_hash(seq_root / t["name"]) for t in tasks}
    write_manifest(out, _manifest(config, seed, tasks, identity, hashes))
    for fmt in formats:
        if fmt != "native":
            result.exports[fmt] = _export_locked(out, fmt, out / fmt, overwrite=True, progress=progress)
    return result


# --------------------------------------------------------------------------------------------
# Verify and export
# --------------------------------------------------------------------------------------------

@dataclass
class VerifyReport:
    checked: int = 0
    missing: list[str] = field(default_factory=list)
    corrupt: dict[str, list[str]] = field(default_factory=dict)
    incomplete: bool = False

    @property
    def ok(self) -> bool:
        return not self.missing and not self.corrupt and not self.incomplete


def verify_dataset(dataset_dir: str | Path, *, progress: bool = False) -> VerifyReport:
    """Re-hash every sequence against its files.sha256 and the manifest's content hash."""
    root = Path(dataset_dir)
    manifest = load_manifest(root)
    complete = manifest.get("complete", False) is True
    report = VerifyReport(incomplete=not complete)
    entries: Iterable[dict[str, Any]] = manifest_entries(manifest, root / MANIFEST)
    planned = manifest.get("config", {}).get("sequences") if isinstance(manifest.get("config"), dict) else None
    listed = {e["name"] for e in entries}
    if isinstance(planned, int):
        for index in range(planned):  # the manifest may not drop what the plan says exists
            if sequence_name(index) not in listed:
                report.corrupt[sequence_name(index)] = ["manifest.json (planned sequence not listed)"]
    if (root / SEQUENCES_DIR).is_dir():
        for child in sorted((root / SEQUENCES_DIR).iterdir()):
            if child.is_dir() and not child.name.startswith(".") and child.name not in listed:
                report.corrupt.setdefault(child.name, []).append("not listed in manifest.json")
    if progress:
        from rich.progress import track

        entries = track(entries, description="verify")
    for entry in entries:
        seq = root / SEQUENCES_DIR / entry["name"]
        report.checked += 1
        if not seq.is_dir():
            report.missing.append(entry["name"])
            continue
        bad = verify_hashes(seq) + _identity_problems(seq, entry)
        if not bad and isinstance(entry.get("n_frames"), int):
            bad = [f"{rel} (planned, absent)" for rel in missing_planned_files(seq, entry["n_frames"])]
        if not bad and complete and not entry.get("content_sha256"):
            bad = ["manifest.json (no content hash recorded for a complete dataset)"]
        if not bad and entry.get("content_sha256") and sequence_hash(seq) != entry["content_sha256"]:
            bad = [HASH_FILE]
        if bad:
            report.corrupt[entry["name"]] = bad
    return report


def manifest_entries(manifest: dict[str, Any], path: Path) -> list[dict[str, Any]]:
    """The manifest's ``sequences`` list, each entry checked to name a plain sequence folder."""
    entries = manifest.get("sequences")
    if not isinstance(entries, list):
        raise UserInputError(f"{path}: key 'sequences' is missing or not a list (not a complete evids manifest)")
    for k, e in enumerate(entries):
        name = e.get("name") if isinstance(e, dict) else None
        if not _plain(name):
            raise UserInputError(f"{path}: sequences[{k}].name must be a plain folder name, got {short_repr(name)}")
        split = e.get("split", "train")
        if not _plain(split):
            raise UserInputError(f"{path}: sequences[{k}].split must be a plain folder name, got {short_repr(split)}")
    return entries


def _plain(name: Any) -> bool:
    """A plain path component (simulator.files.check_plain_name's rule)."""
    try:
        check_plain_name(name, "name")
    except UserInputError:
        return False
    return True


def _identity_problems(seq: Path, entry: dict[str, Any]) -> list[str]:
    """A sequence folder holding another sequence (swapped folders): seed/frame count differ from the entry."""
    try:
        meta = json.loads((seq / "meta.json").read_text())
    except (OSError, ValueError):
        return ["meta.json (unreadable)"]
    if not isinstance(meta, dict):
        return ["meta.json (not a mapping)"]
    wrong = [k for k in ("seed", "n_frames") if k in entry and meta.get(k) != entry[k]]
    return [f"meta.json ({', '.join(wrong)} differ from the manifest: another sequence's folder?)"] if wrong else []


def dataset_sequences(dataset_dir: str | Path) -> list[dict[str, Any]]:
    """Manifest entries of a complete dataset, each with its ``path``."""
    root = Path(dataset_dir)
    manifest = load_manifest(root)
    if not manifest.get("complete"):
        raise UserInputError(f"{root}: the dataset is incomplete; re-run `evids generate` with the same arguments")
    entries = manifest_entries(manifest, root / MANIFEST)
    for e in entries:
        inside(root / SEQUENCES_DIR / e["name"], root / SEQUENCES_DIR)  # no link out of the dataset either
    return [{**e, "path": root / SEQUENCES_DIR / e["name"]} for e in entries]


def export_inputs(dataset_dir: str | Path, out_dir: str | Path) -> list[Path]:
    """What an export reads (and so may never overwrite or enclose): a native dataset's manifest and
    sequences/, or every top-level entry of a TRIDENT clip dataset except ``out_dir`` itself."""
    root, out = Path(dataset_dir), Path(out_dir)
    if _is_trident_dataset(root):
        return [c for c in sorted(root.iterdir()) if c.resolve() != out.resolve() and not c.name.startswith(".")]
    return [root / MANIFEST, root / SEQUENCES_DIR]


def export_dataset(dataset_dir: str | Path, fmt: str, out_dir: str | Path, *, annotate_every: int = 1,
                   distractors: bool | str | None = None, coco_naming: str = "evids", mfcc: str = "evids",
                   test_fraction: float = 0.2, shard_mb: float = 500.0, progress: bool = True,
                   overwrite: bool = False) -> Path:
    """Export a complete dataset (see :func:`_export_locked`) under the safe-output rule: ``out_dir``
    is new/empty, or an earlier evids export replaced only with ``overwrite``; never the dataset's
    manifest or data folders, nor a folder containing them. Holds the dataset lock."""
    root = Path(dataset_dir)
    out = Path(out_dir)
    if not (root / MANIFEST).is_file():
        raise UserInputError(f"{root} is not an evids dataset (no {MANIFEST})")
    check_output(out, inputs=export_inputs(root, out), overwrite=overwrite)
    with DatasetLock(root, f"export {fmt}", required=False):
        return _export_locked(root, fmt, out, annotate_every=annotate_every, distractors=distractors,
                              coco_naming=coco_naming, mfcc=mfcc, test_fraction=test_fraction, shard_mb=shard_mb,
                              progress=progress, overwrite=overwrite)


def _export_locked(dataset_dir: str | Path, fmt: str, out_dir: str | Path, *, annotate_every: int = 1,
                   distractors: bool | str | None = None, coco_naming: str = "evids", mfcc: str = "evids",
                   test_fraction: float = 0.2, shard_mb: float = 500.0, progress: bool = True,
                   overwrite: bool = False) -> Path:
    """Export a complete dataset to ``fmt`` under ``out_dir`` (docs/FORMATS.md); written to a temporary
    sibling and renamed, so a failure leaves ``out_dir`` as it was.

    Native datasets export to antiuav, antiuav_rgbt, antiuav2021, mot (MM-UAV dataset layout plus the
    MOTChallenge evaluation layout under ``gt/``), coco, webdataset and zarr (thermal kelvin stacks,
    the optional zarr extra); TRIDENT clip datasets (made by
    ``evids generate --format trident``) to trident (the public layout) and webdataset.

    ``distractors`` (birds, aircraft): mot default ``none`` (exactly MM-UAV); True or ``class`` = rows
    of class 1 ``not_drone``, ``file`` = a separate distractors.txt; coco default on (flagged
    categories); Anti-UAV is single-object (the first drone) either way. ``coco_naming``: ``evids`` or
    ``mmuav`` (``train-ir.json``, file_name from the dataset root). ``mfcc`` (trident): the MFCC
    pipeline recorded for readers, ``evids`` (correct) or ``trident`` (the public code's)."""
    from simulator.files import atomic_folder

    if annotate_every < 1:
        raise UserInputError(f"--annotate-every must be >= 1, got {annotate_every}")
    if _is_trident_dataset(dataset_dir):
        return _export_trident_dataset(dataset_dir, fmt, out_dir, mfcc=mfcc, test_fraction=test_fraction,
                                       shard_mb=shard_mb, progress=progress, overwrite=overwrite)
    if fmt not in EXPORT_FORMATS:
        raise UserInputError(f"--format must be one of {', '.join(EXPORT_FORMATS)}, got {fmt!r}")
    from simulator.formats.coco import NAMINGS
    from simulator.formats.mot import DISTRACTOR_MODES, distractor_mode

    if coco_naming not in NAMINGS:
        raise UserInputError(f"--coco-naming must be one of {', '.join(NAMINGS)}, got {coco_naming!r}")
    if isinstance(distractors, str) and distractors not in DISTRACTOR_MODES:
        raise UserInputError(f"--distractors must be one of {', '.join(DISTRACTOR_MODES)}, got {distractors!r}")
    entries = dataset_sequences(dataset_dir)
    out = Path(out_dir)
    with atomic_folder(out, overwrite=overwrite, kind=f"export {fmt}") as tmp:
        if fmt in ("antiuav", "antiuav_rgbt", "antiuav2021"):
            from simulator.formats import antiuav

            writer = {"antiuav": antiuav.export_antiuav, "antiuav_rgbt": antiuav.export_antiuav_rgbt,
                      "antiuav2021": antiuav.export_antiuav2021}[fmt]
            for e in _track(entries, progress, f"export {fmt}"):
                writer(e["path"], tmp / e["split"], e["name"])
        elif fmt == "mot":
            from simulator.formats.mot import export_mmuav, write_eval_layout

            splits: dict[str, list[str]] = {}
            for e in _track(entries, progress, "export mot"):
                name = mmuav_number(e["index"])
                export_mmuav(e["path"], tmp / e["split"], name, annotate_every=annotate_every,
                             distractors=distractor_mode(distractors))
                splits.setdefault(e["split"], []).append(name)
            write_eval_layout(tmp, tmp, splits)
        elif fmt == "coco":
            from simulator.formats.coco import export_coco

            export_coco(entries, tmp, distractors=distractors not in (False, "none"), progress=progress,
                        naming=coco_naming)
        elif fmt == "zarr":
            from simulator.formats.kelvin_zarr import export_kelvin_zarr

            export_kelvin_zarr(entries, tmp, progress=progress)
        else:
            from simulator.formats.webdataset import export_native_webdataset

            export_native_webdataset(entries, tmp, shard_bytes=int(shard_mb * 1e6), progress=progress)
    return out


def _is_trident_dataset(dataset_dir: str | Path) -> bool:
    path = Path(dataset_dir) / MANIFEST
    if not path.is_file():
        return False
    try:
        return json.loads(path.read_text()).get("format") == "trident"
    except (ValueError, UnicodeDecodeError, AttributeError):
        return False


def _export_trident_dataset(dataset_dir: str | Path, fmt: str, out_dir: str | Path, *, mfcc: str,
                            test_fraction: float, shard_mb: float, progress: bool, overwrite: bool = False) -> Path:
    """TRIDENT clip dataset -> the public TRIDENT layout or WebDataset shards of segments."""
    from simulator.files import atomic_folder

    if fmt not in TRIDENT_EXPORT_FORMATS:
        raise UserInputError(f"{dataset_dir}: a TRIDENT clip dataset exports to {', '.join(TRIDENT_EXPORT_FORMATS)} "
                             f"only, got {fmt!r}")
    out = Path(out_dir)
    with atomic_folder(out, overwrite=overwrite, kind=f"export {fmt}") as tmp:
        if fmt == "trident":
            from simulator.formats.trident import export_public

            export_public(dataset_dir, tmp, mfcc=mfcc, test_fraction=test_fraction, progress=progress)
        else:
            from simulator.formats.webdataset import export_trident_webdataset

            export_trident_webdataset(dataset_dir, tmp, shard_bytes=int(shard_mb * 1e6), mfcc=mfcc, progress=progress)
    return out


def mmuav_number(index: int) -> str:
    """MM-UAV sequence folder name of dataset sequence ``index`` (0-based): 0001, 0002, ..."""
    return f"{index + 1:04d}"


def _track(items: list, progress: bool, label: str) -> Iterable:
    if not progress:
        return items
    from rich.progress import track

    return track(items, description=label)
