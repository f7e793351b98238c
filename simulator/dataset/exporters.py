"""Export a generated dataset to the benchmarks' layouts: one registry record per (dataset kind, format).

Each :class:`Exporter` says which dataset kind it reads (a native dataset or a TRIDENT clip
dataset), its options as a pydantic model (validated at the boundary, messages naming the
command-line flag), the optional module it needs, and the function that writes the layout
(the layout's own writer lives in ``simulator/formats/<format>.py``). :func:`export_dataset` adds
the safe-output rule, the dataset lock and an atomic output folder around it; docs/FORMATS.md has
each layout field by field.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from scenes.errors import UserInputError
from simulator.dataset.driver import MANIFEST
from simulator.files import DatasetLock, check_output

DatasetKindName = Literal["native", "trident"]


class ExportOptions(BaseModel):
    """Options of one format (none by default)."""

    model_config = ConfigDict(frozen=True, extra="forbid")


class MotOptions(ExportOptions):
    annotate_every: int = Field(1, ge=1)
    distractors: Literal["none", "class", "file"] = "none"


class CocoOptions(ExportOptions):
    distractors: bool = True
    naming: Literal["evids", "mmuav"] = "evids"


class ShardOptions(ExportOptions):
    shard_mb: float = Field(500.0, gt=0)


class ClipShardOptions(ShardOptions):
    mfcc: Literal["evids", "trident"] = "evids"


class TridentPublicOptions(ExportOptions):
    mfcc: Literal["evids", "trident"] = "evids"
    test_fraction: float = Field(0.2, ge=0.0, le=0.99)


FLAGS = {"annotate_every": "--annotate-every", "distractors": "--distractors", "naming": "--coco-naming",
         "shard_mb": "--shard-mb", "mfcc": "--mfcc", "test_fraction": "--test-fraction"}


@dataclass(frozen=True)
class Exporter:
    """One export: the dataset kind it reads, its format name, options and writer."""

    source: DatasetKindName
    fmt: str
    options: type[ExportOptions]
    write: Callable[[Path, Path, Any, bool], None]     # (dataset root, output folder, options, progress)
    requires: tuple[str, str] | None = None             # (module, pip extra) it needs


def _native_entries(root: Path) -> list[dict[str, Any]]:
    from simulator.dataset.generate import dataset_sequences

    return dataset_sequences(root)


def _track(items: list, progress: bool, label: str) -> Iterable:
    if not progress:
        return items
    from rich.progress import track

    return track(items, description=label)


def mmuav_number(index: int) -> str:
    """MM-UAV sequence folder name of dataset sequence ``index`` (0-based): 0001, 0002, ..."""
    return f"{index + 1:04d}"


def _antiuav(variant: str) -> Callable[[Path, Path, Any, bool], None]:
    def write(root: Path, out: Path, options: ExportOptions, progress: bool) -> None:
        from simulator.formats import antiuav

        writer = {"antiuav": antiuav.export_antiuav, "antiuav_rgbt": antiuav.export_antiuav_rgbt,
                  "antiuav2021": antiuav.export_antiuav2021}[variant]
        for e in _track(_native_entries(root), progress, f"export {variant}"):
            writer(e["path"], out / e["split"], e["name"])

    return write


def _mot(root: Path, out: Path, options: MotOptions, progress: bool) -> None:
    from simulator.formats.mot import export_mmuav, write_eval_layout

    splits: dict[str, list[str]] = {}
    for e in _track(_native_entries(root), progress, "export mot"):
        name = mmuav_number(e["index"])
        export_mmuav(e["path"], out / e["split"], name, annotate_every=options.annotate_every,
                     distractors=options.distractors)
        splits.setdefault(e["split"], []).append(name)
    write_eval_layout(out, out, splits)


def _coco(root: Path, out: Path, options: CocoOptions, progress: bool) -> None:
    from simulator.formats.coco import export_coco

    export_coco(_native_entries(root), out, distractors=options.distractors, progress=progress, naming=options.naming)


def _zarr(root: Path, out: Path, options: ExportOptions, progress: bool) -> None:
    from simulator.formats.kelvin_zarr import export_kelvin_zarr

    export_kelvin_zarr(_native_entries(root), out, progress=progress)


def _native_webdataset(root: Path, out: Path, options: ShardOptions, progress: bool) -> None:
    from simulator.formats.webdataset import export_native_webdataset

    export_native_webdataset(_native_entries(root), out, shard_bytes=int(options.shard_mb * 1e6), progress=progress)


def _trident_public(root: Path, out: Path, options: TridentPublicOptions, progress: bool) -> None:
    from simulator.formats.trident import export_public

    export_public(root, out, mfcc=options.mfcc, test_fraction=options.test_fraction, progress=progress)


def _trident_webdataset(root: Path, out: Path, options: ClipShardOptions, progress: bool) -> None:
    from simulator.formats.webdataset import export_trident_webdataset

    export_trident_webdataset(root, out, shard_bytes=int(options.shard_mb * 1e6), mfcc=options.mfcc,
                              progress=progress)


_ALL: tuple[Exporter, ...] = (
    Exporter("native", "antiuav", ExportOptions, _antiuav("antiuav")),
    Exporter("native", "antiuav_rgbt", ExportOptions, _antiuav("antiuav_rgbt")),
    Exporter("native", "antiuav2021", ExportOptions, _antiuav("antiuav2021")),
    Exporter("native", "mot", MotOptions, _mot),
    Exporter("native", "coco", CocoOptions, _coco),
    Exporter("native", "webdataset", ShardOptions, _native_webdataset, ("webdataset", "formats")),
    Exporter("native", "zarr", ExportOptions, _zarr, ("zarr", "zarr")),
    Exporter("trident", "trident", TridentPublicOptions, _trident_public),
    Exporter("trident", "webdataset", ClipShardOptions, _trident_webdataset, ("webdataset", "formats")),
)
EXPORTERS: dict[tuple[str, str], Exporter] = {(e.source, e.fmt): e for e in _ALL}
EXPORT_FORMATS = tuple(e.fmt for e in _ALL if e.source == "native")           # a native dataset's formats
TRIDENT_EXPORT_FORMATS = tuple(e.fmt for e in _ALL if e.source == "trident")  # a TRIDENT clip dataset's


def dataset_kind(dataset_dir: str | Path) -> DatasetKindName:
    """``trident`` for a TRIDENT clip dataset (its manifest says so), else ``native``."""
    path = Path(dataset_dir) / MANIFEST
    try:
        return "trident" if json.loads(path.read_text()).get("format") == "trident" else "native"
    except (OSError, ValueError, UnicodeDecodeError, AttributeError):
        return "native"


def exporter_for(dataset_dir: str | Path, fmt: str) -> Exporter:
    """The registry record that exports this dataset to ``fmt`` (UserInputError naming the valid ones)."""
    kind = dataset_kind(dataset_dir)
    if (kind, fmt) not in EXPORTERS:
        if kind == "trident":
            valid = ", ".join(TRIDENT_EXPORT_FORMATS)
            raise UserInputError(f"{dataset_dir}: a TRIDENT clip dataset exports to {valid} only, got {fmt!r}")
        raise UserInputError(f"--format must be one of {', '.join(EXPORT_FORMATS)}, got {fmt!r}")
    return EXPORTERS[(kind, fmt)]


def validate_options(exporter: Exporter, values: dict[str, Any]) -> ExportOptions:
    """``values`` (only the fields this format has are read) as the exporter's options model;
    UserInputError naming the command-line flag of the first bad one."""
    fields = exporter.options.model_fields
    try:
        return exporter.options.model_validate({k: v for k, v in values.items() if k in fields})
    except ValidationError as exc:
        err = exc.errors()[0]
        name = str(err["loc"][0]) if err["loc"] else "options"
        raise UserInputError(f"{FLAGS.get(name, name)} ({exporter.fmt}): {err['msg']}, got "
                             f"{values.get(name)!r}") from None


def export_inputs(dataset_dir: str | Path, out_dir: str | Path) -> list[Path]:
    """What an export reads (and so may never overwrite or enclose): a native dataset's manifest and
    sequences/, or every top-level entry of a TRIDENT clip dataset except ``out_dir`` itself."""
    from simulator.dataset.generate import SEQUENCES_DIR

    root, out = Path(dataset_dir), Path(out_dir)
    if dataset_kind(root) == "trident":
        return [c for c in sorted(root.iterdir()) if c.resolve() != out.resolve() and not c.name.startswith(".")]
    return [root / MANIFEST, root / SEQUENCES_DIR]


def export_dataset(dataset_dir: str | Path, fmt: str, out_dir: str | Path, *, annotate_every: int = 1,
                   distractors: bool | str | None = None, coco_naming: str = "evids", mfcc: str = "evids",
                   test_fraction: float = 0.2, shard_mb: float = 500.0, progress: bool = True,
                   overwrite: bool = False) -> Path:
    """Export a complete dataset to ``fmt`` under ``out_dir`` (docs/FORMATS.md) under the safe-output
    rule: ``out_dir`` is new/empty, or an earlier evids export replaced only with ``overwrite``; never
    the dataset's manifest or data folders, nor a folder containing them. Holds the dataset lock.

    ``distractors`` (birds, aircraft): mot default ``none`` (exactly MM-UAV); True or ``class`` = rows
    of class 1 ``not_drone``, ``file`` = a separate distractors.txt; coco default on (flagged
    categories); Anti-UAV is single-object (the first drone) either way. ``coco_naming``: ``evids`` or
    ``mmuav`` (``train-ir.json``, file_name from the dataset root). ``mfcc`` (trident): the MFCC
    pipeline recorded for readers, ``evids`` (correct) or ``trident`` (the public code's)."""
    root = Path(dataset_dir)
    out = Path(out_dir)
    if not (root / MANIFEST).is_file():
        raise UserInputError(f"{root} is not an evids dataset (no {MANIFEST})")
    check_output(out, inputs=export_inputs(root, out), overwrite=overwrite)
    with DatasetLock(root, f"export {fmt}", required=False):
        return export_locked(root, fmt, out, annotate_every=annotate_every, distractors=distractors,
                             coco_naming=coco_naming, mfcc=mfcc, test_fraction=test_fraction, shard_mb=shard_mb,
                             progress=progress, overwrite=overwrite)


def export_locked(dataset_dir: str | Path, fmt: str, out_dir: str | Path, *, annotate_every: int = 1,
                  distractors: bool | str | None = None, coco_naming: str = "evids", mfcc: str = "evids",
                  test_fraction: float = 0.2, shard_mb: float = 500.0, progress: bool = True,
                  overwrite: bool = False) -> Path:
    """:func:`export_dataset` for a caller that holds the dataset lock (generation's ``--format``):
    written to a temporary sibling and renamed, so a failure leaves ``out_dir`` as it was."""
    from simulator.files import atomic_folder

    exporter = exporter_for(dataset_dir, fmt)
    if distractors not in (None, True, False, "none", "class", "file"):
        raise UserInputError(f"--distractors must be one of none, class, file, got {distractors!r}")
    mot_mode = {None: "none", False: "none", True: "class"}.get(distractors, distractors)  # type: ignore[arg-type]
    values = {"annotate_every": annotate_every, "naming": coco_naming, "mfcc": mfcc, "test_fraction": test_fraction,
              "shard_mb": shard_mb,
              "distractors": distractors not in (False, "none") if exporter.fmt == "coco" else mot_mode}
    options = validate_options(exporter, values)
    out = Path(out_dir)
    with atomic_folder(out, overwrite=overwrite, kind=f"export {fmt}") as tmp:
        exporter.write(Path(dataset_dir), tmp, options, progress)
    return out
