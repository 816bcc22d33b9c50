"""Configuration fits (Eq. 4.1, 4.3.3, 4.8.1) on synthetic data with known configuration and noise."""

import numpy as np
import pytest

from artmotion.articulation.models import (
    PlanarModel,
    PrismaticModel,
    RevoluteModel,
    StaticModel,
    fit_circle_2d,
    fit_circle_joint,
    make_model,
)
from artmotion.articulation.temporal import configuration_monte_carlo
from artmotion.errors import InputError


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def test_static_fit_recovers_centre():
    rng = np.random.default_rng(0)
    c = np.array([1.0, -2.0, 0.5])
    X = c + rng.normal(0, 0.01, (200, 3))
    m = StaticModel().fit(X)
    assert np.linalg.norm(m.centre - c) < 0.005
    assert m.motion(X).shape == (200, 0)


def test_prismatic_fit_recovers_line_and_motion():
    rng = np.random.default_rng(1)
    o, d = np.array([0.3, -0.2, 1.0]), _unit([1.0, 2.0, -0.5])
    q = np.linspace(0, 0.8, 100)
    X = o + q[:, None] * d + rng.normal(0, 0.003, (100, 3))
    m = PrismaticModel().fit(X)
    assert abs(abs(m.direction @ d) - 1) < 1e-3
    assert m.direction @ d > 0  # oriented along the motion
    qh = m.motion(X)[:, 0]
    assert np.abs((qh - qh[0]) - (q - q[0])).max() < 0.015
    assert np.sqrt(np.mean(m.residuals(X) ** 2)) < 0.006


@pytest.mark.parametrize("dim", [2, 3])
def test_revolute_fit_recovers_circle(dim):
    rng = np.random.default_rng(2)
    c, r = np.array([2.0, 2.0, 0.5]), 0.7
    axis = _unit([0.1, -0.2, 1.0]) if dim == 3 else np.array([0, 0, 1.0])
    u = _unit(np.cross(axis, [1.0, 0, 0]))
    v = np.cross(axis, u)
    th = np.linspace(0.2, 1.6, 120)
    X = c + r * (np.cos(th)[:, None] * u + np.sin(th)[:, None] * v) + rng.normal(0, 0.005, (120, 3))
    if dim == 2:
        X = X[:, :2]
        c = c[:2]
        X3 = np.column_stack([X, np.zeros(len(X))])
    else:
        X3 = X
    m = make_model("revolute", dim).fit(X3)
    assert np.linalg.norm(m.centre[:dim] - c) < 0.02
    assert abs(m.radius - r) < 0.01
    assert abs(abs(m.axis @ axis) - 1) < 1e-2
    q = m.motion(X3)[:, 0]
    assert abs((q[-1] - q[0]) - (th[-1] - th[0])) < 0.03  # angle grows along the track
    # f_M(C, G(X, C)) reproduces the points up to the noise
    assert np.sqrt(np.mean(m.residuals(X3) ** 2)) < 0.01


def test_revolute_jacobian_matches_finite_differences():
    m = RevoluteModel(centre=[1, 2, 3], axis=[0, 0, 1], radius=0.5, u=[1, 0, 0])
    q, h = 0.7, 1e-6
    fd = (m.predict1(q + h) - m.predict1(q - h)) / (2 * h)
    assert np.allclose(fd, m.jacobian1(q), atol=1e-8)
    assert np.allclose(m.jacobian(np.array([q]))[:, 0], fd, atol=1e-8)


def test_planar_fit_recovers_plane():
    rng = np.random.default_rng(3)
    n = _unit([0.2, 0.1, 1.0])
    u = _unit(np.cross(n, [1, 0, 0]))
    v = np.cross(n, u)
    Q = rng.uniform(-1, 1, (150, 2))
    X = 0.5 + Q[:, :1] * u + Q[:, 1:] * v + rng.normal(0, 0.002, (150, 3))
    m = PlanarModel().fit(X)
    assert abs(abs(m.normal @ n) - 1) < 1e-3
    assert np.sqrt(np.mean(m.residuals(X) ** 2)) < 0.004


def test_circle_fit_exact_and_joint_fit_on_clean_data():
    th = np.linspace(0, 2, 30)
    P = np.array([2.0, 2.0]) + np.column_stack([np.cos(th), np.sin(th)])
    c, r = fit_circle_2d(P)
    assert np.allclose(c, [2, 2], atol=1e-9) and abs(r - 1) < 1e-9
    t = np.arange(30.0)
    P = np.array([2.0, 2.0]) + np.column_stack([np.cos(0.3 + 0.05 * t), np.sin(0.3 + 0.05 * t)])
    cj, rj, th0, w = fit_circle_joint(t, P)
    assert np.allclose(cj, [2, 2], atol=1e-6) and abs(rj - 1) < 1e-6 and abs(w - 0.05) < 1e-6


def test_table_4_1_separate_beats_joint():
    """Table 4.1 (fewer runs here; 500 in docs): the separate (circle) estimate has lower mean
    centre and radius errors than the joint non-linear estimate of Eq. 4.29."""
    res = configuration_monte_carlo(runs=120, seed=3)
    assert res["separate"]["centre_error"] < res["joint"]["centre_error"]
    assert res["separate"]["radius_error"] < res["joint"]["radius_error"]
    assert res["separate"]["centre_error"] < 0.3


def test_points_must_be_finite_2d_or_3d():
    from artmotion.articulation.models import as_points3

    with pytest.raises(InputError):
        as_points3(np.zeros((5, 4)))
    with pytest.raises(InputError):
        as_points3(np.array([[0.0, np.nan], [1, 1]]))


@pytest.mark.parametrize("cls", [StaticModel, PrismaticModel, RevoluteModel, PlanarModel])
def test_point_models_refuse_bad_points_and_predict_before_fit(cls):
    with pytest.raises(InputError, match="not fitted"):
        cls().predict(np.zeros((2, cls.dof)))
    with pytest.raises(InputError, match="not fitted"):
        cls().configuration()
    with pytest.raises(InputError, match="NaN"):
        cls().fit(np.full((5, 3), np.nan))
    with pytest.raises(InputError, match="at least"):
        cls().fit(np.zeros((cls.min_points - 1, 3)))
    with pytest.raises(InputError, match="array"):
        cls().fit(np.zeros(3))
    with pytest.raises(InputError, match="weight"):
        cls().fit(np.random.default_rng(0).normal(size=(5, 3)), weights=np.ones(4))
    # identical or collinear points: an answer, not a LinAlgError (a circle's centre and radius
    # would be made up: the revolute model refuses them)
    for X in (np.ones((5, 3)), np.c_[np.arange(5.0), np.zeros(5), np.zeros(5)]):
        if cls is RevoluteModel:
            with pytest.raises(InputError, match="do not span a circle"):
                cls().fit(X)
            continue
        m = cls().fit(X)
        assert np.all(np.isfinite(m.predict(m.motion(X))))


def test_make_model_refuses_unknown_names():
    with pytest.raises(InputError, match="unknown point model"):
        make_model("foo")
