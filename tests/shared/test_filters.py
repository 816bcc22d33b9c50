import math

import numpy as np
import pytest
from scipy.integrate import quad_vec
from scipy.linalg import expm

from artmotion.filters import KalmanFilter, constant_velocity, gaussian_loglik, taylor_model
from artmotion.filters.models import taylor_transition, white_noise_input


@pytest.mark.parametrize("order", [1, 2, 3, 4, 6])
@pytest.mark.parametrize("dt", [0.04, 0.5, 1.0])
def test_taylor_matrices_equal_matrix_exponential(order, dt):
    Ac = np.eye(order, k=1)  # Eq. 4.12
    Bc = np.zeros((order, 1))
    Bc[-1, 0] = 1.0
    np.testing.assert_allclose(taylor_transition(order, dt), expm(Ac * dt), atol=1e-12)
    B, _ = quad_vec(lambda mu: expm(Ac * mu) @ Bc, 0.0, dt)
    np.testing.assert_allclose(white_noise_input(order, dt), B, atol=1e-10)


def test_constant_velocity_is_eq_2_10():
    F, Q, H = constant_velocity(0.5, accel_var=2.0, dims=2)
    A = np.array([[1, 0.5], [0, 1]])
    np.testing.assert_allclose(F, np.kron(np.eye(2), A))
    B = np.array([[0.125], [0.5]])
    np.testing.assert_allclose(Q[:2, :2], 2.0 * B @ B.T)
    np.testing.assert_allclose(H, [[1, 0, 0, 0], [0, 0, 1, 0]])
    F2, Q2 = taylor_model(2, 0.5, [1.0, 3.0], dims=2)
    assert np.isclose(Q2[2, 2] / Q2[0, 0], 3.0)


def test_scalar_kalman_matches_closed_form():
    # Static scalar with prior N(0, 4) and measurements of noise variance 1: the posterior after k
    # measurements is the precision-weighted mean.
    kf = KalmanFilter(x=[0.0], P=[[4.0]], F=[[1.0]], Q=[[0.0]], H=[[1.0]], R=[[1.0]])
    zs = [1.0, 2.0, 0.5]
    for z in zs:
        kf.predict()
        kf.update(z)
    prec = 1 / 4 + len(zs)
    assert np.isclose(kf.P[0, 0], 1 / prec)
    assert np.isclose(kf.x[0], sum(zs) / prec)


def test_kalman_tracks_known_linear_system():
    rng = np.random.default_rng(0)
    F, Q, H = constant_velocity(1.0, accel_var=1e-4, dims=1)
    x_true = np.array([0.0, 1.5])
    kf = KalmanFilter(x=[0, 0], P=np.eye(2) * 100, F=F, Q=Q, H=H, R=[[0.25]])
    nis = []
    for _ in range(200):
        x_true = F @ x_true
        z = H @ x_true + rng.normal(0, 0.5, 1)
        kf.predict()
        y, S = kf.innovation(z)
        nis.append(float(y @ np.linalg.solve(S, y)))
        kf.update(z)
    assert abs(kf.x[1] - 1.5) < 0.05
    assert 0.7 < np.mean(nis[20:]) < 1.3  # consistent: NIS averages to the measurement dimension


def test_time_varying_R_and_loglik():
    kf = KalmanFilter(x=[0.0], P=[[1.0]], F=[[1.0]], Q=[[0.0]], H=[[1.0]], R=[[1.0]])
    ll = kf.update([1.0], R=[[3.0]])
    assert np.isclose(ll, -0.5 * (math.log(2 * math.pi * 4.0) + 1.0 / 4.0))
    assert np.isclose(kf.x[0], 0.25)
    S = np.array([[2.0, 0.3], [0.3, 1.0]])
    y = np.array([0.4, -0.2])
    ref = -0.5 * (2 * math.log(2 * math.pi) + math.log(np.linalg.det(S)) + y @ np.linalg.solve(S, y))
    assert np.isclose(gaussian_loglik(y, S), ref)


def _cv_filter():
    F, Q, H = constant_velocity(1.0, 1.0, dims=1)
    return KalmanFilter([0.0, 0.0], np.eye(2), F, Q, H, [[1.0]])


def test_kalman_filter_refuses_mismatched_shapes_and_negative_variances():
    from artmotion.errors import InputError

    F, Q, H = constant_velocity(1.0, 1.0, dims=1)
    with pytest.raises(InputError, match="z must hold 1 value"):
        _cv_filter().update([1.0, 2.0])
    with pytest.raises(InputError, match="z contains NaN"):
        _cv_filter().update([np.nan])
    with pytest.raises(InputError, match=r"P must have shape \(3, 3\)"):
        KalmanFilter([0.0, 0.0, 0.0], np.eye(2), F, Q, H, [[1.0]])
    with pytest.raises(InputError, match=r"P must have shape \(2, 2\)"):
        KalmanFilter([0.0, 0.0], np.eye(3), F, Q, H, [[1.0]])
    with pytest.raises(InputError, match="R has a negative variance"):
        KalmanFilter([0.0, 0.0], np.eye(2), F, Q, H, [[-1.0]])
    with pytest.raises(InputError, match="R must be a non-negative variance"):
        _cv_filter().update([1.0], R=-1.0)
    with pytest.raises(InputError, match=r"R must have shape \(1, 1\)"):
        _cv_filter().update([1.0], R=np.eye(2))
    kf = _cv_filter()
    kf.x = np.zeros(3)  # a state replaced by hand that no longer fits P
    with pytest.raises(InputError, match=r"P must have shape \(3, 3\)"):
        kf.update([1.0])
    kf = _cv_filter()
    kf.P = np.eye(3)
    with pytest.raises(InputError, match="P must have shape"):
        kf.predict()


def test_constant_velocity_refuses_a_variance_count_other_than_dims():
    from artmotion.errors import InputError

    with pytest.raises(InputError, match="one per axis"):
        constant_velocity(1.0, [1.0, 2.0, 3.0], dims=2)
    F, Q, H = constant_velocity(1.0, [1.0, 2.0], dims=2)
    assert np.isclose(Q[2, 2] / Q[0, 0], 2.0)
