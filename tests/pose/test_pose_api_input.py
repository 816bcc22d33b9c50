"""Bad input to the pose API (PoseFilter, PoseRegressor's parameters) is an InputError naming the
parameter; valid input reads as before."""

import cv2
import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.pose import PoseFilter, PoseRegressor
from artmotion.pose import features as F

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
    crop = [np.random.default_rng(0).integers(0, 256, (50, 70, 3), dtype=np.uint8)]
    for given, whole in ((dict(cell=8.0, size=[64, 96]), dict(cell=8, size=(64, 96))),
                         (dict(cell=np.int64(4), size=np.array([32, 40])), dict(cell=4, size=(32, 40)))):
        reg = PoseRegressor(**given)
        assert all(getattr(reg, k) is v for k, v in given.items())  # kept as given (scikit-learn) ...
        np.testing.assert_array_equal(reg.features(crop), PoseRegressor(**whole).features(crop))  # ... used as whole


# -- PoseRegressor as a scikit-learn estimator; its parameters used as the numbers they are; any crops

@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """40 rendered crops (uint8 BGR, about 85x105 pixels) and their 4 angles."""
    from artmotion.pose.data import load_labelled
    from artmotion.pose.render import write_dataset

    root = tmp_path_factory.mktemp("rendered") / "r"
    write_dataset(root, 40, seed=1, frames=False)
    _, _, imgs, Y = load_labelled(root / "crops", root / "labels.csv")
    return imgs, Y


def test_regressor_is_a_scikit_learn_estimator(rendered, tmp_path):
    from sklearn.base import BaseEstimator, clone
    from sklearn.exceptions import NotFittedError
    from sklearn.utils.validation import check_is_fitted

    imgs, Y = rendered
    reg = PoseRegressor()
    assert isinstance(reg, BaseEstimator) and repr(reg) == "PoseRegressor()"
    assert reg.get_params()["cell"] is None and reg.get_params()["blur"] is None  # no default resolved in __init__
    assert clone(reg).get_params() == reg.get_params()
    given = dict(feature="lbp", cell=8.0, blur=0, size=[64, 48], n_components=np.float64(8), seed=3.0, n_opt=30)
    reg = PoseRegressor(**given)
    params = reg.get_params()
    assert all(params[k] is v for k, v in given.items())  # every parameter stored as given, unconverted
    assert "feature='lbp'" in repr(reg) and "cell=8.0" in repr(reg) and "method" not in repr(reg)
    other = PoseRegressor().set_params(**params)
    assert other.get_params() == params and repr(other) == repr(reg)
    assert other.set_params(cell=None).cell is None and reg.cell == 8.0
    with pytest.raises(NotFittedError):
        check_is_fitted(reg)
    reg.fit(imgs, Y)
    check_is_fitted(reg)
    assert reg.get_params() == params  # fit converts nothing in place
    copy = clone(reg)  # an unfitted model of the same parameters (deep copies of them)
    assert copy.get_params() == params and all(type(copy.get_params()[k]) is type(v) for k, v in given.items())
    with pytest.raises(NotFittedError):
        check_is_fitted(copy)
    with pytest.raises(InputError, match="not fitted yet"):
        copy.predict(imgs[:2])
    np.testing.assert_allclose(copy.fit(imgs, Y).predict(imgs[:5]), reg.predict(imgs[:5]))
    reg.save(tmp_path / "m.npz")  # the resolved values in the file; read back, the same model
    back = PoseRegressor.load(tmp_path / "m.npz")
    assert (back.feature, back.cell, back.size, back.blur) == ("lbp", 8, (64, 48), 0.0)
    np.testing.assert_allclose(back.predict(imgs[:5]), reg.predict(imgs[:5]), atol=1e-6)


@pytest.mark.parametrize("params", [dict(n_components=16.0), dict(n_components=np.float64(16)), dict(seed=0.0),
                                    dict(n_opt=20.0), dict(neighbours=8.0), dict(method="sparse", n_inducing=10.0),
                                    dict(method="sparse", n_inducing=10, n_inducing_var=np.float64(5))])
def test_whole_number_floats_are_taken_as_the_integers_they_are(rendered, params):
    imgs, Y = rendered
    Y = Y[:, :2]  # (two angles: half the hyper-parameter searches)
    reg = PoseRegressor(**{"n_components": 12, **params}).fit(imgs, Y)
    assert all(getattr(reg, k) is v for k, v in params.items())  # used as whole numbers, stored as given
    whole = {k: v if isinstance(v, str) else int(v) for k, v in params.items()}
    want = PoseRegressor(**{"n_components": 12, **whole}).fit(imgs, Y).predict(imgs[:5], return_std=True)
    got = reg.predict(imgs[:5], return_std=True)
    np.testing.assert_allclose(got[0], want[0])
    np.testing.assert_allclose(got[1], want[1])
    assert np.isnan(reg.domain_auc(imgs)) if "seed" in params else True  # (too few crops to judge; no seed error)


def test_crops_are_uint8_uint16_or_floats_in_0_1(rendered):
    imgs, Y = rendered
    reg = PoseRegressor(feature="lbp", n_components=8).fit(imgs[:30], Y[:30])
    test = imgs[30:]
    want = reg.predict(test)
    # the same pictures as uint16 (0..65535) and as floats in [0, 1]: the same angles (to resampling rounding)
    np.testing.assert_allclose(reg.predict([im.astype(np.uint16) * 257 for im in test]), want, atol=0.5)
    np.testing.assert_allclose(reg.predict([im.astype(np.float32) / 255 for im in test]), want, atol=0.5)
    assert F.extract([np.zeros((48, 64)), np.ones((48, 64), np.float32)], "lbp").shape == (2, 696)  # the ends
    # integer crops of other types were read as [0, 1] intensities (LBP angles off by up to 8 degrees)
    for dtype in (np.int64, np.int32, np.int16, np.uint32, np.bool_):
        with pytest.raises(InputError, match=f"crop 1 is {np.dtype(dtype)}.*uint8"):
            reg.predict([test[0], test[1].astype(dtype)])
    with pytest.raises(InputError, match="crop 0 is int64"):
        reg.fit([im.astype(np.int64) for im in imgs], Y)
    # float crops of 0..255 (or any value outside [0, 1]) are refused, not taken as far too bright
    for bad in (test[2].astype(np.float64), test[2].astype(np.float32) / 255 - 0.1):
        with pytest.raises(InputError, match=r"crop 2 .*float.* outside \[0, 1\]"):
            reg.predict([test[0], test[1], bad])
        with pytest.raises(InputError, match=r"crop 2 .*outside \[0, 1\]"):
            F.extract([test[0], test[1], bad], "hog")
    with pytest.raises(InputError, match="outside"):
        reg.predict(np.stack([np.full((48, 64, 3), 2.0)] * 3))  # an (n, H, W, 3) float stack too


def test_a_grey_crop_of_one_channel_and_any_iterable_of_crops_are_taken(rendered):
    imgs, Y = rendered
    grey = [cv2.cvtColor(im, cv2.COLOR_BGR2GRAY) for im in imgs]
    reg = PoseRegressor(n_components=8)
    np.testing.assert_array_equal(reg.features([g[:, :, None] for g in grey]), reg.features(grey))  # (H, W, 1)
    np.testing.assert_array_equal(reg.features(np.stack([g[:40, :80, None] for g in grey[:3]])),
                                  reg.features([g[:40, :80] for g in grey[:3]]))  # an (n, H, W, 1) stack
    with pytest.raises(InputError, match="one 40x80x1 image: pass \\[image\\]"):
        reg.features(grey[0][:40, :80, None])
    # a generator or map of crops, as a list
    ref = PoseRegressor(n_components=8).fit(imgs, Y)
    got = PoseRegressor(n_components=8).fit((im for im in imgs), Y)
    np.testing.assert_array_equal(got.predict(map(np.asarray, imgs[:5])), ref.predict(imgs[:5]))
    mean, std = got.predict(iter(imgs[:5]), return_std=True)
    assert mean.shape == std.shape == (5, 4)
    np.testing.assert_array_equal(reg.features(im for im in imgs[:3]), reg.features(imgs[:3]))
    np.testing.assert_array_equal(F.extract(iter(imgs[:3]), "hog", blur=0.7), reg.features(imgs[:3]))
    assert np.isnan(got.domain_auc(im for im in imgs))  # (fewer crops than it judges)
    for bad in (5, None, "crops/"):
        with pytest.raises(InputError, match="crops"):
            reg.features(bad)


@pytest.mark.parametrize("option", [("--feature", "sift"), ("--method", "fast")])
def test_the_command_line_refuses_a_misspelt_name_before_it_reads_an_image(tmp_path, run_cli, option):
    # the parameters are checked by fit; feature and method (names) also when the model is made
    (tmp_path / "crops").mkdir()
    (tmp_path / "crops" / "a.png").write_bytes(b"not an image")
    (tmp_path / "labels.csv").write_text("image,yaw\na.png,1\n")
    code, _, err = run_cli("pose", "train", tmp_path / "crops", tmp_path / "labels.csv", *option,
                           "--model", tmp_path / "m.npz")
    assert code == 2 and f"unknown {option[0][2:]} '{option[1]}'" in err and "a.png" not in err


def test_a_model_whose_angles_are_not_numbers_is_named_not_written(rendered, tmp_path):
    """Numbers that pass load's checks can still give NaN (a length scale of 1e-30 underflows every
    kernel row): predict names the model file instead of returning NaN angles as measured."""
    imgs, Y = rendered
    PoseRegressor(feature="hog").fit(imgs, Y).save(tmp_path / "m.npz")
    with np.load(tmp_path / "m.npz") as z:
        d = dict(z)
    d["hypers"][:, 0] = 1e-30
    np.savez(tmp_path / "bad.npz", **d)
    bad = PoseRegressor.load(tmp_path / "bad.npz")   # (its test prediction passes)
    with pytest.raises(InputError, match="damaged pose model") as err:
        bad.predict(imgs, return_std=True)
    assert err.value.path == str(tmp_path / "bad.npz")


def test_ragged_or_text_labels_are_an_input_error():
    """Ragged label rows were NumPy's bare ValueError ("inhomogeneous shape")."""
    X = np.random.default_rng(0).random((40, 6))
    for Y in ([[1.0, 2.0]] * 39 + [[1.0]], [["a", "b"]] * 40):
        with pytest.raises(InputError, match="labels must be an array of numbers"):
            PoseRegressor().fit(X, Y, ["a", "b"])
