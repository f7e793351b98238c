"""`evids sim2real`: how far the simulator is from the real Svanström benchmark (docs/SIM2REAL.md)."""
from __future__ import annotations

from pathlib import Path

import typer


def sim2real(
    real: Path = typer.Option(..., "--real", help="The Svanström benchmark: its folder (holding Data/) or a bare git "
                              "mirror of its repository (read in place; nothing is copied)."),
    out: Path = typer.Option(Path("out/sim2real"), "--out", "-o", help="Run folder (created; the synthetic "
                             "counterpart is cached in it and a rerun resumes)."),
    config: Path = typer.Option(None, "--config", "-c",
                                help="Protocol file (default: examples/sim2real_svanstrom.yaml)."),
    quick: bool = typer.Option(False, "--quick",
                               help="Toy scale (tiny renders, few epochs) for tests and a first look."),
    strict: bool = typer.Option(False, "--strict", help="Stop at the first real clip that fails the reader's checks "
                                "(default: skip it and list it in OUT/skipped.txt)."),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show progress bars."),
    tune: bool = typer.Option(False, "--tune", help="Measure on the real CALIBRATION half only, to judge a "
                              "simulator change before the one evaluation run: the evaluation half is not read; "
                              "classifiers are cross-fitted over two folds of calibration clips (runs of 5 "
                              "consecutive clip numbers), statistics use the calibration IQR, the audio track "
                              "tests one fold. Compare two such runs with `evids sim2real-compare`."),
    reuse_renders: Path = typer.Option(None, "--reuse-renders", help="An earlier sim2real run folder (e.g. the "
                                       "`--before` of a comparison): every synthetic set whose recipe is unchanged "
                                       "(same dataset id: generation config, seed, scenario files' paths) and the "
                                       "real samples are hard-linked from it instead of redone, so only what a "
                                       "protocol change touches renders. Both runs stay whole (evids never "
                                       "modifies a file in place)."),
) -> None:
    """Generate the synthetic counterpart of the real benchmark (same sensors, resolutions, classes and box
    sizes), then measure the gap on the real EVALUATION half (even clip numbers; the odd calibration half
    trains and is the only half anything is tuned on): per-class image statistics, crop classifiers
    trained on (a) real, (b) synthetic, (c) both, (d) few-shot real, (d+) few-shot + synthetic with
    clip-bootstrap CIs, and a real-vs-synthetic domain classifier. Writes OUT/sim2real.json,
    OUT/sim2real.html and contact sheets.

    Example: evids sim2real --real ~/data/Drone-detection-dataset --out out/sim2real
    Tuning:  evids sim2real --real ~/data/Drone-detection-dataset --tune --out out/s2r_tune_main
             (edit the protocol) evids sim2real --real ... --tune --out out/s2r_tune_b --reuse-renders out/s2r_tune_main
    """
    from harness.experiments.sim2real.config import DEFAULT_CONFIG
    from harness.experiments.sim2real.harness import format_table, run_sim2real
    from harness.runfolder import create_run_folder
    from scenes.errors import UserInputError
    from simulator.files import DatasetLock, is_evids_output

    if not real.exists():
        raise UserInputError(f"--real: {str(real)!r} does not exist")
    cfg_path = config if config is not None else DEFAULT_CONFIG
    if not Path(cfg_path).is_file():
        raise UserInputError(f"--config: {str(cfg_path)!r} does not exist")
    if reuse_renders is not None and not (reuse_renders.is_dir() and is_evids_output(reuse_renders)
                                          and (reuse_renders / "synthetic").is_dir()):
        raise UserInputError(f"--reuse-renders: {str(reuse_renders)!r} is not an evids sim2real run folder "
                             "(no synthetic/ written by evids)")
    create_run_folder(out, inputs=[real, cfg_path] + ([reuse_renders] if reuse_renders is not None else []))
    with DatasetLock(out, "sim2real"):
        summary = run_sim2real(real, out, config_path=cfg_path, quick=quick, strict=strict, progress=progress,
                               log=typer.echo, tune=tune, reuse_renders=reuse_renders)
    typer.echo(format_table(summary))
    typer.echo(f"report: {out / 'sim2real.html'}")


def sim2real_compare(
    before: Path = typer.Option(..., "--before", help="The `evids sim2real` run folder of the simulator before the "
                                "change."),
    after: Path = typer.Option(..., "--after", help="The run folder after it (same real data and protocol sizes)."),
    json_out: Path = typer.Option(None, "--json", help="Also write the comparison here (a new .json file; an "
                                  "existing one is not replaced)."),
    bootstrap: int = typer.Option(1000, "--bootstrap", min=100, max=100_000, help="Clip resamples."),
) -> None:
    """Judge a simulator change: every crop classifier condition of two sim2real runs compared PAIRED on the
    same real evaluation crops (balanced accuracy after - before, a clip-bootstrap 95 % interval and the
    minimum detectable difference). Nothing is retrained; the runs keep their predictions.

    Example: evids sim2real-compare --before out/s2r_main --after out/s2r_change
    """
    import json

    from harness.experiments.sim2real.compare import compare_runs, format_comparison
    from scenes.errors import UserInputError
    from simulator.files import write_atomic

    for name, folder in (("--before", before), ("--after", after)):
        if not (folder / "sim2real.json").is_file():
            raise UserInputError(f"{name}: {str(folder)!r} holds no sim2real.json (not a finished sim2real run)")
    if json_out is not None:
        if json_out.suffix != ".json":
            raise UserInputError(f"--json: {str(json_out)!r} must end in .json")
        if json_out.exists():
            raise UserInputError(f"--json: {str(json_out)!r} exists; choose a new file")
    result = compare_runs(before, after, bootstrap=bootstrap)
    typer.echo(format_comparison(result))
    if json_out is not None:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(json_out, json.dumps(result, indent=1, sort_keys=True) + "\n")
        typer.echo(f"written: {json_out}")


def register(app: typer.Typer) -> None:
    app.command("sim2real")(sim2real)
    app.command("sim2real-compare")(sim2real_compare)
