"""The ``artmotion`` command line: a thin layer over the Python API.

Each capability registers its commands from its own ``cli`` module. Errors the user can act on
(:class:`artmotion.errors.ArtmotionError`, and OS errors such as a full disk) are printed as one
line on stderr with exit status 2 (out of memory and bugs: 1); set ``ARTMOTION_DEBUG=1`` to see
tracebacks.
"""

from __future__ import annotations

import contextlib
import copy
import os
import re
import sys
from pathlib import Path

import typer

from artmotion import __version__
from artmotion.errors import ArtmotionError, Interrupted, one_line

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
    from artmotion.app import cli as app_cli
    from artmotion.articulation import cli as articulation_cli
    from artmotion.language import cli as language_cli
    from artmotion.pose import cli as pose_cli
    from artmotion.tracking import cli as tracking_cli
    from artmotion.tracking.instruments import cli as tools_cli

    for module in (tracking_cli, tools_cli, pose_cli, articulation_cli, language_cli, app_cli):
        module.register(app)


_register_all()


def _app_for(args: list[str]) -> typer.Typer:
    """The app with only the command (or group) that ``args`` name registered, when they name
    one: Typer builds the click command of every registered command (docstrings, annotations) on
    each call, a tenth of ``artmotion track``'s start-up; ``--help``, a bare ``artmotion`` and an
    unknown name get the whole app (its list, its suggestions)."""
    if not args or args[0].startswith("-"):
        return app
    name = args[0]
    commands = [c for c in app.registered_commands
                if (c.name or getattr(c.callback, "__name__", "").replace("_", "-")) == name]
    groups = [g for g in app.registered_groups if g.name == name]
    if not commands and not groups:
        return app
    pruned = copy.copy(app)
    pruned.registered_commands, pruned.registered_groups = commands, groups
    return pruned


def _terminate(signum, frame):
    """The first SIGINT, SIGTERM or SIGHUP: :class:`Interrupted`, while whose unwinding the
    outputs being written are removed. Any later one is ignored, or it would cut that clean-up
    short (a second Ctrl-C left a hidden, half-written folder behind); SIGKILL still ends it."""
    import signal

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_IGN)
    raise Interrupted(signum)


#: what an interrupted command has kept: finished outputs are complete, nothing else is there
_KEPT = "outputs finished before it are complete; nothing half-written was kept"


def _release_process_resources() -> None:
    """Before ``os._exit``: unlink the semaphores of multiprocessing (a batch's local cluster
    interrupted while starting), which its resource tracker would otherwise report as leaked."""
    mp_util = sys.modules.get("multiprocessing.util")
    if mp_util is not None:
        try:
            mp_util._run_finalizers(0)
        except Exception:       # best effort: the process ends next
            pass


def _fail(message: str, code: int) -> int:
    """Print ``message`` as one line on stderr and return ``code``. A frame reader's thread may
    have the file descriptor 2 pointed at a scratch file while a codec decodes
    (``artmotion.io.media``): the line waits for it, or it would land there and be lost when the
    process ends at once (an interrupted run)."""
    message = one_line(message)
    media = sys.modules.get("artmotion.io.media")     # never imported: nothing was decoded
    lock = media.stderr_lock if media is not None else None
    held = lock is not None and lock.acquire(timeout=10)
    try:
        print(f"artmotion: {message}", file=sys.stderr, flush=True)
    finally:
        if held and lock is not None:
            lock.release()
    return code


class _Stdout:
    """``sys.stdout`` while a command runs: when the reader of a pipe has gone (``artmotion run … |
    head -1``), the printing stops and the work goes on. A write raised ``BrokenPipeError`` out of
    the command before: it exited 1 without a word, and ``run`` left its ``--index`` unwritten.
    The file descriptor is pointed at /dev/null (what is still buffered, and the interpreter's
    flush at exit, go there); everything else is the stream's. Any other failure to write (a
    full disk, ``> /dev/full``) stops the printing the same way and is kept in :attr:`failed`: the
    work goes on, and the command ends with one line saying what was not printed (it aborted the
    command, without naming what could not be written)."""

    def __init__(self, stream):
        self._stream = stream
        self.failed: OSError | None = None

    def write(self, text):
        try:
            return self._stream.write(text)
        except OSError as exc:
            self._closed(exc)
            return len(text)

    def writelines(self, lines):
        for line in lines:
            self.write(line)

    def flush(self):
        try:
            self._stream.flush()
        except OSError as exc:
            self._closed(exc)

    def _closed(self, exc: OSError) -> None:
        if self.failed is None and not isinstance(exc, BrokenPipeError):   # (a reader gone is no failure)
            self.failed = exc
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            try:
                os.dup2(devnull, self._stream.fileno())
            finally:
                os.close(devnull)
        except (OSError, ValueError, AttributeError):    # no file descriptor (a test's capture): no more output
            self._stream = open(os.devnull, "w", encoding="utf-8")
        with contextlib.suppress(OSError, ValueError):
            self._stream.flush()        # (what was buffered goes to /dev/null, not again to the failing file)

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _note_slashed(args: list[str]) -> None:
    """Tell the output layer which names the command line gave with a slash at the end
    (:data:`artmotion.io.atomic.SLASHED`): a command's ``Path`` option loses it (``--model newdir/``
    wrote a file called ``newdir``)."""
    slashed = set()
    for arg in args:
        value = arg.split("=", 1)[1] if arg.startswith("--") and "=" in arg else arg
        if len(value) > 1 and value.endswith(("/", os.sep)):
            slashed |= {value.rstrip("/" + os.sep), os.fspath(Path(value))}
    if slashed:     # (imported only then: --help stays light)
        from artmotion.io import atomic

        atomic.SLASHED.update(slashed)


def _empty_argument(args: list[str]) -> str | None:
    """The option (or ``an argument``) given an empty value (``--out ''``, ``--out=``, ``''``), or
    None: a path option takes ``''`` as the current folder (``--out ''`` wrote into it)."""
    for k, arg in enumerate(args):
        if arg.startswith("--") and arg.endswith("=") and len(arg) > 3:
            return arg[:-1]
        if arg == "":
            before = args[k - 1] if k else ""
            return before if before.startswith("-") and "=" not in before else "an argument"
    return None


def run() -> None:
    """The console script (and ``python -m artmotion``): :func:`main`, then exit with its status.

    Before exiting, the objects the command created are moved out of the garbage collector's
    reach (``gc.freeze``): reference counting frees them at exit all the same, and the
    interpreter's final collections no longer walk every one of them — about 30 ms of a short
    run such as TUD-Campus's 0.3 s. Outputs are complete and closed by then (written to a
    temporary name and renamed)."""
    import gc

    code = main()
    gc.freeze()
    sys.exit(code)


def main(argv: list[str] | None = None) -> int:
    """Run the command line on ``argv`` (default: ``sys.argv``) and return the exit status (the
    console script calls it through :func:`run`).

    Every failure is one line on stderr: bad input (:class:`ArtmotionError`, a usage error, an
    operating-system error such as a full disk, a standard output that cannot be written) exits
    with 2; Ctrl-C with 130 and SIGTERM with 143, after the outputs being written were removed; out
    of memory with 1; anything else is a bug (exit 1, with a hint).
    Python's warnings (a library's RuntimeWarning) are not shown: inputs and results are checked.
    ``ARTMOTION_DEBUG=1`` shows tracebacks and warnings.
    """
    import warnings

    with warnings.catch_warnings():
        if not os.environ.get("ARTMOTION_DEBUG") and not sys.warnoptions:
            warnings.simplefilter("ignore")
        return _main(argv)


def _main(argv: list[str] | None) -> int:
    import signal

    import click

    from artmotion._native import quiet_native_logs

    args = sys.argv[1:] if argv is None else argv
    if (empty := _empty_argument(args)) is not None:     # (before the signal handlers: nothing to restore)
        return _fail(f"error: {empty} is empty (a file name or a value cannot be: a path option took '' as the "
                     "current folder)", 2)
    debug = bool(os.environ.get("ARTMOTION_DEBUG"))
    quiet_native_logs()
    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        try:
            previous[sig] = signal.signal(sig, _terminate)
        except ValueError:      # not the main thread (a test runner, an embedding program)
            pass
    _note_slashed(args)
    stdout = sys.stdout
    if stdout is not None and not isinstance(stdout, _Stdout):
        sys.stdout = _Stdout(stdout)
    try:
        code = _app_for(args)(args=argv, prog_name="artmotion", standalone_mode=False)
        code = code if isinstance(code, int) else 0
        if isinstance(sys.stdout, _Stdout):     # (no stdout at all: nothing was printed, nothing failed)
            sys.stdout.flush()
            failed = sys.stdout.failed
            if failed is not None and code == 0:
                return _fail(f"error: standard output: cannot write: {failed.strerror or failed} (what the "
                             "command printed is lost; the work is done)", 2)
        return code
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.ClickException as exc:
        if debug:
            raise
        # Typer and click both add "Did you mean ...?" to an unknown command: say it once
        message = re.sub(r"( Did you mean [^?]*\?)\1+", r"\1", exc.format_message()).strip().rstrip(".")
        if not message:         # no arguments: the help was shown
            return exc.exit_code
        ctx = getattr(exc, "ctx", None)
        cmd = ctx.command_path.removeprefix("artmotion").strip() if ctx is not None else ""
        hint = f" (see 'artmotion {cmd + ' ' if cmd else ''}--help')"
        return _fail(f"error: {cmd + ': ' if cmd else ''}{message}{hint}", 2)
    except ArtmotionError as exc:
        if debug:
            raise
        return _fail(f"error: {exc}", exc.exit_code)
    except OSError as exc:
        if debug:
            raise
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        return _fail(f"error: {where}{exc.strerror or exc}", 2)
    except (KeyboardInterrupt, click.exceptions.Abort):
        return _fail(f"interrupted: {_KEPT}", 130)
    except Interrupted as exc:
        what = "interrupted" if exc.signum == signal.SIGINT else f"terminated by signal {exc.signum}"
        _fail(f"{what}: {exc.kept or _KEPT}", 0)
        # The outputs were cleaned up while unwinding. The process was asked to end: end it now,
        # without the interpreter's teardown, where a decoder or encoder thread of OpenCV that
        # the signal caught mid-start can abort the process (exit -6 instead of 128 + signal).
        sys.stdout.flush()
        sys.stderr.flush()
        _release_process_resources()
        os._exit(128 + exc.signum)
    except MemoryError as exc:  # not a bug, nor the input's fault: what would not fit, in one line
        if debug:
            raise
        return _fail(f"error: out of memory{f' ({exc})' if str(exc) else ''}: the machine could not hold what "
                     "the command needed (fewer workers, or smaller frames or crops, need less)", 1)
    except Exception as exc:  # a bug: still one line, unless debugging
        if debug:
            raise
        return _fail(f"internal error: {type(exc).__name__}: {exc} "
                     "(a bug: please report it; ARTMOTION_DEBUG=1 shows the traceback)", 1)
    finally:
        if sys.stdout is not stdout:
            sys.stdout.flush()          # (what print() left buffered: a closed pipe stops it here too)
            sys.stdout = stdout
        for sig, handler in previous.items():
            signal.signal(sig, handler)
