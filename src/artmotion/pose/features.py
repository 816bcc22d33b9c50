"""Visual features of a tool crop (Sec. 3.4.1, 3.6): HOG and LBP on a fixed-size resize.

* **HOG** — the 31-dimensional-per-cell variant of Felzenszwalb et al. (the one VLFeat's
  ``vl_hog`` computes and the thesis used): 18 contrast-sensitive + 9 contrast-insensitive
  orientation bins normalised by the four 2×2-cell blocks around each cell (clipped at 0.2),
  plus 4 texture-energy entries. On a 64×48 crop with 8-pixel cells: 8×6 cells × 31 = 1488.
  Implemented in vectorised NumPy over a whole batch.
* **LBP** — per-cell histograms of the 58 uniform 8-neighbour binary patterns
  (``skimage.feature.local_binary_pattern(..., method="nri_uniform")``, the non-uniform bin
  dropped as VLFeat does), each histogram L1-normalised and square-rooted. With 16-pixel cells on a
  64×48 crop: 4×3 cells × 58 = 696 (the thesis' dimension); ``cell`` is configurable.

* **cnn** — the pixels of the resized crop (BGR, [0, 1]); the fitted model turns them into a
  learned feature (:mod:`artmotion.pose.cnn`), as it turns HOG into its principal components.

``extract(images, kind)`` accepts a list (or any iterable) of BGR or grey crops of any size:
uint8 (0..255), uint16 (0..65535) or float intensities in [0, 1]; a grey crop may be
``(H, W)`` or ``(H, W, 1)``, a BGRA crop's alpha is dropped. Other integer types (int64, ...) and
float crops with values outside [0, 1] (0..255 as floats) are an :class:`InputError`: taken as
they are, they read as far too bright and move the angles.
``box_views(boxes, frame_size)`` describes where each crop was cut from its frame.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from functools import lru_cache

import cv2
import numpy as np

from artmotion.errors import InputError, check_range, float_array
from artmotion.io.mot import MAX_COORD

CROP_W, CROP_H = 64, 48  # the thesis' fixed size (width x height)
FEATURES = ("hog", "lbp", "cnn")
_EPS = 1e-4


def crop_list(images):
    """``images`` as :func:`extract` takes them: an array or a sequence (list, tuple) as it is,
    any other iterable of crops (a generator, a map) made a list once; anything else an
    :class:`InputError`."""
    if isinstance(images, np.ndarray):
        if images.ndim == 0:
            raise InputError(f"expected a list of crops (images) or a feature matrix, got one number {images!r}")
        return images
    if isinstance(images, (str, bytes, os.PathLike)) or not isinstance(images, Iterable):
        raise InputError(f"expected a list of crops (images) or a feature matrix, got {type(images).__name__} "
                         f"{images!r:.60}")
    return images if isinstance(images, Sequence) else list(images)


def resize_crop(image: np.ndarray, size: tuple[int, int] = (CROP_W, CROP_H), blur: float = 0.0,
                name: str = "a crop") -> np.ndarray:
    """Resize a crop (any size, grey or BGR) to ``size`` = (width, height), 3-channel float32 in [0, 1].

    The crop's intensities: uint8 0..255, uint16 0..65535, floats 0..1; any other type, or a float
    outside [0, 1], is an :class:`InputError` whose message begins with ``name``.
    ``blur`` > 0: Gaussian smoothing with that sigma (pixels of the resized crop) afterwards, which
    takes sensor noise out of the gradients before a feature sees them.
    """
    img = np.asarray(image)
    if img.ndim == 3 and img.shape[2] == 1:  # grey with a channel axis
        img = img[:, :, 0]
    if img.ndim == 2:
        img = img[:, :, None].repeat(3, axis=2)
    elif img.ndim == 3 and img.shape[2] == 4:
        img = img[:, :, :3]
    if img.ndim != 3 or img.shape[2] != 3 or img.shape[0] < 2 or img.shape[1] < 2:
        raise InputError(f"{name}: expected a grey or BGR image of at least 2x2 pixels, got shape {np.shape(image)}")
    if img.dtype == np.uint8:
        scale = 1.0 / 255.0
    elif img.dtype == np.uint16:
        scale = 1.0 / 65535.0
    elif img.dtype.kind == "f":  # intensities in [0, 1]
        lo, hi = float(img.min()), float(img.max())
        if not (lo >= 0.0 and hi <= 1.0):  # (NaN fails both)
            raise InputError(f"{name} holds float values outside [0, 1] (from {lo:g} to {hi:g}): float crops are "
                             f"intensities in [0, 1] (divide 0..255 values by 255, or give uint8 crops)")
        scale = 1.0
    else:
        raise InputError(f"{name} is {img.dtype}: give uint8 crops (0..255), uint16 (0..65535) or floats in "
                         f"[0, 1] (e.g. image.astype(np.uint8) for 0..255 values)")
    if img.dtype in (np.uint8, np.uint16, np.float32, np.float64):
        # halve big crops with the Gaussian pyramid first (anti-aliased, and much cheaper than one
        # area resize from the full size); stop while the crop is still at least the target size
        while img.shape[0] >= 2 * size[1] and img.shape[1] >= 2 * size[0]:
            img = cv2.pyrDown(np.ascontiguousarray(img))
    img = img.astype(np.float32) * np.float32(scale)  # final resample in float
    interp = cv2.INTER_AREA if img.shape[0] > size[1] else cv2.INTER_LINEAR
    img = cv2.resize(img, size, interpolation=interp)
    return cv2.GaussianBlur(img, (0, 0), blur) if blur > 0 else img


def crop_box(frame: np.ndarray, box) -> np.ndarray:
    """Crop ``box = (x, y, w, h)`` (pixels, top-left) from a frame, clipped to the image; a box that
    is not 4 finite numbers is an :class:`InputError` (NaN cropped the whole width)."""
    b = float_array(box, "box")
    if b.shape != (4,) or not np.isfinite(b).all():
        raise InputError(f"box must be 4 finite numbers x, y, w, h, got {box!r}")
    x, y, w, h = (float(v) for v in b)
    H, W = frame.shape[:2]
    x0, y0 = int(max(0, np.floor(x))), int(max(0, np.floor(y)))
    x1, y1 = int(min(W, np.ceil(x + w))), int(min(H, np.ceil(y + h)))
    if x1 - x0 < 2 or y1 - y0 < 2:
        raise InputError(f"box {tuple(box)} is empty inside a {W}x{H} image")
    return frame[y0:y1, x0:x1]


# ----------------------------------------------------------------------------------------- HOG
@lru_cache(maxsize=8)
def _cell_base(B: int, cy: int, cx: int, cell: int) -> np.ndarray:
    """Index of each pixel's cell histogram in the flat ``(B, cy, cx, 18)`` array (times 18)."""
    cell_idx = (np.arange(cy * cell) // cell)[:, None] * cx + (np.arange(cx * cell) // cell)[None, :]
    base = (np.arange(B)[:, None, None] * (cy * cx) + cell_idx[None]) * 18
    base.setflags(write=False)
    return base


def _check_batch(batch, cell, name: str) -> int:
    """``batch`` a ``(B, H, W, 3)`` array of floats in [0, 1] (:func:`resize_crop`'s crops) and
    ``cell`` a whole number of pixels from 2 to the crops' shorter side; else an
    :class:`InputError` (uint8 crops wrapped around in the gradients, 0-255 floats saturated the
    LBP codes, a cell of 0 divided by zero). Returns the cell as an int."""
    if not (isinstance(batch, np.ndarray) and batch.dtype.kind == "f" and batch.ndim == 4 and batch.shape[3] == 3
            and batch.shape[0] and batch.size):
        got = f"{batch.dtype} array of shape {batch.shape}" if isinstance(batch, np.ndarray) else type(batch).__name__
        raise InputError(f"{name}: crops must be a float array (B, H, W, 3) of values in [0, 1], got a {got}")
    if not (batch.min() >= 0.0 and batch.max() <= 1.0):        # (NaN fails both)
        raise InputError(f"{name}: crops must hold values in [0, 1] (resize_crop's), not 0-255 or NaN")
    return check_range("cell", cell, 2, min(batch.shape[1], batch.shape[2]), integer=True)


def hog_batch(batch: np.ndarray, cell: int = 8) -> np.ndarray:
    """UoCTTI HOG of a batch ``(B, H, W, 3)`` float32 → ``(B, (H//cell)*(W//cell)*31)``."""
    cell = _check_batch(batch, cell, "hog_batch")
    B, H, W, _ = batch.shape
    cy, cx = H // cell, W // cell
    img = batch[:, : cy * cell, : cx * cell, :]
    # centred gradients (one-sided at the border), strongest colour channel per pixel
    gx = np.empty_like(img)
    gy = np.empty_like(img)
    gx[:, :, 1:-1] = img[:, :, 2:] - img[:, :, :-2]
    gx[:, :, 0] = 2 * (img[:, :, 1] - img[:, :, 0])
    gx[:, :, -1] = 2 * (img[:, :, -1] - img[:, :, -2])
    gy[:, 1:-1] = img[:, 2:] - img[:, :-2]
    gy[:, 0] = 2 * (img[:, 1] - img[:, 0])
    gy[:, -1] = 2 * (img[:, -1] - img[:, -2])
    mag2 = gx * gx + gy * gy
    # strongest colour channel per pixel (ties go to the first, as argmax)
    m0, m1, m2 = mag2[..., 0], mag2[..., 1], mag2[..., 2]
    use1 = m1 > m0
    best01 = np.where(use1, m1, m0)
    use2 = m2 > best01
    gx = np.where(use2, gx[..., 2], np.where(use1, gx[..., 1], gx[..., 0]))
    gy = np.where(use2, gy[..., 2], np.where(use1, gy[..., 1], gy[..., 0]))
    mag = np.sqrt(np.where(use2, m2, best01))
    # 18 contrast-sensitive orientation bins with linear interpolation between the two nearest
    pos = np.arctan2(gy, gx) * np.float32(18 / (2 * np.pi))  # (-9, 9]
    pos += np.where(pos < 0, np.float32(18), np.float32(0))  # [0, 18]
    fl = np.floor(pos)
    w1 = pos - fl
    b0 = fl.astype(np.int64)
    b0[b0 >= 18] -= 18
    b1 = b0 + 1
    b1[b1 == 18] = 0
    hist = np.zeros((B, cy, cx, 18), dtype=np.float32)
    base = _cell_base(B, cy, cx, cell)
    flat = hist.reshape(-1)
    flat += np.bincount((base + b0).ravel(), weights=(mag * (1 - w1)).ravel(), minlength=flat.size)[: flat.size]
    flat += np.bincount((base + b1).ravel(), weights=(mag * w1).ravel(), minlength=flat.size)[: flat.size]
    hist = flat.reshape(B, cy, cx, 18)
    insens = hist[..., :9] + hist[..., 9:]
    energy = (insens * insens).sum(-1)  # (B, cy, cx)
    pad = np.concatenate([energy[:, :1], energy, energy[:, -1:]], axis=1)  # edge padding
    pad = np.concatenate([pad[:, :, :1], pad, pad[:, :, -1:]], axis=2)
    # block energies: block (i, j) covers cells (i..i+1, j..j+1) of the padded grid
    blk = pad[:, :-1, :-1] + pad[:, 1:, :-1] + pad[:, :-1, 1:] + pad[:, 1:, 1:]  # (B, cy+1, cx+1)
    norms = [
        1.0 / np.sqrt(blk[:, dy : dy + cy, dx : dx + cx] + _EPS) for dy in (0, 1) for dx in (0, 1)
    ]
    feats = np.concatenate([hist, insens], axis=-1)  # (B, cy, cx, 27)
    out = np.zeros((B, cy, cx, 31), dtype=np.float32)
    for k, n in enumerate(norms):
        h = np.minimum(feats * n[..., None], 0.2)
        out[..., :27] += 0.5 * h
        out[..., 27 + k] = 0.2357 * h[..., :18].sum(-1)
    return out.reshape(B, -1)


# ----------------------------------------------------------------------------------------- LBP
_LBP_UNIFORM = 58


def lbp_batch(batch: np.ndarray, cell: int = 16) -> np.ndarray:
    """Per-cell uniform-LBP histograms of a batch ``(B, H, W, 3)`` → ``(B, cells*58)``."""
    from skimage.feature import local_binary_pattern

    cell = _check_batch(batch, cell, "lbp_batch")
    B, H, W, _ = batch.shape
    cy, cx = H // cell, W // cell
    out = np.empty((B, cy, cx, _LBP_UNIFORM), dtype=np.float32)
    grey = (batch[..., 0] * 0.114 + batch[..., 1] * 0.587 + batch[..., 2] * 0.299) * 255.0
    for b in range(B):
        # 'nri_uniform' codes 0..58; 58 is the non-uniform bin (dropped, as VLFeat does)
        codes = local_binary_pattern(np.clip(grey[b] + 0.5, 0, 255).astype(np.uint8), 8, 1, method="nri_uniform").astype(np.int64)
        codes = codes[: cy * cell, : cx * cell].reshape(cy, cell, cx, cell).transpose(0, 2, 1, 3).reshape(cy, cx, -1)
        idx = (np.arange(cy * cx).reshape(cy, cx, 1) * 59 + codes).ravel()
        h = np.bincount(idx, minlength=cy * cx * 59).reshape(cy, cx, 59)[..., :_LBP_UNIFORM].astype(np.float32)
        out[b] = np.sqrt(h / float(cell * cell))
    return out.reshape(B, -1)


def pixels_batch(batch: np.ndarray, cell: int = 0) -> np.ndarray:
    """The resized crops themselves, one row each (the ``cnn`` feature's input)."""
    return batch.reshape(len(batch), -1)


#: columns of :func:`box_views`
VIEW_DIM = 4


def box_views(boxes, frame_size) -> np.ndarray:
    """``(n, 4)`` where boxes ``(x, y, w, h)`` lie in a ``frame_size = (width, height)`` frame
    (one size for all boxes, or ``(n, 2)``, one per box):
    the box centre relative to the frame centre (x, y, in frame widths, times 4), the log aspect
    ``log(w / h)`` and the log height in frame widths.

    A crop resized to a fixed size forgets this, but it matters: through a pinhole camera the same
    3-D orientation looks different at the edge of the picture than at its centre (the viewing
    ray differs by up to ~16° in a 640-px endoscope frame), and the box's shape is part of the
    pose's appearance."""
    b = float_array(boxes, "boxes")
    size = float_array(frame_size, "frame_size")
    if b.shape[-1:] != (4,) or size.shape[-1:] != (2,):
        raise InputError(f"boxes must be (n, 4) x, y, w, h and frame_size (width, height) or (n, 2), got shapes "
                         f"{b.shape} and {size.shape}")
    b, size = b.reshape(-1, 4), size.reshape(-1, 2)
    if len(size) not in (1, len(b)):
        raise InputError(f"frame_size must be one size or one per box ({len(b)}), got {len(size)}")
    W, H = size[:, 0], size[:, 1]
    # (within MAX_COORD: 1e308 gave infinite views)
    if not np.all(np.isfinite(size)) or np.any(size < 1) or np.any(size > MAX_COORD):
        raise InputError(f"frame sizes must be from 1 to {MAX_COORD:g} pixels")
    if not np.all(np.isfinite(b)) or np.any(b[:, 2:] <= 0) or np.any(np.abs(b) > MAX_COORD):
        raise InputError(f"boxes need finite positions and positive widths and heights within {MAX_COORD:g} pixels")
    cx = (b[:, 0] + b[:, 2] / 2 - W / 2) / W
    cy = (b[:, 1] + b[:, 3] / 2 - H / 2) / W
    return np.stack([4 * cx, 4 * cy, np.log(b[:, 2] / b[:, 3]), np.log(b[:, 3] / W)], 1).astype(np.float32)


def feature_dim(kind: str, size: tuple[int, int] = (CROP_W, CROP_H), cell: int | None = None) -> int:
    if kind == "cnn":
        return size[0] * size[1] * 3
    cell = default_cell(kind) if cell is None else cell
    per = 31 if kind == "hog" else _LBP_UNIFORM
    return (size[0] // cell) * (size[1] // cell) * per


def default_cell(kind: str) -> int:
    return 8 if kind == "hog" else 16


def extract(
    images: Sequence[np.ndarray] | np.ndarray,
    kind: str = "hog",
    size: tuple[int, int] = (CROP_W, CROP_H),
    cell: int | None = None,
    chunk: int = 256,
    blur: float = 0.0,
    first: int = 0,
) -> np.ndarray:
    """Feature matrix ``(len(images), d)`` float32 of crops of any size (resized to ``size``,
    smoothed with a Gaussian of sigma ``blur`` pixels when ``blur`` > 0); ``images`` a list, an
    array or any iterable of crops (see the module's docstring for their types). A bad crop is an
    :class:`InputError` naming its index (counted from ``first``)."""
    if kind not in FEATURES:
        raise InputError(f"unknown feature {kind!r}; choose one of {', '.join(FEATURES)}")
    cell = default_cell(kind) if cell is None else int(cell)
    if kind != "cnn" and (cell < 2 or size[0] // cell < 1 or size[1] // cell < 1):
        raise InputError(f"cell size {cell} does not fit a {size[0]}x{size[1]} crop")
    images = crop_list(images)
    n = len(images)
    out = np.empty((n, feature_dim(kind, size, cell)), dtype=np.float32)
    fn = {"hog": hog_batch, "lbp": lbp_batch, "cnn": pixels_batch}[kind]

    def work(s):
        batch = np.stack([resize_crop(im, size, blur, name=f"crop {first + s + j}")
                          for j, im in enumerate(images[s : s + chunk])])
        out[s : s + len(batch)] = fn(batch, cell)

    starts = list(range(0, n, chunk))
    if len(starts) > 1:  # NumPy and OpenCV release the GIL: use two threads for big batches
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=2) as pool:
            list(pool.map(work, starts))
    else:
        for s in starts:
            work(s)
    return out
