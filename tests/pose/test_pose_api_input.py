"""Bad input to the pose API (PoseFilter, PoseRegressor's parameters) is an InputError naming the
parameter; valid input reads as before."""

import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.pose import PoseFilter, PoseRegressor

MEANS = np.column_stack([np.linspace(0, 10, 8), np.linspace(5, 6, 8)])
ONES = np.ones_like(MEANS)


@pytest.mark.parametrize("run", ["filter", "smooth"])
def test_standard_deviations_whose_squares_overflow_are_refused(run):
    # (std**2 overflowed: smooth gave NaN everywhere, filter from the second row on)
    with pytest.raises(InputError, match="standard deviations must be finite, non-negative and at most 1e\\+100"):
        getattr(PoseFilter([1.0, 1.0]), run)(MEANS, np.full_like(MEANS, 1e200))
    with pytest.raises(InputError, match="standard deviations"):
        PoseFilter([1.0, 1.0]).step(MEANS[0], [1e200, 1.0])
    out, sd = getattr(PoseFilter([1.0, 1.0]), run)(MEANS, np.full_like(MEANS, 1e100))  # the largest: finite
    assert np.isfinite(out).all() and np.isfinite(sd).all()


def test_a_frame_interval_or_variance_whose_powers_overflow_is_refused():
    with pytest.raises(InputError, match=r"dt must be a number in \(0, 1e\+07\], got 1e\+100"):
        PoseFilter([1.0, 1.0], dt=1e100)
    for name in ("accel_var", "filter_std", "smooth_std"):
        kwargs = {"accel_var": [1.0, 1.0], name: [1e300, 1.0]}
        with pytest.raises(InputError, match=f"{name} must be finite, positive and at most"):
            PoseFilter(**kwargs)


def test_values_in_range_but_out_of_scale_for_one_another_are_an_input_error():
    # each within its bound, together the predicted covariance is singular (numerically)
    std = np.full_like(MEANS, 1e12)
    std[::2] = 1.0
    with pytest.raises(InputError, match="out of scale for one another"):
        PoseFilter([1e-300, 1e-300], dt=1e7).smooth(MEANS, std)


def test_multipliers_are_one_or_one_per_angle_checked_when_the_filter_is_made():
    with pytest.raises(InputError, match=r"filter_std must be one multiplier or one per angle \(2\), got shape \(3,\)"):
        PoseFilter([1.0, 1.0], filter_std=[1, 2, 3])
    with pytest.raises(InputError, match="smooth_std must be one multiplier or one per angle"):
        PoseFilter([1.0, 1.0], smooth_std=[[1.0, 2.0]])
    for mult in (2.0, [2.0], [2.0, 3.0]):  # one, or one per angle
        _, sd = PoseFilter([1.0, 1.0], filter_std=mult).filter(MEANS, ONES)
        assert sd.shape == MEANS.shape


@pytest.mark.parametrize("params, message", [
    (dict(size=(64,)), r"size must be a \(width, height\) pair, got \(64,\)"),
    (dict(size=64), r"size must be a \(width, height\) pair, got 64"),
    (dict(size=(64, 48, 3)), r"size must be a \(width, height\) pair"),
    (dict(size=(64.5, 48)), r"size \(crop width and height\) must be a whole number"),
    (dict(cell="x"), r"cell must be a whole number in \[2, 256\], got 'x'"),
    (dict(cell=2.7), r"cell must be a whole number in \[2, 256\], got 2.7"),
    (dict(blur="x"), r"blur must be a number"),
])
def test_regressor_size_and_cell_are_refused_by_name(params, message):
    reg = PoseRegressor(**params)  # scikit-learn style: made without a word (no int() cutting 2.7 to 2) ...
    X = np.random.default_rng(0).normal(size=(20, 5))
    with pytest.raises(InputError, match=message):  # ... refused by fit
        reg.fit(X, X[:, :2])
    with pytest.raises(InputError, match=message):  # and by features
        reg.features([np.zeros((30, 30, 3), np.uint8)])


def test_regressor_takes_whole_numbers_of_any_type():
    reg = PoseRegressor(cell=8.0, size=[64, 96])
    assert (reg.cell, reg.size) == (8, (64, 96)) and type(reg.cell) is int
    reg = PoseRegressor(cell=np.int64(4), size=np.array([32, 40]))
    assert (reg.cell, reg.size) == (4, (32, 40)) and all(type(v) is int for v in reg.size)
