"""Open an image sequence: a MOTChallenge folder, a video file, or a folder of images.

A MOTChallenge folder has ``seqinfo.ini`` and its frames either in ``img1/`` (``000001.jpg``...)
or as the single video file in the folder; ``det/det.txt`` and ``gt/gt.txt`` are picked up when
present. Every problem (missing, damaged or out-of-order frames, a video that ends before its
declared length, a file that is not a video, an empty folder, an implausible ``seqinfo.ini``) is
an :class:`~artmotion.errors.InputError` naming the file; images are checked by
:func:`artmotion.io.media.read_image` (a truncated JPEG is an error, not a gray frame).
"""

from __future__ import annotations

import configparser
import os
import queue
import re
import threading
from collections.abc import Generator, Iterator
from pathlib import Path

import cv2
import numpy as np

from artmotion.errors import InputError, check_range
from artmotion.io.files import as_path
from artmotion.io.media import (
    IMAGE_EXTS,
    MAX_FPS,
    MIN_FPS,
    VIDEO_EXTS,
    check_video,
    exif_orientation,
    frame_depth,
    open_capture,
    read_frame,
    read_image,
    read_image_sized,
    read_video_frame,
)
from artmotion.io.mot import MAX_FRAME

DEFAULT_FPS = 25.0
#: containers whose frame count is exact (an index of every frame): a video of this kind that
#: decodes fewer frames than it declares is damaged; others may declare an estimate
_EXACT_COUNT = frozenset({".mp4", ".m4v", ".mov", ".avi"})

__all__ = ["Sequence", "open_sequence", "IMAGE_EXTS", "VIDEO_EXTS", "hidden", "natural_key"]


def _frame_number(path: Path) -> int | None:
    m = re.search(r"(\d+)(?!.*\d)", path.stem)
    return int(m.group(1)) if m else None


def natural_key(path: str | os.PathLike) -> tuple:
    """Sort key of a file name in number order ("2.png" before "10.png"): its runs of digits
    compared as numbers, the rest as text."""
    parts = re.split(r"(\d+)", os.path.basename(path))
    return tuple((0, int(t), t) if t.isdigit() else (1, 0, t) for t in parts if t)


def hidden(path: Path) -> bool:
    """A file a folder listing leaves out: its name starts with a dot (macOS's ``._*`` metadata
    files beside every copied image, editors' and file managers' files)."""
    return path.name.startswith(".")


class Sequence:
    """A sequence of frames with its metadata.

    Attributes: ``name``, ``fps``, ``width``, ``height``, ``length`` (frame count), ``det_path``
    and ``gt_path`` (``None`` when absent), ``path`` (what was opened), ``images`` (the image
    files, or ``None`` for a video) and ``depth`` (16-bit image files: ``(bits, largest value)``
    of frames spread over the folder, :func:`~artmotion.io.media.frame_depth`, or ``(bits, None)``
    as given to :meth:`set_bits`; frames of fewer than 16 bits are
    read scaled from ``2**bits - 1`` to 255, :func:`~artmotion.io.media.depth_note` says so).
    """

    def __init__(self, path: Path, name: str, fps: float, width: int, height: int, length: int,
                 images: list[Path] | None = None, video: Path | None = None,
                 det_path: Path | None = None, gt_path: Path | None = None, orientation: str = "",
                 depth: tuple[int, int | None] | None = None):
        self.path = path
        self.name = name
        self.fps = float(fps)
        self.width = int(width)
        self.height = int(height)
        self.length = int(length)
        self.images = images
        self.video = video
        self.det_path = det_path
        self.gt_path = gt_path
        #: False when the frame rate was not in the input and DEFAULT_FPS is assumed
        self.fps_known = True
        #: whether ``length`` is exact for a video (seqinfo.ini, or a container with a frame index)
        self.length_exact = video is None or video.suffix.lower() in _EXACT_COUNT
        #: the seqinfo.ini that declares ``length`` for a video (then a longer video is an error)
        self.length_from: Path | None = None
        #: what the input's orientation tag asks a viewer to do with the frames (``""``: nothing),
        #: e.g. ``"turn 90°"``; artmotion reads them as stored (boxes are in stored pixels)
        self.orientation = orientation
        self.depth = depth

    def __len__(self) -> int:
        return self.length

    @property
    def bits(self) -> int | None:
        """The bits its 16-bit frames hold when fewer than 16 (they are read scaled from
        ``2**bits - 1`` to 255, :func:`~artmotion.io.media.read_frame`); None when its frames are
        read as OpenCV reads them (8-bit, or 16-bit by their top 8 bits)."""
        return self.depth[0] if self.depth is not None and self.depth[0] < 16 else None

    def set_bits(self, bits: int | None, name: str = "--bits") -> None:
        """Read its 16-bit frames as holding ``bits`` bits (8 to 16; fewer than 16: scaled from
        ``2**bits - 1`` to 255, 16: by their top 8 bits, as OpenCV reads them), whatever the frames
        spread over it showed (:attr:`depth`); ``None`` keeps that. Frames that are not 16-bit
        image files are an :class:`InputError`: the option would mean nothing there."""
        if bits is None:
            return
        bits = check_range(name, bits, 8, 16, integer=True)
        if self.depth is None:
            raise InputError(f"{name} is for 16-bit image files; these frames are 8-bit", path=self.path)
        self.depth = (int(bits), None)

    def set_fps(self, fps: float | None, name: str = "--fps") -> None:
        """Take ``fps`` (frames/s, within the range a frame rate may have) as the frame rate, the
        input's own or the assumed :data:`DEFAULT_FPS` notwithstanding; ``None`` keeps it."""
        if fps is not None:
            self.fps, self.fps_known = float(check_range(f"{name} (frames/s)", fps, MIN_FPS, MAX_FPS)), True

    #: the ``seqinfo.ini`` the sequence is described by (read, or looked for), or None
    ini_path: Path | None = None
    #: the folder whose single video is the sequence (a MOTChallenge folder or a folder of one
    #: video): a second video written into it would make it unreadable; None otherwise
    video_home: Path | None = None

    def inputs(self) -> tuple[Path | None, ...]:
        """The files and folders this sequence is read from (its video or folder of frames, its
        detections, ground truth and ``seqinfo.ini``): an output must not replace one of them."""
        return (self.video, self.folder, self.det_path, self.gt_path, self.ini_path)

    @property
    def folder(self) -> Path | None:
        """The folder the frames are read from (``None`` for a video): outputs stay out of it."""
        return self.images[0].parent if self.images else None

    def __repr__(self) -> str:
        return (f"Sequence({self.name!r}, {self.length} frames, {self.width}x{self.height}, "
                f"{self.fps:g} fps)")

    def frames(self, prefetch: int = 8, reduce: int = 1) -> Generator[tuple[int, np.ndarray], None, None]:
        """Yield ``(frame_number, BGR uint8 image)`` with 1-based, consecutive frame numbers.

        A background thread decodes up to ``prefetch`` frames ahead (OpenCV releases the GIL
        while decoding), so decoding overlaps the caller's work; ``prefetch=0`` reads in line.
        ``reduce`` (1, 2, 4 or 8) yields images that many times smaller on each side (about
        ``ceil(size / reduce)``): JPEG frames are then decoded at that size directly (libjpeg's
        DCT scaling, several times cheaper), video frames are downscaled in the decoding thread.
        """
        if reduce not in _REDUCED:
            raise ValueError(f"reduce must be one of {sorted(_REDUCED)}, got {reduce!r}")
        if prefetch <= 0:
            yield from self._read(reduce)
            return
        yield from prefetched(self._read(reduce), prefetch)

    def _read(self, reduce: int = 1) -> Generator[tuple[int, np.ndarray], None, None]:
        want = (-(-self.height // reduce), -(-self.width // reduce))
        # a reduced decode rounds the size up (JPEG) or down: either is the sequence's size
        fits = ({self.height // reduce, want[0]}, {self.width // reduce, want[1]})
        if self.images is not None:
            bits = self.bits
            # OpenCV's reduced decoding reads 8 bits: frames of another depth are read whole, then reduced
            k, fit = (reduce, fits) if bits is None else (1, ({self.height}, {self.width}))
            for i, p in enumerate(self.images, start=1):
                # the header's size is checked where it states one (a reduced decode of 639x479 is 640x480's)
                img = (read_image_sized(p, _REDUCED[reduce], expect=(self.width, self.height))[0] if bits is None
                       else read_frame(p, bits))
                if img.shape[0] not in fit[0] or img.shape[1] not in fit[1]:
                    stated = f"about {img.shape[1] * k}x{img.shape[0] * k}" if k > 1 else f"{img.shape[1]}x{img.shape[0]}"
                    raise InputError(f"image size {stated} differs from the sequence's {self.width}x{self.height}", path=p)
                if k < reduce:
                    img = cv2.resize(img, (want[1], want[0]), interpolation=cv2.INTER_AREA)
                yield i, img
            return
        assert self.video is not None  # (a sequence is frames or a video)
        cap = open_capture(self.video)
        if not cap.isOpened():
            raise InputError("cannot open video", path=self.video)
        try:
            n = 0
            got = read_video_frame(cap, self.video, 1)
            while got is not None:
                img = got
                n += 1
                if img.ndim == 2:
                    img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
                if img.shape[:2] != (self.height, self.width) or img.shape[2] != 3 or img.dtype != np.uint8:
                    raise InputError(f"frame {n} is {img.shape[1]}x{img.shape[0]}, not the video's "
                                     f"{self.width}x{self.height} (damaged)", path=self.video)
                if reduce > 1:
                    img = cv2.resize(img, (want[1], want[0]), interpolation=cv2.INTER_AREA)
                yield n, img
                got = read_video_frame(cap, self.video, n + 1)
                if n == self.length and self.length_exact and got is not None:
                    if self.length_from is not None:
                        assert self.video is not None  # the capture was opened from it
                        raise InputError(f"seqinfo.ini says {self.length} frames but {self.video.name} has more",
                                         path=self.length_from)
                    # the container's header counts fewer frames than it holds (a recorder stopped
                    # before it wrote the count): every frame that decodes is read, and the length
                    # is the count of them once read
                    self.length_exact = False
            if n > self.length:
                self.length = n
            if n == 0:
                raise InputError("video has no decodable frames", path=self.video)
            short = self.length - n if self.length_exact else self.length - n - max(2, self.length // 50)
            if short > 0:
                raise InputError(f"video ends after {n} of its {self.length} frames: frame {n + 1} cannot be "
                                 "decoded (truncated or damaged)", path=self.video)
        finally:
            cap.release()


#: imread flags that decode an image ``k`` times smaller on each side
_REDUCED = {1: cv2.IMREAD_COLOR, 2: cv2.IMREAD_REDUCED_COLOR_2, 4: cv2.IMREAD_REDUCED_COLOR_4,
            8: cv2.IMREAD_REDUCED_COLOR_8}


_DONE = object()


def prefetched(items: Iterator, depth: int) -> Iterator:
    """Iterate ``items`` in a daemon thread, ``depth`` ahead; its exceptions re-raise here. The
    items are made in their own order by one thread, so a random generator they draw from is
    drawn in the same order as without the thread."""
    q: queue.Queue = queue.Queue(maxsize=depth)
    stop = threading.Event()

    def put(x) -> bool:
        while not stop.is_set():
            try:
                q.put(x, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def work() -> None:
        try:
            for x in items:
                if not put((x, None)):
                    return
            put((_DONE, None))
        except BaseException as exc:  # handed to the consumer
            put((_DONE, exc))
        finally:
            close = getattr(items, "close", None)
            if close is not None:
                close()               # the reader's own clean-up (release the video) in this thread

    thread = threading.Thread(target=work, name="artmotion-frames", daemon=True)
    thread.start()
    try:
        while True:
            x, exc = q.get()
            if x is _DONE:
                if exc is not None:
                    raise exc
                return
            yield x
    finally:
        stop.set()
        thread.join(timeout=5)


def _probe_video(video: Path) -> tuple[float | None, int, int, int, str]:
    """Frame rate (``None`` if the file does not say), width, height and frame count of a video (as
    stored), and what the rotation in its metadata asks a viewer to do (``""``: nothing)."""
    check_video(video)
    cap = open_capture(video)
    try:
        if not cap.isOpened():
            raise InputError("cannot open video (broken or unsupported)", path=video)
        img = read_video_frame(cap, video, 1)
        if img is None:
            raise InputError("video has no decodable frames", path=video)
        fps = cap.get(cv2.CAP_PROP_FPS)
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
        turn = round(cap.get(cv2.CAP_PROP_ORIENTATION_META) or 0) % 360
    finally:
        cap.release()
    known = np.isfinite(fps) and MIN_FPS <= fps <= MAX_FPS and _avi_rate_stated(video) and _mp4_rate_stated(video)
    return (float(fps) if known else None), img.shape[1], img.shape[0], max(count, 1), f"turn {turn}°" if turn else ""


def _avi_rate_stated(video: Path) -> bool:
    """False for an AVI whose video stream header gives no frame rate (a rate or scale of 0, which
    FFmpeg reads as 25 frames/s without a word); True otherwise (other containers too)."""
    with open(video, "rb") as fh:
        head = fh.read(1 << 16)
    if head[:4] != b"RIFF" or head[8:12] != b"AVI ":
        return True
    # a stream header: "strh", its size, then fccType ("vids" for video), fccHandler, dwFlags,
    # wPriority and wLanguage (2 bytes each), dwInitialFrames, dwScale, dwRate
    at = head.find(b"strh")
    while at >= 0 and head[at + 8:at + 12] != b"vids":
        at = head.find(b"strh", at + 4)
    if at < 0 or at + 36 > len(head):
        return True
    scale, rate = (int.from_bytes(head[at + k:at + k + 4], "little") for k in (28, 32))
    return scale > 0 and rate > 0


def _mp4_rate_stated(video: Path) -> bool:
    """False for an MP4 / QuickTime file whose video track gives no frame rate: a media time scale
    of 0 or a sample of duration 0 in its time-to-sample table (FFmpeg then makes up a rate from what
    is left, e.g. 0.83 frames/s for a 25 frames/s clip); True otherwise (other containers too)."""

    def boxes(fh, start: int, end: int):
        """(type, offset of the body, end) of each box from start to end (ISO/IEC 14496-12 Sec. 4.2)."""
        at = start
        while at + 8 <= end:
            fh.seek(at)
            head = fh.read(16)
            if len(head) < 8:
                return
            size, kind = int.from_bytes(head[:4], "big"), head[4:8]
            body = at + 8
            if size == 1 and len(head) == 16:                  # a 64-bit size follows the type
                size, body = int.from_bytes(head[8:16], "big"), at + 16
            elif size == 0:                                    # the box runs to the end of the file
                size = end - at
            if size < body - at or at + size > end:
                return                                         # damaged: not this check's business
            yield kind, body, at + size
            at += size

    def inside(fh, parents: list[tuple[int, int]], *path: bytes) -> list[tuple[int, int]]:
        """(body, end) of the boxes along ``path`` (types) below ``parents``."""
        for kind in path:
            parents = [(b, e) for parent in parents for k, b, e in boxes(fh, *parent) if k == kind]
        return parents

    def read_at(fh, at: int, size: int) -> bytes:
        fh.seek(at)
        return fh.read(size)

    with open(video, "rb") as fh:
        end = fh.seek(0, os.SEEK_END)
        if read_at(fh, 4, 4) not in (b"ftyp", b"moov", b"mdat", b"wide", b"free", b"skip"):
            return True
        for mdia in inside(fh, [(0, end)], b"moov", b"trak", b"mdia"):
            # the video track: its handler (version/flags, pre_defined, then handler_type) says "vide"
            if not any(read_at(fh, b + 8, 4) == b"vide" for b, _ in inside(fh, [mdia], b"hdlr")):
                continue
            for b, _ in inside(fh, [mdia], b"mdhd"):      # version 1 has 64-bit times before the scale
                if int.from_bytes(read_at(fh, b + (20 if read_at(fh, b, 1) == b"\x01" else 12), 4), "big") == 0:
                    return False
            for b, e in inside(fh, [mdia], b"minf", b"stbl", b"stts"):   # entries: (count, duration)
                n = int.from_bytes(read_at(fh, b + 4, 4), "big")
                table = fh.read(8 * min(n, (e - b - 8) // 8))
                if any(table[k + 4:k + 8] == bytes(4) for k in range(0, len(table), 8)):
                    return False
    return True


def _list_images(folder: Path, ext: str | None = None) -> list[Path]:
    exts = {ext.lower()} if ext else IMAGE_EXTS
    files = [p for p in folder.iterdir() if p.suffix.lower() in exts and not hidden(p)]
    for p in files:     # a frame that is a folder, a pipe or a broken link is not skipped: it is a lost frame
        if not p.is_file():
            raise InputError("named as an image but not a file (a folder, a pipe or a broken link)", path=p)
    if not files:
        raise InputError("no images in folder" if not ext else f"no '{ext}' images in folder", path=folder)
    numbered = [(_frame_number(p), p) for p in files]
    if all(n is not None for n, _ in numbered):
        numbered.sort(key=lambda t: (t[0], t[1].name))
        nums = [n for n, _ in numbered if n is not None]  # all of them (the type checker cannot see it)
        if len(set(nums)) != len(nums):
            k = next(k for k in range(1, len(nums)) if nums[k] == nums[k - 1])
            raise InputError(f"two images have frame number {nums[k]}: {numbered[k - 1][1].name} and "
                             f"{numbered[k][1].name} (a frame's number is the last number in its name)", path=folder)
        # frames must be consecutive: a hole means a missing frame
        start = nums[0]
        for k, (n, p) in enumerate(numbered):
            if n != start + k:
                raise InputError(f"frame {start + k} is missing (after {numbered[k - 1][1].name} comes {p.name}; a "
                                 "frame's number is the last number in its name)", path=folder)
        return [p for _, p in numbered]
    bare = [p for n, p in numbered if n is None]
    if len(bare) < len(files):   # a stray image among numbered frames would hide a missing one
        raise InputError(f"{len(files) - len(bare)} images are numbered frames and {len(bare)} are not (e.g. "
                         f"{min(p.name for p in bare)}): a folder of frames has only frames", path=folder)
    return sorted(files, key=lambda p: p.name)


#: what an EXIF orientation (2-8) asks a viewer to do with the stored pixels
_EXIF_TURNS = {2: "mirror", 3: "turn 180°", 4: "flip", 5: "mirror and turn 270°", 6: "turn 90°",
               7: "mirror and turn 90°", 8: "turn 270°"}


def _image_size(path: Path) -> tuple[int, int, str]:
    """Width and height of the image as stored, and what its orientation tag asks for (``""``)."""
    img = read_image(path)
    return img.shape[1], img.shape[0], _EXIF_TURNS.get(exif_orientation(np.fromfile(path, np.uint8, 2**17)), "")


def _read_seqinfo(ini: Path) -> dict:
    if not ini.is_file():
        raise InputError("not a file (a folder, a pipe or a broken link)", path=ini)   # would be read forever
    cp = configparser.ConfigParser()
    try:
        cp.read_string(ini.read_text(encoding="utf-8-sig"))
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path=ini) from None
    except UnicodeDecodeError:
        raise InputError("not UTF-8 text", path=ini) from None
    except configparser.MissingSectionHeaderError as exc:
        raise InputError("no [Sequence] section header before the first setting", path=ini, line=exc.lineno) from None
    except configparser.ParsingError as exc:
        line = exc.errors[0][0] if exc.errors else None
        raise InputError("not a 'key=value' line", path=ini, line=line) from None
    except configparser.Error as exc:
        raise InputError(f"cannot parse: {exc.message.splitlines()[0]}", path=ini) from None
    if not cp.has_section("Sequence"):
        raise InputError("missing [Sequence] section", path=ini)
    return dict(cp["Sequence"])


#: plausible ranges of the numbers of seqinfo.ini
_RANGES = {"framerate": (MIN_FPS, MAX_FPS), "seqlength": (1, MAX_FRAME), "imwidth": (1, 100_000),
           "imheight": (1, 100_000)}


def _check_size(info: dict, ini: Path, w: int, h: int, frames: Path) -> None:
    """seqinfo.ini's ``imWidth`` and ``imHeight``, where given, are the frames' size (the ground
    truth's boxes are in those pixels)."""
    iw, ih = _num(info, "imwidth", ini, int), _num(info, "imheight", ini, int)
    if (iw is not None and iw != w) or (ih is not None and ih != h):
        raise InputError(f"seqinfo.ini says {iw or w}x{ih or h} pixels but the frames are {w}x{h}", path=frames)


def _num(info: dict, key: str, ini: Path, kind=float):
    """``info[key]`` as a number of ``kind`` in its plausible range, ``None`` when absent."""
    if key not in info:
        return None
    lo, hi = _RANGES[key]
    try:
        v = float(info[key])
    except ValueError:
        raise InputError(f"{key}={info[key]!r} is not a number", path=ini) from None
    if not np.isfinite(v) or not lo <= v <= hi:
        raise InputError(f"{key}={info[key]} is out of range [{lo:g}, {hi:g}]", path=ini)
    if kind is int and v != int(v):
        raise InputError(f"{key}={info[key]} is not a whole number", path=ini)
    return kind(v)


def _companion(path: Path) -> Path | None:
    """``det/det.txt`` or ``gt/gt.txt`` of a sequence: ``None`` when absent; an error when
    something is there that is not a readable file (a folder, a dangling link)."""
    if not path.exists() and not path.is_symlink():
        return None
    if not path.is_file():
        raise InputError("not a file", path=path)
    return path


def _open_mot_folder(folder: Path) -> Sequence:
    ini = folder / "seqinfo.ini"
    info = _read_seqinfo(ini)
    name = info.get("name", folder.name)
    fps = _num(info, "framerate", ini)
    known = fps is not None
    fps = fps or DEFAULT_FPS
    det = _companion(folder / "det" / "det.txt")
    gt = _companion(folder / "gt" / "gt.txt")
    img_dir = folder / info.get("imdir", "img1")
    if img_dir.is_dir():
        ext = info.get("imext")
        images = _list_images(img_dir, ext)
        length = _num(info, "seqlength", ini, int)
        if length is not None and length != len(images):
            raise InputError(f"seqinfo.ini says {length} frames but {img_dir.name}/ has {len(images)}",
                             path=img_dir)
        w, h, turn = _image_size(images[0])
        _check_size(info, ini, w, h, images[0])
        seq = Sequence(folder, name, fps, w, h, len(images), images=images, det_path=det, gt_path=gt,
                       orientation=turn, depth=frame_depth(images))
        seq.fps_known = known
        seq.ini_path = folder / "seqinfo.ini"
        return seq
    videos = sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in VIDEO_EXTS)
    if not videos:
        raise InputError(f"no frames: neither {img_dir.name}/ nor a video file in the folder", path=folder)
    if len(videos) > 1:
        raise InputError(f"several video files in the folder ({', '.join(v.name for v in videos)})", path=folder)
    vfps, w, h, count, turn = _probe_video(videos[0])
    _check_size(info, ini, w, h, videos[0])
    length = _num(info, "seqlength", ini, int)
    exact = videos[0].suffix.lower() in _EXACT_COUNT
    if length is not None and exact and length != count:
        raise InputError(f"seqinfo.ini says {length} frames but {videos[0].name} has {count}", path=ini)
    seq = Sequence(folder, name, fps if known else (vfps or DEFAULT_FPS), w, h, length or count, video=videos[0],
                   det_path=det, gt_path=gt, orientation=turn)
    seq.fps_known = known or vfps is not None
    seq.length_exact = exact or length is not None
    seq.length_from = ini if length is not None else None
    seq.ini_path, seq.video_home = folder / "seqinfo.ini", folder
    return seq


def open_sequence(source: str | os.PathLike | Sequence) -> Sequence:
    """Open a MOTChallenge folder, a video file, or a folder of images (see the module doc)."""
    if isinstance(source, Sequence):
        return source
    path = as_path(source, "a source (a video, a folder of frames or a MOTChallenge folder)")
    if not path.exists():
        raise InputError("no such file or folder", path=path)
    if path.is_dir():
        if os.path.lexists(path / "seqinfo.ini"):     # (a folder or a pipe of that name: an error, not ignored)
            return _open_mot_folder(path)
        # a folder of frames, or a folder holding one video and no image: a bad frame among images is
        # an error, not a reason to read a video that lies beside them instead
        videos = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in VIDEO_EXTS)
        if len(videos) == 1 and not any(p.suffix.lower() in IMAGE_EXTS for p in path.iterdir()):
            return _open_video(videos[0], name=path.name, folder=path)
        if (path / "img1").is_dir() and not any(p.suffix.lower() in IMAGE_EXTS for p in path.iterdir()):
            # a MOTChallenge folder without seqinfo.ini (2DMOT2015's first release): its frames, det/ and gt/
            return _open_image_folder(path / "img1")
        return _open_image_folder(path)
    if path.suffix.lower() in IMAGE_EXTS:
        raise InputError("a single image is not a sequence; give its folder", path=path)
    if path.suffix.lower() not in VIDEO_EXTS:
        kinds = ", ".join(sorted(VIDEO_EXTS))
        raise InputError(f"not a video file name (extension {path.suffix or 'none'}; videos are {kinds}), "
                         "an image folder or a MOTChallenge folder", path=path)
    return _open_video(path)


def _open_image_folder(folder: Path) -> Sequence:
    images = _list_images(folder)
    w, h, turn = _image_size(images[0])
    parent = folder.parent
    det = _companion(parent / "det" / "det.txt")
    gt = _companion(parent / "gt" / "gt.txt")
    # the img1/ folder of a MOTChallenge sequence: its frame rate is in the parent's seqinfo.ini
    ini = parent / "seqinfo.ini"
    fps = _num(_read_seqinfo(ini), "framerate", ini) if ini.is_file() else None
    name = folder.name if folder.name != "img1" else parent.resolve().name or folder.name
    seq = Sequence(folder, name, fps or DEFAULT_FPS, w, h,
                   len(images), images=images, det_path=det, gt_path=gt, orientation=turn, depth=frame_depth(images))
    seq.fps_known = fps is not None
    seq.ini_path = ini
    return seq


def _open_video(video: Path, name: str | None = None, folder: Path | None = None) -> Sequence:
    fps, w, h, count, turn = _probe_video(video)
    base = folder or video.parent
    seq = Sequence(video, name or video.stem, fps or DEFAULT_FPS, w, h, count, video=video,
                   det_path=_companion(base / "det" / "det.txt"), gt_path=_companion(base / "gt" / "gt.txt"),
                   orientation=turn)
    seq.fps_known = fps is not None
    seq.video_home = folder
    return seq
