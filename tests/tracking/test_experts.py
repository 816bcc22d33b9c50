"""Each tracking expert on a synthetic moving blob with known truth (thesis Sec. 2.4)."""

from __future__ import annotations

import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.geometry import box_center
from artmotion.tracking.experts import (
    EXPERTS,
    BlobExpert,
    DetectionExpert,
    Entity,
    FlowExpert,
    Frame,
    KLTExpert,
    MotionExpert,
    box_gaussian,
    foreground,
    make_experts,
    new_motion_filter,
)

from _synth import background, moving_blob

V = (4.0, 1.0)


@pytest.fixture(scope="module")
def blob_video():
    frames, truth = moving_blob(n=25, v=V)
    shared: dict = {}
    # the background model first sees the empty scene for a while, as in a real video
    for k in range(30):
        foreground(Frame(-k, background(), None, scale=1.0, shared=shared))
    fr = []
    for k, img in enumerate(frames, start=1):
        f = Frame(k, img, None, scale=1.0, shared=shared)
        foreground(f)          # the background model sees every frame in order
        fr.append(f)
    return fr, truth


def _errors(expert, fr, truth, start=5):
    errs = []
    for k in range(start, len(fr)):
        ent = Entity(box=truth[k - 1].copy())
        g = expert.propose(fr[k], fr[k - 1], ent)
        assert g is not None, f"{expert.name} had no opinion on frame {k + 1}"
        assert g.mean.shape == (2,) and g.cov.shape == (2, 2)
        assert np.all(np.linalg.eigvalsh(g.cov) > 0)
        errs.append(np.linalg.norm(g.mean - box_center(truth[k])))
    return np.array(errs)


def test_registry_has_the_five_experts():
    assert {"det", "klt", "blob", "motion", "flow"} <= set(EXPERTS)
    assert [e.name for e in make_experts(["klt", "det"])] == ["klt", "det"]


def test_box_gaussian_is_eq_2_9():
    g = box_gaussian([10, 20, 30, 60])
    np.testing.assert_allclose(g.mean, [25, 50])
    np.testing.assert_allclose(g.cov, np.diag([5.0, 10.0]))
    one = box_gaussian(np.array([[10.0, 20.0, 30.0, 60.0]]))    # a stack of one box (was an IndexError)
    np.testing.assert_allclose(one.mean, g.mean)
    for bad in (np.zeros((2, 4)) + 1, [1.0, 2.0, 3.0], np.ones((4, 1))):
        with pytest.raises(InputError, match=r"box_gaussian takes one box"):
            box_gaussian(bad)


def test_klt_follows_the_blob(blob_video):
    fr, truth = blob_video
    err = _errors(KLTExpert(), fr, truth)
    assert np.median(err) < 1.0 and err.max() < 2.5


def test_flow_follows_the_blob(blob_video):
    fr, truth = blob_video
    err = _errors(FlowExpert(), fr, truth)
    # the box starts where the blob was: a static expert would be off by |V| ~ 4.1 px
    assert np.median(err) < 1.5


def test_blob_expert_finds_the_foreground_blob(blob_video):
    fr, truth = blob_video
    err = _errors(BlobExpert(), fr, truth, start=8)
    assert np.median(err) < 2.0


def test_background_subtraction_is_silent_while_the_camera_moves():
    """A moving camera moves the whole background: the background model would see everything as
    foreground. While the tracker says the camera moves there is no foreground and the model is
    learnt afresh afterwards."""
    frames, truth = moving_blob(n=40, v=V)
    shared: dict = {}
    for k in range(30):
        foreground(Frame(-k, background(), None, scale=1.0, shared=shared))
    panned = [np.roll(f, 12 * k, axis=1) for k, f in enumerate(frames[:10])]
    shared["camera_moving"] = True
    masks = [foreground(Frame(k, img, None, scale=1.0, shared=shared)) for k, img in enumerate(panned)]
    assert all(m.max() == 0 for m in masks) and "bg" not in shared
    ent = Entity(box=truth[5].copy())
    f5 = Frame(5, panned[5], None, scale=1.0, shared=shared)
    assert BlobExpert().propose(f5, None, ent) is None
    # the camera is still again: a new model learns the new view and finds the blob
    shared["camera_moving"] = False
    for k in range(30):
        foreground(Frame(100 + k, background(), None, scale=1.0, shared=shared))
    fr = [Frame(200 + k, img, None, scale=1.0, shared=shared) for k, img in enumerate(frames[10:20])]
    for f in fr:
        foreground(f)
    g = BlobExpert().propose(fr[-1], fr[-2], Entity(box=truth[18].copy()))
    assert g is not None and np.linalg.norm(g.mean - box_center(truth[19])) < 3.0


def test_blob_expert_rejects_areas_out_of_ratio(blob_video):
    fr, truth = blob_video
    big = truth[9].copy()
    big[2:] *= 4                       # the blob is 1/16 of this box: below AR_min (Eq. 2.7)
    assert BlobExpert().propose(fr[10], fr[9], Entity(box=big)) is None


def test_motion_expert_predicts_constant_velocity():
    dt = 0.1
    truth = np.array([[100 + 4 * k, 50 + 1 * k] for k in range(12)], float)
    kf = new_motion_filter(truth[0], (30, 60), dt)
    ent = Entity(box=np.r_[truth[0] - [15, 30], 30, 60], kf=kf, centres=[truth[0]])
    m = MotionExpert()
    for c in truth[1:10]:
        kf.predict(Q=m.process_noise(ent))
        kf.update(c, R=np.eye(2) * 0.5)
        ent.centres.append(c)
    g = m.propose(None, None, ent)
    np.testing.assert_allclose(g.mean, truth[10], atol=0.5)
    # acceleration noise from finite differences is at its floor for a constant-velocity path
    Q = m.process_noise(ent)
    assert Q.shape == (4, 4) and Q[0, 0] > 0


def test_detection_expert_indicator_eq_2_4():
    frame = Frame(1, np.zeros((100, 100, 3), np.uint8),
                  detections=[[10, 10, 20, 40, 0.95],      # overlaps, high score -> wins
                              [12, 12, 20, 40, 0.70],      # overlaps, lower score
                              [70, 10, 20, 40, 0.99]],     # best score but no overlap
                  scale=1.0)
    ent = Entity(box=np.array([8.0, 8.0, 20, 40]))
    g = DetectionExpert(threshold=0.5).propose(frame, None, ent)
    np.testing.assert_allclose(g.mean, [20, 30])
    assert DetectionExpert(threshold=0.97).propose(frame, None, ent) is None
    ent.detection = np.array([12, 12, 20, 40, 0.70])      # the tracker's assignment wins
    np.testing.assert_allclose(DetectionExpert().propose(frame, None, ent).mean, [22, 32])
