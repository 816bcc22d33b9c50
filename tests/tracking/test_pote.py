"""Product of Tracking Experts fusion (thesis Eq. 2.1-2.3, Fig. 2.2) and the expert registry."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from artmotion.tracking import Expert, Gaussian, PoTE, fuse, register_expert
from artmotion.tracking.experts import EXPERTS, Entity, Frame


def test_figure_2_2():
    cov = np.diag([16.66, 25.0])
    g = fuse([Gaussian([245, 270], cov), Gaussian([255, 275], cov)])
    np.testing.assert_allclose(g.mean, [250, 272.5])
    np.testing.assert_allclose(g.cov, np.diag([8.33, 12.5]))


def test_none_means_no_opinion():
    a = Gaussian([1, 2], np.eye(2))
    g = fuse([None, a, None])
    np.testing.assert_allclose(g.mean, a.mean)
    np.testing.assert_allclose(g.cov, a.cov)
    assert fuse([None, None]) is None
    assert fuse([]) is None


def test_confident_expert_dominates():
    g = fuse([Gaussian([0, 0], np.eye(2) * 100), Gaussian([10, 10], np.eye(2) * 0.01)])
    np.testing.assert_allclose(g.mean, [10, 10], atol=0.01)


def test_full_covariances_eq_2_3():
    A = np.array([[4.0, 1.0], [1.0, 3.0]])
    B = np.array([[2.0, -0.5], [-0.5, 1.0]])
    ma, mb = np.array([1.0, 2.0]), np.array([-1.0, 0.5])
    g = fuse([Gaussian(ma, A), Gaussian(mb, B)])
    S = np.linalg.inv(np.linalg.inv(A) + np.linalg.inv(B))
    np.testing.assert_allclose(g.cov, S)
    np.testing.assert_allclose(g.mean, S @ (np.linalg.solve(A, ma) + np.linalg.solve(B, mb)))


finite = st.floats(-500, 500, allow_nan=False)
var = st.floats(0.1, 100, allow_nan=False)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(finite, finite, var, var), min_size=1, max_size=5))
def test_product_is_order_free_and_tighter(experts):
    gs = [Gaussian([x, y], np.diag([vx, vy])) for x, y, vx, vy in experts]
    a, b = fuse(gs), fuse(gs[::-1])
    np.testing.assert_allclose(a.mean, b.mean, rtol=1e-9, atol=1e-6)
    # the product is at least as certain as its most certain member
    assert a.cov[0, 0] <= min(g.cov[0, 0] for g in gs) + 1e-9
    assert a.cov[1, 1] <= min(g.cov[1, 1] for g in gs) + 1e-9
    # and lies within the experts' span
    xs = [g.mean[0] for g in gs]
    assert min(xs) - 1e-6 <= a.mean[0] <= max(xs) + 1e-6


def test_a_new_expert_plugs_in_without_touching_the_others():
    @register_expert
    class FixedExpert(Expert):
        name = "test-fixed"
        image_based = False

        def propose(self, frame, prev, entity):
            return Gaussian([100.0, 50.0], np.eye(2))

    try:
        pote = PoTE(["test-fixed", "det"])
        frame = Frame(1, np.zeros((200, 200, 3), np.uint8), detections=[[80, 20, 20, 40, 0.99]], scale=1.0)
        ent = Entity(box=np.array([85.0, 25.0, 20.0, 40.0]))
        g, ops = pote.estimate(frame, None, ent)
        assert set(ops) == {"test-fixed", "det"}
        # det says (90, 40) with cov diag(20, 40)/6; the new expert says (100, 50) with cov I
        assert 90 < g.mean[0] < 100 and 40 < g.mean[1] < 50
    finally:
        EXPERTS.pop("test-fixed", None)


def test_unknown_expert_is_an_error():
    with pytest.raises(KeyError):
        PoTE(["no-such-expert"])
