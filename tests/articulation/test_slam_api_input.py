"""Bad input to the SLAM Python API is an InputError that names the argument and what was got, raised
before any state is touched; valid input runs as before."""

import importlib.util
import math

import numpy as np
import pytest

from artmotion.articulation.slam import EKFSlam, make_world, monte_carlo, pose_errors, simulate
from artmotion.articulation.slam.ekf import gate_threshold
from artmotion.articulation.slam.world import make_scenario
from artmotion.errors import MAX_SEED, InputError

HAVE_GTSAM = importlib.util.find_spec("gtsam") is not None
needs_gtsam = pytest.mark.skipif(not HAVE_GTSAM, reason="gtsam is not installed")

ARGS = dict(x0=[0.0, 0.0, 0.0], dt=0.1, alphas=(0.05, 0.005, 0.005, 0.05), range_std=0.1, bearing_std=0.02, n_max=5)
BACKENDS = [pytest.param("ekf", id="ekf"), pytest.param("ekf_articulated", id="ekf_articulated"),
            pytest.param("graph", id="graph", marks=needs_gtsam)]


def _backend(kind: str, **kw):
    if kind == "graph":
        from artmotion.articulation.slam.graph import GraphSlam

        return GraphSlam(**{**ARGS, **kw})
    return EKFSlam(**{**ARGS, "articulated": kind == "ekf_articulated", **kw})


def _state(f):
    if hasattr(f, "mu"):
        return f.mu[:f.n].tolist(), f.P[:f.n, :f.n].tolist(), f.k, dict(f.kinds)
    return f.pose.tolist(), f.pose_cov.tolist(), f.k, dict(f.kinds)


# -- 1. sightings: a range of 0 or 1e200 turned the whole state to NaN for good, a negative one was
#    taken (and moved the pose); the graph back end took a flat list, a NaN control, a range of 0
#    (gtsam: "indeterminate linear system")
@pytest.mark.parametrize("kind", BACKENDS)
@pytest.mark.parametrize("zs, what", [
    ([[5.0, 0.1], [0.0, 0.0]], r"zs\[1\] of landmark 1 has range 0: ranges must lie in \[1e-06, 1e\+06\]"),
    ([[5.0, 0.1], [-5.0, 0.0]], r"zs\[1\] of landmark 1 has range -5:"),
    ([[1e200, 0.1], [5.0, 0.0]], r"zs\[0\] of landmark 0 has range 1e\+200:"),
    ([[1e-300, 0.1], [5.0, 0.0]], r"zs\[0\] of landmark 0 has range 1e-300:"),
    ([[5.0, 0.1], [math.nan, 0.0]], r"zs\[1\] of landmark 1 has range nan:"),
    ([[5.0, 0.1], [5.0, math.inf]], r"zs\[1\] of landmark 1 has bearing inf: bearings must be finite"),
    ([5.0, 0.1, 5.0, 0.0], r"sightings zs must be \(range, bearing\) pairs"),
])
def test_bad_sightings_are_refused_before_the_state_is_touched(kind, zs, what):
    f = _backend(kind)
    f.predict([1.0, 0.1])
    f.update([0, 1], [[5.0, 0.1], [6.0, -0.2]])
    before = _state(f)
    with pytest.raises(InputError, match=what):
        f.update([0, 1], zs)
    assert _state(f) == before
    for _ in range(3):  # and the back end goes on, finite
        f.predict([0.0, 0.0])
        f.update([0, 1], [[5.0, 0.1], [6.0, -0.2]])
    assert np.isfinite(f.pose).all() and np.isfinite(f.pose_cov).all()


@pytest.mark.parametrize("kind", BACKENDS)
def test_both_back_ends_refuse_a_bad_control_alike(kind):
    f = _backend(kind)
    for u in ([math.nan, 0.1], [1.0, math.inf], [1.0], "vw"):
        with pytest.raises(InputError, match="a control must be two finite numbers"):
            f.predict(u)
    assert f.k == 0 and np.isfinite(f.pose).all()


# -- 2. the constructors' arguments: none was checked (a NaN x0, a negative dt or noise ran on to
#    nonsense; Algorithm 1's were refused at the first sighting under names the user never passed)
BAD_ARGS = [
    ({"x0": [math.nan, 0.0, 0.0]}, "x0 must be 3 finite numbers"),
    ({"x0": [0.0, 0.0]}, "x0 must be 3 finite numbers"),
    ({"x0": "abc"}, "x0 must be"),
    ({"dt": -1.0}, r"dt must be a number in \(0, inf\), got -1"),
    ({"dt": 0.0}, "dt must be"),
    ({"dt": math.nan}, "dt must be"),
    ({"alphas": (-1.0, 0.0, 0.0, 0.0)}, "alphas must be 4 finite numbers >= 0"),
    ({"alphas": (1.0, 1.0, 1.0)}, "alphas must be 4"),
    ({"alphas": (1.0, 1.0, math.inf, 1.0)}, "alphas must be 4"),
    ({"range_std": -1.0}, r"range_std must be a number in \(0, inf\), got -1"),
    ({"range_std": 0.0}, "range_std must be"),
    ({"bearing_std": 0.0}, "bearing_std must be"),
    ({"bearing_std": math.inf}, "bearing_std must be"),
    ({"n_max": -1}, "n_max must be a whole number"),
    ({"n_max": 2.5}, "n_max must be a whole number"),
    ({"motion_var": -1.0}, "motion_var must be"),
    ({"gate": 0.0}, r"gate must be a number in \(0, 1\), got 0"),
    ({"gate": 1.0}, "gate must be"),
    ({"gate": math.nan}, "gate must be"),
    ({"articulated": True, "threshold": 2.0}, r"threshold must be a number in \(0, 1\), got 2"),
    ({"articulated": True, "threshold": 0.0}, "threshold must be"),
    ({"articulated": True, "min_samples": 0}, r"min_samples must be a whole number in \[3, "),
    ({"articulated": True, "min_samples": 7.5}, "min_samples must be"),
    ({"articulated": True, "point_noise": -1.0}, r"point_noise must be a number in \[0, inf\), got -1"),
    ({"articulated": True, "max_radius": -1.0}, r"max_radius must be a number in \(0.5, inf\), got -1"),
    ({"articulated": True, "max_radius": 0.3}, "max_radius must be"),
    ({"articulated": True, "accel": -1.0}, "accel must be"),
]


@pytest.mark.parametrize("cls", ["ekf", pytest.param("graph", marks=needs_gtsam)])
@pytest.mark.parametrize("kw, what", BAD_ARGS)
def test_constructor_arguments_are_checked(cls, kw, what):
    kind = "graph" if cls == "graph" else "ekf"
    with pytest.raises(InputError, match=what) as e:
        _backend(kind, **kw)
    assert "noise_floor" not in str(e.value) and "radius_range" not in str(e.value)


@pytest.mark.parametrize("kw, what", [({"undecided_var": -1.0}, "undecided_var must be"),
                                      ({"undecided_var": math.nan}, "undecided_var must be")])
def test_ekf_only_arguments_are_checked(kw, what):
    with pytest.raises(InputError, match=what):
        _backend("ekf", **kw)


@needs_gtsam
@pytest.mark.parametrize("kw, what", [
    ({"joint_noise": -1.0}, "joint_noise must be"),
    ({"relinearize_threshold": math.nan}, "relinearize_threshold must be"),
    ({"relinearize_skip": 0}, r"relinearize_skip must be a whole number in \[1, "),  # iSAM2 died of SIGFPE
    ({"relinearize_skip": 2.5}, "relinearize_skip must be"),
])
def test_graph_only_arguments_are_checked(kw, what):
    with pytest.raises(InputError, match=what):
        _backend("graph", **kw)


def test_gate_threshold_refuses_with_an_input_error():
    for p in (0.0, 1.0, math.nan, "0.1"):
        with pytest.raises(InputError, match=r"p must be a number in \(0, 1\)"):
            gate_threshold(p)


# -- 3. worlds, runs and errors
@pytest.mark.parametrize("call, what", [
    # (KeyError: the default steps were read from WORLDS[world] before the name was checked)
    (lambda: monte_carlo(runs=1, world="Table4.2", backends=("ekf",)), "unknown world 'Table4.2'"),
    (lambda: monte_carlo(runs=1, steps=5, backends=("ekf",), options=[1]), "options must map back end names"),
    (lambda: monte_carlo(runs=1, steps=5, backends=("ekf",), options={"ekf": 1}), r"options\['ekf'\] must be a dict"),
    (lambda: monte_carlo(runs=1, steps=5, backends=("ekf",), options={"ekff": {}}), "unknown back end in options: 'ekff'"),
    (lambda: monte_carlo(runs=1, steps=5, backends=("ekf",), options={"ekf": {"foo": 1}}),
     r"options\['ekf'\] names no keyword argument of EKFSlam: 'foo'"),
    (lambda: monte_carlo(runs=1, steps=5, backends="ekf"), "backends must be a list of back end names"),
    (lambda: monte_carlo(runs=1, steps=5, backends=("ekf",), landmarks=(5, 3, 3)),
     r"landmarks\[1\] \(prismatic\) \(3\) and landmarks\[2\] \(revolute\) \(3\) add up to more than landmarks\[0\]"),
    (lambda: monte_carlo(runs=1, steps=5, backends=("ekf",), landmarks=(5, 1)), "landmarks must be three counts"),
    (lambda: make_world(10, seed=-1), r"seed must be a whole number in \[0, 4294967295\], got -1"),
    (lambda: make_scenario("corridor", seed=-1), "seed must be"),
    (lambda: make_world(10, radius=math.nan), r"radius must be a number in \(0, inf\), got nan"),
    (lambda: make_world(10, radius=-1.0), "radius must be"),
    (lambda: make_scenario("warehouse", radius=math.inf), "radius must be"),
    (lambda: make_world(2.5, 0, 0), "n_landmarks must be a whole number"),
    (lambda: make_world(5, 3, 3), r"n_prismatic \(3\) and n_revolute \(3\) add up to more than n_landmarks \(5\)"),
    (lambda: simulate(make_world(10), -3), r"steps must be a whole number in \[1, "),
    (lambda: simulate(make_world(10), 0), "steps must be"),
    (lambda: simulate(make_world(10), 3, seed=-1), "seed must be"),
    (lambda: simulate(make_world(10), 3, radius=0.0), "radius must be"),
    (lambda: simulate("table4.2", 3), "world must be a World"),
    (lambda: pose_errors(np.zeros((1, 3)), np.zeros((1, 3))), "at least 2 poses, got 1"),
    (lambda: pose_errors(np.zeros((5, 3)), np.zeros((5, 3)), lag=10), r"lag must be a whole number in \[0, 4\], got 10"),
    (lambda: pose_errors(np.zeros((5, 3)), np.zeros((5, 3)), lag=-1), "lag must be"),
    (lambda: pose_errors(np.zeros((5, 3)), np.zeros((5, 3)), stride=0), "stride must be"),
    (lambda: pose_errors(np.zeros((5, 3)), np.zeros((4, 3))), "est and true must hold as many poses, got 5 and 4"),
    (lambda: pose_errors(np.zeros((5, 2)), np.zeros((5, 2))), r"est must be an \(n, 3\) array of poses"),
    (lambda: pose_errors(np.zeros((5, 3)), np.full((5, 3), math.nan)), "true holds NaN or infinite values"),
    (lambda: pose_errors("abc", np.zeros((5, 3))), "est must be an array of numbers"),
])
def test_world_and_evaluation_arguments_are_checked(call, what):
    with pytest.raises(InputError, match=what):
        call()


def test_valid_edge_cases_still_run():
    """Guards, not mends: the largest seed still runs (later runs' seeds pass 2**32 - 1, which
    NumPy's generators take); lag n - 1 and lists are fine; a whole float count is a count."""
    res = monte_carlo(runs=2, steps=5, seed=MAX_SEED, backends=("ekf",))
    assert res["runs"] == 2 and math.isfinite(res["ekf"]["translation_error"]["mean"])
    p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.1], [2.0, 0.5, 0.2]]
    assert pose_errors(p, p, lag=2)["translation_error"] == 0.0


def test_a_landmark_on_the_path_gives_positive_ranges_the_filters_take():
    """A landmark the robot drives through (a door swinging across the corridor) is nearer than the
    range noise: the simulated range folds back to positive instead of being negative, which the
    filters now refuse (the benchmark's corridor stopped on one)."""
    from artmotion.articulation.slam.world import World

    path = np.array([[10.0 * math.cos(a), 10.0 * math.sin(a)] for a in np.linspace(0.05, 0.6, 12)])
    sim = simulate(World(path), 60, seed=3)
    near = [z[:, 0] for _, z in sim["observations"] if len(z)]
    assert min(float(r.min()) for r in near) > 0
    assert any(float(r.min()) < 0.3 for r in near)  # the case: landmarks within the noise of the robot
    from artmotion.articulation.slam.evaluate import run_slam

    for backend in ("ekf", "articulated"):
        assert np.isfinite(run_slam(sim, backend)["poses"]).all()


# -- 4. whole-number floats are the counts they are: n_max=5.0 passed the check, then NumPy refused
#    "13.0" as an array size; iSAM2 refused relinearize_skip=10.0 with a pybind11 TypeError
@pytest.mark.parametrize("kind", BACKENDS)
def test_whole_number_floats_are_taken_as_integers(kind):
    sim = simulate(make_world(12, 1, 1), 40)
    ints = {"n_max": 12, "min_samples": 7} | ({"relinearize_skip": 10} if kind == "graph" else {})
    runs = []
    for kw in (ints, {k: float(v) for k, v in ints.items()}, {k: np.int64(v) for k, v in ints.items()}):
        f = _backend(kind, x0=sim["poses"][0], dt=sim["dt"], **kw)
        for k, u in enumerate(sim["controls"]):
            f.predict(u)
            f.update(*sim["observations"][k])
        runs.append(_state(f))
    assert runs[1] == runs[0] and runs[2] == runs[0]


@pytest.mark.parametrize("field, value", [("dt", float("nan")), ("dt", -1.0), ("alphas", (-0.1, 0, 0, 0)),
                                          ("alphas", "abcd"), ("alphas", (0.1,)), ("range_std", -1.0),
                                          ("v", float("inf")), ("v", "1"), ("fov", 0.0), ("max_seen", 0)])
def test_a_simulation_config_is_checked_as_made(field, value):
    """NaN or negative noise gave NaN robot poses with no error; others failed deep in NumPy."""
    from artmotion.articulation.slam.world import SimConfig

    with pytest.raises(InputError, match=field.rstrip("s") if field == "alphas" else field):
        SimConfig(**{field: value})
    assert SimConfig().alphas == (0.05, 0.005, 0.005, 0.05)


def test_a_filter_for_more_landmarks_than_memory_holds_is_refused():
    """n_max = 10**6 was in range and asked for 29 TiB of covariance (a MemoryError)."""
    from artmotion.articulation.slam.ekf import MAX_LANDMARKS

    with pytest.raises(InputError, match="n_max must be a whole number in"):
        EKFSlam(np.zeros(3), 0.1, (0,) * 4, 0.1, 0.01, n_max=10**6)
    assert EKFSlam(np.zeros(3), 0.1, (0,) * 4, 0.1, 0.01, n_max=MAX_LANDMARKS).P.shape == (3 + 2 * MAX_LANDMARKS,) * 2


def test_run_slam_refuses_what_is_not_a_simulated_run():
    """``run_slam({})`` was a KeyError 'config'."""
    from artmotion.articulation.slam.evaluate import run_slam
    from artmotion.articulation.slam.world import make_world, simulate

    sim = simulate(make_world(6, 0, 0, seed=0), 5, seed=0)
    for bad in ({}, None, [], {**sim, "config": {}}, {**sim, "observations": sim["observations"][:2]},
                {k: v for k, v in sim.items() if k != "dt"}):
        with pytest.raises(InputError, match="sim must be a simulated run"):
            run_slam(bad, "ekf")
    assert len(run_slam(sim, "ekf")["poses"]) == 6


# -- 5. the public EKF helpers (motion_model, observe, control_noise, inverse_observation) checked
#    nothing: a NaN pose gave a NaN pose, an infinite control an infinite noise, 2 numbers for a pose a
#    ValueError from unpacking, text a UFuncTypeError
def _ekf_helpers():
    from artmotion.articulation.slam import ekf

    return ekf


POSE, CONTROL, ALPHAS = np.array([1.0, 2.0, 0.3]), [1.0, 0.1], [0.05, 0.005, 0.005, 0.05]


@pytest.mark.parametrize("call, what", [
    (lambda e: e.motion_model(np.array([math.nan, 0.0, 0.0]), CONTROL, 0.1),
     r"x must be a pose, 3 numbers \(x, y, theta\), finite and of magnitude at most 1e\+100, got array\(\[nan"),
    (lambda e: e.motion_model(np.zeros(2), CONTROL, 0.1),
     r"x must be a pose, 3 numbers \(x, y, theta\): an array of shape \(3,\), got shape \(2,\)"),
    (lambda e: e.motion_model(np.zeros((1, 3)), CONTROL, 0.1), r"x must be a pose.*got shape \(1, 3\)"),
    (lambda e: e.motion_model("abc", CONTROL, 0.1), r"x must be a pose, 3 numbers \(x, y, theta\), got 'abc'"),
    (lambda e: e.motion_model(POSE, [1.0, math.inf], 0.1), r"u must be a control, 2 numbers \(v, omega\), finite"),
    (lambda e: e.motion_model(POSE, [1.0], 0.1), r"u must be a control, 2 numbers \(v, omega\): an array of shape \(2,\)"),
    (lambda e: e.motion_model(POSE, ["1", "0.1"], 0.1), r"u must be a control, 2 numbers \(v, omega\), got \['1', '0.1'\]"),
    (lambda e: e.motion_model(POSE, [1e200, 0.1], 0.1), r"u must be a control.* magnitude at most 1e\+100"),
    (lambda e: e.motion_model(POSE, CONTROL, 0.0), r"dt must be a number in \(0, 1e\+100\], got 0"),
    (lambda e: e.motion_model(POSE, CONTROL, -0.1), r"dt must be a number in \(0, 1e\+100\], got -0.1"),
    (lambda e: e.motion_model(POSE, CONTROL, math.nan), "dt must be a number in"),
    (lambda e: e.motion_model(POSE, CONTROL, "0.1"), r"dt must be a number in .* got '0.1'"),
    (lambda e: e.motion_model(POSE, CONTROL, None), "dt must be a number in"),
    (lambda e: e.observe(np.zeros(3), np.array(["2", "1"])), r"m must be a landmark position, 2 numbers \(m_x, m_y\), got"),
    (lambda e: e.observe(np.zeros(3), np.array([math.nan, 1.0])), "m must be a landmark position.*finite"),
    (lambda e: e.observe(np.zeros(3), np.zeros(3)), r"m must be a landmark position.*shape \(2,\), got shape \(3,\)"),
    (lambda e: e.observe(np.array([0.0, 0.0, math.inf]), np.ones(2)), "x must be a pose"),
    (lambda e: e.observe(np.array([1.0, 2.0, 0.0]), np.array([1.0, 2.0])), "m must lie away from the pose x, got range 0"),
    (lambda e: e.control_noise([math.inf, 0.1], ALPHAS), r"u must be a control, 2 numbers \(v, omega\), finite"),
    (lambda e: e.control_noise(CONTROL, [0.05, 0.005, 0.005]), r"alphas must be 4 numbers >= 0 .*shape \(4,\), got shape \(3,\)"),
    (lambda e: e.control_noise(CONTROL, [-0.05, 0.005, 0.005, 0.05]), r"alphas must be 4 numbers >= 0"),
    (lambda e: e.control_noise(CONTROL, [0.05, math.nan, 0.005, 0.05]), r"alphas must be 4 numbers >= 0"),
    (lambda e: e.control_noise(CONTROL, "abcd"), r"alphas must be 4 numbers >= 0 .*got 'abcd'"),
    (lambda e: e.inverse_observation(POSE, [math.nan, 0.1]), r"z must be a sighting, 2 numbers \(range, bearing\), finite"),
    (lambda e: e.inverse_observation(POSE, [5.0]), r"z must be a sighting.*shape \(2,\), got shape \(1,\)"),
    (lambda e: e.inverse_observation(POSE, [-5.0, 0.1]), r"z's range must be >= 0 \(a distance\), got -5"),
    (lambda e: e.inverse_observation([0.0, 0.0], [5.0, 0.1]), r"x must be a pose.*got shape \(2,\)"),
])
def test_public_ekf_helpers_refuse_bad_input(call, what):
    with pytest.raises(InputError, match=what):
        call(_ekf_helpers())


def test_public_ekf_helpers_give_what_the_filter_computes():
    """Valid input: the checked helpers return what the filter's unchecked ones do, bit for bit
    (arrays, lists and tuples alike; ints are numbers); a range of 0 inverts to the robot's place."""
    e = _ekf_helpers()
    for x in (POSE, POSE.tolist(), tuple(POSE.tolist())):
        for u in (CONTROL, np.array(CONTROL), (1.0, 0.0), [1, 0]):
            for got, want in zip(e.motion_model(x, u, 0.1), e._motion_model(np.asarray(x), np.asarray(u, float), 0.1)):
                assert np.array_equal(got, want)
        for got, want in zip(e.observe(x, [4.0, 5.0]), e._observe(np.asarray(x), np.array([4.0, 5.0]))):
            assert np.array_equal(got, want)
        for got, want in zip(e.inverse_observation(x, [5.0, 0.2]), e._inverse_observation(np.asarray(x), [5.0, 0.2])):
            assert np.array_equal(got, want)
    assert np.allclose(e.control_noise(CONTROL, ALPHAS), np.diag([0.05 + 0.005 * 0.01, 0.005 + 0.05 * 0.01]), rtol=1e-15)
    assert np.array_equal(e.control_noise(np.array(CONTROL), np.array(ALPHAS)), e._control_noise(CONTROL, ALPHAS))
    assert np.array_equal(e.inverse_observation(POSE, [0.0, 0.1])[0], POSE[:2])
    assert np.isfinite(e.motion_model(POSE, [1e100, 1e-100], 1e100)[2]).all()  # the largest numbers taken stay finite


def test_the_filter_steps_without_the_public_helpers_checks(monkeypatch):
    """The checks cost microseconds a call: EKFSlam's per-step path (>= 500 steps/s at 42 landmarks)
    calls the unchecked helpers, never the public ones."""
    e = _ekf_helpers()

    def refuse(*args, **kwargs):
        raise AssertionError("EKFSlam called a checked public helper")

    for name in ("motion_model", "control_noise", "observe", "inverse_observation"):
        monkeypatch.setattr(e, name, refuse)
    sim = simulate(make_world(12, 1, 1), 40)
    for articulated in (False, True):
        f = _backend("ekf_articulated" if articulated else "ekf", x0=sim["poses"][0], dt=sim["dt"], n_max=12)
        for k, u in enumerate(sim["controls"]):
            f.predict(u)
            f.update(*sim["observations"][k])
        assert np.isfinite(f.pose).all() and len(f.kinds) > 0
