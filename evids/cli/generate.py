"""`evids generate CONFIG --out DIR --format trident`: tri-modal TRIDENT-layout datasets.

Multi-sequence native/Anti-UAV/MOT/COCO generation is the dataset-generation issue's work; until it
lands, other formats are refused with a pointer to `evids render` (one sequence at a time).
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from evids.errors import UserInputError


def generate(
    config: str = typer.Argument(..., help="A TRIDENT generation preset name (e.g. trident_mini) or YAML path."),
    out: Path = typer.Option(..., "--out", "-o", help="Output folder (must be empty or absent)."),
    seed: int = typer.Option(0, "--seed", min=0, help="Seed of every random draw."),
    fmt: str = typer.Option("trident", "--format", help="Dataset layout; currently: trident."),
    clips: Optional[int] = typer.Option(None, "--clips", min=1, help="Generate only the first N clips."),
    quiet: bool = typer.Option(False, "--quiet", help="No progress bar."),
) -> None:
    """Generate a dataset of drone and background clips (RGB video, audio, RF) in the TRIDENT layout.

    Example: evids generate trident_mini --out out/trident --format trident
    """
    if fmt != "trident":
        raise UserInputError(f"--format {fmt!r} is not available in `generate` yet; valid: trident. "
                             "For single sequences in native/antiuav layout use `evids render`.")
    from simulator.trident import generate_trident

    try:
        path = generate_trident(config, out, seed, n_clips=clips, progress=not quiet)
    except ValueError as exc:
        if isinstance(exc, UserInputError):
            raise
        raise UserInputError(str(exc)) from None
    typer.echo(f"trident: {path}")


def register(app: typer.Typer) -> None:
    app.command("generate")(generate)
