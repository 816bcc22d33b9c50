"""A detector of instrument heads learnt from annotated frames: ``artmotion tool train``.

``ToolDetector().fit(frames, heads)`` trains :class:`~artmotion.tracking.instruments.net.HeadNet`
(CPU, a few minutes for 400 frames on 2 cores) on frames and their annotated heads (``(k, 4)``:
x, y, size, angle); ``detect(frame)`` returns ``(k, 5)`` rows x, y, size, angle, score. Training
augments each frame with flips (the angle follows), a random similarity transform (scale ±15 %,
shift), brightness, contrast and blur, so that the camera's zoom and motion, smoke and exposure
changes of later frames look like training ones. ``save``/``load`` keep the weights and settings
in one file (a torch pickle of tensors and numbers only, read with ``weights_only``).
"""

from __future__ import annotations

import io
import math
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from artmotion.errors import InputError, check_range, check_seed, float_array, need_package
from artmotion.io.media import check_frame
from artmotion.io.mot import MAX_BOXES_PER_FRAME
from artmotion.params import Params

__all__ = ["ToolDetector", "check_frame_size", "finite_rows", "is_grey", "need_torch"]

_FORMAT = "artmotion-tool-detector-1"
_MAX_SIDE = 8192    # the largest frame side a model is trained on (8K video)
_MIN_SIDE = 32      # the smallest: 4 cells of the network's output (4 * net.STRIDE)
_MAX_HEADS = MAX_BOXES_PER_FRAME  # the most rows a frame of a predictions file may hold


def scale_to(trained: tuple[int, int], frame: tuple[int, int], tolerance: float = 0.05) -> float:
    """The factor that brings a ``frame`` (h, w) to the area of the ``trained`` frames (h, w), aspect
    kept; 1 within ``tolerance`` (a few pixels of another crop of the same video are no other scale)."""
    f = math.sqrt(trained[0] * trained[1] / (frame[0] * frame[1]))
    return 1.0 if abs(f - 1.0) <= tolerance else f


def finite_rows(values, width: int, what: str, columns: str) -> np.ndarray:
    """``values`` as a ``(k, width)`` array of finite numbers (a single row may be flat); else an
    :class:`InputError` naming ``what`` and its ``columns``."""
    A = float_array(values, f"{what} ({columns})")
    if A.size == 0:
        return A.reshape(0, width)
    if A.ndim not in (1, 2) or A.shape[-1] != width:
        raise InputError(f"{what} must be a (k, {width}) array ({columns}), got shape {A.shape}")
    if not np.isfinite(A).all():
        raise InputError(f"{what} hold NaN or infinite values")
    return A.reshape(-1, width)


def _check_heads(heads, i: int, shape: tuple[int, ...]) -> np.ndarray:
    """The annotated heads of training frame ``i`` (of ``shape``) as ``(k, 4)``: x, y, size, angle,
    finite, inside the frame (as ``artmotion tool train`` requires), of positive size."""
    H = finite_rows(heads, 4, f"the heads of frame {i}", "x, y, size, angle")
    if not len(H):
        return H
    h, w = shape[:2]
    out = ~((H[:, 0] >= 0) & (H[:, 0] < w) & (H[:, 1] >= 0) & (H[:, 1] < h))
    if out.any():
        x, y = H[out][0, :2]
        raise InputError(f"frame {i}: a head at ({x:g}, {y:g}) lies outside the {w}x{h} frame")
    if (H[:, 2] <= 0).any():
        raise InputError(f"frame {i}: a head's size must be positive, got {H[H[:, 2] <= 0][0, 2]:g}")
    return H


def check_frame_size(h: int, w: int, path=None, training: bool = True) -> None:
    """An :class:`InputError` (naming ``path``, the frames) unless frames of ``w`` x ``h`` can be
    trained on or searched: at least 32 pixels a side (4 cells of the network's output), and at
    most 8192 for ``training`` (frames to search are scaled to the training frames' area)."""
    if h < _MIN_SIDE or w < _MIN_SIDE:
        raise InputError(f"frames of {w}x{h} are too small (a detector is trained on and finds instruments in "
                         f"frames of at least {_MIN_SIDE}x{_MIN_SIDE} pixels)", path=path)
    if training and max(h, w) > _MAX_SIDE:
        raise InputError(f"frames of {w}x{h} are too large (at most {_MAX_SIDE} pixels a side)", path=path)


def is_grey(frame: np.ndarray, tolerance: int = 3) -> bool:
    """Whether a BGR frame shows no colour: its three channels differ by at most ``tolerance`` anywhere
    (a grey picture saved as colour, a JPEG's rounding)."""
    f = frame.astype(np.int16)
    return bool(np.abs(f[..., 0] - f[..., 1]).max() <= tolerance and np.abs(f[..., 1] - f[..., 2]).max() <= tolerance)


def need_torch() -> None:
    """An :class:`InputError` saying how to install PyTorch when it is missing (the ``tools`` extra)."""
    need_package("torch", "tools", "the tool commands")


class ToolDetector(Params):
    """Instrument heads from a frame. Parameters as in scikit-learn: set in ``__init__`` (``get_params``,
    ``set_params``, ``sklearn.base.clone``), fitted state with a trailing underscore.

    ``epochs``: passes over the training frames; ``batch``: frames per step; ``lr``: Adam's step;
    ``threshold``: least heat-map score of a detection; ``max_heads``: most heads reported per frame,
    None: twice the most heads of a training frame (``max_heads_``), room for more instruments than
    the training frames show while the weakest of a frame's many faint peaks (5-16 above 0.05 on
    held-out laparoscopic frames, docs/surgical.md) stay out (4 on the shared annotations, of 2
    heads at most: the former fixed cap); ``width``: the network's channels; ``seed``: augmentation
    and initial weights.

    ``left_out_``: after :meth:`detect_batch`, the score of the best peak the cap left out on each
    of its frames (0 where none), so that a caller can say when the cap dropped a likely head.
    ``grey_``: whether every training frame was grey (:func:`is_grey`; None for a model saved
    before it was kept), so that a caller can say when frames are unlike them. ``source_``: the
    file a loaded model came from (named when its output is not finite).
    """

    source_: Path | None = None

    def __init__(self, epochs: int = 30, batch: int = 8, lr: float = 3e-3, threshold: float = 0.05,
                 max_heads: int | None = None, width: int = 32, seed: int = 0):
        self.epochs = epochs
        self.batch = batch
        self.lr = lr
        self.threshold = threshold
        self.max_heads = max_heads
        self.width = width
        self.seed = seed

    # ------------------------------------------------------------------ training
    def fit(self, frames: Sequence[np.ndarray], heads: Sequence[np.ndarray],
            progress: Callable[[int, int, float], None] | None = None) -> ToolDetector:
        """Learn from ``frames`` (BGR uint8, one size) and their heads (``(k, 4)`` each, k may be 0).
        ``progress(epoch, epochs, loss)`` is called after each epoch."""
        from artmotion._torch import torch
        from artmotion.tracking.instruments import net

        check_range("epochs", self.epochs, 1, 10_000, integer=True)
        check_range("batch", self.batch, 1, 1024, integer=True)
        check_range("threshold", self.threshold, 0.0, 1.0, lo_open=True, hi_open=True)   # as load() requires
        if self.max_heads is not None:
            check_range("max_heads", self.max_heads, 1, _MAX_HEADS, integer=True)
        check_range("width", self.width, 1, 1024, integer=True)
        check_range("lr", self.lr, 0.0, 1.0, lo_open=True)
        check_seed(self.seed, "seed")
        if len(frames) == 0 or len(frames) != len(heads):
            raise InputError(f"need frames and their heads, got {len(frames)} frames and {len(heads)} head lists")
        for i, f in enumerate(frames):
            check_frame(f, f"training frame {i}")
        shape = frames[0].shape
        odd = next((i for i, f in enumerate(frames) if f.shape != shape), None)
        if odd is not None:
            raise InputError(f"training frame {odd} is {frames[odd].shape[1]}x{frames[odd].shape[0]}, training frame 0 "
                             f"{shape[1]}x{shape[0]}: a detector learns from frames of one size")
        heads = [_check_heads(H, i, shape) for i, H in enumerate(heads)]
        most = max(len(H) for H in heads)
        cap = min(2 * max(most, 1), _MAX_HEADS) if self.max_heads is None else self.max_heads
        if most > cap:
            i = next(i for i, H in enumerate(heads) if len(H) == most)
            raise InputError(f"training frame {i} has {most} heads, more than the {cap} a frame the detector reports "
                             "(max_heads)")
        h, w = shape[:2]
        assert _MIN_SIDE == 4 * net.STRIDE
        check_frame_size(h, w)
        torch.manual_seed(self.seed)
        rng = np.random.default_rng(self.seed)
        model = net.HeadNet(self.width)
        opt = torch.optim.Adam(model.parameters(), lr=self.lr, weight_decay=1e-4)
        steps = self.epochs * math.ceil(len(frames) / self.batch)
        sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=self.lr, total_steps=steps)
        model.train()
        t0 = time.perf_counter()
        for epoch in range(self.epochs):
            order = rng.permutation(len(frames))
            total = 0.0
            for s in range(0, len(order), self.batch):
                idx = order[s:s + self.batch]
                imgs, hs = zip(*(_augment(frames[i], heads[i], rng) for i in idx))
                opt.zero_grad()
                pred = model(net.to_tensor(list(imgs)))
                # the targets on the network's own grid: ceil(floor(side / 2) / 4) cells, not side // 8
                lo = net.loss(pred, net.targets(list(hs), (pred.shape[2], pred.shape[3])))
                lo.backward()
                opt.step()
                sched.step()
                total += float(lo.detach()) * len(idx)
            if progress is not None:
                progress(epoch + 1, self.epochs, total / len(frames))
        model.eval()
        self.model_ = model
        self.max_heads_ = cap
        self.frame_shape_ = (h, w)
        self.grey_: bool | None = all(is_grey(f) for f in frames)
        self.train_seconds_ = time.perf_counter() - t0
        return self

    # ------------------------------------------------------------------ inference
    def _check_fitted(self):
        if not hasattr(self, "model_"):
            raise InputError("the tool detector is not trained (fit it or load a model)")
        # (a fitted model's threshold may have been set since: set_params checks nothing, as scikit-learn's)
        check_range("threshold", self.threshold, 0.0, 1.0, lo_open=True, hi_open=True)

    def detect(self, frame: np.ndarray) -> np.ndarray:
        """Heads in one BGR frame: ``(k, 5)`` x, y, size, angle, score, best first."""
        return self.detect_batch([frame])[0]

    def detect_batch(self, frames: Sequence[np.ndarray]) -> list[np.ndarray]:
        """:meth:`detect` on several frames of one size at once.

        Frames of another size than the training frames are first scaled (aspect kept) to the
        training frames' area, so that instruments appear at the size the network learnt (a video
        of the same operation at 768x576 for a model trained at 384x288); positions and sizes are
        given back in the frame's own pixels."""
        import cv2

        from artmotion._torch import torch
        from artmotion.tracking.instruments import net

        self._check_fitted()
        if len(frames) == 0:
            return []
        for im in frames:
            check_frame(im)
        h, w = frames[0].shape[:2]
        check_frame_size(h, w, training=False)
        other = next((im.shape for im in frames if im.shape[:2] != (h, w)), None)
        if other is not None:
            raise InputError(f"the frames of one batch must be of one size, got {w}x{h} and {other[1]}x{other[0]}")
        f = scale_to(self.frame_shape_, (h, w))
        if f != 1.0:
            size = (max(2 * net.STRIDE, round(w * f)), max(2 * net.STRIDE, round(h * f)))
            frames = [cv2.resize(im, size, interpolation=cv2.INTER_AREA if f < 1 else cv2.INTER_LINEAR) for im in frames]
            fx, fy = size[0] / w, size[1] / h
        with torch.inference_mode():
            maps = self.model_(net.to_tensor(list(frames))).numpy()
        if not np.isfinite(maps).all():
            # finite weights can still overflow (weights scaled by 1e15): no head found would be
            # said as if nothing were in view
            raise InputError("damaged tool model: its output on these frames is not finite",
                             path=self.source_)
        peaks = [net.decode(m, self.threshold, self.max_heads_ + 1) for m in maps]
        self.left_out_ = np.array([d[self.max_heads_, 4] if len(d) > self.max_heads_ else 0.0 for d in peaks])
        out = [d[:self.max_heads_] for d in peaks]
        if f != 1.0:
            for d in out:
                d[:, 0] /= fx
                d[:, 1] /= fy
                d[:, 2] /= math.sqrt(fx * fy)
        return out

    # ------------------------------------------------------------------ files
    def save(self, path: str | os.PathLike) -> Path:
        """Write the model to ``path`` (atomically)."""
        from artmotion._torch import torch
        from artmotion.io.atomic import atomic_path

        self._check_fitted()
        state = {"format": _FORMAT, "width": self.width, "threshold": float(self.threshold), "max_heads": self.max_heads_,
                 "frame_shape": list(self.frame_shape_), "weights": self.model_.state_dict()}
        if getattr(self, "grey_", None) is not None:
            state["grey"] = bool(self.grey_)
        buf = io.BytesIO()      # torch.save on a full disk raises a RuntimeError of its own; a file's write an OSError
        torch.save(state, buf)
        with atomic_path(path) as tmp:
            tmp.write_bytes(buf.getbuffer())
        return Path(path)

    @classmethod
    def load(cls, path: str | os.PathLike) -> ToolDetector:
        """A detector saved by :meth:`save`; an :class:`InputError` naming the file otherwise."""
        from artmotion._torch import torch
        from artmotion.io.files import existing_file

        p = existing_file(path)
        need_torch()
        from artmotion.tracking.instruments import net

        try:
            state = torch.load(p, map_location="cpu", weights_only=True)
        except Exception as exc:  # a truncated or foreign file: torch's own errors vary
            raise InputError(f"not a tool model ({type(exc).__name__})", path=p) from None
        if not isinstance(state, dict) or state.get("format") != _FORMAT:
            raise InputError("not a tool model (train one with 'artmotion tool train')", path=p)
        try:
            det = cls(threshold=float(state["threshold"]), max_heads=int(state["max_heads"]), width=int(state["width"]))
            det.max_heads_ = int(state["max_heads"])
            model = net.HeadNet(det.width)
            model.load_state_dict(state["weights"])
            h, w = (int(v) for v in state["frame_shape"])
            det.frame_shape_ = (h, w)
            det.grey_ = state.get("grey")   # (absent in models saved before 2026-12: unknown)
            if det.grey_ is not None and not isinstance(det.grey_, bool):
                raise TypeError("grey")
        except (KeyError, TypeError, ValueError, RuntimeError) as exc:
            raise InputError(f"damaged tool model ({type(exc).__name__})", path=p) from None
        # what training writes: a score in (0, 1), a few heads, the size frames were scaled to
        if not (0.0 < det.threshold < 1.0 and 1 <= det.max_heads_ <= _MAX_HEADS
                and all(4 * net.STRIDE <= v <= _MAX_SIDE for v in det.frame_shape_)):
            raise InputError(f"damaged tool model (threshold {det.threshold}, max_heads {det.max_heads_}, "
                             f"frame_shape {det.frame_shape_})", path=p)
        if not all(bool(torch.isfinite(t).all()) for t in model.state_dict().values() if t.is_floating_point()):
            raise InputError("damaged tool model (NaN or infinite weights)", path=p)
        # a negative variance makes every output NaN: no head on any frame, said as if seen
        if any(bool((t < 0).any()) for k, t in model.state_dict().items() if k.endswith("running_var")):
            raise InputError("damaged tool model (a negative batch-normalisation variance)", path=p)
        model.eval()
        det.model_ = model
        det.source_ = p     # (named by detect's error should the network give what is not a number)
        return det


def _augment(img: np.ndarray, heads: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A random flip, similarity transform, brightness, contrast and blur of a frame; the heads
    (x, y, size, angle) follow."""
    import cv2

    h, w = img.shape[:2]
    H = heads.copy()
    s = float(rng.uniform(0.85, 1.15))
    tx, ty = rng.uniform(-0.1, 0.1) * w, rng.uniform(-0.1, 0.1) * h
    fx = -1.0 if rng.random() < 0.5 else 1.0
    fy = -1.0 if rng.random() < 0.5 else 1.0
    # x' = fx s (x - w/2) + w/2 + tx (and y likewise): flips about the centre, scale, shift
    A = np.array([[fx * s, 0.0, (1 - fx * s) * w / 2 + tx], [0.0, fy * s, (1 - fy * s) * h / 2 + ty]])
    out = cv2.warpAffine(img, A, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    if len(H):
        H[:, 0] = A[0, 0] * H[:, 0] + A[0, 2]
        H[:, 1] = A[1, 1] * H[:, 1] + A[1, 2]
        H[:, 2] *= s
        H[:, 3] = np.mod(np.arctan2(fy * np.sin(H[:, 3]), fx * np.cos(H[:, 3])), 2 * np.pi)
        inside = (H[:, 0] >= 0) & (H[:, 0] < w) & (H[:, 1] >= 0) & (H[:, 1] < h)
        H = H[inside]
    c = float(rng.uniform(0.7, 1.3))
    b = float(rng.uniform(-30, 30))
    out = cv2.convertScaleAbs(out, alpha=c, beta=b)
    if rng.random() < 0.25:
        out = cv2.GaussianBlur(out, (0, 0), float(rng.uniform(0.5, 1.5)))
    return out, H
