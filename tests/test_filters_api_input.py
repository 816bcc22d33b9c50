"""The Kalman filter used the filterpy way, by assigning its attributes (``kf.R = 0.5``, ``kf.x = [0, 0]``):
an assignment is checked and converted as the constructor checks and converts (a number for a
covariance is that variance times the identity, lists become float arrays, a column ``x`` or ``z``
is a vector), and a shape that does not fit is an InputError naming the attribute and the size it
must have, never a raw NumPy error or a silently broadcast matrix."""

import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.filters import KalmanFilter

F = [[1.0, 1.0], [0.0, 1.0]]


def _kf(**kw) -> KalmanFilter:
    args = {"x": [0, 0], "P": np.eye(2) * 10, "F": F, "Q": np.eye(2) * 0.01, "H": [[1, 0]], "R": [[0.5]]} | kw
    return KalmanFilter(**args)


def _same(a: KalmanFilter, b: KalmanFilter) -> None:
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.P, b.P)
    assert a.log_likelihood == b.log_likelihood


def test_assigned_numbers_for_covariances_are_that_variance_times_the_identity():
    kf = _kf()
    kf.R = 0.5                                   # (once: a raw ValueError from matmul at the update)
    kf.predict()
    kf.update(1.0)
    ref = _kf()
    ref.predict()
    ref.update(1.0)
    _same(kf, ref)
    kf = _kf()
    kf.Q = 0.01                                  # (once: 0.01 added to every entry of P, off-diagonals too)
    kf.predict()
    ref = _kf()
    ref.predict(Q=0.01)
    _same(kf, ref)
    _same(kf, (lambda k: (k.predict(), k)[1])(_kf(Q=0.01)))   # the constructor takes a number alike
    np.testing.assert_array_equal(kf.Q, 0.01 * np.eye(2))
    kf.P = 4.0
    np.testing.assert_array_equal(kf.P, 4.0 * np.eye(2))


def test_assigned_lists_and_columns_are_float_vectors_and_arrays():
    kf = _kf()
    kf.x = [0.0, 0.0]                            # (once: AttributeError, 'list' has no shape)
    kf.predict()
    assert isinstance(kf.x, np.ndarray) and kf.x.dtype == float
    kf.x = np.array([[1.0], [2.0]])              # a column, as the constructor takes it (once: "x must be a vector")
    assert kf.x.shape == (2,) and kf.x.tolist() == [1.0, 2.0]
    kf.F = F
    kf.H = [[1, 0]]
    assert kf.F.dtype == float and kf.H.dtype == float
    ref = _kf(x=[[1.0], [2.0]])
    kf.P = np.eye(2) * 10
    kf.predict()
    ref.predict()
    _same(kf, ref)


def test_a_column_measurement_is_a_vector():
    kf, ref = _kf(), _kf()
    kf.update(np.array([[1.0]]))                 # filterpy's own convention (once: "z must hold 1 value")
    ref.update([1.0])
    _same(kf, ref)
    two, ref = _kf(H=np.eye(2), R=np.eye(2)), _kf(H=np.eye(2), R=np.eye(2))
    two.update(np.array([[1.0], [2.0]]))
    ref.update([1.0, 2.0])
    _same(two, ref)
    with pytest.raises(InputError, match=r"z must hold 2 values \(the rows of H\), got shape \(2, 2\)"):
        two.update(np.eye(2))


def test_assignments_are_copied_and_keep_the_filter_unchanged_when_refused():
    kf = _kf()
    Q = np.eye(2) * 0.01
    kf.Q = Q
    Q[0, 0] = -1.0                               # the caller's array, changed after the assignment
    kf.predict()
    ref = _kf()
    ref.predict()
    _same(kf, ref)


@pytest.mark.parametrize("name, value, message", [
    ("P", [[1.0, 2.0], [2.0, 1.0]], "P must be positive semi-definite"),
    ("Q", -1.0, "Q must be a non-negative variance, got -1"),
    ("R", np.nan, "R must be a finite variance, got nan"),
    ("R", [[1.0, 0.5], [0.0, 1.0]], "R must be symmetric"),
    ("F", "abc", "F must be an array of numbers"),
    ("F", [[1.0, np.inf], [0.0, 1.0]], "F contains NaN or infinite values"),
    ("F", 2.0, r"F must be a square matrix, got shape \(\)"),
    ("H", [[np.nan, 0.0]], "H contains NaN"),
    ("H", np.zeros((2, 2, 2)), r"H must be a matrix \(m, n\)"),
    ("x", [np.nan, 0.0], "x must be a non-empty state of finite numbers"),
    ("x", np.eye(2), r"x must be a vector .*got shape \(2, 2\)"),
    ("x", [], "x must be a non-empty state"),
], ids=["P-not-psd", "Q-negative", "R-nan", "R-asymmetric", "F-text", "F-inf", "F-number", "H-nan", "H-3d",
        "x-nan", "x-matrix", "x-empty"])
def test_bad_assignments_are_refused_naming_the_attribute(name, value, message):
    kf = _kf()
    before = getattr(kf, name).copy()
    with pytest.raises(InputError, match=f"Kalman filter: {message}"):
        setattr(kf, name, value)
    np.testing.assert_array_equal(getattr(kf, name), before)


def test_a_size_that_does_not_fit_is_named_with_the_size_it_must_have():
    kf = _kf()
    kf.Q = [[0.5]]                               # (once: broadcast over the 2 x 2 P, silently)
    with pytest.raises(InputError, match=r"Q must have shape \(2, 2\), got \(1, 1\)"):
        kf.predict()
    kf = _kf(H=np.eye(2), R=np.eye(2))
    kf.R = [[0.5]]                               # (once: broadcast over S, silently)
    with pytest.raises(InputError, match=r"R must have shape \(2, 2\), got \(1, 1\) \(.*measured value"):
        kf.update([1.0, 2.0])
    with pytest.raises(InputError, match=r"R must have shape \(2, 2\), got \(3, 3\) \(.*measured value"):
        KalmanFilter([0, 0], np.eye(2), F, np.eye(2), np.eye(2), np.eye(3))   # (once: "for a state of 2")
    kf = _kf()
    with pytest.raises(InputError, match=r"R must have shape \(2, 2\), got \(1, 1\)"):
        kf.update([1.0, 2.0], H=np.eye(2))       # a new H with the filter's R of one row (once: broadcast)
    kf.update([1.0, 2.0], H=np.eye(2), R=0.5)   # a number: 0.5 times the identity of the new H's rows
    kf = _kf()
    kf.H = [[1.0, 0.0, 0.0]]
    with pytest.raises(InputError, match=r"H must have shape \(m, 2\) for a state of 2, got \(1, 3\)"):
        kf.update([1.0])


def test_a_state_of_another_size_is_taken_attribute_by_attribute():
    kf = _kf()
    kf.x = [0.0, 0.0, 0.0]                       # filterpy's way: one attribute after the other
    kf.P = 10.0
    kf.F = np.eye(3)
    kf.Q = 0.01
    with pytest.raises(InputError, match=r"H must have shape \(m, 3\)"):
        kf.predict()
    kf.H = [[1.0, 0.0, 0.0]]
    kf.predict()
    kf.update(1.0)
    assert kf.x.shape == (3,) and kf.P.shape == (3, 3)


def test_in_place_operations_work_as_in_filterpy():
    kf = _kf()
    kf.P *= 10.0
    kf.x[0] = 1.0
    np.testing.assert_array_equal(kf.P, np.eye(2) * 100)
    kf.predict()
    assert kf.x.tolist() == [1.0, 0.0]


def test_models_and_likelihoods_beyond_the_floats_are_input_errors():
    """Order 2**63 or 10**9 axes asked for all the memory; dt = 1e155 and a 1e200 innovation
    overflowed (OverflowError), noise 1e308 gave an all-inf Q without a word."""
    from artmotion.filters.kalman import gaussian_loglik
    from artmotion.filters.models import taylor_model

    for args in ((100000, 0.1), (2**63, 0.1), (2, 0.1, 1.0, 10**9), (2, 1e155), (2, 10.0, 1e308)):
        with pytest.raises(InputError):
            taylor_model(*args)
    for y, S in ((1e200, np.eye(1)), (1e150, 1e-200 * np.eye(1))):
        with pytest.raises(InputError, match="beyond the floats"):
            gaussian_loglik(np.array([y]), S)
    F, Q = taylor_model(2, 0.1, 1.0, 3)
    assert F.shape == Q.shape == (6, 6) and np.isfinite(Q).all()
