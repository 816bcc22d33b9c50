"""Reading crops and angle labels; writing predictions (``image,<name>,<name>_std,...``)."""

from __future__ import annotations

import csv
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from artmotion.errors import InputError
from artmotion.io import atomic_write
from artmotion.io.media import IMAGE_EXTS, frame_depth, read_frame
from artmotion.io.sequence import hidden, natural_key
from artmotion.io.table import MAX_ANGLE, cell_number, read_csv


def list_images(folder: str | os.PathLike) -> list[Path]:
    """Image files of a folder in file-name order, numbers compared as numbers ("2.png" before
    "10.png"; one sequence); hidden files (a name starting with a dot: macOS's ``._*``) are left out."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError("not a folder of images", path=folder)
    files = sorted((p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_EXTS and not hidden(p)),
                   key=natural_key)
    if not files:
        raise InputError("no images in folder", path=folder)
    return files


def read_image(path: str | os.PathLike, bits: int | None = None) -> np.ndarray:
    """A crop, checked (:func:`artmotion.io.media.read_image`) and at least 2 x 2 pixels; 16-bit
    crops of ``bits`` bits scaled to 8 (:func:`~artmotion.io.media.read_frame`)."""
    img = read_frame(path, bits)
    if img.shape[0] < 2 or img.shape[1] < 2:
        raise InputError(f"image too small ({img.shape[1]}x{img.shape[0]})", path=path)
    return img


def read_images(paths: Sequence[Path], progress: bool = False) -> list[np.ndarray]:
    """The crops ``paths``, read as :func:`read_image` reads them; 16-bit crops at the bit depth
    that crops spread over them imply (:func:`~artmotion.io.media.frame_depth`), as `run` reads
    16-bit frames."""
    depth = frame_depth(paths)
    it = paths
    if progress:
        from tqdm import tqdm

        it = tqdm(paths, desc="read images", unit="img", leave=False, disable=None)
    return [read_image(p, depth[0] if depth else None) for p in it]


def read_labels(path: str | os.PathLike) -> tuple[list[str], list[str], np.ndarray]:
    """``(angle names, image names, Y)`` from a CSV ``image,<angle>,...`` (any number of angles),
    checked by :func:`artmotion.io.table.read_csv`; every angle a finite number of degrees."""
    header, rows = read_csv(path, what="labels CSV")
    if len(header) < 2 or header[0].lower() != "image":
        raise InputError("header must be 'image,<angle name>,...'", path=path, line=1)
    names = header[1:]
    images, values, seen = [], [], set()
    for lineno, row in rows:
        name = row[0]
        if not name:
            raise InputError("empty image name", path=path, line=lineno)
        if name in seen:
            raise InputError(f"duplicate image {name!r}", path=path, line=lineno)
        seen.add(name)
        images.append(name)
        values.append([cell_number(c, n, path, lineno, -MAX_ANGLE, MAX_ANGLE) for n, c in zip(names, row[1:])])
    if not images:
        raise InputError("no label rows", path=path)
    return names, images, np.array(values, dtype=float)


def _label_key(name: str) -> str:
    """A label's image name without its extension when it has an image file's (of any case): the
    name a crop's file is matched by when its full name has no label (as ``boxes.csv``'s rows)."""
    p = Path(name)
    return p.stem if p.suffix.lower() in IMAGE_EXTS else name


def load_labelled(images_dir: str | os.PathLike, labels: str | os.PathLike, progress: bool = False):
    """Crops and labels matched by file name; every image needs a label and every label an image.

    A label names its crop's file as it is (``000001.png``) or without the extension, which may
    also be of another case (``000001``, ``000001.PNG``), as ``boxes.csv`` does; one label matching
    two crops (``000001.png`` and ``000001.jpg``) is an error naming both.

    Returns ``(names, paths, images, Y)`` in file-name order.
    """
    files = list_images(images_dir)
    names, img_names, Y = read_labels(labels)
    out = prediction_header(names)
    twice = [c for i, c in enumerate(out) if c in out[:i]]
    if twice:  # e.g. columns 'yaw' and 'yaw_std': the predictions could not be read back
        raise InputError(f"column {twice[0]!r} would appear twice in the predictions' header "
                         "(image,<angle>,<angle>_std,...): rename a column", path=labels, line=1)
    index = {n: i for i, n in enumerate(img_names)}
    by_key: dict[str, list[int]] = {}
    for i, n in enumerate(img_names):
        by_key.setdefault(_label_key(n), []).append(i)
    row_of = {p: index[p.name] for p in files if p.name in index}  # exact names first
    owner = {i: p for p, i in row_of.items()}
    for p in files:
        if p in row_of:
            continue
        rows = by_key.get(p.stem, [])
        if len(rows) > 1:
            raise InputError(f"labels {img_names[rows[0]]!r} and {img_names[rows[1]]!r} both name image {p.name}",
                             path=labels)
        if not rows:
            raise InputError(f"image has no label in {labels}", path=p)
        if rows[0] in owner:
            raise InputError(f"label {img_names[rows[0]]!r} names two images: {owner[rows[0]].name} and {p.name} "
                             "(label each by its full file name)", path=labels)
        row_of[p], owner[rows[0]] = rows[0], p
    for i, n in enumerate(img_names):
        if i not in owner:
            raise InputError(f"labelled image {n!r} not found in {images_dir}", path=labels)
    order = [row_of[p] for p in files]
    return names, files, read_images(files, progress), Y[order]


def check_csv_names(paths: Sequence[Path]) -> None:
    """Refuse crops whose file names a predictions CSV would not give back as they are: the reader
    (:func:`read_labels`) strips spaces at the ends of a value and reads a carriage return as a line
    end, and the file is UTF-8 (commas, quotes and line feeds are quoted)."""
    for p in paths:
        n = p.name
        why = "a space at its start or end" if n != n.strip() else "a carriage return" if "\r" in n else ""
        try:
            n.encode("utf-8")
        except UnicodeEncodeError:
            why = "bytes that are not UTF-8"
        if why:
            raise InputError(f"the file name has {why}: a CSV file cannot hold it as it is; rename the file", path=p)


def prediction_header(names: Sequence[str]) -> list[str]:
    """The columns of :func:`write_predictions`' file."""
    return ["image", *(c for n in names for c in (n, f"{n}_std"))]


def write_predictions(path: str | os.PathLike, images: Sequence[str], names: Sequence[str], mean: np.ndarray,
                      std: np.ndarray) -> None:
    """``image,<name>,<name>_std,...`` (degrees), one row per image; a name with a comma, quote or
    line feed is quoted (:mod:`csv`), so :func:`read_labels` reads it back as it is."""
    with atomic_write(path) as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(prediction_header(names))
        for i, img in enumerate(images):
            w.writerow([img, *(f"{v:.4f}" for k in range(len(names)) for v in (mean[i, k], std[i, k]))])


BOX_COLUMNS = ["image", "x", "y", "w", "h", "frame_w", "frame_h"]
#: how far from its crop's corner a keypoint may lie, in crop widths / heights (a jaw tip may leave the box)
MAX_KEYPOINT = 100.0


def _per_image(path, rows, parse, images: Sequence[Path], what: str) -> list:
    """``parse(row, line)`` of the CSV ``rows`` matched to ``images`` by file name without extension
    (a crop ``000001.png`` and its frame ``000001.jpg``): every image needs a row, and a name may
    have one row only (``what`` it is, in messages)."""
    table = {}
    for lineno, row in rows:
        stem = Path(row[0]).stem
        if not stem:
            raise InputError("empty image name", path=path, line=lineno)
        if stem in table:
            raise InputError(f"a second {what} for image {row[0]!r}", path=path, line=lineno)
        table[stem] = parse(row, lineno)
    missing = [p.name for p in images if p.stem not in table]
    if missing:
        raise InputError(f"no {what} for image {missing[0]!r}" + (f" (and {len(missing) - 1} more)" if len(missing) > 1
                                                                    else ""), path=path)
    return [table[p.stem] for p in images]


def read_views(path: str | os.PathLike, images: Sequence[Path]) -> np.ndarray:
    """Where each crop was cut from its frame (:func:`artmotion.pose.features.box_views`), from a
    CSV ``image,x,y,w,h,frame_w,frame_h`` (``artmotion pose render`` writes one, ``boxes.csv``).
    Rows are matched to the crops by file name without extension (a crop ``000001.png`` and its
    frame ``000001.jpg``); every crop needs a row."""
    from artmotion.pose.features import box_views

    header, rows = read_csv(path, what="boxes CSV")
    if [h.lower() for h in header] != BOX_COLUMNS:
        raise InputError(f"header must be '{','.join(BOX_COLUMNS)}'", path=path, line=1)

    def box(row: list[str], lineno: int) -> tuple[tuple[float, ...], tuple[float, float]]:
        x, y = (cell_number(c, n, path, lineno, -1e6, 1e6) for n, c in zip(("x", "y"), row[1:3]))
        w, h, fw, fh = (cell_number(c, n, path, lineno, 1e-3, 1e6) for n, c in zip(BOX_COLUMNS[3:], row[3:7]))
        if x >= fw or y >= fh or x + w <= 0 or y + h <= 0:  # a crop is cut from inside its frame
            raise InputError(f"the box ({x:g}, {y:g}, {w:g}, {h:g}) lies outside its {fw:g}x{fh:g} frame",
                             path=path, line=lineno)
        if w > 2 * fw or h > 2 * fh:      # (one may run over the frame's edge, not be many frames wide)
            raise InputError(f"the box ({x:g}, {y:g}, {w:g}, {h:g}) is more than twice as large as its {fw:g}x{fh:g} "
                             "frame", path=path, line=lineno)
        return (x, y, w, h), (fw, fh)

    boxes = _per_image(path, rows, box, images, "box")
    return box_views([b for b, _ in boxes], [size for _, size in boxes])


def read_keypoints(path: str | os.PathLike, images: Sequence[Path],
                   sizes: Sequence[tuple[int, int]]) -> tuple[list[str], np.ndarray]:
    """``(point names, K)``: the tool's keypoints in each crop from a CSV ``image,<point>_x,<point>_y,...``
    in pixels of the crop (``artmotion pose render`` writes one, ``keypoints.csv``), as ``K``
    ``(n, 2m)`` fractions of each crop's width and height (``sizes``: ``(w, h)`` of ``images``),
    the form :meth:`artmotion.pose.model.PoseRegressor.fit` takes. Rows are matched to the crops by
    file name without extension; every crop needs a row. A point whose x and y are both empty is not
    known in that crop (hidden, or outside it): NaN."""
    header, rows = read_csv(path, what="keypoints CSV")
    pairs = header[1:]
    names = [c[:-2] for c in pairs[0::2]]
    if (len(header) < 3 or header[0].lower() != "image" or len(pairs) % 2
            or any(x != f"{n}_x" or y != f"{n}_y" for n, x, y in zip(names, pairs[0::2], pairs[1::2]))):
        raise InputError("header must be 'image,<point>_x,<point>_y,...' (one x, y pair per point)", path=path, line=1)

    def point_row(row: list[str], lineno: int) -> list[float]:
        values = []
        for n, x, y in zip(names, row[1::2], row[2::2]):
            if (x == "") != (y == ""):
                raise InputError(f"point {n!r} has an x or a y but not both (both empty: not known)", path=path,
                                 line=lineno)
            values += [np.nan, np.nan] if x == "" else [cell_number(c, f"{n}_{a}", path, lineno, -1e6, 1e6)
                                                       for a, c in (("x", x), ("y", y))]
        return values

    points = _per_image(path, rows, point_row, images, "row of keypoints")
    K = np.array(points, dtype=float).reshape(len(images), len(pairs))
    K /= np.tile(np.asarray(sizes, dtype=float), len(names))
    if np.isnan(K).all():   # (an empty file's header and image names: nothing to learn, said as learnt)
        raise InputError("no keypoint is known in any row (every x and y is empty)", path=path)
    far = np.flatnonzero(np.nanmax(np.abs(K), axis=1, initial=0.0) > MAX_KEYPOINT)
    if len(far):
        raise InputError(f"the keypoints of image {images[far[0]].name!r} lie more than {MAX_KEYPOINT:g} crop widths or "
                         "heights from the crop's corner (pixels of the crop, not of the frame?)", path=path)
    return names, K
