"""The ``artmotion`` command line: a thin layer over the Python API.

Each capability registers its commands from its own ``cli`` module. Errors the user can act on
(:class:`artmotion.errors.ArtmotionError`, and OS errors such as a full disk) are printed as one
line on stderr with exit status 2; set ``ARTMOTION_DEBUG=1`` to see tracebacks.
"""

from __future__ import annotations

import os
import sys

import typer

from artmotion import __version__
from artmotion.errors import ArtmotionError

app = typer.Typer(
    name="artmotion",
    help="Understand articulated motion from cameras: track, pose, articulation, language.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _version(value: bool):
    if value:
        typer.echo(f"artmotion {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, help="Print the version."),
):
    """artmotion: tracking, pose, articulation and language from video."""


def _register_all() -> None:
    from artmotion.tracking import cli as tracking_cli
    from artmotion.pose import cli as pose_cli
    from artmotion.articulation import cli as articulation_cli
    from artmotion.language import cli as language_cli
    from artmotion.app import cli as app_cli

    for module in (tracking_cli, pose_cli, articulation_cli, language_cli, app_cli):
        module.register(app)


_register_all()


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the exit status."""
    debug = bool(os.environ.get("ARTMOTION_DEBUG"))
    try:
        app(args=argv, prog_name="artmotion", standalone_mode=True)
    except SystemExit as exc:
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else 1)
    except ArtmotionError as exc:
        if debug:
            raise
        print(f"artmotion: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except OSError as exc:
        if debug:
            raise
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print(f"artmotion: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("artmotion: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # a bug: still one line, unless debugging
        if debug:
            raise
        print(
            f"artmotion: internal error: {type(exc).__name__}: {exc} (ARTMOTION_DEBUG=1 shows the traceback)",
            file=sys.stderr,
        )
        return 1
    return 0
