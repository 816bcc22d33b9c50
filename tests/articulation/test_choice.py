"""Model choice (#14) on the shapes where it used to fail: curved drawers, slipping doors, doors
opened and closed again; and the pieces of the score (noise, correlation, curvature's Occam factor)."""

import json

import numpy as np
import pytest

from artmotion.articulation.online import autocorrelation_time, curvature_occam, estimate_online
from artmotion.articulation.synthetic import KINDS, synthetic_log


def _log(kind, seed):
    return synthetic_log(kind, 1000 * list(KINDS).index(kind) + seed)


@pytest.mark.parametrize("seed", range(4))
def test_curved_drawer_is_prismatic(seed):
    # a pull that bends by 2-8 mm over 0.25-0.5 m fits a circle of several metres as well as a line:
    # the circle's radius is beyond any hinge's, its curvature pays its Occam factor
    X, truth = _log("curved_drawer", seed)
    res = estimate_online(X)
    assert res.model == truth == "prismatic", (res.probabilities, res.margin)
    # with a prior that admits 10 m hinges the same bend can pass for one (the prior does the work)
    wide = estimate_online(X, radius_range=(0.01, 100.0))
    assert wide.probabilities["prismatic"] < res.probabilities["prismatic"]


@pytest.mark.parametrize("seed", range(4))
def test_slipping_door_is_revolute_with_its_own_noise(seed):
    X, truth = _log("slipping_door", seed)
    res = estimate_online(X)
    assert res.model == truth == "revolute", res.probabilities
    # the noise is estimated per model (Student-t: the slips do not inflate the circle's)
    assert res.noise["revolute"] < 0.006 < res.noise["prismatic"]


@pytest.mark.parametrize("seed", range(3))
def test_back_and_forth_door_never_flips(seed):
    X, truth = _log("back_and_forth_door", seed)
    res = estimate_online(X)
    assert len(X) > 700 and res.model == truth == "revolute"
    assert res.decided_at < 0.5 * len(X)
    tail = res.history[res.decided_at:, res.names.index("revolute")]
    assert tail.min() > 0.75  # decided once, never revised (the threshold's run is unbroken)


def test_static_point_with_held_handle():
    X, truth = _log("static", 0)
    res = estimate_online(X)
    assert res.model == truth == "static" and not res.revised


def test_autocorrelation_time():
    rng = np.random.default_rng(0)
    assert autocorrelation_time(rng.normal(size=(4000, 3))) < 1.3
    e = np.zeros((20000, 1))
    w = rng.normal(size=20000)
    for k in range(1, 20000):
        e[k] = 0.9 * e[k - 1] + w[k]
    assert 19 * 0.7 < autocorrelation_time(e) < 19 * 1.3  # (1 + phi) / (1 - phi)


def test_curvature_occam():
    rng = (0.01, 1.0)
    assert curvature_occam(2.0, 1e6, rng, 2) > -1e-3  # a likelihood flat over the prior costs nothing
    # peaked inside: the posterior's area over the prior's density, p(|k|) = 1 / (|k| log 100)
    p = 1.0 / (2.0 * np.log(100.0))
    sharp = curvature_occam(2.0, 0.01, rng, 2)
    assert sharp == pytest.approx(np.log(p * 0.01**2 / 2.0), abs=0.02)  # 2 components: s^2 / |k|
    assert curvature_occam(2.0, 0.01, rng, 1) == pytest.approx(np.log(0.5 * np.sqrt(2 * np.pi) * 0.01 * p), abs=0.02)
    assert curvature_occam(0.1, 0.01, rng, 2) < sharp - 20  # a radius of 10 m, well outside the range


def test_fit_json_reports_noise_and_margin(tmp_path, run_cli):
    X, _ = _log("door", 1)
    p = tmp_path / "door.txt"
    np.savetxt(p, X)
    code, out, _ = run_cli("articulation", "fit", str(p), "--json")
    d = json.loads(out)
    assert code == 0 and d["model"] == "revolute"
    assert set(d["noise_per_model"]) == {"static", "prismatic", "revolute"}
    assert d["noise"] == d["noise_per_model"]["revolute"] < 0.01
    assert d["margin"]["runner_up"] in ("static", "prismatic") and d["margin"]["log_odds"] > np.log(3.0)
    code, out, _ = run_cli("articulation", "fit", str(p))
    assert code == 0 and "margin over" in out and "noise std per model" in out
    code, _, err = run_cli("articulation", "fit", str(p), "--radius-range", "1", "0.5")
    assert code == 2 and "--radius-range" in err
