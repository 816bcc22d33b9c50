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


# -- a configuration given to a model's constructor is checked as a fit's points are: a NaN centre was
#    predicted as NaN, a 5-number centre silently cut to 3, a radius of -1 or "1" taken (a mirrored
#    circle; a UFuncTypeError at predict), an infinite direction gave NaN predictions
@pytest.mark.parametrize("make, what", [
    (lambda: StaticModel(centre=[np.nan, 0, 0]), r"centre must be finite numbers, got \[nan, 0.0, 0.0\]"),
    (lambda: StaticModel(centre=[1, 2, 3, 4, 5]),
     r"centre must be 2 or 3 numbers \(an array of shape \(2,\) or \(3,\)\), got shape \(5,\)"),
    (lambda: StaticModel(centre=[[1, 2, 3]]), r"centre must be 2 or 3 numbers .* got shape \(1, 3\)"),
    (lambda: StaticModel(centre=5.0), r"centre must be 2 or 3 numbers .* got shape \(\)"),
    (lambda: StaticModel(centre=["1", "2", "3"]), "centre must be an array of numbers"),
    (lambda: StaticModel(centre=[1e200, 0, 0]), "centre must be numbers of magnitude at most 1e\\+100"),
    (lambda: PrismaticModel(origin=[0, 0, 0], direction=[np.inf, 0, 0]), r"direction must be finite numbers"),
    (lambda: PrismaticModel(origin=[0, 0, np.nan], direction=[1, 0, 0]), r"origin must be finite numbers"),
    (lambda: PrismaticModel(origin=[0, 0], direction=[1, 0, 0]), r"direction must have as many numbers as origin \(2\), got 3"),
    (lambda: PrismaticModel(origin=[0, 0, 0, 0], direction=[1, 0, 0]), r"origin must be 2 or 3 numbers"),
    (lambda: PrismaticModel(origin=[0, 0, 0], direction="x"), "direction must be an array of numbers"),
    (lambda: RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 1], radius=-1.0, u=[1, 0, 0]),
     r"radius must be a number in \(0, 1e\+100\], got -1"),
    (lambda: RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 1], radius=0.0, u=[1, 0, 0]), "radius must be a number in"),
    (lambda: RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 1], radius=np.nan, u=[1, 0, 0]), "radius must be a number in"),
    (lambda: RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 1], radius=np.inf, u=[1, 0, 0]), "radius must be a number in"),
    (lambda: RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 1], radius="1", u=[1, 0, 0]), r"radius must be a number in .* got '1'"),
    (lambda: RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 1], radius=True, u=[1, 0, 0]), "radius must be a number in"),
    (lambda: RevoluteModel(centre=[0, 0], axis=[0, 0, 1], radius=1.0, u=[1, 0, 0]),
     r"centre must be 3 numbers \(an array of shape \(3,\)\), got shape \(2,\)"),
    (lambda: RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 1, 0], radius=1.0, u=[1, 0, 0]), "axis must be 3 numbers"),
    (lambda: RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 1], radius=1.0, u=[1, np.nan, 0]), "u must be finite numbers"),
    (lambda: RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 1], radius=1.0, u=[0, 0, -2]), "u must not be parallel to the axis"),
    (lambda: RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 1], radius=1.0, u=[1e-9, 0, 1]), "u must not be parallel to the axis"),
    (lambda: RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 1], radius=1.0, u=[0, 0, 0]),
     "u must be a direction, not a zero vector"),
    (lambda: RevoluteModel(planar_axis=[0, 0, 0]), "planar_axis must be a direction, not a zero vector"),
    (lambda: RevoluteModel(planar_axis=[0, 0, np.inf]), "planar_axis must be finite numbers"),
    (lambda: PlanarModel(origin=[0, 0, 0], normal=[0, 0, 0]), "normal must be a direction, not a zero vector"),
    (lambda: PlanarModel(origin=[0, 0], normal=[0, 0, 1]), r"origin must be 3 numbers"),
    (lambda: PlanarModel(origin=[0, 0, 0], normal=[np.nan, 0, 1]), "normal must be finite numbers"),
    (lambda: PlanarModel(planar_axis=[1, 2]), "planar_axis must be 3 numbers"),
])
def test_model_constructors_refuse_a_bad_configuration(make, what):
    with pytest.raises(InputError, match=what):
        make()


def test_revolute_constructor_projects_u_into_the_circle_plane():
    """u = (1, 0, 1) about the z axis predicted an ellipse (|p| = 1, 0.707, 1): its part along the
    axis is dropped, as fit does, and the points lie on the circle of the radius given."""
    m = RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 1], radius=1.0, u=[1, 0, 1])
    assert np.allclose(m.u, [1, 0, 0]) and np.allclose(m.v, [0, 1, 0])
    q = np.linspace(0, 2 * np.pi, 9)
    P = m.predict(q)
    assert np.allclose(np.linalg.norm(P, axis=1), 1.0) and np.allclose(P[:, 2], 0.0)
    assert np.allclose(m.motion(P)[:, 0], q)
    m2 = RevoluteModel(centre=[1, 2, 3], axis=[0, 0, 2], radius=2, u=[0, 3, -5])  # scaled, slanted u
    assert np.allclose(m2.u, [0, 1, 0]) and np.allclose(m2.axis, [0, 0, 1]) and m2.radius == 2.0
    assert np.allclose(np.linalg.norm(m2.predict(q) - [1, 2, 3], axis=1), 2.0)
    # a perpendicular u is kept as given (the valid case runs as before)
    u = np.array([3.0, 4.0, 0.0]) / 5.0
    assert np.array_equal(RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 1], radius=1.0, u=u).u, u)


def test_an_unconfigured_revolute_model_says_it_is_not_fitted():
    """``RevoluteModel().v`` was a TypeError ('NoneType' object is not subscriptable); predict1 of a
    model given no radius a TypeError from the arithmetic."""
    with pytest.raises(InputError, match="revolute model is not fitted"):
        _ = RevoluteModel().v
    with pytest.raises(InputError, match="revolute model is not fitted"):
        _ = RevoluteModel(axis=[0, 0, 1]).v
    partial = RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 1], u=[1, 0, 0])  # no radius
    for call in (partial.predict1, partial.jacobian1, partial.predict, partial.jacobian):
        with pytest.raises(InputError, match="revolute model is not fitted"):
            call(0.3)
    with pytest.raises(InputError, match="revolute model is not fitted"):
        RevoluteModel(centre=[0, 0, 0], radius=1.0, u=[1, 0, 0]).predict1(0.3)  # no axis
    # once fitted, v is there
    th = np.linspace(0.0, 1.5, 20)
    X = np.column_stack([np.cos(th), np.sin(th), np.zeros(20)])
    m = RevoluteModel()
    m.fit(X)
    assert np.allclose(np.abs(m.v @ [0, 0, 1]), 0.0) and np.isclose(np.linalg.norm(m.v), 1.0)


def test_valid_given_configurations_run_as_before():
    """Guards: 2-D configurations of the models that take 2-D points, NumPy scalars and ints, a
    whole-number radius."""
    assert StaticModel(centre=[1, 2]).predict(np.zeros((2, 0))).tolist() == [[1.0, 2.0], [1.0, 2.0]]
    assert StaticModel(centre=[1, 2, 3]).configuration() == {"centre": [1.0, 2.0, 3.0]}
    assert np.allclose(PrismaticModel(origin=[0, 0], direction=[0, 2]).predict([1.5]), [[0, 1.5]])
    m = RevoluteModel(centre=np.zeros(3), axis=np.array([0, 0, 1]), radius=np.float64(2), u=[1, 0, 0])
    assert m.radius == 2.0 and np.allclose(m.predict1(np.pi / 2), [0, 2, 0])
    assert RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 1], radius=3, u=[0, 1, 0]).configuration()["radius"] == 3.0
    pm = PlanarModel(origin=[0, 0, 0], normal=[0, 0, 5])
    assert np.allclose(pm.normal, [0, 0, 1]) and np.allclose(pm.predict([[1.0, 2.0]])[0, 2], 0.0)
    assert np.array_equal(RevoluteModel(planar_axis=[0, 0, 2]).planar_axis, [0, 0, 2])  # kept as given
