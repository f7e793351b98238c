"""`evids generate`, `evids export`, `evids verify`, `evids fixture`: datasets at scale.

Thin wrappers over simulator.dataset.generate (native datasets, exporters, verify), simulator.dataset.trident
(`--format trident`) and simulator.dataset.fixtures.
"""
from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Iterator, Optional

import typer

from scenes.errors import UserInputError


def _formats(text: str) -> tuple[str, ...]:
    from simulator.dataset.exporters import EXPORT_FORMATS

    formats = tuple(dict.fromkeys(f.strip() for f in text.split(",") if f.strip()))
    valid = ("native",) + EXPORT_FORMATS
    bad = [f for f in formats if f not in valid]
    if bad or not formats:
        raise UserInputError(f"--format: unknown format(s) {bad or [text]}; valid: {', '.join(valid)} "
                             "(comma-separated), or trident alone")
    return formats


def generate(
    config: str = typer.Argument(..., help="A generation YAML, a generation preset (scenes/generation/, e.g. "
                                 "mixed_small) or a scene preset (that scene with default randomisation)."),
    out: Path = typer.Option(..., "--out", "-o",
                             help="Dataset folder (new, or an unfinished/identical run to resume)."),
    seed: int = typer.Option(0, "--seed", min=0, help="Seed of every random draw."),
    sequences: Optional[int] = typer.Option(None, "--sequences", min=1,
                                            help="Number of sequences (default: the config's)."),
    frames: Optional[int] = typer.Option(None, "--frames", min=1, help="Frames per sequence (default: the config's)."),
    workers: int = typer.Option(1, "--workers", "-w", min=1, help="Parallel worker processes (or Ray CPUs)."),
    executor: str = typer.Option("local", "--executor", help="local (process pool) or ray."),
    ray_address: Optional[str] = typer.Option(None, "--ray-address",
                                              help="Ray cluster address (default: start a local Ray)."),
    fmt: str = typer.Option("native", "--format", help="native plus any of antiuav, antiuav_rgbt, mot, coco "
                            "(comma-separated); or trident (TRIDENT clip datasets)."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace a different dataset already in --out."),
    clips: Optional[int] = typer.Option(None, "--clips", min=1, help="trident only: the first N clips."),
    quiet: bool = typer.Option(False, "--quiet", help="No progress bar."),
) -> None:
    """Generate a randomised, split, reproducible dataset (resumable: re-run the same command).

    Examples: evids generate mixed_small --out out/mixed --seed 0 --sequences 50 --workers 2 --format native,mot,coco;
    evids generate trident_mini --out out/trident --format trident
    """
    if fmt.strip() == "trident":
        from simulator.dataset.trident import generate_trident

        if sequences is not None or frames is not None or executor != "local":
            raise UserInputError("--format trident takes --clips, --seed, --workers, --overwrite and --quiet (not "
                                 "--sequences, --frames or --executor)")
        try:
            with _generation_errors("clips"):
                path = generate_trident(config, out, seed, n_clips=clips, progress=not quiet, workers=workers,
                                        overwrite=overwrite)
        except ValueError as exc:
            if isinstance(exc, UserInputError):
                raise
            raise UserInputError(str(exc)) from None
        typer.echo(f"trident: {path}")
        return
    if clips is not None:
        raise UserInputError("--clips applies to --format trident only; use --sequences")
    if executor == "ray":
        from harness.cli import require_module

        require_module("ray", "--executor ray", "pip install -e '.[ray]' (bash run.sh installs it)")
    from simulator.dataset.generate import generate_dataset

    with _generation_errors("sequences"):
        result = generate_dataset(config, out, seed, sequences=sequences, frames=frames, workers=workers,
                                  executor=executor, ray_address=ray_address, formats=_formats(fmt),
                                  overwrite=overwrite, progress=not quiet)
    for note in result.notes:
        typer.echo(f"note: {note}", err=True)
    typer.echo(f"native: {result.out_dir} ({len(result.rendered)} rendered, {len(result.skipped)} already complete)")
    for kind, path in result.exports.items():
        typer.echo(f"{kind}: {path}")


@contextlib.contextmanager
def _generation_errors(units: str) -> Iterator[None]:
    """Exit 1 naming the failed units (the others are kept), 130 on Ctrl-C (finished units are kept)."""
    from simulator.dataset.driver import GenerationFailed

    try:
        yield
    except GenerationFailed as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(1) from None
    except KeyboardInterrupt:
        typer.echo(f"interrupted: finished {units} are kept; run the same command again to resume", err=True)
        raise typer.Exit(130) from None


def export(
    dataset: Path = typer.Argument(..., help="A native dataset folder (made by `evids generate`), or a TRIDENT clip "
                                   "dataset (made by `evids generate --format trident`)."),
    fmt: str = typer.Option(..., "--format", help="native datasets: antiuav, antiuav_rgbt, antiuav2021, mot, coco, "
                            "webdataset, zarr (float32 thermal kelvin stacks, chunked per frame; needs the zarr "
                            "extra); TRIDENT clip datasets: trident (the public layout), webdataset "
                            "(comma-separated for several)."),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help="Output folder (default DATASET/<format>); one "
                                       "format: written here; several: OUT/<format>."),
    annotate_every: int = typer.Option(1, "--annotate-every", min=1, help="mot: gt rows on frames 1, 1+k, ... only "
                                       "(MM-UAV's test split uses 20)."),
    distractors: Optional[bool] = typer.Option(None, "--distractors/--no-distractors", help="Include birds/aircraft "
                                               "(default: no for mot, yes for coco as flagged categories)."),
    distractors_as: str = typer.Option("class", "--distractors-as", help="mot with --distractors: 'class' (rows of "
                                       "MM-UAV class 1 not_drone in gt.txt) or 'file' (a separate distractors.txt)."),
    coco_naming: str = typer.Option("evids", "--coco-naming", help="coco: 'evids' (<split>_ir.json, file_name "
                                    "relative to the split folder) or 'mmuav' (<split>-ir.json, from the root)."),
    mfcc: str = typer.Option("evids", "--mfcc", help="trident/webdataset of clips: MFCC pipeline recorded for readers, "
                             "'evids' (correct) or 'trident' (the public code's, bit for bit)."),
    test_fraction: float = typer.Option(0.2, "--test-fraction", min=0.0, max=0.99, help="trident: share of clips "
                                        "per class in Test/ (the rest in Train/)."),
    shard_mb: float = typer.Option(500.0, "--shard-mb", min=0.001,
                                   help="webdataset: start a new shard past this size."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace an export an earlier `evids export` wrote."),
    quiet: bool = typer.Option(False, "--quiet", help="No progress bar."),
) -> None:
    """Export a dataset to benchmark layouts (Anti-UAV, MM-UAV, COCO-video, TRIDENT, WebDataset); docs/FORMATS.md.

    Example: evids export out/mixed --format mot --out out/mixed_mmuav --annotate-every 20
    """
    from simulator.dataset.exporters import EXPORT_FORMATS, TRIDENT_EXPORT_FORMATS, export_dataset

    formats = [f.strip() for f in fmt.split(",") if f.strip() and f.strip() != "native"]
    valid = set(EXPORT_FORMATS) | set(TRIDENT_EXPORT_FORMATS)
    bad = [f for f in formats if f not in valid]
    if bad or not formats:
        raise UserInputError(f"--format: unknown format(s) {bad or [fmt]}; valid: {', '.join(sorted(valid))}")
    from harness.cli import require_module

    for f, module, extra in (("zarr", "zarr", "zarr"), ("webdataset", "webdataset", "formats")):
        if f in formats:
            require_module(module, f"--format {f}", f"pip install -e '.[{extra}]' (bash run.sh installs it)")
    if distractors_as not in ("class", "file"):
        raise UserInputError(f"--distractors-as must be 'class' or 'file', got {distractors_as!r}")
    from simulator.dataset.exporters import export_inputs
    from simulator.files import check_output

    targets = {f: (out if len(formats) == 1 else out / f) if out is not None else dataset / f
               for f in dict.fromkeys(formats)}
    for target in targets.values():  # all refused before any is written
        if (dataset / "manifest.json").is_file():
            check_output(target, inputs=export_inputs(dataset, target), overwrite=overwrite)
    mode: bool | str | None = distractors
    for f in dict.fromkeys(formats):
        if f == "mot":
            mode = distractors_as if distractors else "none"
        elif f == "coco":
            mode = distractors
        path = export_dataset(dataset, f, targets[f], annotate_every=annotate_every, distractors=mode,
                              coco_naming=coco_naming, mfcc=mfcc, test_fraction=test_fraction, shard_mb=shard_mb,
                              progress=not quiet, overwrite=overwrite)
        typer.echo(f"{f}: {path}")


def verify(dataset: Path = typer.Argument(..., help="A dataset folder `evids generate` wrote (native or trident).")
           ) -> None:
    """Re-hash every sequence (or clip); list missing and corrupt ones (exit 1 if any). Re-running the
    same `evids generate` command regenerates exactly those."""
    from simulator.dataset.generate import verify_dataset

    report = verify_dataset(dataset, progress=True)
    for name in report.missing:
        typer.echo(f"missing: {name}")
    for name, files in sorted(report.corrupt.items()):
        typer.echo(f"corrupt: {name} ({', '.join(files[:5])}{', ...' if len(files) > 5 else ''})")
    if report.incomplete:
        typer.echo("incomplete: the generation run has not finished (manifest has no hashes yet)")
    if not report.ok:
        raise typer.Exit(1)
    typer.echo(f"ok: {report.checked} {report.noun}s intact")


def fixture(
    name: str = typer.Argument(..., help="native, antiuav, antiuav_rgbt, mmuav, coco or trident."),
    out: Path = typer.Option(..., "--out", "-o", help="Output folder (new or empty)."),
    preset: str = typer.Option("clear_day_quad", "--preset", help="Scene preset to render."),
    seed: int = typer.Option(0, "--seed", min=0, help="Seed."),
    overwrite: bool = typer.Option(False, "--overwrite",
                                   help="Replace a fixture folder an earlier `evids fixture` wrote."),
) -> None:
    """Write a tiny regression dataset (the pytest plugin's fixtures; bytes stable per package version).

    Example: evids fixture mmuav --out tests/data/mmuav
    """
    from simulator.dataset.fixtures import build_fixture
    from simulator.files import check_output, remove_output

    check_output(out, overwrite=overwrite)
    if overwrite:
        remove_output(out)

    typer.echo(f"{name}: {build_fixture(name, out, preset=preset, seed=seed)}")


def register(app: typer.Typer) -> None:
    app.command("generate")(generate)
    app.command("export")(export)
    app.command("verify")(verify)
    app.command("fixture")(fixture)
