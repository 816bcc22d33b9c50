"""The Kalman filter bank (Eq. 2.10), the RTS smoother of the offline pass, camera motion."""

from __future__ import annotations

import cv2
import filterpy.kalman as filterpy  # the reference implementation (dev extra)
import numpy as np

from artmotion.tracking.camera import CameraMotion, estimate_motion
from artmotion.tracking.offline import rts_smooth
from artmotion.tracking.state import KalmanBank, NoiseEstimator, boxes_to_z, z_to_boxes


def _reference(bank: KalmanBank, slot: int, dt: float) -> "filterpy.KalmanFilter":
    """filterpy's KalmanFilter with the same state, F, Q and R as one filter of the bank."""
    kf = filterpy.KalmanFilter(dim_x=8, dim_z=4)
    kf.x = bank.x[slot].copy()
    kf.P = bank.P[slot].copy()
    kf.F = np.eye(8)
    kf.F[np.arange(4), np.arange(4) + 4] = dt
    kf.H = np.eye(4, 8)
    return kf


def _Q(bank: KalmanBank, slot: int, dt: float) -> np.ndarray:
    w, h = bank.x[slot, 2:4]
    sa = (np.array([w, h, w, h]) * bank.rel_accel) ** 2
    Q = np.zeros((8, 8))
    for i in range(4):
        Q[i, i] = dt ** 4 / 4 * sa[i]
        Q[i, i + 4] = Q[i + 4, i] = dt ** 3 / 2 * sa[i]
        Q[i + 4, i + 4] = dt ** 2 * sa[i]
    return Q


def test_bank_agrees_with_filterpy_step_by_step():
    rng = np.random.default_rng(0)
    bank = KalmanBank(accel=0.7, size_accel=0.2, meas=0.05, size_meas=0.08)
    dt = 1 / 7.0
    boxes = np.array([[100.0, 50, 40, 90], [300, 80, 30, 70], [10, 10, 60, 150]])
    slots = [bank.add(b) for b in boxes]
    refs = [_reference(bank, s, dt) for s in slots]
    for step in range(12):
        for s, kf in zip(slots, refs):
            kf.predict(Q=_Q(bank, s, dt))    # Q from the state before the prediction, as the bank does
        bank.predict(slots, dt)
        for s, kf in zip(slots, refs):
            np.testing.assert_allclose(bank.x[s], kf.x, rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(bank.P[s], kf.P, rtol=1e-9, atol=1e-6)
        upd = [0, 2] if step % 3 else [0, 1, 2]
        z = boxes[upd] + rng.normal(0, 2, (len(upd), 4)) + step * np.array([5.0, 1, 0.2, 0.5])
        R = bank.R([slots[i] for i in upd])
        for i, r in zip(upd, R):
            refs[i].update(boxes_to_z(z[upd.index(i)])[0], R=np.diag(r))
        bank.update([slots[i] for i in upd], z)
        for s, kf in zip(slots, refs):
            np.testing.assert_allclose(bank.x[s], kf.x, rtol=1e-9, atol=1e-7)
            np.testing.assert_allclose(bank.P[s], kf.P, rtol=1e-7, atol=1e-6)


def test_bank_reuses_slots_and_grows():
    bank = KalmanBank(capacity=2)
    a, b = bank.add([0, 0, 10, 20]), bank.add([5, 5, 10, 20])
    c = bank.add([50, 50, 10, 20])              # grows
    assert len({a, b, c}) == 3 and len(bank.x) >= 3
    bank.remove(b)
    assert bank.add([1, 1, 4, 4]) == b
    np.testing.assert_allclose(bank.boxes([c])[0], [50, 50, 10, 20])
    np.testing.assert_allclose(z_to_boxes(boxes_to_z([[1, 2, 3, 4]])), [[1, 2, 3, 4]])


def test_warp_moves_boxes_with_the_camera():
    bank = KalmanBank()
    s = bank.add([100, 100, 20, 40])
    A = np.array([[1.1, 0.0, 5.0], [0.0, 1.1, -3.0]])    # zoom in and pan
    bank.warp([s], A)
    x, y, w, h = bank.boxes([s])[0]
    cx, cy = 110.0, 120.0
    np.testing.assert_allclose([x + w / 2, y + h / 2], [1.1 * cx + 5, 1.1 * cy - 3])
    np.testing.assert_allclose([w, h], [22.0, 44.0])


def test_rts_smoother_agrees_with_filterpy():
    rng = np.random.default_rng(1)
    bank = KalmanBank()
    dt = 0.1
    s = bank.add([0.0, 0, 20, 50])
    kf = _reference(bank, s, dt)
    xp, Pp, xf, Pf, Fs, Qs, warps = [bank.x[s].copy()], [bank.P[s].copy()], [bank.x[s].copy()], [bank.P[s].copy()], [], [], [None]
    for k in range(1, 25):
        Q = _Q(bank, s, dt)
        bank.predict([s], dt)
        xp.append(bank.x[s].copy())
        Pp.append(bank.P[s].copy())
        if k % 4:                                   # every fourth frame is missed
            bank.update([s], np.array([[3.0 * k, 1.0 * k, 20, 50]]) + rng.normal(0, 1.5, (1, 4)))
        xf.append(bank.x[s].copy())
        Pf.append(bank.P[s].copy())
        Fs.append(kf.F.copy())
        Qs.append(Q)
        warps.append(None)
    xs = rts_smooth(xp, Pp, xf, Pf, warps, dt)
    # filterpy's smoother takes F_{k+1}, Q_{k+1} for the step from k to k+1
    ref, *_ = filterpy.KalmanFilter(dim_x=8, dim_z=4).rts_smoother(
        np.array(xf), np.array(Pf), Fs=np.array([Fs[0]] + Fs), Qs=np.array([Qs[0]] + Qs))
    np.testing.assert_allclose(xs, ref, rtol=1e-6, atol=1e-6)


def _texture(h: int, w: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 255, (h // 6, w // 6), dtype=np.uint8)
    return cv2.GaussianBlur(cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC), (3, 3), 0)


def test_estimate_motion_recovers_a_shift_and_ignores_excluded_boxes():
    big = _texture(400, 500)
    prev = big[50:290, 60:380]
    cur = big[47:287, 66:386]              # the camera moved: image content shifts by (-6, +3)
    A, pts = estimate_motion(prev, cur)
    assert A is not None
    np.testing.assert_allclose(A[:, :2], np.eye(2), atol=0.01)
    np.testing.assert_allclose(A[:, 2], [-6.0, 3.0], atol=0.3)
    # the inliers, followed into the next frame, give the next motion without new corners
    nxt = big[44:284, 72:392]
    A2, pts2 = estimate_motion(cur, nxt, points=pts)
    np.testing.assert_allclose(A2[:, 2], [-6.0, 3.0], atol=0.3)
    assert len(pts2) >= 0.8 * len(pts)
    # a box over the whole image leaves no background: no estimate
    assert estimate_motion(cur, nxt, exclude=[[0, 0, 320, 240]], points=pts)[0] is None
    assert estimate_motion(np.zeros((240, 320), np.uint8), np.zeros((240, 320), np.uint8))[0] is None


def test_camera_motion_is_only_estimated_where_the_camera_moves():
    big = _texture(400, 600, seed=3)
    cam = CameraMotion(fps=10, check=0.5, settle=1.0)
    still = [cam.step(big[50:290, 60:380], 0.5) for _ in range(12)]
    assert all(a is None for a in still) and not cam.moving
    moved = [cam.step(big[50:290, 60 + 4 * k:380 + 4 * k], 0.5) for k in range(1, 15)]
    assert cam.moving
    got = [a for a in moved if a is not None]
    assert len(got) >= 8
    # full-image pixels: a shift of 4 small pixels at scale 0.5 is 8 full pixels
    np.testing.assert_allclose(got[-1][0, 2], -8.0, atol=0.5)


def test_noise_estimator_recovers_both_noises_despite_outliers():
    """Boxes moved by white acceleration of known relative size (Eq. 2.10) and measured with known
    relative noise per coordinate, with heavy tails (5 % of the boxes three times as noisy: cut
    by an occluder): the second-difference moments recover the detector noise and the
    acceleration of the bulk, far from the configured priors; the plain mean of the squared
    differences (a non-robust estimate) is inflated by the tails."""
    rng = np.random.default_rng(0)
    true_sd = np.array([0.10, 0.04, 0.15, 0.06])
    true_acc = np.array([3.0, 1.0, 0.02, 0.02])
    dt = 1 / 25
    est = NoiseEstimator([0.05] * 4, [1.0, 1.0, 0.25, 0.25], dt, window=4000, horizon=1.0)
    for person in range(100):
        size = np.array([40.0, 100.0]) * rng.uniform(0.5, 2)
        x = np.r_[rng.uniform(100, 500, 2), size]
        v = np.r_[rng.normal(0, 0.5, 2) * size[1], 0, 0]
        for k in range(75):
            scale = np.r_[x[2:], x[2:]]
            a = rng.normal(0, 1, 4) * true_acc * scale
            x, v = x + v * dt + 0.5 * a * dt * dt, v + a * dt
            tail = 3.0 if rng.random() < 0.05 else 1.0
            est.observe(person, k, x + rng.normal(0, tail, 4) * true_sd * scale)
            if person % 7 == 0 and k == 30:      # a missed detection: the run starts again
                est.observe(person, k + 1000, x)
                break
        est.forget(person)
    np.testing.assert_allclose(est.sd(), true_sd, rtol=0.2)
    # the centre's acceleration is found; the sizes' is far below what 15 % and 6 % of scatter
    # let one see over the horizon (the lag-1 and lag-25 variances differ by less than their
    # sampling noise), and the estimate stays well under the centre's
    np.testing.assert_allclose(est.accel_sd()[:2], true_acc[:2], rtol=0.3)
    assert np.all(est.accel_sd()[2:] < 0.3 * true_acc[0])
    mean_based = np.sqrt(np.mean(est._d2[0, :est.n], 0) / 6)   # squared lag-1 differences
    assert np.all(mean_based > 1.2 * true_sd)
    # without data the estimates are the priors
    fresh = NoiseEstimator([0.05] * 4, [1.0] * 4, dt)
    assert np.allclose(fresh.sd(), 0.05) and np.allclose(fresh.accel_sd(), 1.0)


def test_row_medians_equal_numpy_median():
    """The noise estimator's median (no numpy.ma import) gives numpy's numbers exactly."""
    from artmotion.tracking.state import _row_medians

    rng = np.random.default_rng(3)
    for n in range(1, 30):
        a = rng.normal(size=(2, n)) * rng.uniform(0.1, 10)
        assert np.array_equal(_row_medians(a), np.median(a, axis=1))
    assert np.isnan(_row_medians(np.zeros((2, 0)))).all()


def test_a_still_camera_asks_for_its_image_only_when_it_checks():
    """The grey image may be given as a function: a still camera calls it on its check frames
    only (every ``check`` seconds), so the tracker does not convert every frame."""
    big = _texture(400, 600, seed=3)
    cam = CameraMotion(fps=10, check=0.5, settle=1.0)
    calls, frame = [], [0]

    def image():
        calls.append(frame[0])
        return big[50:290, 60:380]

    for frame[0] in range(1, 13):
        assert cam.step(image, 0.5) is None
    assert calls == [1, 6, 11] and not cam.moving
