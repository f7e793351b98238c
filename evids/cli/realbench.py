"""`evids realbench`: the evidential pipeline on the real Svanström clips beside the generated counterpart,
and whether synthetic stress tests predict real ones (docs/EXPERIMENTS.md, "Real benchmark")."""
from __future__ import annotations

from pathlib import Path

import typer


def realbench(
    real: Path = typer.Option(..., "--real", help="The Svanström benchmark: its folder or a bare git mirror."),
    sim2real: Path = typer.Option(..., "--sim2real", help="A finished `evids sim2real` run folder: its protocol, "
                                  "synthetic counterpart and real-sample cache are reused (read only)."),
    out: Path = typer.Option(Path("out/realbench"), "--out", "-o", help="Run folder (created)."),
    quick: bool = typer.Option(False, "--quick", help="Toy scale (few steps, one severity) for tests."),
    audio: bool = typer.Option(True, "--audio/--no-audio", help="Include the audio track."),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show progress bars."),
) -> None:
    """Train the softmax and evidential classifiers per sensor (IR crops, visible crops, audio windows) on
    (a) the real calibration half, (b) synthetic, (c) both; score them on the real EVALUATION half (balanced
    accuracy, ECE, UAUC of vacuity / entropy / confidence, clip-bootstrap CIs, MDEs); run the degradation
    sweep on real and synthetic evaluation inputs and report the sweep agreement. Writes
    OUT/realbench.json, OUT/realbench.html and OUT/realbench_agreement.png.

    Example: evids realbench --real ~/data/Drone-detection-dataset --sim2real out/sim2real --out out/realbench
    """
    from evids.experiments.realbench.harness import format_table, run_realbench
    from evids.runfolder import create_run_folder
    from scenes.errors import UserInputError
    from simulator.files import DatasetLock

    if not real.exists():
        raise UserInputError(f"--real: {str(real)!r} does not exist")
    if not (sim2real / "sim2real.json").is_file():
        raise UserInputError(f"--sim2real: {str(sim2real)!r} holds no sim2real.json (run `evids sim2real` first)")
    create_run_folder(out, inputs=[real, sim2real])
    with DatasetLock(out, "realbench"):
        summary = run_realbench(real, sim2real, out, quick=quick, audio=audio, progress=progress, log=typer.echo)
    typer.echo(format_table(summary))
    typer.echo(f"report: {out / 'realbench.html'}")


def register(app: typer.Typer) -> None:
    app.command("realbench")(realbench)
