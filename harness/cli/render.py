"""`evids render` and `evids scenes ...`: thin wrappers over scenes.loader and simulator.dataset.sequence."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from scenes.errors import UserInputError

scenes_app = typer.Typer(help="List, show and validate scene presets and files.", no_args_is_help=True)


def _parse_formats(text: str) -> tuple[str, ...]:
    from simulator.dataset.sequence import FORMATS

    formats = tuple(f.strip() for f in text.split(",") if f.strip())
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        raise UserInputError(f"--format: unknown format(s) {bad or [text]}; valid: {', '.join(FORMATS)} "
                             "(comma-separated)")
    return formats


def render(
    scene: str = typer.Argument(..., help="A preset name (see `evids scenes list`) or a scenario YAML path."),
    out: Path = typer.Option(..., "--out", "-o", help="Output folder; the sequence goes to OUT/<scenario name>/."),
    seed: Optional[int] = typer.Option(None, "--seed", help="Random seed (default: the scenario's own seed, else 0)."),
    frames: Optional[int] = typer.Option(None, "--frames", min=1, help="Render only the first K frames."),
    fmt: str = typer.Option("native", "--format", help="native and/or antiuav, comma-separated."),
    preview: bool = typer.Option(False, "--preview",
                                 help="Also write OUT/<name>_preview.png (RGB | thermal contact sheet)."),
    overwrite: bool = typer.Option(False, "--overwrite",
                                   help="Replace OUT/<scenario name>/ if an earlier evids render wrote it."),
    quiet: bool = typer.Option(False, "--quiet", help="No progress bar."),
) -> None:
    """Render a scenario to paired RGB + thermal frames, masks and labels.

    Example: evids render dusk_crossover --out out --preview
    """
    from scenes.loader import load_scenario
    from simulator.dataset.sequence import render_sequence

    scenario = load_scenario(scene)
    formats = _parse_formats(fmt)
    if seed is not None and seed < 0:
        raise UserInputError(f"--seed must be >= 0, got {seed}")
    use_seed = seed if seed is not None else (scenario.seed if scenario.seed is not None else 0)
    from simulator.files import check_output, inside

    scene_file = [Path(scene)] if Path(scene).is_file() else []
    targets = [out / scenario.name] if "native" in formats else []
    if "antiuav" in formats:
        targets += [out / "antiuav" / scenario.name, out / "antiuav" / f"{scenario.name}_visible"]
    for target in targets:
        inside(target, out)
        check_output(target, inputs=scene_file, overwrite=overwrite)
    notes: list[str] = []
    written = render_sequence(scenario, use_seed, out, n_frames=frames, formats=formats, preview=preview,
                              progress=not quiet, overwrite=overwrite, notes=notes)
    for kind, path in written.items():
        typer.echo(f"{kind}: {path}")
    for note in notes:
        typer.echo(f"note: {note}", err=True)


@scenes_app.command("list")
def scenes_list() -> None:
    """Print the preset names with their whole descriptions (wrapped, nothing cut)."""
    import shutil
    import textwrap

    from scenes.loader import load_scenario, preset_names

    width = max(60, min(shutil.get_terminal_size((100, 24)).columns, 140))
    for name in preset_names():
        description = " ".join(load_scenario(name).description.split())
        typer.echo(textwrap.fill(description, width, initial_indent=f"{name:22s} ", subsequent_indent=" " * 23))


@scenes_app.command("show")
def scenes_show(name: str = typer.Argument(..., help="Preset name or YAML path.")) -> None:
    """Print a scenario as fully resolved YAML (every default filled in)."""
    from scenes.loader import load_scenario, scenario_to_yaml

    typer.echo(scenario_to_yaml(load_scenario(name)), nl=False)


@scenes_app.command("validate")
def scenes_validate(path: Path = typer.Argument(..., help="Scenario YAML file.")) -> None:
    """Validate a scenario file; errors name the field path and the bad value (exit status 2)."""
    from scenes.loader import load_scenario

    scenario = load_scenario(path)
    typer.echo(f"ok: {scenario.name} ({scenario.n_frames} frames, {len(scenario.targets)} targets)")


def register(app: typer.Typer) -> None:
    app.command("render")(render)
    app.add_typer(scenes_app, name="scenes")
