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


def test_ekf_slam_is_consistent_on_a_static_world():
    """Average robot-pose NEES over runs stays within the chi^2 95 % band (3 dof x runs)."""
    from scipy.stats import chi2

    runs, steps = 8, 250
    nees = []
    for r in range(runs):
        world = make_world(42, 0, 0, seed=r)
        sim = simulate(world, steps, seed=100 + r)
        out = run_slam(sim, articulated=False)
        e = out["poses"] - sim["poses"]
        e[:, 2] = (e[:, 2] + np.pi) % (2 * np.pi) - np.pi
        nees.append([e[k] @ np.linalg.solve(out["covs"][k], e[k]) for k in range(1, steps + 1)])
    nees = np.array(nees)
    lo, hi = chi2.ppf([0.025, 0.975], 3 * runs) / runs
    mean_t = nees.mean(axis=0)
    assert lo < nees.mean() < hi
    assert np.mean((mean_t > lo) & (mean_t < hi)) > 0.8


def test_articulated_slam_identifies_moving_landmarks():
    world = make_world(42, 1, 1, seed=0)
    sim = simulate(world, 600, seed=1)
    cfg = sim["config"]
    f = EKFSlam(sim["poses"][0], sim["dt"], cfg.alphas, cfg.range_std, cfg.bearing_std, 42, articulated=True)
    tracked = []
    for k, u in enumerate(sim["controls"]):
        f.predict(u)
        ids, z = sim["observations"][k]
        f.update(ids, z)
        if 41 in ids and 41 in f.blocks:  # a decided revolute landmark follows the truth while seen
            tracked.append(np.linalg.norm(f.landmark_positions()[41] - sim["landmarks"][k + 1][41]))
    assert f.blocks[40].kind == "prismatic"
    assert f.blocks[41].kind == "revolute"
    static_ok = [f.blocks[i].kind == "static" for i in range(40) if i in f.blocks]
    assert np.mean(static_ok) > 0.9
    assert len(tracked) >= 5 and np.median(tracked) < 0.6


def test_articulated_beats_ekf_with_moving_landmarks():
    res = monte_carlo(runs=3, steps=500, seed=7)
    a, e = res["articulated"], res["ekf"]
    assert a["translation_error"] < 0.7 * e["translation_error"]
    assert a["rotation_error"] < e["rotation_error"]


def test_pose_errors_zero_for_perfect_estimate():
    p = np.column_stack([np.arange(20.0), np.zeros(20), np.linspace(0, 1, 20)])
    err = pose_errors(p, p)
    assert err["translation_error"] == 0 and err["rotation_error"] == 0
    q = p.copy()
    q[:, 0] += 1.0  # a constant offset changes absolute but not relative errors
    assert pose_errors(q, p)["translation_error"] < 1e-12
    assert math.isclose(pose_errors(q, p)["absolute_translation_error"], 1.0)
