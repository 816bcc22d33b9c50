"""Pose regression from tool crops (Sec. 3.4) and temporal filtering (Sec. 3.5).

``PoseRegressor(feature="hog").fit(images, Y)`` learns one GP per angle; ``predict(images,
return_std=True)`` gives the mean and the predictive standard deviation of every angle.
``PoseFilter`` smooths a sequence of predictions with a constant-velocity Kalman filter per angle
(Eq. 3.6) that observes the GP mean with the GP variance as its measurement noise (Eq. 3.7).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

import numpy as np

from artmotion.errors import InputError
from artmotion.filters import KalmanFilter, constant_velocity
from artmotion.io import atomic_path
from artmotion.pose import features as F
from artmotion.pose.gp import ExactGP, Hyper, SparseGP, fit_gp

MAGIC = "artmotion-pose-gp"
VERSION = 1


def accel_variance(Y: np.ndarray, dt: float = 1.0) -> np.ndarray:
    """White-noise acceleration variance per column of a time-ordered ``Y`` (``2 var(d2 y) / dt^4``).

    For the discretised model of Eq. 3.6, ``y[t+1] - 2 y[t] + y[t-1] = dt^2 (a[t] + a[t-1]) / 2``.
    """
    Y = np.asarray(Y, dtype=float).reshape(len(Y), -1)
    if len(Y) < 4:
        return np.ones(Y.shape[1])
    d2 = np.diff(Y, n=2, axis=0)
    return np.maximum(2.0 * d2.var(axis=0) / dt**4, 1e-6)


class PoseFilter:
    """Per-angle Kalman filter, constant velocity with white-noise acceleration (Eq. 3.6, 3.7).

    ``accel_var``: acceleration variance per angle (units²/frame⁴); ``dt`` the frame interval.
    ``filter(mean, std)`` runs forward over a sequence (causal, real-time) and returns the
    filtered means and standard deviations; ``step`` fuses one frame.
    """

    def __init__(self, accel_var, dt: float = 1.0):
        self.accel_var = np.atleast_1d(np.asarray(accel_var, dtype=float))
        self.dt = float(dt)
        self.reset()

    def reset(self) -> None:
        self._kf: list[KalmanFilter] | None = None

    def _start(self, z: np.ndarray, var: np.ndarray) -> None:
        self._kf = []
        for k, q in enumerate(self.accel_var):
            Fm, Q, H = constant_velocity(self.dt, q, dims=1)
            P = np.diag([var[k], max(var[k], q) * 10.0])
            self._kf.append(KalmanFilter([z[k], 0.0], P, Fm, Q, H, [[var[k]]]))

    def step(self, mean, std) -> tuple[np.ndarray, np.ndarray]:
        """Fuse one frame's GP prediction (mean and std per angle); return the filtered state."""
        z = np.asarray(mean, dtype=float).ravel()
        var = np.maximum(np.asarray(std, dtype=float).ravel() ** 2, 1e-9)
        if len(z) != len(self.accel_var):
            raise InputError(f"expected {len(self.accel_var)} angles, got {len(z)}")
        if self._kf is None:
            self._start(z, var)
            return z.copy(), np.sqrt(var)
        out, sd = np.empty_like(z), np.empty_like(z)
        for k, kf in enumerate(self._kf):
            kf.predict()
            kf.update(z[k], R=[[var[k]]])
            out[k], sd[k] = kf.x[0], np.sqrt(kf.P[0, 0])
        return out, sd

    def filter(self, mean, std) -> tuple[np.ndarray, np.ndarray]:
        mean = np.atleast_2d(np.asarray(mean, dtype=float))
        std = np.atleast_2d(np.asarray(std, dtype=float))
        self.reset()
        out, sd = np.empty_like(mean), np.empty_like(mean)
        for t in range(len(mean)):
            out[t], sd[t] = self.step(mean[t], std[t])
        return out, sd


class PoseRegressor:
    """Joint angles from a tool crop: HOG/LBP features + one GP per angle (scikit-learn style).

    Parameters: ``feature`` (``"hog"`` or ``"lbp"``), ``cell`` (feature cell size; default 8 for
    HOG, 16 for LBP), ``size`` (crop resize, width×height), ``method`` (``"auto"``, ``"exact"``,
    ``"sparse"``), ``max_exact`` (``auto`` switches to the sparse GP above this many training
    examples), ``n_inducing``, ``n_opt`` (subset used for hyper-parameter optimisation),
    ``restarts``, ``seed``, ``progress`` (tqdm bars), ``inducing`` (``"kmeans"`` or ``"random"``
    choice of the sparse GP's inducing inputs).
    """

    def __init__(self, feature: str = "hog", cell: int | None = None, size: tuple[int, int] = (F.CROP_W, F.CROP_H),
                 method: str = "auto", max_exact: int = 2000, n_inducing: int = 1000, n_opt: int = 500,
                 restarts: int = 1, seed: int = 0, progress: bool = False, inducing: str = "kmeans"):
        if feature not in F.FEATURES:
            raise InputError(f"unknown feature {feature!r}; choose one of {', '.join(F.FEATURES)}")
        self.feature = feature
        self.cell = F.default_cell(feature) if cell is None else int(cell)
        self.size = (int(size[0]), int(size[1]))
        self.method = method
        self.max_exact = max_exact
        self.n_inducing = n_inducing
        self.n_opt = n_opt
        self.restarts = restarts
        self.seed = seed
        self.progress = progress
        self.inducing = inducing
        self.names_: list[str] | None = None
        self.gp_ = None
        self.accel_var_: np.ndarray | None = None

    # -- features
    def features(self, images: Sequence[np.ndarray]) -> np.ndarray:
        return F.extract(images, self.feature, self.size, self.cell)

    # -- training / prediction
    def fit(self, images, Y, names: Sequence[str] | None = None):
        """Fit on crops (list of images) or a precomputed feature matrix, and angles ``Y`` (n, k)."""
        X = self._as_features(images)
        Y = np.asarray(Y, dtype=float)
        Y = Y.reshape(len(Y), -1)
        if len(X) != len(Y):
            raise InputError(f"{len(X)} images but {len(Y)} label rows")
        if len(X) < 3:
            raise InputError("need at least 3 training examples")
        if not np.all(np.isfinite(Y)):
            raise InputError("labels contain NaN or infinite values")
        self.names_ = list(names) if names is not None else [f"angle{k}" for k in range(Y.shape[1])]
        self.gp_ = fit_gp(X, Y, self.method, self.max_exact, self.n_inducing, self.n_opt, self.restarts,
                          self.seed, progress=self.progress, inducing=self.inducing)
        self.accel_var_ = accel_variance(Y)
        return self

    def _as_features(self, images) -> np.ndarray:
        if isinstance(images, np.ndarray) and images.ndim == 2 and images.dtype != np.uint8:
            return images
        return self.features(images)

    def predict(self, images, return_std: bool = False, batch: int = 1024):
        if self.gp_ is None:
            raise RuntimeError("PoseRegressor is not fitted")
        X = self._as_features(images)
        means, stds = [], []
        for s in range(0, len(X), batch):
            r = self.gp_.predict(X[s : s + batch], return_std=True)
            means.append(r[0])
            stds.append(r[1])
        mean = np.concatenate(means) if means else np.empty((0, len(self.names_)))
        std = np.concatenate(stds) if stds else np.empty((0, len(self.names_)))
        return (mean, std) if return_std else mean

    def make_filter(self, dt: float = 1.0) -> PoseFilter:
        return PoseFilter(self.accel_var_, dt)

    # -- persistence
    def save(self, path: str | os.PathLike) -> None:
        gp = self.gp_
        X = gp.X if isinstance(gp, ExactGP) else gp.X_train
        Ys = gp.Ys
        data = dict(
            magic=np.array(MAGIC), version=np.array(VERSION), feature=np.array(self.feature),
            cell=np.array(self.cell), size=np.array(self.size), names=np.array(self.names_),
            method=np.array(gp.kind), X=X.astype(np.float32), Ys=Ys, y_mean=gp.y_mean, y_std=gp.y_std,
            hypers=np.array([h.as_array() for h in gp.hypers]), accel_var=self.accel_var_,
            var_scale=gp.var_scale,
            inducing=gp.inducing if isinstance(gp, SparseGP) else np.zeros(0, np.int64),
        )
        with atomic_path(path, suffix=".npz") as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, **data)

    @classmethod
    def load(cls, path: str | os.PathLike) -> "PoseRegressor":
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                d = {k: z[k] for k in z.files}
        except FileNotFoundError:
            raise InputError("model file not found", path=path) from None
        except (ValueError, OSError, EOFError) as exc:
            raise InputError(f"not an artmotion pose model ({type(exc).__name__})", path=path) from None
        if "magic" not in d or str(d["magic"]) != MAGIC:
            raise InputError("not an artmotion pose model (no magic key)", path=path)
        if int(d["version"]) != VERSION:
            raise InputError(f"unsupported pose model version {int(d['version'])}", path=path)
        try:
            reg = cls(feature=str(d["feature"]), cell=int(d["cell"]), size=tuple(int(v) for v in d["size"]))
            reg.names_ = [str(s) for s in d["names"]]
            hypers = [Hyper(*map(float, h)) for h in d["hypers"]]
            X = d["X"].astype(np.float64)
            if str(d["method"]) == "exact":
                reg.gp_ = ExactGP(X, d["Ys"], hypers, d["y_mean"], d["y_std"])
            else:
                reg.gp_ = SparseGP(X, d["Ys"], hypers, d["y_mean"], d["y_std"], d["inducing"])
            reg.gp_.var_scale = np.asarray(d["var_scale"], dtype=float)
            reg.accel_var_ = d["accel_var"]
            reg.method = str(d["method"])
        except (KeyError, ValueError, TypeError, np.linalg.LinAlgError) as exc:
            raise InputError(f"corrupt artmotion pose model: {exc}", path=path) from None
        return reg
