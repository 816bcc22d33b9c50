"""Images and videos, checked before they are believed.

OpenCV decodes a truncated JPEG as an image whose missing part is gray, and opens almost any file
as a "video" (a JPEG renamed ``.mp4`` is a one-frame video). Tracking a gray frame, or a text file,
and reporting success is the worst thing a tracker can do, so every image and video goes through
here:

* :func:`read_image` reads a file's bytes once, checks their structure — a JPEG's marker segments
  up to the end-of-image marker, with the entropy-coded data of every scan scanned for bytes that
  cannot occur there; a PNG's chunks with their CRCs up to ``IEND`` — and decodes the same bytes
  (no second read). A damaged file is an :class:`~artmotion.errors.InputError` naming it. Damage
  that keeps the structure intact (a block of a JPEG's data overwritten by zeros) cannot be seen
  without decoding and is not caught.
* :func:`check_video` recognises a video container by its first bytes (MP4/MOV, AVI, Matroska/
  WebM, MPEG, FLV, ASF/WMV, Ogg) and refuses images and anything else.

File types are named here once (:data:`IMAGE_EXTS`, :data:`VIDEO_EXTS`) for every reader.
"""

from __future__ import annotations

import os
import zlib
from pathlib import Path

import numpy as np

from artmotion.errors import InputError

__all__ = ["IMAGE_EXTS", "VIDEO_EXTS", "check_image_bytes", "check_video", "image_problem", "read_image"]

IMAGE_EXTS = frozenset({".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp", ".ppm", ".pgm", ".pnm"})
VIDEO_EXTS = frozenset({".mp4", ".avi", ".mov", ".mkv", ".m4v", ".mpg", ".mpeg", ".webm", ".wmv", ".flv", ".ts",
                        ".ogv"})

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _jpeg_problem(b: np.ndarray) -> str | None:
    """What is wrong with the JPEG bytes ``b`` (uint8), or ``None``."""
    n = len(b)
    ff = np.flatnonzero(b == 0xFF)
    pos = 2
    while True:
        if pos + 1 >= n:
            return "truncated JPEG (ends before its end-of-image marker)"
        if b[pos] != 0xFF:
            return f"corrupt JPEG (no marker at byte {pos})"
        m = int(b[pos + 1])
        if m == 0xFF:                        # fill byte
            pos += 1
            continue
        if m == 0xD9:                        # end of image
            return None
        if 0xD0 <= m <= 0xD7 or m == 0x01:   # markers without a length
            pos += 2
            continue
        if m < 0xC0:
            return f"corrupt JPEG (invalid marker 0x{m:02X} at byte {pos})"
        if pos + 3 >= n:
            return "truncated JPEG (ends inside a marker segment)"
        end = pos + 2 + ((int(b[pos + 2]) << 8) | int(b[pos + 3]))
        if end > n:
            return "truncated JPEG (ends inside a marker segment)"
        if m != 0xDA:
            pos = end
            continue
        # a scan's entropy-coded data: a 0xFF byte is followed by a stuffed 0x00, a restart
        # marker 0xD0-0xD7, another 0xFF (fill), or the next marker (>= 0xC0)
        cand = ff[np.searchsorted(ff, end):]
        cand = cand[cand + 1 < n]
        nxt = b[cand + 1]
        stop = np.flatnonzero((nxt != 0x00) & ((nxt < 0xD0) | (nxt > 0xD7)) & (nxt != 0xFF))
        if not len(stop):
            return "truncated JPEG (ends inside the image data)"
        pos = int(cand[stop[0]])
        if b[pos + 1] < 0xC0:
            return f"corrupt JPEG (invalid byte sequence in the image data at byte {pos})"


def _png_problem(data: bytes) -> str | None:
    """What is wrong with the PNG bytes ``data``, or ``None`` (chunks and CRCs up to IEND)."""
    pos, n = 8, len(data)
    while True:
        if pos + 8 > n:
            return "truncated PNG (ends before its IEND chunk)"
        length = int.from_bytes(data[pos:pos + 4], "big")
        kind = data[pos + 4:pos + 8]
        end = pos + 12 + length
        if end > n:
            return "truncated PNG (ends inside a chunk)"
        crc = int.from_bytes(data[end - 4:end], "big")
        if zlib.crc32(data[pos + 4:end - 4]) != crc:
            return f"corrupt PNG (bad checksum of a {kind.decode('latin-1')!r} chunk)"
        if kind == b"IEND":
            return None
        pos = end


def image_problem(buf: np.ndarray) -> str | None:
    """What is wrong with the image file bytes ``buf`` (uint8), or ``None`` when its structure is
    sound (JPEG and PNG are checked through; other formats only by their decoder)."""
    if len(buf) >= 3 and buf[0] == 0xFF and buf[1] == 0xD8 and buf[2] == 0xFF:
        return _jpeg_problem(buf)
    if bytes(buf[:8]) == _PNG_SIGNATURE:
        return _png_problem(buf.tobytes())
    return None


def check_image_bytes(buf: np.ndarray, path) -> None:
    """Raise an :class:`InputError` naming ``path`` when :func:`image_problem` finds one."""
    problem = image_problem(buf)
    if problem is not None:
        raise InputError(problem, path=path)


def read_image(path: str | os.PathLike, flags: int | None = None) -> np.ndarray:
    """Read and check an image file (see the module docstring); ``flags`` are OpenCV's imread
    flags (default ``IMREAD_COLOR``; ``IMREAD_REDUCED_COLOR_2`` etc. decode it smaller). Returns
    the decoded image; raises :class:`InputError` for a missing, empty, damaged or undecodable
    file."""
    import cv2

    try:
        buf = np.fromfile(os.fspath(path), dtype=np.uint8)
    except FileNotFoundError:
        raise InputError("no such file", path=path) from None
    except IsADirectoryError:
        raise InputError("is a folder, not an image", path=path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path=path) from None
    if not len(buf):
        raise InputError("empty file", path=path)
    check_image_bytes(buf, path)
    img = cv2.imdecode(buf, cv2.IMREAD_COLOR if flags is None else flags)
    if img is None or img.size == 0:
        raise InputError("cannot decode image (corrupt or not an image)", path=path)
    return img


#: first bytes of video containers: (offset, bytes)
_VIDEO_MAGIC = (
    (4, b"ftyp"), (4, b"moov"), (4, b"mdat"), (4, b"wide"), (4, b"free"), (4, b"skip"),   # MP4 / MOV
    (0, b"RIFF"),                                                                       # AVI (RIFF....AVI )
    (0, b"\x1a\x45\xdf\xa3"),                                                           # Matroska / WebM
    (0, b"\x00\x00\x01\xba"), (0, b"\x00\x00\x01\xb3"),                                 # MPEG program / video
    (0, b"FLV"), (0, b"OggS"),
    (0, b"\x30\x26\xb2\x75\x8e\x66\xcf\x11"),                                           # ASF / WMV
)


def check_video(path: str | os.PathLike) -> Path:
    """``path`` if it is a file whose content is a video container, else an :class:`InputError`
    saying what it is (missing, a folder, empty, an image, not a video)."""
    path = Path(path)
    if not path.exists():
        raise InputError("no such file", path=path)
    if not path.is_file():
        raise InputError("not a file", path=path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(16)
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path=path) from None
    if not head:
        raise InputError("empty file", path=path)
    if head[:3] == b"\xff\xd8\xff" or head[:8] == _PNG_SIGNATURE:
        raise InputError("is an image, not a video", path=path)
    if head[:4] == b"RIFF" and head[8:12] not in (b"AVI ", b"AVIX"):
        raise InputError("not a video (a RIFF file that is not AVI)", path=path)
    mpeg_ts = head[:1] == b"\x47" and path.suffix.lower() in (".ts", ".mts", ".m2ts")
    if not mpeg_ts and not any(head[o:o + len(m)] == m for o, m in _VIDEO_MAGIC):
        kind = f" (extension {path.suffix})" if path.suffix else ""
        raise InputError(f"not a video{kind}: its content is no known video container", path=path)
    return path
