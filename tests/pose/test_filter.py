import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.pose.filter import PoseFilter, accel_variance


def _reference_kf(z, r, q, dt=1.0):
    """Textbook Kalman recursion of Eq. 3.6-3.7 written out by hand."""
    F = np.array([[1, dt], [0, 1]])
    B = np.array([[dt**2 / 2], [dt]])
    Q = B @ B.T * q
    x = np.array([z[0], 0.0])
    P = np.diag([r[0], max(r[0], q) * 10])
    out = [z[0]]
    for t in range(1, len(z)):
        x = F @ x
        P = F @ P @ F.T + Q
        S = P[0, 0] + r[t]
        K = P[:, 0] / S
        x = x + K * (z[t] - x[0])
        P = P - np.outer(K, P[0, :])
        out.append(x[0])
    return np.array(out)


def test_filter_matches_reference_on_linear_system():
    rng = np.random.default_rng(0)
    n, q = 300, 0.01
    acc = rng.normal(0, np.sqrt(q), n)
    vel = np.cumsum(acc)
    pos = np.cumsum(vel)
    std = rng.uniform(1.0, 4.0, n)  # time-varying measurement noise (the GP variance)
    z = pos + rng.normal(0, 1, n) * std
    f = PoseFilter([q])
    m, s = f.filter(z[:, None], std[:, None])
    np.testing.assert_allclose(m[:, 0], _reference_kf(z, std**2, q), atol=1e-8)
    assert np.abs(m[:, 0] - pos).mean() < 0.6 * np.abs(z - pos).mean()
    assert np.all(s[1:, 0] < std[1:])


def test_filter_independent_per_angle_and_step_equals_batch():
    rng = np.random.default_rng(1)
    z = rng.normal(size=(50, 3)).cumsum(0)
    sd = np.full((50, 3), 0.5)
    f = PoseFilter([0.1, 1.0, 10.0])
    m, _ = f.filter(z, sd)
    f.reset()
    step = np.array([f.step(z[t], sd[t])[0] for t in range(50)])
    np.testing.assert_allclose(m, step)
    m1, _ = PoseFilter([1.0]).filter(z[:, 1:2], sd[:, 1:2])
    np.testing.assert_allclose(m[:, 1], m1[:, 0])


def test_accel_variance_of_white_noise_acceleration():
    rng = np.random.default_rng(2)
    q = 0.5
    a = rng.normal(0, np.sqrt(q), 20000)
    # the discretised model of Eq. 3.6: x += v + a/2, v += a
    x = np.zeros(len(a))
    v = 0.0
    for t in range(1, len(a)):
        x[t] = x[t - 1] + v + a[t - 1] / 2
        v += a[t - 1]
    assert abs(accel_variance(x[:, None])[0] - q) < 0.05
    # rows taken out of the sequence (a cross-validation fold) leave gaps: only runs of three
    # consecutive frames count, so the estimate does not change
    keep = np.sort(np.random.default_rng(3).choice(len(x), size=16000, replace=False))
    assert abs(accel_variance(x[keep, None], frames=keep)[0] - q) < 0.06
    assert accel_variance(x[keep, None])[0] > 3 * q  # ignoring the gaps inflates it


def _reference_rts(z, r, q):
    """The forward recursion of :func:`_reference_kf`, then the Rauch-Tung-Striebel pass backward,
    written out by hand."""
    F = np.array([[1.0, 1.0], [0.0, 1.0]])
    Q = np.array([[0.25, 0.5], [0.5, 1.0]]) * q
    x, P = np.array([z[0], 0.0]), np.diag([r[0], max(r[0], q) * 10])
    xs, Ps = [x], [P]
    for t in range(1, len(z)):
        x, P = F @ x, F @ P @ F.T + Q
        K = P[:, 0] / (P[0, 0] + r[t])
        x, P = x + K * (z[t] - x[0]), P - np.outer(K, P[0, :])
        xs.append(x)
        Ps.append(P)
    out = [xs[-1][0]]
    x, P = xs[-1], Ps[-1]
    for t in range(len(z) - 2, -1, -1):
        Pp = F @ Ps[t] @ F.T + Q
        G = Ps[t] @ F.T @ np.linalg.inv(Pp)
        x, P = xs[t] + G @ (x - F @ xs[t]), Ps[t] + G @ (P - Pp) @ G.T
        out.append(x[0])
    return np.array(out[::-1])


def test_smoother_matches_reference_and_beats_the_filter():
    rng = np.random.default_rng(3)
    n, q = 400, 0.01
    pos = np.cumsum(np.cumsum(rng.normal(0, np.sqrt(q), n)))
    std = rng.uniform(1.0, 4.0, n)
    z = pos + rng.normal(0, 1, n) * std
    f = PoseFilter([q, q])
    m, s = f.smooth(np.c_[z, -z], np.c_[std, std])
    np.testing.assert_allclose(m[:, 0], _reference_rts(z, std**2, q), atol=1e-6)
    np.testing.assert_allclose(m[:, 1], -m[:, 0], atol=1e-9)  # the angles do not mix
    fm, fs = PoseFilter([q]).filter(z[:, None], std[:, None])
    assert np.abs(m[:, 0] - pos).mean() < 0.8 * np.abs(fm[:, 0] - pos).mean()
    assert np.all(s[:, 0] <= fs[:, 0] + 1e-9) and np.allclose(s[-1, 0], fs[-1, 0])
    assert f.smooth(np.empty((0, 2)), np.empty((0, 2)))[0].shape == (0, 2)


def test_smoother_bridges_the_frames_a_track_missed():
    """Rows numbered by their frames: a gap is steps of the motion model without a measurement.
    Across 20 missed frames of a steady motion the smoother stays on it; taking the rows on either
    side of the gap for neighbours (no ``frames``) sees a jump and smears it over both sides."""
    rng = np.random.default_rng(5)
    frames = np.r_[np.arange(0, 30), np.arange(50, 80)]
    truth = 2.0 * frames
    z = truth + rng.normal(0, 1, len(frames))
    std = np.ones((len(frames), 1))
    f = PoseFilter([0.01])
    bridged = f.smooth(z[:, None], std, frames=frames)
    joined = f.smooth(z[:, None], std)
    assert np.abs(bridged[0][:, 0] - truth).max() < 3.0
    assert np.abs(joined[0][:, 0] - truth).max() > 5.0
    # consecutive frames: the same as without them
    np.testing.assert_allclose(f.smooth(z[:30, None], std[:30], frames=frames[:30])[0], f.smooth(z[:30, None], std[:30])[0])
    with pytest.raises(InputError, match="increasing"):
        f.smooth(z[:, None], std, frames=frames[::-1])


def test_fit_tunes_its_filter_on_the_calibration_rows(monkeypatch):
    """fit hands tune_filter the calibration rows (their labels, the GP's held-out predictions of
    them, their frame numbers) and keeps what it returns: the filter a user gets is the tuned one."""
    from artmotion.pose import model as M

    rng = np.random.default_rng(6)
    n = 200
    Y = np.c_[np.sin(np.arange(n) / 10.0), np.cos(np.arange(n) / 15.0)] * 20
    X = np.c_[Y / 20, rng.normal(0, 0.05, (n, 3))]
    seen = {}

    def fake(Yc, mean, std, accel, frames):
        seen.update(Y=Yc, mean=mean, std=std, frames=frames)
        return np.array([10.0, 100.0]), np.array([2.0, 3.0]), np.array([4.0, 5.0])

    monkeypatch.setattr(M, "tune_filter", fake)
    reg = M.PoseRegressor().fit(X, Y, ["a", "b"], groups=np.repeat([0, 1], n // 2))
    order, n_cal, frames = M.calibration_order(n, np.repeat([0, 1], n // 2))
    cal = order[n - n_cal:]
    np.testing.assert_array_equal(seen["Y"], Y[cal])
    np.testing.assert_array_equal(seen["frames"], frames[cal])
    assert len(seen["mean"]) == n_cal and np.abs(seen["mean"] - Y[cal]).mean() < 0.3 * np.abs(Y[cal]).mean()
    np.testing.assert_allclose(reg.accel_var_, accel_variance(Y, frames=frames) * [10, 100])
    filt = reg.make_filter()
    np.testing.assert_array_equal(filt.filter_std, [2, 3])
    np.testing.assert_array_equal(filt.smooth_std, [4, 5])


def test_tune_filter_undoes_a_measurement_variance_too_wide_for_the_filter():
    """A variance that is right for the errors: the labels' own motion prior (scale 1, or close).
    A variance calibrated for a ±3σ band of heavy-tailed errors, several times the typical error's
    (here 4×): a larger acceleration variance, so that the filter follows the measurements as much
    as they deserve, and it errs less with it than with the labels' prior. Errors that last (a
    constant offset for 40 frames at a time): the smoothed σ, which takes them as independent, is
    widened until its ±3σ band holds them, and the band holds new rows of the same kind."""
    from artmotion.pose.filter import tune_filter

    rng = np.random.default_rng(4)
    n = 1200
    Y = (30 * np.sin(np.arange(n) / 40.0))[:, None]
    accel = accel_variance(Y)
    frames = np.r_[np.arange(600), np.arange(602, 1202)]  # two sequences
    pred = Y + rng.normal(0, 5, (n, 1))
    right, wide = np.full((n, 1), 5.0), np.full((n, 1), 20.0)
    s_right, f_right, m_right = (v[0] for v in tune_filter(Y, pred, right, accel, frames))
    s_wide = tune_filter(Y, pred, wide, accel, frames)[0][0]
    assert s_right <= 3.2 and s_wide >= 10, (s_right, s_wide)
    assert f_right < 1.5 and m_right < 1.5, (f_right, m_right)  # independent errors: about Kalman's own

    def err(std, s):
        return np.abs(PoseFilter(accel * s).smooth(pred, std)[0] - Y).mean()

    assert err(wide, s_wide) < 0.9 * err(wide, 1.0)
    assert err(right, s_right) < 0.5 * np.abs(pred - Y).mean()

    def lasting():
        return Y + np.repeat(rng.normal(0, 5, n // 40), 40)[:, None] + rng.normal(0, 1, (n, 1))

    scale, f_std, m_std = tune_filter(Y, lasting(), right, accel, frames)
    assert m_std[0] > 1.5, m_std
    new = lasting()
    inside = []
    for filt in (PoseFilter(accel * scale), PoseFilter(accel * scale, filter_std=f_std, smooth_std=m_std)):
        m, s = filt.smooth(new, right)
        inside.append(np.mean(np.abs(new - m) <= 3 * s))
    assert inside[0] < 0.95 and inside[1] > 0.97, inside


def test_filter_refuses_nan_and_bad_parameters():
    m = np.cumsum(np.ones((10, 2)), 0)
    sd = np.ones((10, 2))
    bad = m.copy()
    bad[4, 0] = np.nan
    with pytest.raises(InputError, match="means contain NaN"):
        PoseFilter([1.0, 1.0]).filter(bad, sd)
    for s in (sd * np.inf, sd * np.nan, -sd):
        with pytest.raises(InputError, match="standard deviations"):
            PoseFilter([1.0, 1.0]).filter(m, s)
    with pytest.raises(InputError, match="shape of the means"):
        PoseFilter([1.0, 1.0]).filter(m, sd[:, :1])
    with pytest.raises(InputError, match="means contain NaN"):
        PoseFilter([1.0, 1.0]).step([np.nan, 0.0], [1.0, 1.0])
    for kwargs in ({"accel_var": [np.nan, 1.0]}, {"accel_var": [1.0, 0.0]}, {"accel_var": [1.0, 1.0], "dt": np.nan},
                   {"accel_var": [1.0, 1.0], "dt": 0.0}):
        with pytest.raises(InputError, match="accel_var|dt"):
            PoseFilter(**kwargs)


def test_smooth_refuses_fractional_frames_and_huge_spans():
    m, sd = np.zeros((2, 2)), np.ones((2, 2))
    with pytest.raises(InputError, match="whole numbers"):
        PoseFilter([1.0, 1.0]).smooth(m, sd, frames=[1, 2.5])
    with pytest.raises(InputError, match="span at most"):
        PoseFilter([1.0, 1.0]).smooth(m, sd, frames=[1, 10**9])
    out, _ = PoseFilter([1.0, 1.0]).smooth(m, sd, frames=[1.0, 5.0])  # whole floats are frame numbers
    assert out.shape == (2, 2)
