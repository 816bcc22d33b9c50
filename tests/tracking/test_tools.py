"""Surgical instruments (#15): detector training, augmentation, tracking, and the tool commands."""

import json
import math
import shutil

import cv2
import numpy as np
import pytest
from conftest import shared_path

from artmotion.errors import InputError
from artmotion.tracking.instruments.annotations import read_predictions, read_tools_csv
from artmotion.tracking.instruments.detector import ToolDetector, _augment, scale_to
from artmotion.tracking.instruments.track import ToolTracker, track_tools

pytest.importorskip("torch")


def test_augmentation_moves_heads_with_the_image():
    rng = np.random.default_rng(0)
    img = np.full((144, 192, 3), 40, np.uint8)
    heads = np.array([[60.0, 50.0, 20.0, 0.3], [140.0, 100.0, 30.0, 4.0]])
    for x, y, _s, a in heads:  # a bright head and a grey shaft pointing along the angle
        cv2.line(img, (int(x), int(y)), (int(x + 40 * math.cos(a)), int(y + 40 * math.sin(a))), (120, 120, 120), 3)
        cv2.circle(img, (int(x), int(y)), 4, (255, 255, 255), -1)
    for _ in range(20):
        out, H = _augment(img, heads, rng)
        for x, y, _s, a in H:
            assert out[int(round(y)), int(round(x))].max() > 150  # still on the head
            px, py = int(round(x + 20 * math.cos(a))), int(round(y + 20 * math.sin(a)))
            if 0 <= px < 192 and 0 <= py < 144:
                assert out[py, px].max() > 70  # and the angle still points along the shaft


def test_tracker_keeps_one_identity_and_follows_detections():
    class NoDetector:
        def detect(self, frame):
            return np.zeros((0, 5))

    frame = np.random.default_rng(1).integers(0, 255, (120, 160, 3), dtype=np.uint8)
    tr = ToolTracker(NoDetector(), klt=False, coast=3)
    ids, err = set(), []
    for k in range(30):
        x, y = 30 + 3 * k, 60 + math.sin(k / 5) * 10
        rows = tr.update(frame, np.array([[x, y, 25.0, 1.0, 0.9]]))
        for r in rows:
            ids.add(int(r[0]))
            err.append(math.hypot(r[1] - x, r[2] - y))
    assert ids == {0} and max(err) < 5.0
    # without detections the head is reported for `coast` frames, then no more
    n = [len(tr.update(frame, np.zeros((0, 5)))) for _ in range(6)]
    assert n[:3] == [1, 1, 1] and n[3:] == [0, 0, 0]


@pytest.mark.parametrize("experts", [{"klt": True}, {"klt": False, "flow": True}])
def test_image_motion_experts_carry_a_head_between_detections(experts):
    """A textured patch slides over a textured background; after a few detections, KLT or the
    dense-flow (DIS) expert alone follows it through frames without any (the motion filter alone
    would coast at its last velocity, and the patch changes direction)."""
    class NoDetector:
        def detect(self, frame):
            return np.zeros((0, 5))

    rng = np.random.default_rng(2)
    back = cv2.GaussianBlur(rng.integers(0, 255, (144, 192, 3), dtype=np.uint8), (5, 5), 1.0)
    patch = cv2.GaussianBlur(rng.integers(0, 255, (30, 30, 3), dtype=np.uint8), (3, 3), 0.8)

    def frame_at(x, y):
        f = back.copy()
        f[int(y) - 15:int(y) + 15, int(x) - 15:int(x) + 15] = patch
        return f

    tr = ToolTracker(NoDetector(), coast=20, max_miss=30, camera=False, **experts)
    path = [(40 + 4 * k, 70) for k in range(8)] + [(68, 70 + 4 * k) for k in range(1, 12)]  # right, then down
    err = []
    for k, (x, y) in enumerate(path):
        dets = np.array([[x, y, 30.0, 0.0, 0.9]]) if k < 5 else np.zeros((0, 5))
        rows = tr.update(frame_at(x, y), dets)
        if k >= 5:
            err.append(math.hypot(rows[0, 1] - x, rows[0, 2] - y))
    assert max(err) < 6.0, err


@pytest.fixture(scope="module")
def lap_subset(tmp_path_factory):
    root = shared_path("surgical", "lap-tools")
    gt = read_tools_csv(root / "tools.csv")
    d = tmp_path_factory.mktemp("lap")
    (d / "frames").mkdir()
    for f in sorted(gt)[:24]:
        shutil.copy(root / "frames" / f"{f:06d}.png", d / "frames")
    return root, d


def test_train_track_eval_commands(lap_subset, run_cli, tmp_path):
    root, d = lap_subset
    model = tmp_path / "tools.pt"
    code, out, err = run_cli("tool", "train", d / "frames", root / "tools.csv", "--model", model, "--epochs", "2")
    assert code == 0, err
    assert "trained on 24 frames" in out and model.exists()
    pred = tmp_path / "pred.csv"
    code, out, err = run_cli("tool", "track", d / "frames", "--model", model, "--out", pred, "--threshold", "0.05")
    assert code == 0, err
    p = read_predictions(pred)  # (no rows when nothing was found: an answer too)
    assert set(p) <= set(read_tools_csv(root / "tools.csv"))  # frames numbered by their file names
    assert "24 frames" in out
    code, out, err = run_cli("tool", "eval", root / "tools.csv", root / "tools.csv")
    assert code == 2 and "tools.csv" in err  # annotations are not predictions: one line naming the file
    # the truth itself, as predictions, scores 1 (the identities linked from frame to frame)
    from artmotion.tracking.instruments.annotations import write_predictions

    gt = read_tools_csv(root / "tools.csv")
    perfect = {f: np.column_stack([np.arange(len(h)), h, np.ones(len(h))]) for f, h in gt.items() if f < min(gt) + 3}
    write_predictions(tmp_path / "perfect.csv", perfect)
    code, out, err = run_cli("tool", "eval", root / "tools.csv", tmp_path / "perfect.csv", "--json", "--fps", "12")
    res = json.loads(out)
    assert code == 0 and res["precision"] == 1.0 and res["median_angle_error_deg"] < 0.01 and res["fps"] == 12.0
    assert res["matched"] == sum(len(h) for h in perfect.values()) and res["recall"] == pytest.approx(res["matched"] / res["gt"])
    # predictions of nothing found (what 'tool track' writes then) score, with recall 0
    write_predictions(tmp_path / "none.csv", {})
    code, out, err = run_cli("tool", "eval", root / "tools.csv", tmp_path / "none.csv", "--json")
    assert code == 0, err
    assert json.loads(out)["recall"] == 0.0
    # the whole pipeline with the tool model: tracks, sentences, report, index
    code, out, err = run_cli("run", d / "frames", "--tool-model", model, "--out", tmp_path / "run",
                             "--index", tmp_path / "index.sqlite")
    assert code == 0, err
    run = json.loads((tmp_path / "run" / "run.json").read_text())
    assert run["detections"] == "tool model" and (tmp_path / "run" / "report.html").is_file()
    assert run["files"]["video"] == "annotated.mp4" and (tmp_path / "run" / "annotated.mp4").stat().st_size > 0
    assert all(t["id"] >= 1 for t in run["track_summary"])
    assert all(s["subject"] == "tool" for s in run["sentences"])
    # a model that is not one
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a model")
    code, _, err = run_cli("tool", "track", d / "frames", "--model", bad, "--out", tmp_path / "x.csv")
    assert code == 2 and "bad.pt" in err and "not a tool model" in err and not (tmp_path / "x.csv").exists()
    code, _, err = run_cli("tool", "train", d / "frames", root / "tools.csv", "--model", model, "--epochs", "0")
    assert code == 2 and "--epochs" in err


def test_trained_detector_finds_heads_on_frames_it_saw(lap_subset):
    # a fit that can fail: after a short training the heads of its own frames are found
    root, d = lap_subset
    gt = read_tools_csv(root / "tools.csv")
    frames = sorted(gt)[:24]
    imgs = [cv2.imread(str(d / "frames" / f"{f:06d}.png")) for f in frames]
    det = ToolDetector(epochs=30, threshold=0.05).fit(imgs, [gt[f] for f in frames])
    hit = total = 0
    for img, f in zip(imgs, frames):
        D = det.detect(img)
        for x, y, *_ in gt[f]:
            total += 1
            hit += bool(len(D)) and float(np.min(np.hypot(D[:, 0] - x, D[:, 1] - y))) <= 15
    assert hit / total > 0.5
    # the same frames at twice the size: brought back to the training size, the heads found in
    # the big frames' pixels (without the scaling the network sees instruments twice the size it learnt)
    big_hit = 0
    for img, f in zip(imgs, frames):
        D = det.detect(cv2.resize(img, None, fx=2, fy=2, interpolation=cv2.INTER_LINEAR))
        for x, y, *_ in gt[f]:
            big_hit += bool(len(D)) and float(np.min(np.hypot(D[:, 0] - 2 * x, D[:, 1] - 2 * y))) <= 30
    assert big_hit >= 0.9 * hit
    # the tracker's pixel settings follow the video's size
    tr = ToolTracker(det)
    tr.update(cv2.resize(imgs[0], None, fx=2, fy=2))
    assert tr._px == pytest.approx(2.0)


def _untrained_detector(shape=(96, 128)):
    from artmotion.tracking.instruments import net

    det = ToolDetector(width=4)
    det.model_, det.frame_shape_, det.max_heads_ = net.HeadNet(det.width).eval(), shape, 4
    return det


def test_detector_refuses_what_is_not_a_bgr_uint8_frame():
    """Grey, BGRA, bool, float, empty frames and None used to reach torch or OpenCV (deep errors, or
    a ZeroDivisionError); frames of two sizes in one batch, NumPy's stack."""
    det = _untrained_detector()
    frame = np.random.default_rng(0).integers(0, 255, (96, 128, 3), dtype=np.uint8)
    assert det.detect(frame).shape[1] == 5
    assert [d.shape[1] for d in det.detect_batch([frame, frame])] == [5, 5]
    for bad in (frame[:, :, 0], np.dstack([frame, frame[:, :, :1]]), frame > 100, frame.astype(np.float32), None,
                frame.tolist()):
        with pytest.raises(InputError, match=r"must be a BGR uint8 image \(H, W, 3\), got"):
            det.detect(bad)
    with pytest.raises(InputError, match="0x0 pixels is too small"):
        det.detect(np.zeros((0, 0, 3), np.uint8))
    with pytest.raises(InputError, match="one size, got 128x96 and 64x48"):
        det.detect_batch([frame, frame[:48, :64]])


@pytest.mark.parametrize("heads,settings,message", [
    ([[np.nan, 10, 8, 0]], {}, "frame 1 hold NaN"),
    ([[10, 10, 8, np.inf]], {}, "frame 1 hold NaN"),
    ([[70, 10, 8, 0]], {}, r"frame 1: a head at \(70, 10\) lies outside the 64x48 frame"),
    ([[10, -1, 8, 0]], {}, "outside"),
    ([[10, 10, 0, 0]], {}, "size must be positive"),
    ([[10, 10]], {}, r"must be a \(k, 4\) array"),
    ([[10, 10, 8, 0]], {"width": 0}, "width"),
    ([[10, 10, 8, 0]], {"lr": float("nan")}, "lr"),
    ([[10, 10, 8, 0]], {"lr": 0.0}, "lr"),
    ([[10, 10, 8, 0]], {"seed": -1}, "seed"),
])
def test_fit_refuses_bad_heads_and_settings(heads, settings, message):
    frames = [np.full((48, 64, 3), 90, np.uint8)] * 2
    with pytest.raises(InputError, match=message):
        ToolDetector(epochs=1, batch=2, **settings).fit(frames, [np.array([[20.0, 20, 8, 0]]), np.array(heads, float)])


def test_fit_refuses_frames_that_are_not_bgr_uint8():
    good = np.full((48, 64, 3), 90, np.uint8)
    for bad in (good[:, :, 0], good.astype(np.float32), None):
        with pytest.raises(InputError, match="training frame 1 must be a BGR uint8 image"):
            ToolDetector(epochs=1, batch=2).fit([good, bad], [np.zeros((0, 4))] * 2)


def test_tracker_refuses_bad_frames_and_detections_and_goes_on():
    class NaNDetector:
        def detect(self, frame):
            return np.array([[np.nan, 1, 1, 1, 1.0]])

    frame = np.random.default_rng(1).integers(0, 255, (120, 160, 3), dtype=np.uint8)
    tr = ToolTracker(NaNDetector(), klt=False)
    with pytest.raises(InputError, match="BGR uint8"):
        tr.update(frame[:, :, 0], np.zeros((0, 5)))
    with pytest.raises(InputError, match="the detector's detections hold NaN"):
        tr.update(frame)
    det = np.array([[50.0, 60, 25, 1, 0.9]])
    tr.update(frame, det)
    for bad, message in ((np.array([[np.nan, 60, 25, 1, 0.9]]), "detections hold NaN"),
                         (np.array([[50.0, 60, 25, 0.9]]), r"\(k, 5\) array"),
                         (np.ones((2, 10)), r"\(k, 5\) array")):
        with pytest.raises(InputError, match=message):
            tr.update(frame, bad)
    with pytest.raises(InputError, match="a frame of 80x60 after frames of 160x120"):
        tr.update(frame[:60, :80], det)
    rows = tr.update(frame, det)  # nothing above changed the tracker: the head is confirmed on its second frame
    assert rows.shape == (1, 6) and rows[0, 0] == 0 and abs(rows[0, 1] - 50) < 1


def test_scale_to():
    assert scale_to((288, 384), (288, 384)) == 1.0
    assert scale_to((288, 384), (290, 390)) == 1.0  # a few pixels are no other scale
    assert scale_to((288, 384), (576, 768)) == pytest.approx(0.5)
    assert scale_to((288, 384), (720, 1280)) == pytest.approx((288 * 384 / (720 * 1280)) ** 0.5)


def test_events_from_tracks():
    from artmotion.language.describe import events_from_tracks

    rows = [[f, 1, 100, 100, 20, 20, 1, -1, -1, -1] for f in range(1, 11)]
    rows += [[f, 2, 0, 50, 20, 20, 1, -1, -1, -1] for f in range(4, 8)]  # starts and ends at the left border
    ev = events_from_tracks(np.array(rows, float), (200, 200))
    assert [(e["type"], e["frame"], e["tracks"], e["side"]) for e in ev] == [("enter", 4, [2], "left"),
                                                                          ("exit", 7, [2], "left")]


def test_train_refuses_heads_outside_their_frame(tmp_path, run_cli):
    frames = tmp_path / "frames"
    frames.mkdir()
    for n in (1, 2):
        cv2.imwrite(str(frames / f"{n:06d}.png"), np.full((48, 64, 3), 100, np.uint8))
    csv = tmp_path / "tools.csv"
    csv.write_text("frame,tool,y,x,scale,angle\n1,0,10,20,5,0\n2,0,5,999,5,0\n")
    code, out, err = run_cli("tool", "train", frames, csv, "--model", tmp_path / "m.npz", "--epochs", "1")
    assert code == 2 and "tools.csv" in err and "frame 2" in err and "64x48" in err and err.count("\n") == 1
    assert not (tmp_path / "m.npz").exists()


def test_loading_a_damaged_model(tmp_path):
    p = tmp_path / "m.pt"
    import torch

    torch.save({"format": "artmotion-tool-detector-1", "width": 32}, p)
    with pytest.raises(InputError, match="damaged tool model"):
        ToolDetector.load(p)
    with pytest.raises(InputError, match="no such file"):
        ToolDetector.load(tmp_path / "missing.pt")


@pytest.mark.parametrize("field,value", [("frame_shape", [0, 0]), ("frame_shape", [1_000_000, 1_000_000]),
                                         ("threshold", float("nan")), ("threshold", 2.0),
                                         ("max_heads", 0), ("max_heads", 10**9)])
def test_loading_a_model_with_absurd_settings(tmp_path, field, value):
    """A model file whose settings no training writes (a frame size of 0 would divide by zero, a
    huge one exhaust memory) is refused on loading, not at the first frame."""
    import torch

    from artmotion.tracking.instruments import net

    det = ToolDetector()
    det.model_, det.frame_shape_, det.max_heads_ = net.HeadNet(det.width), (288, 384), 4
    good = tmp_path / "good.pt"
    det.save(good)
    assert ToolDetector.load(good).frame_shape_ == (288, 384)
    state = torch.load(good, weights_only=True)
    state[field] = value
    bad = tmp_path / "bad.pt"
    torch.save(state, bad)
    with pytest.raises(InputError, match="damaged tool model"):
        ToolDetector.load(bad)


def test_saving_a_model_on_a_full_disk_is_an_input_error(tmp_path):
    """torch.save given a file name reports a full disk as a RuntimeError of its own ("enforce
    fail at inline_container.cc"), which the command line took for a bug (exit 1): the model is
    written by Python's file I/O, whose OSError is a clear "cannot write". A file-size limit stands
    in for the full disk."""
    import resource

    det = _untrained_detector()
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (4096, hard))
    try:
        with pytest.raises(InputError, match="m.pt: cannot write: File too large"):
            det.save(tmp_path / "m.pt")
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    assert list(tmp_path.iterdir()) == []


class _FixedDetector:
    """A stand-in for a loaded model (``ToolDetector.load``): one head at (30, 20) on every frame."""
    threshold, max_heads_, frame_shape_ = 0.05, 4, (48, 64)

    def detect(self, frame):
        return np.array([[30.0, 20.0, 10.0, 0.5, 0.9]])


def _noise_frames(folder, numbers, size=(48, 64)):
    folder.mkdir()
    rng = np.random.default_rng(0)
    for n in numbers:
        cv2.imwrite(str(folder / f"{n}.png"), rng.integers(0, 255, (*size, 3), dtype=np.uint8))
    return folder


def test_a_head_is_reported_from_its_first_frame(tmp_path, run_cli, monkeypatch):
    """A head is confirmed on its second detection; its first frame was lost (every run lost its
    first frame, and one frame gave 0 heads without a word). The rows of a head's tentative frames
    are reported once it is confirmed, also across a frame without its detection; a head detected
    once is not."""
    frame = np.random.default_rng(1).integers(0, 255, (120, 160, 3), dtype=np.uint8)

    class Scripted:
        dets = {0: [[50, 60, 25, 1, 0.9]], 1: [], 2: [[52, 60, 25, 1, 0.9]], 3: [[54, 60, 25, 1, 0.9]],
                4: [[54, 60, 25, 1, 0.9], [130, 20, 25, 1, 0.9]], 5: [[54, 60, 25, 1, 0.9]], 6: []}

        def __init__(self):
            self.k = -1

        def detect(self, frame):
            self.k += 1
            return np.array(self.dets[self.k], float).reshape(-1, 5)

    out = list(track_tools(((n, frame) for n in range(10, 17)), Scripted(), klt=False))
    assert [n for n, _ in out] == list(range(10, 17))
    assert [len(r) for _, r in out] == [1, 0, 1, 1, 1, 1, 0]  # the head of frame 130,20 seen once: never
    assert all(r[0, 0] == 0 for _, r in out if len(r)) and abs(out[0][1][0, 1] - 50) < 1e-9
    # through the command: two frames, a head on both; one frame, why there is none
    monkeypatch.setattr(ToolDetector, "load", classmethod(lambda cls, path: _FixedDetector()))
    model = tmp_path / "m.pt"
    model.write_bytes(b"model")
    two = _noise_frames(tmp_path / "two", (1, 2))
    code, out_text, err = run_cli("tool", "track", two, "--model", model, "--out", tmp_path / "two.csv")
    assert code == 0, err
    assert sorted(read_predictions(tmp_path / "two.csv")) == [1, 2] and "2 frames, 2 heads of 1 instruments" in out_text
    one = _noise_frames(tmp_path / "one", (1,))
    code, out_text, err = run_cli("tool", "track", one, "--model", model, "--out", tmp_path / "one.csv")
    assert code == 0, err
    assert "1 frames, 0 heads of 0 instruments (a head is confirmed by detections on 2 frames, and the input has 1)" \
        in out_text


def test_track_says_when_frames_are_scaled_to_the_model(tmp_path, run_cli, monkeypatch):
    """A crop (or any frame of another size) was scaled to the model's frame area without a word."""
    monkeypatch.setattr(ToolDetector, "load", classmethod(lambda cls, path: _FixedDetector()))
    model = tmp_path / "m.pt"
    model.write_bytes(b"model")
    code, out, err = run_cli("tool", "track", _noise_frames(tmp_path / "big", (1, 2), (96, 128)), "--model", model,
                             "--out", tmp_path / "p.csv")
    assert code == 0, err
    assert "frames of 128x96 scaled x0.50 to the model's 64x48 area (the same view assumed)" in out
    code, out, err = run_cli("tool", "track", _noise_frames(tmp_path / "same", (1, 2)), "--model", model,
                             "--out", tmp_path / "q.csv")
    assert code == 0 and "scaled" not in out


def test_frames_too_small_for_the_detector_are_refused_before_the_work(tmp_path, run_cli, monkeypatch):
    """tool track (and run --tool-model) scaled 1x1 or 8x8 frames x330 to the model's area and
    tracked them (exit 0), where tool train refuses frames under 32x32; the detector refuses them
    in the API too."""
    monkeypatch.setattr(ToolDetector, "load", classmethod(lambda cls, path: _FixedDetector()))
    model = tmp_path / "m.pt"
    model.write_bytes(b"model")
    tiny = _noise_frames(tmp_path / "tiny", (1, 2), (8, 8))
    for args in (("tool", "track", tiny, "--model", model, "--out", tmp_path / "p.csv"),
                 ("run", tiny, "--tool-model", model, "--out", tmp_path / "r", "--no-video")):
        code, out, err = run_cli(*args)
        assert code == 2 and "frames of 8x8 are too small" in err and err.count("\n") == 1, err
        assert not (tmp_path / "p.csv").exists() and not (tmp_path / "r").exists()
    with pytest.raises(InputError, match="frames of 8x8 are too small"):
        _untrained_detector().detect(np.zeros((8, 8, 3), np.uint8))
    assert _untrained_detector().detect(np.zeros((40, 9000, 3), np.uint8)).shape[1] == 5   # (larger: scaled)


def test_track_checks_frame_numbers_before_the_work(tmp_path, run_cli, monkeypatch):
    """Frames named by a date stamp were all tracked, then the OUTPUT file was blamed for their
    numbers; the first frame whose number no predictions file holds is named, before any work."""
    tracked = []

    class Counting(_FixedDetector):
        def detect(self, frame):
            tracked.append(1)
            return super().detect(frame)

    monkeypatch.setattr(ToolDetector, "load", classmethod(lambda cls, path: Counting()))
    model = tmp_path / "m.pt"
    model.write_bytes(b"model")
    frames = tmp_path / "frames"
    frames.mkdir()
    for n in (20241129001, 20241129002):
        cv2.imwrite(str(frames / f"cam_{n}.png"), np.zeros((48, 64, 3), np.uint8))
    code, out, err = run_cli("tool", "track", frames, "--model", model, "--out", tmp_path / "pred.csv")
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert "cam_20241129001.png: frame number 20241129001" in err and "pred.csv" not in err
    assert not tracked and not (tmp_path / "pred.csv").exists()


def test_train_names_the_frame_of_another_size(tmp_path, run_cli):
    frames = _noise_frames(tmp_path / "frames", (1, 2, 3))
    cv2.imwrite(str(frames / "2.png"), np.zeros((64, 80, 3), np.uint8))
    csv = tmp_path / "tools.csv"
    csv.write_text("frame,tool,y,x,scale,angle\n1,0,10,20,5,0\n2,0,10,20,5,0\n3,0,10,20,5,0\n")
    code, out, err = run_cli("tool", "train", frames, csv, "--model", tmp_path / "m.pt", "--epochs", "1")
    assert code == 2 and err.count("\n") == 1
    assert "2.png: image size 80x64 differs from the other training frames' 64x48" in err
    assert not (tmp_path / "m.pt").exists()
    with pytest.raises(InputError, match="training frame 1 is 80x64, training frame 0 64x48"):
        ToolDetector(epochs=1).fit([np.zeros((48, 64, 3), np.uint8), np.zeros((64, 80, 3), np.uint8)],
                                   [np.zeros((0, 4))] * 2)


def test_training_on_any_frame_size():
    """A side 2-7 more than a multiple of 8 (854x480) crashed training: the targets' grid (side // 8)
    was not the network's output (ceil(floor(side / 2) / 4) cells)."""
    heads = np.array([[20.0, 15.0, 8.0, 0.5]])
    for w, h in ((42, 34), (47, 39)):  # sides 2 and 7 more than a multiple of 8
        frames = [np.random.default_rng(w).integers(0, 255, (h, w, 3), dtype=np.uint8)] * 2
        det = ToolDetector(epochs=1, batch=2, width=4).fit(frames, [heads, heads])
        assert det.detect(frames[0]).shape[1] == 5


def test_the_cap_of_heads_comes_from_the_training_frames(tmp_path, run_cli, monkeypatch):
    """A fixed cap of 4 heads a frame dropped the 5th and 6th instruments of frames showing 6,
    without a word. The cap is now twice the most heads of a training frame, kept in the model;
    an explicit one below that is refused; and 'tool track' says when the cap left out a likely head."""
    six = np.array([[8.0 + 9 * k, 20.0, 6.0, 0.5] for k in range(6)])
    frames = [np.full((48, 64, 3), 90, np.uint8)] * 2
    det = ToolDetector(epochs=1, batch=2, width=4).fit(frames, [six, six[:2]])
    assert det.max_heads_ == 12
    det.save(tmp_path / "m.pt")
    assert ToolDetector.load(tmp_path / "m.pt").max_heads_ == 12
    assert ToolDetector(epochs=1, batch=2, width=4).fit(frames, [six[:2], np.zeros((0, 4))]).max_heads_ == 4
    with pytest.raises(InputError, match="training frame 0 has 6 heads, more than the 5 a frame"):
        ToolDetector(epochs=1, batch=2, width=4, max_heads=5).fit(frames, [six, six[:2]])
    # a network sure of a head everywhere: every cell a peak scoring ~1, 2 kept, the rest left out and said
    from artmotion._torch import torch

    det = _untrained_detector((48, 64))
    det.max_heads_ = 2
    with torch.no_grad():
        det.model_.head.bias[0] = 10.0
        det.model_.head.weight.zero_()
    frame = np.full((48, 64, 3), 90, np.uint8)
    assert len(det.detect(frame)) == 2 and det.left_out_[0] > 0.99
    monkeypatch.setattr(ToolDetector, "load", classmethod(lambda cls, path: det))
    code, out, err = run_cli("tool", "track", _noise_frames(tmp_path / "frames", (1, 2, 3)), "--model", tmp_path / "m.pt",
                             "--out", tmp_path / "p.csv")
    assert code == 0, err
    assert "note: on 3 frame(s) the detector found more heads than the 2 a frame the model reports" in err


def test_loading_a_model_with_a_negative_variance(tmp_path):
    """A negative batch-normalisation variance makes every output NaN: `tool track` said "0 heads"
    and exited 0 (found by a fuzzing review)."""
    import torch

    from artmotion.tracking.instruments import net

    det = ToolDetector()
    det.model_, det.frame_shape_, det.max_heads_ = net.HeadNet(det.width), (288, 384), 4
    good = tmp_path / "good.pt"
    det.save(good)
    state = torch.load(good, weights_only=True)
    key = next(k for k in state["weights"] if k.endswith("running_var"))
    state["weights"][key] = state["weights"][key] * 0 - 1
    bad = tmp_path / "bad.pt"
    torch.save(state, bad)
    with pytest.raises(InputError, match="damaged tool model .a negative batch-normalisation variance"):
        ToolDetector.load(bad)


def test_a_model_whose_output_is_not_finite_is_named(tmp_path):
    """Finite weights can still overflow (every weight scaled by 1e15): detect names the model file
    instead of finding no head, which `tool track` said as "0 heads" and exit 0."""
    import torch

    from artmotion.tracking.instruments import net

    det = ToolDetector()
    det.model_, det.frame_shape_, det.max_heads_ = net.HeadNet(det.width), (48, 64), 4
    good = tmp_path / "good.pt"
    det.save(good)
    state = torch.load(good, weights_only=True)
    for k, t in state["weights"].items():
        if t.is_floating_point() and "running_" not in k:
            state["weights"][k] = t * 1e15
    bad = tmp_path / "bad.pt"
    torch.save(state, bad)
    frame = np.random.default_rng(0).integers(0, 255, (48, 64, 3), dtype=np.uint8)
    assert len(ToolDetector.load(good).detect(frame)) <= 4
    with pytest.raises(InputError, match="damaged tool model: its output") as err:
        ToolDetector.load(bad).detect(frame)
    assert err.value.path == str(bad)


def test_tool_detector_has_scikit_learns_parameter_protocol():
    # get_params / set_params / clone as every other estimator of the package (it had none:
    # sklearn.base.clone failed on it)
    from sklearn.base import clone

    det = ToolDetector(epochs=3, threshold=0.2)
    assert det.get_params() == {"batch": 8, "epochs": 3, "lr": 3e-3, "max_heads": None, "seed": 0,
                                "threshold": 0.2, "width": 32}
    twin = clone(det)
    assert twin is not det and twin.get_params() == det.get_params()
    assert twin.set_params(width=8).width == 8 and det.width == 32
    assert repr(det) == "ToolDetector(epochs=3, threshold=0.2)"
    with pytest.raises(InputError, match="'depth' is not a parameter of ToolDetector"):
        det.set_params(depth=2)


def test_a_fitted_tool_detectors_threshold_set_later_is_checked_where_it_is_used(tmp_path):
    # set_params checks nothing (scikit-learn's convention); a threshold of NaN set on a trained
    # model found 0 heads without a word, -1 returned every faint peak, "0.3" failed deep in NumPy
    frames = [np.full((32, 32, 3), 90, np.uint8) for _ in range(2)]
    det = ToolDetector(epochs=1, batch=2, width=4).fit(frames, [np.array([[16.0, 16, 8, 0]])] * 2)
    for bad in (float("nan"), -1.0, "0.3", 1.0):
        det.set_params(threshold=bad)
        with pytest.raises(InputError, match="threshold must be a number in"):
            det.detect(frames[0])
    det.set_params(threshold=0.05)
    assert det.detect(frames[0]).shape[1] == 5
    det.set_params(threshold=np.float64(0.3))       # saved as a plain number: load read it back
    path = det.save(tmp_path / "tool.pt")
    assert ToolDetector.load(path).threshold == 0.3

