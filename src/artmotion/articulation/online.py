"""Online articulation model selection, Algorithm 1 (Section 4.5).

After ``min_samples`` observations every candidate model fits its configuration ``C_j`` (models.py)
and starts a filter on its motion variables with a Taylor model of order ``n`` (Eq. 4.12-4.14).
Each new observation ``z_k`` (a 3-D point) is predicted by every model through ``f_M(C_j, q)``;
the innovation log-likelihood ``log P(z_k | Z_{0:k-1}, M_j)`` (an EKF where ``f_M`` is non-linear)
updates the model probabilities ``mu_j(k)`` by Eq. 4.16. A model is decided when its probability
passes ``tau``.

All models are scored in the *same observation space* (3-D point positions with the same noise
``R = sigma^2 I``) and the process noise is set in that space too (a white-noise acceleration of
the point, ``sigma_a`` in length/step^2, is ``sigma_a / r`` in angle for a revolute joint), so a
model with more freedom is not favoured by a different scale. Because configurations fitted from
7 samples are poor (a short arc is nearly a line), every model re-fits its configuration as
samples arrive (each time the count grows by 10 %, at least by one sample) and restarts its
filter on the recent window; the model probabilities carry on.

The noise ``sigma`` is ``max(noise_floor, sigma_hat)`` where ``sigma_hat`` is a robust (median
absolute deviation) estimate from the second differences of the (last 500) samples: the data's
own noise, never below the floor (default 5 mm, a tracker's typical accuracy, in metres). The
acceleration noise of the point is ``0.05 sigma`` per time unit squared unless given.

Nested models. A line is a circle of infinite radius and a point is a circle of zero radius, so
evidence between them is only counted where the data can tell them apart at the noise level:

* a "circle" with radius below ``sigma`` cannot gain over the static model;
* an arc can gain over the line once it has turned ``theta_min = sqrt(8 sigma / r_max)``, bulges
  from its chord by ``sigma`` and beats the line's squared residuals by chi^2_2(0.1 %) = 13.8
  noise units; the line can gain over the arc once the motion is ``L_min = sqrt(8 sigma r_max)``
  long (then an arc of the largest expected radius ``r_max``, default 1 m, would differ from it by
  ``sigma``); before either, both score their mixture (Bayes factor held at 1);
* once the line could be told from an arc but the fitted arc is not credible, the revolute
  probability counts for prismatic in the decision (the arc *is* the line at this noise).

Decision. A model is decided while its probability exceeds ``tau``; "static" must in addition have
stayed above ``tau`` for as many samples again as it took to get there (see :meth:`_decide`): the
static model is nested in every moving one (speed zero), so the data can favour it only by Occam's
factor and cannot refute a motion that has not started yet; the observation time is the only time
scale available.

Cost. The per-sample filter steps of the common models (static; one motion variable with constant
velocity) run on Python floats; samples live in a growing array; a configuration re-fit computes
each model's motion variables once (sweep and squared residuals for the separability test come from
them) and the circle's Gauss-Newton refinement works on sums over the points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from artmotion.articulation.models import as_points3, make_model
from artmotion.errors import InputError
from artmotion.filters import taylor_model

__all__ = ["OnlineEstimator", "OnlineResult", "estimate_online", "robust_noise"]

_LOG2PI = math.log(2.0 * math.pi)
_FQ_CACHE: dict = {}
_STATIC_FQ = (np.eye(3), np.zeros((3, 3)))


def robust_noise(X: np.ndarray) -> float:
    """Per-axis noise std from second differences (MAD), averaged over axes with motion."""
    X = np.asarray(X, dtype=float)
    if len(X) < 4:
        return 0.0
    dd = np.ascontiguousarray((X[2:] - 2.0 * X[1:-1] + X[:-2]).T)  # second differences, (3, m)
    mad = 1.4826 * _median_rows(np.abs(dd - _median_rows(dd)[:, None])) / math.sqrt(6.0)
    return float(np.sqrt(np.mean(mad**2)))


def _median_rows(A: np.ndarray) -> np.ndarray:
    """``np.median(A, axis=1)`` by one partition (the same values, less overhead)."""
    m = A.shape[1]
    h = m // 2
    if m % 2:
        return np.partition(A, h, axis=1)[:, h]
    B = np.partition(A, (h - 1, h), axis=1)
    return 0.5 * (B[:, h - 1] + B[:, h])


class _ModelFilter:
    """EKF on the motion variables of one fitted point model (observation = 3-D point)."""

    swept: float  #: motion range of the last configuration fit (set by ``OnlineArticulation``)
    rss: float  #: squared residuals of the last configuration fit (set by ``OnlineArticulation``)

    def __init__(self, model, order: int):
        self._x: np.ndarray | None = None
        self._P: np.ndarray | None = None
        # scalar state of the fast paths (static: x0, x1, x2, p; cv1: q, q', p00, p01, p11)
        self._s: tuple[float, ...] | None = None
        self._prm: tuple | None = None  # the model's parameters as floats, cached between configuration fits
        self._prm_src: np.ndarray | None = None
        self.model = model
        self.order = order if model.dof > 0 else 1
        self.dof = model.dof

    # the state lives in Python floats on the fast paths (no array per step); arrays on demand
    def _sync(self):
        s = self._s
        if s is not None:
            if self.dof == 0:
                self._x = np.array(s[:3])
                self._P = np.diag([s[3]] * 3)
            else:
                self._x = np.array(s[:2])
                self._P = np.array([[s[2], s[3]], [s[3], s[4]]])
            self._s = None

    @property
    def x(self):
        self._sync()
        return self._x

    @x.setter
    def x(self, value):
        self._sync()
        self._x = value
        self._prm = None

    @property
    def P(self):
        self._sync()
        return self._P

    @P.setter
    def P(self, value):
        self._sync()
        self._P = value

    def _FQ(self, dt: float, accel: float):
        if self.dof == 0:  # static: the 3-D position itself, constant
            return _STATIC_FQ
        var = accel**2
        if self.model.name == "revolute":
            var = var / max(self.model.radius, 1e-9) ** 2
        key = (self.order, dt, var, self.dof)
        FQ = _FQ_CACHE.get(key)
        if FQ is None:
            if len(_FQ_CACHE) > 4096:
                _FQ_CACHE.clear()
            FQ = _FQ_CACHE[key] = taylor_model(self.order, dt, var, self.dof)
        return FQ

    def start(self, X: np.ndarray, dts: np.ndarray, sigma: float, accel: float):
        """Fit nothing; initialise the state from a vague prior and filter the window ``X``."""
        if self.dof == 0:
            self.x = X[0].copy()
            self.P = np.eye(3) * 1e6 * (sigma**2 + 1e-12)
        else:
            q = self.model.motion(X[:1])[0]
            n = self.order * self.dof
            self.x = np.zeros(n)
            self.x[:: self.order] = q
            span = max(float(np.ptp(np.asarray(X), axis=0).max()), sigma, 1e-9)
            s = span if self.model.name != "revolute" else span / max(self.model.radius, 1e-9)
            self.P = np.eye(n) * (10.0 * s) ** 2
        zs = np.asarray(X, dtype=float).tolist()
        ds = np.asarray(dts, dtype=float).tolist()
        r2 = sigma * sigma
        if self.dof == 0:
            for z in zs[1:]:
                self._step_static(z, r2)
        elif self.dof == 1 and self.order == 2:
            self._filter_cv1(zs[1:], ds, r2, accel)
        else:
            for k in range(1, len(X)):
                self.step(X[k], dts[k - 1], sigma, accel)

    def step(self, z: np.ndarray, dt: float, sigma: float, accel: float) -> float:
        """Predict over ``dt``, fuse point ``z``; returns the innovation log-likelihood."""
        r2 = sigma * sigma
        if self.dof == 0:
            return self._step_static(z.tolist() if isinstance(z, np.ndarray) else z, r2)
        if self.dof == 1 and self.order == 2:
            return self._step_cv1(z.tolist() if isinstance(z, np.ndarray) else z, dt, r2, accel)
        z = np.asarray(z, dtype=float)
        F, Q = self._FQ(dt, accel)
        x = F @ self.x
        P = F @ self.P @ F.T + Q
        if self.dof == 1:
            # H = J e_0^T: rank one, Sherman-Morrison (S = r2 I + p00 J J^T)
            q = x[0]
            zhat = self.model.predict1(q)
            J = self.model.jacobian1(q)
            y = z - zhat
            j2 = float(J @ J)
            jy = float(J @ y)
            p00 = P[0, 0]
            d = r2 + p00 * j2
            g = 1.0 / d
            col = P[:, 0].copy()
            self.x = x + col * (jy * g)
            self.P = P - (j2 * g) * np.outer(col, col)
            maha = (y @ y - (p00 / d) * jy * jy) / r2
            logdet = 3 * math.log(r2) + math.log(d / r2)
            return float(-0.5 * (3 * _LOG2PI + logdet + maha))
        idx = slice(0, None, self.order)
        q = x[idx]
        zhat = self.model.predict(q)[0]
        J = self.model.jacobian(q)  # (3, dof)
        H = np.zeros((3, x.shape[0]))
        H[:, idx] = J
        y = z - zhat
        PHt = P @ H.T
        S = H @ PHt
        S[np.diag_indices(3)] += r2
        Sinv = np.linalg.inv(S)
        K = PHt @ Sinv
        self.x = x + K @ y
        self.P = P - K @ PHt.T
        self.P = 0.5 * (self.P + self.P.T)
        sign, logdet = np.linalg.slogdet(S)
        return float(-0.5 * (3 * _LOG2PI + logdet + y @ Sinv @ y))

    def _step_static(self, z, r2: float) -> float:
        """Static point: isotropic prior and noise keep ``P = p I`` (F = I, Q = 0), a scalar filter."""
        s = self._s
        if s is None:
            assert self._x is not None and self._P is not None  # set by ``start``
            x0, x1, x2 = self._x.tolist()
            p = float(self._P[0, 0])
        else:
            x0, x1, x2, p = s
        z0, z1, z2 = z
        y0, y1, y2 = z0 - x0, z1 - x1, z2 - x2
        s_ = p + r2
        g = p / s_
        self._s = (x0 + g * y0, x1 + g * y1, x2 + g * y2, p - p * g)
        return -0.5 * (3 * (_LOG2PI + math.log(s_)) + (y0 * y0 + y1 * y1 + y2 * y2) / s_)

    def _step_cv1(self, z, dt: float, r2: float, accel: float) -> float:
        """The common case (one motion variable, constant velocity) in scalars: same maths as the
        general path (Eq. 4.13-4.14 with n = 2, rank-one EKF update)."""
        s = self._s
        if s is None:
            assert self._x is not None and self._P is not None  # set by ``start``
            x0, x1 = self._x.tolist()
            P = self._P
            p00, p01, p11 = float(P[0, 0]), float(P[0, 1]), float(P[1, 1])
        else:
            x0, x1, p00, p01, p11 = s
        m = self.model
        src = m.origin if m.name == "prismatic" else m.centre
        prm = self._prm
        if prm is None or self._prm_src is not src:  # a new configuration fit makes new arrays
            prm = self._prm = m.params
            self._prm_src = src
        var = accel * accel
        if m.name == "revolute":
            var /= max(prm[3], 1e-9) ** 2
        # predict: A = [[1, dt], [0, 1]], Q = var B B^T with B = [dt^2/2, dt]
        b0, b1 = 0.5 * dt * dt, dt
        x0 = x0 + dt * x1
        p00, p01, p11 = (p00 + 2 * dt * p01 + dt * dt * p11 + var * b0 * b0,
                         p01 + dt * p11 + var * b0 * b1, p11 + var * b1 * b1)
        z0, z1, z2 = z
        if m.name == "prismatic":
            ox, oy, oz, dx, dy, dz = prm
            y0, y1, y2 = z0 - ox - x0 * dx, z1 - oy - x0 * dy, z2 - oz - x0 * dz
            jx, jy_, jz = dx, dy, dz
        else:
            cx, cy, cz, r, ux, uy, uz, vx, vy, vz = prm
            co, si = math.cos(x0), math.sin(x0)
            a, b = r * co, r * si
            y0, y1, y2 = z0 - cx - a * ux - b * vx, z1 - cy - a * uy - b * vy, z2 - cz - a * uz - b * vz
            jx, jy_, jz = -b * ux + a * vx, -b * uy + a * vy, -b * uz + a * vz
        j2 = jx * jx + jy_ * jy_ + jz * jz
        jy = jx * y0 + jy_ * y1 + jz * y2
        yy = y0 * y0 + y1 * y1 + y2 * y2
        d = r2 + p00 * j2
        g = jy / d
        x0 += p00 * g
        x1 += p01 * g
        c = j2 / d
        self._s = (x0, x1, p00 - c * p00 * p00, p01 - c * p00 * p01, p11 - c * p01 * p01)
        maha = (yy - (p00 / d) * jy * jy) / r2
        return -0.5 * (3 * _LOG2PI + 3 * math.log(r2) + math.log(d / r2) + maha)

    def _filter_cv1(self, zs, ds, r2: float, accel: float):
        """:meth:`_step_cv1` over a window (the same arithmetic, no likelihoods): filter restarts."""
        assert self._x is not None and self._P is not None  # set by ``start``
        x0, x1 = self._x.tolist()
        P = self._P
        p00, p01, p11 = float(P[0, 0]), float(P[0, 1]), float(P[1, 1])
        m = self.model
        prm = self._prm = m.params
        self._prm_src = m.origin if m.name == "prismatic" else m.centre
        var = accel * accel
        rev = m.name == "revolute"
        if rev:
            var /= max(prm[3], 1e-9) ** 2
            cx, cy, cz, r, ux, uy, uz, vx, vy, vz = prm
        else:
            ox, oy, oz, dx, dy, dz = prm
        cos, sin = math.cos, math.sin
        for (z0, z1, z2), dt in zip(zs, ds):
            b0, b1 = 0.5 * dt * dt, dt
            x0 = x0 + dt * x1
            p00, p01, p11 = (p00 + 2 * dt * p01 + dt * dt * p11 + var * b0 * b0,
                             p01 + dt * p11 + var * b0 * b1, p11 + var * b1 * b1)
            if rev:
                co, si = cos(x0), sin(x0)
                a, b = r * co, r * si
                y0, y1, y2 = z0 - cx - a * ux - b * vx, z1 - cy - a * uy - b * vy, z2 - cz - a * uz - b * vz
                jx, jy_, jz = -b * ux + a * vx, -b * uy + a * vy, -b * uz + a * vz
            else:
                y0, y1, y2 = z0 - ox - x0 * dx, z1 - oy - x0 * dy, z2 - oz - x0 * dz
                jx, jy_, jz = dx, dy, dz
            j2 = jx * jx + jy_ * jy_ + jz * jz
            jy = jx * y0 + jy_ * y1 + jz * y2
            d = r2 + p00 * j2
            g = jy / d
            x0 += p00 * g
            x1 += p01 * g
            c = j2 / d
            p00, p01, p11 = p00 - c * p00 * p00, p01 - c * p00 * p01, p11 - c * p01 * p01
        self._s = (x0, x1, p00, p01, p11)

    def predict_ahead(self, steps: int, dt: float, accel: float) -> np.ndarray:
        """Mean positions of the next ``steps`` samples (no observations)."""
        F, _ = self._FQ(dt, accel)
        x = self.x.copy()
        out = []
        for _ in range(steps):
            x = F @ x
            if self.dof == 0:
                out.append(x.copy())
            else:
                out.append(self.model.predict(x[:: self.order])[0])
        return np.array(out).reshape(-1, 3)


@dataclass
class OnlineResult:
    """What Algorithm 1 found for one track."""

    model: str | None  # decided model at the end (None: undecided)
    probabilities: dict  # final mu_j
    decided_at: int | None  # sample index since which ``model`` has stayed above tau
    first_decision: tuple | None  # (model, sample index) of the first model to pass tau
    history: np.ndarray  # (n, r) model probabilities per sample (NaN before min_samples)
    names: list
    configuration: dict
    motion: np.ndarray  # (n, dof) motion variables of ``model`` (or of the most probable one)
    prediction: np.ndarray  # (h, dim) predicted next samples
    sigma: float
    n: int
    dim: int
    fits: dict = field(default_factory=dict)

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
            "configuration": self.configuration,
            "motion": [list(map(float, row)) for row in self.motion],
            "prediction": [list(map(float, row)) for row in self.prediction],
        }


class OnlineEstimator:
    """Algorithm 1, one observation at a time: ``est.update(z, t)``; ``est.probabilities``.

    ``models``: candidate point models; ``threshold``: tau; ``order``: Taylor order n of the
    motion variables; ``noise_floor``: lower bound of the observation noise std (same unit as the
    points); ``noise``: fixed observation noise std (None: estimate, see module doc);
    ``accel``: white-noise acceleration std of the point per time unit squared (None: 0.05 x noise).
    """

    def __init__(
        self,
        models=("static", "prismatic", "revolute"),
        threshold: float = 0.75,
        min_samples: int = 7,
        order: int = 2,
        noise: float | None = None,
        noise_floor: float = 0.005,
        accel: float | None = None,
        dim: int = 3,
        refit: bool = True,
        window: int = 30,
        max_radius: float = 1.0,
        transfer: bool = False,
        confirm_static: bool = True,
    ):
        if min_samples < 3:
            raise InputError("min_samples must be at least 3")
        if not 0.0 < threshold < 1.0:
            raise InputError("threshold must lie in (0, 1)")
        self.names = list(models)
        self.threshold = threshold
        self.min_samples = min_samples
        self.order = order
        self.noise = noise
        self.noise_floor = noise_floor
        self.accel = accel
        self.dim = dim
        self.refit = refit
        self.window = window
        self.max_radius = max_radius
        self.transfer = transfer
        self._Xbuf = np.empty((64, 3))  # samples in a growing array (doubling): no list -> array copies
        self._Tbuf = np.empty(64)
        self._n = 0
        self.filters: list | None = None
        self.logp = np.zeros(len(self.names))
        self.history: list = []
        self.first_decision: tuple[str, int] | None = None
        self.decisions: list = []  # decided model (or None) per sample
        self._above: tuple[int, int] | None = None  # (model index, first sample) of the current run above tau
        self.confirm_static = confirm_static
        self._next_refit = 0
        self.sigma = noise if noise is not None else noise_floor
        self._sep = (False, False)
        self._static = self.names.index("static") if "static" in self.names else None
        self._rev = self.names.index("revolute") if "revolute" in self.names else None
        self._pri = self.names.index("prismatic") if "prismatic" in self.names else None

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
    def probabilities(self) -> dict:
        """Model probabilities ``mu_j(k)`` (Eq. 4.16), as used for the decision: once the motion is
        long enough to tell a line from an arc but the fitted arc is not credible (see
        :meth:`_separable`), the revolute hypothesis *is* the line and its mass goes to prismatic."""
        return dict(zip(self.names, self._probs()))

    def _probs(self) -> list:
        lp = self.logp.tolist()
        m = max(lp)
        p = [math.exp(v - m) for v in lp]
        tot = sum(p)
        p = [v / tot for v in p]
        if self._rev is not None and self._pri is not None and self.filters is not None:
            rev_ok, pri_ok = self._sep
            if pri_ok and not rev_ok:
                p[self._pri] += p[self._rev]
                p[self._rev] = 0.0
        return p

    @property
    def decision(self) -> str | None:
        """The model decided at the latest sample (None: undecided); see :meth:`_decide`."""
        return self.decisions[-1] if self.decisions else None

    def _decide(self, p: list, k: int) -> str | None:
        """The decision rule on the probabilities ``p`` of sample ``k``.

        A model is decided while its probability exceeds ``tau``, except "static", which must also
        have stayed above ``tau`` for at least as many samples as were seen before it got there
        (decided at ``k >= 2 k0`` when it passed ``tau`` at ``k0``). Static is nested in every moving
        model (speed zero), so data can favour it only by Occam's factor and can never refute a
        motion that has not started yet; with no time scale of the mechanism known, the observation
        time itself is the only scale: a stillness claimed from ``k0`` samples must be confirmed by
        as long again.
        """
        j = max(range(len(p)), key=p.__getitem__)
        if not p[j] > self.threshold:
            self._above = None
            return None
        if self._above is None or self._above[0] != j:
            self._above = (j, k)
        if j == self._static and self.confirm_static and k < 2 * self._above[1]:
            return None
        return self.names[j]

    def _sigma(self) -> float:
        if self.noise is not None:
            return float(self.noise)
        return max(self.noise_floor, robust_noise(self.X[-500:]))

    def _accel(self, sigma: float) -> float:
        return 0.05 * sigma if self.accel is None else float(self.accel)

    def _separable(self) -> tuple[bool, bool]:
        """May the revolute / the prismatic model gain evidence over the other yet?

        A line and an arc of the largest expected radius ``r_max`` differ by ``sigma`` once the
        motion is ``L_min = sqrt(8 sigma r_max)`` long: only then can a line be preferred. An arc
        can be preferred once it has turned ``theta_min = sqrt(8 sigma / r_max)`` and bulges from
        its chord by at least ``sigma``; neither before the point has moved ``4 sigma``.
        """
        assert self.filters is not None and self._rev is not None and self._pri is not None  # see ``_fit_all``
        rmax = self.max_radius
        rev = self.filters[self._rev]
        travel = self.filters[self._pri].swept
        if travel < 4.0 * self.sigma:
            return False, False
        sweep = rev.swept
        sagitta = rev.model.radius * (1.0 - math.cos(min(sweep, math.pi) / 2.0))
        rev_ok = sweep >= math.sqrt(8.0 * self.sigma / rmax) and sagitta >= self.sigma
        if rev_ok:
            # and the arc must explain the points significantly better than the line: the drop in
            # squared residuals (in noise units) beats chi^2 with 2 degrees of freedom at 0.1 %
            rss_line = self.filters[self._pri].rss
            rss_arc = rev.rss
            rev_ok = (rss_line - rss_arc) / self.sigma**2 > 13.8
        pri_ok = travel >= math.sqrt(8.0 * self.sigma * rmax)
        return rev_ok, pri_ok

    def _window(self) -> int:
        """Samples a filter (re)start runs over: the recent ``window``, at least ``min_samples``."""
        return max(self.min_samples, min(self.window, self._n))

    @staticmethod
    def _refit(f: _ModelFilter, X: np.ndarray) -> np.ndarray:
        """Fit ``f``'s configuration to ``X``; set ``f.swept`` and ``f.rss`` (squared residuals, for
        :meth:`_separable`) from the motion variables, which it returns ``(n, 1)``."""
        f.model.fit(X)
        q = f.model.motion(X)
        f.swept = float(np.ptp(q))
        f.rss = float(np.sum((X - f.model.predict(q)) ** 2))
        return q

    def _fit_all(self):
        X = self.X
        T = self.T
        self.sigma = self._sigma()
        a = self._accel(self.sigma)
        if self.filters is None:
            self.filters = [_ModelFilter(make_model(n, self.dim), self.order) for n in self.names]
            for f in self.filters:
                f.model.warm = True  # circle re-fits start from the previous circle when it fits better
        w = self._window()
        for f in self.filters:
            started = f.x is not None
            if started and f.model.dof == 0:
                f.model.fit(X)  # the static filter's state is the position itself: nothing to map
                continue
            if started and f.model.dof == 1 and self.transfer:
                # carry the motion state over to the new configuration: the same predicted point,
                # velocity and covariance mapped through the Jacobians (dq_new = s dq_old)
                x0 = float(f.x[0])
                p_old = f.model.predict1(x0)
                J_old = f.model.jacobian1(x0)
                qs = self._refit(f, X)[:, 0]
                q_new = float(f.model.motion(p_old[None, :])[0, 0])
                if f.model.name == "revolute":
                    q_new = qs[-1] + math.remainder(q_new - qs[-1], 2.0 * math.pi)
                J_new = f.model.jacobian1(q_new)
                s_ = float(J_new @ J_old) / max(float(J_new @ J_new), 1e-300)
                f.x = np.array([q_new, s_ * f.x[1]])
                f.P = f.P * (s_ * s_)
                continue
            if f.model.dof == 1:
                self._refit(f, X)
            else:
                f.model.fit(X)
                f.swept = 0.0
            f.start(X[-w:], np.diff(T[-w:]), self.sigma, a)
        if self._rev is not None and self._pri is not None:
            self._sep = self._separable()
        k = len(X)
        self._next_refit = max(k + 1, int(math.ceil(k * 1.1)))  # geometric schedule: O(log n) re-fits

    # -- the algorithm
    def update(self, z, t: float | None = None) -> dict:
        """Add one observation (2-D or 3-D point); returns the current model probabilities."""
        z = np.asarray(z, dtype=float).reshape(-1)
        if z.shape[0] == 2:
            z = np.array([z[0], z[1], 0.0])
        k = self._n
        t = float(k) if t is None else float(t)
        if k and not t > self._Tbuf[k - 1]:
            raise InputError("time stamps must increase")
        if k == len(self._Tbuf):
            self._Xbuf = np.concatenate([self._Xbuf, np.empty_like(self._Xbuf)])
            self._Tbuf = np.concatenate([self._Tbuf, np.empty_like(self._Tbuf)])
        self._Xbuf[k] = z
        self._Tbuf[k] = t
        self._n = k + 1
        if k + 1 < self.min_samples:
            self.history.append(np.full(len(self.names), np.nan))
            self.decisions.append(None)
            return {}
        if self.filters is None:
            self._fit_all()  # Estimate C_j, Estimate Temporal Structure
        else:
            dt = t - self._Tbuf[k - 1]
            a = self._accel(self.sigma)
            zl = z.tolist()
            sig = self.sigma
            ll = [f.step(zl, dt, sig, a) for f in self.filters]
            if self._static is not None and self._rev is not None and self.filters[self._rev].model.radius < sig:
                # a "circle" smaller than the noise is a static point, not evidence of rotation
                ll[self._rev] = min(ll[self._rev], ll[self._static])
            if self._rev is not None and self._pri is not None:
                rev_ok, pri_ok = self._sep
                r, p = ll[self._rev], ll[self._pri]
                if not (rev_ok or pri_ok):
                    # line and arc not yet told apart: both score their mixture (Bayes factor 1)
                    hi = max(r, p)
                    ll[self._rev] = ll[self._pri] = hi + math.log1p(math.exp(min(r, p) - hi)) - math.log(2.0)
                elif not rev_ok:
                    ll[self._rev] = min(r, p)
                elif not pri_ok:
                    ll[self._pri] = min(r, p)
            lp = [u + v for u, v in zip(self.logp.tolist(), ll)]  # Eq. 4.16 in log space
            m = max(lp)
            self.logp = np.array([v - m for v in lp])
            if self.refit and self._n >= self._next_refit:
                self._fit_all()
        p = self._probs()
        self.history.append(np.array(p))
        d = self._decide(p, k)
        self.decisions.append(d)
        if self.first_decision is None and d is not None:
            self.first_decision = (d, k)
        return dict(zip(self.names, p))

    def result(self, horizon: int = 5) -> OnlineResult:
        n = self._n
        hist = np.array(self.history) if self.history else np.zeros((0, len(self.names)))
        dim = self.dim
        if self.filters is None:
            return OnlineResult(None, {m: 1.0 / len(self.names) for m in self.names}, None, None, hist,
                                self.names, {}, np.zeros((n, 0)), np.zeros((0, dim)), self.sigma, n, dim)
        probs = self.probabilities
        best = int(np.argmax([probs[m] for m in self.names]))
        model = self.decision
        decided_at = None
        if model is not None:
            best = self.names.index(model)
            decided_at = len(self.decisions)
            while decided_at > 0 and self.decisions[decided_at - 1] == model:
                decided_at -= 1
        X = self.X
        T = self.T
        fits = {}
        for f in self.filters:  # final configurations from all samples
            f.model.fit(X)
            fits[f.model.name] = f.model
        f = self.filters[best]
        cfg = f.model.configuration(dim)
        q = f.model.motion(X)
        if f.model.name == "revolute":
            cfg["angle_range"] = [float(q.min()), float(q.max())]
        elif f.model.name == "prismatic":
            cfg["length_range"] = [float(q.min()), float(q.max())]
        cfg["rms_residual"] = float(np.sqrt(np.mean(f.model.residuals(X) ** 2)))
        dt = float(np.median(np.diff(T))) if n > 1 else 1.0
        w = self._window()
        a = self._accel(self.sigma)
        f.start(X[-w:], np.diff(T[-w:]), self.sigma, a)
        pred = f.predict_ahead(horizon, dt, a)[:, :dim]
        return OnlineResult(model, probs, decided_at, self.first_decision, hist, self.names, cfg, q, pred,
                            self.sigma, n, dim, fits)


def estimate_online(X, t=None, **kwargs) -> OnlineResult:
    """Run Algorithm 1 over a whole track ``X`` (``(n, 2)`` or ``(n, 3)``), sample by sample."""
    X3, dim = as_points3(X)
    kwargs.setdefault("dim", dim)
    est = OnlineEstimator(**kwargs)
    for k in range(len(X3)):
        est.update(X3[k], None if t is None else t[k])
    return est.result()
