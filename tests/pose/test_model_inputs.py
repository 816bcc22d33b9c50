"""``PoseRegressor`` refuses misuse with one clear :class:`InputError` instead of a silent wrong
answer (NaN angles, one prediction per image row) or a deep NumPy/scikit-learn/torch error."""

import math

import numpy as np
import pytest
from sklearn.exceptions import NotFittedError

from artmotion.errors import InputError
from artmotion.pose.model import PoseRegressor


def _crops(n=12, seed=0):
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 255, (40, 56, 3), dtype=np.uint8) for _ in range(n)]


def _labels(n=12):
    t = np.arange(n, dtype=float)
    return np.c_[10 * np.sin(t / 3), 5 * np.cos(t / 4)]


def _matrix(n=30, seed=1):
    X = np.random.default_rng(seed).normal(size=(n, 5))
    return X, np.c_[3 * X[:, 0], X[:, 1] - X[:, 2]]


@pytest.fixture(scope="module")
def fitted():
    return PoseRegressor(n_components=4, method="exact").fit(_crops(), _labels(), ["opening", "roll"])


def test_predict_refuses_one_image_a_bad_batch_and_non_finite_inputs(fitted):
    img = _crops(1, seed=5)[0]
    assert fitted.predict([img]).shape == (1, 2)
    assert fitted.predict(np.stack([img, img])).shape == (2, 2)  # an (n, H, W, 3) stack is a list of crops
    with pytest.raises(InputError, match="list of crops.*got one 40x56x3 image"):
        fitted.predict(img)
    with pytest.raises(InputError, match="one 40x56 image"):
        fitted.predict(img[:, :, 0])
    for batch in (0, -1, 2.5):
        with pytest.raises(InputError, match="batch"):
            fitted.predict([img, img], batch=batch)
    bad = np.full((40, 56, 3), 0.5, np.float32)
    bad[3, 4, 1] = np.nan
    with pytest.raises(InputError, match="crop holds NaN or infinite"):
        fitted.predict([img, bad])
    with pytest.raises(InputError, match="crop holds NaN or infinite"):
        fitted.predict(np.stack([bad * np.inf]))


def test_predict_checks_a_feature_matrix():
    X, Y = _matrix()
    reg = PoseRegressor(method="exact").fit(X, Y)
    assert np.isfinite(reg.predict(X[:3])).all()
    for value in (np.nan, np.inf, 1e300):
        Z = X[:3].copy()
        Z[1, 2] = value
        with pytest.raises(InputError, match="feature matrix holds"):
            reg.predict(Z)
    with pytest.raises(InputError, match="4 columns, but this model takes 5"):
        reg.predict(X[:3, :4])


@pytest.mark.parametrize("params", [dict(n_opt=0), dict(n_opt=1), dict(n_components=0), dict(net_steps=0), dict(seed=-1),
                                    dict(neighbours=-3), dict(neighbours=0), dict(blur=math.nan), dict(blur=math.inf),
                                    dict(inducing="bogus"), dict(method="sparse", n_inducing=0),
                                    dict(n_inducing_var=0), dict(restarts=-1), dict(max_exact=1.5),
                                    dict(opening_weight=math.nan), dict(net_beta=-1.0)])
def test_fit_refuses_invalid_parameters(params):
    X, Y = _matrix()
    reg = PoseRegressor(**params)  # scikit-learn style: made without a word, refused by fit
    name = next(iter(params)) if "n_inducing" not in params else "n_inducing"
    with pytest.raises(InputError, match=name):
        reg.fit(X, Y)


def test_fit_refuses_a_method_set_after_the_model_is_made():
    X, Y = _matrix()
    reg = PoseRegressor()
    reg.method = "bogus"
    with pytest.raises(InputError, match="unknown method 'bogus'"):
        reg.fit(X, Y)


def test_fit_refuses_bad_features_labels_and_names():
    X, Y = _matrix()
    for value, what in ((np.nan, "NaN or infinite"), (np.inf, "NaN or infinite"), (1e300, "beyond")):
        Xb, Yb = X.copy(), Y.copy()
        Xb[4, 1] = Yb[4, 1] = value
        with pytest.raises(InputError, match=f"feature matrix holds.*{what}" if what != "beyond" else "feature matrix.*beyond"):
            PoseRegressor().fit(Xb, Y)
        with pytest.raises(InputError, match=f"labels.*{what}"):
            PoseRegressor().fit(X, Yb)
    with pytest.raises(InputError, match="one column per angle, got shape"):
        PoseRegressor().fit(X, np.zeros((len(X), 0)))
    with pytest.raises(InputError, match="need at least 3 training examples"):
        PoseRegressor().fit(X[:0], Y[:0])
    with pytest.raises(InputError, match="1 angle names for 2 label columns"):
        PoseRegressor().fit(X, Y, names=["opening"])
    with pytest.raises(InputError, match="distinct, non-empty"):
        PoseRegressor().fit(X, Y, names=["a", "a"])
    with pytest.raises(InputError, match="not one string"):
        PoseRegressor().fit(X, Y, names="ab")
    with pytest.raises(InputError, match="list of crops"):
        PoseRegressor().fit(_crops(1)[0], Y[:40])
    assert PoseRegressor().fit(X, Y[:, 0]).names_ == ["angle0"]  # one angle as a vector


def test_a_fitted_model_is_saved_and_read_back(fitted, tmp_path):
    fitted.save(tmp_path / "m.npz")  # what fit accepts (names checked against the labels) load reads back
    assert PoseRegressor.load(tmp_path / "m.npz").names_ == ["opening", "roll"]


def test_a_model_used_before_fit_says_so(tmp_path):
    reg = PoseRegressor()
    for use in (lambda: reg.predict(np.zeros((1, 5))), reg.make_filter, lambda: reg.save(tmp_path / "m.npz"),
                lambda: reg.domain_auc(np.zeros((1, 5)))):
        with pytest.raises(InputError, match="not fitted yet") as err:
            use()
        assert isinstance(err.value, NotFittedError)  # scikit-learn's convention too
    assert not (tmp_path / "m.npz").exists()


def test_a_model_fitted_on_a_feature_matrix_of_its_own_width_takes_no_crops():
    """Fitted on 10 columns where its HOG has 124, predict on crops failed in NumPy's matmul and
    save wrote a file that load called corrupt: both now say what the model takes."""
    rng = np.random.default_rng(0)
    reg = PoseRegressor(feature="hog", size=(16, 16), method="exact").fit(rng.random((30, 10)), rng.random((30, 2)))
    assert reg.predict(rng.random((3, 10))).shape == (3, 2)
    for call in (lambda: reg.predict([np.zeros((20, 20, 3), np.uint8)]), lambda: reg.save("never.npz")):
        with pytest.raises(InputError, match="fitted on a feature matrix of 10 columns, not on the 124"):
            call()
