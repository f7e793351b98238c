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


def _register_all() -> None:
    from evids.cli import degrade as degrade_cli
    from evids.cli import detect as detect_cli
    from evids.cli import experiments as experiments_cli
    from evids.cli import generate as generate_cli
    from evids.cli import render as render_cli
    from evids.cli import sim2real as sim2real_cli

    render_cli.register(app)
    degrade_cli.register(app)
    generate_cli.register(app)
    experiments_cli.register(app)
    detect_cli.register(app)
    sim2real_cli.register(app)


def main(argv: list[str] | None = None) -> None:
    """Console entry point: bad input prints one line and exits 2; a file-system failure (disk full,
    permission) prints one line naming the path and exits 1; Ctrl-C exits 130. Anything else is a
    bug and keeps its traceback (set EVIDS_DEBUG=1 to see tracebacks for the cases above too)."""
    import os

    _register_all()
    debug = bool(os.environ.get("EVIDS_DEBUG"))
    from degradations.errors import DegradationError

    try:
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
