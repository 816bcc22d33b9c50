"""The state of every tracked entity (thesis Sec. 2.5.1, motion continuity Eq. 2.10).

Each entity's box is a constant-velocity Kalman filter on ``[cx, cy, w, h]`` with their
velocities (per second, so that the same settings hold at 7 and at 30 frames per second). The
acceleration is white noise (Eq. 2.10: ``Q = B Σ_a Bᵀ`` per coordinate with ``B = [½Δt², Δt]``);
``Σ_a`` and the measurement noise are proportional to the box's size, so a person far away and
one close to the camera are treated alike. All filters live in one :class:`KalmanBank` and are
predicted and updated together (vectorised over the entities), with filterpy's names: ``x``
(state), ``P`` (covariance), ``F``, ``Q``, ``H``, ``R``.

The bank also applies the camera's own motion (:meth:`KalmanBank.warp`, a 2×3 similarity from
:mod:`artmotion.tracking.camera`) to the states and their covariances.
"""

from __future__ import annotations

import numpy as np

__all__ = ["NoiseEstimator", "DETECTED", "GROUP", "INTERPOLATED", "KINDS", "LOST", "TENTATIVE", "KalmanBank", "boxes_to_z",
           "warp_matrix", "z_to_boxes"]

#: what supports a track's state on a frame: an assigned detection, the image experts and motion
#: only (lost), motion inside a group node, a detection before the track was confirmed, the
#: offline interpolation
KINDS = ("det", "lost", "group", "tentative", "interp")
DETECTED, LOST, GROUP, TENTATIVE, INTERPOLATED = range(len(KINDS))
_DIAG = np.arange(4)


def boxes_to_z(boxes) -> np.ndarray:
    """``(N, 4)`` boxes ``x, y, w, h`` (top-left) to measurements ``cx, cy, w, h``."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    z = b.copy()
    z[:, :2] += 0.5 * b[:, 2:4]
    return z


def warp_matrix(A: np.ndarray) -> np.ndarray:
    """The 8×8 map of the state ``cx, cy, w, h`` and their velocities under the camera's motion
    ``A`` (2×3 similarity): centres and their velocities rotate and scale, sizes scale."""
    M = A[:, :2]
    s = float(np.sqrt(abs(np.linalg.det(M))))
    T = np.zeros((8, 8))
    T[:2, :2] = T[4:6, 4:6] = M
    T[2, 2] = T[3, 3] = T[6, 6] = T[7, 7] = s
    return T


def z_to_boxes(z) -> np.ndarray:
    """Inverse of :func:`boxes_to_z`."""
    z = np.asarray(z, dtype=float).reshape(-1, 4)
    b = z.copy()
    b[:, :2] -= 0.5 * z[:, 2:4]
    return b



def _row_medians(a: np.ndarray) -> np.ndarray:
    """``np.median(a, axis=1)``, the same numbers, without importing ``numpy.ma`` (which
    ``np.median`` does on its first call: a few ms of every command's start-up)."""
    n = a.shape[1]
    k = (n - 1) // 2
    if n == 0:
        return np.full(a.shape[0], np.nan)
    if n % 2:
        return np.partition(a, k, axis=1)[:, k]
    part = np.partition(a, [k, k + 1], axis=1)
    return (part[:, k] + part[:, k + 1]) / 2

class KalmanBank:
    """Constant-velocity Kalman filters of many boxes (state ``cx, cy, w, h, vcx, vcy, vw, vh``).

    ``accel``: standard deviation of the centre's acceleration, in box sizes per s² (x relative
    to the width, y to the height); ``size_accel`` the same for width and height; ``meas``:
    standard deviation of a detection's centre, relative to the box size; ``size_meas`` of its
    width and height; ``speed0``: prior standard deviation of a new entity's speed, box heights
    per second. Slots are reused; ``capacity`` grows as needed.
    """

    def __init__(self, accel: float = 1.0, size_accel: float = 0.25, meas: float = 0.05, size_meas: float = 0.05,
                 speed0: float = 1.0, capacity: int = 32):
        #: standard deviations of the acceleration of cx, cy, w, h relative to (w, h, w, h)
        self.rel_accel = np.array([accel, accel, size_accel, size_accel], dtype=float)
        #: standard deviations of a detection's cx, cy, w, h relative to (w, h, w, h)
        self.rel_sd = np.array([meas, meas, size_meas, size_meas], dtype=float)
        self.speed0 = float(speed0)
        self.x = np.zeros((capacity, 8))
        self.P = np.zeros((capacity, 8, 8))
        self.free = list(range(capacity - 1, -1, -1))

    # ------------------------------------------------------------------ slots
    def add(self, box) -> int:
        """A new filter at ``box`` (``x, y, w, h``) with zero velocity; returns its slot."""
        if not self.free:
            n = len(self.x)
            self.x = np.concatenate([self.x, np.zeros((n, 8))])
            self.P = np.concatenate([self.P, np.zeros((n, 8, 8))])
            self.free = list(range(2 * n - 1, n - 1, -1))
        s = self.free.pop()
        z = boxes_to_z(box)[0]
        self.x[s] = 0.0
        self.x[s, :4] = z
        w, h = max(z[2], 1.0), max(z[3], 1.0)
        sd = np.concatenate([self.rel_sd * [w, h, w, h],
                             [self.speed0 * h, self.speed0 * h, 0.1 * self.speed0 * w, 0.1 * self.speed0 * h]])
        self.P[s] = np.diag(sd ** 2)
        return s

    def remove(self, slot: int) -> None:
        self.free.append(slot)

    # ------------------------------------------------------------------ filter steps
    @staticmethod
    def _sizes(x: np.ndarray) -> np.ndarray:
        """``(N, 4)`` box sizes ``w, h, w, h`` (at least 1 pixel) of states ``x``: the scale of
        each coordinate's noise."""
        return np.maximum(x[:, 2:4], 1.0)[:, [0, 1, 0, 1]]

    def predict(self, slots, dt: float) -> None:
        """One time step of ``dt`` seconds for the filters in ``slots`` (Eq. 2.10)."""
        slots = np.asarray(slots, dtype=int)
        if not len(slots):
            return
        x, P = self.x[slots], self.P[slots]
        # Q = B Σ_a B' per coordinate, Σ_a proportional to the box size (before the step)
        sa = (self._sizes(x) * self.rel_accel) ** 2
        x[:, :4] += dt * x[:, 4:]
        # P <- F P F' with F = [[I, dt I], [0, I]], by blocks (in place: P is a copy)
        A, B, C, D = P[:, :4, :4], P[:, :4, 4:], P[:, 4:, :4], P[:, 4:, 4:]
        A += dt * (B + C)
        A += dt * dt * D
        B += dt * D
        C += dt * D
        q_pp, q_pv, q_vv = dt ** 4 / 4.0, dt ** 3 / 2.0, dt * dt
        P[:, _DIAG, _DIAG] += q_pp * sa
        P[:, _DIAG, _DIAG + 4] += q_pv * sa
        P[:, _DIAG + 4, _DIAG] += q_pv * sa
        P[:, _DIAG + 4, _DIAG + 4] += q_vv * sa
        self.x[slots] = x
        self.P[slots] = P

    def R(self, slots) -> np.ndarray:
        """Measurement noise ``(N, 4)`` variances of the filters' detections."""
        return (self._sizes(self.x[slots]) * self.rel_sd) ** 2

    def update(self, slots, boxes, R=None) -> None:
        """Kalman update of ``slots`` with measured ``boxes`` (``x, y, w, h``); ``R`` optional
        ``(N, 4)`` variances (default :meth:`R`)."""
        slots = np.asarray(slots, dtype=int)
        if not len(slots):
            return
        z = boxes_to_z(boxes)
        x, P = self.x[slots], self.P[slots]
        S = P[:, :4, :4].copy()
        r = self.R(slots) if R is None else np.asarray(R, dtype=float).reshape(-1, 4)
        S[:, np.arange(4), np.arange(4)] += r
        PHt = P[:, :, :4]                                   # (N, 8, 4)
        K = np.linalg.solve(S, PHt.transpose(0, 2, 1)).transpose(0, 2, 1)   # P H' S^-1 (S symmetric)
        x = x + np.einsum("nij,nj->ni", K, z - x[:, :4])
        P = P - np.einsum("nij,njk->nik", K, P[:, :4, :])
        self.x[slots] = x
        self.P[slots] = 0.5 * (P + P.transpose(0, 2, 1))

    def warp(self, slots, A) -> None:
        """Apply the camera's motion ``A`` (2×3 similarity, previous frame -> current frame)."""
        slots = np.asarray(slots, dtype=int)
        if not len(slots):
            return
        A = np.asarray(A, dtype=float)
        T = warp_matrix(A)
        x = self.x[slots] @ T.T
        x[:, :2] += A[:, 2]
        self.x[slots] = x
        self.P[slots] = np.einsum("ij,njk,lk->nil", T, self.P[slots], T)

    # ------------------------------------------------------------------ read-out
    def boxes(self, slots) -> np.ndarray:
        """Current boxes ``x, y, w, h`` of ``slots``."""
        slots = np.asarray(slots, dtype=int)
        z = self.x[slots, :4].copy()
        z[:, 2:4] = np.maximum(z[:, 2:4], 1.0)
        return z_to_boxes(z)

    def velocity(self, slot: int) -> np.ndarray:
        """Centre velocity (pixels per second) of one filter."""
        return self.x[slot, 4:6].copy()

    def centre_cov(self, slot: int) -> np.ndarray:
        """Covariance of one filter's centre."""
        return self.P[slot, :2, :2].copy()


class NoiseEstimator:
    """Both noises of the constant-velocity model estimated from the detections themselves, per
    coordinate (cx, cy, w, h, relative to the box size): the detector's noise ``R`` and the
    acceleration noise ``Q`` (Eq. 2.10).

    Fixed noise levels suit the data they were chosen on and nothing else: the Faster R-CNN boxes
    of a 1080p pedestrian zone scatter by 1-7 % of the box, those of MOT15 by 8-21 %; people walk
    at a steady pace, while a surgical tool near the camera changes its image size several times
    a second. Both levels are therefore method-of-moments estimates from the second differences
    of each track's detections on consecutive frames. Under the model (white acceleration of
    variance ``q``, detections with independent noise of variance ``r``), the second difference
    at lag ``L``, ``z[k+L] - 2 z[k] + z[k-L]``, has variance ``L (4L² - 1) / 6 · Δt⁴ q + 6 r``:
    lag 1 (``V1 = Δt⁴ q / 2 + 6 r``) and the lag of ``horizon`` seconds (:attr:`lag`, at least 3)
    give two equations in the two unknowns. Each variance is the median of the squared differences over the last
    ``window`` samples divided by the median of χ²₁ (a wrong association or a box cut by an
    occluder does not inflate it). The configured noise is a prior worth ``prior_n`` samples; the
    estimates never go below ``floor`` (relative standard deviations).
    """

    _MEDIAN_CHI2_1 = 0.4549364231195724   # median of chi-square with 1 degree of freedom

    def __init__(self, meas_sd, accel_sd, dt: float, window: int = 400, prior_n: int = 20, floor: float = 0.005,
                 horizon: float = 1.0):
        self.prior_r = np.asarray(meas_sd, dtype=float) ** 2
        self.prior_q = np.asarray(accel_sd, dtype=float) ** 2
        self.dt = float(dt)
        self.window = int(window)
        self.prior_n = float(prior_n)
        self.floor = float(floor)
        # squared second differences at lag 1 and at the long lag: a ring of the last ``window``
        self._d2 = np.zeros((2, self.window, 4))
        self._n = self._next = 0
        self._recent: dict[int, list] = {}
        #: the long lag, in frames: the time scale over which the acceleration is measured
        self.lag = max(3, int(round(horizon / self.dt)))
        self._r, self._q = self.prior_r.copy(), self.prior_q.copy()
        self._stale = False

    @staticmethod
    def _scale(z: np.ndarray) -> np.ndarray:
        w, h = max(z[2], 1.0), max(z[3], 1.0)
        return np.array([w, h, w, h])

    def observe(self, key: int, frame: int, z) -> None:
        """Detection ``z`` (``cx, cy, w, h``) of track ``key`` on ``frame``; a track's samples
        are its runs of detections on consecutive frames."""
        z = np.asarray(z, dtype=float)
        buf = self._recent.get(key)
        if buf is None or buf[-1][0] != frame - 1:
            buf = self._recent[key] = []
        buf.append((frame, z))
        L = self.lag
        if len(buf) > 2 * L + 1:
            del buf[0]
        if len(buf) < 2 * L + 1:
            return
        zs = [b[1] for b in buf]
        self._d2[0, self._next] = ((zs[-1] - 2 * zs[-2] + zs[-3]) / self._scale(zs[-2])) ** 2
        self._d2[1, self._next] = ((zs[-1] - 2 * zs[-1 - L] + zs[-1 - 2 * L]) / self._scale(zs[-1 - L])) ** 2
        self._next = (self._next + 1) % self.window
        self._n = min(self._n + 1, self.window)
        self._stale = True      # estimated when asked for: once per frame, not per detection

    def forget(self, key: int) -> None:
        """Track ``key`` ended."""
        self._recent.pop(key, None)

    @property
    def n(self) -> int:
        return self._n

    def _estimate(self) -> None:
        if not self._stale:
            return
        c, dt4 = self._MEDIAN_CHI2_1, self.dt ** 4
        v1, vL = _row_medians(self._d2[:, :self._n]) / c
        L = self.lag
        q = np.maximum(vL - v1, 0.0) / ((L * (4 * L * L - 1) / 6.0 - 0.5) * dt4)
        r = np.maximum(v1 - 0.5 * dt4 * q, 0.0) / 6.0
        n, p = self._n, self.prior_n
        self._r, self._q = (n * r + p * self.prior_r) / (n + p), (n * q + p * self.prior_q) / (n + p)
        self._stale = False

    def sd(self) -> np.ndarray:
        """Relative standard deviations of a detection's cx, cy, w, h."""
        self._estimate()
        return np.sqrt(np.maximum(self._r, self.floor ** 2))

    def accel_sd(self) -> np.ndarray:
        """Relative standard deviations of the acceleration of cx, cy, w, h (box sizes per s²)."""
        self._estimate()
        return np.sqrt(np.maximum(self._q, self.floor ** 2))
