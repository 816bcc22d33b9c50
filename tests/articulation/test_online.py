"""Algorithm 1: online model selection on synthetic points."""

import numpy as np
import pytest

from artmotion.articulation.online import OnlineEstimator, estimate_online
from artmotion.errors import InputError


def _track(kind, n=150, noise=0.003, seed=0, dim=3):
    rng = np.random.default_rng(seed)
    s = np.linspace(0, 1, n)
    if kind == "static":
        X = np.tile([0.4, -0.2, 0.9], (n, 1))
    elif kind == "prismatic":
        X = np.array([0.1, 0.2, 0.3]) + 0.5 * s[:, None] * np.array([0.6, 0.8, 0.0])
    else:
        th = 1.5 * s
        X = np.column_stack([0.2 + 0.45 * np.cos(th), -0.1 + 0.45 * np.sin(th), 0.5 + 0 * th])
    X = X + rng.normal(0, noise, X.shape)
    return X[:, :dim]


@pytest.mark.parametrize("kind", ["static", "prismatic", "revolute"])
@pytest.mark.parametrize("seed", [0, 1])
def test_selection_converges_to_true_model(kind, seed):
    res = estimate_online(_track(kind, seed=seed))
    assert res.model == kind, res.probabilities
    assert res.probabilities[kind] > 0.75
    assert res.decided_at is not None and res.decided_at < 120
    assert not res.revised


@pytest.mark.parametrize("kind", ["static", "prismatic", "revolute"])
def test_selection_in_2d(kind):
    res = estimate_online(_track(kind, dim=2, seed=5))
    assert res.model == kind
    assert len(res.prediction[0]) == 2


def test_revolute_configuration_and_prediction():
    X = _track("revolute", n=200, noise=0.002, seed=3)
    res = estimate_online(X)
    cfg = res.configuration
    assert abs(cfg["radius"] - 0.45) < 0.01
    assert np.linalg.norm(np.array(cfg["centre"][:2]) - [0.2, -0.1]) < 0.01
    # the predicted next sample continues the arc
    th_next = 1.5 * (1 + 1 / 199)
    nxt = np.array([0.2 + 0.45 * np.cos(th_next), -0.1 + 0.45 * np.sin(th_next), 0.5])
    assert np.linalg.norm(res.prediction[0] - nxt) < 0.01
    assert res.motion.shape == (200, 1)


def test_probabilities_follow_eq_4_16():
    est = OnlineEstimator()
    X = _track("prismatic", n=40)
    for k in range(len(X)):
        est.update(X[k])
    h = np.array(est.history)
    ok = ~np.isnan(h[:, 0])
    assert np.allclose(h[ok].sum(axis=1), 1.0)
    assert np.isnan(h[:6]).all()  # nothing before min_samples


def test_too_few_samples_is_undecided():
    res = estimate_online(_track("prismatic", n=4))
    assert res.model is None and res.decided_at is None
    assert res.to_dict()["model"] == "undecided"


def test_time_must_increase():
    est = OnlineEstimator()
    est.update([0, 0, 0], 1.0)
    with pytest.raises(InputError):
        est.update([0, 0, 0], 1.0)


def test_bad_parameters():
    with pytest.raises(InputError):
        OnlineEstimator(threshold=1.5)
    with pytest.raises(InputError):
        OnlineEstimator(min_samples=1)


def _still_then_arc(n_still=60, n_move=150, noise=0.001, seed=0):
    """A gripper that holds still (door not yet moving), then opens a door of radius 0.35 m."""
    rng = np.random.default_rng(seed)
    th = np.concatenate([np.zeros(n_still), np.linspace(0, 1.2, n_move)])
    X = np.column_stack([0.35 * np.cos(th), 0.35 * np.sin(th), 0 * th])
    return X + rng.normal(0, noise, X.shape)


def test_static_is_confirmed_for_as_long_again():
    # a point that stays still: "static" passes tau at k0 and is decided only from 2 k0 on
    est = OnlineEstimator()
    X = _track("static", n=150, seed=2)
    for k in range(len(X)):
        est.update(X[k])
    h = np.nan_to_num(np.array(est.history)[:, est.names.index("static")])
    k0 = int(np.flatnonzero(h <= est.threshold)[-1] + 1)  # start of the final run above tau
    res = est.result()
    assert res.model == "static"
    assert res.decided_at == 2 * k0 and res.first_decision == ("static", 2 * k0)
    # without the confirmation the decision comes as soon as static passes tau
    raw = estimate_online(X, confirm_static=False)
    assert raw.first_decision[1] <= k0 and raw.decided_at == k0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_still_start_is_not_first_decided_static(seed):
    # still for 40 samples: "static" passes tau after ~25, the door moves before that is confirmed
    X = _still_then_arc(n_still=40, seed=seed)
    res = estimate_online(X)
    assert res.model == "revolute" and not res.revised, res.first_decision
    raw = estimate_online(X, confirm_static=False)
    assert raw.model == "revolute" and raw.first_decision[0] == "static"  # what the rule prevents


def test_fast_filter_path_matches_the_ekf_equations():
    """The scalar constant-velocity path is the EKF of Eq. 4.13-4.14 with H = J e_0^T."""
    from artmotion.articulation.models import make_model
    from artmotion.articulation.online import _ModelFilter

    X = _track("revolute", n=60, noise=0.002, seed=4)
    for name in ("prismatic", "revolute"):
        model = make_model(name).fit(X)
        f = _ModelFilter(model, 2)
        f.start(X[:10], np.ones(9), 0.005, 0.00025)
        x, P = f.x.copy(), f.P.copy()
        r2, var, dt = 0.005**2, 0.00025**2 / (model.radius**2 if name == "revolute" else 1.0), 1.0
        F = np.array([[1.0, dt], [0.0, 1.0]])
        B = np.array([0.5 * dt * dt, dt])
        for z in X[10:]:
            ll = f.step(z, dt, 0.005, 0.00025)
            x = F @ x
            P = F @ P @ F.T + var * np.outer(B, B)
            H = np.column_stack([model.jacobian1(x[0]), np.zeros(3)])
            y = z - model.predict1(x[0])
            S = H @ P @ H.T + r2 * np.eye(3)
            K = P @ H.T @ np.linalg.inv(S)
            x, P = x + K @ y, P - K @ H @ P
            expect = -0.5 * (3 * np.log(2 * np.pi) + np.linalg.slogdet(S)[1] + y @ np.linalg.solve(S, y))
            assert abs(ll - expect) < 1e-6 * max(1.0, abs(expect))
        assert np.allclose(f.x, x, rtol=1e-7, atol=1e-10) and np.allclose(f.P, P, rtol=1e-6, atol=1e-14)
