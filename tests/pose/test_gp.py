import numpy as np
import pytest

from artmotion.pose.gp import ExactGP, Hyper, SparseGP, choose_inducing, fit_gp, neg_log_marginal_likelihood, optimise_hyper, sqdist


def _closed_form(X, y, Xs, h):
    """Eq. 3.5 written out with explicit inverses."""
    k = lambda A, B: h.sf2 * np.exp(-0.5 * ((A[:, None, :] - B[None, :, :]) ** 2).sum(-1) / h.length**2)
    Kinv = np.linalg.inv(k(X, X) + h.sn2 * np.eye(len(X)))
    Ks = k(Xs, X)
    mean = Ks @ Kinv @ y
    var = np.diag(k(Xs, Xs) - Ks @ Kinv @ Ks.T) + h.sn2
    return mean, var


def test_exact_gp_matches_closed_form():
    rng = np.random.default_rng(1)
    X = rng.uniform(-3, 3, (40, 2))
    y = np.sin(X[:, 0]) + 0.1 * rng.normal(size=40)
    Xs = rng.uniform(-4, 4, (7, 2))
    h = Hyper(length=1.3, sf2=0.8, sn2=0.05)
    gp = ExactGP(X, y[:, None], [h], np.zeros(1), np.ones(1))
    m, s = gp.predict(Xs, return_std=True)
    mc, vc = _closed_form(X, y, Xs, h)
    np.testing.assert_allclose(m[:, 0], mc, atol=1e-5)
    np.testing.assert_allclose(s[:, 0] ** 2, vc, rtol=1e-4, atol=1e-6)


def test_variance_grows_away_from_data():
    X = np.linspace(0, 1, 20)[:, None]
    gp = ExactGP(X, np.sin(X), [Hyper(0.3, 1.0, 0.01)], np.zeros(1), np.ones(1))
    _, s = gp.predict(np.array([[0.5], [3.0]]), return_std=True)
    assert s[0, 0] < 0.2 and s[1, 0] > 0.95  # prior std far away (sqrt(sf2 + sn2))


def test_local_variance_with_all_points_is_exact_and_an_upper_bound_otherwise():
    rng = np.random.default_rng(4)
    X = rng.uniform(-3, 3, (60, 2))
    Y = np.stack([np.sin(X[:, 0]), X[:, 1] ** 2 / 9], 1)
    hs = [Hyper(1.0, 0.8, 0.01), Hyper(0.7, 1.5, 0.05)]
    Xs = rng.uniform(-3.5, 3.5, (25, 2))
    m_ex, s_ex = ExactGP(X, Y, hs, np.zeros(2), np.ones(2)).predict(Xs, True)
    m_all, s_all = ExactGP(X, Y, hs, np.zeros(2), np.ones(2), neighbours=60).predict(Xs, True)
    np.testing.assert_allclose(m_all, m_ex, atol=1e-8)  # the mean is always exact
    np.testing.assert_allclose(s_all, s_ex, rtol=2e-3, atol=1e-4)
    near = ExactGP(X, Y, hs, np.zeros(2), np.ones(2), neighbours=12)
    m_nn, s_nn = near.predict(Xs, True)
    np.testing.assert_allclose(m_nn, m_ex, atol=1e-8)
    assert np.all(s_nn >= s_ex - 1e-6)  # conditioning on fewer points never shrinks the variance
    assert np.median(s_nn / s_ex) < 1.5  # ...and the nearest points carry most of the information
    # a model rebuilt from its alpha (as after loading) predicts the same without the O(n^3) solve
    again = ExactGP(X, Y, hs, np.zeros(2), np.ones(2), neighbours=12, alpha=near.alpha)
    assert again.L == []
    np.testing.assert_allclose(again.predict(Xs, True)[1], s_nn)


def test_sparse_with_all_points_inducing_equals_exact():
    rng = np.random.default_rng(2)
    X = rng.normal(size=(30, 3))
    Y = np.stack([X[:, 0] ** 2, np.cos(X[:, 1])], 1)
    hs = [Hyper(1.5, 1.0, 0.1), Hyper(0.9, 2.0, 0.02)]
    ex = ExactGP(X, Y, hs, np.zeros(2), np.ones(2))
    sp = SparseGP(X, Y, hs, np.zeros(2), np.ones(2), np.arange(30))
    Xs = rng.normal(size=(9, 3))
    (m1, s1), (m2, s2) = ex.predict(Xs, True), sp.predict(Xs, True)
    np.testing.assert_allclose(m1, m2, atol=2e-3)
    np.testing.assert_allclose(s1, s2, atol=2e-3)


def test_variance_from_fewer_inducing_inputs_leaves_the_mean_and_costs_less():
    """``var_inducing``: the same projected-process GP on a subset of the inducing inputs gives
    the variance (an m_v × m_v matrix per output), the mean is the full set's to the last bit;
    ``fit_gp(n_inducing_var=...)`` picks that subset without changing the mean's inducing inputs."""
    rng = np.random.default_rng(4)
    X = rng.normal(size=(300, 3))
    Y = np.stack([np.sin(X[:, 0]), X[:, 1] * X[:, 2]], 1) + 0.05 * rng.normal(size=(300, 2))
    hs = [Hyper(1.2, 1.0, 0.01), Hyper(0.8, 1.5, 0.02)]
    ind = choose_inducing(X, 60, rng)
    full = SparseGP(X, Y, hs, np.zeros(2), np.ones(2), ind)
    sub = SparseGP(X, Y, hs, np.zeros(2), np.ones(2), ind, np.arange(0, 60, 4))
    small = SparseGP(X, Y, hs, np.zeros(2), np.ones(2), ind[::4])  # the subset alone
    Xs = rng.normal(size=(50, 3))
    (m1, s1), (m2, s2), (_, s3) = full.predict(Xs, True), sub.predict(Xs, True), small.predict(Xs, True)
    assert np.array_equal(m1, m2) and sub.M[0].shape == (15, 15)
    np.testing.assert_allclose(s2, s3, rtol=1e-4)      # the subset's own variance
    assert not np.allclose(s1, s2, rtol=1e-3)
    a = fit_gp(X, Y, method="sparse", n_inducing=40, n_opt=100, restarts=1)
    b = fit_gp(X, Y, method="sparse", n_inducing=40, n_opt=100, restarts=1, n_inducing_var=10)
    assert a.var_inducing is None and len(b.var_inducing) == 10 and np.array_equal(a.inducing, b.inducing)
    assert np.array_equal(a.predict(Xs), b.predict(Xs))


def test_nlml_gradient_matches_finite_differences():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(25, 2))
    y = rng.normal(size=25)
    D2 = sqdist(X, X)
    th = np.array([0.2, -0.1, -1.0])
    _, g = neg_log_marginal_likelihood(th, D2, y)
    eps = 1e-5
    for i in range(3):
        e = np.zeros(3)
        e[i] = eps
        fd = (neg_log_marginal_likelihood(th + e, D2, y)[0] - neg_log_marginal_likelihood(th - e, D2, y)[0]) / (2 * eps)
        assert g[i] == pytest.approx(fd, rel=1e-4, abs=1e-6)


def test_hyperparameters_recover_noise_level():
    rng = np.random.default_rng(4)
    X = rng.uniform(0, 10, (300, 1))
    y = np.sin(X[:, 0]) + rng.normal(0, 0.3, 300)
    h = optimise_hyper(sqdist(X, X), y, restarts=2)
    assert 0.05 < h.sn2 < 0.15  # true 0.09
    assert 0.5 < h.length < 3.0


def test_fit_gp_predicts_in_original_units():
    rng = np.random.default_rng(5)
    X = rng.uniform(0, 6, (150, 1))
    Y = np.stack([100 + 20 * np.sin(X[:, 0]), -5 * X[:, 0]], 1) + rng.normal(0, 0.5, (150, 2))
    for method in ("exact", "sparse"):
        gp = fit_gp(X, Y, method=method, n_inducing=60, n_opt=150, restarts=1)
        Xs = np.linspace(0.5, 5.5, 20)[:, None]
        m, s = gp.predict(Xs, return_std=True)
        truth = np.stack([100 + 20 * np.sin(Xs[:, 0]), -5 * Xs[:, 0]], 1)
        assert np.abs(m - truth).max() < 1.5
        assert np.all(s > 0.2) and np.all(s < 2.0)


def test_kmeans_inducing_are_unique_rows_spread_over_clusters():
    rng = np.random.default_rng(5)
    # 90 % of the rows in one tight cluster, 10 % spread over 9 others: Lloyd's iterations start
    # from the random subset and never lose a cluster it covers
    centres = rng.normal(scale=10.0, size=(10, 4))
    lab = np.r_[np.zeros(450, int), np.repeat(np.arange(1, 10), 6)]
    X = centres[lab] + 0.01 * rng.normal(size=(len(lab), 4))
    idx = choose_inducing(X, 10, np.random.default_rng(0), "kmeans")
    assert len(idx) == 10 and len(np.unique(idx)) == 10 and np.all(np.diff(idx) > 0)
    rnd = choose_inducing(X, 10, np.random.default_rng(0), "random")
    assert len(np.unique(rnd)) == 10
    assert set(lab[rnd]) <= set(lab[idx])
    # k-means lowers the quantisation error (mean squared distance to the nearest inducing input)
    x = rng.normal(size=(600, 3)) * np.array([3.0, 1.0, 0.3])
    qerr = lambda i: sqdist(x, x[i]).min(1).mean()
    for seed in range(3):
        assert qerr(choose_inducing(x, 30, np.random.default_rng(seed))) < qerr(choose_inducing(x, 30, np.random.default_rng(seed), "random"))
    np.testing.assert_array_equal(choose_inducing(X[:7], 10, np.random.default_rng(0)), np.arange(7))
    with pytest.raises(ValueError):
        choose_inducing(X, 10, np.random.default_rng(0), "farthest")


def test_fit_gp_inducing_choice_both_work():
    rng = np.random.default_rng(6)
    X = rng.uniform(-2, 2, (200, 2))
    Y = np.sin(X[:, :1]) + 0.05 * rng.normal(size=(200, 1))
    for how in ("kmeans", "random"):
        gp = fit_gp(X, Y, method="sparse", n_inducing=40, n_opt=100, restarts=1, inducing=how)
        assert isinstance(gp, SparseGP) and len(np.unique(gp.inducing)) == 40
        assert np.abs(gp.predict(X) - Y).mean() < 0.15


def test_calibrated_band_holds_its_share_of_new_rows_under_heavy_tailed_errors():
    """``calibrate``: the ±3σ band is widened until it holds 99.73 % of the held-out last rows, as
    a Gaussian's would. With heavy-tailed errors (Student-t, 4 d.o.f.) matching the mean squared
    residual instead left a band that held 98.0-98.9 % of new rows (four seeds; 99.5-99.8 % now);
    with Gaussian errors the band is not widened."""
    rng = np.random.default_rng(0)

    def data(n, noise):
        x = rng.uniform(-3, 3, (n, 1))
        return x, np.sin(2 * x) + 0.05 * noise(n)[:, None]

    for noise, wide in ((lambda n: rng.standard_t(4, n), True), (rng.standard_normal, False)):
        X, Y = data(3000, noise)
        gp = fit_gp(X, Y, method="exact", n_opt=400, calibrate=0.2)
        Xt, Yt = data(20000, noise)
        m, s = gp.predict(Xt, return_std=True)
        inside = float(np.mean(np.abs(Yt - m) <= 3 * s))
        assert inside > 0.993, inside
        assert (gp.var_scale[0] > 1.5) == wide, gp.var_scale


def test_groups_calibrate_on_the_end_of_every_group_and_keep_the_motion_prior_within_groups():
    """``PoseRegressor.fit(groups=...)``: the variance is calibrated on the last 20 % of every
    group. Two pooled recordings, the noisy one first: calibrated on the end of the pooled rows (the
    quiet recording only), the band holds 95.2-97.0 % of new noisy rows (four seeds); calibrated on the
    end of each, 99.3-99.6 %."""
    from artmotion.errors import InputError
    from artmotion.pose.model import PoseRegressor, calibration_order

    rng = np.random.default_rng(1)

    def data(n, noise):
        x = rng.uniform(-3, 3, (n, 1))
        return x, np.sin(2 * x) + noise * rng.standard_normal((n, 1))

    (Xb, Yb), (Xa, Ya) = data(2500, 0.2), data(2500, 0.02)
    X, Y = np.vstack([Xb, Xa]), np.vstack([Yb, Ya])
    groups = np.repeat(["noisy", "quiet"], 2500)
    Xt, Yt = data(20000, 0.2)
    inside = {}
    for g in (None, groups):
        reg = PoseRegressor(method="exact", n_opt=400).fit(X, Y, ["a"], groups=g)
        m, s = reg.predict(Xt, return_std=True)
        inside[g is None] = float(np.mean(np.abs(Yt - m) <= 3 * s))
    assert inside[False] > 0.985 and inside[True] < 0.98, inside

    order, n_cal, frames = calibration_order(10, [5] * 5 + [2] * 5)
    assert n_cal == 2 and list(order) == [0, 1, 2, 3, 5, 6, 7, 8, 4, 9]
    assert list(np.diff(frames)) == [1, 1, 1, 1, 3, 1, 1, 1, 1]  # no second difference across the seam
    with pytest.raises(InputError, match="10 training rows but 3 groups"):
        calibration_order(10, [0, 0, 1])
