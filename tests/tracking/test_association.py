"""The assignment solver of the association step against SciPy's, and its cost at start-up."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.optimize import linear_sum_assignment

from artmotion.tracking.association import INF, assign, hungarian

SRC = Path(__file__).resolve().parents[2] / "src"


def _matrices(max_side: int = 20):
    shapes = st.tuples(st.integers(1, max_side), st.integers(1, max_side))
    # few distinct values make ties; INF entries are forbidden pairs
    values = st.sampled_from([0.0, 0.1, 0.25, 0.5, 0.5, 0.7, 0.9, 1.0, INF, INF])
    return shapes.flatmap(lambda s: arrays(float, s, elements=values))


def _check(pairs, cost):
    rows = [i for i, _ in pairs]
    cols = [j for _, j in pairs]
    assert len(set(rows)) == len(rows) and len(set(cols)) == len(cols)
    assert all(cost[i, j] < INF for i, j in pairs)


@settings(max_examples=400, deadline=None)
@given(_matrices())
def test_assign_is_scipys_optimum(cost):
    """As many allowed pairs as SciPy's assignment keeps, at the same total cost."""
    got = assign(cost)
    _check(got, cost)
    r, c = linear_sum_assignment(cost)
    ref = [(i, j) for i, j in zip(r, c) if cost[i, j] < INF]
    assert len(got) == len(ref)
    assert abs(sum(cost[i, j] for i, j in got) - sum(cost[i, j] for i, j in ref)) < 1e-9


@settings(max_examples=300, deadline=None)
@given(arrays(float, st.tuples(st.integers(1, 12), st.integers(1, 12)), elements=st.floats(-5, 5)))
def test_hungarian_is_optimal(cost):
    got = hungarian(cost)
    assert len(got) == min(cost.shape)
    _check(got, np.zeros_like(cost))
    r, c = linear_sum_assignment(cost)
    assert abs(sum(cost[i, j] for i, j in got) - cost[r, c].sum()) < 1e-9


def test_groups_larger_than_the_small_solver_still_solved():
    rng = np.random.default_rng(1)
    cost = rng.random((30, 25))              # one dense group: the SciPy path
    got = assign(cost)
    r, c = linear_sum_assignment(cost)
    assert len(got) == 25 and abs(sum(cost[i, j] for i, j in got) - cost[r, c].sum()) < 1e-9


def test_tracking_does_not_import_scipy_optimize(tmp_path):
    """SciPy's optimizer costs ~0.4 s of start-up: a frame's small assignments do without it; nor
    numpy.ma (np.unique imports it: 40 ms, a sixth of the short sequences' 2x budget)."""
    code = ("import sys; from artmotion.cli import main; code = main(sys.argv[1:]); "
            "assert code == 0, code; print('scipy.optimize' in sys.modules or 'numpy.ma' in sys.modules)")
    sample = Path(__file__).resolve().parents[2] / "data" / "TUD-Campus"
    out = subprocess.run([sys.executable, "-c", code, "track", str(sample), "--out", str(tmp_path / "r.txt"),
                          "--no-progress"], capture_output=True, text=True, env={"PYTHONPATH": str(SRC), "PATH": "/usr/bin:/bin"})
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "False"
