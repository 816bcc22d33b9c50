"""Images and videos, checked before they are believed.

OpenCV decodes a truncated JPEG as an image whose missing part is gray, and opens almost any file
as a "video" (a JPEG renamed ``.mp4`` is a one-frame video). Tracking a gray frame, or a text file,
and reporting success is the worst thing a tracker can do, so every image and video goes through
here:

* :func:`read_image` reads a file's bytes once, checks their structure — a JPEG's marker segments
  up to the end-of-image marker, with the entropy-coded data of every scan scanned for bytes that
  cannot occur there; a PNG's chunks with their CRCs up to ``IEND`` — and decodes the same bytes
  (no second read). A damaged file is an :class:`~artmotion.errors.InputError` naming it. Damage
  that keeps the structure intact (bytes of a JPEG's image data cut out or overwritten) shows
  while decoding: libjpeg decodes around it and reports it only on stderr ("Corrupt JPEG data:
  premature end of data segment"), which is captured during the decode (:func:`_decode`) and
  made the error. What even the decoder cannot see (a flipped bit that changes one coefficient)
  is not caught.
* :func:`check_video` recognises a video container by its first bytes (MP4/MOV, AVI, Matroska/
  WebM, MPEG, FLV, ASF/WMV, Ogg) and refuses images and anything else, and an AVI shorter than
  its header declares (OpenCV plays a cut AVI's remaining frames and says nothing).
  :func:`open_capture` opens it with the AVI reader's own messages kept off stderr, and
  :func:`read_video_frame` reads a frame and refuses it when FFmpeg reported damage it decoded
  around (its log, on stderr, captured while the frame decodes).

* :func:`write_image` encodes an image in memory and writes it atomically (a full disk is an
  error naming the file, not a codec's message); :func:`check_written_video` reads back a video
  just written and refuses it unless every frame is there (OpenCV's writer reports no errors).
* OpenCV's own messages are kept off stderr by the command line
  (:func:`artmotion._native.quiet_native_logs`), FFmpeg's by the capture around every call into
  it: a damaged file is reported once, as an error naming it.

File types are named here once (:data:`IMAGE_EXTS`, :data:`VIDEO_EXTS`) for every reader.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import threading
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Literal

import numpy as np

from artmotion.errors import InputError
from artmotion.io.files import check_riff_size, check_text, read_head

__all__ = ["IMAGE_EXTS", "MAX_FPS", "MIN_FPS", "VIDEO_EXTS", "check_image_bytes", "check_video", "check_written_video",
           "cv2_name", "depth_note", "ffmpeg_quiet", "frame_depth", "image_problem", "open_capture", "read_frame", "read_image",
           "read_video_frame", "write_image"]

IMAGE_EXTS = frozenset({".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp", ".ppm", ".pgm", ".pnm"})
VIDEO_EXTS = frozenset({".mp4", ".avi", ".mov", ".mkv", ".m4v", ".mpg", ".mpeg", ".webm", ".wmv", ".flv", ".ts",
                        ".ogv"})

#: the frame rates of a sequence (frames per second) that every command accepts: from one frame in
#: 1000 s (time-lapse) to 1000 frames per second
MIN_FPS, MAX_FPS = 0.001, 1000.0

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


_Size = tuple[int, int] | None


def _jpeg_structure(b: np.ndarray) -> tuple[str | None, _Size]:
    """What is wrong with the JPEG bytes ``b`` (uint8), or ``None``; and the ``(width, height)`` of
    its frame header (SOFn segment) when the walk reached it."""
    n = len(b)
    ff = np.flatnonzero(b == 0xFF)
    pos = 2
    size: _Size = None
    while True:
        if pos + 1 >= n:
            return "truncated JPEG (ends before its end-of-image marker)", size
        if b[pos] != 0xFF:
            return f"corrupt JPEG (no marker at byte {pos})", size
        m = int(b[pos + 1])
        if m == 0xFF:                        # fill byte
            pos += 1
            continue
        if m == 0xD9:                        # end of image
            return None, size
        if 0xD0 <= m <= 0xD7 or m == 0x01:   # markers without a length
            pos += 2
            continue
        if m < 0xC0:
            return f"corrupt JPEG (invalid marker 0x{m:02X} at byte {pos})", size
        if pos + 3 >= n:
            return "truncated JPEG (ends inside a marker segment)", size
        end = pos + 2 + ((int(b[pos + 2]) << 8) | int(b[pos + 3]))
        if end > n:
            return "truncated JPEG (ends inside a marker segment)", size
        if m <= 0xCF and m not in (0xC4, 0xC8, 0xCC) and pos + 9 <= n:   # SOFn: precision, height, width
            size = (int(b[pos + 7]) << 8 | int(b[pos + 8]), int(b[pos + 5]) << 8 | int(b[pos + 6]))
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
            return "truncated JPEG (ends inside the image data)", size
        pos = int(cand[stop[0]])
        if b[pos + 1] < 0xC0:
            return f"corrupt JPEG (invalid byte sequence in the image data at byte {pos})", size


def _png_structure(data: bytes) -> tuple[str | None, _Size]:
    """What is wrong with the PNG bytes ``data``, or ``None`` (chunks and CRCs up to IEND); and the
    ``(width, height)`` of its IHDR chunk."""
    pos, n = 8, len(data)
    size: _Size = None
    while True:
        if pos + 8 > n:
            return "truncated PNG (ends before its IEND chunk)", size
        length = int.from_bytes(data[pos:pos + 4], "big")
        kind = data[pos + 4:pos + 8]
        if kind == b"IHDR" and pos + 16 <= n:
            size = (int.from_bytes(data[pos + 8:pos + 12], "big"), int.from_bytes(data[pos + 12:pos + 16], "big"))
        end = pos + 12 + length
        if end > n:
            return "truncated PNG (ends inside a chunk)", size
        crc = int.from_bytes(data[end - 4:end], "big")
        if zlib.crc32(data[pos + 4:end - 4]) != crc:
            return f"corrupt PNG (bad checksum of a {kind.decode('latin-1')!r} chunk)", size
        if kind == b"IEND":
            return None, size
        pos = end


def _tiff_ifd(data: bytes, at: int, order: Literal["little", "big"], big: bool) -> dict[int, int] | None:
    """The numeric tags (first value of each) of the TIFF image file directory at byte ``at`` of
    ``data`` (a TIFF file, or the TIFF inside a JPEG's EXIF segment), with ``-1`` the offset of the
    next directory; ``None`` if the data ends inside it. ``big``: BigTIFF (8-byte offsets)."""
    off_size, count_size, entry_size = (8, 8, 20) if big else (4, 2, 12)

    def uint(pos: int, size: int) -> int:
        return int.from_bytes(data[pos:pos + size], order)

    if at + count_size > len(data):
        return None
    n = uint(at, count_size)
    found = {}
    for k in range(min(n, 4096)):
        e = at + count_size + k * entry_size
        if e + entry_size > len(data):
            return None
        size = {3: 2, 4: 4, 16: 8}.get(uint(e + 2, 2))      # SHORT, LONG, LONG8
        if size is not None:       # tag, type, count, then the values or, if they do not fit, their offset
            value = e + 4 + off_size
            if uint(e + 4, off_size) * size > off_size:
                value = uint(value, off_size)
            found[uint(e, 2)] = uint(value, size)
    found[-1] = uint(at + count_size + n * entry_size, off_size)  # the next directory
    return found


def _tiff_header(data: bytes) -> tuple[Literal["little", "big"], bool, int]:
    """Byte order, BigTIFF or not, and the first directory's offset of the TIFF bytes ``data``."""
    order: Literal["little", "big"] = "little" if data[:2] == b"II" else "big"
    big = int.from_bytes(data[2:4], order) == 43
    first = int.from_bytes(data[8:16] if big else data[4:8], order)
    return order, big, first


def _tiff_structure(data: bytes) -> tuple[str | None, _Size]:
    """What artmotion cannot take in the TIFF bytes ``data`` — more than one page (a stack of
    frames: OpenCV decodes the first and says nothing), or floating-point samples (no 8-bit
    picture without a range nobody stated) — or ``None``; and the first page's ``(width, height)``.
    Reduced-resolution pages (thumbnails, ``NewSubfileType`` bit 0) are no pages. Damage is left to
    the decoder."""
    order, big, at = _tiff_header(data)
    first = _tiff_ifd(data, at, order, big) if len(data) >= (16 if big else 8) else None
    if first is None:
        return None, None
    size = (first[256], first[257]) if 256 in first and 257 in first else None
    if first.get(339) == 3:                                        # SampleFormat: IEEE float
        return ("a TIFF of floating-point samples: artmotion reads 8- or 16-bit images (convert it, "
                "e.g. scaled to 0-255)"), size
    seen: set[int] = set()
    at, pages = first[-1], 1
    while at and at not in seen and len(seen) < 10_000:
        seen.add(at)
        ifd = _tiff_ifd(data, at, order, big)
        if ifd is None:
            break
        pages += not ifd.get(254, 0) & 1
        at = ifd[-1]
    if pages > 1:
        return (f"a TIFF of {pages} pages: artmotion reads one image per file (save the pages as "
                "numbered frames)"), size
    return None, size


def exif_orientation(buf: np.ndarray) -> int:
    """The EXIF orientation (1-8; 1: as stored) of the JPEG bytes ``buf``; 1 without one (or for
    another format). artmotion decodes the pixels as stored and does not apply it (see
    :func:`read_image`)."""
    b = buf[:2**17].tobytes()
    if not b.startswith(b"\xff\xd8"):
        return 1
    pos = 2
    while pos + 4 <= len(b) and b[pos] == 0xFF and b[pos + 1] not in (0xDA, 0xD9):
        end = pos + 2 + int.from_bytes(b[pos + 2:pos + 4], "big")
        if b[pos + 1] == 0xE1 and b[pos + 4:pos + 10] == b"Exif\x00\x00":
            tiff = b[pos + 10:end]
            if len(tiff) >= 8:
                order, big, at = _tiff_header(tiff)
                ifd = _tiff_ifd(tiff, at, order, big)
                value = (ifd or {}).get(0x0112, 1)
                return value if 1 <= value <= 8 else 1
        pos = end
    return 1


#: first bytes of a TIFF file (little- and big-endian; classic and BigTIFF)
_TIFF_MAGIC = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")


def _image_structure(buf: np.ndarray) -> tuple[str | None, _Size]:
    """One walk through a JPEG's segments, a PNG's chunks or a TIFF's pages: what is wrong (``None``:
    sound, or another format) and the ``(width, height)`` its header states (``None``: not found,
    or another format)."""
    if len(buf) >= 3 and buf[0] == 0xFF and buf[1] == 0xD8 and buf[2] == 0xFF:
        return _jpeg_structure(buf)
    if bytes(buf[:8]) == _PNG_SIGNATURE:
        return _png_structure(buf.tobytes())
    if bytes(buf[:4]) in _TIFF_MAGIC:
        return _tiff_structure(buf.tobytes())
    return None, None


def image_problem(buf: np.ndarray) -> str | None:
    """What is wrong with the image file bytes ``buf`` (uint8), or ``None`` when its structure is
    sound (JPEG and PNG are checked through; other formats only by their decoder)."""
    return _image_structure(buf)[0]


def check_frame(frame, what: str = "a frame", min_side: int = 1) -> None:
    """An :class:`InputError` unless ``frame`` (``what``, for the message) is a BGR uint8 image
    ``(H, W, 3)`` (OpenCV's convention: what the readers return and every stage takes) whose sides
    have at least ``min_side`` pixels."""
    if not isinstance(frame, np.ndarray) or frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3:
        got = (f"a {frame.dtype} array of shape {frame.shape}" if isinstance(frame, np.ndarray)
               else f"a {type(frame).__name__}")
        raise InputError(f"{what} must be a BGR uint8 image (H, W, 3), got {got}")
    if min(frame.shape[:2]) < min_side:
        raise InputError(f"{what} of {frame.shape[1]}x{frame.shape[0]} pixels is too small "
                         f"(at least {min_side} a side)")


def check_image_bytes(buf: np.ndarray, path) -> None:
    """Raise an :class:`InputError` naming ``path`` when :func:`image_problem` finds one."""
    problem = image_problem(buf)
    if problem is not None:
        raise InputError(problem, path=path)


#: the most pixels an image may have (16384 x 8192): more is a decompression bomb, not a frame —
#: decoding a 20000 x 20000 PNG of 1 MB takes OpenCV many seconds and 1.2 GB
MAX_IMAGE_PIXELS = 2**27


def read_image(path: str | os.PathLike, flags: int | None = None) -> np.ndarray:
    """Read and check an image file (see the module docstring); ``flags`` are OpenCV's imread
    flags (default ``IMREAD_COLOR``; ``IMREAD_REDUCED_COLOR_2`` etc. decode it smaller). Returns
    the decoded image, its pixels as stored (an EXIF orientation tag is not applied:
    :func:`exif_orientation`); raises :class:`InputError` for a missing, empty, damaged or
    undecodable file."""
    return read_image_sized(path, flags)[0]


def read_image_sized(path: str | os.PathLike, flags: int | None = None,
                     expect: tuple[int, int] | None = None) -> tuple[np.ndarray, _Size]:
    """:func:`read_image`, and the ``(width, height)`` the file's header states (JPEG, PNG, TIFF;
    ``None`` for other formats): a reduced decode rounds the size, which the header does not.
    ``expect``: a sequence's frame size, which a stated size other than it is an error for (before
    the decoding)."""
    import cv2

    if "\x00" in os.fspath(path):
        raise InputError("not a file name (it holds a NUL byte)", path=os.fspath(path).replace("\x00", "\\0"))
    if os.path.exists(path) and not os.path.isdir(path) and not os.path.isfile(path):
        raise InputError("not a file (a device or a pipe)", path=path)     # would be read forever
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
    problem, size = _image_structure(buf)  # one walk: the file's structure and its stated size
    if problem is not None:
        raise InputError(problem, path=path)
    if expect is not None and size is not None and tuple(size) != tuple(expect):
        raise InputError(f"image size {size[0]}x{size[1]} differs from the sequence's {expect[0]}x{expect[1]}",
                         path=path)
    if size is not None and size[0] * size[1] > MAX_IMAGE_PIXELS:
        raise InputError(f"image of {size[0]}x{size[1]} pixels: larger than artmotion reads "
                         f"({MAX_IMAGE_PIXELS // 2**20} megapixels at most)", path=path)
    # the pixels as stored, whatever an EXIF orientation tag asks for: every coordinate artmotion
    # reads or writes (detections, ground truth, seqinfo.ini, the header's size) is in that frame
    img, damage = _decode(buf, (cv2.IMREAD_COLOR if flags is None else flags) | cv2.IMREAD_IGNORE_ORIENTATION)
    if damage:
        raise InputError(f"corrupt image data ({damage})", path=path)
    if img is None or img.size == 0:
        if size is not None:        # (a sound header: OpenCV's decoder also gives nothing when memory runs out)
            raise InputError(f"cannot decode the image of {size[0]}x{size[1]} pixels (corrupt data, or not enough "
                             "memory to decode it)", path=path)
        raise InputError("cannot decode image (corrupt or not an image)", path=path)
    return img, size


#: bit depths a 16-bit image file may hold (a 12-bit camera's 0-4095 in a 16-bit PNG)
DEPTHS = (8, 10, 12, 14, 16)
#: how many frames of a sequence, spread over it, :func:`frame_depth` looks at
DEPTH_FRAMES = 5
#: suffixes of files that hold 8-bit images only (no decode needed to know)
_EIGHT_BIT = frozenset({".jpg", ".jpeg", ".webp", ".bmp"})


def _png_bits(path) -> int | None:
    """The bit depth a PNG's header (IHDR) states; None for another format or a header cut short
    (the decoder then says what is wrong), or for what is not a regular file (a pipe would block)."""
    try:
        if not os.path.isfile(path):
            return None
        with open(path, "rb") as fh:
            head = fh.read(25)
    except (OSError, ValueError):       # (ValueError: a NUL byte in the name)
        return None
    return head[24] if len(head) == 25 and head[:8] == _PNG_SIGNATURE and head[12:16] == b"IHDR" else None


def frame_depth(paths) -> tuple[int, int] | None:
    """``(bits, largest value)`` of a sequence of 16-bit image files, from :data:`DEPTH_FRAMES` of
    its frames spread evenly from the first to the last: the one of :data:`DEPTHS` whose top bit
    their largest value uses (a 12-bit camera's 2048-4095 in a 16-bit PNG: 12), else 16; None for
    8-bit frames."""
    import cv2

    paths = list(paths)
    if not paths or Path(paths[0]).suffix.lower() in _EIGHT_BIT or _png_bits(paths[0]) in range(1, 9):
        return None     # (an 8-bit PNG's header says so: no frame decoded only to be told)
    top = -1
    for k in sorted(set(np.linspace(0, len(paths) - 1, DEPTH_FRAMES).round().astype(int).tolist())):
        img = read_image(paths[k], cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH)
        if img.dtype != np.uint16:
            return None
        top = max(top, int(img.max()))
    # a depth is read only from values that use its top bit: frames that are dark (a fade-in, a
    # lens cap) are 16-bit frames read as before, not a 6-bit camera whose other frames saturate
    bits = next((b for b in DEPTHS if 2 ** (b - 1) <= top < 2**b), 16)
    return bits, top


def depth_note(depth: tuple[int, int | None] | None) -> str:
    """What :func:`frame_depth`'s answer (or a depth given with ``--bits``: ``(bits, None)``) means
    for the frames (``""`` when they are read as OpenCV reads them: 8-bit, or 16-bit by their top 8
    bits)."""
    if depth is None or depth[0] >= 16:
        return ""
    bits, top = depth
    seen = f"with values up to {top} (in {DEPTH_FRAMES} spread over the sequence)" if top is not None else "(--bits)"
    return f"16-bit frames {seen}: read as {bits}-bit, {2**bits - 1} scaled to 255"


def read_frame(path: str | os.PathLike, bits: int | None = None) -> np.ndarray:
    """A frame as a BGR uint8 image: a 16-bit one of ``bits`` bits (:func:`frame_depth`, or as
    given, the same for every frame of a sequence) scaled from its ``2**bits - 1`` to 255 (a larger
    value is an :class:`InputError`: the depth was wrong); ``bits`` None or 16 reads it as OpenCV
    does (its top 8 bits)."""
    import cv2

    if bits is None or bits >= 16:
        return read_image(path)
    img = read_image(path, cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH)
    if img.dtype == np.uint8:
        return img
    if int(img.max()) >= 2**bits:
        raise InputError(f"values up to {int(img.max())}: more than the {bits} bits the frames are read at (the "
                         f"depth {DEPTH_FRAMES} frames spread over the sequence showed, or --bits): give their depth "
                         "with --bits (track, run and articulation video take it)", path=path)
    return cv2.convertScaleAbs(img, alpha=255.0 / (2**bits - 1))


#: how libjpeg and libpng report, on stderr only, damage they decoded around (a gray block, a
#: desynchronised scan): the decoder still returns an image
_DAMAGE = ("Corrupt JPEG data", "Premature end of JPEG file", "Invalid SOS parameters", "Inconsistent progression",
           "Huffman table", "Bogus", "libpng error")
#: their other messages (e.g. "libpng warning: iCCP: known incorrect sRGB profile"): not shown
_CODEC = _DAMAGE + ("libpng warning", "Warning:", "JPEG", "Unsupported")
#: FFmpeg's own log: its default callback writes ``[codec @ 0x55d0c0a8] message`` on stderr (after
#: colour codes when ``AV_LOG_FORCE_COLOR`` is set), maybe after another writer's unfinished line
_COLOUR = re.compile(r"\x1b\[[0-9;]*m")
_FFMPEG_LINE = re.compile(rf"(?:{_COLOUR.pattern})*\[([^\]@\s]+?) @ (?:0x)?[0-9a-fA-F]+\] ?")
#: FFmpeg's messages logged without a context, so without the ``[codec @ 0x..]`` prefix
_FFMPEG_BARE = re.compile(r"Truncating packet of size|error while decoding")
#: FFmpeg's messages while opening about the header's timing, which it replaces by a default: the
#: frames are sound, and the caller finds the frame rate unknown and says so (``_probe_video``)
_FFMPEG_TIMING = ("Invalid mdhd time scale 0, defaulting to 1",)
#: FFmpeg's audio decoders (it decodes a little of every stream while opening, to know them)
_AUDIO_CODEC = re.compile(r"(aac|ac3|eac3|mp[123]|opus|vorbis|flac|alac|pcm_|adpcm_|wma|amr|dca|dts|truehd|mlp|"
                          r"speex|gsm|cook|atrac|qdm|nellymoser|g72|qcelp|evrc|dvaudio|s302m|dolby_e|real_|sipr|"
                          r"wavpack|ape|tta|als|ilbc|mace|ra_|smackaud|binkaudio|interplay_|roq_dpcm|xan_dpcm)",
                          re.IGNORECASE)


def _opening_damage(said: list[str]) -> str | None:
    """What FFmpeg reported about the file's data while it opened (:func:`_ffmpeg_said`), if
    anything, leaving out what does not concern the frames: an audio stream's damage (artmotion
    reads no audio), and header timing it replaced by a default (:data:`_FFMPEG_TIMING`). A video
    decoder's report would be made again when the frame is read."""
    told = []
    for line in said:
        m = _FFMPEG_LINE.search(line)
        if _COLOUR.sub("", line).strip().endswith(_FFMPEG_TIMING) or (m is not None and _AUDIO_CODEC.match(m.group(1))):
            continue
        told.append(line)
    return _ffmpeg_said(told)[1]


def _ffmpeg_said(said: list[str]) -> tuple[dict[int, int], str | None]:
    """Which of the captured lines ``said`` hold FFmpeg's text, each with where it starts in the
    line (another writer's unfinished line may come first: a progress bar), and the first thing it
    said (``"codec: message"``; None when it said nothing). Its text starts with ``[codec @ 0x..]``
    (after its colour codes, with ``AV_LOG_FORCE_COLOR``; the code that ends the colour comes on a
    line of its own), except a few messages logged without a context (:data:`_FFMPEG_BARE`)."""
    mine: dict[int, int] = {}
    first = None
    for i, raw in enumerate(said):
        m = _FFMPEG_LINE.search(raw)
        at = m or _FFMPEG_BARE.search(raw)
        if at is None:
            if i - 1 in mine and "\x1b" in raw and not _COLOUR.sub("", raw).strip():
                mine[i] = 0
            continue
        mine[i] = at.start()
        text = _COLOUR.sub("", raw[at.end() if m is not None else at.start():]).strip()
        if text and first is None:
            first = text if m is None else f"{m.group(1)}: {text}"
    return mine, first


#: held while a decode points the file descriptor 2 at its scratch file: hold it to write to the
#: real stderr (the command line's one-line error, which a decoding thread would otherwise swallow)
stderr_lock = threading.Lock()
_capture = threading.local()


@contextlib.contextmanager
def _stderr_captured(native: tuple[str, ...]) -> Iterator[list[str]]:
    """Point the file descriptor 2 at a scratch file while the block runs (native code writes
    there, out of Python's reach); the yielded list then holds the lines written meanwhile. Lines
    that start with one of ``native``, and FFmpeg's (:func:`_ffmpeg_said`), are the libraries' and
    are kept off stderr; anything else (another thread's: a progress bar) is passed on as it was
    written. A capture inside another on the same thread reads what its own block wrote and leaves
    the passing on to the outer one."""
    said: list[str] = []
    if getattr(_capture, "depth", 0):
        fd = _capture.file.fileno()           # fd 2 shares its offset: what the block writes follows
        start = os.lseek(fd, 0, os.SEEK_CUR)
        _capture.depth += 1
        try:
            yield said
        finally:
            _capture.depth -= 1
            end = os.lseek(fd, 0, os.SEEK_CUR)
            said += os.pread(fd, max(end - start, 0), start).decode("utf-8", "replace").splitlines()
        return
    raw = ""
    try:
        with stderr_lock:
            scratch = getattr(_capture, "file", None)
            if scratch is None:
                import tempfile  # (only where a codec decodes: image folders never need it)

                scratch = _capture.file = tempfile.TemporaryFile()
            scratch.seek(0)
            scratch.truncate()
            try:
                sys.stderr.flush()
                saved = os.dup(2)
            except (OSError, ValueError, AttributeError):     # no stderr to redirect: run as is
                saved = None
            if saved is not None:
                os.dup2(scratch.fileno(), 2)
            _capture.depth = 1
            try:
                yield said
            finally:
                _capture.depth = 0
                if saved is not None:
                    os.dup2(saved, 2)
                    os.close(saved)
                scratch.seek(0)
                raw = scratch.read().decode("utf-8", "replace")
                said += raw.splitlines()
    finally:
        if raw:                                     # (nearly every decode writes nothing)
            pieces = raw.splitlines(keepends=True)  # (the same lines as ``said``, with their ends)
            ffmpeg = _ffmpeg_said(said)[0] if not os.environ.get("ARTMOTION_DEBUG") else {}
            other = "".join(piece if i not in ffmpeg else piece[:ffmpeg[i]] for i, piece in enumerate(pieces)
                            if not said[i].startswith(native))
            if other.strip():
                os.write(2, other.encode())


def ffmpeg_quiet():
    """A block whose FFmpeg messages (a video writer's opening and closing) are kept off stderr; a
    writer's failure is found by :func:`check_written_video`, not by reading them. It holds
    stderr for the block: keep the block to one call, never one that waits for another thread
    that reads frames (a :meth:`~artmotion.io.sequence.Sequence.frames` with its prefetching
    thread), which would wait for it in turn."""
    _ffmpeg_logs_on_stderr()
    return _stderr_captured(())


def _ffmpeg_logs_on_stderr() -> None:
    """Leave FFmpeg's log to its own default (its errors, on stderr), which :func:`read_video_frame`
    reads: with ``OPENCV_FFMPEG_LOGLEVEL`` or ``OPENCV_FFMPEG_DEBUG`` set, OpenCV prints it on
    stdout instead, where damage would pass unseen and the text would mix with a command's output.
    OpenCV reads them when it first starts FFmpeg; ``ARTMOTION_DEBUG`` keeps them."""
    if not os.environ.get("ARTMOTION_DEBUG"):
        os.environ.pop("OPENCV_FFMPEG_LOGLEVEL", None)
        os.environ.pop("OPENCV_FFMPEG_DEBUG", None)


def _decode(buf: np.ndarray, flags: int) -> tuple[np.ndarray | None, str | None]:
    """``cv2.imdecode`` and the first damage its codec reported meanwhile (``None`` if none).

    libjpeg warns about corrupt data it decodes around ("Corrupt JPEG data: 67 extraneous bytes
    before marker 0xd9") only on the process's stderr, and OpenCV returns the image: what the
    codec says while the image decodes is captured (:func:`_stderr_captured`) and read back."""
    import cv2

    # libtiff reports damaged strips ("Using code not yet in table") only through OpenCV's log,
    # which artmotion silences: for a TIFF, the log speaks while it decodes, into the capture
    tiff = bytes(buf[:4]) in _TIFF_MAGIC
    level = cv2.utils.logging.getLogLevel() if tiff else None     # (no log calls for every other frame)
    with _stderr_captured(_CODEC + (("[ERROR:",) if tiff else ())) as said:
        try:
            if tiff:
                cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
            img = cv2.imdecode(buf, flags)
        except cv2.error:                                  # beyond OpenCV's limits (pixels, size)
            img = None
        finally:
            if level is not None:
                cv2.utils.logging.setLogLevel(level)
    damage = (line.strip() for line in said if line.startswith(_DAMAGE) or (tiff and "TIFF_Error" in line))
    return img, next(damage, None)


#: what OpenCV's own AVI reader prints on a damaged file (with ``fprintf``, past its log level)
_CONTAINER = ("Unexpected element",)


def _video_captured():
    """:func:`_stderr_captured` for a call into a video reader: its container messages kept off
    stderr (all shown with ``ARTMOTION_DEBUG``)."""
    return _stderr_captured(() if os.environ.get("ARTMOTION_DEBUG") else _CONTAINER)


def cv2_name(path: str | os.PathLike) -> str:
    """``path`` as the string OpenCV is given to open or write: an :class:`InputError` naming it
    when it is not UTF-8 text (OpenCV crashes the process on a name with bytes that are not UTF-8,
    which Python reads as lone surrogates)."""
    check_text(path, "OpenCV cannot open it")
    return os.fspath(path)


def open_capture(path: str | os.PathLike):
    """``cv2.VideoCapture(path)``, its container parser's messages kept off stderr (a damaged AVI
    prints "Unexpected element. Expected: LIST. Got: JUNK."; the caller reports it as one error),
    reading the frames as stored (a rotation in the container's metadata is not applied:
    ``CAP_PROP_ORIENTATION_META`` says what it asks for). FFmpeg decodes on one thread, so that
    what it reports while a frame decodes belongs to that frame (:func:`read_video_frame`; with
    frame threads it reports a frame's damage during a later read, or after the last). Opening
    reads into the file: damage FFmpeg reports meanwhile (``[flv @ 0x..] Packet mismatch``) is an
    :class:`InputError` naming ``path``."""
    import cv2

    name = cv2_name(path)
    _ffmpeg_logs_on_stderr()
    with _video_captured() as said:
        cap = cv2.VideoCapture(name, cv2.CAP_FFMPEG, [cv2.CAP_PROP_N_THREADS, 1])
        ffmpeg = cap.isOpened()
        if not ffmpeg:                           # (a file FFmpeg cannot read: OpenCV's own readers)
            cap = cv2.VideoCapture(name)
    damage = _opening_damage(said) if ffmpeg else None
    if damage is not None:
        cap.release()
        raise InputError(f"damaged: FFmpeg found broken data while opening it ({damage})", path=path)
    cap.set(cv2.CAP_PROP_ORIENTATION_AUTO, 0)      # the frames as stored, as images (read_image)
    return cap


def read_video_frame(cap, path: str | os.PathLike, number: int) -> np.ndarray | None:
    """The next frame of ``cap`` (:func:`open_capture`), ``None`` at its end. FFmpeg conceals
    damaged data (a frame's broken macroblocks filled from their neighbours; a cut last frame
    partly decoded) and reports it only in its log (``[mpeg4 @ 0x..] illegal dc vlc``), which is
    captured while the frame decodes: damage is an :class:`InputError` naming ``path`` and frame
    ``number`` (counted from 1), not a frame with wrong pixels. A decoder that holds frames back
    (MPEG-1 in Matroska; B-frames) reports a packet's damage a frame or two before the frame it
    spoils comes out: the frame named is where the damage was found."""
    with _video_captured() as said:
        ok, img = cap.read()
    damage = _ffmpeg_said(said)[1]
    if damage is not None:
        where = (f"frame {number}" if ok else "its first frame, which does not decode" if number == 1
                 else f"the end, after frame {number - 1}")
        raise InputError(f"damaged data at {where}: FFmpeg decoded around it ({damage})", path=path)
    return img if ok else None


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
    head = read_head(path, 16)
    if not head:
        raise InputError("empty file", path=path)
    if head[:3] == b"\xff\xd8\xff" or head[:8] == _PNG_SIGNATURE:
        raise InputError("is an image, not a video", path=path)
    if head[:4] == b"RIFF" and head[8:12] not in (b"AVI ", b"AVIX"):
        raise InputError("not a video (a RIFF file that is not AVI)", path=path)
    check_riff_size(path, head)     # an AVI cut short: its frames there, its index
    mpeg_ts = head[:1] == b"\x47" and path.suffix.lower() in (".ts", ".mts", ".m2ts")
    if not mpeg_ts and not any(head[o:o + len(m)] == m for o, m in _VIDEO_MAGIC):
        kind = f" (extension {path.suffix})" if path.suffix else ""
        raise InputError(f"not a video{kind}: its content is no known video container", path=path)
    return path


def write_image(path: str | os.PathLike, img: np.ndarray, params: list[int] | None = None) -> Path:
    """Encode ``img`` in the format of ``path``'s extension and write it atomically."""
    import cv2

    from artmotion.io.atomic import atomic_write

    path = Path(path)
    ext = path.suffix or ".png"
    if not cv2.haveImageWriter("x" + ext):
        raise InputError(f"cannot write {ext} images (e.g. .png, .jpg)", path=path)
    try:
        ok, buf = cv2.imencode(ext, img, params or [])
    except cv2.error:       # (an image or parameters the encoder does not take)
        ok = False
    if not ok:
        got = f"a {img.dtype} array of shape {img.shape}" if isinstance(img, np.ndarray) else f"a {type(img).__name__}"
        raise InputError(f"cannot encode the image as {ext} ({got}; or its parameters)", path=path)
    with atomic_write(path, "wb") as fh:
        fh.write(buf.tobytes())
    return path


def check_written_video(path: str | os.PathLike, frames: int, where: str | os.PathLike | None = None) -> None:
    """Raise unless the video at ``path`` (just written) opens and holds ``frames`` frames: OpenCV's
    writer drops frames silently when the disk is full. ``where`` names it in the message."""
    import cv2

    try:
        cap = open_capture(path)
    except InputError as exc:
        raise InputError(f"the video written cannot be read back ({exc.reason}; disk full?)", path=where or path) from None
    try:
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) if cap.isOpened() else -1
    finally:
        cap.release()
    if count != frames:
        got = "cannot be read back" if count < 0 else f"holds {count} of its {frames} frames"
        raise InputError(f"the video written {got} (disk full?)", path=where or path)
