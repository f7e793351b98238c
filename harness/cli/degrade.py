"""`evids degrade DATASET --spec SPEC --out DIR`: a stored degraded copy of native sequences."""
from __future__ import annotations

from pathlib import Path

import typer

from scenes.errors import UserInputError


def degrade(
    dataset: Path = typer.Argument(..., help="A native sequence folder, or a folder of them."),
    spec: Path = typer.Option(..., "--spec", help="Degradation spec (YAML or JSON; see docs/DEGRADATIONS.md)."),
    out: Path = typer.Option(..., "--out", "-o", help="Output folder for the degraded copies."),
    seed: int = typer.Option(0, "--seed", min=0, help="Seed of every degradation draw."),
    overwrite: bool = typer.Option(False, "--overwrite",
                                   help="Replace degraded copies an earlier `evids degrade` wrote."),
) -> None:
    """Degrade RGB and thermal frames of native sequences by a spec; writes each sequence with a
    degradation_record.json (per-frame severity and compromised flags per modality).

    Example: evids degrade out/dusk_crossover --spec examples/ir_blind.yaml --out out/degraded
    """
    from degradations.errors import DegradationError
    from degradations.spec import load_spec
    from simulator.dataset.degrade import degrade_sequence, find_sequences
    from simulator.files import check_no_overlap, check_output

    try:
        parsed = load_spec(spec)
    except (DegradationError, ValueError) as exc:
        raise UserInputError(str(exc)) from None
    sequences = find_sequences(dataset)
    # every output is checked before the first is written: all or nothing is refused
    check_no_overlap(out, [dataset, *sequences, spec])
    for sequence in sequences:
        check_output(out / sequence.name, inputs=[dataset, sequence, spec], overwrite=overwrite)
    for sequence in sequences:
        try:
            path = degrade_sequence(sequence, parsed, out, seed, overwrite=overwrite)
        except DegradationError as exc:
            raise UserInputError(f"{sequence}: {exc}") from None
        typer.echo(f"degraded: {path}")


def register(app: typer.Typer) -> None:
    app.command("degrade")(degrade)
