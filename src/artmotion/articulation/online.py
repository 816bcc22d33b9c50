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
samples arrive (at every sample while few, then each time the count grows by 10 %) and restarts its
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
    dd = np.diff(X, n=2, axis=0)
    mad = 1.4826 * np.median(np.abs(dd - np.median(dd, axis=0)), axis=0) / math.sqrt(6.0)
    return float(np.sqrt(np.mean(mad**2)))


class _ModelFilter:
    """EKF on the motion variables of one fitted point model (observation = 3-D point)."""

    def __init__(self, model, order: int):
        self.x = None
        self.model = model
        self.order = order if model.dof > 0 else 1
        self.dof = model.dof

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
            var = np.ones(n)
            span = max(float(np.ptp(np.asarray(X), axis=0).max()), sigma, 1e-9)
            s = span if self.model.name != "revolute" else span / max(self.model.radius, 1e-9)
            var[:] = (10.0 * s) ** 2
            var[:: self.order] = (10.0 * s) ** 2
            self.P = np.diag(var)
        for k in range(1, len(X)):
            self.step(X[k], dts[k - 1], sigma, accel)

    def step(self, z: np.ndarray, dt: float, sigma: float, accel: float) -> float:
        """Predict over ``dt``, fuse point ``z``; returns the innovation log-likelihood."""
        r2 = sigma * sigma
        if self.dof == 0:
            return self._step_static(z, r2)
        if self.dof == 1 and self.order == 2:
            return self._step_cv1(z, dt, r2, accel)
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
        p = self.P[0, 0]
        x0, x1, x2 = self.x.tolist()
        z0, z1, z2 = z.tolist() if isinstance(z, np.ndarray) else z
        y0, y1, y2 = z0 - x0, z1 - x1, z2 - x2
        s = p + r2
        g = p / s
        self.x = np.array([x0 + g * y0, x1 + g * y1, x2 + g * y2])
        self.P = np.diag([p - p * g] * 3)
        return -0.5 * (3 * (_LOG2PI + math.log(s)) + (y0 * y0 + y1 * y1 + y2 * y2) / s)

    def _step_cv1(self, z, dt: float, r2: float, accel: float) -> float:
        """The common case (one motion variable, constant velocity) in scalars: same maths as the
        general path (Eq. 4.13-4.14 with n = 2, rank-one EKF update)."""
        x0, x1 = self.x
        P = self.P
        p00, p01, p11 = P[0, 0], P[0, 1], P[1, 1]
        var = accel * accel
        if self.model.name == "revolute":
            var /= max(self.model.radius, 1e-9) ** 2
        # predict: A = [[1, dt], [0, 1]], Q = var B B^T with B = [dt^2/2, dt]
        b0, b1 = 0.5 * dt * dt, dt
        x0 = x0 + dt * x1
        p00, p01, p11 = (p00 + 2 * dt * p01 + dt * dt * p11 + var * b0 * b0,
                         p01 + dt * p11 + var * b0 * b1, p11 + var * b1 * b1)
        z0, z1, z2 = z.tolist() if isinstance(z, np.ndarray) else z
        m = self.model
        if m.name == "prismatic":
            ox, oy, oz, dx, dy, dz = m.params
            y0, y1, y2 = z0 - ox - x0 * dx, z1 - oy - x0 * dy, z2 - oz - x0 * dz
            jx, jy_, jz = dx, dy, dz
        else:
            cx, cy, cz, r, ux, uy, uz, vx, vy, vz = m.params
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
        n00, n01, n11 = p00 - c * p00 * p00, p01 - c * p00 * p01, p11 - c * p01 * p01
        self.x = np.array([x0, x1])
        self.P = np.array([[n00, n01], [n01, n11]])
        maha = (yy - (p00 / d) * jy * jy) / r2
        return -0.5 * (3 * _LOG2PI + 3 * math.log(r2) + math.log(d / r2) + maha)

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
        self.X: list = []
        self.T: list = []
        self.filters: list | None = None
        self.logp = np.zeros(len(self.names))
        self.history: list = []
        self.first_decision = None
        self._next_refit = 0
        self.sigma = noise if noise is not None else noise_floor
        self._sep = (False, False)
        self._static = self.names.index("static") if "static" in self.names else None
        self._rev = self.names.index("revolute") if "revolute" in self.names else None
        self._pri = self.names.index("prismatic") if "prismatic" in self.names else None

    # -- helpers
    @property
    def probabilities(self) -> dict:
        """Model probabilities ``mu_j(k)`` (Eq. 4.16), as used for the decision: once the motion is
        long enough to tell a line from an arc but the fitted arc is not credible (see
        :meth:`_separable`), the revolute hypothesis *is* the line and its mass goes to prismatic."""
        p = np.exp(self.logp - self.logp.max())
        p /= p.sum()
        if self._rev is not None and self._pri is not None and self.filters is not None:
            rev_ok, pri_ok = self._sep
            if pri_ok and not rev_ok:
                p[self._pri] += p[self._rev]
                p[self._rev] = 0.0
        return dict(zip(self.names, p))

    def _sigma(self) -> float:
        if self.noise is not None:
            return float(self.noise)
        return max(self.noise_floor, robust_noise(np.asarray(self.X[-500:])))

    def _accel(self, sigma: float) -> float:
        return 0.05 * sigma if self.accel is None else float(self.accel)

    def _separable(self) -> tuple[bool, bool]:
        """May the revolute / the prismatic model gain evidence over the other yet?

        A line and an arc of the largest expected radius ``r_max`` differ by ``sigma`` once the
        motion is ``L_min = sqrt(8 sigma r_max)`` long: only then can a line be preferred. An arc
        can be preferred once it has turned ``theta_min = sqrt(8 sigma / r_max)`` and bulges from
        its chord by at least ``sigma``; neither before the point has moved ``4 sigma``.
        """
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
            X = np.asarray(self.X)
            rss_line = float(np.sum(self.filters[self._pri].model.residuals(X) ** 2))
            rss_arc = float(np.sum(rev.model.residuals(X) ** 2))
            rev_ok = (rss_line - rss_arc) / self.sigma**2 > 13.8
        pri_ok = travel >= math.sqrt(8.0 * self.sigma * rmax)
        return rev_ok, pri_ok

    def _fit_all(self):
        X = np.asarray(self.X)
        T = np.asarray(self.T)
        self.sigma = self._sigma()
        a = self._accel(self.sigma)
        if self.filters is None:
            self.filters = [_ModelFilter(make_model(n, self.dim), self.order) for n in self.names]
        w = max(self.min_samples, min(self.window, len(X)))
        for f in self.filters:
            started = getattr(f, "x", None) is not None
            if started and f.model.dof == 0:
                f.model.fit(X)  # the static filter's state is the position itself: nothing to map
                continue
            if started and f.model.dof == 1 and self.transfer:
                # carry the motion state over to the new configuration: the same predicted point,
                # velocity and covariance mapped through the Jacobians (dq_new = s dq_old)
                x0 = float(f.x[0])
                p_old = f.model.predict1(x0)
                J_old = f.model.jacobian1(x0)
                f.model.fit(X)
                qs = f.model.motion(X)[:, 0]
                f.swept = float(np.ptp(qs))
                q_new = float(f.model.motion(p_old[None, :])[0, 0])
                if f.model.name == "revolute":
                    q_new = qs[-1] + math.remainder(q_new - qs[-1], 2.0 * math.pi)
                J_new = f.model.jacobian1(q_new)
                s_ = float(J_new @ J_old) / max(float(J_new @ J_new), 1e-300)
                f.x = np.array([q_new, s_ * f.x[1]])
                f.P = f.P * (s_ * s_)
                continue
            f.model.fit(X)
            f.swept = float(np.ptp(f.model.motion(X))) if f.model.dof == 1 else 0.0
            f.start(X[-w:], np.diff(T[-w:]), self.sigma, a)
        if self._rev is not None and self._pri is not None:
            self._sep = self._separable()
        k = len(X)
        self._next_refit = k + 1 if k < 30 else int(math.ceil(k * 1.1))

    # -- the algorithm
    def update(self, z, t: float | None = None) -> dict:
        """Add one observation (2-D or 3-D point); returns the current model probabilities."""
        z = np.asarray(z, dtype=float).reshape(-1)
        if z.shape[0] == 2:
            z = np.array([z[0], z[1], 0.0])
        t = float(len(self.X)) if t is None else float(t)
        if self.T and not t > self.T[-1]:
            raise InputError("time stamps must increase")
        k = len(self.X)
        self.X.append(z)
        self.T.append(t)
        if k + 1 < self.min_samples:
            self.history.append(np.full(len(self.names), np.nan))
            return {}
        if self.filters is None:
            self._fit_all()  # Estimate C_j, Estimate Temporal Structure
        else:
            dt = t - self.T[-2]
            a = self._accel(self.sigma)
            ll = np.array([f.step(z, dt, self.sigma, a) for f in self.filters])
            if self._static is not None and self._rev is not None and self.filters[self._rev].model.radius < self.sigma:
                # a "circle" smaller than the noise is a static point, not evidence of rotation
                ll[self._rev] = min(ll[self._rev], ll[self._static])
            if self._rev is not None and self._pri is not None:
                rev_ok, pri_ok = self._sep
                r, p = ll[self._rev], ll[self._pri]
                if not (rev_ok or pri_ok):
                    # line and arc not yet told apart: both score their mixture (Bayes factor 1)
                    ll[self._rev] = ll[self._pri] = np.logaddexp(r, p) - math.log(2.0)
                elif not rev_ok:
                    ll[self._rev] = min(r, p)
                elif not pri_ok:
                    ll[self._pri] = min(r, p)
            self.logp = self.logp + ll  # Eq. 4.16 in log space
            self.logp -= self.logp.max()
            if self.refit and len(self.X) >= self._next_refit:
                self._fit_all()
        probs = self.probabilities
        p = np.array([probs[n] for n in self.names])
        self.history.append(p)
        if self.first_decision is None and p.max() > self.threshold:
            self.first_decision = (self.names[int(p.argmax())], k)
        return probs

    def result(self, horizon: int = 5) -> OnlineResult:
        n = len(self.X)
        hist = np.array(self.history) if self.history else np.zeros((0, len(self.names)))
        dim = self.dim
        if self.filters is None:
            return OnlineResult(None, {m: 1.0 / len(self.names) for m in self.names}, None, None, hist,
                                self.names, {}, np.zeros((n, 0)), np.zeros((0, dim)), self.sigma, n, dim)
        probs = self.probabilities
        best = int(np.argmax([probs[m] for m in self.names]))
        model = self.names[best] if probs[self.names[best]] > self.threshold else None
        decided_at = None
        if model is not None:
            above = np.nan_to_num(hist[:, best], nan=0.0) > self.threshold
            below = np.flatnonzero(~above)
            decided_at = int(below[-1] + 1) if below.size else 0
        X = np.asarray(self.X)
        T = np.asarray(self.T)
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
        f.start(X[-max(self.min_samples, min(self.window, n)):], np.diff(T[-max(self.min_samples, min(self.window, n)):]),
                self.sigma, self._accel(self.sigma))
        pred = f.predict_ahead(horizon, dt, self._accel(self.sigma))[:, :dim]
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
