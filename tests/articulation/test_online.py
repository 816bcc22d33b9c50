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
    if kind != "revolute":  # a short arc is a line until it bends by more than the noise
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
def test_still_start_then_motion(seed):
    # still for 40 samples: static while still (and confirmed), revolute soon after the door moves
    X = _still_then_arc(n_still=40, seed=seed)
    res = estimate_online(X)
    assert res.model == "revolute" and res.decided_at < 40 + 60, (res.first_decision, res.decided_at)
    assert res.first_decision[0] in ("static", "revolute")


def test_along_track_filter_is_the_kalman_filter():
    """The scalar constant-velocity filter along the motion is Eq. 4.13-4.14 with H = [1, 0]; the
    geometric term is the Gaussian density of the residual off the line (nu=None)."""
    from artmotion.articulation.models import make_model
    from artmotion.articulation.online import _ModelFilter

    X = _track("prismatic", n=60, noise=0.002, seed=4)
    T = np.arange(60.0)
    f = _ModelFilter(make_model("prismatic").fit(X), 2, nu=None, dim=3)
    f.sigma = f.sigma_along = 0.002
    f.accel = 0.0004
    geo, along = f.start(X, T)
    s = f.model.motion(X)[:, 0]
    E = X - f.model.predict(s[:, None])
    r2 = 0.002**2
    assert abs(geo - np.sum(-0.5 * (2 * np.log(2 * np.pi * r2)) - 0.5 * (E**2).sum(1) / r2)) < 1e-6 * abs(geo)
    x = np.array([s[1], s[1] - s[0]])          # at the second sample (the loop goes on from the third)
    P = np.array([[r2, r2], [r2, 2 * r2]])
    F = np.array([[1.0, 1.0], [0.0, 1.0]])
    B = np.array([0.5, 1.0])
    expect = 0.0
    for k in range(2, 60):
        x = F @ x
        P = F @ P @ F.T + 0.0004**2 * np.outer(B, B)
        S = P[0, 0] + r2
        y = s[k] - x[0]
        expect += -0.5 * (np.log(2 * np.pi * S) + y * y / S)
        K = P[:, 0] / S
        x, P = x + K * y, P - np.outer(K, P[0])
    assert abs(along - expect) < 1e-6 * abs(expect)
    assert np.allclose(f.x[0], x) and np.allclose(f.P[0], P, rtol=1e-6, atol=1e-14)


def _arc(n=40):
    a = np.linspace(0, 1.2, n)
    return np.c_[0.5 * np.cos(a), 0.5 * np.sin(a), np.zeros(n)]


@pytest.mark.parametrize("kwargs, match", [
    ({"noise": 0.0}, "noise"), ({"noise": float("nan")}, "noise"), ({"accel": float("nan")}, "accel"),
    ({"temperature": float("inf")}, "temperature"), ({"nu": 0}, "nu"), ({"order": 0}, "order"),
    ({"order": 100}, "order"), ({"models": ("foo",)}, "models"), ({"models": ()}, "models"),
    ({"dim": 5}, "dim"), ({"t": np.arange(10.0)}, "one time stamp per sample"),
    ({"t": np.r_[np.arange(39.0), np.inf]}, "finite"), ({"t": np.arange(40.0) * 1e-300}, "steps between"),
    ({"t": np.arange(40.0) * 1e300}, "steps between"),
])
def test_estimate_online_refuses_misuse(kwargs, match):
    with pytest.raises(InputError, match=match):
        estimate_online(_arc(), **kwargs)


def test_estimate_online_refuses_huge_values_and_update_checks_each_sample():
    with pytest.raises(InputError, match="magnitude"):
        estimate_online(_arc() * 1e300)
    X = _arc()
    est = OnlineEstimator()
    for z in X[:10]:
        est.update(z)
    with pytest.raises(InputError, match="finite"):
        est.update([np.nan, 0, 0])
    with pytest.raises(InputError, match="2-D or 3-D point"):
        est.update([1.0, 0, 0, 0])
    est.update(X[10])  # the refused samples left no trace
    assert len(est.X) == 11 and np.all(np.isfinite(est.X))


@pytest.mark.parametrize("decimals, n", [(4, 60), (9, 60), (3, 60), (2, 300)])
def test_a_drawer_along_an_axis_written_with_few_decimals_is_prismatic(decimals, n):
    """Noise-free positions along the x axis: nothing off the line, so its noise fell to 1e-9 and
    (1) the filter along the line, started one sample behind, took every later sample for an
    outlier; (2) the rounding of the positions was scored against that noise. Both called the
    drawer static with probability 1."""
    from artmotion.articulation.online import resolution

    s = np.linspace(0.0, 0.4, n)
    X = np.round(np.c_[0.2 + s, np.full(n, -0.3), np.full(n, 0.1)], decimals)
    assert resolution(X) == pytest.approx(10.0**-decimals)
    res = estimate_online(X)
    assert res.model == "prismatic" and res.probabilities["prismatic"] > 0.99
    assert resolution(np.random.default_rng(0).random(50)) == 0.0


@pytest.mark.parametrize("kind", ["drawer", "door"])
@pytest.mark.parametrize("scale", [1e-6, 1e-9, 1e6])
def test_the_answer_does_not_depend_on_the_unit(kind, scale):
    """Micrometres written in metres all lay within the absolute tolerance of the decimal grid's
    coarsest step, so their 'rounding' (a step of 1) became the noise: static at any radius prior."""
    from artmotion.articulation.online import resolution
    from artmotion.articulation.synthetic import synthetic_log

    P, truth = synthetic_log(kind, seed=1)
    assert resolution(P * scale) <= 1e-12 * scale       # (at most the float precision of the values)
    base = estimate_online(P)
    res = estimate_online(P * scale, radius_range=(0.05 * scale, 1.0 * scale))
    assert base.model == truth and res.model == truth, res.probabilities
    assert abs(res.probabilities[truth] - base.probabilities[truth]) < 1e-3


@pytest.mark.parametrize("order", [2, 3, 4, 5, 6])
def test_every_order_answers_on_noise_free_tracks(order):
    """Orders 4-6 started every derivative beyond the velocity with a vague prior: against a clean
    track's noise the filter's covariance went negative (an internal error, or a moving line called
    static and a circle's prediction not finite)."""
    n = 60
    s = np.linspace(0.0, 0.4, n)
    line = np.c_[s, 2 * s, np.zeros(n)]
    th = np.linspace(0.0, 1.2, n)
    arc = np.c_[0.5 * np.cos(th), 0.5 * np.sin(th), np.zeros(n)]
    assert estimate_online(line, order=order).model == "prismatic"
    res = estimate_online(arc, order=order)
    assert res.model == "revolute" and np.all(np.isfinite(res.prediction))


@pytest.mark.parametrize("offset", [(5e4, 5.4e6, 300.0), (1e9, -1e9, 0.0)])
def test_an_offset_of_the_coordinates_does_not_change_the_answer(offset):
    """The same 2 cm drawer track (0.05 mm noise) in coordinates far from the origin (UTM metres):
    the noise floor follows the coordinates' float precision, not their size (it was 1e-9 of
    their magnitude: 5.4 mm at 5.4e6 m, and the drawer came out undecided between line and arc)."""
    rng = np.random.default_rng(3)
    d = np.linspace(0.0, 0.02, 200)
    X = np.column_stack([0.3 + d, np.full(200, 0.1), np.full(200, 0.5)]) + rng.normal(0.0, 5e-5, (200, 3))
    here, there = estimate_online(X), estimate_online(X + np.array(offset))
    assert here.model == there.model == "prismatic"
    for name, p in here.probabilities.items():
        assert there.probabilities[name] == pytest.approx(p, abs=1e-3)


def test_a_pose_log_far_from_the_origin_keeps_its_answer():
    """A pose log's noise floor follows the positions' float precision too: a 2 cm slide with
    0.2 mm noise, 5e6 m from the origin, was scored against 5 mm of noise and called static."""
    from artmotion.articulation.rigid import pose_noise
    from artmotion.articulation.trajectory import fit_poses

    rng = np.random.default_rng(4)
    n = 100
    P = np.column_stack([np.linspace(0.0, 0.02, n), np.zeros(n), np.zeros(n)]) + rng.normal(0.0, 2e-4, (n, 3))
    Q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    off = np.array([512345.0, 5412345.0, 300.0])
    assert pose_noise(P + off, Q)[0] == pytest.approx(pose_noise(P, Q)[0], rel=1e-3)
    assert fit_poses(P, Q)["model"] == fit_poses(P + off, Q)["model"] == "prismatic"


def test_a_quaternion_and_its_negative_are_one_rotation():
    """A log whose quaternions flip sign (q and -q, the same orientation) has the angular noise of
    one that does not: the flips read as rounding of values 2 apart (0.29 rad) before."""
    from artmotion.articulation.rigid import pose_noise

    n = 40
    P = np.column_stack([np.linspace(0.0, 0.4, n), np.zeros(n), np.zeros(n)])
    Q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    flipped = Q * np.where(np.arange(n) % 3 == 1, -1.0, 1.0)[:, None]
    assert pose_noise(P, flipped)[1] == pose_noise(P, Q)[1] < 1e-6


@pytest.mark.parametrize("glitch, n", [((1.0, 0.0, 0.0), 100), ((0.0, 0.0, 2.0), 100), ((0.0, 0.0, 2.0), 99)])
def test_one_glitch_does_not_flip_the_answer(glitch, n):
    """One sample a metre or two off (a tracker's glitch) among 100 on a door's arc: each re-fit
    re-weighted from a plain least-squares fit stayed in the Student-t optimum the glitch drags, and
    the door was called a line (0.98). With 99 samples the final configuration is fitted after the
    last re-fit (the radius came out 1.006 m when that fit started plain)."""
    rng = np.random.default_rng(5)
    th = np.linspace(0.0, 1.4, 100)[:n]
    X = np.column_stack([1.0 + 0.4 * np.cos(th), 2.0 + 0.4 * np.sin(th), np.full(n, 0.5)])
    X += rng.normal(0.0, 1e-3, X.shape)
    X[50] += glitch
    res = estimate_online(X)
    assert res.model == "revolute" and res.probabilities["revolute"] > 0.9, res.probabilities
    assert res.configuration["radius"] == pytest.approx(0.4, abs=0.01)


def test_fitted_is_the_robust_fit_on_a_copy():
    """``fitted(name)`` is what a caller acting on the decision takes (SLAM's joint): the robust fit
    to every sample, on a copy, so that neither the estimator's own filters nor its answer move."""
    rng = np.random.default_rng(5)
    th = np.linspace(0.0, 1.4, 99)
    X = np.column_stack([1.0 + 0.4 * np.cos(th), 2.0 + 0.4 * np.sin(th), np.full(99, 0.5)])
    X += rng.normal(0.0, 1e-3, X.shape)
    X[50] += (1.0, 0.0, 0.0)
    est = OnlineEstimator()
    for x in X:
        est.update(x)
    own = [(f, f.model.radius if f.model.name == "revolute" else None) for f in est.filters]
    before = est.result().configuration
    f = est.fitted("revolute")
    assert all(f is not g and f.model is not g.model for g, _ in own)
    assert f.model.radius == pytest.approx(0.4, abs=0.01)
    assert [(g, g.model.radius if g.model.name == "revolute" else None) for g in est.filters] == own
    assert est.result().configuration == before
    with pytest.raises(ValueError, match="no fitted model"):
        est.fitted("free")


def test_online_update_refuses_a_time_stamp_given_as_text_or_a_bool_and_a_complex_point():
    from artmotion.errors import InputError

    from decimal import Decimal

    est = OnlineEstimator()
    for t in ("1.5", True, np.bool_(False), b"2", 1 + 0j, [1.5], np.array("1", dtype=object)):
        with pytest.raises(InputError, match=r"a time stamp must be a \(real\) number"):
            est.update([0.0, 0.0, 0.0], t)
    with pytest.raises(InputError, match="an observation must be an array of numbers"):
        est.update([1 + 2j, 0.0, 0.0], 1.0)
    for k, t in enumerate((np.float32(1.0), np.array(2.0), Decimal("3"), 4)):     # real numbers of any kind
        est.update([0.0, 0.0, 0.0], t)
        assert est._n == k + 1
