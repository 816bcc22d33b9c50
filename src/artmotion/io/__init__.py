"""File formats and safe writing (MOTChallenge text, event JSON lines, atomic output)."""

from artmotion.io.atomic import atomic_dir, atomic_path, atomic_write, check_apart, check_writable, save_figure
from artmotion.io.events import read_events, write_events
from artmotion.io.files import check_text
from artmotion.io.mot import MOT_COLUMNS, read_mot, write_mot

__all__ = [
    "MOT_COLUMNS",
    "atomic_dir",
    "atomic_path",
    "atomic_write",
    "check_apart",
    "check_text",
    "check_writable",
    "read_events",
    "read_mot",
    "save_figure",
    "write_events",
    "write_mot",
]
