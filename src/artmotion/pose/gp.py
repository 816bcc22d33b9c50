"""Gaussian-process regression (Eq. 3.1-3.5), exact and sparse, one GP per output.

Each output ``y_k`` (standardised to zero mean / unit variance; the constant mean function of
Fig. 3.2d) gets its own squared-exponential kernel ``k(x, x') = s_f^2 exp(-|x - x'|^2 / (2 l^2))``
plus Gaussian noise ``s_n^2`` (Eq. 3.3). Hyper-parameters ``(l, s_f, s_n)`` maximise the log
marginal likelihood (L-BFGS with analytic gradients, a few restarts) on a random subset of the
training set; the full training set is then solved once with those values.

* :class:`ExactGP` caches ``alpha = K^-1 y`` (and the Cholesky factor ``L`` of ``K + s_n^2 I``
  when the variance is exact): a prediction costs ``O(n d)`` for the kernel row, ``O(n)`` for the
  mean and ``O(n^2)`` for the exact variance, or ``O(r^3)`` for the local variance from the ``r``
  nearest training inputs.
* :class:`SparseGP` is the deterministic-training-conditional (projected-process / Nyström)
  approximation with ``m`` inducing inputs (chosen among the training inputs): training
  ``O(n m^2)``, prediction ``O(m d)`` + ``O(m)`` mean + ``O(m^2)`` variance.

Both return the predictive mean and the variance of a new *observation* ``y* = f(x*) + e``
(latent variance + ``s_n^2``), in the original units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_triangular
from scipy.optimize import minimize

_JITTER = 1e-8


def sqdist(A: np.ndarray, B: np.ndarray, A2: np.ndarray | None = None, B2: np.ndarray | None = None) -> np.ndarray:
    """Squared Euclidean distances between the rows of ``A`` and ``B`` (clipped at 0)."""
    A2 = (A * A).sum(1) if A2 is None else A2
    B2 = (B * B).sum(1) if B2 is None else B2
    D = A @ B.T
    D *= -2.0
    D += A2[:, None]
    D += B2[None, :]
    np.maximum(D, 0.0, out=D)
    return D


def se_kernel(D2: np.ndarray, length: float, sf2: float) -> np.ndarray:
    return sf2 * np.exp(D2 * (-0.5 / (length * length)))


@dataclass
class Hyper:
    length: float
    sf2: float
    sn2: float

    def as_array(self) -> np.ndarray:
        return np.array([self.length, self.sf2, self.sn2])


def neg_log_marginal_likelihood(theta: np.ndarray, D2: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
    """``-log p(y | X, theta)`` and its gradient; ``theta = [log l, log s_f, log s_n]``."""
    log_l, log_sf, log_sn = theta
    l2, sf2, sn2 = math.exp(2 * log_l), math.exp(2 * log_sf), math.exp(2 * log_sn)
    n = len(y)
    Kf = sf2 * np.exp(D2 * (-0.5 / l2))
    K = Kf.copy()
    K[np.diag_indices(n)] += sn2 + _JITTER
    try:
        c = cho_factor(K, lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        return 1e25, np.zeros(3)
    alpha = cho_solve(c, y, check_finite=False)
    nll = 0.5 * float(y @ alpha) + float(np.log(np.diag(c[0])).sum()) + 0.5 * n * math.log(2 * math.pi)
    Kinv = cho_solve(c, np.eye(n), check_finite=False)
    W = np.outer(alpha, alpha) - Kinv  # dNLL/dtheta = -1/2 tr(W dK/dtheta)
    g_l = -0.5 * float((W * (Kf * (D2 / l2))).sum())
    g_sf = -0.5 * float((W * (2.0 * Kf)).sum())
    g_sn = -0.5 * float(np.trace(W) * 2.0 * sn2)
    return nll, np.array([g_l, g_sf, g_sn])


def optimise_hyper(D2: np.ndarray, y: np.ndarray, restarts: int = 3, seed: int = 0) -> Hyper:
    """Maximise the log marginal likelihood of standardised ``y`` given squared distances ``D2``."""
    med = float(np.sqrt(np.median(D2[np.triu_indices(len(y), 1)]))) or 1.0
    rng = np.random.default_rng(seed)
    starts = [np.array([math.log(med), 0.0, math.log(0.1)])]
    for _ in range(max(0, restarts - 1)):
        starts.append(np.array([math.log(med) + rng.uniform(-1.0, 1.0), rng.uniform(-0.5, 0.5), rng.uniform(-4.0, -1.0)]))
    bounds = [(math.log(med) - 4.0, math.log(med) + 3.0), (math.log(1e-2), math.log(1e2)), (math.log(1e-3), math.log(3.0))]
    best = None
    for s in starts:
        res = minimize(neg_log_marginal_likelihood, s, args=(D2, y), jac=True, method="L-BFGS-B", bounds=bounds,
                       options={"maxiter": 100})
        if best is None or res.fun < best.fun:
            best = res
    assert best is not None  # ``starts`` is never empty
    ll, lsf, lsn = best.x
    return Hyper(math.exp(ll), math.exp(2 * lsf), math.exp(2 * lsn))


class _BaseGP:
    """Shared bookkeeping: output standardisation and hyper-parameters per output."""

    kind = "base"

    def __init__(self, hypers: list[Hyper], y_mean: np.ndarray, y_std: np.ndarray):
        self.hypers = hypers
        self.y_mean = np.asarray(y_mean, dtype=float)
        self.y_std = np.asarray(y_std, dtype=float)
        self.var_scale = np.ones(len(hypers))
        #: :func:`fit_gp`'s prediction (mean, std; calibrated, in the outputs' units) of the rows it
        #: held out to calibrate the variance, by the GP solved without them (its hyper-parameters,
        #: though, were chosen on a subsample of all rows, these included); not saved
        self.held_out: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def n_outputs(self) -> int:
        return len(self.hypers)

    def _finish(self, mu: np.ndarray, var: np.ndarray, return_std: bool):
        mean = mu * self.y_std + self.y_mean
        if not return_std:
            return mean
        return mean, np.sqrt(np.maximum(var, 1e-12) * self.var_scale) * self.y_std


class ExactGP(_BaseGP):
    """Exact GP with cached ``alpha = K^-1 y`` per output (the thesis' method).

    The mean costs ``O(n d)`` per frame (the kernel row) + ``O(n)``. The variance is either exact
    (``neighbours=None``: the cached Cholesky factor ``L``, ``O(n^2)`` per frame and output) or the
    *local* variance of the same GP conditioned only on the ``neighbours`` training inputs nearest
    to the query (a nearest-neighbour GP, as in Vecchia's approximation): ``O(r^3)`` per frame,
    independent of ``n``. Conditioning on a subset never lowers the variance, so the local one is an
    upper bound of the exact variance; with a squared-exponential kernel the far points carry
    almost no information about ``f(x*)`` and the two are close. ``alpha`` may be given (a loaded
    model) to skip the ``O(n^3)`` solve when ``L`` is not needed.
    """

    kind = "exact"

    def __init__(self, X: np.ndarray, Ys: np.ndarray, hypers, y_mean, y_std, neighbours: int | None = None,
                 alpha: np.ndarray | None = None):
        super().__init__(hypers, y_mean, y_std)
        self.X = np.ascontiguousarray(X, dtype=np.float64)
        self.Ys = np.asarray(Ys, dtype=np.float64)
        self.neighbours = None if neighbours is None else max(1, min(int(neighbours), len(self.X)))
        self.X2 = (self.X * self.X).sum(1)
        self._X32 = self.X.astype(np.float32)
        self._X2_32 = self.X2.astype(np.float32)
        self.L = []
        if alpha is not None and self.neighbours is not None:
            self.alpha = np.asarray(alpha, dtype=np.float64).reshape(len(self.X), len(hypers))
            return
        D2 = sqdist(self.X, self.X, self.X2, self.X2)
        n = len(self.X)
        alphas = []
        for k, h in enumerate(hypers):
            K = se_kernel(D2, h.length, h.sf2)
            K[np.diag_indices(n)] += h.sn2 + _JITTER
            L = np.linalg.cholesky(K)
            del K
            alphas.append(cho_solve((L, True), self.Ys[:, k], check_finite=False))
            if self.neighbours is None:
                self.L.append(L)
        self.alpha = np.stack(alphas, axis=1)

    def predict(self, X: np.ndarray, return_std: bool = False):
        X = np.atleast_2d(np.asarray(X))
        # the kernel row is the cost: float32 (changes the mean by < 0.01° on the pose data)
        D2 = sqdist(np.asarray(X, dtype=np.float32), self._X32, None, self._X2_32)
        mu = np.empty((len(X), self.n_outputs))
        var = np.empty_like(mu)
        for k, h in enumerate(self.hypers):
            Ks = se_kernel(D2, h.length, h.sf2)  # stays float32 (Python scalars are weakly typed)
            mu[:, k] = Ks @ self.alpha[:, k]
            if return_std and self.neighbours is None:
                V = solve_triangular(self.L[k], Ks.T.astype(np.float64), lower=True, check_finite=False)
                var[:, k] = h.sf2 - (V * V).sum(0) + h.sn2
        if return_std and self.neighbours is not None:
            var = self._local_variance(D2)
        return self._finish(mu, var, return_std)

    def _local_variance(self, D2: np.ndarray) -> np.ndarray:
        """Predictive variance given only the ``neighbours`` nearest training inputs of each row."""
        r = self.neighbours
        assert r is not None  # only called with local variance
        nn = np.argpartition(D2, r - 1, axis=1)[:, :r] if r < D2.shape[1] else np.broadcast_to(
            np.arange(D2.shape[1]), D2.shape)
        Xn = self.X[nn]  # (B, r, d)
        sq = self.X2[nn]
        Dnn = sq[:, :, None] + sq[:, None, :] - 2.0 * (Xn @ Xn.transpose(0, 2, 1))
        np.maximum(Dnn, 0.0, out=Dnn)
        ds = np.take_along_axis(D2, nn, axis=1).astype(np.float64)
        # all outputs in one batched solve: (outputs, B, r, r)
        c = np.array([-0.5 / (h.length * h.length) for h in self.hypers])[:, None, None]
        sf2 = np.array([h.sf2 for h in self.hypers])
        sn2 = np.array([h.sn2 for h in self.hypers])
        K = np.exp(Dnn[None] * c[..., None]) * sf2[:, None, None, None]
        K += ((sn2 + 1e-6 * sf2)[:, None, None, None]) * np.eye(r)  # near-duplicate frames
        ks = np.exp(ds[None] * c) * sf2[:, None, None]
        sol = np.linalg.solve(K, ks[..., None])[..., 0]
        return (sf2[:, None] - (ks * sol).sum(-1) + sn2[:, None]).T


class SparseGP(_BaseGP):
    """Deterministic training conditional (projected process) GP with ``m`` inducing inputs.

    With ``Kmm = L_m L_m^T``, ``V = L_m^-1 Kmn`` and ``A = s_n^2 I + V V^T``:
    mean ``= k*^T c`` with ``c = L_m^-T A^-1 V y``; latent variance
    ``= s_f^2 - |L_m^-1 k*|^2 + s_n^2 |A^-1/2 L_m^-1 k*|^2 = s_f^2 + k*^T M k*``.

    ``var_inducing``: positions in ``inducing`` of a smaller set for the variance (the same model
    with those inducing inputs only: ``M`` is ``m_v × m_v``, a query's variance costs ``m_v²``
    instead of ``m²``); the mean is unchanged. Its variance is another approximation of the same
    GP's (mostly wider: fewer inducing inputs explain less of a query; in places narrower), and the
    calibration (:func:`fit_gp`) scales it to the errors on held-out rows like the full one.
    """

    kind = "sparse"

    def __init__(self, X: np.ndarray, Ys: np.ndarray, hypers, y_mean, y_std, inducing: np.ndarray,
                 var_inducing: np.ndarray | None = None):
        super().__init__(hypers, y_mean, y_std)
        X = np.asarray(X, dtype=np.float64)
        self.X = X.astype(np.float32)
        self.Ys = np.asarray(Ys, dtype=np.float64)
        self.inducing = np.asarray(inducing, dtype=np.int64)
        #: positions (in ``inducing``) of the smaller set the variance is computed from, or None:
        #: the same set as the mean's (the variance costs O(m²) per query and output, the mean O(m))
        self.var_inducing = None if var_inducing is None else np.asarray(var_inducing, dtype=np.int64)
        self.Z = np.ascontiguousarray(X[self.inducing])
        self.Z2 = (self.Z * self.Z).sum(1)
        self._Z32 = self.Z.astype(np.float32)
        self._Z2_32 = self.Z2.astype(np.float32)
        Dmm = sqdist(self.Z, self.Z, self.Z2, self.Z2)
        Dmn = sqdist(self.Z, X, self.Z2)
        v = self.var_inducing
        cs: list[np.ndarray] = []
        self.M: list[np.ndarray] = []
        for k, h in enumerate(hypers):
            V, La, Pinv = _dtc(Dmm, Dmn, h)
            beta = cho_solve((La, True), V @ Ys[:, k], check_finite=False)
            cs.append(Pinv.T @ beta)
            if v is not None:  # the same model on the smaller set, for the variance only
                _, La, Pinv = _dtc(Dmm[np.ix_(v, v)], Dmn[v], h)
            G = solve_triangular(La, Pinv, lower=True, check_finite=False)  # A^-1/2 L_m^-1
            self.M.append((h.sn2 * (G.T @ G) - Pinv.T @ Pinv).astype(np.float32))
        self.c = np.stack(cs, axis=1)

    def predict(self, X: np.ndarray, return_std: bool = False):
        X = np.atleast_2d(np.asarray(X))
        D2 = sqdist(np.asarray(X, dtype=np.float32), self._Z32, None, self._Z2_32)
        mu = np.empty((len(X), self.n_outputs))
        var = np.empty_like(mu)
        for k, h in enumerate(self.hypers):
            Ks = se_kernel(D2, h.length, h.sf2)  # float32
            mu[:, k] = Ks @ self.c[:, k]
            if return_std:
                Kv = Ks if self.var_inducing is None else Ks[:, self.var_inducing]
                q = ((Kv @ self.M[k]) * Kv).sum(1, dtype=np.float64)
                var[:, k] = np.maximum(h.sf2 + q, 1e-6 * h.sf2) + h.sn2
        return self._finish(mu, var, return_std)


def _dtc(Dmm: np.ndarray, Dmn: np.ndarray, h) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The factors of a projected-process GP with hyper-parameters ``h`` from the squared distances
    among the inducing inputs and to the training inputs: ``V = L_m^-1 Kmn``, the Cholesky factor
    of ``A = s_n^2 I + V V^T`` and ``L_m^-1`` (see :class:`SparseGP`)."""
    m = len(Dmm)
    Kmm = se_kernel(Dmm, h.length, h.sf2)
    Kmm[np.diag_indices(m)] += 1e-6 * h.sf2
    Lm = np.linalg.cholesky(Kmm)
    V = solve_triangular(Lm, se_kernel(Dmn, h.length, h.sf2), lower=True, check_finite=False)
    A = V @ V.T
    A[np.diag_indices(m)] += h.sn2
    La = np.linalg.cholesky(A)
    Pinv = solve_triangular(Lm, np.eye(m), lower=True, check_finite=False)  # L_m^-1
    return V, La, Pinv


def choose_inducing(X: np.ndarray, m: int, rng: np.random.Generator, how: str = "kmeans",
                    iters: int = 8) -> np.ndarray:
    """Indices of ``m`` inducing inputs among the rows of ``X`` (sorted, unique).

    ``how="random"``: a uniform random subset. ``"kmeans"``: a few Lloyd iterations of k-means
    started from a random subset, then the training row nearest to each centre (so the inducing
    inputs stay training rows and a model file only stores their indices); centres that share a
    nearest row are topped up at random. k-means spreads the inducing inputs over the input
    distribution instead of spending them where consecutive frames pile up.
    """
    n = len(X)
    if m >= n:
        return np.arange(n)
    start = np.sort(rng.choice(n, size=m, replace=False))
    if how == "random":
        return start
    if how != "kmeans":
        raise ValueError(f"unknown inducing-point selection {how!r}")
    X32 = np.ascontiguousarray(X, dtype=np.float32)
    X2 = (X32 * X32).sum(1)
    C = X32[start].copy()
    for _ in range(iters):
        assign = sqdist(X32, C, X2).argmin(1)
        counts = np.bincount(assign, minlength=m).astype(np.float32)
        onehot = np.zeros((n, m), dtype=np.float32)
        onehot[np.arange(n), assign] = 1.0
        sums = onehot.T @ X32
        keep = counts > 0
        C[keep] = sums[keep] / counts[keep, None]
    idx = np.unique(sqdist(C, X32, None, X2).argmin(1))
    if len(idx) < m:
        rest = np.setdiff1d(np.arange(n), idx)
        idx = np.concatenate([idx, rng.choice(rest, size=m - len(idx), replace=False)])
    return np.sort(idx)


def standardise(Y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    mean = Y.mean(0)
    std = Y.std(0)
    std = np.where(std > 1e-12, std, 1.0)
    return (Y - mean) / std, mean, std


#: the share of held-out rows a calibrated ±3σ band holds (a Gaussian's)
BAND_LEVEL = 0.9973


def fit_gp(
    X: np.ndarray,
    Y: np.ndarray,
    method: str = "auto",
    max_exact: int = 2000,
    n_inducing: int = 600,
    n_opt: int = 800,
    restarts: int = 2,
    seed: int = 0,
    hypers: list[Hyper] | None = None,
    progress: bool = False,
    calibrate: float = 0.2,
    inducing: str = "kmeans",
    neighbours: int | None = None,
    n_inducing_var: int | None = None,
):
    """Fit one GP per column of ``Y``: hyper-parameters on a subset of ``n_opt``, then one full solve.

    ``method="auto"`` uses :class:`ExactGP` up to ``max_exact`` training points and
    :class:`SparseGP` with ``n_inducing`` inducing inputs beyond.

    ``calibrate`` (fraction, 0 = off): the same GP is solved on the first ``1 - calibrate`` of the
    rows (in the given order, i.e. time order for a sequence) and predicts the last block; the
    predictive variance of each output is then scaled so that its ±3σ band holds as many of those
    held-out rows as a Gaussian ±3σ band would (99.73 %: a split-conformal calibration,
    ``(q(|z|) / 3)²`` with ``z`` the standardised residuals; never below 1). Neighbouring frames
    make the marginal-likelihood noise estimate optimistic for new stretches of motion, and the
    residuals are heavy-tailed: matching the mean squared residual instead left the band too narrow
    (docs/pose.md).

    ``inducing``: how the sparse GP picks its inducing inputs, ``"kmeans"`` (default) or
    ``"random"`` (see :func:`choose_inducing`). ``neighbours``: the exact GP's variance from that
    many nearest training inputs (None: the exact ``O(n^2)`` variance; see :class:`ExactGP`).
    ``n_inducing_var``: the sparse GP's variance from that many of its inducing inputs (chosen
    among them the same way; None: all of them; see :class:`SparseGP`).
    """
    X = np.asarray(X, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64).reshape(len(X), -1)
    n = len(X)
    if method == "auto":
        method = "exact" if n <= max_exact else "sparse"
    if method not in ("exact", "sparse"):
        raise ValueError(f"unknown GP method {method!r}")
    Ys, y_mean, y_std = standardise(Y)
    rng = np.random.default_rng(seed)
    if hypers is None:
        sub = np.sort(rng.choice(n, size=min(n, n_opt), replace=False))
        D2 = sqdist(X[sub], X[sub])
        hypers = []
        it = range(Y.shape[1])
        if progress:
            from tqdm import tqdm

            it = tqdm(it, desc="GP hyper-parameters", unit="output", leave=False, disable=None)
        for k in it:
            hypers.append(optimise_hyper(D2, Ys[sub, k], restarts=restarts, seed=seed + k))
    def build(Xb, Yb):
        if method == "exact":
            return ExactGP(Xb, Yb, hypers, np.zeros(Yb.shape[1]), np.ones(Yb.shape[1]), neighbours)
        ind = choose_inducing(Xb, n_inducing, rng, inducing)
        var = None
        if n_inducing_var is not None and n_inducing_var < len(ind):
            # its own generator: the mean's inducing inputs stay those chosen without it
            var = choose_inducing(Xb[ind], n_inducing_var, np.random.default_rng([seed, 1]), inducing)
        return SparseGP(Xb, Yb, hypers, np.zeros(Yb.shape[1]), np.ones(Yb.shape[1]), ind, var)

    scale = np.ones(Y.shape[1])
    n_cal = int(round(n * (1 - calibrate))) if calibrate else n
    held_out = None
    if 10 <= n_cal <= n - 10:
        m, s = build(X[:n_cal], Ys[:n_cal]).predict(X[n_cal:], return_std=True)
        z = np.abs(Ys[n_cal:] - m) / s
        scale = np.maximum(1.0, (np.quantile(z, BAND_LEVEL, axis=0) / 3.0) ** 2)
        held_out = (m * y_std + y_mean, s * np.sqrt(scale) * y_std)
    gp = build(X, Ys)
    gp.y_mean, gp.y_std, gp.var_scale, gp.held_out = y_mean, y_std, scale, held_out
    return gp
