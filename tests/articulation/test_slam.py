"""EKF SLAM and Articulated EKF SLAM (Sections 4.6-4.7, Algorithm 2)."""

import math

import numpy as np
import pytest

from artmotion.articulation.slam import (
    EKFSlam,
    make_world,
    monte_carlo,
    motion_model,
    observe,
    pose_errors,
    run_slam,
    simulate,
)
from artmotion.articulation.slam.evaluate import nees
from artmotion.articulation.slam.landmarks import LandmarkModels
from artmotion.articulation.slam.world import WORLDS, make_scenario
from artmotion.errors import InputError


@pytest.mark.parametrize("u", [(1.0, 0.3), (0.5, -0.2), (1.0, 0.0)])
def test_motion_jacobians_match_finite_differences(u):
    x = np.array([1.0, -2.0, 0.4])
    dt, h = 0.1, 1e-6
    _, Gx, Gu = motion_model(x, u, dt)
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        fd = (motion_model(x + e, u, dt)[0] - motion_model(x - e, u, dt)[0]) / (2 * h)
        assert np.allclose(fd, Gx[:, k], atol=1e-6)
    for k in range(2):
        e = np.zeros(2)
        e[k] = h
        up, um = np.add(u, e), np.subtract(u, e)
        if u[1] == 0.0 and k == 1:  # Eq. 4.21 branch: compare with a small non-zero omega
            up, um = np.array([u[0], 2e-6]), np.array([u[0], 1e-6])
            fd = (motion_model(x, up, dt)[0] - motion_model(x, um, dt)[0]) / 1e-6
            assert np.allclose(fd, Gu[:, k], atol=1e-4)
            continue
        fd = (motion_model(x, up, dt)[0] - motion_model(x, um, dt)[0]) / (2 * h)
        assert np.allclose(fd, Gu[:, k], atol=1e-6)


def test_observation_jacobians_match_finite_differences():
    x = np.array([1.0, -2.0, 0.4])
    m = np.array([4.0, 1.0])
    h = 1e-6
    _, Hx, Hm = observe(x, m)
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        fd = (observe(x + e, m)[0] - observe(x - e, m)[0]) / (2 * h)
        assert np.allclose(fd, Hx[:, k], atol=1e-6)
    for k in range(2):
        e = np.zeros(2)
        e[k] = h
        fd = (observe(x, m + e)[0] - observe(x, m - e)[0]) / (2 * h)
        assert np.allclose(fd, Hm[:, k], atol=1e-6)


@pytest.mark.parametrize("backend", ["ekf", "articulated"])
def test_slam_is_consistent_on_a_static_world(backend):
    """Average robot-pose NEES over runs stays within the chi^2 95 % band (3 dof x runs)."""
    from scipy.stats import chi2

    runs, steps = 8, 250
    values = []
    for r in range(runs):
        world = make_world(42, 0, 0, seed=r)
        sim = simulate(world, steps, seed=100 + r)
        out = run_slam(sim, backend)
        values.append(nees(out["poses"], out["covs"], sim["poses"]))
    values = np.array(values)
    lo, hi = chi2.ppf([0.025, 0.975], 3 * runs) / runs
    mean_t = values.mean(axis=0)
    assert lo < values.mean() < hi
    assert np.mean((mean_t > lo) & (mean_t < hi)) > 0.8


def test_new_landmarks_enter_at_once_unless_delayed():
    sim = simulate(make_world(42, 1, 1, seed=3), 30, seed=4)
    first = {int(i) for i in sim["observations"][0][0]}
    for delayed, expect in ((False, first), (True, set())):
        out = run_slam(sim, "articulated", delayed=delayed)
        f = out["filter"]
        entered = {i for i, k in f.decided_at.items() if k == 1}  # the first update follows one predict
        assert entered == expect


@pytest.mark.parametrize("articulated", [False, True])
def test_bad_controls_and_sightings_are_refused_before_the_state_is_touched(articulated):
    """A NaN or infinite control or sighting, or ids and sightings of different lengths, used to
    poison the whole state (a landmark at NaN, then a NaN pose) or be cut short silently."""
    f = EKFSlam(np.zeros(3), 0.1, [0.1] * 4, 0.1, 0.01, 10, articulated=articulated)
    f.predict([1.0, 0.1])
    f.update([0], [[5.0, 0.1]])
    state = (f.mu.copy(), f.P.copy(), f.n, dict(f.kinds), f.k)
    bad_updates = [([0], [[math.nan, 0.1]]), ([1], [[math.inf, 0.1]]), ([0], [[5.0, -math.inf]]),
                   ([0, 1], [[5.0, 0.1]]), ([0], [[5.0, 0.1], [6.0, 0.2]]), ([0], [[5.0, 0.1, 2.0]]),
                   ([math.nan], [[5.0, 0.1]]), ([0.5], [[5.0, 0.1]])]
    for ids, zs in bad_updates:
        with pytest.raises(InputError, match="sighting|landmark ids"):
            f.update(ids, zs)
    for u in ([math.nan, 0.1], [1.0, math.inf], [1.0], [1.0, 0.1, 0.0], "vw"):
        with pytest.raises(InputError, match="a control must be two finite numbers"):
            f.predict(u)
    np.testing.assert_array_equal(f.mu, state[0])
    np.testing.assert_array_equal(f.P, state[1])
    assert (f.n, f.kinds, f.k) == state[2:]
    f.predict(np.array([1.0, 0.1]))  # and the filter goes on as before
    f.update(np.array([0]), np.array([[5.0, 0.1]]))
    f.update([], [])
    assert np.isfinite(f.pose).all() and np.isfinite(f.P[:f.n, :f.n]).all()


@pytest.mark.parametrize("name", list(WORLDS))
def test_named_worlds(name):
    world = make_scenario(name, seed=5)
    kinds = np.array(world.kinds)
    sim = simulate(world, WORLDS[name][1], seed=6)
    L = sim["landmarks"]
    moved = np.ptp(L, axis=0).max(axis=1)
    assert np.all(moved[kinds == "static"] == 0) and np.all(moved[kinds != "static"] > 0.3)
    assert (kinds != "static").sum() >= (2 if name == "table4.2" else 15)
    if name == "moving-only":  # a stretch of the loop with no static landmark in view
        seen_static = np.array([np.any(kinds[ids] == "static") for ids, _ in sim["observations"]])
        assert 0.2 < 1 - seen_static.mean() < 0.8
    with pytest.raises(InputError):
        make_scenario("nowhere")


def test_articulated_slam_identifies_moving_landmarks():
    """Table 4.2 world, 4 runs: the moving landmarks end with their own joint, the static ones
    static; a moving landmark in the state as such follows the truth."""
    right, static_ok, tracked = [], [], []
    for s in range(4):
        world = make_scenario("table4.2", seed=1000 * s)
        sim = simulate(world, 600, seed=1000 * s + 1)
        cfg = sim["config"]
        f = EKFSlam(sim["poses"][0], sim["dt"], cfg.alphas, cfg.range_std, cfg.bearing_std, 42, articulated=True)
        for k, u in enumerate(sim["controls"]):
            f.predict(u)
            ids, z = sim["observations"][k]
            f.update(ids, z)
            for i in (40, 41):
                if i in ids and f.kinds.get(i) == world.kinds[i]:
                    tracked.append(np.linalg.norm(f.landmark_positions()[i] - sim["landmarks"][k + 1][i]))
        right += [f.kinds.get(i) == world.kinds[i] for i in (40, 41)]
        static_ok += [f.kinds.get(i, "static") == "static" for i in range(40)]
    assert np.mean(right) >= 0.75 and np.mean(static_ok) > 0.95
    assert len(tracked) >= 20 and np.median(tracked) < 0.6


def test_articulated_beats_ekf_with_moving_landmarks():
    res = monte_carlo(runs=3, steps=500, seed=7, backends=("articulated", "ekf", "articulated_delayed"))
    a, e, d = res["articulated"], res["ekf"], res["articulated_delayed"]
    assert a["translation_error"]["mean"] < 0.7 * e["translation_error"]["mean"]
    assert a["rotation_error"]["mean"] < e["rotation_error"]["mean"]
    # no delay for the static majority: better than the thesis's Algorithm 2 and consistent
    assert a["translation_error"]["mean"] < d["translation_error"]["mean"]
    assert a["nees"]["mean"] < 6.0  # the robot pose's NEES has mean 3 when consistent
    assert a["translation_error"]["low"] <= a["translation_error"]["mean"] <= a["translation_error"]["high"]


def test_pose_errors_zero_for_perfect_estimate():
    p = np.column_stack([np.arange(20.0), np.zeros(20), np.linspace(0, 1, 20)])
    err = pose_errors(p, p)
    assert err["translation_error"] == 0 and err["rotation_error"] == 0
    q = p.copy()
    q[:, 0] += 1.0  # a constant offset changes absolute but not relative errors
    assert pose_errors(q, p)["translation_error"] < 1e-12
    assert math.isclose(pose_errors(q, p)["absolute_translation_error"], 1.0)


def test_a_rejected_decision_is_learnt_afresh():
    """A door decided static while it stood still swings open: its sightings fail the gate, it leaves
    the state, Algorithm 1 learns it again and it comes back as revolute."""
    rng = np.random.default_rng(2)
    x = np.zeros(3)  # the robot stands still, looking along +x, among static landmarks
    static = np.column_stack([np.linspace(3, 8, 8), np.tile([-3.0, 3.0], 4)])
    hinge, r = np.array([5.0, 0.0]), 1.0
    f = EKFSlam(x, 0.1, (0.05, 0.005, 0.005, 0.05), 0.1, math.radians(1), 9, articulated=True)
    kinds = []
    for k in range(300):
        a = 0.0 if k < 100 else 0.8 * (1 - math.cos(0.05 * (k - 100)))  # still, then opening and closing
        lm = np.vstack([static, hinge + r * np.array([math.cos(a), math.sin(a)])])
        z = np.array([observe(x, m)[0] for m in lm]) + rng.normal(0, [0.1, math.radians(1)], (len(lm), 2))
        f.predict((0.0, 0.0))
        f.update(np.arange(len(lm)), z)
        kinds.append(f.kinds.get(8))
    assert "static" in kinds[:100]
    assert any(j == 8 and kind == "static" for j, _, kind in f.reverted)
    assert kinds[-1] == "revolute"


def test_the_gate_catches_a_slow_drift_sooner_with_the_sum_of_innovations():
    """A cart creeping 3 cm a step along the line of sight (the range's noise is 10 cm) passes the
    gate sighting by sighting until the static estimate has fallen far behind it; the sum of its
    last three innovations fails sooner, so it leaves the state sooner (5 runs). The static
    landmarks around it stay (at most one exit among the 40 of the 5 runs)."""
    x = np.zeros(3)
    static = np.column_stack([np.linspace(3, 8, 8), np.tile([-3.0, 3.0], 4)])
    first, false = {}, {}
    for window in (0, 3):
        first[window], false[window] = [], 0
        for seed in range(5):
            rng = np.random.default_rng(seed)
            f = EKFSlam(x, 0.1, (0.05, 0.005, 0.005, 0.05), 0.1, math.radians(1), 9, gating=True,
                        drift_window=window)
            for k in range(60):
                lm = np.vstack([static, [4.0 + 0.03 * k, 0.0]])
                z = np.array([observe(x, m)[0] for m in lm]) + rng.normal(0, [0.1, math.radians(1)], (len(lm), 2))
                f.predict((0.0, 0.0))
                f.update(np.arange(len(lm)), z)
            exits = {j: k for j, k, _ in reversed(f.reverted)}   # each landmark's first exit
            first[window].append(exits.get(8, 60))
            false[window] += len(set(exits) - {8})
    assert np.mean(first[3]) < np.mean(first[0]) - 3
    assert false[0] == 0 and false[3] <= 1


@pytest.mark.parametrize("seed", range(4))
def test_a_decided_joint_is_fitted_robustly(seed):
    """The joint that Algorithm 1's decision hands to the filter is fitted as Algorithm 1 fits it:
    one sighting 1 m off among a swinging door's does not drag the hinge (a plain least-squares
    re-fit put it 0.3-1.2 m away)."""
    rng = np.random.default_rng(seed)
    models = LandmarkModels(dt=0.1)
    hinge, r = np.array([2.0, 1.0]), 1.0
    for k in range(200):
        m = hinge + r * np.array([math.cos(0.1 * k), math.sin(0.1 * k)]) + rng.normal(0, 0.03, 2)
        if k == 5:
            m = m + [1.0, 0.0]
        decision = models.observe(0, m, np.eye(2) * 0.03**2, k)
        if decision is not None:
            break
    assert decision is not None and decision.kind == "revolute"
    assert np.linalg.norm(decision.joint.origin - hinge) < 0.15
    assert abs(decision.joint.radius - r) < 0.15


def test_gate_threshold_is_the_chi2_quantile():
    from scipy.stats import chi2

    from artmotion.articulation.slam.ekf import gate_threshold

    for p in (0.001, 0.01, 0.05):
        assert gate_threshold(p) == pytest.approx(chi2.ppf(1 - p, 2))
    with pytest.raises(ValueError):
        gate_threshold(0.0)


@pytest.mark.parametrize("kind", ["prismatic", "revolute"])
def test_shaped_joint_position_and_jacobian(kind):
    """A joint moved by ``(dx, dy, de)``: no move is the joint itself; the Jacobian matches finite
    differences."""
    from artmotion.articulation.slam.landmarks import Joint

    if kind == "prismatic":
        j = Joint("prismatic", np.array([1.0, 2.0]), np.array([0.6, 0.8]))
    else:
        j = Joint("revolute", np.array([1.0, 2.0]), radius=1.5)
    q = 0.7
    m, J = j.position_shaped(q, np.zeros(3))
    assert np.allclose(m, j.position(q)[0]) and np.allclose(J[:, 0], j.position(q)[1])
    x, h = np.array([q, 0.1, -0.2, 0.05]), 1e-6
    f = lambda v: j.position_shaped(v[0], v[1:])[0]  # noqa: E731
    _, J = j.position_shaped(x[0], x[1:])
    for k in range(4):
        e = np.zeros(4)
        e[k] = h
        assert np.allclose((f(x + e) - f(x - e)) / (2 * h), J[:, k], atol=1e-6)


def test_shape_covariance_matches_the_scatter_of_fits():
    """The Gauss-Newton covariance of a fitted line's angle and offset, and of a circle's radius,
    agrees with the scatter of least-squares fits to noisy points (within 15 %)."""
    from scipy.optimize import least_squares

    from artmotion.articulation.slam.landmarks import Joint

    rng = np.random.default_rng(0)
    sigma, n = 0.05, 40
    # a line along x through the origin, points over 3 m
    line = Joint("prismatic", np.zeros(2), np.array([1.0, 0.0]))
    xs = np.linspace(-1.5, 1.5, n)
    C = line.shape_covariance(np.column_stack([xs, np.zeros(n)]), sigma, gauge=0.1)
    fits = np.array([np.polyfit(xs, rng.normal(0, sigma, n), 1) for _ in range(3000)])
    assert np.isclose(np.std(np.arctan(fits[:, 0])), math.sqrt(C[2, 2]), rtol=0.15)
    assert np.isclose(np.std(fits[:, 1]), math.sqrt(C[1, 1]), rtol=0.15)  # offset along the normal (y)
    assert np.isclose(C[0, 0], 0.1**2)  # along the line: only the gauge
    # an arc of 90 degrees of a 1 m circle
    circ = Joint("revolute", np.zeros(2), radius=1.0)
    a = np.linspace(0, math.pi / 2, n)
    P = np.column_stack([np.cos(a), np.sin(a)])
    C = circ.shape_covariance(P, sigma, gauge=0.1)
    radii = []
    for _ in range(400):
        Q = P + rng.normal(0, sigma, P.shape)
        res = least_squares(lambda p, Q=Q: np.hypot(Q[:, 0] - p[0], Q[:, 1] - p[1]) - p[2], [0.0, 0.0, 1.0])
        radii.append(res.x[2])
    assert np.isclose(np.std(radii), math.sqrt(C[2, 2]), rtol=0.15)
    # a shorter arc pins the radius down less
    short = circ.shape_covariance(P[: n // 3], sigma, gauge=0.1)
    assert short[2, 2] > 4 * C[2, 2]


@pytest.mark.parametrize("curvature", [0.0, 1e-4, 0.01, 0.8, -1.2])  # 0.01: both sides of the series switch
def test_curve_joint_position_jacobian_and_coordinate(curvature):
    """A path of constant curvature (line and circle alike): the Jacobian of ``m(s)`` in ``(s, dx,
    dy, dphi, dkappa)`` matches finite differences, also near and at zero curvature (the series),
    and ``coordinate`` inverts ``position``."""
    from artmotion.articulation.slam.landmarks import Joint

    j = Joint("curve", np.array([1.0, 2.0]), np.array([math.cos(0.3), math.sin(0.3)]), curvature=curvature)
    f = lambda v: j.position_shaped(v[0], v[1:])[0]  # noqa: E731
    for s in (0.0, 1e-3, 0.7, -1.3):
        x, h = np.array([s, 0.01, -0.02, 0.05, 0.003]), 1e-6
        _, J = j.position_shaped(x[0], x[1:])
        for k in range(5):
            e = np.zeros(5)
            e[k] = h
            assert np.allclose((f(x + e) - f(x - e)) / (2 * h), J[:, k], atol=1e-6)
        assert abs(j.coordinate(j.position(s)[0]) - s) < 1e-9
    # continuous where the closed form takes over from the series (|curvature * s| = 0.01)
    if curvature:
        s0 = 0.01 / abs(curvature)
        assert np.allclose(j.position_shaped(s0 * (1 - 1e-9), np.zeros(4))[1], j.position_shaped(s0 * (1 + 1e-9), np.zeros(4))[1],
                           atol=1e-9)
    if curvature > 0.1:  # a circle of radius 1/curvature about the centre left of the tangent
        centre = j.origin + np.array([-j.direction[1], j.direction[0]]) / curvature
        for s in (0.5, 2.0):
            assert np.isclose(np.linalg.norm(j.position(s)[0] - centre), 1.0 / curvature)


def test_fit_curve_recovers_circle_and_line():
    """Gauss-Newton from a straight guess bends to the curvature of noisy points on an arc, stays
    straight on a line, and its covariance is smaller where the points say more."""
    from artmotion.articulation.slam.landmarks import Joint

    rng = np.random.default_rng(1)
    a = np.linspace(0.2, 1.6, 60)
    P = np.array([3.0, -1.0]) + 1.1 * np.column_stack([np.cos(a), np.sin(a)]) + rng.normal(0, 0.03, (60, 2))
    d = (P[-1] - P[0]) / np.linalg.norm(P[-1] - P[0])
    fit, C = Joint("curve", P.mean(axis=0), d).fit_curve(P, 0.03, 0.15)
    assert abs(fit.curvature - 1 / 1.1) < 3 * math.sqrt(C[3, 3]) and abs(fit.curvature - 1 / 1.1) < 0.1
    t = np.linspace(0, 3, 50)
    L = np.column_stack([t, 0.5 * t]) + rng.normal(0, 0.03, (50, 2))
    fit, C_line = Joint("curve", L[0], np.array([1.0, 0.5]) / math.hypot(1.0, 0.5)).fit_curve(L, 0.03, 0.15)
    assert abs(fit.curvature) < 3 * math.sqrt(C_line[3, 3]) and abs(fit.curvature) < 0.1
    _, C_short = Joint("curve", L[0], np.array([1.0, 0.5]) / math.hypot(1.0, 0.5)).fit_curve(L[:15], 0.03, 0.15)
    assert C_short[3, 3] > 4 * C_line[3, 3]
    anchored = fit.anchored(L[-1])
    assert abs(anchored.coordinate(L[-1])) < 1e-9


def test_curve_joints_in_articulated_slam():
    """With ``joint_curve`` (the default) the decided moving landmarks enter as curves (6 state
    variables each; the block keeps Algorithm 1's name) and the filter still tracks the robot."""
    w = make_scenario("warehouse", seed=3)
    sim = simulate(w, 400, seed=4)
    out = run_slam(sim, "articulated", joint_curve=True)
    f = out["filter"]
    moving = [b for b in f.blocks.values() if b.kind != "static"]
    assert moving and all(b.joint.kind == "curve" and b.dim == 6 for b in moving)
    gated = run_slam(sim, "ekf_gated")
    err = pose_errors(out["poses"], sim["poses"])["translation_error"]
    assert err < 2 * pose_errors(gated["poses"], sim["poses"])["translation_error"]


@pytest.mark.parametrize("kwargs, match", [
    ({"seed": -1}, "seed"), ({"lag": 100}, "lag"), ({"lag": -1}, "lag"), ({"runs": 2.5}, "runs"),
    ({"runs": 0}, "runs"), ({"steps": 1}, "steps"),
])
def test_monte_carlo_refuses_bad_options(kwargs, match):
    with pytest.raises(InputError, match=match):
        monte_carlo(**{"runs": 1, "steps": 5, **kwargs})


def test_the_interval_of_an_error_does_not_go_below_zero():
    """Two runs: the t interval of a mean error went to [-0.283, 0.429]."""
    from artmotion.articulation.slam.evaluate import _interval

    assert _interval([0.01, 0.5])["low"] == 0.0
    assert _interval([-1.0, 0.5])["low"] < 0.0          # (a signed quantity keeps its interval)
    got = _interval([0.30, 0.31, 0.29, 0.30])
    assert 0.27 < got["low"] < 0.30 < got["high"] < 0.33


def test_monte_carlo_reports_progress_after_each_back_ends_run_and_the_same_results():
    calls = []
    kw = dict(runs=2, steps=20, seed=3, backends=("ekf", "ekf_gated"))
    res = monte_carlo(**kw, on_run=lambda done, total: calls.append((done, total)))
    assert calls == [(1, 4), (2, 4), (3, 4), (4, 4)]
    plain = monte_carlo(**kw)
    for name in kw["backends"]:
        assert res[name]["translation_error"] == plain[name]["translation_error"]
    from artmotion.errors import InputError

    with pytest.raises(InputError, match="on_run must be a function"):
        monte_carlo(**kw, on_run="yes")
    calls.clear()       # a back end listed twice (the API keeps both) counts twice
    monte_carlo(**{**kw, "backends": ("ekf", "ekf")}, on_run=lambda done, total: calls.append((done, total)))
    assert calls == [(1, 4), (2, 4), (3, 4), (4, 4)]
