"""Pose regression from tool crops (Sec. 3.4).

``PoseRegressor(feature="hog").fit(images, Y)`` learns one GP per angle; ``predict(images,
return_std=True)`` gives the mean and the predictive standard deviation of every angle;
``make_filter()`` the temporal filter (Sec. 3.5, :mod:`artmotion.pose.filter`) tuned for them.
"""

from __future__ import annotations

import contextlib
import functools
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from sklearn.base import BaseEstimator

from artmotion.errors import InputError, check_bool, check_range, check_seed, float_array, need_package
from artmotion.io import atomic_path
from artmotion.io.files import as_path, read_head
from artmotion.pose import features as F
from artmotion.pose.data import MAX_KEYPOINT, prediction_header
from artmotion.pose.filter import PoseFilter, accel_variance, tune_filter
from artmotion.pose.gp import ExactGP, Hyper, SparseGP, fit_gp

MAGIC = "artmotion-pose-gp"
VERSION = 2
#: which angles a ``cnn`` model predicts with its network's read-out (``PoseRegressor(net_mean=...)``)
NET_MEANS = ("opening", "all", "none")
#: the last fraction of the training rows on which the GP's variance is calibrated
CALIBRATE = 0.2
#: the fewest labelled crops a model is trained on
MIN_EXAMPLES = 3
#: the fewest crops of one sequence whose GP variance is calibrated (:func:`artmotion.pose.gp.fit_gp`
#: calibrates on 10 held-out rows or more: the last ``CALIBRATE`` of 48 crops)
CALIBRATED_MIN = 48
#: :meth:`PoseRegressor.far_from_training`: the share of the GP's prior variance left at a crop that
#: no training crop explains (0.06-0.3 on unseen and dark renders, 0.96-1 on crops unlike every one
#: of a few near-identical training crops)
FAR_SHARE = 0.5
#: :meth:`PoseRegressor.domain_auc`: least AUC of crops that are not what the model was trained on,
#: the fewest crops it judges
FOREIGN_AUC = 0.9
DOMAIN_MIN = 100
#: the fewest distinct nearest training crops it judges by
DOMAIN_DISTINCT = 10


def is_foreign(auc: float) -> bool:
    """Whether :meth:`PoseRegressor.domain_auc` says the crops are not what the model was trained
    on (NaN, not judged: no)."""
    return bool(auc >= FOREIGN_AUC)


@functools.cache
def _threads():
    """threadpoolctl's view of the loaded thread pools, made once: ``threadpool_limits`` looks
    them all up again on every call (2 ms with torch loaded, longer than a frame's prediction).
    Only BLAS is limited through it; the BLAS libraries are loaded with NumPy, before it is made."""
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


#: largest count a parameter (steps, inducing inputs, neighbours, ...) may be
_MAX_COUNT = 2**31 - 1
#: a model file's arrays together (uncompressed) at most this many bytes
_MAX_MODEL_BYTES = 4 * 2**30
#: hyper-parameters of a model file (length scale, signal and noise variance) within [this, 1 / this]
_MIN_HYPER = 1e-30


@functools.cache
def _not_fitted_error() -> type:
    """The error of a model used before :meth:`PoseRegressor.fit`: an :class:`InputError` (one line
    from the command line) that is also scikit-learn's ``NotFittedError`` (made on first use:
    importing scikit-learn takes a while)."""
    from sklearn.exceptions import NotFittedError

    return type("PoseNotFittedError", (InputError, NotFittedError), {"__module__": __name__})


def _not_fitted() -> InputError:
    return _not_fitted_error()("this PoseRegressor is not fitted yet: call fit() or PoseRegressor.load() first")


def is_opening(name: str) -> bool:
    """Whether an angle column is the jaw opening (its name contains "open")."""
    return "open" in name.lower()


def calibration_order(n: int, groups=None) -> tuple[np.ndarray, int, np.ndarray]:
    """Rows reordered so that the calibration rows come last, how many they are, and a frame
    number per row (in the original order) whose steps are 1 only within a group.

    The calibration rows are the last ``CALIBRATE`` of every group (``groups`` None: of all rows);
    :meth:`PoseRegressor.fit` trains on the others and calibrates the GP's variance on them."""
    g = np.zeros(n, dtype=int) if groups is None else np.unique(np.asarray(groups), return_inverse=True)[1].ravel()
    if len(g) != n:
        raise InputError(f"{n} training rows but {len(g)} groups")
    held = np.zeros(n, dtype=bool)
    for k in np.unique(g):
        rows = np.flatnonzero(g == k)
        held[rows[len(rows) - int(round(len(rows) * CALIBRATE)):]] = True
    if n - held.sum() < 3:  # too few to train on: calibrate on none
        held[:] = False
    frames = np.arange(n) + 2 * np.concatenate([[0], np.cumsum(g[1:] != g[:-1])])
    return np.concatenate([np.flatnonzero(~held), np.flatnonzero(held)]), int(held.sum()), frames


#: the choices of :class:`PoseRegressor`'s ``method``
METHODS = ("auto", "exact", "sparse")


class _Params(NamedTuple):
    """:class:`PoseRegressor`'s numeric parameters as :meth:`PoseRegressor.fit` uses them: checked,
    defaults resolved, whole numbers as ``int`` (the estimator keeps them as given)."""

    cell: int
    size: tuple[int, int]
    blur: float
    n_components: int | None
    max_exact: int
    neighbours: int | None
    n_inducing: int
    n_inducing_var: int | None
    n_opt: int
    restarts: int
    seed: int
    net_steps: int
    opening_weight: float
    net_beta: float
    keypoint_weight: float


class PoseRegressor(BaseEstimator):
    """Joint angles from a tool crop: HOG/LBP/learned features + one GP per angle (scikit-learn style).

    Parameters: ``feature`` (``"hog"``, ``"lbp"`` or ``"cnn"``: a small network trained in
    ``fit`` on the training crops, :mod:`artmotion.pose.cnn`; needs PyTorch), ``cell`` (feature
    cell size; default 8 for HOG, 16 for LBP), ``size`` (crop resize, width×height), ``blur``
    (Gaussian sigma in pixels of the resized crop, against sensor noise; 0 = none; default 0.7,
    0 for ``cnn``), ``net_steps`` (``cnn``: training mini-batches of 64 crops), ``augment``
    (``cnn``: appearance augmentation while training), ``opening_weight`` (``cnn``: the loss
    weight of angles whose name contains "open", the jaw angle, against 1 for the others: the
    jaws are small in the crop and their look depends on the roll; 3 takes 8 % off its error on
    unseen motion, docs/pose.md), ``net_beta`` (``cnn``: the smooth L1 loss's quadratic zone in
    standard deviations of each angle; 0.05, nearly the absolute error, learns the median, which
    errs less on average than the mean a wide zone learns, docs/pose.md), ``keypoint_weight`` (``cnn``
    trained with ``keypoints``: the loss weight of each keypoint coordinate, an auxiliary target;
    docs/pose.md), ``net_mean`` (``cnn``:
    which angles take the network's own read-out of its feature as their mean, the GP giving
    their variance: ``"opening"`` (the default), ``"all"`` or ``"none"``. Away from its training
    crops a GP's mean falls back to the training mean, which pulls a wide-open or closed jaw
    towards half-open; the read-out extrapolates. Chosen on one unseen sequence and checked on
    four more, docs/pose.md), ``n_components`` (the features are projected on their first
    principal components before the GP; ``None`` keeps the raw feature), ``method`` (``"auto"``,
    ``"exact"``, ``"sparse"``), ``max_exact`` (``auto`` switches to the sparse GP above this many
    training examples), ``neighbours`` (the exact GP's variance from this many nearest training
    crops; ``None``: the exact ``O(n^2)`` variance), ``n_inducing`` (sparse GP),
    ``n_inducing_var`` (the sparse GP's variance from that many of its inducing inputs, a frame's
    variance 16× cheaper at 250 of 1000; ``None``: all of them), ``n_opt`` (subset used for
    hyper-parameter optimisation), ``restarts``, ``seed``, ``progress`` (tqdm bars), ``inducing``
    (``"kmeans"`` or ``"random"`` choice of the sparse GP's inducing inputs).

    A scikit-learn estimator: the parameters are kept as given (``get_params``, ``set_params``,
    ``sklearn.base.clone``) and checked, resolved (``None`` defaults) and taken as whole numbers
    where they are used (:meth:`fit`, :meth:`features`, :meth:`save`); only ``feature``,
    ``method`` and ``net_mean`` are also checked when the model is made, so that a command line
    refuses a misspelt name before it reads any image. The fitted state ends in ``_``.
    """

    # the fitted state, None until fit or load (class attributes: scikit-learn's check_is_fitted
    # looks for instance attributes ending in "_")
    net_: Any = None  # artmotion.pose.cnn.CropNet once a cnn model is fitted
    #: angles whose mean is the network's read-out, and its scale back to degrees (``cnn``)
    readout_: np.ndarray | None = None
    net_mu_: np.ndarray | None = None
    net_sd_: np.ndarray | None = None
    names_: list[str] | None = None
    source_: Path | None = None  # the file a loaded model came from (named by predict's errors)
    gp_: ExactGP | SparseGP | None = None
    accel_var_: np.ndarray | None = None
    #: multipliers of the filter's and the smoother's standard deviations (:func:`tune_filter`)
    filter_std_: np.ndarray | None = None
    smooth_std_: np.ndarray | None = None
    pca_mean_: np.ndarray | None = None
    pca_components_: np.ndarray | None = None

    def __init__(self, feature: str = "hog", cell: int | None = None, size: tuple[int, int] = (F.CROP_W, F.CROP_H),
                 blur: float | None = None, n_components: int | None = 128, method: str = "auto", max_exact: int = 6000,
                 neighbours: int | None = 16, n_inducing: int = 1000, n_opt: int = 500, restarts: int = 1,
                 seed: int = 0, progress: bool = False, inducing: str = "kmeans", net_steps: int = 3000,
                 augment: bool = True, opening_weight: float = 3.0, net_mean: str = "opening",
                 n_inducing_var: int | None = 250, net_beta: float = 0.05, keypoint_weight: float = 0.5):
        # the names only, and nothing stored but the parameters as given (scikit-learn: ``clone``
        # makes the model anew from ``get_params``); the numbers are checked by fit (_params)
        _check_choices(feature=feature, method=method, net_mean=net_mean)
        self.feature = feature
        self.cell = cell
        self.size = size
        self.blur = blur
        self.net_steps = net_steps
        self.augment = augment
        self.opening_weight = opening_weight
        self.net_beta = net_beta
        self.keypoint_weight = keypoint_weight
        self.net_mean = net_mean
        self.n_components = n_components
        self.method = method
        self.max_exact = max_exact
        self.neighbours = neighbours
        self.n_inducing = n_inducing
        self.n_inducing_var = n_inducing_var
        self.n_opt = n_opt
        self.restarts = restarts
        self.seed = seed
        self.progress = progress
        self.inducing = inducing

    def __sklearn_is_fitted__(self) -> bool:
        return self.gp_ is not None

    def _params(self) -> _Params:
        """The parameters checked and resolved, as :meth:`fit` uses them (scikit-learn checks in
        ``fit``, not in ``__init__``: a parameter may be set after the model is made); the ranges
        are those :meth:`load` accepts in a model file. The model's own parameters are left as given."""
        _check_choices(feature=self.feature, method=self.method, inducing=self.inducing, net_mean=self.net_mean)
        check_bool("progress", self.progress)
        check_bool("augment", self.augment)
        cell, size, blur = self._crop_params()

        def count(name: str, lo: int) -> int:
            return check_range(name, getattr(self, name), lo, _MAX_COUNT, integer=True)

        def optional(name: str) -> int | None:  # None: the raw feature, the exact variance, all inducing inputs
            return None if getattr(self, name) is None else count(name, 1)

        # (one hyper-parameter optimisation row gives NaN hyper-parameters: n_opt at least 2)
        return _Params(cell=cell, size=size, blur=blur, n_components=optional("n_components"),
                       max_exact=count("max_exact", 0), neighbours=optional("neighbours"), n_inducing=count("n_inducing", 1),
                       n_inducing_var=optional("n_inducing_var"), n_opt=count("n_opt", 2), restarts=count("restarts", 0),
                       seed=_seed(self.seed), net_steps=count("net_steps", 1),
                       opening_weight=float(check_range("opening_weight", self.opening_weight, 0.0, 1e6)),
                       net_beta=float(check_range("net_beta", self.net_beta, 0.0, 1e6)),
                       keypoint_weight=float(check_range("keypoint_weight", self.keypoint_weight, 0.0, 1e6)))

    def _crop_params(self) -> tuple[int, tuple[int, int], float]:
        """``cell``, ``size`` and ``blur``, the parameters of :meth:`features`, checked, their
        defaults resolved (``cell``: 8 for HOG, 16 for LBP; ``blur``: 0.7, 0 for ``cnn``) and whole
        numbers as ints."""
        _check_choices(feature=self.feature)
        cell = F.default_cell(self.feature) if self.cell is None else check_range("cell", self.cell, 2, 256, integer=True)
        size = self.size
        if not isinstance(size, (tuple, list, np.ndarray)) or len(size) != 2:
            raise InputError(f"size must be a (width, height) pair, got {size!r}")
        w, h = (check_range("size (crop width and height)", v, 8, 4096, integer=True) for v in size)
        # the network learns its own blur (augmentation); HOG and LBP need one against sensor noise
        blur = ((0.0 if self.feature == "cnn" else 0.7) if self.blur is None
                else float(check_range("blur", self.blur, 0.0, 100.0)))
        return cell, (w, h), blur

    # -- features
    def features(self, images: Iterable[np.ndarray] | np.ndarray) -> np.ndarray:
        """The feature matrix of crops (a list or any iterable of BGR/grey images: uint8, uint16
        or floats in [0, 1]; or an ``(n, H, W[, C])`` array), one row per crop."""
        images = F.crop_list(images)
        if isinstance(images, np.ndarray) and images.ndim == 2:
            raise _one_image(images)
        self._is_matrix(images)  # (one image of several channels: an error)
        return self._features(images)

    def _features(self, images, first: int = 0) -> np.ndarray:
        """:meth:`features` of a list or an array of crops, the first of which is crop ``first``
        (of what the caller was given: its messages name crops by their place there)."""
        cell, size, blur = self._crop_params()
        # (crop by crop: no mask as large as a whole stack of float crops; integer crops need none)
        if not (isinstance(images, np.ndarray) and images.dtype.kind not in "fc") and any(
                np.asarray(im).dtype.kind in "fc" and not np.isfinite(im).all() for im in images):
            raise InputError("a crop holds NaN or infinite pixel values")
        return F.extract(images, self.feature, size, cell, blur=blur, first=first)

    def _project(self, X: np.ndarray, views: np.ndarray | None = None) -> np.ndarray:
        """The GP's inputs: the learned feature of the network (``cnn``), the principal components
        of the feature, or the feature itself."""
        if self.net_ is not None:
            from artmotion.pose import cnn

            _, size, _ = self._crop_params()
            crops = np.asarray(X, dtype=np.float32).reshape(len(X), size[1], size[0], 3)
            return cnn.embed(self.net_, crops, views).astype(np.float64)
        if self.pca_components_ is None:
            return X
        assert self.pca_mean_ is not None  # set together with ``pca_components_``
        return (np.asarray(X, dtype=np.float32) - self.pca_mean_) @ self.pca_components_.T

    @property
    def uses_views_(self) -> bool:
        """Whether the model needs ``views`` (``features.box_views``) with every crop."""
        return self.net_ is not None and self.net_.extra > 0

    def _check_views(self, views, n: int, fitting: bool = False) -> np.ndarray | None:
        """``views`` checked; ``None`` for a model that does not use them (HOG, LBP, a network
        trained without them)."""
        if views is None:
            if self.uses_views_ and not fitting:
                raise InputError("this pose model was trained with the boxes' places in their frames: "
                                 "give the boxes with the crops (views=, or --boxes)")
            return None
        V = check_views(views, n)
        return V if (self.feature == "cnn" if fitting else self.uses_views_) else None

    # -- training / prediction
    def fit(self, images, Y, names: Sequence[str] | None = None, views=None, groups=None, keypoints=None):
        """Fit on crops (list of images) or a precomputed feature matrix, and angles ``Y`` (n, k).

        ``views`` (``cnn`` only, else ignored): :func:`artmotion.pose.features.box_views` of the
        crops' boxes; a model trained with them needs them at prediction too.

        ``keypoints`` (``cnn`` only, else ignored): ``(n, 2m)`` points of the tool in each crop as
        fractions of its width and height (x / w, y / h, as :func:`artmotion.pose.data.read_keypoints`
        gives them; NaN where not known), which the network learns to find besides the angles, each
        coordinate with the loss weight ``keypoint_weight`` (:func:`artmotion.pose.cnn.fit_net`).
        Only training uses them; the model predicts the angles from the crop alone.

        The GP's variance is calibrated on the last ``CALIBRATE`` of the rows (a ``cnn`` network
        never sees them). ``groups`` (one label per row: the recording or render each crop comes
        from, each group's rows in time order): the last ``CALIBRATE`` of every group instead, so
        that every kind of training motion is in the calibration, and the motion prior's second
        differences never straddle two groups. Without ``groups`` the rows are one sequence. On the
        same rows the filter is tuned (:func:`tune_filter`)."""
        p = self._params()
        Y = float_array(Y, "labels")
        if Y.ndim == 1:
            Y = Y[:, None]
        if Y.ndim != 2 or Y.shape[1] == 0:
            raise InputError(f"labels must be a matrix of one row per crop and one column per angle, got shape {Y.shape}")
        if not np.all(np.isfinite(Y)):
            raise InputError("labels contain NaN or infinite values")
        if Y.size and np.abs(Y).max() > _MAX_VALUE:  # (the GP's standardisation would overflow)
            raise InputError(f"labels hold values beyond ±{_MAX_VALUE:g}")
        names = _angle_names(names, Y.shape[1])
        X = self._as_features(F.crop_list(images))
        if len(X) != len(Y):
            raise InputError(f"{len(X)} images but {len(Y)} label rows")
        if len(X) < MIN_EXAMPLES:
            raise InputError(f"need at least {MIN_EXAMPLES} training examples, got {len(X)}")
        self.names_ = names
        self.pca_mean_ = self.pca_components_ = None
        self.net_ = self.readout_ = self.net_mu_ = self.net_sd_ = None
        V = self._check_views(views, len(X), fitting=True)
        K = check_keypoints(keypoints, len(X)) if self.feature == "cnn" else None
        order, n_cal, frames = calibration_order(len(X), groups)
        self.accel_var_ = accel_variance(Y, frames=frames)
        self.filter_std_ = self.smooth_std_ = np.ones(Y.shape[1])
        in_order = np.array_equal(order, np.arange(len(X)))  # without groups: no copy of the crops
        if self.feature == "cnn":
            need_package("torch", "tools", "the cnn pose feature")
            from artmotion.pose import cnn

            # the network never sees the calibration rows (the last ones of ``order``): a network's
            # feature of its own training crops is optimistic, and so would the variance be
            m = len(X) - n_cal
            rows = order[:m]
            crops = np.asarray(X[:m] if in_order else X[rows], dtype=np.float32).reshape(m, p.size[1], p.size[0], 3)
            weights = [p.opening_weight if is_opening(n) else 1.0 for n in self.names_]
            self.net_ = cnn.fit_net(crops, Y[rows], p.net_steps, seed=p.seed, extra=None if V is None else V[rows],
                                    augmented=self.augment, weights=np.array(weights), progress=self.progress,
                                    beta=p.net_beta, points=None if K is None else K[rows],
                                    point_weight=p.keypoint_weight)
            self.net_mu_, self.net_sd_ = cnn.target_scale(Y[rows])
            self.readout_ = np.array([self.net_mean == "all" or (self.net_mean == "opening" and is_opening(n))
                                      for n in self.names_])
        elif p.n_components is not None and p.n_components < min(X.shape):
            from sklearn.decomposition import PCA

            pca = PCA(p.n_components, svd_solver="randomized", random_state=p.seed).fit(X if in_order else X[order])
            self.pca_mean_ = pca.mean_.astype(np.float32)
            self.pca_components_ = pca.components_.astype(np.float32)
        # the GP's rows in ``order`` (calibration rows last); projected first, so no crop is copied
        Z = self._project(X, V)[order]
        self.gp_ = fit_gp(Z, Y[order], self.method, p.max_exact, p.n_inducing, p.n_opt, p.restarts, p.seed,
                          progress=self.progress, inducing=self.inducing, neighbours=p.neighbours,
                          calibrate=n_cal / len(X), n_inducing_var=p.n_inducing_var)
        if self.gp_.held_out is not None:  # the filter's motion prior, tuned on the calibration rows
            cal = order[len(X) - n_cal:]
            mean, std = self.gp_.held_out
            assert len(mean) == n_cal, "the GP held out other rows than the calibration rows"
            mean = mean.copy()  # the read-out below replaces columns: not in the GP's own record
            if self.readout_ is not None and self.readout_.any():  # the network never saw these rows
                mean[:, self.readout_] = self._readout(Z[len(X) - n_cal:])[:, self.readout_]
            scale, self.filter_std_, self.smooth_std_ = tune_filter(Y[cal], mean, std, self.accel_var_, frames[cal])
            self.accel_var_ = self.accel_var_ * scale
        return self

    @staticmethod
    def _is_matrix(images) -> bool:
        """Whether ``images`` is a feature matrix (checked: finite numbers) rather than crops (a
        list, or an ``(n, H, W[, 3])`` array); one image is neither (its rows are no crops)."""
        if not isinstance(images, np.ndarray):
            return False
        if images.ndim == 2 and images.dtype != np.uint8:
            if images.dtype.kind not in "fiu":
                raise InputError(f"a feature matrix must hold real numbers, got {images.dtype}")
            if not np.isfinite(images).all():
                raise InputError("the feature matrix holds NaN or infinite values")
            if images.size and np.abs(images).max() > _MAX_VALUE:
                raise InputError(f"the feature matrix holds values beyond ±{_MAX_VALUE:g}")
            if images.shape[1] == 0:    # (fitted, it would predict the labels' mean for anything)
                raise InputError("the feature matrix has no columns: at least one feature is needed")
            return True
        if images.ndim == 2 or (images.ndim == 3 and images.shape[2] in (1, 3, 4)):
            raise _one_image(images)
        return False

    def _as_features(self, images) -> np.ndarray:
        return images if self._is_matrix(images) else self._features(images)

    def _takes_crops(self) -> None:
        """An :class:`InputError` when the model was fitted on a feature matrix of another width
        than its feature of a crop (a GP on features of the caller's own): it takes such a matrix,
        not crops (whose feature it could not read: NumPy's shape error, or a saved file that
        loads as corrupt)."""
        if self.net_ is not None or self.gp_ is None:
            return
        cell, size, _ = self._crop_params()
        width = self.pca_mean_.shape[0] if self.pca_mean_ is not None else self.gp_.X.shape[1]
        dim = F.feature_dim(self.feature, size, cell)
        if width != dim:
            raise InputError(f"this model was fitted on a feature matrix of {width} columns, not on the {dim} of the "
                             f"{self.feature} feature of {size[0]}x{size[1]} crops: it takes such a matrix, not crops, "
                             "and is no model of crops to save")

    def predict(self, images, return_std: bool = False, batch: int = 256, views=None):
        """Mean (and std) of every angle for crops or a feature matrix (and their ``views`` if the
        model was trained with them); chunks of ``batch`` frames run on a small thread pool (NumPy
        and OpenCV release the GIL; the network runs on torch's own threads)."""
        gp = self.gp_
        if gp is None or self.names_ is None:
            raise _not_fitted()
        return_std = check_bool("return_std", return_std)
        batch = check_range("batch", batch, 1, _MAX_COUNT, integer=True)
        images = F.crop_list(images)  # (any iterable of crops: a list, once)
        matrix = self._is_matrix(images)  # (checked once here, not again in every chunk)
        if matrix:
            cell, size, _ = self._crop_params()
            dim = (self.pca_mean_.shape[0] if self.pca_mean_ is not None
                   else F.feature_dim(self.feature, size, cell) if self.net_ is not None else gp.X.shape[1])
            if images.shape[1] != dim:
                raise InputError(f"the feature matrix has {images.shape[1]} columns, but this model takes {dim}")
        if not matrix:
            self._takes_crops()
        V = self._check_views(views, len(images))
        if self.net_ is not None:  # the network runs on the whole batch, on torch's threads
            images = self._project(images if matrix else self._features(images), V)
            prepare = None
        else:
            prepare = lambda part, s: self._project(part if matrix else self._features(part, first=s))  # noqa: E731

        def work(s):
            part = images[s : s + batch]
            return gp.predict(part if prepare is None else prepare(part, s), return_std=True)

        starts = list(range(0, len(images), batch))
        if len(starts) > 1:
            from concurrent.futures import ThreadPoolExecutor

            # one BLAS thread per worker: the pool already uses the cores (1.3-1.4x faster here)
            with _threads().limit(limits=1, user_api="blas"), ThreadPoolExecutor(max_workers=min(4, os.cpu_count() or 1)) as pool:
                parts = list(pool.map(work, starts))
        else:
            # one chunk. Right after the network, torch's OpenMP threads still spin on the cores and
            # a multi-threaded BLAS call fights them: one BLAS thread then (per crop, for calls of 1,
            # 8, 64 and 256 crops: 1.2-1.5, 0.56-0.64, 0.26-0.27, 0.26-0.27 ms against 8.0-8.8, 1.0,
            # 0.29-0.31, 0.31-0.32 without). Without a network BLAS keeps its threads (one HOG frame
            # 0.8 ms, not 1.2).
            with _threads().limit(limits=1, user_api="blas") if self.net_ is not None else contextlib.nullcontext():
                parts = [work(s) for s in starts]
        k = len(self.names_)
        mean = np.concatenate([p[0] for p in parts]) if parts else np.empty((0, k))
        std = np.concatenate([p[1] for p in parts]) if parts else np.empty((0, k))
        if self.net_ is not None and self.readout_ is not None and self.readout_.any() and len(mean):
            mean[:, self.readout_] = self._readout(images)[:, self.readout_]
        if not (np.isfinite(mean).all() and np.isfinite(std).all()):
            # a model whose numbers pass load's checks can still give NaN on some crops (a length
            # scale of 1e-30 underflows every kernel row): not angles to write as if measured
            raise InputError("damaged pose model: its angles for some crops are not finite numbers",
                             path=self.source_)
        return (mean, std) if return_std else mean

    def _readout(self, F: np.ndarray) -> np.ndarray:
        """The network's own prediction of every angle (degrees) from its feature ``F``."""
        assert self.net_mu_ is not None and self.net_sd_ is not None  # fitted with the network
        W = self.net_.head.weight.detach().numpy().astype(np.float64)
        b = self.net_.head.bias.detach().numpy().astype(np.float64)
        return (F @ W.T + b) * self.net_sd_ + self.net_mu_

    def domain_auc(self, images, views=None, max_rows: int = 1000) -> float:
        """How well ``images`` (crops or a feature matrix, with their ``views`` if the model uses
        them) can be told from the training crops nearest to them: about 0.5 or below, not at all
        (alike); 1, always (another domain; :func:`is_foreign`). NaN when there is too little to
        judge: fewer than :data:`DOMAIN_MIN` crops, or fewer than :data:`DOMAIN_DISTINCT` distinct
        training crops nearest to them (an instrument held still; or crops of another look that
        all fall near a few training crops, which this test cannot tell).

        A classifier two-sample test (Lopez-Paz and Oquab 2017) on matched samples: the
        cross-validated ROC AUC of a logistic regression between the crops' GP inputs and those of
        their nearest training crops. Matching keeps a video's narrow stretch of motion from being
        told apart from a broad training set only for being narrow. The GP's own variance cannot
        say this: a learned feature maps a crop it was never trained on (a real instrument, for a
        model trained on renders) near training crops, where the variance is small (docs/surgical.md).
        """
        from sklearn.linear_model import LogisticRegression
        from sklearn.metrics import roc_auc_score
        from sklearn.model_selection import cross_val_predict
        from sklearn.neighbors import NearestNeighbors

        gp = self.gp_
        if gp is None:
            raise _not_fitted()
        images = F.crop_list(images)
        max_rows = check_range("max_rows", max_rows, 1, _MAX_COUNT, integer=True)
        n = len(images)
        if n == 0:  # nothing to judge (and no views to check: a run with no tracks has none)
            return float("nan")
        V = self._check_views(views, n)
        if n < DOMAIN_MIN:
            return float("nan")
        rng = np.random.default_rng(_seed(self.seed))
        pick = np.sort(rng.choice(n, min(n, max_rows), replace=False))
        some = images[pick] if isinstance(images, np.ndarray) else [images[i] for i in pick]
        Z = self._project(self._as_features(some), None if V is None else V[pick])
        T = gp.X[np.unique(NearestNeighbors(n_neighbors=1).fit(gp.X).kneighbors(Z)[1].ravel())]
        if len(T) < DOMAIN_DISTINCT:  # a handful of points is told apart from anything in many dimensions
            return float("nan")
        A = np.vstack([T, Z])
        A = (A - A.mean(0)) / (A.std(0) + 1e-9)
        y = np.r_[np.zeros(len(T)), np.ones(len(Z))]
        p = cross_val_predict(LogisticRegression(max_iter=2000), A, y, cv=5, method="predict_proba")[:, 1]
        return float(roc_auc_score(y, p))

    def prior_std(self) -> np.ndarray:
        """Each angle's standard deviation (degrees) at a crop far from every training crop: the
        GP's prior, i.e. the spread of the training angles (calibrated)."""
        gp = self.gp_
        if gp is None:
            raise _not_fitted()
        prior = np.array([h.sf2 + h.sn2 for h in gp.hypers])
        return np.sqrt(prior * gp.var_scale) * gp.y_std

    def far_from_training(self, std: np.ndarray) -> np.ndarray:
        """Which crops, given the standard deviations :meth:`predict` gave them (``(n, k)``), are
        far from every training crop: for every angle more than :data:`FAR_SHARE` of the GP's prior
        variance is left (its training crops explain less than half of it). There the model knows
        nothing: its mean falls back to the training mean (or the network's read-out) and its
        standard deviation to :meth:`prior_std`, the spread of the training angles, which a training
        set of a few near-identical crops makes tiny whatever the error."""
        gp = self.gp_
        if gp is None:
            raise _not_fitted()
        S = float_array(std, "std")
        if S.ndim == 1 and gp.n_outputs == 1:
            S = S[:, None]
        if S.ndim != 2 or S.shape[1] != gp.n_outputs or not (np.isfinite(S).all() and (S >= 0).all()):
            # (a (2, 5) array for 2 angles was reshaped into 5 answers; NaN said "not far")
            raise InputError(f"std must be an (n, {gp.n_outputs}) array of finite numbers >= 0 (predict's standard "
                             f"deviations), got shape {S.shape}")
        sf2 = np.array([h.sf2 for h in gp.hypers])
        sn2 = np.array([h.sn2 for h in gp.hypers])
        latent = (S / gp.y_std) ** 2 / gp.var_scale - sn2
        return np.all(latent > FAR_SHARE * sf2, axis=1)

    def make_filter(self, dt: float = 1.0) -> PoseFilter:
        """The model's Kalman filter: its acceleration variance from the training labels, scaled on
        the calibration rows, and its bands calibrated there (:func:`tune_filter`); ``dt`` in frames."""
        if self.accel_var_ is None or self.filter_std_ is None or self.smooth_std_ is None:
            raise _not_fitted()
        return PoseFilter(self.accel_var_, dt, self.filter_std_, self.smooth_std_)

    # -- persistence
    def save(self, path: str | os.PathLike) -> None:
        gp = self.gp_
        if gp is None or self.accel_var_ is None or self.filter_std_ is None:
            raise _not_fitted()
        self._takes_crops()
        neighbours = getattr(gp, "neighbours", None)
        cell, size, blur = self._crop_params()  # (the values the model uses, not None for a default)
        data: dict[str, Any]  # arrays only; ``Any`` because ``**data`` also meets savez' ``allow_pickle: bool``
        data = dict(
            magic=np.array(MAGIC), version=np.array(VERSION), feature=np.array(self.feature),
            cell=np.array(cell), size=np.array(size), blur=np.array(blur), names=np.array(self.names_),
            method=np.array(gp.kind), X=gp.X.astype(np.float32), Ys=gp.Ys, y_mean=gp.y_mean, y_std=gp.y_std,
            hypers=np.array([h.as_array() for h in gp.hypers]), accel_var=self.accel_var_,
            var_scale=gp.var_scale,
            filter_std=self.filter_std_, smooth_std=self.smooth_std_,
            inducing=gp.inducing if isinstance(gp, SparseGP) else np.zeros(0, np.int64),
            var_inducing=(gp.var_inducing if isinstance(gp, SparseGP) and gp.var_inducing is not None
                          else np.zeros(0, np.int64)),
            alpha=gp.alpha if isinstance(gp, ExactGP) else np.zeros(0),
            neighbours=np.array(-1 if neighbours is None else neighbours),
            pca_mean=np.zeros(0, np.float32) if self.pca_mean_ is None else self.pca_mean_,
            pca_components=np.zeros((0, 0), np.float32) if self.pca_components_ is None else self.pca_components_,
        )
        if self.net_ is not None:
            from artmotion.pose import cnn

            data.update({_NET + k: v for k, v in cnn.state_arrays(self.net_).items()})
            if self.readout_ is not None and self.net_mu_ is not None and self.net_sd_ is not None:
                data.update(readout=self.readout_.astype(np.int64), net_mu=self.net_mu_, net_sd=self.net_sd_)
        with atomic_path(path, suffix=".npz") as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, **data)

    @classmethod
    def load(cls, path: str | os.PathLike) -> PoseRegressor:
        """Read a model written by :meth:`save` and check it whole before it is used: every array
        of the right type, shape and finite values, the parameters in range, the feature of its
        crop size of the dimension the GP was trained on, and a test prediction finite. A
        truncated, renamed, foreign or damaged file is an :class:`InputError` naming it."""
        import tokenize
        import zipfile
        import zlib

        path = as_path(path, "a pose model")
        if read_head(path, 4, missing="model file not found") != b"PK\x03\x04":
            raise InputError("not an artmotion pose model (not a NumPy .npz file)", path=path)
        try:
            _check_npz_sizes(path)
            with np.load(path, allow_pickle=False) as z:
                d = {k: z[k] for k in z.files}
        except InputError as exc:
            raise InputError(exc.reason, path=path) from None
        # (a damaged array header reaches NumPy's header tokenizer: TokenError, SyntaxError)
        # (a damaged compression-method field: zipfile's NotImplementedError)
        except (ValueError, OSError, EOFError, zipfile.BadZipFile, zlib.error, KeyError, tokenize.TokenError,
                SyntaxError, NotImplementedError) as exc:
            raise InputError(f"not an artmotion pose model (unreadable: {type(exc).__name__})", path=path) from None
        if not isinstance(d, dict) or "magic" not in d or d["magic"].shape != () or str(d["magic"]) != MAGIC:
            raise InputError("not an artmotion pose model (no magic key)", path=path)
        try:
            version = int(d["version"])
        except (KeyError, ValueError, TypeError, OverflowError):
            raise InputError("corrupt artmotion pose model: no version", path=path) from None
        if version != VERSION:
            raise InputError(f"unsupported pose model version {version}", path=path)
        try:
            reg = _model_from_arrays(cls, d)
        except InputError as exc:
            raise InputError(f"corrupt artmotion pose model: {exc.reason}", path=path) from None
        except (KeyError, ValueError, TypeError, IndexError, OverflowError, np.linalg.LinAlgError) as exc:
            raise InputError(f"corrupt artmotion pose model: {type(exc).__name__} {exc}", path=path) from None
        reg.source_ = path      # (named by predict's error should the model give what is not a number)
        return reg


def _check_npz_sizes(path: Path) -> None:
    """Every array of the ``.npz`` at ``path`` holds the data its header declares, and all of them
    together at most :data:`_MAX_MODEL_BYTES`, checked from the zip's directory and the arrays'
    headers before any array is read: a header declaring a terabyte (or a compressed "bomb") was a
    MemoryError, or memory filled before the model was refused. An :class:`InputError` otherwise."""
    import zipfile

    with zipfile.ZipFile(path) as zf:
        members = zf.infolist()
        if sum(m.file_size for m in members) > _MAX_MODEL_BYTES:
            raise InputError(f"not an artmotion pose model (its arrays hold more than {_MAX_MODEL_BYTES / 2**30:g} GiB)")
        for m in members:
            with zf.open(m) as fh:
                version = np.lib.format.read_magic(fh)
                shape, _, dtype = (np.lib.format.read_array_header_1_0(fh) if version == (1, 0)
                                   else np.lib.format.read_array_header_2_0(fh))
                if math.prod(shape) * dtype.itemsize > m.file_size:
                    raise InputError(f"corrupt artmotion pose model: array {m.filename!r} declares shape {shape}, "
                                     f"more data than the file holds")


def check_views(views, n: int) -> np.ndarray:
    """``views`` of ``n`` crops checked: ``(n, VIEW_DIM)`` finite numbers (:func:`features.box_views`)."""
    V = float_array(views, "views").astype(np.float32)
    if V.shape != (n, F.VIEW_DIM) or not np.all(np.isfinite(V)):
        raise InputError(f"views must be {n}x{F.VIEW_DIM} finite numbers (features.box_views), got {V.shape}")
    return V


def check_keypoints(keypoints, n: int) -> np.ndarray | None:
    """``keypoints`` of :meth:`PoseRegressor.fit` checked: ``(n, 2m)`` numbers, NaN where a point is
    not known (as a whole: x and y both), none infinite or far outside its crop."""
    if keypoints is None:
        return None
    K = float_array(keypoints, "keypoints")
    if K.ndim != 2 or len(K) != n or K.shape[1] == 0 or K.shape[1] % 2:
        raise InputError(f"keypoints must be {n} rows of x, y pairs (one row per crop), got shape {K.shape}")
    if np.isinf(K).any():
        raise InputError("keypoints hold infinite values")
    if (np.isnan(K[:, 0::2]) != np.isnan(K[:, 1::2])).any():
        raise InputError("a keypoint has an x but no y, or a y but no x (NaN marks a point not known: both)")
    if np.nanmax(np.abs(K), initial=0.0) > MAX_KEYPOINT:
        raise InputError(f"keypoints lie more than {MAX_KEYPOINT:g} crop widths or heights from their crops' corners "
                         "(they are fractions of the crop's width and height: x / w, y / h)")
    return K


def _one_image(image: np.ndarray) -> InputError:
    return InputError(f"expected a list of crops or a feature matrix, got one {'x'.join(map(str, image.shape))} image: "
                      f"pass [image] for one crop")


def _check_choices(**given) -> None:
    """Each of ``feature``, ``method``, ``inducing``, ``net_mean`` given one of its choices, else an
    :class:`InputError` naming it."""
    choices = {"feature": F.FEATURES, "method": METHODS, "inducing": ("kmeans", "random"), "net_mean": NET_MEANS}
    for name, value in given.items():
        if not isinstance(value, str) or value not in choices[name]:
            raise InputError(f"unknown {name} {value!r}; choose one of {', '.join(choices[name])}")


def _seed(seed) -> int:
    """``seed`` checked, as NumPy and scikit-learn take it (an int)."""
    return check_seed(seed, "seed")


def _angle_names(names, k: int) -> list[str]:
    """``names`` of ``k`` angles checked as :meth:`PoseRegressor.load` reads them back (``angle0``,
    ``angle1``, ... for None)."""
    if names is None:
        return [f"angle{i}" for i in range(k)]
    if isinstance(names, str):
        raise InputError(f"names must be a list of {k} angle names, not one string")
    names = list(names)
    if len(names) != k:
        raise InputError(f"{len(names)} angle names for {k} label columns")
    if not all(isinstance(n, str) and n for n in names) or len(set(names)) != k:
        raise InputError(f"angle names must be distinct, non-empty strings, got {names!r}")
    out = prediction_header(names)
    twice = [c for i, c in enumerate(out) if c in out[:i]]
    if twice:   # e.g. 'yaw' and 'yaw_std', or 'image': predictions could not be read back
        raise InputError(f"angle names {names!r} put column {twice[0]!r} twice in the predictions' header "
                         "(image,<angle>,<angle>_std,...)")
    return names


def _array(d: dict, key: str, shape: tuple, kind: str = "f") -> np.ndarray:
    """``d[key]`` checked: numeric (``"f"``), integer (``"i"``) or text (``"U"``), of ``shape``
    (``None`` entries are free), finite."""
    if key not in d:
        raise InputError(f"no {key!r} array")
    a = d[key]
    ok = {"f": np.issubdtype(a.dtype, np.number) and not np.issubdtype(a.dtype, np.complexfloating),
          "i": np.issubdtype(a.dtype, np.integer), "U": np.issubdtype(a.dtype, np.str_)}[kind]
    if not ok or a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape)):
        want = "x".join("n" if s is None else str(s) for s in shape) or "a scalar"
        raise InputError(f"{key!r} is not a {'number' if kind != 'U' else 'text'} array of shape {want} "
                         f"(found {a.dtype} {'x'.join(map(str, a.shape)) or 'scalar'})")
    if kind == "f" and not np.all(np.isfinite(a)):
        raise InputError(f"{key!r} holds NaN or infinite values")
    if kind == "f" and a.size and np.abs(a).max() > _MAX_VALUE:
        raise InputError(f"{key!r} holds values beyond ±{_MAX_VALUE:g}")
    return a


def _distinct_indices(a: np.ndarray, n: int) -> bool:
    """Whether the non-empty integer array ``a`` holds distinct indices into ``n`` items."""
    return bool(a.min() >= 0 and a.max() < n and len(np.unique(a)) == len(a))


#: prefix of the network's weights in a ``cnn`` model file
_NET = "net:"

#: no number in a model is larger (float32, in which inputs are stored, ends at 3.4e38)
_MAX_VALUE = 1e30


def _model_from_arrays(cls, d: dict) -> PoseRegressor:
    """A :class:`PoseRegressor` from the arrays of a model file, every one checked (see ``load``)."""
    from artmotion.errors import check_range

    feature = str(_array(d, "feature", (), "U"))
    if feature not in F.FEATURES:
        raise InputError(f"unknown feature {feature!r}")
    cell = check_range("cell", _array(d, "cell", (), "i").item(), 2, 256, integer=True)
    size = tuple(check_range("crop size", int(v), 8, 4096, integer=True) for v in _array(d, "size", (2,), "i"))
    blur = check_range("blur", float(_array(d, "blur", ())), 0.0, 100.0)
    method = str(_array(d, "method", (), "U"))
    if method not in ("exact", "sparse"):
        raise InputError(f"unknown GP method {method!r}")
    names = [str(s) for s in _array(d, "names", (None,), "U")]
    k = len(names)
    if not k:
        raise InputError("no angle names")
    _angle_names(names, k)
    X = _array(d, "X", (None, None))
    n, dim = X.shape
    if n < 1 or dim < 1:
        raise InputError("no training inputs")
    hypers = _array(d, "hypers", (k, 3))
    if not np.all((hypers >= _MIN_HYPER) & (hypers <= 1.0 / _MIN_HYPER)):   # (a length of 1e-200 squares to 0)
        raise InputError(f"'hypers' (length, signal and noise variance) must lie in [{_MIN_HYPER:g}, {1 / _MIN_HYPER:g}]")
    Ys = _array(d, "Ys", (n, k))
    y_mean, y_std = _array(d, "y_mean", (k,)), _array(d, "y_std", (k,))
    var_scale, accel_var = _array(d, "var_scale", (k,)), _array(d, "accel_var", (k,))
    if np.any(y_std <= 0) or np.any(var_scale <= 0) or np.any(accel_var <= 0):
        raise InputError("'y_std', 'var_scale' and 'accel_var' must be positive")
    nb = check_range("neighbours", _array(d, "neighbours", (), "i").item(), -1, 1_000_000, integer=True)
    full = F.feature_dim(feature, size, cell)
    pca_c = _array(d, "pca_components", (None, None))
    reg = cls(feature=feature, cell=cell, size=size, blur=blur)
    if feature == "cnn":
        need_package("torch", "tools", "a cnn pose model")
        from artmotion.pose import cnn

        net = {k[len(_NET):]: _array(d, k, (None,) * d[k].ndim) for k in d if k.startswith(_NET)}
        try:
            reg.net_ = cnn.from_arrays(net, k, size)
        except ValueError as exc:
            raise InputError(str(exc)) from None
        if dim != reg.net_.head.in_features:
            raise InputError(f"inputs of dimension {dim}, but the network's feature has {reg.net_.head.in_features}")
        reg.n_components = None
        if "readout" in d:      # (models written before 2026-11-26 have none: the GP's mean for every angle)
            readout = _array(d, "readout", (k,), "i")
            if not np.isin(readout, (0, 1)).all():
                raise InputError("'readout' is not a 0/1 flag per angle")
            reg.readout_ = readout.astype(bool)
            reg.net_mu_ = _array(d, "net_mu", (k,)).astype(float)
            reg.net_sd_ = _array(d, "net_sd", (k,)).astype(float)
            if np.any(reg.net_sd_ <= 0):
                raise InputError("'net_sd' must be positive")
            reg.net_mean = "all" if reg.readout_.all() else "none" if not reg.readout_.any() else "opening"
        else:
            reg.net_mean = "none"
    elif pca_c.size:
        if pca_c.shape != (dim, full):
            raise InputError(f"'pca_components' is {pca_c.shape[0]}x{pca_c.shape[1]}, not {dim}x{full} "
                             f"(inputs of the GP x {feature} features of a {size[0]}x{size[1]} crop)")
        reg.pca_mean_ = _array(d, "pca_mean", (full,)).astype(np.float32)
        reg.pca_components_ = pca_c.astype(np.float32)
        reg.n_components = dim
    else:
        if dim != full:
            raise InputError(f"inputs of dimension {dim}, but {feature} features of a {size[0]}x{size[1]} crop "
                             f"have {full}")
        reg.n_components = None
    reg.names_ = names
    reg.neighbours = None if nb < 0 else nb
    hyp = [Hyper(*map(float, h)) for h in hypers]
    X = X.astype(np.float64)
    if method == "exact":
        alpha = _array(d, "alpha", (n, k)) if reg.neighbours is not None else None
        reg.gp_ = ExactGP(X, Ys, hyp, y_mean, y_std, reg.neighbours, alpha)
    else:
        inducing = _array(d, "inducing", (None,), "i")
        if not len(inducing) or not _distinct_indices(inducing, n):
            raise InputError("'inducing' are not distinct indices of training inputs")
        # the variance's own inducing inputs (positions among those): absent or empty, the same set
        var_ind = _array(d, "var_inducing", (None,), "i") if "var_inducing" in d else np.zeros(0, np.int64)
        if len(var_ind) and not _distinct_indices(var_ind, len(inducing)):
            raise InputError("'var_inducing' are not distinct positions among the inducing inputs")
        reg.gp_ = SparseGP(X, Ys, hyp, y_mean, y_std, inducing, var_ind if len(var_ind) else None)
        reg.n_inducing, reg.n_inducing_var = len(inducing), len(var_ind) or None
    reg.gp_.var_scale = var_scale.astype(float)
    reg.accel_var_ = accel_var.astype(float)
    # (models written before 2026-11-28 have none: the filter's own standard deviations)
    for key in ("filter_std", "smooth_std"):
        m = _array(d, key, (k,)).astype(float) if key in d else np.ones(k)
        if np.any(m < 1):
            raise InputError(f"{key!r} must be at least 1")
        setattr(reg, key + "_", m)
    reg.method = method
    # a test prediction on a gray crop: whatever slipped through shows here, before any long work
    views = np.zeros((1, F.VIEW_DIM)) if reg.uses_views_ else None
    mean, std = reg.predict([np.full((size[1], size[0], 3), 128, np.uint8)], return_std=True, views=views)
    if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(std))):
        raise InputError("its prediction is not finite")
    return reg
