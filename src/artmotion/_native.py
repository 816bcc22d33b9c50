"""Native libraries' own messages (FFmpeg, OpenCV) kept off stderr.

Imports nothing heavy: the command line calls :func:`quiet_native_logs` before every command.
"""

from __future__ import annotations

import os
import sys


def quiet_native_logs() -> None:
    """Silence FFmpeg's and OpenCV's messages on stderr (``[mjpeg @ 0x...] overread 8``,
    ``[ WARN:0] ... Failed to write frame``): the readers of :mod:`artmotion.io.media` report damage
    as one :class:`~artmotion.errors.InputError` naming the file, and writers are checked. FFmpeg
    reads its level when OpenCV first opens a video, so call this before. ``ARTMOTION_DEBUG=1``
    keeps them."""
    if os.environ.get("ARTMOTION_DEBUG"):
        return
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")      # AV_LOG_QUIET
    os.environ.setdefault("OPENCV_LOG_LEVEL", "SILENT")
    cv2 = sys.modules.get("cv2")
    if cv2 is not None and hasattr(cv2, "utils"):
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
