"""Bad input to the tracking API is an InputError that says what is wrong and what was given;
valid input gives what it always gave (docs/interfaces.md, "Python API", "Errors")."""

from __future__ import annotations

import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.geometry import iou_matrix, max_iou, union_box
from artmotion.tracking import (
    EXPERTS,
    Gaussian,
    MultiObjectTracker,
    PoTE,
    TrackerConfig,
    box_gaussian,
    fuse,
    register_expert,
    run_tracker,
)
from artmotion.tracking.experts import Expert, Frame, make_experts

W, H = 320, 240
IMG = np.zeros((H, W, 3), np.uint8)


def walk(n: int = 12, people: int = 2) -> dict:
    """Detections of ``people`` walking to the right, frames 1..n."""
    return {k: np.array([[20.0 + 90 * p + 3 * k, 60.0 + 5 * p, 30.0, 80.0, 0.9] for p in range(people)])
            for k in range(1, n + 1)}


def run(dets=None, frames=None, tracker=None, **kw):
    t = tracker or MultiObjectTracker(25, W, H)
    frames = frames if frames is not None else ((k, IMG) for k in range(1, 13))
    last = run_tracker(t, frames, walk() if dets is None else dets, **kw)
    rows, events = t.finish(last)
    return rows, events


# ------------------------------------------------------------------------------ 1. shapes
@pytest.mark.parametrize("cols", [6, 10])
def test_detections_of_another_shape_are_refused_not_reshaped(cols):
    # (N, 10) MOT rows or (N, 6) box, score, class were read as other boxes (r_det.py)
    rows = {k: np.column_stack([d, np.ones((len(d), cols - 5))]) for k, d in walk().items()}
    with pytest.raises(InputError, match=rf"frame 1: detections must be an \(N, 5\) array.*got shape \(2, {cols}\)"):
        run(rows)


def test_detections_of_the_right_shape_or_empty_are_taken():
    rows, _ = run()
    assert len(set(rows[:, 1])) == 2
    empty = {k: v for k, v in walk().items()}
    empty[3], empty[4], empty[5] = [], np.zeros((0, 5)), np.zeros(0)   # nothing on frames 3-5
    run(empty)
    f = Frame(1, IMG, [[1, 2, 3, 4, 0.5]])
    assert f.detections.shape == (1, 5)


def test_box_functions_need_four_columns():
    five = np.array([[0, 0, 10, 10, 0.9], [5, 5, 10, 10, 0.8]])
    for call in (lambda: iou_matrix(five, five[:, :4]), lambda: iou_matrix(five[:, :4], five),
                 lambda: max_iou([0, 0, 10, 10], five), lambda: union_box(five), lambda: union_box(five.ravel()[:8])):
        with pytest.raises(InputError, match=r"got shape \("):
            call()
    with pytest.raises(InputError, match="at least one box"):
        union_box(np.zeros((0, 4)))
    # the valid forms are unchanged: one box, a stack, no boxes at all
    assert iou_matrix([0, 0, 10, 10], five[:, :4]).shape == (1, 2)
    assert iou_matrix([], five[:, :4]).shape == (0, 2)
    assert max_iou([0, 0, 10, 10], []) == 0.0
    assert max_iou(np.array([[0, 0, 10, 10]]), five[:, :4]) == 1.0
    np.testing.assert_array_equal(union_box(five[:, :4]), [0, 0, 15, 15])


# ------------------------------------------------------------------------------ 2. the tracker's size and rate
@pytest.mark.parametrize("fps, width, height, needle", [
    (float("nan"), W, H, "frame rate"), (0, W, H, "frame rate"), (-5, W, H, "frame rate"),
    (float("inf"), W, H, "frame rate"), (None, W, H, "frame rate"), ("25", W, H, "frame rate"),
    (25, 0, H, "width"), (25, -W, H, "width"), (25, float("nan"), H, "width"), (25, 320.5, H, "width"),
    (25, W, 0, "height"), (25, W, -1, "height"), (25, W, float("inf"), "height"),
])
def test_tracker_rate_and_size_are_checked(fps, width, height, needle):
    with pytest.raises(InputError, match=needle):
        MultiObjectTracker(fps, width, height)


def test_tracker_online_flag_is_checked():
    with pytest.raises(InputError, match="online must be True or False"):
        MultiObjectTracker(25, W, H, online="no")


def test_whole_float_size_and_integer_rate_are_the_same_tracker():
    a = MultiObjectTracker(25, W, H)
    b = MultiObjectTracker(25.0, float(W), np.int64(H))
    assert (a.fps, a.width, a.height) == (b.fps, b.width, b.height) == (25.0, W, H)
    assert type(b.width) is int and type(b.height) is int


def test_image_of_another_size_than_the_tracker_is_refused():
    with pytest.raises(InputError, match=r"frame 1: the image is 640x480, the tracker's frames are 320x240"):
        run(frames=((k, np.zeros((480, 640, 3), np.uint8)) for k in range(1, 13)))


def test_image_decoded_smaller_may_round_up_or_down():
    # a 321x241 sequence decoded twice smaller is 161x121 (JPEG) or 160x120 (resize): both fit
    for w, h in ((161, 121), (160, 120)):
        t = MultiObjectTracker(25, 321, 241)
        run(frames=((k, np.zeros((h, w, 3), np.uint8)) for k in range(1, 13)), tracker=t, decode=2, reduce=2)
    t = MultiObjectTracker(25, 321, 241)
    with pytest.raises(InputError, match="the image is 100x120"):
        run(frames=((k, np.zeros((120, 100, 3), np.uint8)) for k in range(1, 13)), tracker=t, decode=2, reduce=2)


# ------------------------------------------------------------------------------ 3. run_tracker's input
@pytest.mark.parametrize("column, value, why", [(0, np.nan, "NaN or infinite"), (2, np.inf, "NaN or infinite"),
                                                (4, np.nan, "NaN or infinite"), (2, -30.0, "box of no size"),
                                                (3, 0.0, "box of no size")])
def test_bad_detection_values_name_the_frame(column, value, why):
    dets = walk()
    dets[5] = dets[5].copy()
    dets[5][1, column] = value
    with pytest.raises(InputError, match=f"frame 5: detections row 1 has a {why}"):
        run(dets)


@pytest.mark.parametrize("numbers, needle", [
    (range(12, 0, -1), "frame numbers must increase: frame 11 after frame 12"),
    ([1, 2, 3, 3, 4], "frame numbers must increase: frame 3 after frame 3"),
    (range(-3, 9), "frame number must be a whole number.*got -3"),
    (range(0, 12), "frame number must be a whole number.*got 0"),
    ([1, 2, 2.5, 3], "frame number must be a whole number.*got 2.5"),
    ([1, True], "frame number must be a whole number.*got True"),
    ([1, "2"], "frame number must be a whole number.*got '2'"),
])
def test_frame_numbers_are_whole_increasing_from_one(numbers, needle):
    with pytest.raises(InputError, match=needle):
        run(frames=((k, IMG) for k in numbers))


def test_whole_float_or_numpy_frame_numbers_are_frame_numbers():
    # float frame numbers (a MOT array's first column) crashed in the events (TypeError)
    ints = run()
    for conv in (float, np.int64, np.float64):
        rows, events = run(frames=((conv(k), IMG) for k in range(1, 13)))
        np.testing.assert_array_equal(rows, ints[0])
        assert events == ints[1]
    t = MultiObjectTracker(25, W, H)
    assert run_tracker(t, ((float(k), IMG) for k in range(1, 4)), walk()) == 3
    assert type(t.last_frame) is int


@pytest.mark.parametrize("image, needle", [
    (IMG[:, :, 0].astype(np.uint16), r"got uint16 array of shape \(240, 320\)"), (None, "got NoneType"),
    (IMG.astype(float), r"got float64 array of shape \(240, 320, 3\)"),
    (np.zeros((H, W, 4), np.uint8), r"shape \(240, 320, 4\)"), (np.zeros((0, 0, 3), np.uint8), r"shape \(0, 0, 3\)"),
])
def test_images_must_be_bgr_uint8(image, needle):
    with pytest.raises(InputError, match=r"frame 1: the image must be a BGR \(or grey\) uint8 array.*" + needle):
        run(frames=((k, image) for k in range(1, 13)))


@pytest.mark.parametrize("grey", [IMG[:, :, 0], IMG[:, :, :1]], ids=["HxW", "HxWx1"])
def test_grey_frames_are_tracked_as_bgr(grey):
    """A grey camera's uint8 frames are taken (made BGR): the same tracks as the BGR frames (they
    were refused)."""
    rows, events = run(frames=((k, grey) for k in range(1, 13)))
    want = run()
    np.testing.assert_array_equal(rows, want[0])
    assert events == want[1]


def test_detections_must_be_a_mapping():
    with pytest.raises(InputError, match="detections must be a mapping.*got list"):
        run(list(walk().values()))
    for key in ("1", 1.5, True):      # (keyed by text or 1.5: no box was ever found, and no error)
        with pytest.raises(InputError, match="frame numbers must be whole numbers"):
            run({key: walk()[1], **walk()})
    assert len(run({np.int64(k): v for k, v in walk().items()})[0])      # NumPy's integers are frame numbers
    with pytest.raises(InputError, match="detections must be a mapping.*got NoneType"):
        run_tracker(MultiObjectTracker(25, W, H), ((k, IMG) for k in range(1, 3)), None)


@pytest.mark.parametrize("kw, needle", [(dict(reduce=0), "reduce"), (dict(reduce=1.5), "reduce"),
                                        (dict(detect_every=0), "detect_every"),
                                        (dict(detect_every=-1), "detect_every"), (dict(decode=0), "decode")])
def test_reduce_and_detect_every_are_whole_numbers_from_one(kw, needle):
    with pytest.raises(InputError, match=needle + " must be a whole number in"):
        run(**kw)


def test_frames_must_be_pairs():
    with pytest.raises(InputError, match="frames must be"):
        run(frames=[IMG, IMG])
    with pytest.raises(InputError, match="frames must be"):
        run(frames=5)


# ------------------------------------------------------------------------------ 4. TrackerConfig.check
@pytest.mark.parametrize("kw, needle", [(dict(size_meas=0.0, size_accel=0.0), "size_meas and size_accel"),
                                        (dict(meas=0.0, accel=0.0), "meas and accel")])
def test_zero_measurement_and_process_noise_are_refused(kw, needle):
    # (r_misc.py: LinAlgError: Singular matrix on the first update)
    with pytest.raises(InputError, match=needle + " must not both be 0"):
        TrackerConfig(adapt_noise=False, **kw).check()
    with pytest.raises(InputError, match=needle):
        run(tracker=MultiObjectTracker(25, W, H, config=TrackerConfig(adapt_noise=False, **kw)))
    TrackerConfig(**kw).check()                              # the noise is estimated: fine
    for one in kw:                                           # either alone is fine
        run(tracker=MultiObjectTracker(25, W, H, config=TrackerConfig(adapt_noise=False, **{one: 0.0})))


def test_zero_size_noise_without_the_motion_expert_is_refused():
    # without the motion expert the noise is not estimated even with adapt_noise
    with pytest.raises(InputError, match="size_meas and size_accel must not both be 0 without the 'motion'"):
        MultiObjectTracker(25, W, H, experts=("det",), config=TrackerConfig(size_meas=0.0, size_accel=0.0))


def test_numpy_integers_are_whole_numbers():
    cfg = TrackerConfig(app_parts=np.int64(2), confirm_hits=np.int32(3), tentative_misses=np.uint8(1)).check()
    assert (cfg.app_parts, cfg.confirm_hits, cfg.tentative_misses) == (2, 3, 1)
    for bad in (2.0, True, "2"):
        with pytest.raises(InputError, match="app_parts must be a whole number"):
            TrackerConfig(app_parts=bad).check()
    a = run(tracker=MultiObjectTracker(25, W, H, config=TrackerConfig(app_parts=2, confirm_hits=3)))
    b = run(tracker=MultiObjectTracker(25, W, H, config=TrackerConfig(app_parts=np.int64(2), confirm_hits=np.int64(3))))
    np.testing.assert_array_equal(a[0], b[0])


# ------------------------------------------------------------------------------ 5. expert names
def test_unknown_expert_names_are_input_errors():
    with pytest.raises(InputError, match=r"unknown expert 'kl' \(choose from .*klt"):
        MultiObjectTracker(25, W, H, experts=("det", "motion", "kl"))
    with pytest.raises(InputError, match="unknown expert 'kl'"):
        PoTE(["klt", "kl"])
    with pytest.raises(KeyError):               # as before, for code that caught it
        make_experts(["nope"])
    for bad, needle in ((("det", "det"), "listed twice"), (("motion",), "'det' expert is needed"),
                        ((), "no experts given"), (5, "got int"), ((1,), "unknown expert 1")):
        with pytest.raises(InputError, match=needle):
            MultiObjectTracker(25, W, H, experts=bad)


def test_expert_names_in_a_string_are_split_at_commas():
    # a string was iterated character by character (KeyError: 'd')
    a = run(tracker=MultiObjectTracker(25, W, H, experts=("det", "motion")))
    b = run(tracker=MultiObjectTracker(25, W, H, experts="det, motion"))
    np.testing.assert_array_equal(a[0], b[0])
    assert PoTE("klt").names == ["klt"]
    assert PoTE("klt,blob").names == ["klt", "blob"]
    assert [e.name for e in make_experts("klt,det")] == ["klt", "det"]


# ------------------------------------------------------------------------------ 6. beliefs
@pytest.mark.parametrize("mean, cov, needle", [
    ([100.0, 50.0], np.zeros((2, 2)), "covariance is not finite and positive definite"),
    ([0.0, 0.0], -np.eye(2), "covariance is not finite and positive definite"),
    ([1.0, 2.0], np.full((2, 2), np.nan), "covariance is not finite and positive definite"),
    ([1.0, 2.0], np.diag([np.inf, 1.0]), "covariance is not finite and positive definite"),
    ([1.0, 2.0], [[1.0, 2.0], [2.0, 1.0]], "covariance is not finite and positive definite"),
    ([np.nan, 0.0], np.eye(2), r"belief 0 has a mean that is not finite \(nan, 0\)"),
    ([np.inf, 0.0], np.eye(2), "mean that is not finite"),
])
@pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning")
def test_fuse_refuses_beliefs_that_are_not_gaussians(mean, cov, needle):
    good = Gaussian([5.0, 5.0], np.eye(2))
    with pytest.raises(InputError, match=needle):
        fuse([Gaussian(mean, cov), good])
    with pytest.raises(InputError, match=needle.replace("belief 0", "belief 2")):
        fuse([good, None, Gaussian(mean, cov)])


def test_fuse_of_valid_beliefs_is_unchanged():
    g = fuse([Gaussian([0.0, 0.0], np.eye(2)), None, Gaussian([4.0, 2.0], np.diag([1.0, 3.0]))])
    np.testing.assert_allclose(g.mean, [2.0, 0.5])
    np.testing.assert_allclose(g.cov, np.diag([0.5, 0.75]))
    assert fuse([None]) is None and fuse([]) is None


def test_box_gaussian_needs_a_positive_size():
    for box in ([100, 100, -40, 80], [100, 100, 40, 0], [100, 100, np.nan, 80]):
        with pytest.raises(InputError, match="positive width and height"):
            box_gaussian(box)
    np.testing.assert_allclose(box_gaussian([0, 0, 6, 12]).cov, np.diag([1.0, 2.0]))
    for box in ([np.nan, 100, 40, 80], [np.inf, 100, 40, 80]):     # (a NaN or infinite mean was returned)
        with pytest.raises(InputError, match="a finite box"):
            box_gaussian(box)
    for scale in (0.0, -1.0, np.nan):                               # (no covariance, or a negative one)
        with pytest.raises(InputError, match="scale must be"):
            box_gaussian([0, 0, 6, 12], scale=scale)
    np.testing.assert_allclose(box_gaussian([0, 0, 6, 12], scale=2.0).cov, np.diag([2.0, 4.0]))


@pytest.mark.parametrize("belief, needle", [
    (lambda e: Gaussian([np.nan, 100.0], np.eye(2)), "a mean that is not finite"),
    (lambda e: Gaussian([0.0, 0.0], np.zeros((2, 2))), "a covariance that is not finite and positive definite"),
    (lambda e: Gaussian(e.box[:2] + e.box[2:4] / 2, -np.eye(2)), "a covariance that is not finite and positive"),
    (lambda e: (1.0, 2.0), "a tuple, not a Gaussian or None"),
])
def test_a_users_expert_with_a_bad_belief_is_named(belief, needle):
    # such an expert once emptied the result without a word (p17.py)
    @register_expert
    class Bad(Expert):
        name = "test-bad"
        image_based = False

        def propose(self, frame, prev, entity):
            return belief(entity)

    try:
        cfg = TrackerConfig(experts_when="all")
        with pytest.raises(InputError, match=r"frame 2: expert 'test-bad' gave " + needle):
            run(tracker=MultiObjectTracker(25, W, H, experts=("det", "motion", "test-bad"), config=cfg))
        pote = PoTE(["test-bad"])
        from artmotion.tracking.experts import Entity
        with pytest.raises(InputError, match="expert 'test-bad' gave"):
            pote.estimate(Frame(7, IMG), None, Entity(box=np.array([10.0, 10.0, 20.0, 40.0])))
    finally:
        EXPERTS.pop("test-bad", None)


def test_finish_takes_a_length_of_at_least_the_last_frame():
    """``finish(-5)`` closed the sequence with a negative length (events at its end were wrong)."""
    t = MultiObjectTracker(25, W, H)
    last = run_tracker(t, ((k, IMG) for k in range(1, 13)), walk())
    for bad in (-5, 0, last - 1, 2.5, "12", True):
        with pytest.raises(InputError, match="length must be a whole number"):
            t.finish(bad)
    rows, _ = t.finish(last + 3)
    assert len(rows)


def test_an_empty_detection_file_is_said_where_the_detections_are_named(sample_seq, tmp_path, run_cli):
    """An empty det.txt (or one of blank lines only) tracked nobody and said "0 tracks" and nothing
    else: a scene with nobody in it, or a mistake, which the user must be told."""
    from artmotion.tracking import track

    for text in ("", "\n\n"):
        det = tmp_path / "det.txt"
        det.write_text(text)
        res = track(sample_seq, det=det)
        assert len(res.tracks) == 0 and res.detector.endswith("(no detections in it: nothing tracked)")
    code, out, err = run_cli("track", sample_seq, "--det", det, "--out", tmp_path / "r.txt", "--no-progress")
    assert code == 0 and "det.txt (no detections in it: nothing tracked)" in out + err, out + err


def test_frames_too_small_for_a_detector_name_the_input(tmp_path):
    """A 2x2 video without detections: "a detector's frame of 2x2 pixels is too small", naming nothing."""
    import cv2

    from artmotion.tracking import track

    path = tmp_path / "tiny.mp4"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 25, (2, 2))
    for _ in range(3):
        w.write(np.zeros((2, 2, 3), np.uint8))
    w.release()
    with pytest.raises(InputError, match=r"tiny.mp4: frames of 2x2 pixels are too small for the built-in detector"):
        track(path)
