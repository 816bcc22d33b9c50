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
