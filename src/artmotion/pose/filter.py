"""Temporal filtering of pose predictions (Sec. 3.5).

``PoseFilter`` smooths a sequence of predictions with a constant-velocity Kalman filter per angle
(Eq. 3.6) that observes the GP mean with the GP variance as its measurement noise (Eq. 3.7):
forward in real time, or forward and back over a recorded sequence (Rauch-Tung-Striebel).
:func:`accel_variance` is its motion prior from training labels, :func:`tune_filter` its tuning on
held-out predictions (what :meth:`~artmotion.pose.model.PoseRegressor.fit` does on its
calibration rows).
"""

from __future__ import annotations

import numpy as np

from artmotion.errors import InputError, check_range, float_array
from artmotion.filters import constant_velocity
from artmotion.io.mot import MAX_FRAME

__all__ = ["ACCEL_SCALES", "MAX_ACCEL_VAR", "MAX_DT", "MAX_STD", "PoseFilter", "accel_variance", "tune_filter"]


def accel_variance(Y: np.ndarray, dt: float = 1.0, frames: np.ndarray | None = None) -> np.ndarray:
    """White-noise acceleration variance per column of a time-ordered ``Y`` (``2 var(d2 y) / dt^4``).

    For the discretised model of Eq. 3.6, ``y[t+1] - 2 y[t] + y[t-1] = dt^2 (a[t] + a[t-1]) / 2``.
    ``frames``: the frame number of each row; only second differences over three consecutive
    frames count (rows taken out of a sequence, e.g. a cross-validation fold, leave gaps).
    """
    Y = np.asarray(Y, dtype=float).reshape(len(Y), -1)
    if len(Y) < 4:
        return np.ones(Y.shape[1])
    d2 = np.diff(Y, n=2, axis=0)
    if frames is not None:
        step = np.diff(np.asarray(frames))
        d2 = d2[(step[:-1] == 1) & (step[1:] == 1)]
        if len(d2) < 2:
            return np.ones(Y.shape[1])
    return np.maximum(2.0 * d2.var(axis=0) / dt**4, 1e-6)


#: multipliers of the acceleration variance that :func:`tune_filter` tries
ACCEL_SCALES = 10.0 ** np.arange(0.0, 3.25, 0.5)


def tune_filter(Y: np.ndarray, mean: np.ndarray, std: np.ndarray, accel_var: np.ndarray,
                frames: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The filter for predictions like ``mean, std`` (held-out, with their labels ``Y``; rows in
    time order, ``frames`` numbering them, a step other than 1 starting a new sequence), per angle:
    the multiplier of ``accel_var`` (one of :data:`ACCEL_SCALES`) under which
    :meth:`PoseFilter.smooth` errs least (absolute error), and the multipliers of the filtered and
    of the smoothed standard deviations that make their ±3σ bands hold as many rows as a Gaussian's
    (the rule of :func:`~artmotion.pose.gp.fit_gp`; never below 1).
    :meth:`~artmotion.pose.model.PoseRegressor.fit` tunes its filter so on its calibration rows.

    The filter weighs each frame's prediction by the GP's variance, which :func:`~artmotion.pose.gp.fit_gp` calibrates
    for a ±3σ band: the residuals are heavy-tailed, so that variance is several times the typical
    frame's error (the opening's σ 15-18° against errors of 5-7°). With the labels' own
    acceleration variance (:func:`accel_variance`) the filter then leaned on its motion prior and
    lagged: the filtered opening was worse than the raw one (6.83 against 6.07° on the unseen
    sequences, docs/pose.md). A larger acceleration variance lets it follow the predictions as far
    as they deserve. And its covariance takes every frame's error as independent of the next, but
    an error lasts as long as a pose is read badly (a jaw seen edge-on): the smoothed σ came out a
    quarter to a half of the GP's and its band held 78-95 % of the truth; hence the multipliers."""
    from artmotion.pose.gp import BAND_LEVEL

    S = ACCEL_SCALES
    k = Y.shape[1]
    starts = np.flatnonzero(np.r_[True, np.diff(frames) != 1, True])
    segments = [(a, b) for a, b in zip(starts[:-1], starts[1:]) if b - a >= 3]
    if not segments:
        return np.ones(k), np.ones(k), np.ones(k)
    # every scale at once: the angles' filters are independent, so each (scale, angle) is one
    # column, scale by scale; per segment, the filtered and the smoothed means and deviations
    runs = []
    f = PoseFilter((S[:, None] * accel_var[None, :]).ravel())
    for a, b in segments:
        xs, Ps = f._forward(np.tile(mean[a:b], len(S)), np.tile(std[a:b], len(S)))
        runs.append((Y[a:b], [(xs[:, :, 0], np.sqrt(Ps[:, :, 0, 0])), f._backward(xs, Ps)]))
    err = sum(np.abs(outs[1][0] - np.tile(y, len(S))).sum(0) for y, outs in runs).reshape(len(S), k)
    best = np.argmin(err, axis=0)
    cols = best * k + np.arange(k)  # each angle's column at its chosen scale
    band = []
    for which in (0, 1):  # filtered, smoothed
        z = np.concatenate([np.abs(y - outs[which][0][:, cols]) / np.maximum(outs[which][1][:, cols], 1e-9)
                            for y, outs in runs])
        band.append(np.maximum(1.0, np.quantile(z, BAND_LEVEL, axis=0) / 3.0))
    scale = S[best]
    return scale, band[0], band[1]


#: largest standard deviation of a prediction (``std``), multiplier of the returned ones
#: (``filter_std``, ``smooth_std``) and acceleration variance (``accel_var``) the filter takes,
#: and largest frame interval (``dt``, in frames: the longest video): within them the variances
#: (the squares) and the covariances built from them stay finite. (The smoother itself gives a
#: frame without a measurement a deviation of 1e12.)
MAX_STD = 1e100
MAX_ACCEL_VAR = 1e100
MAX_DT = float(MAX_FRAME)


def _positive(name: str, value, hi: float = MAX_STD) -> np.ndarray:
    """``value`` as a float array of finite positive numbers up to ``hi``, else an :class:`InputError`."""
    a = np.atleast_1d(float_array(value, name))
    if not (np.all(np.isfinite(a)) and np.all(a > 0.0) and np.all(a <= hi)):
        raise InputError(f"{name} must be finite, positive and at most {hi:g}, got {a.ravel()[:8].tolist()}")
    return a if np.ndim(value) else a.reshape(())


def _finite(*arrays: np.ndarray) -> None:
    """An :class:`InputError` unless every value of ``arrays`` (the filter's output) is finite:
    the backstop for ``std``, ``dt`` and ``accel_var`` each in range but out of scale for one
    another (the covariances overflow or turn singular)."""
    if not all(np.all(np.isfinite(a)) for a in arrays):
        raise InputError(_OUT_OF_SCALE)


_OUT_OF_SCALE = ("the filter's estimates are not finite: std, dt and accel_var are too far out of scale "
                 "for one another")


class PoseFilter:
    """Per-angle Kalman filter, constant velocity with white-noise acceleration (Eq. 3.6, 3.7).

    ``accel_var``: acceleration variance per angle (units²/frame⁴); ``dt`` the frame interval
    (in frames); ``filter_std``, ``smooth_std``: multipliers of the standard deviations returned
    (per angle or one). ``filter(mean, std)`` runs forward over a sequence (causal, real-time)
    and returns the filtered means and standard deviations; ``step`` fuses one frame;
    ``smooth(mean, std)`` estimates every frame from the whole sequence (offline).

    ``accel_var``, the multipliers and ``std`` are positive (``std`` non-negative) and at most
    :data:`MAX_ACCEL_VAR` and :data:`MAX_STD`, ``dt`` in ``(0, MAX_DT]``, so that the variances
    stay finite; a result that is not finite all the same (values in range but out of scale for
    one another) is an :class:`InputError` too (``step`` then resets the filter).
    """

    def __init__(self, accel_var, dt: float = 1.0, filter_std=1.0, smooth_std=1.0):
        self.accel_var = np.atleast_1d(_positive("accel_var", accel_var, MAX_ACCEL_VAR))
        if self.accel_var.ndim != 1 or not len(self.accel_var):
            raise InputError(f"accel_var must be one variance per angle, got shape {self.accel_var.shape}")
        self.dt = float(check_range("dt", dt, 0.0, MAX_DT, lo_open=True))
        # multipliers of the standard deviations that ``filter``/``step`` and ``smooth`` return
        # (:func:`tune_filter`: the filter's own covariance takes the errors as independent)
        k = len(self.accel_var)
        self.filter_std = _positive("filter_std", filter_std)
        self.smooth_std = _positive("smooth_std", smooth_std)
        for name, mult in (("filter_std", self.filter_std), ("smooth_std", self.smooth_std)):
            if mult.ndim > 1 or mult.size not in (1, k):
                raise InputError(f"{name} must be one multiplier or one per angle ({k}), got shape {mult.shape}")
        # the angles' filters are independent: one 2-state filter each, stepped together (F, Q
        # per angle: the diagonal blocks of the constant-velocity model over all angles)
        Fm, Q, _ = constant_velocity(self.dt, self.accel_var, dims=k)
        self.F = Fm[:2, :2]
        self.Q = np.stack([Q[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] for i in range(k)])
        self.reset()

    def reset(self) -> None:
        self.x: np.ndarray | None = None   # (k, 2): each angle's [y, y']
        self.P = np.zeros((0, 2, 2))        # (k, 2, 2): their covariances

    def _start(self, z: np.ndarray, var: np.ndarray) -> None:
        self.x = np.column_stack([z, np.zeros_like(z)])
        self.P = np.zeros((len(z), 2, 2))
        self.P[:, 0, 0] = var
        self.P[:, 1, 1] = np.maximum(var, self.accel_var) * 10.0

    def _check(self, mean, std) -> tuple[np.ndarray, np.ndarray]:
        """``mean`` and ``std`` as 2-D float arrays of the same shape, one column per angle, finite
        (``std`` non-negative); else an :class:`InputError`."""
        mean = np.atleast_2d(float_array(mean, "mean"))
        std = np.atleast_2d(float_array(std, "std"))
        if mean.ndim != 2 or mean.shape[1] != len(self.accel_var):
            raise InputError(f"expected {len(self.accel_var)} angles per row of means, got shape {mean.shape}")
        if std.shape != mean.shape:
            raise InputError(f"std must have the shape of the means {mean.shape}, got {std.shape}")
        if not np.all(np.isfinite(mean)):
            raise InputError("the means contain NaN or infinite values")
        if not (np.all(np.isfinite(std)) and np.all(std >= 0.0) and np.all(std <= MAX_STD)):
            raise InputError(f"the standard deviations must be finite, non-negative and at most {MAX_STD:g}")
        return mean, std

    def step(self, mean, std) -> tuple[np.ndarray, np.ndarray]:
        """Fuse one frame's GP prediction (mean and std per angle); return the filtered state."""
        z = float_array(mean, "mean").ravel()     # (text or complex numbers refused, as filter() does)
        if len(z) != len(self.accel_var):
            raise InputError(f"expected {len(self.accel_var)} angles, got {len(z)}")
        mean, std = self._check(z[None, :], float_array(std, "std").reshape(1, -1))
        out, sd = self._step(mean[0], std[0])
        if not (np.all(np.isfinite(out)) and np.all(np.isfinite(sd))):
            self.reset()
        _finite(out, sd)
        return out, sd

    def _step(self, z: np.ndarray, std: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`step` on checked input."""
        var = np.maximum(std**2, 1e-9)
        if self.x is None:
            self._start(z, var)
            return z.copy(), np.sqrt(var) * self.filter_std
        # predict (Eq. 3.6), then update with the GP's mean as the measurement of the angle and
        # its variance as R (Eq. 3.7); the covariance in Joseph form (it stays symmetric positive)
        x = self.x @ self.F.T
        P = self.F @ self.P @ self.F.T + self.Q
        K = P[:, :, 0] / (P[:, 0, 0] + var)[:, None]
        self.x = x + K * (z - x[:, 0])[:, None]
        I_KH = np.tile(np.eye(2), (len(z), 1, 1))
        I_KH[:, :, 0] -= K
        self.P = I_KH @ P @ I_KH.transpose(0, 2, 1) + var[:, None, None] * (K[:, :, None] * K[:, None, :])
        return self.x[:, 0].copy(), np.sqrt(self.P[:, 0, 0]) * self.filter_std

    def _forward(self, mean, std) -> tuple[np.ndarray, np.ndarray]:
        """The forward pass over a sequence: every frame's filtered state and covariance."""
        mean, std = self._check(mean, std)
        self.reset()
        T, k = mean.shape
        xs, Ps = np.empty((T, k, 2)), np.empty((T, k, 2, 2))
        for t in range(T):
            self._step(mean[t], std[t])
            assert self.x is not None  # set by the first step
            xs[t], Ps[t] = self.x, self.P
        return xs, Ps

    def _backward(self, xs: np.ndarray, Ps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The Rauch-Tung-Striebel backward pass over :meth:`_forward`'s states: means and
        standard deviations (not yet multiplied by ``smooth_std``)."""
        T = len(xs)
        out, sd = np.empty(xs.shape[:2]), np.empty(xs.shape[:2])
        if T == 0:
            return out, sd
        x, P = xs[-1], Ps[-1]
        out[-1], sd[-1] = x[:, 0], np.sqrt(P[:, 0, 0])
        for t in range(T - 2, -1, -1):
            Pp = self.F @ Ps[t] @ self.F.T + self.Q  # the prediction of frame t + 1 from frame t
            G = Ps[t] @ self.F.T @ np.linalg.inv(Pp)
            x = xs[t] + (G @ (x - xs[t] @ self.F.T)[:, :, None])[:, :, 0]
            P = Ps[t] + G @ (P - Pp) @ G.transpose(0, 2, 1)
            out[t], sd[t] = x[:, 0], np.sqrt(np.maximum(P[:, 0, 0], 0.0))
        return out, sd

    def filter(self, mean, std) -> tuple[np.ndarray, np.ndarray]:
        xs, Ps = self._forward(mean, std)
        out, sd = xs[:, :, 0].copy(), np.sqrt(Ps[:, :, 0, 0]) * self.filter_std
        _finite(out, sd)
        return out, sd

    def smooth(self, mean, std, frames=None) -> tuple[np.ndarray, np.ndarray]:
        """Offline: every frame's estimate from the whole sequence, past and future frames — the
        forward filter, then the Rauch-Tung-Striebel backward pass (for a recorded video; the
        forward :meth:`filter` is the real-time one).

        ``frames``: the rows' frame numbers (increasing; None: consecutive). A frame missing
        between two rows (a track that lost its box) is a step of the motion model without a
        measurement, so the prior bridges the gap as far as it deserves, instead of taking the
        rows on either side for neighbours."""
        mean, std = self._check(mean, std)
        if frames is not None:
            frames = float_array(frames, "frames")
            if frames.ndim != 1 or not np.all(np.isfinite(frames)) or np.any(frames != np.round(frames)):
                raise InputError("frames must be whole numbers, one per row")
            if len(frames) != len(mean) or np.any(np.diff(frames) < 1):
                raise InputError("frames must number the rows, increasing")
            if len(frames) and frames[-1] - frames[0] + 1 > MAX_FRAME:
                raise InputError(f"frames must span at most {MAX_FRAME} frames, got {frames[-1] - frames[0] + 1:.0f}")
            frames = frames.astype(np.int64)
            if len(frames) and frames[-1] - frames[0] + 1 > len(frames):
                at = frames - frames[0]
                full_mean = np.zeros((at[-1] + 1, mean.shape[1]))
                full_std = np.full_like(full_mean, 1e12)  # no measurement: K ≈ 0
                full_mean[at], full_std[at] = mean, std
                out, sd = self.smooth(full_mean, full_std)
                return out[at], sd[at]
        try:
            out, sd = self._backward(*self._forward(mean, std))
        except np.linalg.LinAlgError:  # a singular predicted covariance
            raise InputError(_OUT_OF_SCALE) from None
        sd = sd * self.smooth_std
        _finite(out, sd)
        return out, sd
