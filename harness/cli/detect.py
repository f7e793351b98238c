"""`evids detect train|evaluate|report|run`: the detection experiment (issue 16; the paper's E1/E3 on
generated paired RGB/thermal video). Thin wrappers over :mod:`harness.experiments.detection`."""
from __future__ import annotations

from pathlib import Path

import typer

detect_app = typer.Typer(name="detect", no_args_is_help=True, add_completion=False, pretty_exceptions_enable=False,
                         help="Detection experiment: per-stream RGB/thermal detectors (sigmoid vs evidential), "
                              "decision-level fusion, detection-tracking switching, crossover stress test.")


@detect_app.command("train")
def train(
    config: str = typer.Option("full", "--config", "-c", help="A detection config YAML, or one of: full, demo, tiny."),
    out: Path = typer.Option(..., "--out", "-o", help="Run folder (generated datasets are cached beside it in data/)."),
) -> None:
    """Generate (or read) the datasets and train the detectors.

    Example: evids detect train --config full --out out/detection/run
    """
    from harness.experiments.detection.runner import train as run_train

    run_train(config, out, typer.echo)
    typer.echo(f"trained: {out / 'models'}")


@detect_app.command("evaluate")
def evaluate(run: Path = typer.Argument(..., help="A run folder written by `evids detect train`.")) -> None:
    """Fit thresholds on val, run conditions (a)-(h) on the test sets, metrics and headline answers."""
    from harness.cli import TRACKEVAL_INSTALL, require_module

    require_module("trackeval", "evids detect (tracking metrics)", TRACKEVAL_INSTALL)
    from harness.experiments.detection.runner import evaluate as run_evaluate

    run_evaluate(run, typer.echo)
    typer.echo(f"evaluated: {run / 'metrics.json'}")


@detect_app.command("report")
def report(run: Path = typer.Argument(..., help="An evaluated detection run folder.")) -> None:
    """Write RUN/detection.html."""
    from harness.experiments.detection.report import build_detection_report

    typer.echo(f"report: {build_detection_report(run)}")


@detect_app.command("run")
def run_all(
    config: str = typer.Option("full", "--config", "-c", help="A detection config YAML, or one of: full, demo, tiny."),
    out: Path = typer.Option(..., "--out", "-o", help="Run folder."),
) -> None:
    """train + evaluate + report in one go."""
    from harness.cli import TRACKEVAL_INSTALL, require_module

    require_module("trackeval", "evids detect (tracking metrics)", TRACKEVAL_INSTALL)
    from harness.experiments.detection import run_detection

    path = run_detection(config, out, typer.echo)
    typer.echo(f"report: {path}")


def register(app: typer.Typer) -> None:
    app.add_typer(detect_app, name="detect")
