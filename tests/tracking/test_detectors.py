"""The built-in person detectors (artmotion.tracking.detectors): SSDLite through OpenCV's dnn
module on the shipped TUD-Campus sample, HOG, the anchors, and bad input."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.geometry import iou
from artmotion.io import read_mot
from artmotion.tracking import MultiObjectTracker, TrackerConfig, open_sequence, run_tracker, track
from artmotion.tracking.detectors import (
    Detector,
    HOGDetector,
    SSDLiteDetector,
    _ssd_anchors,
    make_detector,
    ssdlite_weights,
)

SAMPLE = Path(__file__).resolve().parents[2] / "data" / "TUD-Campus"


@pytest.fixture(scope="module")
def ssd():
    return SSDLiteDetector()


@pytest.fixture(scope="module")
def tud_frames():
    seq = open_sequence(SAMPLE)
    return seq, list(seq.frames())


def test_weights_are_installed_by_the_project():
    # `make install` puts the wheel in without its dependencies; the graph is found without
    # importing the package (which would import TensorFlow)
    path = ssdlite_weights()
    assert path is not None and path.stat().st_size > 1_000_000
    assert make_detector("auto").name == "ssdlite"


def test_anchor_layout_of_ssdlite_mobilenet_v2():
    shapes = [(19, 19), (10, 10), (5, 5), (3, 3), (2, 2), (1, 1)]
    a = _ssd_anchors(shapes)
    assert a.shape == (19 * 19 * 3 + (100 + 25 + 9 + 4 + 1) * 6, 4) == (1917, 4)
    # the first map: 3 anchors per cell, the first one of scale 0.1 at the first cell's centre
    np.testing.assert_allclose(a[0], [0.5 / 19, 0.5 / 19, 0.1, 0.1])
    np.testing.assert_allclose(a[1, 2:], [0.2 / np.sqrt(2), 0.2 * np.sqrt(2)])
    np.testing.assert_allclose(a[3, :2], [0.5 / 19, 1.5 / 19])            # row-major, anchors innermost
    # the last map's last anchor sits between the last scale and 1
    np.testing.assert_allclose(a[-1], [0.5, 0.5, np.sqrt(0.95), np.sqrt(0.95)])
    # a wider input keeps anchors at their size in pixels: smaller in [0, 1] across
    wide = _ssd_anchors(shapes, relative_size=(2.0, 1.0))
    np.testing.assert_allclose(wide[:, 3] * 2, a[:, 3])
    np.testing.assert_allclose(wide[:, 2], a[:, 2])


def test_ssdlite_finds_the_people_of_tud_campus(ssd, tud_frames):
    """Against the ground truth of frames 1, 30 and 60: most people found at IoU 0.5 with a
    confident score, and few confident boxes on nothing."""
    _, frames = tud_frames
    gt = read_mot(SAMPLE / "gt" / "gt.txt")
    found = total = wrong = confident = 0
    for n in (1, 30, 60):
        boxes, scores = ssd.detect(frames[n - 1][1])
        assert boxes.shape == (len(scores), 4) and np.all((scores > 0) & (scores <= 1))
        g = gt[(gt[:, 0] == n) & (gt[:, 6] != 0), 2:6]
        conf = boxes[scores >= 0.5]
        o = iou(conf[:, None, :], g[None, :, :]) if len(conf) else np.zeros((0, len(g)))
        total += len(g)
        found += int((o.max(axis=0) >= 0.5).sum()) if len(conf) else 0
        confident += len(conf)
        wrong += int((o.max(axis=1) < 0.3).sum()) if len(g) else len(conf)
    assert total >= 15
    assert found / total >= 0.6, (found, total)
    assert wrong / max(confident, 1) <= 0.2, (wrong, confident)


def test_nothing_confident_in_a_blank_frame(ssd):
    boxes, scores = ssd.detect(np.full((480, 640, 3), 128, np.uint8))
    assert not np.any(scores >= 0.5)


def test_detector_rows_are_what_the_tracker_takes(ssd, tud_frames):
    _, frames = tud_frames
    rows = ssd(frames[0][1])
    assert rows.ndim == 2 and rows.shape[1] == 5 and len(rows) > 0
    assert ssd(np.zeros((100, 100, 3), np.uint8)).shape[1] == 5


def test_tracking_with_the_detector_on_a_worker_thread_is_sequential_tracking(ssd, tud_frames):
    """run_tracker runs the detector one frame ahead on a thread: the tracks are exactly those
    of detecting every frame first."""
    seq, frames = tud_frames
    frames = frames[:20]
    dets = {n: ssd(img) for n, img in frames}

    def tracks(**kw):
        t = MultiObjectTracker(seq.fps, seq.width, seq.height, config=TrackerConfig())
        n = run_tracker(t, iter(frames), **kw)
        return t.finish(n)[0]

    a, b = tracks(detections=dets), tracks(detections={}, detector=ssd)
    assert len(a) > 20
    np.testing.assert_array_equal(a, b)


def test_track_without_detections_uses_ssdlite(tmp_path, tud_frames):
    _, frames = tud_frames
    folder = tmp_path / "imgs"
    folder.mkdir()
    for n, img in frames[:8]:
        cv2.imwrite(str(folder / f"{n:06d}.jpg"), img)
    res = track(folder, fps=25)
    assert res.detector == "ssdlite" and res.frames == 8 and res.num_tracks >= 3


def test_hog_detector_interface():
    img = np.full((240, 320, 3), 90, np.uint8)
    boxes, scores = HOGDetector().detect(img)
    assert boxes.shape == (len(scores), 4)


@pytest.mark.parametrize("frame", [np.zeros((50, 50), np.uint8), np.zeros((50, 50, 3), np.float32),
                                   np.zeros((4, 50, 3), np.uint8), "image.png"])
def test_bad_frames_are_refused(ssd, frame):
    with pytest.raises(InputError):
        ssd.detect(frame)


@pytest.mark.parametrize("params", [{"short_side": 10}, {"short_side": 300.5}, {"short_side": float("nan")},
                                    {"score_threshold": 1.5}, {"nms_iou": -0.1}])
def test_bad_parameters_are_refused(params):
    with pytest.raises(InputError):
        SSDLiteDetector(**params)


def test_bad_weights_are_one_error(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        SSDLiteDetector(weights=tmp_path / "missing.pb")
    junk = tmp_path / "junk.pb"
    junk.write_bytes(b"not a graph" * 100)
    with pytest.raises(InputError, match="junk.pb"):
        SSDLiteDetector(weights=junk)


def test_unknown_detector(run_cli, tmp_path):
    with pytest.raises(InputError, match="unknown detector"):
        make_detector("yolo")
    code, _, err = run_cli("track", str(SAMPLE / "TUD-Campus.mp4"), "--det", str(SAMPLE / "det" / "det.txt"),
                           "--detector", "yolo")
    # checked even when a detections file makes the detector unnecessary
    assert code == 2 and "unknown detector" in err
    (tmp_path / "v").mkdir()
    video = tmp_path / "v" / "clip.mp4"
    video.write_bytes((SAMPLE / "TUD-Campus.mp4").read_bytes())
    code, _, err = run_cli("track", str(video), "--detector", "yolo")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "unknown detector" in err


@pytest.mark.parametrize("k", ["0", "-1", "1.5", "101", "nan"])
@pytest.mark.parametrize("command", ["track", "run"])
def test_bad_detect_every(run_cli, tmp_path, command, k):
    out = ("--out", str(tmp_path / "run")) if command == "run" else ()
    code, _, err = run_cli(command, str(SAMPLE), *out, "--detect-every", k)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--detect-every" in err


def test_the_python_api_names_its_own_argument():
    """track() is called from Python: its error names ``detect_every``, not the CLI's option."""
    from artmotion.tracking import track

    with pytest.raises(InputError, match="^detect_every must"):
        track(SAMPLE, detect_every=0)


class _Truth(Detector):
    """TUD-Campus's ground truth as a detector: it knows each frame by its pixels."""

    name = "truth"

    def __init__(self, frames):
        self.frames = frames
        self.seen = []

    def detect(self, frame):
        n = next(k for k, img in self.frames if np.array_equal(img, frame))
        self.seen.append(n)
        gt = read_mot(SAMPLE / "gt" / "gt.txt")
        g = gt[(gt[:, 0] == n) & (gt[:, 6] != 0)]
        return g[:, 2:6], np.full(len(g), 0.9)


def _image_folder(path, frames):
    path.mkdir()
    for n, img in frames:
        cv2.imwrite(str(path / f"{n:06d}.png"), img)
    return path


def test_a_detector_of_your_own(tmp_path, tud_frames):
    """track() takes any Detector; it runs on every detect_every-th frame only, and on the last."""
    _, frames = tud_frames
    truth = _Truth(frames[:12])
    res = track(_image_folder(tmp_path / "imgs", frames[:12]), fps=25, detector=truth, detect_every=3)
    assert res.detector == "truth" and truth.seen == [1, 4, 7, 10, 12]
    assert res.num_tracks >= 4
    # the last frame's people are boxed: nothing after frame 10 confirmed them before
    assert (res.tracks[:, 0] == 12).sum() >= 4


@pytest.mark.parametrize("n, every", [(2, 2), (5, 5)])
def test_a_clip_no_longer_than_the_detection_step_is_tracked(tmp_path, tud_frames, n, every):
    """A clip of at most ``detect_every`` frames is detected on its first and last frames: two
    frames of detections confirm its people (one frame did not: no track, and no word why)."""
    _, frames = tud_frames
    truth = _Truth(frames[:n])
    res = track(_image_folder(tmp_path / "imgs", frames[:n]), fps=25, detector=truth, detect_every=every)
    assert truth.seen == [1, n]
    assert res.num_tracks >= 3


def test_a_detector_of_your_own_is_held_to_a_detections_file():
    """What a user's detector returns is checked as a detections file is (NaN boxes raised a deep
    ValueError, a score of 5 reached the results), and so are the tracker's settings (a NaN gate
    gave no tracks without a word)."""
    frame = np.zeros((48, 64, 3), np.uint8)

    class Returns(Detector):
        def __init__(self, out):
            self.out = out

        def detect(self, frame):
            return self.out

    box = np.array([[1.0, 2.0, 10.0, 20.0]])
    assert Returns((box, [0.5]))(frame).shape == (1, 5)
    assert Returns((np.zeros((0, 4)), []))(frame).shape == (0, 5)
    for out, needle in (((box * np.nan, [0.5]), "NaN"), ((box, [0.5, 0.6]), "1 boxes but 2 scores"),
                        (None, "must return"), ((box, [5.0]), r"scores must lie in \[0, 1\]"),
                        ((-box, [0.5]), "positive size")):
        with pytest.raises(InputError, match=needle):
            Returns(out)(frame)
    with pytest.raises(InputError, match="detector must be a name"):
        track(SAMPLE, det=None, detector=42)
    for bad, needle in ((dict(match_iou=float("nan")), "match_iou"), (dict(max_lost=float("inf")), "max_lost"),
                        (dict(experts_when="bogus"), "experts_when"), (dict(confirm_hits=0), "confirm_hits")):
        with pytest.raises(InputError, match=needle):
            MultiObjectTracker(25.0, 640, 480, config=TrackerConfig(**bad))
    with pytest.raises(InputError, match="config must be a TrackerConfig"):
        MultiObjectTracker(25.0, 640, 480, config={"high": 0.5})


def test_a_detector_of_your_own_wins_over_the_sequences_detections(tmp_path, tud_frames):
    """A MOTChallenge folder (or a video beside det/det.txt) has its own detections; a Detector
    passed to track() was dropped for them without a word."""
    _, frames = tud_frames
    folder = tmp_path / "seq"
    folder.mkdir()
    _image_folder(folder / "img1", frames[:6])
    (folder / "det").mkdir()
    (folder / "det" / "det.txt").write_text("1,-1,10,10,50,100,0.9,-1,-1,-1\n")
    truth = _Truth(frames[:6])
    res = track(folder, fps=25, detector=truth, detect_every=1)
    assert res.detector == "truth" and truth.seen == [1, 2, 3, 4, 5, 6]
    assert track(folder, fps=25).detector.endswith("det.txt")
    with pytest.raises(InputError, match="not both"):
        track(folder, det=folder / "det" / "det.txt", fps=25, detector=_Truth(frames[:6]))
