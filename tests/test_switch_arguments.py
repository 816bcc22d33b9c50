"""Switches of the Python API take True or False, not any value: ``"no"`` is true to Python, so an
estimator given ``refit="no"`` or ``augment="no"`` silently left the switch on."""

from __future__ import annotations

import numpy as np
import pytest

from artmotion.errors import InputError, check_bool

BAD = ["no", "False", 0, 1, None, [], 0.0]


def test_check_bool_takes_python_and_numpy_booleans_only():
    assert check_bool("x", True) is True and check_bool("x", np.bool_(False)) is False
    assert check_bool("x", None, none=True) is None
    for bad in BAD:
        with pytest.raises(InputError, match="x must be True or False"):
            check_bool("x", bad)


@pytest.mark.parametrize("name", ["refit", "confirm_static", "hold"])
def test_online_estimator(name):
    from artmotion.articulation.online import OnlineEstimator

    for bad in BAD:
        with pytest.raises(InputError, match=f"{name} must be True or False"):
            OnlineEstimator(**{name: bad})
    OnlineEstimator(**{name: False})


@pytest.mark.parametrize("name", ["augment", "progress"])
def test_pose_regressor(name):
    from artmotion.pose.model import PoseRegressor

    X = np.random.default_rng(0).random((40, 6))
    Y = np.random.default_rng(1).random((40, 2)) * 10
    with pytest.raises(InputError, match=f"{name} must be True or False"):
        PoseRegressor(**{name: "no"}).fit(X, Y, ["a", "b"])


@pytest.mark.parametrize("name", ["articulated", "delayed", "joint_shift", "joint_shape", "joint_curve", "gating"])
def test_ekf_slam(name):
    from artmotion.articulation.slam.ekf import EKFSlam

    args = ([0.0, 0.0, 0.0], 0.1, [0.05, 0.005, 0.005, 0.05], 0.1, 0.02, 10)
    with pytest.raises(InputError, match=f"{name} must be True or False"):
        EKFSlam(*args, **{name: "no"})
    EKFSlam(*args, **{name: False})


@pytest.mark.parametrize("name", ["gating", "history", "articulated"])
def test_graph_slam(name):
    pytest.importorskip("gtsam")
    from artmotion.articulation.slam.graph import GraphSlam

    args = ([0.0, 0.0, 0.0], 0.1, [0.05, 0.005, 0.005, 0.05], 0.1, 0.02, 10)
    with pytest.raises(InputError, match=f"{name} must be True or False"):
        GraphSlam(*args, **{name: "no"})


@pytest.mark.parametrize("name", ["online", "progress"])
def test_track(name, sample_seq):
    from artmotion.tracking import track

    with pytest.raises(InputError, match=f"{name} must be True or False"):
        track(sample_seq, **{name: "no"})
