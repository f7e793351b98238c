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
    visual: str = typer.Option("ir,visible", "--visual", help="Visual sensors, comma-separated ('' for none)."),
    seeds: int = typer.Option(None, "--seeds", min=1, help="Use the first N training seeds of the protocol "
                              "(default: all)."),
    severities: str = typer.Option(None, "--severities", help="Comma-separated severities in (0, 5] "
                                   "(default 1,2,3,4,5; --quick: 5)."),
    steps: int = typer.Option(None, "--steps", min=1, help="Training steps per model (default 300; --quick 15)."),
    audio_clips: int = typer.Option(None, "--audio-clips-per-class", min=2, help="Synthetic audio clips per class "
                                    "(default: the protocol's)."),
    triplets: int = typer.Option(None, "--triplets", min=2, help="Pseudo-triplets per domain for the conflict "
                                 "study (default 200; --quick 40)."),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show progress bars."),
) -> None:
    """Train the softmax and evidential classifiers per sensor (IR crops, visible crops, audio windows) on
    (a) the real calibration half, (b) synthetic, (c) both; score them on the real EVALUATION half (balanced
    accuracy, ECE, UAUC of vacuity / entropy / confidence, clip-bootstrap CIs, MDEs); run the degradation
    sweep on real and synthetic evaluation inputs and report the sweep agreement; then the conflict programs
    (one sensor's clip swapped for a twin of the other label) on class-matched pseudo-triplets of both domains
    (the real sensors are not synchronised: a real triplet is three independent clips of one class). Writes
    OUT/realbench.json, OUT/realbench.html and OUT/realbench_agreement.png.

    Example: evids realbench --real ~/data/Drone-detection-dataset --sim2real out/sim2real --out out/realbench
    """
    from harness.experiments.realbench.harness import format_table, run_realbench
    from harness.runfolder import create_run_folder
    from scenes.errors import UserInputError
    from simulator.files import DatasetLock

    sensors = tuple(v.strip() for v in visual.split(",") if v.strip())
    bad = [v for v in sensors if v not in ("ir", "visible")]
    if bad:
        raise UserInputError(f"--visual: unknown sensor(s) {bad}; expected ir, visible")
    try:
        sev = tuple(float(v) for v in severities.split(",")) if severities else None
    except ValueError:
        raise UserInputError(f"--severities: {severities!r} is not a comma-separated list of numbers") from None
    if sev is not None and not all(0.0 < v <= 5.0 for v in sev):
        raise UserInputError(f"--severities: every severity must lie in (0, 5], got {list(sev)}")
    if not real.exists():
        raise UserInputError(f"--real: {str(real)!r} does not exist")
    if not (sim2real / "sim2real.json").is_file():
        raise UserInputError(f"--sim2real: {str(sim2real)!r} holds no sim2real.json (run `evids sim2real` first)")
    create_run_folder(out, inputs=[real, sim2real])
    with DatasetLock(out, "realbench"):
        summary = run_realbench(real, sim2real, out, quick=quick, audio=audio, visual=sensors, n_seeds=seeds,
                                severities=sev, steps=steps, audio_clips_per_class=audio_clips, n_triplets=triplets,
                                progress=progress,
                                log=typer.echo)
    typer.echo(format_table(summary))
    typer.echo(f"report: {out / 'realbench.html'}")


def register(app: typer.Typer) -> None:
    app.command("realbench")(realbench)
