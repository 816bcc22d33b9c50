"""Open an image sequence: a MOTChallenge folder, a video file, or a folder of images.

A MOTChallenge folder has ``seqinfo.ini`` and its frames either in ``img1/`` (``000001.jpg``...)
or as the single video file in the folder; ``det/det.txt`` and ``gt/gt.txt`` are picked up when
present. Every problem (missing, unreadable or out-of-order frames, a broken video, an empty
folder) is an :class:`~artmotion.errors.InputError` naming the file.
"""

from __future__ import annotations

import configparser
import os
import queue
import re
import threading
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

from artmotion.errors import InputError

IMAGE_EXTS = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp", ".ppm", ".pgm")
VIDEO_EXTS = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg", ".wmv")
DEFAULT_FPS = 25.0

__all__ = ["Sequence", "open_sequence", "IMAGE_EXTS", "VIDEO_EXTS"]


def _frame_number(path: Path) -> int | None:
    m = re.search(r"(\d+)(?!.*\d)", path.stem)
    return int(m.group(1)) if m else None


class Sequence:
    """A sequence of frames with its metadata.

    Attributes: ``name``, ``fps``, ``width``, ``height``, ``length`` (frame count), ``det_path``
    and ``gt_path`` (``None`` when absent), ``path`` (what was opened) and ``images`` (the image
    files, or ``None`` for a video).
    """

    def __init__(self, path: Path, name: str, fps: float, width: int, height: int, length: int,
                 images: list[Path] | None = None, video: Path | None = None,
                 det_path: Path | None = None, gt_path: Path | None = None):
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

    def __len__(self) -> int:
        return self.length

    def __repr__(self) -> str:
        return (f"Sequence({self.name!r}, {self.length} frames, {self.width}x{self.height}, "
                f"{self.fps:g} fps)")

    def frames(self, prefetch: int = 8) -> Iterator[tuple[int, np.ndarray]]:
        """Yield ``(frame_number, BGR uint8 image)`` with 1-based, consecutive frame numbers.

        A background thread decodes up to ``prefetch`` frames ahead (OpenCV releases the GIL
        while decoding), so decoding overlaps the caller's work; ``prefetch=0`` reads in line.
        """
        if prefetch <= 0:
            yield from self._read()
            return
        yield from _prefetched(self._read(), prefetch)

    def _read(self) -> Iterator[tuple[int, np.ndarray]]:
        if self.images is not None:
            for i, p in enumerate(self.images, start=1):
                img = cv2.imread(str(p), cv2.IMREAD_COLOR)
                if img is None:
                    raise InputError("cannot read image (missing or corrupt)", path=p)
                if img.shape[:2] != (self.height, self.width):
                    raise InputError(
                        f"image size {img.shape[1]}x{img.shape[0]} differs from the sequence's "
                        f"{self.width}x{self.height}", path=p)
                yield i, img
            return
        cap = cv2.VideoCapture(str(self.video))
        if not cap.isOpened():
            raise InputError("cannot open video", path=self.video)
        try:
            n = 0
            while True:
                ok, img = cap.read()
                if not ok or img is None:
                    break
                n += 1
                if img.ndim == 2:
                    img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
                yield n, img
            if n == 0:
                raise InputError("video has no decodable frames", path=self.video)
        finally:
            cap.release()


_DONE = object()


def _prefetched(items: Iterator, depth: int) -> Iterator:
    """Iterate ``items`` in a daemon thread, ``depth`` ahead; its exceptions re-raise here."""
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


def _probe_video(video: Path) -> tuple[float, int, int, int]:
    if not video.is_file():
        raise InputError("no such file", path=video)
    cap = cv2.VideoCapture(str(video))
    try:
        if not cap.isOpened():
            raise InputError("cannot open video (broken or unsupported)", path=video)
        ok, img = cap.read()
        if not ok or img is None:
            raise InputError("video has no decodable frames", path=video)
        fps = cap.get(cv2.CAP_PROP_FPS)
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
    finally:
        cap.release()
    if not np.isfinite(fps) or fps <= 0 or fps > 1000:
        fps = DEFAULT_FPS
    return float(fps), img.shape[1], img.shape[0], max(count, 1)


def _list_images(folder: Path, ext: str | None = None) -> list[Path]:
    exts = (ext.lower(),) if ext else IMAGE_EXTS
    files = [p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in exts]
    if not files:
        raise InputError("no images in folder" if not ext else f"no '{ext}' images in folder", path=folder)
    numbered = [(_frame_number(p), p) for p in files]
    if all(n is not None for n, _ in numbered):
        numbered.sort(key=lambda t: (t[0], t[1].name))
        nums = [n for n, _ in numbered]
        if len(set(nums)) != len(nums):
            dup = next(n for n in nums if nums.count(n) > 1)
            raise InputError(f"two images have frame number {dup}", path=folder)
        # frames must be consecutive: a hole means a missing frame
        start = nums[0]
        for k, (n, p) in enumerate(numbered):
            if n != start + k:
                raise InputError(f"frames out of order: expected frame {start + k}, found {p.name}", path=p)
        return [p for _, p in numbered]
    return sorted(files, key=lambda p: p.name)


def _image_size(path: Path) -> tuple[int, int]:
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise InputError("cannot read image (missing or corrupt)", path=path)
    return img.shape[1], img.shape[0]


def _read_seqinfo(ini: Path) -> dict:
    cp = configparser.ConfigParser()
    try:
        cp.read_string(ini.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, configparser.Error) as exc:
        raise InputError(f"cannot parse seqinfo.ini: {exc}", path=ini) from None
    if not cp.has_section("Sequence"):
        raise InputError("missing [Sequence] section", path=ini)
    return dict(cp["Sequence"])


def _num(info: dict, key: str, ini: Path, kind=float):
    if key not in info:
        return None
    try:
        v = kind(float(info[key]))
    except ValueError:
        raise InputError(f"{key}={info[key]!r} is not a number", path=ini) from None
    if v <= 0:
        raise InputError(f"{key} must be positive, got {info[key]}", path=ini)
    return v


def _open_mot_folder(folder: Path) -> Sequence:
    ini = folder / "seqinfo.ini"
    info = _read_seqinfo(ini)
    name = info.get("name", folder.name)
    fps = _num(info, "framerate", ini) or DEFAULT_FPS
    det = folder / "det" / "det.txt"
    gt = folder / "gt" / "gt.txt"
    det = det if det.is_file() else None
    gt = gt if gt.is_file() else None
    img_dir = folder / info.get("imdir", "img1")
    if img_dir.is_dir():
        ext = info.get("imext")
        images = _list_images(img_dir, ext)
        length = _num(info, "seqlength", ini, int)
        if length is not None and length != len(images):
            raise InputError(f"seqinfo.ini says {length} frames but {img_dir.name}/ has {len(images)}",
                             path=img_dir)
        w, h = _image_size(images[0])
        return Sequence(folder, name, fps, w, h, len(images), images=images, det_path=det, gt_path=gt)
    videos = sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in VIDEO_EXTS)
    if not videos:
        raise InputError(f"no frames: neither {img_dir.name}/ nor a video file in the folder", path=folder)
    if len(videos) > 1:
        raise InputError(f"several video files in the folder ({', '.join(v.name for v in videos)})", path=folder)
    vfps, w, h, count = _probe_video(videos[0])
    length = _num(info, "seqlength", ini, int) or count
    return Sequence(folder, name, fps, w, h, length, video=videos[0], det_path=det, gt_path=gt)


def open_sequence(source: str | os.PathLike | Sequence) -> Sequence:
    """Open a MOTChallenge folder, a video file, or a folder of images (see the module doc)."""
    if isinstance(source, Sequence):
        return source
    path = Path(source)
    if not path.exists():
        raise InputError("no such file or folder", path=path)
    if path.is_dir():
        if (path / "seqinfo.ini").is_file():
            return _open_mot_folder(path)
        try:
            return _open_image_folder(path)
        except InputError:
            videos = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in VIDEO_EXTS)
            if len(videos) == 1:
                return _open_video(videos[0], name=path.name, folder=path)
            raise
    if path.suffix.lower() in IMAGE_EXTS:
        raise InputError("a single image is not a sequence; give its folder", path=path)
    return _open_video(path)


def _open_image_folder(folder: Path) -> Sequence:
    images = _list_images(folder)
    w, h = _image_size(images[0])
    parent = folder.parent
    det = parent / "det" / "det.txt"
    gt = parent / "gt" / "gt.txt"
    return Sequence(folder, folder.name if folder.name != "img1" else parent.name, DEFAULT_FPS, w, h,
                    len(images), images=images,
                    det_path=det if det.is_file() else None, gt_path=gt if gt.is_file() else None)


def _open_video(video: Path, name: str | None = None, folder: Path | None = None) -> Sequence:
    fps, w, h, count = _probe_video(video)
    base = folder or video.parent
    det = base / "det" / "det.txt"
    gt = base / "gt" / "gt.txt"
    return Sequence(video, name or video.stem, fps, w, h, count, video=video,
                    det_path=det if det.is_file() else None, gt_path=gt if gt.is_file() else None)
