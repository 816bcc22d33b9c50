"""Input checks of the articulation Python API (rigid, models, online, trajectory): bad input raises
an InputError naming the parameter and what was got, never a confident answer or a crash deep inside."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from artmotion.articulation import (
    OnlineEstimator,
    PlanarModel,
    PrismaticModel,
    RevoluteModel,
    StaticModel,
    classify_motion,
    classify_poses,
    estimate_online,
    fit_circle_2d,
    fit_circle_joint,
    fit_trajectory,
)
from artmotion.articulation.trajectory import fit_poses
from artmotion.errors import InputError

F = 10
ROTATIONS = Rotation.from_rotvec(np.outer(np.linspace(0, 1, F), [0, 0, 1])).as_matrix()
QUATS = Rotation.from_matrix(ROTATIONS).as_quat()
POSITIONS = np.tile([0.5, 0.0, 0.0], (F, 1))


def _arc3(n=40, seed=0):
    rng = np.random.default_rng(seed)
    th = np.linspace(0, 1.5, n)
    return np.column_stack([0.3 * np.cos(th), 0.3 * np.sin(th), np.zeros(n)]) + rng.normal(0, 1e-3, (n, 3))


# -- 1. classify_motion / classify_poses: garbage is refused, not called rigid


def test_classify_motion_still_classifies_valid_motion():
    assert classify_motion(ROTATIONS, np.zeros((F, 3))).model == "revolute"
    assert classify_poses(POSITIONS, QUATS).model == "revolute"
    assert classify_poses(POSITIONS, QUATS, noise=None).model == "revolute"


@pytest.mark.parametrize("kwargs, match", [
    ({"t": np.full((F, 3), np.nan)}, "t contains NaN"),
    ({"t": np.zeros((3, 3))}, r"t must be an \(F, 3\) array.*got shape \(3, 3\)"),
    ({"t": np.zeros((F, 2))}, r"t must be an \(F, 3\) array"),
    ({"R": np.full((F, 3, 3), np.inf)}, "R contains NaN"),
    ({"R": np.zeros((F, 3))}, r"R must be an \(F, 3, 3\) array"),
    ({"R": np.zeros((0, 3, 3)), "t": np.zeros((0, 3))}, "at least one"),
    ({"R": "rotations"}, "R must be an array of numbers"),
    ({"R": np.tile(2 * np.eye(3), (F, 1, 1))}, "R is not a rotation matrix"),     # (was called static)
    ({"R": np.tile(np.diag([1.0, 1.0, -1.0]), (F, 1, 1))}, "a reflection"),
    ({"noise": -1}, r"noise must be a number in \(0, inf\), got -1"),
    ({"noise": 0, "size": 0}, "noise must be"),
    ({"noise": float("nan")}, "noise must be"),
    ({"size": 0}, "size must be"),
    ({"angular_noise": -1}, "angular_noise must be"),
    ({"angular_noise": float("nan")}, "angular_noise must be"),
    ({"centre": [0, 0]}, "centre must be"),
])
def test_classify_motion_refuses_bad_input(kwargs, match):
    args = {"R": ROTATIONS, "t": np.zeros((F, 3)), **kwargs}
    with pytest.raises(InputError, match=match):
        classify_motion(**args)


@pytest.mark.parametrize("kwargs, match", [
    ({"angular_noise": -1}, "angular_noise must be"),
    ({"angular_noise": float("nan")}, "angular_noise must be"),
    ({"noise": -1}, "noise must be"),
    ({"size": -1, "noise": None}, "size must be"),
    ({"positions": np.full((F, 3), np.nan)}, "positions contain NaN"),
    ({"quats": np.zeros((F, 4)), "noise": None}, r"quaternions must be unit quaternions.*norm 0"),
    ({"quats": np.zeros((F, 4))}, "quaternions must be unit quaternions"),
    ({"quats": np.full((F, 4), np.nan), "noise": None}, "quaternions must be unit quaternions"),
])
def test_classify_poses_refuses_bad_input(kwargs, match):
    args = {"positions": POSITIONS, "quats": QUATS, **kwargs}
    with pytest.raises(InputError, match=match):
        classify_poses(**args)


# -- 2. circle fits


def test_circle_fits_on_valid_points_unchanged():
    th = np.linspace(0, 2, 30)
    P = np.array([2.0, 2.0]) + np.column_stack([np.cos(th), np.sin(th)])
    c, r = fit_circle_2d(P)
    assert np.allclose(c, [2, 2]) and abs(r - 1) < 1e-9
    c, r = fit_circle_2d(P[:3])  # three points span a circle
    assert np.allclose(c, [2, 2]) and abs(r - 1) < 1e-9


@pytest.mark.parametrize("P, match", [
    (np.column_stack([np.cos(np.linspace(0, 1.5, 8)), np.zeros(8), np.sin(np.linspace(0, 1.5, 8))]),
     r"P must be an \(n, 2\) array.*got shape \(8, 3\)"),
    ([[1.0, 2.0]], "at least 3 points"),
    (np.ones((5, 2)), "one line"),
    (np.column_stack([np.arange(5.0), 2 * np.arange(5.0) + 1]), "one line"),
    (np.zeros((0, 2)), "at least 3 points"),
    ([[0, 0], [1, np.nan], [2, 2]], "NaN"),
    ([[0, 0], [1, 1e200], [2, 2]], "magnitude"),
    ("points", "array of numbers"),
])
def test_fit_circle_2d_refuses_bad_points(P, match, capfd):
    with pytest.raises(InputError, match=match):
        fit_circle_2d(P)
    assert capfd.readouterr().err == ""  # no LAPACK complaints on stderr


def test_fit_circle_2d_refuses_bad_weights_and_init():
    P = np.column_stack([np.cos(np.linspace(0, 2, 6)), np.sin(np.linspace(0, 2, 6))])
    with pytest.raises(InputError, match="weights"):
        fit_circle_2d(P, weights=np.ones(5))
    with pytest.raises(InputError, match="weights"):
        fit_circle_2d(P, weights=-np.ones(6))
    with pytest.raises(InputError, match="at least 3 points, got 2 points of positive weight"):
        fit_circle_2d(P, weights=[1, 1, 0, 0, 0, 0])  # two points left: no circle
    with pytest.raises(InputError, match="init"):
        fit_circle_2d(P, init=(np.zeros(3), 1.0))
    with pytest.raises(InputError, match="init"):
        fit_circle_2d(P, init="ab")


@pytest.mark.parametrize("t, P, match", [
    (np.arange(8.0), np.column_stack([np.cos(np.linspace(0, 1.5, 8)), np.zeros(8), np.sin(np.linspace(0, 1.5, 8))]),
     r"P must be an \(n, 2\) array.*got shape \(8, 3\)"),
    ([], np.zeros((0, 2)), "at least 3 points"),
    ([0, 1, 2], np.column_stack([np.cos([0, 1, 2, 3]), np.sin([0, 1, 2, 3])]), r"t must hold one time per point \(4\)"),
    ([0, 1, np.nan], np.column_stack([np.cos([0, 1, 2]), np.sin([0, 1, 2])]), "t contains NaN"),
    (np.arange(5.0), np.ones((5, 2)), "one line"),
    # one time for every point: LAPACK printed "On entry to DLASCL ..." and the SVD did not converge
    (np.zeros(6), np.column_stack([np.cos(np.arange(6.0)), np.sin(np.arange(6.0))]), "at least two different times"),
])
def test_fit_circle_joint_refuses_bad_input(t, P, match, capfd):
    with pytest.raises(InputError, match=match):
        fit_circle_joint(t, P)
    assert capfd.readouterr().err == ""


def test_fit_circle_joint_refuses_bad_start():
    t = np.arange(5.0)
    P = np.column_stack([np.cos(0.2 * t), np.sin(0.2 * t)])
    for kw in ({"theta0": float("nan")}, {"omega": "fast"}):
        with pytest.raises(InputError, match=next(iter(kw))):
            fit_circle_joint(t, P, **kw)


# -- 3. fitted point models


@pytest.fixture
def fitted():
    X = _arc3()
    return {"X": X, "static": StaticModel().fit(X), "prismatic": PrismaticModel().fit(X),
            "revolute": RevoluteModel().fit(X), "planar": PlanarModel().fit(X)}


@pytest.mark.parametrize("name", ["static", "prismatic", "revolute", "planar"])
def test_models_refuse_bad_points(fitted, name):
    m = fitted[name]
    for method in (m.motion, m.residuals):
        with pytest.raises(InputError, match="NaN"):
            method([[np.nan, 0.0, 0.0]])
        with pytest.raises(InputError, match=r"\(n, 3\) array.*got shape \(40, 2\)"):
            method(fitted["X"][:, :2])
        with pytest.raises(InputError, match="array of numbers"):
            method("points")


@pytest.mark.parametrize("name", ["static", "prismatic", "revolute", "planar"])
def test_models_refuse_bad_motion_variables(fitted, name):
    m = fitted[name]
    with pytest.raises(InputError, match=rf"motion variables must be an \(n, {m.dof}\) array.*got shape \(3, 5\)"):
        m.predict(np.zeros((3, 5)))
    with pytest.raises(InputError, match="jacobian|motion variable"):
        m.jacobian(np.zeros(m.dof + 1))
    if m.dof:
        with pytest.raises(InputError, match="finite"):
            m.predict(np.full((2, m.dof), np.nan))
        with pytest.raises(InputError, match="jacobian"):
            m.jacobian([])
        with pytest.raises(InputError, match="jacobian"):
            m.jacobian([np.nan] * m.dof)


def test_models_still_take_valid_motion_variables(fitted):
    m = fitted["revolute"]
    q = m.motion(fitted["X"])
    assert m.predict(q).shape == (40, 3)
    assert np.array_equal(m.predict(q[:, 0]), m.predict(q))  # n values for one motion variable
    assert m.predict(0.3).shape == (1, 3)
    assert m.jacobian(0.3).shape == (3, 1)
    p = fitted["planar"]
    assert p.predict([0.1, 0.2]).shape == (1, 3)  # one point's two motion variables
    s = fitted["static"]
    assert s.predict(s.motion(fitted["X"])).shape == (40, 3)


@pytest.mark.parametrize("X", [np.ones((6, 3)), np.c_[np.arange(5.0), np.zeros(5), np.zeros(5)]])
def test_revolute_fit_refuses_points_that_span_no_circle(X):
    with pytest.raises(InputError, match="do not span a circle"):
        RevoluteModel().fit(X)


# -- 4. Algorithm 1


@pytest.mark.parametrize("kwargs, match", [
    ({"noise": 1e-160}, r"noise must be a number in \[1e-100, 1e\+100\], got 1e-160"),
    ({"noise": 1e154}, "noise must be"),
    ({"noise": 1e200}, "noise must be"),
    ({"accel": 1e200}, "accel must be"),
    ({"noise_floor": 1e200}, "noise_floor must be"),
    ({"radius_range": (1,)}, "radius_range must be"),
    ({"radius_range": "ab"}, "radius_range"),
    ({"radius_range": (2.0, 1.0)}, "radius_range"),
    ({"radius_range": (0.0, 1.0)}, "radius_range"),
    ({"radius_range": (0.1, math.inf)}, "radius_range"),
    ({"radius_range": None}, "radius_range"),
])
def test_online_refuses_bad_parameters(kwargs, match):
    with pytest.raises(InputError, match=match):
        OnlineEstimator(**kwargs)
    with pytest.raises(InputError, match=match):
        estimate_online(_arc3(), **kwargs)


@pytest.mark.filterwarnings("ignore:overflow:RuntimeWarning")  # the overflow the test provokes
def test_online_never_decides_on_undefined_probabilities():
    """Scores that overflow (a noise far below the data's scale) are an error, not NaN probabilities
    and a decision."""
    X = np.random.default_rng(0).normal(0, 1e90, (20, 3))
    with pytest.raises(InputError, match="not finite.*noise=1e-100"):
        estimate_online(X, noise=1e-100)


def test_online_points_must_match_dim():
    th = np.linspace(0, 1.5, 40)
    V = np.column_stack([0.3 * np.cos(th), np.zeros(40), 0.3 * np.sin(th)])
    assert estimate_online(V).model == "revolute"
    with pytest.raises(InputError, match=r"dim=2.*3 columns"):
        estimate_online(V, dim=2)
    with pytest.raises(InputError, match=r"dim=3.*2 columns"):
        estimate_online(V[:, :2], dim=3)
    est = OnlineEstimator(dim=2)
    est.update([1.0, 2.0])
    est.update([1.0, 2.0, 0.0])  # a 2-D point written in 3-D
    with pytest.raises(InputError, match="dim=2.*z = 0.5"):
        est.update([1.0, 2.0, 0.5])


def test_online_estimator_takes_one_kind_of_observation():
    """In 3-D a 2-D point after 3-D ones was put at z = 0 (a silent jump), and an unstamped
    observation after stamped ones got its sample index as its time (51 after 5.0 s)."""
    est = OnlineEstimator()
    for i in range(5):
        est.update([0.1 * i, 0.0, 0.5], 0.1 * i)
    with pytest.raises(InputError, match="3-D point like the earlier ones"):
        est.update([1.0, 2.0], 0.6)
    with pytest.raises(InputError, match="needs a time stamp"):
        est.update([0.6, 0.0, 0.5])
    est.update([0.6, 0.0, 0.5], 0.6)   # the refusals left the estimator as it was
    assert est.X.shape == (6, 3)
    other = OnlineEstimator()
    other.update([0.0, 0.0, 0.0])
    with pytest.raises(InputError, match="no time stamp was given before"):
        other.update([0.1, 0.0, 0.0], 1.0)


def test_online_extreme_but_valid_parameters_still_run():
    res = estimate_online(_arc3(), noise=1e-3, accel=1e3, noise_floor=1e-100, radius_range=(1e-100, 1e100))
    assert all(math.isfinite(p) for p in res.probabilities.values())


# -- 5. fit_trajectory on a pose file


@pytest.fixture
def pose_file(tmp_path):
    n = 20
    R = Rotation.from_rotvec(np.outer(np.linspace(0, 1, n), [0, 0, 1]))
    pos = R.apply([0.5, 0.0, 0.0])
    p = tmp_path / "pose.txt"
    np.savetxt(p, np.column_stack([pos, R.as_quat()]))
    return p


@pytest.mark.parametrize("kwargs, match", [
    ({"threshold": 5}, r"threshold must be a number in \(0, 1\), got 5"),
    ({"min_samples": 0}, "min_samples must be a whole number"),
    ({"min_samples": 2.5}, "min_samples must be a whole number"),
    ({"order": 0}, "order must be"),
    ({"radius_range": (1,)}, "radius_range must be"),
    ({"noise_floor": -1}, "noise_floor must be"),
    ({"noise": 0}, "noise must be"),
])
def test_fit_trajectory_pose_refuses_what_the_point_path_refuses(pose_file, kwargs, match):
    with pytest.raises(InputError, match=match):
        fit_trajectory(pose_file, **kwargs)


def test_fit_trajectory_refuses_unknown_keywords(pose_file, tmp_path):
    with pytest.raises(TypeError, match="unexpected keyword argument 'foo'"):
        fit_trajectory(pose_file, foo=1)
    pts = tmp_path / "arc.txt"
    np.savetxt(pts, _arc3())
    with pytest.raises(TypeError, match="unexpected keyword argument 'foo'"):
        fit_trajectory(pts, foo=1)


def test_fit_trajectory_pose_ignores_algorithm_1_options(pose_file):
    """Options of Algorithm 1 that are in range do not apply to a pose track (as the CLI says)."""
    base = fit_trajectory(pose_file)
    assert base["model"] == "revolute"
    assert fit_trajectory(pose_file, threshold=0.9, order=3, radius_range=(0.1, 2.0)) == base


def test_fit_poses_checks_its_parameters():
    with pytest.raises(InputError, match="min_samples must be a whole number"):
        fit_poses(POSITIONS, QUATS, min_samples=2.5)
    with pytest.raises(InputError, match="min_samples must be"):
        fit_poses(POSITIONS, QUATS, min_samples=0)
    with pytest.raises(InputError, match="horizon must be"):
        fit_poses(POSITIONS, QUATS, horizon=-1)
    with pytest.raises(InputError, match="noise_floor must be"):
        fit_poses(POSITIONS, QUATS, noise_floor=float("nan"))
    with pytest.raises(InputError, match="quaternions must be unit quaternions"):
        fit_poses(POSITIONS, np.zeros((F, 4)))
    assert fit_poses(POSITIONS, QUATS, min_samples=2)["model"] == "revolute"


def test_classify_motion_two_frames_in_a_plane():
    """Two translations off one line span a plane: planar, not an IndexError (the reduced SVD of 2
    frames has no third direction)."""
    assert classify_motion(np.stack([np.eye(3)] * 2), [[0.1, 0.0, 0.0], [0.0, 0.1, 0.0]]).model == "planar"


# -- 6. whole-number floats are the integers they are (they passed the checks, then crashed deep inside)


def test_online_takes_whole_number_floats_for_its_integer_parameters():
    X = _arc3()
    base = estimate_online(X).to_dict()
    for kwargs in ({"order": 2.0}, {"dim": 3.0}, {"min_samples": 7.0},
                   {"order": np.float64(2.0), "dim": np.int64(3), "min_samples": np.float64(7.0)}):
        assert estimate_online(X, **kwargs).to_dict() == base, kwargs   # (once: TypeError)
    assert estimate_online(X, order=3.0).to_dict() == estimate_online(X, order=3).to_dict()
    P = X[:, :2]
    assert estimate_online(P, dim=2.0).to_dict() == estimate_online(P).to_dict()


def test_online_result_checks_its_horizon():
    est = OnlineEstimator()
    for z in _arc3():
        est.update(z)
    assert np.array_equal(est.result(horizon=3.0).prediction, est.result(horizon=3).prediction)
    assert est.result(horizon=3).prediction.shape == (3, 3)
    for bad in (-1, 2.5, "5", None):
        with pytest.raises(InputError, match="horizon must be a whole number"):
            est.result(horizon=bad)


# -- 7. point models copy the arrays they are given (they kept the caller's array, and followed its changes)


def _mutate(*arrays):
    for a in arrays:
        a[:] = [7.0, -3.0, 2.0]


@pytest.mark.parametrize("case", ["static", "prismatic", "revolute", "revolute-planar", "planar", "planar-axis"])
def test_point_models_copy_the_arrays_they_are_given(case):
    o, d, u, ax = np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    if case == "static":
        m = StaticModel(o)
        _mutate(o)
        assert m.predict(np.zeros((1, 0))).tolist() == [[0.0, 0.0, 0.0]]  # (once: [[7, -3, 2]])
        assert m.configuration()["centre"] == [0.0, 0.0, 0.0]
    elif case == "prismatic":
        m = PrismaticModel(o, d)
        _mutate(o, d)
        assert m.predict([1.0]).tolist() == [[1.0, 0.0, 0.0]]
    elif case == "revolute":
        m = RevoluteModel(centre=o, axis=ax, radius=1.0, u=u)
        _mutate(o, ax, u)
        np.testing.assert_allclose(m.predict([math.pi / 2]), [[0.0, 1.0, 0.0]], atol=1e-15)
    elif case == "planar":
        m = PlanarModel(origin=o, normal=ax)
        _mutate(o, ax)
        assert m.configuration()["origin"] == [0.0, 0.0, 0.0] and m.configuration()["normal"] == [0.0, 0.0, 1.0]
    else:
        X = _arc3()
        X[:, 2] = 0.0
        cls = RevoluteModel if case == "revolute-planar" else PlanarModel
        want = cls(planar_axis=ax.copy()).fit(X).configuration()
        m = cls(planar_axis=ax)
        _mutate(ax)
        assert m.fit(X).configuration() == want   # (once: fitted about the caller's changed axis)


# -- 8. OnlineEstimator is a scikit-learn estimator (clone, get_params/set_params, repr)


def test_online_estimator_is_a_scikit_learn_estimator():
    from sklearn.base import clone

    est = OnlineEstimator()
    assert repr(est) == "OnlineEstimator()"
    assert est.get_params()["models"] == ("static", "prismatic", "revolute")
    given = dict(models=("prismatic", "revolute"), order=3.0, dim=np.int64(3), min_samples=8.0,
                 radius_range=[0.1, 2], threshold=0.8, nu=None)
    est = OnlineEstimator(**given)
    params = est.get_params()
    assert all(params[k] is v for k, v in given.items())    # stored as given, unconverted
    assert "order=3.0" in repr(est) and "threshold=0.8" in repr(est) and "confirm_static" not in repr(est)
    fresh = clone(est)                                       # (sklearn checks that each is stored as given)
    assert fresh.get_params() == params and type(fresh.order) is float and type(fresh.radius_range) is list
    X = _arc3()
    for z in X:
        est.update(z)
    fresh = clone(est)                                       # a fresh estimator of the same parameters
    assert fresh.X.shape == (0, 3) and fresh.get_params() == est.get_params()
    for z in X:
        fresh.update(z)
    assert fresh.result().to_dict() == est.result().to_dict()
    want = OnlineEstimator(models="prismatic", order=3)
    other = OnlineEstimator().set_params(models="prismatic", order=3)
    assert repr(other) == repr(want) and other.names == ["prismatic"]
    for z in X:
        want.update(z)
        other.update(z)
    assert other.result().to_dict() == want.result().to_dict()


def test_online_estimator_set_params_checks_as_the_constructor_does():
    est = OnlineEstimator(order=3)
    with pytest.raises(InputError, match="order must be a whole number"):
        est.set_params(order=0)
    with pytest.raises(InputError, match="models must name"):
        est.set_params(models=("static", "hinge"))
    assert est.order == 3 and est.names == ["static", "prismatic", "revolute"]   # untouched
    with pytest.raises(ValueError, match="speed"):
        est.set_params(speed=2)
    est.update([0.0, 0.0, 0.0])
    with pytest.raises(InputError, match="before the first update"):
        est.set_params(order=2)                              # its samples were scored with order 3


def test_fit_poses_takes_no_time_stamps_it_would_ignore():
    """fit_poses had a ``time`` argument it never used; a third positional argument is now an error,
    not silently dropped (the classification is geometric)."""
    with pytest.raises(TypeError):
        fit_poses(POSITIONS, QUATS, np.arange(len(POSITIONS)))


# ---------------------------------------------------------------- video segmentation stages


def _walks(seed: int = 0, frames: int = 30, n: int = 20):
    """``n`` point tracks wandering for ``frames`` frames (a 200 x 200 image at 30 frames/s): their
    positions and the PointTracks of them."""
    from artmotion.articulation.video.tracks import PointTracks

    rng = np.random.default_rng(seed)
    xy = np.cumsum(rng.normal(0, 0.1, (frames, n, 2)), axis=0) + rng.uniform(0, 100, (1, n, 2))
    return xy, PointTracks(xy, 30.0, 200, 200)


def _part_of(xy):
    """The rigid part of the first ten tracks of ``xy``: the Part and its motion (A, segment, kind)."""
    from artmotion.articulation.video import segment as S

    A, seg, kind = S.part_motion(xy, np.arange(10))
    return S.Part(np.arange(10), A, seg, 3.0, kind), A, seg, kind


def _segment_cases():
    from artmotion.articulation.video import segment as S

    xy, T = _walks()
    return [
        (lambda: S.camera_motion(T, "a"), "sigma must be a number in"),
        (lambda: S.camera_motion(T, float("nan")), "sigma must be a number in"),
        (lambda: S.camera_motion(T, -1.0), "sigma must be a number in"),
        (lambda: S.camera_motion(xy, 0.1), "tracks must be a PointTracks"),
        (lambda: S.noise_level(xy), "tracks must be a PointTracks"),
        (lambda: S.rest_frames(0), "fps must be a number in"),
        (lambda: S.rest_frames(30, -1), "rest must be a number in"),
        (lambda: S.moving_tracks(T, float("nan")), "sigma must be a number in"),
        (lambda: S.moving_tracks(T, 0.1, move="x"), "move must be a number in"),
        (lambda: S.chain_affines(xy, np.array([100, 200, 300])), r"idx must index the 20 tracks \(-20 to 19\), got 100 to 300"),
        (lambda: S.chain_affines(xy[0], np.array([0, 1, 2])), r"xy must be track positions of shape \(frames, tracks, 2\)"),
        (lambda: S.chain_affines(np.full((3, 4, 2), np.inf), [0, 1, 2]), "xy must be finite"),
        (lambda: S.factorise_motion(xy, np.array([0.5, 1.5, 2.5])), "idx must be a 1-D array of track indices"),
        (lambda: S.factorise_motion(xy, np.arange(5), nu=-1), "nu must be a number in"),
        (lambda: S.part_motion(xy, np.array([], dtype=int)), "needs at least 3 tracks, got 0"),
        (lambda: S.rigid_parts(T, np.array([999]), 0.1), "cand must index the 20 tracks"),
        (lambda: S.rigid_parts(T, np.ones(3, bool), 0.1), r"cand as a mask must have one entry per track \(20\)"),
        (lambda: S.rigid_parts(T, np.arange(20), 0.1, max_parts=0), "max_parts must be a whole number"),
        (lambda: S.rigid_parts(T, np.arange(20), 0.1, iters=-1), "iters must be a whole number"),
        (lambda: S.rigid_parts(T, np.arange(20), 0.1, min_tracks=0), "min_tracks must be a whole number"),
        (lambda: S.rigid_parts(T, np.arange(20), -0.1), "sigma must be a number in"),
        (lambda: S.rigid_parts(T, np.arange(20), 0.1, seed=-1), "seed must be what numpy.random.default_rng takes"),
    ]


def test_video_segmentation_stages_take_what_numpy_takes():
    # whole-number floats as counts (iters=200.0 passed the check and then failed in range()),
    # negative and whole-number float indices, a seed of None or a Generator, sigma 0 and tol 0
    from artmotion.articulation.video import segment as S

    xy, T = _walks(2, 12, 10)
    a = S.chain_affines(xy, [-1, -2, -3])
    assert all(np.array_equal(u, v) for u, v in zip(a[:2], S.chain_affines(xy, [9, 8, 7])[:2]))
    assert np.array_equal(S.factorise_motion(xy, np.array([0.0, 1.0, 2.0]), max_iters=1.0, tol=0)[0],
                          S.factorise_motion(xy, [0, 1, 2], max_iters=1, tol=0)[0])
    for kw in ({"iters": 20.0, "max_parts": 2.0, "min_tracks": 3.0}, {"seed": None}, {"seed": np.random.default_rng(0)},
               {"seed": np.random.SeedSequence(1)}, {"seed": 2**40}):
        assert isinstance(S.rigid_parts(T, np.arange(10), 0.0, **kw), list)
    assert S.camera_motion(T, 0.0)[0] in (True, False) and len(S.moving_tracks(T, 0.0)) >= 0


def test_video_segmentation_stages_take_a_mask_as_indices():
    from artmotion.articulation.video import segment as S

    xy = _walks(1, 10, 6)[0]
    mask = np.array([True, True, False, True, False, False])
    a, b = S.chain_affines(xy, mask), S.chain_affines(xy, [0, 1, 3])
    assert all(np.array_equal(u, v) for u, v in zip(a[:2], b[:2])) and a[2:] == b[2:]


def _joint_cases():
    from artmotion.articulation.video import joint as J
    from artmotion.articulation.video import segment as S

    xy, T = _walks()
    P, A, seg, kind = _part_of(xy)
    return [
        (lambda: J.plane_rectifier("a"), "L must be an array of numbers"),
        (lambda: J.plane_rectifier(np.zeros((3, 3))), r"L must be linear maps of shape \(frames, 2, 2\)"),
        (lambda: J.plane_rectifier(np.full((4, 2, 2), np.nan)), "L must be finite maps"),
        (lambda: J.lift_part(xy, P), "tracks must be a PointTracks"),
        (lambda: J.lift_part(T, "p"), "part must be a Part"),
        (lambda: J.lift_part(T, P, focal=-1), "focal must be a number in"),
        (lambda: J.lift_part(T, P, focal=float("nan")), "focal must be a number in"),
        (lambda: J.lift_part(T, S.Part(np.array([50, 60, 70]), A, seg, 3.0, kind)),
         r"part.tracks must index the 20 tracks \(-20 to 19\), got 50 to 70"),
        (lambda: J.lift_part(T, S.Part(np.arange(10), A[:5], seg, 3.0, kind)), r"needs part.A of shape \(30, 2, 3\)"),
        (lambda: J.classify_part(T, P, foo=1), "'foo' is not an option of the model choice"),
        (lambda: J.classify_part(None, P), "tracks must be a PointTracks"),
        (lambda: J.classify_part(T, S.Part(np.array([], dtype=int), A, seg, 3.0, kind)), "at least one track"),
    ]


@pytest.mark.parametrize("stage, case", [("segment", k) for k in range(len(_segment_cases()))]
                         + [("joint", k) for k in range(len(_joint_cases()))])
def test_video_stages_refuse_bad_arguments_by_name(stage, case):
    # segment's were bare TypeError / IndexError / AttributeError / ValueError from inside NumPy,
    # or (a NaN or negative noise level, indices out of range) a silent wrong answer: the camera
    # called moving, no moving track, no part; joint's bare LinAlgError / AttributeError /
    # IndexError / TypeError, and a negative or NaN focal length lifted the part without a word
    call, message = {"segment": _segment_cases, "joint": _joint_cases}[stage]()[case]
    with pytest.raises(InputError, match=message):
        call()


def test_video_joint_stage_takes_a_part_as_segment_takes_its_indices():
    # a Part of negative, whole-number float or two indices was lifted before the checks; the
    # checks refused it while chain_affines takes such indices
    from dataclasses import replace

    from artmotion.articulation.video import joint as J

    xy, T = _walks()
    P = _part_of(xy)[0]
    base = J.lift_part(T, P)
    for tracks in (np.arange(10) - 20, np.arange(10.0)):
        r, used, pts = J.lift_part(T, replace(P, tracks=tracks))
        assert r == base[0] and np.array_equal(used, base[1]) and np.allclose(pts, base[2])
    assert J.classify_part(T, replace(P, tracks=np.array([0, 1])))["points"] == 2

