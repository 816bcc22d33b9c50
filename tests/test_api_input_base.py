"""Input checks of the bottom layers (filters, rotations, atomic writes, MOT and events files):
bad input is an InputError that says what is wrong and what was got; valid input is unchanged."""

import json
import math
import re

import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.filters import KalmanFilter, constant_velocity, gaussian_loglik, taylor_model
from artmotion.filters.models import taylor_transition, white_noise_input
from artmotion.geometry import angle_between, axis_angle_to_matrix, matrix_to_axis_angle, matrix_to_quat, rotation_angle
from artmotion.io import atomic_write, read_events, read_mot, write_events, write_mot

# ---------------------------------------------------------------- Kalman filter


def _filter(n_meas: int = 1) -> KalmanFilter:
    H = np.eye(2)[:n_meas]
    return KalmanFilter([1.0, 1.0], np.eye(2), np.eye(2), np.eye(2), H, np.eye(n_meas))


@pytest.mark.parametrize("name", ["P", "Q", "R"])
def test_kalman_filter_refuses_a_covariance_that_is_not_positive_semi_definite(name):
    # symmetric with a non-negative diagonal, eigenvalues 3 and -1: not a covariance (once accepted:
    # after an update P held a negative variance and the log-likelihood looked confident)
    args = {"x": [0.0, 0.0], "P": np.eye(2), "F": np.eye(2), "Q": np.zeros((2, 2)), "H": np.eye(2), "R": np.eye(2)}
    args[name] = [[1.0, 2.0], [2.0, 1.0]]
    with pytest.raises(InputError, match=rf"{name} must be positive semi-definite .* smallest eigenvalue is -1"):
        KalmanFilter(**args)


def test_kalman_filter_refuses_an_asymmetric_covariance():
    with pytest.raises(InputError, match="P must be symmetric .* by up to 0.5"):
        KalmanFilter([0.0, 0.0], [[1.0, 0.5], [0.0, 1.0]], np.eye(2), np.zeros((2, 2)), [[1.0, 0.0]], [[1.0]])
    with pytest.raises(InputError, match="Q must be symmetric"):
        KalmanFilter([0.0] * 3, np.eye(3), np.eye(3), [[1, 0, 0.1], [0, 1, 0], [0, 0, 1]], [[1.0, 0, 0]], [[1.0]])


def test_kalman_filter_accepts_singular_covariances_with_round_off():
    # the Taylor models' Q is of rank 1 per axis: its smallest eigenvalues are round-off around 0
    for order, dims in ((2, 1), (3, 1), (2, 2)):
        F, Q = taylor_model(order, 0.04, 2.0, dims)
        n = order * dims
        kf = KalmanFilter(np.zeros(n), Q, F, Q, np.eye(n)[:1], [[0.0]])
        kf.predict(F, Q)
        kf.predict(Q=Q * 3.0)


@pytest.mark.parametrize("override, message", [
    ({"R": [[1.0, np.nan], [np.nan, 1.0]]}, "R contains NaN"),
    ({"R": np.inf}, "R must be a finite variance, got inf"),
    ({"R": [[1.0, 0.0], [0.0, -1.0]]}, "R has a negative variance on its diagonal"),
    ({"R": [[1.0, 2.0], [2.0, 1.0]]}, "R must be positive semi-definite"),
    ({"H": [[np.nan, 0.0], [0.0, 1.0]]}, "H contains NaN"),
    ({"H": "abc"}, "H must be an array of numbers"),
], ids=["R-nan", "R-inf", "R-negative", "R-not-psd", "H-nan", "H-text"])
def test_kalman_update_refuses_bad_overrides_and_keeps_the_state(override, message):
    kf = _filter(2)
    x, P = kf.x.copy(), kf.P.copy()
    with pytest.raises(InputError, match=message):
        kf.update([1.0, 2.0], **override)
    np.testing.assert_array_equal(kf.x, x)      # (a NaN override once made the state NaN)
    np.testing.assert_array_equal(kf.P, P)


def test_kalman_update_refuses_an_infinite_measurement_variance():
    kf = _filter()
    with pytest.raises(InputError, match="R must be a finite variance, got inf"):
        kf.update([1.0], R=math.inf)            # (once: a log-likelihood of -inf)


@pytest.mark.parametrize("override, message", [
    ({"F": np.full((2, 2), np.nan)}, "F contains NaN"),
    ({"F": np.eye(3)}, r"F must have shape \(2, 2\), got \(3, 3\)"),
    ({"F": 2.0}, r"F must have shape \(2, 2\), got \(\)"),
    ({"Q": np.full((2, 2), np.nan)}, "Q contains NaN"),
    ({"Q": -0.5}, "Q must be a non-negative variance, got -0.5"),
    ({"Q": [[1.0, 2.0], [2.0, 1.0]]}, "Q must be positive semi-definite"),
    ({"Q": "abc"}, "Q must be an array of numbers"),
], ids=["F-nan", "F-shape", "F-number", "Q-nan", "Q-negative-number", "Q-not-psd", "Q-text"])
def test_kalman_predict_refuses_bad_overrides_and_keeps_the_state(override, message):
    kf = _filter()
    with pytest.raises(InputError, match=message):
        kf.predict(**override)
    np.testing.assert_array_equal(kf.x, [1.0, 1.0])
    np.testing.assert_array_equal(kf.P, np.eye(2))


def test_kalman_predict_takes_lists_and_a_number_for_q_as_filterpy_does():
    kf = _filter()
    kf.predict(F=[[1.0, 1.0], [0.0, 1.0]])      # a list (once: AttributeError)
    np.testing.assert_array_equal(kf.x, [2.0, 1.0])
    kf = _filter()
    kf.predict(Q=0.5)                            # filterpy: a scalar Q is Q times the identity
    np.testing.assert_array_equal(kf.P, 1.5 * np.eye(2))   # (once: 0.5 added to every entry)
    kf = _filter(2)
    a = _filter(2)
    assert kf.update([1.0, 2.0], R=0.5) == a.update([1.0, 2.0], R=0.5 * np.eye(2))


def test_kalman_overrides_give_the_results_they_gave():
    # a filter stepped with the same F, Q at every step (the overrides' checks skipped once seen)
    # and one with fresh copies each step agree bit for bit with the filter's own F, Q
    F, Q = taylor_model(3, 0.02, 0.7)
    kfs = [KalmanFilter([0.0, 0.0, 0.0], np.eye(3), F, Q, [[1.0, 0.0, 0.0]], [[1e-4]]) for _ in range(3)]
    for k in range(30):
        z = [math.sin(0.1 * k)]
        kfs[0].predict()
        kfs[1].predict(F, Q)
        kfs[2].predict(F.copy(), Q.copy())
        lls = [kf.update(z) for kf in kfs]
        assert lls[0] == lls[1] == lls[2]
    for kf in kfs[1:]:
        np.testing.assert_array_equal(kf.x, kfs[0].x)
        np.testing.assert_array_equal(kf.P, kfs[0].P)


def test_kalman_override_check_notices_a_matrix_changed_in_place():
    F, Q = taylor_model(2, 1.0, 1.0)
    kf = KalmanFilter([0.0, 0.0], np.eye(2), F, Q, [[1.0, 0.0]], [[1.0]])
    kf.predict(F, Q)
    Q[0, 0] = -1.0                               # the same array, now not a covariance
    with pytest.raises(InputError, match="Q has a negative variance"):
        kf.predict(F, Q)


@pytest.mark.parametrize("y, S, message", [
    ([1.0], 0.0, "the variance S must be positive, got 0"),
    ([1.0], [[-1.0]], "the variance S must be positive, got -1"),
    ([1.0], np.nan, "must be finite"),
    ([np.nan, 1.0], np.eye(2), "must be finite"),
    ([1.0, 1.0], [[1.0, 2.0], [2.0, 1.0]], "positive definite covariance, but its smallest eigenvalue is -1"),
    ([1.0, 1.0], 1.0, r"y must hold 1 value \(the size of S\), got shape \(2,\)"),
], ids=["zero", "negative", "nan-S", "nan-y", "not-pd", "y-shape"])
def test_gaussian_loglik_refuses_a_covariance_that_is_not_positive(y, S, message):
    with pytest.raises(InputError, match=message):       # (once: "math domain error", or NaN)
        gaussian_loglik(np.asarray(y), np.asarray(S))


def test_gaussian_loglik_unchanged():
    assert gaussian_loglik(np.array([1.0]), np.array([[2.0]])) == -0.5 * (math.log(2 * math.pi) + math.log(2.0) + 0.5)


# ---------------------------------------------------------------- Taylor models


@pytest.mark.parametrize("kwargs, message", [
    ({"dt": math.nan}, r"dt \(the time step\) must be a number in \[0, inf\), got nan"),
    ({"dt": -0.5}, r"dt \(the time step\) must be a number in \[0, inf\), got -0.5"),
    ({"noise_var": -1.0}, "noise variances must be finite and >= 0, got -1"),
    ({"noise_var": math.inf}, "noise variances must be finite and >= 0, got inf"),
    ({"order": 2.5}, r"order \(of the Taylor model\) must be a whole number in \[1, 20\], got 2.5"),
    ({"order": 0}, r"order \(of the Taylor model\) must be a whole number in \[1, 20\], got 0"),
    ({"order": True}, "order .* must be a whole number"),
], ids=["dt-nan", "dt-negative", "var-negative", "var-inf", "order-2.5", "order-0", "order-bool"])
def test_taylor_model_refuses_bad_steps_orders_and_variances(kwargs, message):
    args = {"order": 2, "dt": 0.1, "noise_var": 1.0} | kwargs
    with pytest.raises(InputError, match=message):
        taylor_model(**args)


def test_taylor_pieces_refuse_bad_orders_and_steps():
    for f in (taylor_transition, white_noise_input):
        with pytest.raises(InputError, match="order"):
            f(0, 0.1)
        with pytest.raises(InputError, match="dt"):
            f(2, math.nan)


def test_taylor_model_still_takes_a_zero_step_and_numpy_numbers():
    F, Q = taylor_model(2, 0.0)
    np.testing.assert_array_equal(F, np.eye(2))
    np.testing.assert_array_equal(Q, np.zeros((2, 2)))
    F, Q = taylor_model(np.int64(2), np.float64(0.5), np.array([1.0, 2.0]), dims=2)
    assert F.shape == (4, 4)
    F1, _, _ = constant_velocity(0.5, 1.0, dims=1)
    np.testing.assert_array_equal(F1, [[1.0, 0.5], [0.0, 1.0]])


# ---------------------------------------------------------------- atomic_write


@pytest.mark.parametrize("mode", ["a", "r", "r+", "x", "ab", "wx", "wbt", ""])
def test_atomic_write_refuses_modes_that_do_not_write_anew_and_leaves_the_file(tmp_path, mode):
    p = tmp_path / "log.txt"
    p.write_text("day 1\n")
    with pytest.raises(InputError, match=f"mode must be a write mode .*got {re.escape(repr(mode))}"):
        with atomic_write(p, mode) as fh:
            fh.write("day 2\n")
    assert p.read_text() == "day 1\n"           # ("a" once replaced it, "r" emptied it)
    assert sorted(q.name for q in tmp_path.iterdir()) == ["log.txt"]


@pytest.mark.parametrize("mode, data", [("w", "text"), ("wt", "text"), ("wb", b"bytes"), ("w+", "text")])
def test_atomic_write_takes_write_modes(tmp_path, mode, data):
    p = tmp_path / "out"
    p.write_text("old")
    with atomic_write(p, mode) as fh:
        fh.write(data)
    assert p.read_bytes() == (data if isinstance(data, bytes) else data.encode())


# ---------------------------------------------------------------- write_mot


@pytest.mark.parametrize("w, h", [(0.004, 4.0), (3.0, 0.001), (0.0049999, 2.0)])
def test_write_mot_refuses_a_size_it_would_write_as_zero(tmp_path, w, h):
    p = tmp_path / "t.txt"
    with pytest.raises(InputError, match=r"box size .* \(frame 1, id 7\) would be written as 0 .* read_mot refuses"):
        write_mot(p, [[1, 7, 1.0, 2.0, w, h]])
    assert not p.exists()


def test_write_mot_refuses_a_score_it_would_write_as_infinity(tmp_path):
    with pytest.raises(InputError, match="score .* would be written as infinity"):
        write_mot(tmp_path / "t.txt", [[1, 1, 1.0, 2.0, 3.0, 4.0, 1.7976e308]])


def test_write_mot_output_is_unchanged_and_read_back(tmp_path):
    p = tmp_path / "t.txt"
    write_mot(p, [[2, 1, 1, 2, 3, 4, 1], [1, 5, 1.234, -2.5, 0.005, 4, 0.98765], [1, 2, 0, 0, 10, 0.0051, 1]])
    assert p.read_text() == ("1,2,0.00,0.00,10.00,0.01,1,-1,-1,-1\n"
                             "1,5,1.23,-2.50,0.01,4.00,0.9877,-1,-1,-1\n"
                             "2,1,1.00,2.00,3.00,4.00,1,-1,-1,-1\n")
    assert read_mot(p).shape == (3, 10)


# ---------------------------------------------------------------- rotations


def test_matrix_to_axis_angle_refuses_a_stack():
    R = np.stack([axis_angle_to_matrix([0, 0, 1], 0.5), axis_angle_to_matrix([1, 0, 0], 1.0)])
    with pytest.raises(InputError, match=r"one 3x3 matrix, got a stack of shape \(2, 3, 3\)"):
        matrix_to_axis_angle(R)                  # (once: a (2, 3) "axis" and one angle)


@pytest.mark.parametrize("f", [matrix_to_quat, matrix_to_axis_angle, rotation_angle])
@pytest.mark.parametrize("R, message", [
    (2 * np.eye(3), r"not a rotation matrix: R Rᵀ differs from the identity by 3 \(tolerance 0.001\)"),
    (np.diag([1.0, 1.0, 3.0]), "not a rotation matrix: R Rᵀ differs from the identity by 8"),
    (np.diag([1.0, 1.0, -1.0]), r"its determinant is -1 \(a reflection\)"),
    (np.full((3, 3), np.nan), "R contains NaN or infinite values"),
    (np.eye(2), r"R must be a 3x3 rotation matrix.*got shape \(2, 2\)"),
    ("abc", "R must be an array of numbers"),
], ids=["2I", "diag-1-1-3", "reflection", "nan", "2x2", "text"])
def test_rotation_matrices_are_checked(f, R, message):
    with pytest.raises(InputError, match=message):   # (once: the identity, 1.047 rad or LinAlgError)
        f(R)


def test_a_stack_names_the_matrix_that_is_not_a_rotation():
    R = np.stack([np.eye(3), 2 * np.eye(3)])
    with pytest.raises(InputError, match=r"\(matrix 2\)"):
        matrix_to_quat(R)


def test_rotations_take_what_they_took():
    R = axis_angle_to_matrix([1.0, 2.0, 2.0], 0.7)
    axis, angle = matrix_to_axis_angle(R)
    np.testing.assert_allclose(axis, np.array([1.0, 2.0, 2.0]) / 3.0, atol=1e-12)
    assert math.isclose(angle, 0.7)
    assert axis_angle_to_matrix([0, 0, 1], [0.1, 0.2, 0.3]).shape == (3, 3, 3)
    assert matrix_to_quat(np.stack([R, R])).shape == (2, 4)
    np.testing.assert_allclose(rotation_angle(np.stack([R, np.eye(3)])), [0.7, 0.0], atol=1e-12)
    matrix_to_quat(R * (1 + 1e-5))               # round-off within the tolerance


@pytest.mark.parametrize("axis, angle, message", [
    ([0, 0, 0], 0.3, r"axis must be a non-zero vector .*got \[0.0, 0.0, 0.0\]"),
    ([np.nan, 0, 1], 0.3, "axis contains NaN"),
    ([[0, 0, 1], [1, 0, 0]], [0.1, 0.2], r"axis must be a 3-vector, got shape \(2, 3\)"),
    ([0, 0, 1], np.nan, "angle contains NaN"),
], ids=["zero-axis", "nan-axis", "stack-of-axes", "nan-angle"])
def test_axis_angle_to_matrix_refuses_a_zero_axis_and_nan(axis, angle, message):
    with pytest.raises(InputError, match=message):   # (once: a NaN matrix)
        axis_angle_to_matrix(axis, angle)


@pytest.mark.parametrize("u, v, message", [
    ([0, 0, 0], [1, 0, 0], r"u must be a non-zero vector .*got \[0.0, 0.0, 0.0\]"),
    ([1, 0, 0], [[1, 0, 0], [0, 0, 0]], r"v must be a non-zero vector .*row 2"),
    ([np.nan, 0, 0], [1, 0, 0], "u contains NaN"),
    ([1, 0, 0], [1, 0], r"same length, got shapes \(3,\) and \(2,\)"),
], ids=["zero-u", "zero-row-of-v", "nan", "lengths"])
def test_angle_between_refuses_a_zero_vector(u, v, message):
    with pytest.raises(InputError, match=message):   # (once: NaN)
        angle_between(u, v)


# ---------------------------------------------------------------- events


EVENT = {"type": "enter", "frame": 12, "tracks": [3], "side": "left", "x": 14.0, "y": 300.5}


@pytest.mark.parametrize("text, where", [('"q": 1e999', "'q'"), ('"meta": {"a": [1, -1e999]}', r"'meta'\['a'\]\[1\]")],
                         ids=["key", "nested"])
def test_read_events_refuses_a_number_that_overflows_to_infinity(tmp_path, text, where):
    p = tmp_path / "e.jsonl"
    p.write_text(json.dumps(EVENT) + "\n" + json.dumps(EVENT)[:-1] + ", " + text + "}\n")
    with pytest.raises(InputError, match=rf"e.jsonl:2: {where} is a number out of range: it overflows to infinity"):
        read_events(p)                           # (once: read as inf)


@pytest.mark.parametrize("extra, message", [
    ({"score": math.nan}, "'score' is nan"),
    ({"score": -math.inf}, "'score' is -inf"),
    ({"box": [1.0, math.inf]}, r"'box'\[1\] is inf"),
    ({"meta": {"a": np.float32("nan")}}, r"'meta'\['a'\] is nan"),
    ({"box": np.zeros(4)}, r"'box' is a NumPy array of shape \(4,\).*tolist"),
    ({"s": {1, 2}}, "'s' is a set, which JSON cannot hold"),
], ids=["nan", "-inf", "inf-in-list", "nan-float32-nested", "ndarray", "set"])
def test_write_events_refuses_values_json_cannot_hold(tmp_path, extra, message):
    p = tmp_path / "e.jsonl"
    with pytest.raises(InputError, match=f"event 2 for .*e.jsonl: {message}"):
        write_events(p, [EVENT, EVENT | extra])  # (once: a raw ValueError or TypeError)
    assert not p.exists()


def test_write_events_takes_numpy_numbers(tmp_path):
    p = tmp_path / "e.jsonl"
    write_events(p, [EVENT | {"frame": np.int64(12), "tracks": [np.int32(3)], "x": np.float32(14.0),
                              "y": np.float64(300.5), "flag": np.bool_(True)}])
    assert read_events(p) == [EVENT | {"flag": True}]
    assert p.read_text() == json.dumps(EVENT | {"flag": True}) + "\n"


def test_write_events_output_is_unchanged(tmp_path):
    p = tmp_path / "e.jsonl"
    events = [EVENT, {"type": "merge", "frame": 15, "tracks": [3, 4], "group": 9, "end_frame": 20,
                      "extra": {"a": [1, 2.5, None, True, "s"], 3: "k"}}]
    write_events(p, events)
    assert p.read_text() == "".join(json.dumps(e, sort_keys=False, allow_nan=False) + "\n" for e in events)


# ---------------------------------------------------------------- arrays of numbers


@pytest.mark.parametrize("value", [[1 + 2j, 3.0], ["1.5", "2"], np.array(["1"]), [1, "a"], np.array([1, "2"], dtype=object),
                                   np.array([1j]), np.array([np.complex64(1 + 2j), 1.0], dtype=object),
                                   np.array([np.array(1j), 1.0], dtype=object)])
def test_float_array_refuses_text_and_complex_numbers(value):
    # NumPy parses "1.5" and drops an imaginary part with only a ComplexWarning: an observation of
    # 1+2j was taken as 1, and text as the number it spells
    from artmotion.errors import float_array

    with pytest.raises(InputError, match="z must be an array of numbers"):
        float_array(value, "z")


def test_float_array_keeps_real_numbers_of_any_type():
    from artmotion.errors import float_array

    for value in ([1, 2], np.float32([1.5]), np.array([1, 2], dtype=object), np.int64(3), [[1.0, 2.0]]):
        out = float_array(value, "z")
        assert out.dtype == np.float64 and np.array_equal(out, np.asarray(value, dtype=float))


def test_read_events_refuses_only_a_line_repeated_exactly(tmp_path):
    # a key outside the grammar (a score) or x given as 5 and 5.0 are other lines, read as before
    from artmotion.io import read_events

    ev = {"type": "enter", "frame": 3, "tracks": [1], "side": "left"}
    lines = [{**ev, "score": 0.9}, {**ev, "score": 0.5}, {**ev, "x": 5}, {**ev, "x": 5.0}, {**ev, "side": None}, ev]
    p = tmp_path / "events.jsonl"
    p.write_text("".join(json.dumps(e) + "\n" for e in lines))
    assert len(read_events(p)) == 6
    p.write_text(p.read_text() + json.dumps(ev) + "\n")
    with pytest.raises(InputError, match=r"events.jsonl:7: the same event as line 6 \(a line repeated\)"):
        read_events(p)
