"""Temporal structure of motion variables (Section 4.4) and the configuration experiments of 4.8.1-4.8.2.

* :func:`filter_order` runs a Kalman filter with a Taylor model of order ``n`` (Eq. 4.12-4.14,
  :func:`artmotion.filters.taylor_model`) on a directly observed motion variable.
* :func:`compare_orders` does so for several orders, each with its process noise chosen by the
  innovation likelihood (a grid over decades), as Fig. 4.5 does for a pendulum's angle.
* :func:`configuration_monte_carlo` reproduces Table 4.1: a point on a circle about (2, 2) with
  radius 1 and noise variance 0.01 per axis, the circle estimated jointly with the motion
  (Eq. 4.29, non-linear in ``theta_0`` and ``omega``) or separately (a circle fit).
"""

from __future__ import annotations

import math

import numpy as np

from artmotion.articulation.models import fit_circle_2d, fit_circle_joint
from artmotion.filters import KalmanFilter, taylor_model

__all__ = ["filter_order", "compare_orders", "pendulum", "configuration_monte_carlo", "plot_orders"]


def filter_order(q, t, order: int, process_var: float, obs_var: float, horizon: int = 0) -> dict:
    """Kalman filter of a scalar motion variable with an order-``order`` Taylor model.

    Returns ``filtered`` (n,), ``predicted`` (one step ahead, before each update; NaN at 0),
    ``loglik`` (sum of innovation log-likelihoods from the ``order``-th sample on) and, if
    ``horizon > 0``, ``ahead`` (n,): the ``horizon``-step prediction made ``horizon`` samples earlier.
    """
    q = np.asarray(q, dtype=float)
    t = np.asarray(t, dtype=float)
    n = len(q)
    x0 = np.zeros(order)
    x0[0] = q[0]
    P0 = np.eye(order) * (10.0 * (np.ptp(q) + math.sqrt(obs_var))) ** 2
    H = np.zeros((1, order))
    H[0, 0] = 1.0
    kf = KalmanFilter(x0, P0, np.eye(order), np.zeros((order, order)), H, [[obs_var]])
    filtered = np.empty(n)
    predicted = np.full(n, np.nan)
    ahead = np.full(n, np.nan)
    filtered[0] = q[0]
    ll = 0.0
    cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    def model(dt):
        FQ = cache.get(dt)
        if FQ is None:
            FQ = cache[dt] = taylor_model(order, dt, process_var)
        return FQ

    for k in range(1, n):
        kf.predict(*model(t[k] - t[k - 1]))
        predicted[k] = kf.x[0]
        lk = kf.update([q[k]])
        if k >= order:
            ll += lk
        filtered[k] = kf.x[0]
        if horizon and k + horizon < n:
            x = kf.x.copy()
            for j in range(horizon):
                x = model(t[k + j + 1] - t[k + j])[0] @ x
            ahead[k + horizon] = x[0]
    return {"filtered": filtered, "predicted": predicted, "loglik": ll, "ahead": ahead}


def compare_orders(q, t, orders=(1, 2, 3), obs_var: float = 1e-4, truth=None, horizon: int = 10) -> dict:
    """Fit each Taylor order to the observed motion variable ``q``; process noise by likelihood.

    Returns ``{order: {process_var, loglik, rmse_filtered, rmse_predicted, rmse_ahead, filtered}}``
    where errors are against ``truth`` if given (else against ``q``).
    """
    q = np.asarray(q, dtype=float)
    ref = q if truth is None else np.asarray(truth, dtype=float)
    out = {}
    for n in orders:
        best = None
        for pv in 10.0 ** np.arange(-10.0, 6.5, 0.5):
            r = filter_order(q, t, n, pv, obs_var)
            if best is None or r["loglik"] > best[1]["loglik"]:
                best = (pv, r)
        assert best is not None  # the first process variance always sets it
        pv, _ = best
        r = filter_order(q, t, n, pv, obs_var, horizon=horizon)
        ok = ~np.isnan(r["predicted"])
        ok_a = ~np.isnan(r["ahead"])
        out[n] = {
            "process_var": float(pv),
            "loglik": float(r["loglik"]),
            "rmse_filtered": float(np.sqrt(np.mean((r["filtered"] - ref) ** 2))),
            "rmse_predicted": float(np.sqrt(np.mean((r["predicted"][ok] - ref[ok]) ** 2))),
            "rmse_ahead": float(np.sqrt(np.mean((r["ahead"][ok_a] - ref[ok_a]) ** 2))) if ok_a.any() else float("nan"),
            "filtered": r["filtered"],
            "ahead": r["ahead"],
        }
    return out


def pendulum(duration: float = 10.0, dt: float = 0.02, length: float = 1.0, theta0: float = 1.0,
             damping: float = 0.1, noise_std: float = 0.01, seed: int = 0):
    """Angle of a damped pendulum ``theta'' = -g/L sin(theta) - c theta'`` and noisy readings."""
    from scipy.integrate import solve_ivp

    t = np.arange(0.0, duration, dt)
    sol = solve_ivp(lambda _, y: [y[1], -9.81 / length * math.sin(y[0]) - damping * y[1]],
                    (0.0, t[-1]), [theta0, 0.0], t_eval=t, rtol=1e-9, atol=1e-9)
    truth = sol.y[0]
    rng = np.random.default_rng(seed)
    return t, truth + rng.normal(0.0, noise_std, len(t)), truth


def configuration_monte_carlo(runs: int = 500, n: int = 20, centre=(2.0, 2.0), radius: float = 1.0,
                              noise_var: float = 0.01, omega: float = 0.1, alpha: float = 0.0,
                              seed: int = 0) -> dict:
    """Table 4.1: mean centre and radius errors of the joint (Eq. 4.29) and separate estimates.

    Each run draws a start angle uniformly and ``n`` samples ``theta_k = theta_0 + omega k +
    alpha k^2 / 2`` (``alpha = 0``: the constant velocity the joint model assumes). The joint fit
    starts, as it must without knowing the answer, from the centroid, the mean distance to it and
    the angles seen from it.
    """
    rng = np.random.default_rng(seed)
    c = np.asarray(centre, dtype=float)
    sd = math.sqrt(noise_var)
    errs: dict[str, list[list[float | np.floating]]] = {"joint": [[], []], "separate": [[], []]}
    tk = np.arange(n, dtype=float)
    for _ in range(runs):
        th0 = rng.uniform(-math.pi, math.pi)
        th = th0 + omega * tk + 0.5 * alpha * tk**2
        P = c + radius * np.column_stack([np.cos(th), np.sin(th)]) + rng.normal(0.0, sd, (n, 2))
        cj, rj, _, _ = fit_circle_joint(tk, P)
        cs, rs = fit_circle_2d(P)
        errs["joint"][0].append(np.linalg.norm(cj - c))
        errs["joint"][1].append(abs(rj - radius))
        errs["separate"][0].append(np.linalg.norm(cs - c))
        errs["separate"][1].append(abs(rs - radius))
    out = {}
    for k, (ce_list, re_list) in errs.items():
        ce, re = np.array(ce_list), np.array(re_list)
        out[k] = {"centre_error": float(np.mean(ce)), "radius_error": float(np.mean(re)),
                  "centre_error_median": float(np.median(ce)), "radius_error_median": float(np.median(re))}
    return out


def plot_orders(t, q, truth, results: dict, path) -> None:
    """Fig. 4.5: the filtered angle of every order against the readings (PNG, written atomically)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from artmotion.io import save_figure

    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    axes[0].plot(t, q, ".", ms=2, color="0.6", label="readings")
    axes[0].plot(t, truth, "k-", lw=1, label="true angle")
    for n, r in results.items():
        axes[0].plot(t, r["filtered"], lw=1, label=f"order {n} (state {n})")
        axes[1].plot(t, r["ahead"] - truth, lw=1, label=f"order {n}: rmse {r['rmse_ahead']:.3f}")
    axes[0].set_ylabel("angle (rad)")
    axes[0].legend(fontsize=7)
    axes[1].set_ylabel("10-step prediction error (rad)")
    axes[1].set_xlabel("time (s)")
    axes[1].legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=90)
