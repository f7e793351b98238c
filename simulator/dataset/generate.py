"""Generate a native dataset from a generation config: resumable, local process pool or Ray.

Layout (docs/DATASETS.md)::

    DIR/manifest.json             resolved config, seed, versions, per-sequence seed/split/hash
    DIR/sequences/seq000001/      native layout (docs/NATIVE_FORMAT.md), renamed into place whole
    DIR/<format>/                 optional exports (antiuav, antiuav_rgbt, antiuav2021, mot, coco, webdataset, zarr)

The output rules, the lock, resume and the manifest (written first with ``"complete": false``,
rewritten as each sequence finishes, last with ``"complete": true``) belong to the driver shared
with the TRIDENT kind (:mod:`simulator.dataset.driver`); this module is the native kind: its plan,
its per-sequence render task, and verify (exports: simulator.dataset.exporters).
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
from typing import Any, Iterable, Iterator

from scenes.errors import UserInputError, short_repr
from simulator.dataset.config import (
    GenerationConfig,
    load_generation_config,
    randomised_scenario,
    sequence_name,
    sequence_seed,
    split_assignment,
)
from simulator.dataset.driver import (
    MANIFEST,
    GenerationResult,
    Unit,
    VerifyReport,
    canonical_sha256,
    clean_stale,
    drive,
    recorded_hashes,
)
from simulator.dataset.exporters import EXPORT_FORMATS, dataset_kind, export_locked
from simulator.files import (
    HASH_FILE,
    MARKER_FILE,
    check_plain_name,
    copy_tree_no_symlinks,
    inside,
    temp_sibling,
    verify_hashes,
)
from simulator.jobs import JobError, Start, iter_jobs, threads_per_worker

SEQUENCES_DIR = "sequences"
DATASET_FORMAT = "evids-native-dataset"
EXECUTORS = ("local", "ray")


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
    return canonical_sha256({"config": config.model_dump(mode="json"), "seed": int(seed), "tasks": tasks})


def sequence_hash(sequence_dir: Path) -> str:
    """Content hash of a native sequence: sha256 of its files.sha256 (what write_hashes returns)."""
    return hashlib.sha256((Path(sequence_dir) / HASH_FILE).read_bytes()).hexdigest()


def _manifest(config: GenerationConfig, seed: int, tasks: list[dict[str, Any]], identity: str,
              hashes: dict[str, str], complete: bool) -> dict[str, Any]:
    from simulator.files import package_versions

    sequences = []
    for t in tasks:
        sequences.append({"name": t["name"], "index": t["index"], "source": t["source"], "seed": t["seed"],
                          "split": t["split"], "n_frames": t["n_frames"],
                          "content_sha256": hashes.get(t["name"])})
    return {
        "format": DATASET_FORMAT, "format_version": 1, "dataset_id": identity, "complete": complete,
        "config": config.model_dump(mode="json"), "seed": int(seed), "versions": package_versions(),
        "splits": {s: [t["name"] for t in tasks if t["split"] == s] for s in ("train", "val", "test")},
        "sequences": sequences,
    }


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


def iter_tasks(tasks: list[dict[str, Any]], sequences_dir: Path, *, workers: int = 1, executor: str = "local",
               ray_address: str | None = None, progress: bool = True, label: str = "generate",
               force_pool: bool = False) -> Iterator[dict[str, Any]]:
    """Run render tasks on the chosen executor with a driver-side progress bar; each result as it finishes.

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
    for i, result in iter_jobs(render_task, calls, workers=workers, start=start, on_error="collect",
                               progress=label if progress else None, ray_address=ray_address):
        if isinstance(result, JobError):  # render_task never raises: its worker died, or Ray failed
            why = f"Ray task failed: {result.message}" if start == "ray" else f"worker process died ({result.error})"
            result = {"name": tasks[i]["name"], "error": why}
        yield result


def run_tasks(tasks: list[dict[str, Any]], sequences_dir: Path, **kwargs: Any) -> dict[str, dict[str, Any]]:
    """:func:`iter_tasks` collected: results by sequence name."""
    return {r["name"]: r for r in iter_tasks(tasks, sequences_dir, **kwargs)}


# --------------------------------------------------------------------------------------------
# Driver
# --------------------------------------------------------------------------------------------

def generate_dataset(config_or_name: str | Path | dict | GenerationConfig, out_dir: str | Path, seed: int, *,
                     sequences: int | None = None, frames: int | None = None, workers: int = 1,
                     executor: str = "local", ray_address: str | None = None, formats: Iterable[str] = ("native",),
                     overwrite: bool = False, progress: bool = True,
                     reuse_from: str | Path | None = None) -> GenerationResult:
    """Generate (or finish) the dataset in ``out_dir``; see the module docstring.

    Sequences already present and intact are kept; missing or corrupt ones are (re)rendered. An
    ``out_dir`` holding a different dataset is refused unless ``overwrite``. ``reuse_from``: an earlier
    dataset folder; if it is the same dataset (same ``dataset_id``: config, seed, scenarios), its intact
    sequences that ``out_dir`` lacks are hard-linked in instead of rendered (``GenerationResult.linked``);
    any other folder, or none there, changes nothing. Raises :class:`GenerationFailed` naming the failed
    sequences (the rest stay complete).
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
    config_file = ([Path(config_or_name)] if isinstance(config_or_name, (str, Path)) and Path(config_or_name).is_file()
                   else [])
    kind = NativeDataset(config, seed, tasks, executor=executor, ray_address=ray_address,
                         reuse_from=None if reuse_from is None else Path(reuse_from))

    def export(result: GenerationResult) -> None:  # under the dataset lock, after the final manifest
        for fmt in formats:
            if fmt != "native":
                result.exports[fmt] = export_locked(result.out_dir, fmt, result.out_dir / fmt, overwrite=True,
                                                     progress=progress)

    result = drive(kind, out_dir, inputs=config_file, overwrite=overwrite, workers=workers, progress=progress,
                   finish=export)
    result.linked = list(kind.linked)
    return result


@dataclass
class NativeDataset:
    """The native dataset kind (simulator.dataset.driver): one unit per sequence folder under sequences/."""

    config: GenerationConfig
    seed: int
    tasks: list[dict[str, Any]]
    executor: str = "local"
    ray_address: str | None = None
    noun: str = "sequence"
    reuse_from: Path | None = None      # an earlier folder of the same dataset: its sequences are linked
    linked: list[str] = field(default_factory=list, init=False)
    _identity: str | None = field(default=None, init=False, repr=False)

    @property
    def label(self) -> str:
        return f"generate {self.config.name}"

    def identity(self) -> str:
        if self._identity is None:   # hashed once: every journal write of the manifest carries it
            self._identity = dataset_identity(self.config, self.seed, self.tasks)
        return self._identity

    def units(self) -> list[Unit]:
        return [Unit(t["name"], t) for t in self.tasks]

    def prepare(self, out: Path) -> None:
        seq_root = out / SEQUENCES_DIR
        seq_root.mkdir(exist_ok=True)
        clean_stale(seq_root)
        wanted = {t["name"] for t in self.tasks}
        for child in seq_root.iterdir():
            if child.is_symlink():  # never followed: the link goes, its target stays
                child.unlink()
            elif child.is_dir() and child.name not in wanted:
                shutil.rmtree(child)
        if self.reuse_from is not None:
            self.linked = self._link_from(self.reuse_from, seq_root)

    def _link_from(self, source: Path, seq_root: Path) -> list[str]:
        """Hard-link into ``seq_root`` the intact sequences of ``source`` (an earlier folder of this very
        dataset: same ``dataset_id``) that ``seq_root`` lacks, each through a temporary sibling; a
        source that is no evids dataset or another dataset gives nothing. Returns the linked names."""
        if source.resolve() == seq_root.parent.resolve() or not (source / MANIFEST).is_file():
            return []
        try:
            old = load_manifest(source)
        except UserInputError:
            return []
        if old.get("dataset_id") != self.identity():
            return []
        recorded = recorded_hashes(old)
        linked = []
        for task in self.tasks:
            name, src = task["name"], source / SEQUENCES_DIR / task["name"]
            if ((seq_root / name).exists() or name not in recorded or src.is_symlink()
                    or not _sequence_ok(src, task, recorded[name])):
                continue
            tmp = temp_sibling(seq_root / name)      # a killed run leaves only a temporary (clean_stale)
            copy_tree_no_symlinks(src, tmp, hard_link=True)
            if (src / MARKER_FILE).is_file():           # written by evids: a later --overwrite may replace it
                shutil.copy2(src / MARKER_FILE, tmp / MARKER_FILE)
            os.rename(tmp, seq_root / name)
            linked.append(name)
        return linked

    def unit_ok(self, out: Path, unit: Unit, recorded_hash: str | None) -> bool:
        return _sequence_ok(out / SEQUENCES_DIR / unit.name, unit.payload, recorded_hash)

    def unit_hash(self, out: Path, unit: Unit) -> str:
        return sequence_hash(out / SEQUENCES_DIR / unit.name)

    def run(self, out: Path, todo: list[Unit], *, workers: int, progress: bool) -> Iterator[dict[str, Any]]:
        return iter_tasks([u.payload for u in todo], out / SEQUENCES_DIR, workers=workers, executor=self.executor,
                          ray_address=self.ray_address, progress=progress, label=self.label)

    def manifest(self, units: list[Unit], hashes: dict[str, str], complete: bool, out: Path) -> dict[str, Any]:
        return _manifest(self.config, self.seed, self.tasks, self.identity(), hashes, complete)


# --------------------------------------------------------------------------------------------
# Verify and export
# --------------------------------------------------------------------------------------------

def verify_dataset(dataset_dir: str | Path, *, progress: bool = False) -> VerifyReport:
    """Re-hash every sequence against its files.sha256 and the manifest's content hash (a TRIDENT clip
    dataset: every clip against the manifest, simulator.dataset.trident.verify_trident)."""
    root = Path(dataset_dir)
    if dataset_kind(root) == "trident":
        from simulator.dataset.trident import verify_trident

        return verify_trident(root)
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
