"""Native libraries' own messages (FFmpeg, OpenCV) kept off stderr.

Imports nothing heavy: the command line calls :func:`quiet_native_logs` before every command.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator


def quiet_native_logs() -> None:
    """Silence OpenCV's messages on stderr (``[ WARN:0] ... Failed to write frame``): the readers of
    :mod:`artmotion.io.media` report damage as one :class:`~artmotion.errors.InputError` naming the
    file, and writers are checked. FFmpeg's are not silenced (OpenCV then leaves FFmpeg's log at
    its errors, on stderr): :mod:`artmotion.io.media` captures them while a video opens and while
    each frame decodes, because they are the only report of damage FFmpeg decoded around
    (``[mpeg4 @ 0x...] illegal dc vlc``), and keeps them off stderr (a video writer's too, as it
    opens and closes). ``ARTMOTION_DEBUG=1`` keeps them all."""
    if os.environ.get("ARTMOTION_DEBUG"):
        return
    os.environ.setdefault("OPENCV_LOG_LEVEL", "SILENT")
    cv2 = sys.modules.get("cv2")
    if cv2 is not None and hasattr(cv2, "utils"):
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)


@contextlib.contextmanager
def signals_held(enabled: bool = True) -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP back while the block runs: one that arrives meanwhile is
    recorded and handed to its handler as the block ends. For work that an interruption must not
    cut in two: the import of torch (whose native start-up calls back into Python: interrupted
    there, the process aborted with "terminate called after throwing an instance of
    'pybind11::error_already_set'", exit 134 and a stack dump, instead of the command line's one
    line), and the start of a batch's worker processes. Python runs signal handlers in the main
    thread only, so elsewhere (or when not ``enabled``) the block runs as it is."""
    import signal
    import threading

    if not enabled or threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    previous = {int(sig): signal.signal(sig, lambda signum, _frame: pending.append(signum))
                for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        _restore(list(previous.items()))
        if pending:
            handler = previous[pending[0]]
            if callable(handler):
                handler(pending[0], None)
            elif handler != signal.SIG_IGN:
                signal.raise_signal(pending[0])       # the default action


def _restore(handlers: list) -> None:
    """Put back each ``(signal, handler)``: every one, even when a handler put back first runs at
    once (a signal arriving meanwhile) and raises — each restore is in the ``finally`` of the one
    before."""
    import signal

    if handlers:
        try:
            if handlers[0][1] is not None:      # (a handler set from C, outside Python: none to put back)
                signal.signal(*handlers[0])
        finally:
            _restore(handlers[1:])
