"""The `evids` command line: one entry point, thin sub-commands over tested library code.

Each sub-command lives in its own module with a ``register(app)`` function; this module only
assembles them and turns expected errors into a one-line message and exit status 2.
"""
from __future__ import annotations

import sys

import typer

from scenes.errors import UserInputError

app = typer.Typer(
    name="evids",
    help="Synthetic counter-drone scenarios (RGB/thermal/audio/RF), sensor degradations and "
    "evidential-fusion experiments, all on the CPU.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _no_placeholder_for_flags() -> None:
    """Recent typer prints a ``<bool>`` type beside every ``--flag/--no-flag`` in --help, as if the
    flag took a value: show no type for flags, and ranged types without the word "range" (older
    typer, without display_type_rich, shows neither)."""
    from typer.core import TyperOption

    original = getattr(TyperOption, "display_type_rich", None)
    if original is None or getattr(original, "evids_flags", False):
        return

    def display_type_rich(self, ctx):  # noqa: ANN001 - typer's signature
        if getattr(self, "is_flag", False):
            return None
        # "<float range> [0.0<=x<=0.99]" -> "<float> [0.0<=x<=0.99]": the range follows anyway, and the
        # shorter type column leaves the help text room (export --help was squeezed into ~40 columns)
        return original(self, ctx).replace(" range>", ">")

    display_type_rich.evids_flags = True  # type: ignore[attr-defined]  # marker: patched once per process
    TyperOption.display_type_rich = display_type_rich  # type: ignore[method-assign]  # patching typer's class


_no_placeholder_for_flags()

TRACKEVAL_INSTALL = ("bash run.sh installs it; with pip: pip install --no-deps trackeval==1.3.0 (the tracking extra "
                     "cannot bring it: trackeval declares the GUI opencv-python, which would replace "
                     "opencv-python-headless)")


def require_module(module: str, what: str, install: str) -> None:
    """An optional dependency checked at a command's start (not minutes into it): UserInputError,
    one line naming what needs it and how to install it (the extra)."""
    import importlib.util

    if importlib.util.find_spec(module) is None:
        raise UserInputError(f"{what} needs the Python package {module!r}, which is not installed: {install}")


def _register_all() -> None:
    from harness.cli import degrade as degrade_cli
    from harness.cli import detect as detect_cli
    from harness.cli import experiments as experiments_cli
    from harness.cli import generate as generate_cli
    from harness.cli import realbench as realbench_cli
    from harness.cli import render as render_cli
    from harness.cli import sim2real as sim2real_cli

    render_cli.register(app)
    degrade_cli.register(app)
    generate_cli.register(app)
    experiments_cli.register(app)
    detect_cli.register(app)
    sim2real_cli.register(app)
    realbench_cli.register(app)


def main(argv: list[str] | None = None) -> None:
    """Console entry point: bad input prints one line and exits 2; a file-system failure (disk full,
    permission) prints one line naming the path and exits 1; Ctrl-C exits 130. Anything else is a
    bug and keeps its traceback (set EVIDS_DEBUG=1 to see tracebacks for the cases above too)."""
    import os

    _register_all()
    debug = bool(os.environ.get("EVIDS_DEBUG"))
    from degradations.errors import DegradationError

    try:
        from simulator.render.mitsuba_setup import requested_variant

        requested_variant()  # a bad EVIDS_MITSUBA_VARIANT fails every command at once, not mid-render
        app(args=argv, standalone_mode=True)
    except (UserInputError, DegradationError) as exc:
        if debug:
            raise
        typer.echo(f"error: {_bounded(str(exc))}", err=True)
        sys.exit(2)
    except FileExistsError as exc:  # the safe-output rule refused to replace something
        if debug:
            raise
        typer.echo(f"error: {_bounded(str(exc))}", err=True)
        sys.exit(2)
    except RecursionError:
        if debug:
            raise
        typer.echo("error: input nested too deeply to process", err=True)
        sys.exit(2)
    except OSError as exc:
        if debug:
            raise
        typer.echo(f"error: {exc.strerror or exc}{f': {exc.filename}' if exc.filename else ''}", err=True)
        sys.exit(1)
    except KeyboardInterrupt:
        typer.echo("interrupted", err=True)
        sys.exit(130)


MAX_MESSAGE_CHARS = 4000


def _bounded(text: str) -> str:
    """Error text cut to MAX_MESSAGE_CHARS (a message never reproduces a huge input)."""
    return text if len(text) <= MAX_MESSAGE_CHARS else text[: MAX_MESSAGE_CHARS - 20] + " ... (truncated)"
