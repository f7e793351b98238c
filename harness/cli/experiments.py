"""`evids train|evaluate|sweep|report|demo`: the experiment harness (thin wrappers over
:mod:`harness.experiments` and :mod:`harness.report`)."""
from __future__ import annotations

from pathlib import Path

import typer

from scenes.errors import UserInputError

_STUDIES = ("degradation", "conflict", "gate")


def _run_lock(run: Path, purpose: str):
    """The run folder's writer lock (a second evaluate/sweep on the same run refuses); taken only
    on a real run folder, so nothing is written into a folder that is not one."""
    from simulator.files import DatasetLock

    if not (Path(run) / "config.yaml").is_file():
        raise UserInputError(f"{str(run)!r} is not a run folder (no config.yaml); run `evids train` first")
    return DatasetLock(run, purpose)


def train(
    config: Path = typer.Option(..., "--config", "-c", help="Experiment config YAML (see examples/experiment.yaml)."),
    out: Path = typer.Option(..., "--out", "-o", help="Run folder (created; a generated dataset is cached in it)."),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show progress bars."),
) -> None:
    """Prepare the dataset (generate it into OUT/data, or read a TRIDENT-layout folder) and train the
    six unimodal models (audio/video/RF x sigmoid/evidential) and the Late Fusion and GMU heads.

    Example: evids train --config examples/experiment.yaml --out runs/exp1
    """
    from harness.experiments import load_experiment_config
    from harness.experiments.runner import stage_train
    from harness.runfolder import create_run_folder
    from simulator.files import DatasetLock

    cfg = load_experiment_config(config)  # validated in full (harness.experiments.validate) before any work
    create_run_folder(out, inputs=[config] + ([Path(cfg.dataset.path)] if cfg.dataset.path else []))
    with DatasetLock(out, "train"):  # one writer per run folder
        stage_train(cfg, out, progress)
    typer.echo(f"trained: {out / 'models.pt'}")


def evaluate(
    run: Path = typer.Argument(..., help="A run folder written by `evids train`."),
    progress: bool = typer.Option(True, "--progress/--no-progress"),
) -> None:
    """Run every ablation condition under every noise seed, with clip-clustered bootstrap comparisons
    (writes evaluate.json, conditions.csv, bootstrap.csv, predictions.npz, figures/examples.png)."""
    from harness.experiments.runner import open_run, stage_evaluate, stage_examples

    with _run_lock(run, "evaluate"):
        ctx = open_run(run, progress)
        stage_evaluate(ctx)
        stage_examples(ctx)
    typer.echo(f"evaluated: {run / 'conditions.csv'}")


def sweep(
    run: Path = typer.Argument(..., help="A run folder written by `evids train`."),
    only: str = typer.Option(",".join(_STUDIES), "--only",
                             help="Comma-separated subset of: degradation,conflict,gate."),
    progress: bool = typer.Option(True, "--progress/--no-progress"),
) -> None:
    """Degradation sweep (severity grid per modality), conflict study (scheduled conflict programs)
    and gate sweep with realised vs projected CPU time saving."""
    from harness.experiments.conflict_study import stage_conflict
    from harness.experiments.gate_timing import stage_gate
    from harness.experiments.runner import open_run, stage_sweep

    kinds = [k.strip() for k in only.split(",") if k.strip()]
    bad = [k for k in kinds if k not in _STUDIES]
    if bad or not kinds:
        raise UserInputError(f"--only: unknown study {bad or only!r}; choose from {', '.join(_STUDIES)}")
    with _run_lock(run, "sweep"):
        ctx = open_run(run, progress)
        for kind in kinds:
            {"degradation": stage_sweep, "conflict": stage_conflict, "gate": stage_gate}[kind](ctx)
            typer.echo(f"{kind}: done")


def report(run: Path = typer.Argument(..., help="A run folder after `evids evaluate` (and optionally `sweep`)."),
           progress: bool = typer.Option(False, "--progress/--no-progress",
                                         help="Accepted like every command's (the report shows no progress bar)."),
           ) -> None:
    """Write RUN/report.html (self-contained, opens offline) and RUN/metrics.json."""
    from harness.report import build_report

    if not Path(run).is_dir():
        raise UserInputError(f"run folder {str(run)!r} does not exist")
    typer.echo(f"report: {build_report(run)}")


def demo(
    out: Path = typer.Option(Path("out/demo"), "--out", "-o", help="Run folder (re-running reuses its dataset)."),
    quick: bool = typer.Option(False, "--quick", help="Toy scale (about 1-2 minutes) instead of the full demo."),
    progress: bool = typer.Option(True, "--progress/--no-progress"),
    detection: bool = typer.Option(False, "--detection", help="Run the reduced detection experiment (RGB/thermal "
                                   "detectors, fusion, tracking; budget 15 minutes on 2 cores) into OUT/detection "
                                   "instead."),
) -> None:
    """The main job: generate a small seeded RGB + audio + RF scenario set, train sigmoid and
    evidential models, run all ablation conditions, a reduced degradation sweep, the conflict study
    and a gate sweep, and write OUT/report.html (about 10 minutes on 2 CPU cores; --quick: toy scale).
    """
    if detection:
        from harness.cli import TRACKEVAL_INSTALL, require_module

        require_module("trackeval", "evids demo --detection", TRACKEVAL_INSTALL)
    from harness.runfolder import create_run_folder
    from simulator.files import DatasetLock

    create_run_folder(out)
    with DatasetLock(out, "demo"):
        if detection:
            from harness.experiments.detection import run_detection_demo

            typer.echo(f"report: {run_detection_demo(out, typer.echo)}")
            return
        from harness.experiments import run_demo

        times = run_demo(out, quick=quick, progress=progress, log=typer.echo)
    typer.echo(f"total: {sum(times.values()):.1f} s")
    typer.echo(f"report: {out / 'report.html'}")


def audit(
    dataset: Path = typer.Argument(..., help="A TRIDENT-layout dataset folder whose clips carry train/test splits."),
    json_out: Path = typer.Option(None, "--json", help="Also write the audit as JSON to this (new) file."),
    progress: bool = typer.Option(False, "--progress/--no-progress"),
) -> None:
    """Shortcut audit: target-blind baselines (scene statistics: median frame colour, target-free
    strips, mean MFCC and mean spectrum on segments where the drone is not observable) fitted on
    train and scored on test, balanced accuracy with 95 % scene-bootstrap CIs.

    Exit status 0 when no baseline beats chance, 3 when one beats chance beyond its CI and by the
    tolerance (a shortcut: something other than the target separates the classes), 2 for bad input.
    Verdicts follow docs/EXPERIMENTS.md's rule; the seed is the audit config's, as in a run's audit.

    Example: evids audit out/demo/data
    """
    from evids.metrics.significance import separating_digits
    from harness.experiments.audit import audit_clips, dataset_split
    from harness.experiments.data import load_clips
    from simulator.files import write_atomic

    if not Path(dataset).is_dir():
        raise UserInputError(f"DATASET: {str(dataset)!r} is not a folder")
    if json_out is not None and Path(json_out).exists():
        raise UserInputError(f"--json: {str(json_out)!r} exists; choose a new file")
    clips = load_clips(dataset, progress)
    split = dataset_split(clips)
    res = audit_clips(clips, split)  # AuditConfig's seed: the same as a run's audit stage
    for r in res["baselines"]:
        # enough digits that the printed CI agrees with the label (0.50004 prints 0.50004, not 0.500)
        score = "n/a" if r["score"] is None else (f"{r['score']:.3f} [{separating_digits(r['ci_low'], 0.5)}, "
                                                 f"{separating_digits(r['ci_high'], 0.5)}]")
        typer.echo(f"{r['variant']:<20} {r['feature']:<20} {r['model']:<9} {score:<24} {r['status']}")
    if json_out is not None:
        import json

        write_atomic(Path(json_out), json.dumps(res, indent=1))
    if res["shortcut"]:
        typer.echo("audit: SHORTCUT found (a target-blind baseline beats chance)")
        raise typer.Exit(3)
    undecided = sum(1 for r in res["baselines"] if r.get("decisive") and r.get("verdict") == "undecided")
    typer.echo(f"audit: no shortcut ({res['n_scored']} scored"
               + (f"; {undecided} undecided at this size)" if undecided else "; every decisive baseline at chance)"))


def register(app: typer.Typer) -> None:
    app.command("audit")(audit)
    app.command("train")(train)
    app.command("evaluate")(evaluate)
    app.command("sweep")(sweep)
    app.command("report")(report)
    app.command("demo")(demo)
