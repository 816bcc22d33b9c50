"""Taylor models of any order (Eq. 4.12-4.15) and the order comparison of Fig. 4.5."""

import math

import numpy as np
import pytest
from scipy.linalg import expm

from artmotion.articulation.temporal import compare_orders, filter_order, pendulum
from artmotion.filters import taylor_transition, white_noise_input


@pytest.mark.parametrize("order", [1, 2, 3, 4, 6])
@pytest.mark.parametrize("dt", [0.01, 0.5, 2.0])
def test_discrete_a_b_match_matrix_exponential(order, dt):
    Ac = np.eye(order, k=1)
    Bc = np.zeros((order, 1))
    Bc[-1, 0] = 1.0
    # Van Loan: expm([[Ac, Bc], [0, 0]] dt) = [[A, int_0^dt expm(Ac s) ds Bc], [0, I]]
    Mc = np.zeros((order + 1, order + 1))
    Mc[:order, :order] = Ac
    Mc[:order, order:] = Bc
    E = expm(Mc * dt)
    assert np.allclose(taylor_transition(order, dt), E[:order, :order], atol=1e-12)
    assert np.allclose(white_noise_input(order, dt), E[:order, order:], atol=1e-12)


def test_taylor_prediction_is_exact_for_polynomials():
    # an order-n model predicts a polynomial of degree n-1 exactly (Eq. 4.15)
    t0, dt = 0.3, 0.7
    coeffs = [1.0, -2.0, 0.5]  # q = 1 - 2t + 0.5 t^2
    q = lambda t: coeffs[0] + coeffs[1] * t + coeffs[2] * t * t
    state = np.array([q(t0), coeffs[1] + 2 * coeffs[2] * t0, 2 * coeffs[2]])
    assert math.isclose((taylor_transition(3, dt) @ state)[0], q(t0 + dt), rel_tol=1e-12)


def test_higher_order_follows_pendulum_better():
    t, q, truth = pendulum(duration=6.0, dt=0.02, noise_std=0.01, seed=1)
    res = compare_orders(q, t, orders=(1, 2, 3), obs_var=1e-4, truth=truth, horizon=10)
    # order 1 (angle only) cannot predict ahead; velocity/acceleration states can
    assert res[2]["rmse_ahead"] < 0.6 * res[1]["rmse_ahead"]
    assert res[3]["rmse_ahead"] < 0.6 * res[1]["rmse_ahead"]
    assert res[2]["loglik"] > res[1]["loglik"]


def test_filter_order_tracks_constant_velocity():
    t = np.arange(50.0)
    q = 0.1 * t
    r = filter_order(q, t, 2, 1e-8, 1e-6)
    assert abs(r["filtered"][-1] - q[-1]) < 1e-3
    assert abs(r["predicted"][-1] - q[-1]) < 1e-3
