"""Factorisation W = M S (Eq. 4.2-4.7) and rigid-body classification (4.3.2)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation as Rot

from artmotion.articulation.rigid import classify_points, classify_poses, factorize, stack_w
from artmotion.errors import InputError

RNG = np.random.default_rng(0)
SHAPE = RNG.normal(size=(6, 3)) * 0.1


def _motion(kind, f):
    a = 0.03 * f
    if kind == "static":
        return np.eye(3), np.zeros(3)
    if kind == "prismatic":
        return np.eye(3), np.array([1.0, 2.0, 0.5]) * 0.01 * f / np.sqrt(5.25)
    if kind == "revolute":
        R = Rot.from_rotvec([0, 0, a]).as_matrix()
        c = np.array([0.5, 0.2, 0.0])
        return R, c - R @ c
    if kind == "planar":
        return Rot.from_rotvec([0, 0, a]).as_matrix(), np.array([0.02 * f, 0.01 * f, 0.0])
    R = Rot.from_rotvec([a, 0.5 * a, 0.2 * np.sin(f / 5)]).as_matrix()
    return R, np.array([0.01 * f, 0.02 * f, -0.01 * f])


def _tracks(kind, F=30, noise=0.001, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for f in range(F):
        R, t = _motion(kind, f)
        out.append(SHAPE @ R.T + t)
    return np.array(out) + rng.normal(0, noise, (F, len(SHAPE), 3))


def test_w_is_rank_four_for_a_rigid_body():
    W = stack_w(_tracks("general", noise=0.0))
    s = np.linalg.svd(W, compute_uv=False)
    assert s[3] > 1e-3 * s[0] and s[4] < 1e-10 * s[0]


@pytest.mark.parametrize("method", ["orthonormal", "auto"])
def test_factorisation_recovers_shape_and_motion(method):
    tracks = _tracks("general", noise=0.0)
    R, t, S = factorize(tracks, method=method)
    # rotations are proper and reproduce the data
    assert np.allclose(np.linalg.det(R), 1.0)
    rec = np.einsum("fij,nj->fni", R, S) + t[:, None, :]
    assert np.abs(rec - tracks).max() < 1e-6
    # the shape is metric: pairwise distances as in the true body
    d_true = np.linalg.norm(SHAPE[:, None] - SHAPE[None], axis=2)
    d_est = np.linalg.norm(S[:, None] - S[None], axis=2)
    assert np.abs(d_true - d_est).max() < 1e-6
    # relative rotations match the truth
    for f in (5, 17, 29):
        Rt = _motion("general", f)[0] @ _motion("general", 0)[0].T
        Re = R[f] @ R[0].T
        assert np.abs(Rt - Re).max() < 1e-6


@pytest.mark.parametrize("kind,expected", [
    ("static", "static"), ("prismatic", "prismatic"), ("revolute", "revolute"),
    ("planar", "planar"), ("general", "rigid"),
])
def test_rigid_classification(kind, expected):
    res = classify_points(_tracks(kind), noise=0.001)
    assert res.model == expected, res.residuals
    if expected == "revolute":
        assert abs(abs(res.configuration["axis"][2]) - 1) < 0.02
        c = np.array(res.configuration["point"])
        assert np.linalg.norm(c[:2] - [0.5, 0.2]) < 0.02


def test_three_points_are_enough():
    tr = _tracks("revolute", noise=0.0005)[:, :3]
    assert classify_points(tr, noise=0.001).model == "revolute"


def test_pose_track_classification():
    n = 60
    a = np.linspace(0, 1.0, n)
    c = np.array([0.5, 0.0, 0.0])
    R = Rot.from_rotvec(np.column_stack([np.zeros(n), np.zeros(n), a]))
    pos = R.apply(-c) + c
    assert classify_poses(pos, R.as_quat(), noise=0.001).model == "revolute"
    pos = np.column_stack([np.linspace(0, 0.4, n), np.zeros(n), np.zeros(n)])
    q = np.tile([0, 0, 0, 1.0], (n, 1))
    assert classify_poses(pos, q, noise=0.001).model == "prismatic"
    assert classify_poses(np.zeros((n, 3)), q, noise=0.001).model == "static"
    with pytest.raises(InputError):
        classify_poses(pos, q * 2)


def test_factorize_rejects_bad_shapes():
    with pytest.raises(InputError):
        factorize(np.zeros((5, 2, 3)))


def _turning_body(frames=20):
    body = np.random.default_rng(0).normal(size=(6, 3))
    return np.stack([Rot.from_rotvec([0, 0, a]).apply(body) for a in np.linspace(0, 1, frames)])


def test_classify_poses_refuses_misuse():
    t = np.linspace(0, 1, 20)
    P = np.c_[np.cos(t), np.sin(t), 0 * t]
    q = np.c_[0 * t, 0 * t, np.sin(t / 2), np.cos(t / 2)]
    assert classify_poses(P, q).model == "revolute"
    with pytest.raises(InputError, match="NaN"):
        classify_poses(P * np.nan, q)
    with pytest.raises(InputError, match="size"):
        classify_poses(P, q, size=0)
    with pytest.raises(InputError, match="noise"):
        classify_poses(P, q, noise=float("nan"))
    with pytest.raises(InputError, match="as many rows"):
        classify_poses(P[:5], q)
    with pytest.raises(InputError, match="at least 2 poses"):
        classify_poses(P[:0], q[:0])
    with pytest.raises(InputError, match=r"\(F, 4\)"):
        classify_poses(P, q[:, :3])


def test_classify_points_refuses_misuse_and_degenerate_bodies():
    tracks = _turning_body()
    assert classify_points(tracks).model == "revolute"
    for noise in (0.0, -1.0, float("nan")):
        with pytest.raises(InputError, match="noise"):
            classify_points(tracks, noise=noise)
    with pytest.raises(InputError, match="method"):
        classify_points(tracks, method="bogus")
    with pytest.raises(InputError, match="magnitude"):
        classify_points(tracks * 1e300)
    line = np.stack([np.c_[np.arange(6.0), np.zeros(6), np.zeros(6)]] * 20)
    with pytest.raises(InputError, match="one line"):
        classify_points(line)
    with pytest.raises(InputError, match="one line"):
        classify_points(np.ones((20, 5, 3)))
    # a flat body that does not turn has a degenerate gauge: an answer, not a LinAlgError
    flat = np.c_[tracks[0][:, :2], np.zeros(6)]
    assert classify_points(np.stack([flat] * 10)).model == "static"
    assert classify_points(np.stack([flat + [0.1 * k, 0, 0] for k in range(10)])).model == "prismatic"


@pytest.mark.parametrize("unit", [1.0, 1000.0])
def test_pose_tracks_answer_alike_in_metres_and_millimetres(unit):
    """A fixed noise of 0.005 data units called a drawer written in millimetres 'rigid'; the noise
    of a pose track is estimated from the track."""
    from artmotion.articulation.trajectory import fit_poses

    rng = np.random.default_rng(0)
    n = 200
    tilt = lambda k: Rot.from_rotvec(rng.normal(0.0, 0.002, (k, 3)))   # noqa: E731 (orientation noise)
    s = 0.4 * (0.5 - 0.5 * np.cos(np.linspace(0.0, np.pi, n)))
    drawer = np.c_[s, np.zeros(n), np.zeros(n)] + rng.normal(0.0, 0.001, (n, 3))
    a = 1.2 * (0.5 - 0.5 * np.cos(np.linspace(0.0, np.pi, n)))
    R = Rot.from_rotvec(np.c_[np.zeros(n), np.zeros(n), a])
    c = np.array([0.5, 0.0, 0.0])
    door = R.apply(-c) + c + rng.normal(0.0, 0.001, (n, 3))
    tumble = Rot.from_rotvec(np.c_[a, 0.5 * a ** 2, np.sin(3 * a)])
    free = np.c_[s, s ** 2, np.sin(5 * s)] + rng.normal(0.0, 0.001, (n, 3))
    for P, Rs, truth in ((drawer, tilt(n), "prismatic"), (door, tilt(n) * R, "revolute"),
                         (free, tilt(n) * tumble, "rigid")):
        out = fit_poses(P * unit, Rs.as_quat())
        assert out["model"] == truth, (truth, out["noise"], out["angular_noise"])
        assert 0.0005 < out["noise"] / unit < 0.002 and 0.001 < out["angular_noise"] < 0.004
