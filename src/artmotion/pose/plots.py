"""Figures of chapter 3 on rendered data: regression comparison (Fig. 3.2), 3σ band (Fig. 3.4),
filtered vs raw (Fig. 3.6). Matplotlib with the Agg backend; files written atomically."""

from __future__ import annotations

import numpy as np

from artmotion.io import save_figure


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def regression_comparison(path, seed: int = 0) -> dict:
    """Sec. 3.3.2: y = x + 0.005 x² + ε, ε ~ N(0, 10), x ∈ {1..10} ∪ {21..25}; 4 regressors with ±2σ bands.

    Returns the fitted parameters (for the docs).
    """
    from scipy import stats

    from artmotion.pose.gp import fit_gp

    rng = np.random.default_rng(seed)
    x = np.r_[np.arange(1, 11), np.arange(21, 26)].astype(float)
    y = x + 0.005 * x**2 + rng.normal(0, np.sqrt(10.0), len(x))
    xs = np.linspace(-5, 32, 300)
    out, bands = {}, []
    for deg, name in ((1, "linear"), (2, "quadratic")):
        A = np.vander(x, deg + 1)
        coef, res, *_ = np.linalg.lstsq(A, y, rcond=None)
        dof = len(x) - deg - 1
        s2 = float(((y - A @ coef) ** 2).sum() / dof)
        As = np.vander(xs, deg + 1)
        cov = s2 * np.linalg.inv(A.T @ A)
        sd = np.sqrt(s2 + np.einsum("ij,jk,ik->i", As, cov, As))  # prediction interval
        t = stats.t.ppf(0.975, dof)
        bands.append((name, As @ coef, t * sd))
        out[name] = coef.tolist()
    # Bayesian linear regression: prior N(0, 5 I) on (slope, intercept), noise variance 10
    A = np.vander(x, 2)
    S = np.linalg.inv(np.eye(2) / 5.0 + A.T @ A / 10.0)
    w = S @ A.T @ y / 10.0
    As = np.vander(xs, 2)
    sd = np.sqrt(10.0 + np.einsum("ij,jk,ik->i", As, S, As))
    bands.append(("Bayesian linear", As @ w, 2 * sd))
    out["bayesian"] = w.tolist()
    gp = fit_gp(x[:, None], y, method="exact", n_opt=len(x), restarts=3, calibrate=0)
    m, s = gp.predict(xs[:, None], return_std=True)
    bands.append(("GP (SE kernel)", m[:, 0], 2 * s[:, 0]))
    h = gp.hypers[0]
    out["gp"] = {"length": h.length, "sf": float(np.sqrt(h.sf2) * gp.y_std[0]), "sn": float(np.sqrt(h.sn2) * gp.y_std[0])}
    plt = _plt()
    fig, axes = plt.subplots(1, 4, figsize=(16, 3.8), sharey=True)
    for ax, (name, mu, half), tag in zip(axes, bands, "abcd"):
        ax.fill_between(xs, mu - half, mu + half, color="C0", alpha=0.25, label="±2σ (95 %)")
        ax.plot(xs, mu, "C0", label="mean")
        ax.plot(xs, xs + 0.005 * xs**2, "k--", lw=1, label="true f")
        ax.plot(x, y, "ro", ms=4, label="data")
        ax.set_title(f"({tag}) {name}")
        ax.set_xlabel("x")
    axes[0].set_ylabel("y")
    axes[0].legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=90)
    return out


def band_plot(path, truth, mean, std, name="opening", start=0, length=300):
    """Fig. 3.4: GP mean with its ±3σ band and the true angle over a stretch of frames."""
    plt = _plt()
    t = np.arange(start, min(len(truth), start + length))
    fig, ax = plt.subplots(figsize=(10, 3.5))
    ax.fill_between(t, mean[t] - 3 * std[t], mean[t] + 3 * std[t], color="C0", alpha=0.25, label="GP ±3σ")
    ax.plot(t, mean[t], "C0", lw=1, label="GP mean")
    ax.plot(t, truth[t], "k", lw=1.2, label="true")
    inside = np.mean(np.abs(truth - mean) <= 3 * std)
    ax.set_title(f"{name}: truth inside ±3σ for {100 * inside:.1f} % of all frames")
    ax.set_xlabel("frame")
    ax.set_ylabel(f"{name} (deg)")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=90)


def filter_plot(path, truth, raw, filtered, name="opening", start=0, length=300):
    """Fig. 3.6: true, GP-mean and Kalman-filtered angle."""
    plt = _plt()
    t = np.arange(start, min(len(truth), start + length))
    fig, ax = plt.subplots(figsize=(10, 3.5))
    ax.plot(t, truth[t], "k", lw=1.5, label="true")
    ax.plot(t, raw[t], "C1", lw=0.8, alpha=0.8, label=f"GP mean (MAE {np.abs(raw - truth).mean():.2f}°)")
    ax.plot(t, filtered[t], "C0", lw=1.2, label=f"Kalman filtered (MAE {np.abs(filtered - truth).mean():.2f}°)")
    ax.set_xlabel("frame")
    ax.set_ylabel(f"{name} (deg)")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=90)
