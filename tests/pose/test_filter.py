import numpy as np

from artmotion.pose.model import PoseFilter, accel_variance


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
