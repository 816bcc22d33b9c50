"""CSV tables with a header row, checked once for every reader (labels, pose predictions, the
grounding index).

:func:`read_csv` returns the header and the data rows with their line numbers, or raises an
:class:`~artmotion.errors.InputError` naming the file (and line): missing, not UTF-8, not CSV,
empty, a header with an empty or repeated column name (a repeated name would silently hide one of
the columns), missing required columns, a row with the wrong number of values. :func:`cell_number`
reads one value as a finite number in a range.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Sequence
from pathlib import Path

from artmotion.errors import InputError, check_range
from artmotion.io.files import number, read_text

__all__ = ["MAX_ANGLE", "cell_number", "read_csv"]

#: angles (degrees) of the pose CSV files (labels, predictions; docs/interfaces.md) lie within +-this
MAX_ANGLE = 1e6


def read_csv(path: str | os.PathLike, need: Sequence[str] = (), what: str = "CSV file"
             ) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """``(header, [(line number, values), ...])`` of a CSV file whose first row names its columns;
    names and values are stripped of spaces, blank rows skipped. ``need``: columns that must be
    there. ``what`` names the kind of file in messages."""
    path = Path(path)
    text = read_text(path, f"a {what}")
    reader = csv.reader(io.StringIO(text, newline=""))
    rows: list[tuple[int, list[str]]] = []
    try:
        for row in reader:
            if row and any(c.strip() for c in row):
                rows.append((reader.line_num, [c.strip() for c in row]))
    except csv.Error as exc:
        raise InputError(f"not a {what}: {exc}", path=path, line=reader.line_num) from None
    if not rows:
        raise InputError(f"empty file (a {what} starts with a header row)", path=path, line=1)
    line, header = rows[0]
    if any(not name for name in header):
        raise InputError("the header has an empty column name", path=path, line=line)
    twice = sorted({name for name in header if header.count(name) > 1})
    if twice:
        raise InputError(f"column {twice[0]!r} appears more than once in the header", path=path, line=line)
    missing = [c for c in need if c not in header]
    if missing:
        raise InputError(f"the header lacks columns {', '.join(missing)}", path=path, line=line)
    for lineno, row in rows[1:]:
        if len(row) != len(header):
            raise InputError(f"expected {len(header)} values, found {len(row)}", path=path, line=lineno)
    return header, rows[1:]


def cell_number(value: str, column: str, path, line: int, lo: float, hi: float) -> float:
    """The text ``value`` of column ``column`` as a finite number in ``[lo, hi]``."""
    try:
        v = number(value)
    except ValueError:
        raise InputError(f"{column}: not a number: {value[:40]!r}", path=path, line=line) from None
    return check_range(column, v, lo, hi, path=path, line=line)
