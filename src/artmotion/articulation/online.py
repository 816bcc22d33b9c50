"""Online articulation model selection, Algorithm 1 (Section 4.5), with Occam-sound scores.

After ``min_samples`` observations every candidate model (static, prismatic = a line, revolute =
a circle) fits its configuration ``C_j`` (models.py) and its noise, and every new observation
``z_k`` (a 2-D or 3-D point) adds its log-likelihood under each model to that model's score,
Eq. 4.16 in log space; the probabilities ``mu_j(k)`` are the normalised exponentials of the scores.

Likelihood of a sample. It splits into the residual ``e`` off the model's manifold (``dim - dof``
dimensions; all of ``z - centre`` for the static model) and the position ``s`` along it (the
line's coordinate, the circle's arc length). ``e`` is scored by a Student-t density (``nu`` = 4
degrees of freedom) with the model's own noise scale ``sigma_j``; ``s`` by the predictive density
of a Kalman filter with a Taylor model of order ``n`` (Eq. 4.12-4.14) that integrates the motion
out (white noise on its acceleration, estimated from the samples' second differences less the
noise's share). A line and a circle through the same samples move alike along them, so both are
scored along the motion by the line's filter: the choice between them rests on their geometry.

Noise from the data, per model. At each configuration fit every model re-fits by iteratively
re-weighted least squares under the Student-t (a fit weighted as a smooth motion sees the samples,
then two re-weighted by the model's residuals: :meth:`OnlineEstimator._smooth_weights`) and
estimates ``sigma_j`` as the t-scale of its residuals: a few slips of the gripper are down-weighted
instead of making every model look impossible. ``noise`` fixes one ``sigma`` for all models (SLAM
knows its sensor); ``noise_floor`` bounds the estimate from below, and so does the rounding of
positions a log wrote with few decimals (:func:`resolution`).

Score (BIC over effective samples):

    score_j(k) = w L_j(k) - (p_j / 2) log(w k) + log O_j

``L_j``: the sum of the log-likelihoods; ``p_j``: parameters fitted to the same samples (the
configuration: static 3, line 4 in 3-D, 2 and 2 in 2-D; the noise levels); ``w = T / tau``: what
one sample is worth. Real residuals are correlated (arm compliance): ``tau`` is the integrated
autocorrelation time of the circle's residuals (Geyer's initial positive sequence; the richest
model's, where no structure is left), and ``T`` (``temperature``) calibrates what remains. A
circle is charged as the line it bends plus the Occam factor ``O_j`` of its curvature
(:meth:`OnlineEstimator._curvature_occam`): with the radius log-uniform on ``radius_range`` (a line
is a circle of infinite radius), a short arc whose curvature the data cannot pin costs nothing and
leaves line and circle tied, while a long, nearly straight one, or a circle larger than any hinge,
pays. ``T`` (0.25) was chosen by leave-one-mechanism-out on the shared logs and synthetic ones;
``radius_range`` (5 cm - 1 m) is the physical range of furniture and tool hinges
(benchmarks/articulation_choice.py, docs/articulation.md).

Re-fits. Configurations fitted from 7 samples are poor, so every model re-fits its configuration
and noise as samples arrive (each time the count grows by ``refit_growth``, 20 %, at least by one
sample) and its score becomes the log-likelihood of all samples under the new fit (between
re-fits, new samples add their predictive log-likelihoods). Motion that reverses (open, close,
open again) is one more acceleration of the motion variable: no fit assumes monotone motion and
the circle's angle is unwrapped.

Decision. A model is decided when its probability exceeds ``tau`` and stays decided until another
model is (``hold``); "static" must in addition have
stayed above ``tau`` for as many samples again as it took to get there (see :meth:`_decide`): the
static model is nested in every moving one (speed zero), so the data can favour it only by Occam's
factor and cannot refute a motion that has not started yet; the observation time is the only time
scale available.

Cost. A sample's step runs on Python floats; samples live in a growing array; re-fits are
O(log n) and the circle's Gauss-Newton refinement works on sums over the points.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field

import numpy as np

from artmotion.articulation.models import MAX_COORD, POINT_MODELS, as_points3, make_model
from artmotion.errors import InputError, check_bool, check_range, float_array
from artmotion.filters import taylor_model, taylor_transition
from artmotion.params import Params

__all__ = ["OnlineEstimator", "OnlineResult", "autocorrelation_time", "curvature_occam", "estimate_online", "robust_scale"]

_LOG2PI = math.log(2.0 * math.pi)
_FQ_CACHE: dict = {}

#: highest Taylor order of the motion model (``dt^order / order!`` must stay a usable float)
MAX_ORDER = 8
#: least and largest step between two samples' time stamps (their powers enter the motion model)
MIN_STEP, MAX_STEP = 1e-12, 1e12
#: least and largest noise level, acceleration and hinge radius (data units): their squares and
#: reciprocals must stay normal floats (a noise of 1e-160 squared is 0, one of 1e200 overflows)
MIN_SCALE, MAX_SCALE = 1e-100, 1e100


def _median_rows(A: np.ndarray) -> np.ndarray:
    """``np.median(A, axis=1)`` by one partition (the same values, less overhead)."""
    m = A.shape[1]
    h = m // 2
    if m % 2:
        return np.partition(A, h, axis=1)[:, h]
    B = np.partition(A, (h - 1, h), axis=1)
    return 0.5 * (B[:, h - 1] + B[:, h])


def _t_const(nu: float | None, d: int) -> float:
    """Normalising constant of a ``d``-dimensional Student-t (``nu``) or Gaussian (None) density."""
    if nu is None:
        return -0.5 * d * _LOG2PI
    return math.lgamma(0.5 * (nu + d)) - math.lgamma(0.5 * nu) - 0.5 * d * math.log(nu * math.pi)


def robust_scale(e2: np.ndarray, d: int, nu: float | None, iters: int = 5) -> tuple[float, np.ndarray]:
    """Scale ``s^2`` of residuals with squared norms ``e2`` in ``d`` dimensions under a Student-t
    (``nu``) or Gaussian (None) model, by iteratively re-weighted least squares; and the weights."""
    n = max(len(e2), 1)
    s2 = float(e2.sum()) / (n * d)
    w = np.ones(len(e2))
    if nu is None or not s2 > 0.0:
        return s2, w
    for _ in range(iters):
        w = (nu + d) / (nu + e2 / s2)
        s2 = max(float(w @ e2) / (n * d), 1e-300)
    return s2, w


def autocorrelation_time(E: np.ndarray) -> float:
    """Integrated autocorrelation time ``tau = 1 + 2 sum_k rho(k)`` of the rows of ``E`` (``(n, d)``:
    a vector series, its components pooled), by Geyer's initial positive sequence (the sum runs while
    consecutive pairs ``rho(2m) + rho(2m + 1)`` stay positive). ``n / tau`` samples carry as much
    information as independent ones."""
    E = np.asarray(E, dtype=float)
    E = E - E.mean(axis=0)
    n = len(E)
    if n < 4:
        return 1.0
    m = 1 << (2 * n - 1).bit_length()
    F = np.fft.rfft(E, m, axis=0)
    acf = np.fft.irfft((F * F.conj()).real.sum(axis=1), m)[:n]
    if not acf[0] > 0.0:
        return 1.0
    rho = acf / acf[0]
    pairs = rho[: n - n % 2].reshape(-1, 2).sum(axis=1)  # Gamma_m = rho(2m) + rho(2m + 1)
    neg = np.flatnonzero(pairs <= 0.0)
    stop = int(neg[0]) if neg.size else len(pairs)
    tau = 2.0 * float(pairs[:stop].sum()) - 1.0
    return float(min(max(tau, 1.0), n / 2.0))


def curvature_occam(khat: float, sk: float, radius_range: tuple[float, float], m: int) -> float:
    """``log E_prior[exp(-|k - k_hat|^2 / (2 sk^2))]`` for a curvature vector ``k`` with ``m`` (1 or 2)
    components whose magnitude ``1 / r`` has ``r`` log-uniform on ``radius_range`` (direction uniform);
    ``k_hat``: magnitude of the fitted curvature. By quadrature over ``|k|`` on a log grid."""
    lo, hi = 1.0 / radius_range[1], 1.0 / radius_range[0]
    rho = np.geomspace(lo, hi, 256)
    a0, a1 = max(lo, khat - 8.0 * sk), min(hi, khat + 8.0 * sk)
    if a0 < a1:  # resolve a likelihood narrower than the grid
        rho = np.union1d(rho, np.linspace(a0, a1, 129))
    a = (rho - khat) ** 2 / (2.0 * sk * sk)
    if m == 2:  # average over the direction: exp(-(rho^2 + k^2) / 2 s^2) I0(rho k / s^2)
        from scipy.special import i0e

        g = np.exp(-a) * i0e(rho * khat / (sk * sk))
    else:  # both signs
        g = np.exp(-a) + np.exp(-((rho + khat) ** 2) / (2.0 * sk * sk))
        g = 0.5 * g
    dens = g / (rho * math.log(hi / lo))  # the log-uniform prior density of |k|
    return float(math.log(max(float(np.sum(0.5 * (dens[1:] + dens[:-1]) * np.diff(rho))), 1e-300)))


def rounding_std(X: np.ndarray) -> float:
    """The std of the rounding of values written on :func:`resolution`'s grid (uniform over a step)."""
    return resolution(X) / math.sqrt(12.0)


def precision_floor(X: np.ndarray) -> float:
    """The least noise std that positions ``X`` can carry: the rounding of values written with few
    decimals (:func:`rounding_std`), and a relative 1e-9 of the data's spread so that
    ``sigma^2 > 0``, or the float precision of its coordinates (``1e-14`` of their magnitude, some
    45 ulps), whichever is larger. Not 1e-9 of the coordinates' magnitude: a drawer's 2 cm track
    with 0.05 mm of noise, in UTM coordinates 5.4e6 m from the origin, was scored against 5.4 mm."""
    X = np.asarray(X, dtype=float)
    if X.size == 0:
        return 1e-100
    return max(rounding_std(X), 1e-9 * float(np.ptp(X, axis=0).max()), 1e-14 * float(np.abs(X).max()), 1e-100)


def resolution(X: np.ndarray, digits: int = 12) -> float:
    """The step of the decimal grid that every value of ``X`` lies on (``10**-d`` for the fewest
    decimals ``d <= digits`` that write them all; 0 when none does): values a log wrote with few
    decimals carry at least their rounding as noise. A value is on the grid when it is within the
    float error of its own size of a grid point (an absolute tolerance put every value below it on
    the coarsest grid: a track of micrometres in metres got a step of 1 and was called static).
    Only the columns that vary count: a constant one says nothing of rounding (an orientation
    written as the quaternion 0 0 0 1 throughout is not rounded to whole numbers)."""
    X = np.asarray(X, dtype=float)
    if X.ndim == 2:
        X = X[:, np.ptp(X, axis=0) > 0]
    X = X.ravel()
    if not len(X):
        return 0.0
    for d in range(digits + 1):
        scaled = X * 10.0**d
        if np.all(np.abs(scaled - np.round(scaled)) <= 1e-14 * np.abs(scaled)):
            return 10.0**-d
    return 0.0


class _ModelFilter:
    """One candidate model's evidence: a fitted configuration, its noise, and a Kalman filter on
    the position *along* the model's manifold.

    A sample ``z`` splits into its residual ``e`` off the manifold (``d = dim - dof`` dimensions;
    all of ``z - centre`` for the static model) and its position along it, the motion variable in
    length units ``s`` (the line's coordinate, the circle's arc length ``r q``). The log-likelihood
    of ``z`` is ``log t_d(e; sigma)`` plus the predictive log-likelihood of ``s`` under the Taylor
    model of order ``n`` (Eq. 4.12-4.14, white noise ``accel`` on the highest derivative, observation
    noise ``sigma``). A line and a circle through the same samples have nearly the same ``s``: their
    temporal terms cancel and the choice between them rests on the geometry; the static model has
    no motion and scores all ``dim`` dimensions as residual.

    ``nu``: Student-t degrees of freedom (None: Gaussian), for the residual and for the filter,
    whose update inflates the noise of an observation far off its prediction by the inverse t-weight
    ``(nu + 1) / (nu + m)`` (``m``: its squared Mahalanobis distance) so one slip does not drag it.
    """

    sigma: float  #: observation noise std off the manifold (set by ``OnlineEstimator``)
    sigma_along: float  #: observation noise std along it (set by ``OnlineEstimator``)
    accel: float  #: process noise std of the motion in length units (set by ``OnlineEstimator``)
    residuals: np.ndarray  #: residual vectors of the last configuration fit

    def __init__(self, model, order: int, nu: float | None = None, dim: int = 3):
        self.model = model
        self.order = order
        self.dof = model.dof
        self.nu = nu
        self.d = dim if model.dof == 0 else max(dim - model.dof, 0)
        self._cd = _t_const(nu, self.d)
        self._c1 = _t_const(nu, 1)
        self.x: np.ndarray | None = None  # filter state per motion variable: (dof, order)
        self.P: np.ndarray | None = None  # (dof, order, order)
        self._q_last = 0.0  # last motion variable of a circle (its angle is unwrapped against it)

    def _t(self, m: float, d: int, c: float) -> float:
        """log density of a ``d``-dim standardised residual with squared norm ``m`` (t or Gaussian)."""
        if self.nu is None:
            return c - 0.5 * m
        return c - 0.5 * (self.nu + d) * math.log1p(m / self.nu)

    def _geometry(self, e2: np.ndarray) -> float:
        """Sum of the residuals' log-densities, ``sum log t_d(e; sigma)``."""
        if self.d == 0:
            return 0.0
        m = e2 / self.sigma**2
        base = len(e2) * (self._cd - self.d * math.log(self.sigma))
        if self.nu is None:
            return float(base - 0.5 * m.sum())
        return float(base - 0.5 * (self.nu + self.d) * np.log1p(m / self.nu).sum())

    def _lengths(self, q: np.ndarray) -> np.ndarray:
        """Motion variables ``(n, dof)`` in length units."""
        return q * self.model.radius if self.model.name == "revolute" else q

    def start(self, X: np.ndarray, T: np.ndarray, along: bool = True) -> tuple[float, float]:
        """Log-likelihoods of all samples ``X`` (times ``T``) under the fitted configuration: off the
        manifold, and along it with the motion integrated out by the filter (the first two samples
        only position it; 0 when ``along`` is False). Leaves the filter at the last sample."""
        m = self.model
        q = m.motion(X)
        E = X - m.predict(q)
        geo = self._geometry(np.einsum("ij,ij->i", E, E))
        if self.dof == 0:
            return geo, 0.0
        self._q_last = float(q[-1, 0])
        if not along:
            self.x = None
            return geo, 0.0
        S = self._lengths(q)
        total = 0.0
        n, o = len(S), self.order
        self.x = np.zeros((self.dof, o))
        self.P = np.zeros((self.dof, o, o))
        r2 = self.sigma_along**2
        # conditioned on the first samples, the loop below going on from the next one: the position
        # at the second sample (order 1), or the state at sample c - 1 that the first c = order
        # samples determine (the polynomial through them: position and velocity from two samples at
        # order 2), with the noise's spread through that polynomial; derivatives that too short a
        # track leaves open get a vague prior. (A vague prior on every derivative beyond the
        # velocity, against the noise of a clean track, put the filter's covariance beyond float
        # precision at orders 4-6.)
        c = min(max(o, 2), n)
        D = np.zeros((o, c))
        if o == 1:
            D[0, c - 1] = 1.0
        else:       # (c <= o) s_i = sum_d h_i^d / d! x_d for the first c derivatives x_d
            h = T[:c] - T[c - 1]
            D[:c] = np.linalg.inv(np.stack([h**i / math.factorial(i) for i in range(c)], axis=1))
        for j in range(self.dof):
            x = D @ S[:c, j]
            P = r2 * (D @ D.T)
            for d in range(c, o):
                P[d, d] = 1e6 * (r2 + float(np.ptp(S[:, j])) ** 2 + 1e-300)
            self.x[j], self.P[j] = x, P
            for k in range(c, n):
                total += self._step_axis(j, float(S[k, j]), float(T[k] - T[k - 1]))
        return geo, total

    def _step_axis(self, j: int, s: float, dt: float) -> float:
        """Predict motion variable ``j`` over ``dt``, fuse its observation ``s``; the log-likelihood."""
        assert self.x is not None and self.P is not None
        r2 = self.sigma_along**2
        var = self.accel**2
        if self.order == 2:  # the common case in floats: A = [[1, dt], [0, 1]], B = [dt^2 / 2, dt]
            x0, x1 = float(self.x[j, 0]), float(self.x[j, 1])
            p00, p01, p11 = float(self.P[j, 0, 0]), float(self.P[j, 0, 1]), float(self.P[j, 1, 1])
            b0, b1 = 0.5 * dt * dt, dt
            x0 = x0 + dt * x1
            p00, p01, p11 = (p00 + 2 * dt * p01 + dt * dt * p11 + var * b0 * b0,
                             p01 + dt * p11 + var * b0 * b1, p11 + var * b1 * b1)
            y = s - x0
            sv = p00 + r2
            m = y * y / sv
            ll = self._t(m, 1, self._c1) - 0.5 * math.log(sv)
            if self.nu is not None and m > 1.0:
                sv = p00 + r2 * (self.nu + m) / (self.nu + 1.0)
            g0, g1 = p00 / sv, p01 / sv
            self.x[j, 0], self.x[j, 1] = x0 + g0 * y, x1 + g1 * y
            self.P[j, 0, 0], self.P[j, 0, 1] = p00 - g0 * p00, p01 - g0 * p01
            self.P[j, 1, 0], self.P[j, 1, 1] = self.P[j, 0, 1], p11 - g1 * p01
            return ll
        F, Q = _taylor(self.order, dt, var)
        x = F @ self.x[j]
        P = F @ self.P[j] @ F.T + Q
        y = s - x[0]
        p00 = max(float(P[0, 0]), 0.0)
        sv = p00 + r2
        m = y * y / sv
        ll = self._t(m, 1, self._c1) - 0.5 * math.log(sv)
        r = r2
        if self.nu is not None and m > 1.0:
            r = r2 * (self.nu + m) / (self.nu + 1.0)
            sv = p00 + r
        K = P[:, 0] / sv
        self.x[j] = x + K * y
        # Joseph's form, (I - K H) P (I - K H)^T + K r K^T: the plain P - K H P lost positive
        # definiteness at orders 4-6 (vague higher derivatives against a noise-free track's 1e-18)
        # and the next innovation variance came out negative
        IKH = np.eye(len(x))
        IKH[:, 0] -= K
        P = IKH @ P @ IKH.T + r * np.outer(K, K)
        self.P[j] = 0.5 * (P + P.T)
        return float(ll)

    def step(self, z, dt: float) -> tuple[float, float]:
        """Log-likelihoods of a new sample ``z`` (3 floats) under the current configuration, off the
        manifold and (when the filter runs, see :meth:`start`) along it."""
        m = self.model
        z0, z1, z2 = z
        s: list[float] = []  # the motion variables in length units
        if m.name == "static":
            c0, c1, c2 = m.centre
            e2 = (z0 - c0) ** 2 + (z1 - c1) ** 2 + (z2 - c2) ** 2
        elif m.name == "prismatic":
            o, dvec = m.origin, m.direction
            y0, y1, y2 = z0 - o[0], z1 - o[1], z2 - o[2]
            q = y0 * dvec[0] + y1 * dvec[1] + y2 * dvec[2]
            e2 = max(y0 * y0 + y1 * y1 + y2 * y2 - q * q, 0.0)
            s = [q]
        elif m.name == "revolute":
            c, u, v, ax = m.centre, m.u, m.v, m.axis
            y0, y1, y2 = z0 - c[0], z1 - c[1], z2 - c[2]
            a = y0 * u[0] + y1 * u[1] + y2 * u[2]
            b = y0 * v[0] + y1 * v[1] + y2 * v[2]
            h = y0 * ax[0] + y1 * ax[1] + y2 * ax[2]
            q = self._q_last + math.remainder(math.atan2(b, a) - self._q_last, 2.0 * math.pi)
            self._q_last = q
            e2 = (math.hypot(a, b) - m.radius) ** 2 + h * h
            s = [q * m.radius]
        else:
            qv = m.motion(np.array([z]))[0]
            e = np.asarray(z) - m.predict(qv[None, :])[0]
            e2 = float(e @ e)
            s = qv.tolist()
        geo = 0.0
        if self.d:
            geo = self._t(e2 / self.sigma**2, self.d, self._cd) - self.d * math.log(self.sigma)
        if self.x is None or not s:
            return geo, 0.0
        return geo, sum(self._step_axis(j, sj, dt) for j, sj in enumerate(s))

    def velocity(self, X: np.ndarray, T: np.ndarray) -> tuple[float, float]:
        """Rate of the (first) motion variable at the last sample and its variance, in the model's
        own units (radians for a circle) per time unit; filters ``X`` if this model's motion was
        scored by the reference filter."""
        if not self.dof:
            return 0.0, 0.0
        if self.x is None:
            self.start(X, T)
        assert self.x is not None and self.P is not None
        scale = 1.0 / self.model.radius if self.model.name == "revolute" else 1.0
        v = float(self.x[0, 1]) if self.order > 1 else 0.0
        p = float(self.P[0, 1, 1]) if self.order > 1 else 0.0
        return v * scale, p * scale * scale

    def predict_ahead(self, steps: int, dt: float) -> np.ndarray:
        """Mean positions of the next ``steps`` samples (no observations)."""
        m = self.model
        if self.dof == 0 or self.x is None:
            return np.repeat(np.asarray(m.centre if self.dof == 0 else m.predict(np.zeros((1, self.dof)))[0])[None, :],
                             steps, axis=0)
        F = taylor_transition(self.order, dt)
        x = self.x.copy()
        out = []
        for _ in range(steps):
            x = x @ F.T
            s = x[:, 0]
            q = s / m.radius if m.name == "revolute" else s
            out.append(m.predict(q[None, :])[0])
        return np.array(out).reshape(-1, 3)


def _taylor(order: int, dt: float, var: float):
    key = (order, dt, var)
    FQ = _FQ_CACHE.get(key)
    if FQ is None:
        if len(_FQ_CACHE) > 4096:
            _FQ_CACHE.clear()
        FQ = _FQ_CACHE[key] = taylor_model(order, dt, var, 1)
    return FQ


@dataclass
class OnlineResult:
    """What Algorithm 1 found for one track."""

    model: str | None  # decided model at the end (None: undecided)
    probabilities: dict  # final mu_j
    decided_at: int | None  # sample index since which ``model`` has stayed decided
    first_decision: tuple | None  # (model, sample index) of the first model to pass tau
    history: np.ndarray  # (n, r) model probabilities per sample (NaN before min_samples)
    names: list
    configuration: dict
    motion: np.ndarray  # (n, dof) motion variables of ``model`` (or of the most probable one)
    prediction: np.ndarray  # (h, dim) predicted next samples
    sigma: float  # observation noise std of ``model`` (estimated unless fixed)
    n: int
    dim: int
    fits: dict = field(default_factory=dict)
    noise: dict = field(default_factory=dict)  # every model's own noise estimate
    margin: float = math.inf  # log-odds of the most probable model over the runner-up (nats)
    runner_up: str | None = None

    @property
    def revised(self) -> bool:
        """True if the first decision was a different model than the final one."""
        return self.first_decision is not None and self.model is not None and self.first_decision[0] != self.model

    def to_dict(self) -> dict:
        return {
            "model": self.model if self.model is not None else "undecided",
            "probabilities": {k: float(v) for k, v in self.probabilities.items()},
            "decided_at": self.decided_at,
            "first_decision": None
            if self.first_decision is None
            else {"model": self.first_decision[0], "at": self.first_decision[1]},
            "samples": self.n,
            "noise": self.sigma,
            "noise_per_model": {k: float(v) for k, v in self.noise.items()},
            "margin": {"runner_up": self.runner_up, "log_odds": self.margin if math.isfinite(self.margin) else None},
            "configuration": self.configuration,
            "motion": [list(map(float, row)) for row in self.motion],
            "prediction": [list(map(float, row)) for row in self.prediction],
        }


class OnlineEstimator(Params):
    """Algorithm 1, one observation at a time: ``est.update(z, t)``; ``est.probabilities``.

    ``models``: candidate point models; ``threshold``: tau; ``order``: Taylor order n of the
    motion variables; ``noise``: one fixed observation noise std for every model (None: each model
    estimates its own, see the module doc), never below ``noise_floor``; ``accel``: fixed white-noise
    acceleration std of the point per time unit squared (None: estimated from the samples);
    ``refit``/``refit_growth``: re-fit the configurations each time the sample count grows by this
    factor; ``nu``: Student-t degrees of freedom of the observations (None: Gaussian);
    ``temperature``: ``T``, the weight of the evidence (see :attr:`weight`); ``radius_range``: prior
    range of a revolute joint's radius (data units; 5 cm - 1 m, the hinges of furniture and hand
    tools), see :meth:`_curvature_occam`; ``hold``: a decision stands until another model is decided.
    ``T`` was chosen by leave-one-mechanism-out (benchmarks/articulation_choice.py).

    ``noise`` lies in ``[MIN_SCALE, MAX_SCALE]``, ``noise_floor`` and ``accel`` in ``[0, MAX_SCALE]``,
    both ends of ``radius_range`` in ``[MIN_SCALE, MAX_SCALE]`` (1e-100 to 1e100); with ``dim=2``
    observations lie in ``z = 0``. Scores that still overflow (a noise far below the data's scale)
    raise an :class:`InputError` instead of giving undefined probabilities.

    scikit-learn's parameter protocol (:class:`~artmotion.params.Params`, without importing
    scikit-learn): the parameters are kept as given (``get_params``, ``sklearn.base.clone``, the
    repr; ``order=3.0`` is order 3), :meth:`set_params` checks them as the constructor does, before
    the first update; ``names`` lists the candidate models.
    """

    def __init__(
        self,
        models=("static", "prismatic", "revolute"),
        threshold: float = 0.75,
        min_samples: int = 7,
        order: int = 2,
        noise: float | None = None,
        noise_floor: float = 0.0,
        accel: float | None = None,
        dim: int = 3,
        refit: bool = True,
        refit_growth: float = 1.2,
        nu: float | None = 4.0,
        temperature: float = 0.25,
        radius_range: tuple[float, float] = (0.05, 1.0),
        confirm_static: bool = True,
        hold: bool = True,
    ):
        # every check comes before any attribute is set: a refused value leaves the estimator as it
        # was (``set_params``); the whole numbers resolved here build the state, the parameters are
        # kept as given (scikit-learn's convention: ``get_params``, ``clone`` and the repr show them)
        check_range("min_samples", min_samples, 3, 10**9, integer=True)
        check_range("threshold", threshold, 0.0, 1.0, lo_open=True, hi_open=True)
        check_range("refit_growth", refit_growth, 1.0, 1e6, lo_open=True)
        check_range("temperature", temperature, 0.0, 1e3, lo_open=True)
        for name, flag in (("refit", refit), ("confirm_static", confirm_static), ("hold", hold)):
            check_bool(name, flag)
        try:
            names = [models] if isinstance(models, str) else list(models)
        except TypeError:
            names = []
        if not names or any(not isinstance(m, str) or m not in POINT_MODELS for m in names) \
                or len(set(names)) != len(names):
            raise InputError(f"models must name some of {', '.join(POINT_MODELS)} (each once), got {models!r}")
        check_range("order", order, 1, MAX_ORDER, integer=True)
        if isinstance(dim, bool) or not isinstance(dim, (int, float, np.number)) or dim not in (2, 3):
            raise InputError(f"dim must be 2 or 3, got {dim!r}")
        d = int(dim)
        if noise is not None:
            check_range("noise", noise, MIN_SCALE, MAX_SCALE)
        check_range("noise_floor", noise_floor, 0.0, MAX_SCALE)
        if accel is not None:
            check_range("accel", accel, 0.0, MAX_SCALE)
        if nu is not None:
            check_range("nu", nu, 0.0, 1e6, lo_open=True)
        try:
            lo, hi = radius_range
        except (TypeError, ValueError):
            raise InputError(f"radius_range must be (low, high), two numbers with 0 < low < high, got {radius_range!r}") from None
        check_range("radius_range's low end", lo, MIN_SCALE, MAX_SCALE)
        check_range("radius_range's high end", hi, lo, MAX_SCALE, lo_open=True)
        self.models = models
        self.threshold = threshold
        self.min_samples = min_samples
        self.order = order
        self.noise = noise
        self.noise_floor = noise_floor
        self.accel = accel
        self.dim = dim
        self.refit = refit
        self.refit_growth = refit_growth
        self.nu = nu
        self.temperature = temperature
        self.radius_range = radius_range
        self.confirm_static = confirm_static
        self.hold = hold
        self.names = names  # the candidate models' names, in order
        self._Xbuf = np.empty((64, 3))  # samples in a growing array (doubling): no list -> array copies
        self._Tbuf = np.empty(64)
        self._n = 0
        self._given: tuple[int, bool] | None = None  # the first observation's size and whether it had a time stamp
        self.filters: list | None = None
        # log-likelihoods per model: off the manifold, and along it (one-parameter motions share the
        # reference model's: the line's when it is a candidate; see ``loglik``)
        self._geo = np.zeros(len(self.names))
        self._along = np.zeros(len(self.names))
        one = [j for j, n in enumerate(self.names) if make_model(n, d).dof == 1]
        self._ref = (self.names.index("prismatic") if "prismatic" in self.names else one[0]) if one else None
        self._shares = np.array([j in one for j in range(len(self.names))])
        self.history: list = []
        self.first_decision: tuple[str, int] | None = None
        self.decisions: list = []  # decided model (or None) per sample
        self._above: tuple[int, int] | None = None  # (model index, first sample) of the current run above tau
        self._next_refit = 0
        self._last_fit = 0
        self.tau = 1.0  # autocorrelation time of the residuals (see ``_autocorrelation``)
        self._static = self.names.index("static") if "static" in self.names else None
        # parameters each model's score is charged ``1/2 log n`` for: configuration, observation
        # noise and (when it moves and the acceleration is estimated) its process noise; a circle is
        # charged as a line, its curvature by its Occam factor (``_curvature_occam``)
        self._charge = np.array([make_model("prismatic" if n == "revolute" else n, d).n_params[d]
                                 + (noise is None) + (accel is None and n != "static") for n in self.names], dtype=float)
        self._occam = np.zeros(len(self.names))
        # the parameters as the algorithm uses them (a whole float such as ``3.0`` is the int it is;
        # the radius range as floats); set_params sets them anew with the parameters
        self._dim, self._order, self._min_samples = d, int(order), int(min_samples)
        self._radius_range = (float(lo), float(hi))

    def set_params(self, **params) -> OnlineEstimator:
        """scikit-learn's ``set_params``: the parameters checked as the constructor checks them (a
        refused one leaves the estimator as it was), and the estimator set up anew from them. Only
        before the first :meth:`update`: the samples seen were scored under the old parameters
        (``clone(est).set_params(...)`` gives a fresh estimator)."""
        if self._n:
            raise InputError(f"set_params: parameters are set before the first update, and this estimator has seen "
                             f"{self._n} sample{'s' if self._n != 1 else ''} (clone(est).set_params(...) gives a "
                             "fresh one)")
        return super().set_params(**params)

    # -- helpers
    @property
    def X(self) -> np.ndarray:
        """The samples so far, ``(n, 3)`` (a view: copy it to keep it)."""
        return self._Xbuf[: self._n]

    @property
    def T(self) -> np.ndarray:
        """Their times, ``(n,)``."""
        return self._Tbuf[: self._n]

    @property
    def sigma(self) -> float:
        """The observation noise std of the most probable model (of all models when fixed)."""
        if self.filters is None:
            return float(self.noise) if self.noise is not None else self.noise_floor
        return self.filters[int(np.argmax(self.scores()))].sigma

    def _own_along(self, j: int) -> bool:
        return not self._shares[j] or j == self._ref

    @property
    def loglik(self) -> np.ndarray:
        """Log-likelihood of the samples under every model (Eq. 4.16 summed in log space). A line
        and a circle through the same samples move alike along them: both are scored along the
        motion by the line's filter, so that the choice between them rests on their geometry."""
        along = self._along.copy()
        if self._ref is not None:
            along[self._shares] = self._along[self._ref]
        return self._geo + along

    @property
    def weight(self) -> float:
        """What one sample is worth: ``T / tau`` (``tau``: autocorrelation time of the residuals)."""
        return self.temperature / self.tau

    def scores(self) -> np.ndarray:
        """``score_j = w sum_i log P(z_i | ...) - p_j / 2 log(w k)``: BIC over the effective sample
        count ``w k`` (``w``: :attr:`weight`; see the module doc)."""
        w = self.weight
        return w * self.loglik - 0.5 * self._charge * math.log(max(w * self._n, 1.0)) + self._occam

    @property
    def probabilities(self) -> dict:
        """Model probabilities ``mu_j(k)``: the normalised exponentials of :meth:`scores` (Eq. 4.16)."""
        return dict(zip(self.names, self._probs()))

    def _probs(self) -> list:
        sc = self.scores().tolist()
        m = max(sc)
        p = [math.exp(v - m) for v in sc]
        tot = sum(p)
        if not tot >= 1.0:  # NaN: a score is NaN, or the best is infinite (the exponent of the best is 1)
            raise InputError(f"Algorithm 1's model scores are not finite at sample {self._n - 1} ({dict(zip(self.names, sc))}): "
                             f"the noise (noise={self.noise}, noise_floor={self.noise_floor}, accel={self.accel}) "
                             "is out of scale with the data; give them in the data's units")
        return [v / tot for v in p]

    @property
    def decision(self) -> str | None:
        """The model decided at the latest sample (None: undecided); see :meth:`_decide`."""
        return self.decisions[-1] if self.decisions else None

    def _decide(self, p: list, k: int) -> str | None:
        """The decision rule on the probabilities ``p`` of sample ``k``.

        A model is decided when its probability exceeds ``tau``, except "static", which must also
        have stayed above ``tau`` for at least as many samples as were seen before it got there
        (decided at ``k >= 2 k0`` when it passed ``tau`` at ``k0``). With ``hold`` (default) a
        decision stands until another model is decided: evidence that wavers below ``tau`` (a
        re-fit, a stretch of the track that fits both models) does not withdraw it; without, a model
        is decided only while above ``tau``. Static is nested in every moving
        model (speed zero), so data can favour it only by Occam's factor and can never refute a
        motion that has not started yet; with no time scale of the mechanism known, the observation
        time itself is the only scale: a stillness claimed from ``k0`` samples must be confirmed by
        as long again.
        """
        j = max(range(len(p)), key=p.__getitem__)
        held = self.decision if self.hold else None
        if not p[j] > self.threshold:
            self._above = None
            return held
        if self._above is None or self._above[0] != j:
            self._above = (j, k)
        if j == self._static and self.confirm_static and k < 2 * self._above[1]:
            return held
        return self.names[j]

    def _fit_model(self, f: _ModelFilter, X: np.ndarray, floor: float, w0: np.ndarray | None):
        """Fit ``f``'s configuration to ``X`` robustly and estimate its noise: Student-t re-weighted
        fits of the configuration, from the samples' starting weights ``w0``
        (:meth:`_smooth_weights`), and of the scale of its residuals (module doc)."""
        s2, E = self._irls(f.model, X, max(f.d, 1), w0)
        line = self.filters[self._ref] if self._ref is not None and self.filters is not None else None
        if f.model.name == "revolute" and line is not None and line is not f and s2 > line.sigma**2:
            # a circle that fits worse than the line it contains started from a bad circle: fit afresh
            cold = copy.deepcopy(f.model)
            cold.warm = False
            s2c, Ec = self._irls(cold, X, max(f.d, 1), w0)
            if s2c < s2:
                cold.warm = True
                f.model, s2, E = cold, s2c, Ec
        f.residuals = E
        f.sigma = max(math.sqrt(s2), floor) if self.noise is None else max(float(self.noise), floor)

    def _irls(self, m, X: np.ndarray, d: int, w: np.ndarray | None) -> tuple[float, np.ndarray]:
        """Model ``m`` fitted to ``X`` from the samples' starting weights ``w``, then twice
        re-weighted by the Student-t of its residuals; the residuals' t-scale squared (``d``
        dimensions) and the residual vectors."""
        for _ in range(3 if self.nu is not None else 1):
            m.fit(X, w)
            E = X - m.predict(m.motion(X))
            s2, w = robust_scale(np.einsum("ij,ij->i", E, E), d, self.nu)
        return s2, E

    def _smooth_weights(self, X: np.ndarray, T: np.ndarray) -> np.ndarray | None:
        """Starting weights of the samples: Student-t weights of their departures from the line
        through their two neighbours (second differences, at times ``T``), the same for every
        model. A plain least-squares start lets a glitch drag every model's fit into a wrong
        Student-t optimum (one sample 1 m off turned a circle prismatic); these give the glitch
        little weight, and no model gains by its own outliers."""
        if self.nu is None or len(X) < 5:
            return None
        span = T[2:] - T[:-2]
        a = np.divide(T[2:] - T[1:-1], span, out=np.full(len(span), 0.5), where=span > 0)[:, None]
        r = X[1:-1] - (a * X[:-2] + (1.0 - a) * X[2:])
        _, w = robust_scale(np.einsum("ij,ij->i", r, r), self._dim, self.nu)
        # a sample takes the least weight of the three differences it enters (a glitch spoils all three)
        w = np.concatenate([[w[0]], w, [w[-1]]])
        return np.minimum(np.minimum(w, np.r_[w[1:], w[-1]]), np.r_[w[0], w[:-1]])

    def _motion_noise(self, X: np.ndarray, sigma: float, dt: float) -> float:
        """Process noise of the motion (length per time unit squared), the same for every model: the
        point's acceleration from robust second differences of the samples, less the share of the
        observation noise ``sigma`` (``Delta^2 x = dt^2 (a_k + a_{k-1}) / 2 + 6 sigma^2`` per axis)."""
        if self.accel is not None:
            return float(self.accel)
        if len(X) < 5:
            return 0.05 * sigma / dt**2
        dd = np.ascontiguousarray((X[2:] - 2.0 * X[1:-1] + X[:-2]).T)
        var = float(np.sum((1.4826 * _median_rows(np.abs(dd - _median_rows(dd)[:, None]))) ** 2))
        return math.sqrt(max(2.0 * (var - 6.0 * self._dim * sigma**2), (0.05 * sigma) ** 2)) / dt**2

    def _curvature_occam(self, j: int) -> float:
        """Log Occam factor of circle ``j``'s curvature over the line it bends.

        A circle is a line bent by a curvature vector ``k`` (``dim - 1`` components, perpendicular to
        the line; ``|k| = 1 / r``). Prior: the radius is log-uniform on ``radius_range`` (data units;
        a line is a circle of infinite radius, so a radius beyond the range *is* a line), any bending
        direction. Likelihood of ``k``: the quadratic through the two fits, peaking at the circle's
        ``k_hat`` and lower by ``Delta`` (the circle's gain over the line, in effective samples) at
        the line, ``k = 0``: ``sigma_k = k_hat / sqrt(2 Delta)``. The factor is the prior's expectation
        of the likelihood relative to its peak (at most 1): a short arc, whose likelihood is flat over
        the prior, costs nothing and leaves line and circle tied; a well measured one pays the
        posterior's share of the prior (in 3-D ``log(sigma_k^2 p(k_hat) / k_hat)``, ``p`` the prior
        density of ``|k|``); a circle outside the range pays for the distance to it. When no circle
        fits better than the line, the likelihood peaks at ``k = 0`` with the width the residuals'
        sensitivity to ``k`` gives.
        """
        if self._ref is None or self.names[self._ref] != "prismatic" or self.filters is None:
            return 0.0
        f = self.filters[j]
        khat = 1.0 / max(f.model.radius, 1e-300)
        gain = self.weight * (self._geo[j] - self._geo[self._ref])
        if gain > 1e-12:
            return curvature_occam(khat, khat / math.sqrt(2.0 * gain), self._radius_range, self._dim - 1)
        # no circle fits better than the line: the likelihood peaks at k = 0 with the width that the
        # residuals' sensitivity to k gives, c^2 the mean square of s^2 / 2 (s: position along the
        # line) after its best fit by a line
        line = self.filters[self._ref]
        s = line.model.motion(self.X)[:, 0]
        L = float(np.ptp(s))
        if not L > 0.0:
            return 0.0
        u = (s - s.mean()) / L
        A = np.column_stack([np.ones_like(u), u])
        b = 0.5 * u * u
        res = b - A @ np.linalg.lstsq(A, b, rcond=None)[0]
        c2 = float(res @ res) / len(u) * L**4
        sk = line.sigma / math.sqrt(max(self.weight * self._n, 1.0) * max(c2, 1e-300))
        return curvature_occam(0.0, sk, self._radius_range, self._dim - 1)

    def _autocorrelation(self) -> float:
        """``tau`` of the residuals of the richest moving model (the circle, if a candidate): like the
        noise level of an F-test, the noise's correlation is measured where no structure is left
        (were the simpler model true, the richer one's residuals would be its noise too)."""
        assert self.filters is not None
        moving = sorted((f for f in self.filters if f.dof), key=lambda f: f.model.n_params[self._dim])
        f = moving[-1] if moving else self.filters[0]
        return autocorrelation_time(f.residuals[:, : self._dim])

    def _floor(self, X: np.ndarray) -> float:
        """Least noise std: ``noise_floor`` or :func:`precision_floor` (noise-free positions of a
        drawer along an axis, printed to 4 decimals, were scored against a noise of 1e-9 and called
        static)."""
        return max(self.noise_floor, precision_floor(X))

    def _fit_all(self):
        X = self.X
        T = self.T
        floor = self._floor(X)
        dt = float(np.median(np.diff(T))) if len(T) > 1 else 1.0
        if self.filters is None:
            self.filters = [_ModelFilter(make_model(n, self._dim), self._order, self.nu, self._dim) for n in self.names]
            for f in self.filters:
                f.model.warm = True  # circle re-fits start from the previous circle when it fits better
                # a circle through points on a line (or at one point) is scored, and loses, not refused
                f.model.require_circle = False
        w0 = self._smooth_weights(X, T)
        for f in self.filters:
            self._fit_model(f, X, floor, w0)
        # the motion's process noise is the same for every model (the point's acceleration); the
        # noise along the motion is each model's own, as off it (isotropic deviations)
        moving = [f for f in self.filters if f.dof]
        if moving:
            accel = self._motion_noise(X, min(f.sigma for f in moving), dt)
            for f in moving:
                f.sigma_along, f.accel = f.sigma, accel
        for j, f in enumerate(self.filters):
            # the marginal likelihood of all samples so far under the new configuration and noise
            self._geo[j], self._along[j] = f.start(X, T, along=self._own_along(j))
        # what one sample is worth, from the residuals' correlation
        self.tau = self._autocorrelation()
        for j, f in enumerate(self.filters):
            if f.model.name == "revolute":
                self._occam[j] = self._curvature_occam(j)
        k = len(X)
        self._last_fit = k
        self._next_refit = max(k + 1, int(math.ceil(k * self.refit_growth)))  # geometric schedule: O(log n) re-fits

    # -- the algorithm
    def update(self, z, t: float | None = None) -> dict:
        """Add one observation (2-D or 3-D point); returns the current model probabilities."""
        z = float_array(z, "an observation").reshape(-1)
        if z.shape[0] not in (2, 3):
            raise InputError(f"an observation must be a 2-D or 3-D point, got {z.shape[0]} values")
        # one kind of observation per track: in 3-D a 2-D point after 3-D ones would be put at
        # z = 0 (a jump of the track; with dim=2 every z is 0 anyway), and an unstamped one after
        # stamped ones would be stamped with its sample index
        given = (int(z.shape[0]) if self._dim == 3 else 2, t is not None)
        if self._given is not None and given != self._given:
            size, stamped = self._given
            if given[0] != size:
                raise InputError(f"an observation must be a {size}-D point like the earlier ones, got {given[0]} values")
            raise InputError("every observation needs a time stamp, as the earlier ones had" if stamped
                             else "no time stamp was given before: give every observation one, or none")
        if z.shape[0] == 2:
            z = np.array([z[0], z[1], 0.0])
        if not (abs(z[0]) <= MAX_COORD and abs(z[1]) <= MAX_COORD and abs(z[2]) <= MAX_COORD):
            raise InputError(f"an observation must be finite coordinates of magnitude at most {MAX_COORD:g}, got {z.tolist()}")
        if self._dim == 2 and z[2] != 0.0:
            raise InputError(f"with dim=2 an observation is a 2-D point (or one with z = 0), got z = {z[2]:g}")
        k = self._n
        if t is None:
            t = float(k)
        else:
            try:
                stamp = np.asarray(t)
                if (stamp.ndim or stamp.dtype.kind in "bcSUV"        # (float() takes "1.5", True, [1.5])
                        or (stamp.dtype.kind == "O" and isinstance(stamp.item(), (str, bytes, bool, complex)))):
                    raise TypeError
                t = float(t)
            except (TypeError, ValueError):
                raise InputError(f"a time stamp must be a (real) number, got {t!r}") from None
            if not math.isfinite(t):
                raise InputError(f"time stamps must be finite, got {t}")
        if k and not t > self._Tbuf[k - 1]:
            raise InputError("time stamps must increase")
        if k and not MIN_STEP <= t - self._Tbuf[k - 1] <= MAX_STEP:
            raise InputError(f"steps between time stamps must lie in [{MIN_STEP:g}, {MAX_STEP:g}], "
                             f"got {t - self._Tbuf[k - 1]:g}")
        if k == len(self._Tbuf):
            self._Xbuf = np.concatenate([self._Xbuf, np.empty_like(self._Xbuf)])
            self._Tbuf = np.concatenate([self._Tbuf, np.empty_like(self._Tbuf)])
        self._Xbuf[k] = z
        self._Tbuf[k] = t
        self._n = k + 1
        self._given = given
        if k + 1 < self._min_samples:
            self.history.append(np.full(len(self.names), np.nan))
            self.decisions.append(None)
            return {}
        if self.filters is None:
            self._fit_all()  # Estimate C_j, Estimate Temporal Structure
        else:
            dt = t - self._Tbuf[k - 1]
            zl = z.tolist()
            if self.noise is not None:  # fixed by the caller (SLAM updates it as it goes)
                for f in self.filters:
                    f.sigma = f.sigma_along = max(float(self.noise), self.noise_floor)
            for j, f in enumerate(self.filters):  # Eq. 4.16 in log space
                g, a = f.step(zl, dt)
                self._geo[j] += g
                self._along[j] += a
            if self.refit and self._n >= self._next_refit:
                self._fit_all()
        p = self._probs()
        self.history.append(np.array(p))
        d = self._decide(p, k)
        self.decisions.append(d)
        if self.first_decision is None and d is not None:
            self.first_decision = (d, k)
        return dict(zip(self.names, p))

    def _final_filters(self, names=None, copies: bool = False) -> dict:
        """The filters of models ``names`` (all by default) with their configurations fitted to all
        samples so far, as at a re-fit (robust start and Student-t re-weighting), on copies so that
        updates may go on; the filters themselves when the last re-fit saw every sample, unless
        ``copies``."""
        assert self.filters is not None
        X = self.X
        stale = self._n > self._last_fit
        floor = self._floor(X) if stale else 0.0
        w0 = self._smooth_weights(X, self.T) if stale else None
        final = {}
        for g in self.filters:
            if names is not None and g.model.name not in names:
                continue
            if stale or copies:
                g = copy.copy(g)
                g.model = copy.deepcopy(g.model)
            if stale:
                self._fit_model(g, X, floor, w0)
                g.x = None  # the filter state belonged to the previous configuration
            final[g.model.name] = g
        return final

    def fitted(self, name: str) -> _ModelFilter:
        """A copy of model ``name``'s filter with its configuration fitted robustly to all samples so
        far: what a caller that acts on Algorithm 1's decision should use, not a plain least-squares
        fit that one glitch drags."""
        if self.filters is None or name not in self.names:
            raise InputError(f"no fitted model {name!r} (models: {', '.join(self.names)}; "
                             f"fitted after {self.min_samples} samples)")
        return self._final_filters({name}, copies=True)[name]

    def result(self, horizon: int = 5) -> OnlineResult:
        """What Algorithm 1 found so far, with the ``horizon`` samples it predicts next (a whole number >= 0)."""
        horizon = check_range("horizon", horizon, 0, 10**6, integer=True)
        n = self._n
        hist = np.array(self.history) if self.history else np.zeros((0, len(self.names)))
        dim = self._dim
        if self.filters is None:
            return OnlineResult(None, {m: 1.0 / len(self.names) for m in self.names}, None, None, hist,
                                self.names, {}, np.zeros((n, 0)), np.zeros((0, dim)), self.sigma, n, dim)
        probs = self.probabilities
        scores = self.scores()
        order = np.argsort(-scores)
        best = int(order[0])
        model = self.decision
        decided_at = None
        if model is not None:
            best = self.names.index(model)
            decided_at = len(self.decisions)
            while decided_at > 0 and self.decisions[decided_at - 1] == model:
                decided_at -= 1
        X = self.X
        T = self.T
        final = self._final_filters()
        f = final[self.names[best]]
        fits = {k: g.model for k, g in final.items()}
        noise = {k: g.sigma for k, g in final.items()}
        cfg = f.model.configuration(dim)
        q = f.model.motion(X)
        if f.model.name == "revolute":
            cfg["angle_range"] = [float(q.min()), float(q.max())]
        elif f.model.name == "prismatic":
            cfg["length_range"] = [float(q.min()), float(q.max())]
        cfg["rms_residual"] = float(np.sqrt(np.mean(f.model.residuals(X) ** 2)))
        dt = float(np.median(np.diff(T))) if n > 1 else 1.0
        if f.dof and f.x is None:  # its motion was scored by the reference filter: run its own
            f.start(X, T)
        pred = f.predict_ahead(horizon, dt)[:, :dim]
        margin = float(scores[order[0]] - scores[order[1]]) if len(order) > 1 else math.inf
        return OnlineResult(model, probs, decided_at, self.first_decision, hist, self.names, cfg, q, pred,
                            f.sigma, n, dim, fits, noise, margin, str(self.names[order[1]]) if len(order) > 1 else None)


def estimate_online(X, t=None, **kwargs) -> OnlineResult:
    """Run Algorithm 1 over a whole track ``X`` (``(n, 2)`` or ``(n, 3)``), sample by sample."""
    known = OnlineEstimator._param_names()      # (a bare TypeError otherwise)
    unknown = sorted(set(kwargs) - set(known))
    if unknown:
        raise InputError(f"{', '.join(map(repr, unknown))} is not an option of the model choice "
                         f"(OnlineEstimator's: {', '.join(known)})")
    X3, dim = as_points3(X)
    if t is not None:
        t = float_array(t, "time stamps")
        if t.shape != (len(X3),):
            raise InputError(f"t must hold one time stamp per sample ({len(X3)}), got shape {t.shape}")
    given = kwargs.get("dim", dim)
    if not isinstance(given, bool) and given in (2, 3) and given != dim:
        raise InputError(f"dim={given!r} but the points have {dim} columns: give (n, {given}) points or dim={dim}")
    kwargs.setdefault("dim", dim)
    est = OnlineEstimator(**kwargs)
    for k in range(len(X3)):
        est.update(X3[k], None if t is None else t[k])
    return est.result()
