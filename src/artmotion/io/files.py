"""Reading input files with one-line errors: the file must exist and be a regular file (a folder,
a device or a pipe would be read forever), and a read that fails names the file."""

from __future__ import annotations

import json
import os
from pathlib import Path

from artmotion.errors import InputError

__all__ = ["as_path", "check_text", "existing_file", "number", "read_head", "read_text"]


def number(text: str) -> float:
    """``float(text)`` for a field of a data file, without Python's literal extras: ``1_0`` is not
    ten (a ``ValueError``, as for any other text that is not a number)."""
    if "_" in text:
        raise ValueError(f"not a number: {text!r}")
    return float(text)


def as_path(value, what: str = "path") -> Path:
    """``value`` (text, bytes or a path object) as a :class:`~pathlib.Path`; anything else (None, a
    number) an :class:`InputError` naming ``what``, not a TypeError from deep inside."""
    if isinstance(value, bytes):
        value = os.fsdecode(value)
    if not isinstance(value, (str, os.PathLike)):
        raise InputError(f"{what} must be a file name (text or a path), got {type(value).__name__}")
    return Path(value)


def check_text(path: str | os.PathLike, why: str = "an index keeps paths as text", fix: str = "rename it") -> None:
    """An :class:`InputError` naming ``path`` when it holds bytes that are not UTF-8 (read by Python as
    lone surrogates): such a name cannot be stored as text (``why``), so the work that would need it
    is refused before it starts rather than after; ``fix``: what to do about it."""
    try:
        os.fsdecode(path).encode("utf-8")
    except UnicodeEncodeError:
        raise InputError(f"the name holds bytes that are not UTF-8 text ({why}): {fix}", path=path) from None


def existing_file(path: str | os.PathLike, missing: str = "no such file") -> Path:
    """``path`` as a :class:`~pathlib.Path` if it is a regular file, else an :class:`InputError`
    (``missing`` when nothing is there, "not a file" otherwise)."""
    path = as_path(path)
    if not path.is_file():
        raise InputError(missing if not path.exists() else "not a file", path=path)
    return path


def read_head(path: str | os.PathLike, n: int, missing: str = "no such file") -> bytes:
    """The first ``n`` bytes of the regular file ``path`` (fewer if it is shorter)."""
    path = existing_file(path, missing)
    try:
        with open(path, "rb") as fh:
            return fh.read(n)
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", path=path) from None


def check_riff_size(path: str | os.PathLike, head: bytes) -> None:
    """An :class:`InputError` when ``path``, a RIFF file (AVI, WAV) whose first bytes are ``head``,
    is shorter than its header declares: it lost its end, which OpenCV and libsndfile read past
    without a word (the frames or samples that are left)."""
    if head[:4] != b"RIFF" or len(head) < 8:
        return
    declared = int.from_bytes(head[4:8], "little") + 8
    size = Path(path).stat().st_size
    if size < declared:
        raise InputError(f"truncated: {size} of the {declared} bytes its header declares", path=path)


def _not_json_constant(name: str):
    raise ValueError(f"{name} is not a number JSON allows")


def _no_repeated_key(pairs: list[tuple[str, object]]) -> dict:
    out: dict = {}
    for k, v in pairs:
        if k in out:
            raise ValueError(f"key {k!r} given twice in one object")
        out[k] = v
    return out


def strict_json(text: str):
    """``json.loads`` of what JSON allows: ``NaN`` and ``Infinity`` (Python's extensions) and a key
    given twice in one object (the parser keeps the last value; which was meant is not known) are
    a ValueError (``json.JSONDecodeError`` for other malformed text; RecursionError when nested
    too deeply)."""
    return json.loads(text, parse_constant=_not_json_constant, object_pairs_hook=_no_repeated_key)


def read_text(path: str | os.PathLike, what: str) -> str:
    """The UTF-8 text (a byte-order mark dropped) of the regular file ``path``; ``what`` names the
    kind of file in the message when it is not text ("a MOTChallenge file")."""
    path = existing_file(path)
    try:
        return path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(f"not UTF-8 text ({what} is text)", path=path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", path=path) from None
