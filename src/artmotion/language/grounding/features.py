"""Visual and audio features of the grounding experiment (thesis 5.4).

Visual: the shape is segmented in HSV by its saturation (the table is grey-beige, the shapes are
saturated); colour is the segment's mean RGB (in [0, 1]); shape is the elliptic Fourier
descriptor (EFD) of its outer contour, 20 harmonics (80 numbers), normalised for position (the
constant term is dropped), scale (first harmonic of unit size), rotation and starting point.

Rotation/start normalisation: writing harmonic ``n`` as two counter-rotating phasors
``c(+n), c(-n)``, a rotation by ``phi`` and a shift of the starting point by ``tau`` multiply
``c(k)`` by ``exp(i(phi + k tau))``. We set the phase of ``c(+1)`` and of the largest other
phasor ``c(m)`` to zero; the ``|m-1|`` solutions differ by the shape's own symmetry, or are told
apart by the remaining phasors (the one maximising ``sum |c| (Re c + Im c)`` over them; a generic
direction, so that mirror-symmetric shapes, whose phasors are real or imaginary, are decided too).
Unlike rotating to the first harmonic's major axis alone, this stays defined when the first harmonic is a
circle (squares, triangles, hexagons).

Audio: MFCC (13 coefficients) of the 20 frames of highest energy, in time order, after trimming
silence; the frame hop is a fixed fraction of the utterance so that a word spoken fast or slow
gives the same number of frames (260 numbers).
"""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import pyefd

from artmotion.errors import InputError
from artmotion.io.files import check_riff_size, read_head
from artmotion.io.media import check_frame

HARMONICS = 20
N_MFCC = 13
N_TOP = 20
AUDIO_DIM = N_MFCC * N_TOP  # 260
SHAPE_DIM = 4 * HARMONICS  # 80
COLOR_DIM = 3


# ---------------------------------------------------------------------------------------------
# visual


def segment_shape(img_bgr: np.ndarray, *, min_area: float = 0.002, where: str | None = None) -> np.ndarray:
    """Mask (uint8 0/1) of the largest saturated region; :class:`InputError` if there is none."""
    hsv = cv2.cvtColor(img_bgr, cv2.COLOR_BGR2HSV)
    sat = cv2.medianBlur(hsv[:, :, 1], 5)
    otsu, _ = cv2.threshold(sat, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    thr = max(float(otsu), 90.0)
    mask: np.ndarray = (sat > thr).astype(np.uint8)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel)
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, kernel)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n <= 1:
        raise InputError("no shape found (no saturated region)", path=where)
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    if stats[k, cv2.CC_STAT_AREA] < min_area * mask.size:
        raise InputError("no shape found (saturated region too small)", path=where)
    return (labels == k).astype(np.uint8)


def outer_contour(mask: np.ndarray) -> np.ndarray:
    """The outer contour of a mask as ``(N, 2)`` float ``x, y`` points, at sub-pixel precision.

    The mask's holes are filled and its edge is smoothed (Gaussian, 1.5 px) before the 0.5 level
    line is traced, so that the staircase of pixel edges does not leak into high harmonics.
    """
    from skimage import measure

    m = mask.astype(np.uint8)
    contours, _ = cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    c = max(contours, key=cv2.contourArea)
    filled = np.zeros(m.shape, np.uint8)
    cv2.drawContours(filled, [c], -1, 1, thickness=cv2.FILLED)
    soft = cv2.GaussianBlur(np.pad(filled, 4).astype(np.float32), (0, 0), 1.5)
    levels = measure.find_contours(soft, 0.5)
    if not levels:
        return c[:, 0, :].astype(float)
    best = max(levels, key=len)
    return np.column_stack([best[:, 1] - 4, best[:, 0] - 4])


def _to_phasors(coeffs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a, b, c, d = coeffs.T
    return ((a + d) + 1j * (c - b)) / 2, ((a - d) + 1j * (c + b)) / 2


def _from_phasors(pos: np.ndarray, neg: np.ndarray) -> np.ndarray:
    A = pos + neg  # a + i c
    B = 1j * (pos - neg)  # b + i d
    return np.stack([A.real, B.real, A.imag, B.imag], axis=1)


def normalize_efd(coeffs: np.ndarray) -> np.ndarray:
    """Elliptic Fourier coefficients ``(n, 4)`` made invariant to scale, rotation and start point."""
    coeffs = np.asarray(coeffs, dtype=float)
    pos, neg = _to_phasors(coeffs)
    if abs(neg[0]) > abs(pos[0]):  # traverse counter-clockwise (in x-right, y-up terms)
        pos, neg = neg, pos
    s = abs(pos[0])
    if s < 1e-12:
        raise ValueError("degenerate contour")
    pos, neg = pos / s, neg / s
    n = len(pos)
    ks = np.concatenate([np.arange(1, n + 1), -np.arange(1, n + 1)])
    cs = np.concatenate([pos, neg])
    mags = np.abs(cs)
    th1 = np.angle(cs[0])
    others = np.argsort(-mags[1:]) + 1
    m_idx = others[0]
    m = ks[m_idx]
    if mags[m_idx] < 1e-3 or m == 1:
        cands = [(-th1, 0.0)]
    else:
        thm = np.angle(cs[m_idx])
        cands = []
        for j in range(abs(m - 1)):
            tau = (th1 - thm + 2 * np.pi * j) / (m - 1)
            cands.append((-th1 - tau, tau))
    best, best_score = None, -np.inf
    rest = np.ones(len(cs), bool)
    rest[[0, m_idx]] = False
    for phi, tau in cands:
        c2 = cs * np.exp(1j * (phi + ks * tau))
        score = float(np.sum(mags[rest] * (c2[rest].real + c2[rest].imag)))
        if score > best_score + 1e-9:
            best, best_score = c2, score
    assert best is not None  # ``cands`` is never empty (m != 1); only NaN scores would leave it unset
    return _from_phasors(best[:n], best[n:])


def shape_descriptor(contour: np.ndarray, harmonics: int = HARMONICS) -> np.ndarray:
    """Normalised EFD of a closed contour, ``(harmonics, 4)``."""
    contour = np.asarray(contour, dtype=float)
    if len(contour) < 8:
        raise ValueError("contour too short")
    # y grows downwards in images: flip so that rotations read as usual
    pts = np.column_stack([contour[:, 0], -contour[:, 1]])
    coeffs = pyefd.elliptic_fourier_descriptors(np.vstack([pts, pts[:1]]), order=harmonics, normalize=False)
    return normalize_efd(coeffs)


def color_feature(img_bgr: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Mean RGB of the masked pixels, in [0, 1]."""
    m = mask.astype(bool)
    bgr = img_bgr[m].reshape(-1, 3).mean(axis=0) / 255.0
    return bgr[::-1].copy()


def visual_features(img_bgr: np.ndarray, *, where: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(colour (3,), shape (80,))`` features of the image of one shape (a BGR uint8 image)."""
    check_frame(img_bgr, "image")      # (a grey or float image failed inside OpenCV)
    mask = segment_shape(img_bgr, where=where)
    try:
        shape = shape_descriptor(outer_contour(mask)).ravel()
    except ValueError as exc:
        raise InputError(f"no usable shape contour: {exc}", path=where) from None
    return color_feature(img_bgr, mask), shape


def render_shape(shape: np.ndarray, rgb: np.ndarray, size: int = 128, background=(235, 235, 235)) -> np.ndarray:
    """Image (RGB uint8) of the contour rebuilt from a shape descriptor, filled with ``rgb``."""
    coeffs = np.asarray(shape, dtype=float).reshape(-1, 4)
    pts = pyefd.reconstruct_contour(coeffs, locus=(0, 0), num_points=400)
    pts[:, 1] = -pts[:, 1]
    ext = np.abs(pts).max() + 1e-9
    pts = pts / ext * (0.42 * size) + size / 2
    img = np.empty((size, size, 3), np.uint8)
    img[:] = background
    col = tuple(int(v) for v in np.clip(np.asarray(rgb) * 255, 0, 255))
    cv2.fillPoly(img, [np.round(pts * 16).astype(np.int32)], col, lineType=cv2.LINE_AA, shift=4)
    return img


# ---------------------------------------------------------------------------------------------
# audio


#: the least sample rate of speech worth a feature (telephone speech: 8 kHz)
MIN_RATE = 8000


def read_wav(path: str | os.PathLike) -> tuple[np.ndarray, int]:
    """Mono float samples and rate; :class:`InputError` if missing, not audio, empty or silent."""
    import soundfile as sf

    path = Path(path)
    if not path.is_file():
        raise InputError("no such file", path=path)
    check_riff_size(path, read_head(path, 12))   # a cut WAV: libsndfile reads the samples left
    try:
        y, sr = sf.read(str(path), dtype="float32", always_2d=True)
    except Exception as exc:  # libsndfile's errors have no common base worth naming
        raise InputError(f"not a readable audio file ({type(exc).__name__})", path=path) from None
    if sr < MIN_RATE:
        raise InputError(f"sample rate {sr} Hz: speech needs at least {MIN_RATE} Hz", path=path)
    y = y.mean(axis=1)
    if y.size < 0.05 * sr:
        raise InputError("audio too short", path=path)
    if not np.all(np.isfinite(y)):
        raise InputError("audio has NaN samples", path=path)
    if float(np.max(np.abs(y))) < 1e-3:
        raise InputError("silent audio", path=path)
    return y, int(sr)


def audio_feature_from_samples(y: np.ndarray, sr: int, *, where: str | None = None) -> np.ndarray:
    """MFCC of the 20 highest-energy frames, time-ordered, flattened (260,)."""
    import librosa

    y = np.asarray(y, dtype=np.float32)
    y, _ = librosa.effects.trim(y, top_db=35)
    if y.size < 0.05 * sr:
        raise InputError("audio too short after trimming silence", path=where)
    n_target = 2 * N_TOP
    hop = max(32, int(len(y) // n_target))
    n_fft = 1024 if sr >= 16000 else 512
    if len(y) < n_fft:
        y = np.pad(y, (0, n_fft - len(y)))
    mfcc = librosa.feature.mfcc(y=y, sr=sr, n_mfcc=N_MFCC, n_fft=n_fft, hop_length=hop, center=True)
    rms = librosa.feature.rms(y=y, frame_length=n_fft, hop_length=hop, center=True)[0]
    n = min(mfcc.shape[1], rms.shape[0])
    mfcc, rms = mfcc[:, :n], rms[:n]
    if n < N_TOP:
        idx = np.sort(np.argsort(-rms)[:n])
        idx = np.concatenate([idx, np.full(N_TOP - n, idx[-1])])
    else:
        idx = np.sort(np.argsort(-rms, kind="stable")[:N_TOP])
    return mfcc[:, idx].T.ravel().astype(float)


def audio_feature(path: str | os.PathLike) -> np.ndarray:
    """260-d audio feature of a WAV file."""
    y, sr = read_wav(path)
    return audio_feature_from_samples(y, sr, where=str(path))
