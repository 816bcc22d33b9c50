"""``artmotion articulation fit`` and ``artmotion slam simulate`` through the root CLI."""

import json
import math

import numpy as np
import pytest


def _write(path, rows, fmt="%.6f", header=None, sep=" "):
    with open(path, "w") as fh:
        if header:
            fh.write(header + "\n")
        for r in rows:
            fh.write(sep.join(fmt % v for v in r) + "\n")
    return path


def _arc(n=150, noise=0.002, seed=0):
    rng = np.random.default_rng(seed)
    th = np.linspace(0, 1.4, n)
    return np.column_stack([0.4 * np.cos(th), 0.4 * np.sin(th), 0.1 + 0 * th]) + rng.normal(0, noise, (n, 3))


def test_fit_json_revolute(tmp_path, run_cli):
    p = _write(tmp_path / "door.txt", _arc())
    code, out, err = run_cli("articulation", "fit", p, "--json")
    assert code == 0, err
    res = json.loads(out)
    assert res["model"] == "revolute"
    assert set(res["probabilities"]) == {"static", "prismatic", "revolute"}
    assert isinstance(res["decided_at"], int)
    assert abs(res["configuration"]["radius"] - 0.4) < 0.01
    assert len(res["motion"]) == 150 and len(res["prediction"]) == 5


def test_fit_json_of_a_file_name_that_is_not_utf8_is_strict_json(tmp_path, run_cli):
    """The name's bytes that are not UTF-8 went into the JSON as a lone surrogate (a strict reader
    refuses it, jq loses the name): written escaped, as an error line writes it."""
    import os

    p = _write(tmp_path / os.fsdecode(b"d\xe9.txt"), _arc())
    code, out, err = run_cli("articulation", "fit", p, "--json")
    assert code == 0, err
    out.encode("utf-8")     # (a lone surrogate could not be encoded)
    assert json.loads(out)["file"].endswith("d\\udce9.txt")


def test_fit_says_which_line_is_a_sample_far_from_both_neighbours(tmp_path, run_cli):
    """One sample 1 km off (a corrupt line) decided a door's answer with probability 1.000 and no
    word said: the note names its line; a clean track has no such note."""
    X = _arc()
    clean = _write(tmp_path / "clean.txt", X)
    X[70, 0] += 1000.0
    bad = _write(tmp_path / "glitch.txt", X)
    code, out, err = run_cli("articulation", "fit", bad, "--json")
    assert code == 0 and "line 71: a sample far from both its neighbours" in json.loads(out)["note"], out
    code, out, err = run_cli("articulation", "fit", clean)
    assert code == 0 and "far from both its neighbours" not in out


def test_fit_summary_and_time_column_with_header(tmp_path, run_cli):
    X = _arc()
    t = np.arange(len(X)) * 0.05
    p = _write(tmp_path / "door.csv", np.column_stack([t, X]), header="time,x,y,z", sep=",")
    code, out, err = run_cli("articulation", "fit", p)
    assert code == 0, err
    assert "model: revolute" in out and "time column" in out
    code, out, _ = run_cli("articulation", "fit", p, "--json", "--threshold", "0.9", "--min-samples", "10")
    assert json.loads(out)["time_column"] is True


def test_the_header_names_the_columns(tmp_path, run_cli):
    """The header decides which column is which, in any order and with units: 'x,y,z,t' took x for
    the time (four columns) and 'time_s,x,y' took the time for x, each a confident wrong answer."""
    X = _arc()
    t = 1000 + np.arange(len(X)) * 0.05
    want = None
    for header, cols in (("t,x,y,z", [t, *X.T]), ("x,y,z,t", [*X.T, t]), ("time_s,z_m,y_m,x_m", [t, *X.T[::-1]]),
                         ("y,x,z", [X[:, 1], X[:, 0], X[:, 2]])):
        p = _write(tmp_path / "door.csv", np.column_stack(cols), header=header, sep=",")
        code, out, err = run_cli("articulation", "fit", p, "--json")
        assert code == 0, err
        res = json.loads(out)
        assert res["model"] == "revolute" and res["time_column"] == ("t" in header), header
        centre = res["configuration"]["centre"]
        assert want is None or np.allclose(centre, want, atol=1e-9), header
        want = centre
    code, _, err = run_cli("articulation", "fit", p, "--time")
    assert code == 2 and "names no time column, but --time" in err


def test_fit_2d_prismatic_and_pose(tmp_path, run_cli):
    n = 100
    rng = np.random.default_rng(1)
    xy = np.column_stack([np.linspace(0, 0.5, n), np.linspace(0, 0.25, n)]) + rng.normal(0, 0.002, (n, 2))
    code, out, _ = run_cli("articulation", "fit", _write(tmp_path / "p.txt", xy), "--json")
    assert code == 0 and json.loads(out)["model"] == "prismatic"
    pose = np.column_stack([np.linspace(0, 0.5, n), np.zeros(n), np.zeros(n), np.tile([0, 0, 0, 1.0], (n, 1))])
    code, out, _ = run_cli("articulation", "fit", _write(tmp_path / "pose.txt", pose), "--json")
    res = json.loads(out)
    assert code == 0 and res["model"] == "prismatic" and res["input"] == "pose"
    # Algorithm 1's options do not apply to a pose track: said, not silently ignored
    code, out, _ = run_cli("articulation", "fit", tmp_path / "pose.txt", "--order", "3")
    assert code == 0 and "noise std: " in out and "(--order: options of Algorithm 1's point tracks" in out
    code, out, _ = run_cli("articulation", "fit", tmp_path / "pose.txt")
    assert code == 0 and "options of Algorithm 1" not in out


def test_constant_trajectory_is_static(tmp_path, run_cli):
    # "static" must be confirmed for as long again as it took to become probable (45 samples here)
    p = _write(tmp_path / "c.txt", np.tile([1.0, 2.0, 3.0], (100, 1)))
    code, out, _ = run_cli("articulation", "fit", p, "--json")
    assert code == 0 and json.loads(out)["model"] == "static"


def test_too_few_samples_is_undecided(tmp_path, run_cli):
    p = _write(tmp_path / "few.txt", [[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]])
    code, out, _ = run_cli("articulation", "fit", p, "--json")
    res = json.loads(out)
    assert code == 0 and res["model"] == "undecided" and res["decided_at"] is None


@pytest.mark.parametrize("content,needle", [
    ("0 0 0\n1 1\n", "f.txt:2: expected 3 columns"),
    ("0 0 0\nnan 0 0\n", "f.txt:2: NaN"),
    ("0 0 0 0 0 0 2\n", "f.txt:1: non-unit quaternion"),
    ("0 0 0 0 0\n", "f.txt:1: expected 2"),
    ("# only a comment\n", "f.txt: no samples"),
    ("0 1 2\nabc 1 2\n", "f.txt:2: not a number"),
    ("0 0 0 0\n0 1 1 1\n", "f.txt:2: time must increase"),
    ("t x y\n0 0 0\n1e-13 1 1\n", "f.txt:3: time step 1e-13 from the row before"),
    ("0,0,0\n0.1,,0.2\n", "f.txt:2: empty field"),      # not the point (0.1, 0.2): the rest would shift
    ("0;0;0\n;0.1;0.2\n", "f.txt:2: empty field"),
    ("0 0 0\n1_0 1 1\n", "f.txt:2: not a number"),     # Python's float() reads 1_0 as ten
    ("0.3x 0 0\n0 0 0\n1 1 1\n", "f.txt:1: not a number"),  # a damaged first row, not a header to skip
    ("px,py,pz\n0,0,0\n1,1,1\n", "f.txt:1: header: unknown column name 'px'"),
    ("t,x,time\n0,0,0\n1,1,1\n", "f.txt:1: header: two time columns"),
    ("x,x,y\n0,0,0\n1,1,1\n", "f.txt:1: header: a column named twice"),
    ("x,z\n0,0\n1,1\n", "f.txt:1: header: columns x, z: expected"),
])
def test_bad_input_is_one_line(tmp_path, run_cli, content, needle):
    p = tmp_path / "f.txt"
    p.write_text(content)
    code, out, err = run_cli("articulation", "fit", p)
    assert code == 2
    assert needle in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_missing_file_and_bad_options(tmp_path, run_cli):
    code, _, err = run_cli("articulation", "fit", tmp_path / "nope.txt")
    assert code == 2 and "no such file" in err
    p = _write(tmp_path / "a.txt", _arc(20))
    code, _, err = run_cli("articulation", "fit", p, "--threshold", "1.5")
    assert code == 2 and "threshold" in err
    code, _, err = run_cli("articulation", "fit", p, "--no-time", "--min-samples", "2")
    assert code == 2


def test_slam_simulate_json_and_plot(tmp_path, run_cli):
    png = tmp_path / "slam.png"
    code, out, err = run_cli("slam", "simulate", "--steps", "150", "--runs", "1", "--landmarks", "20",
                             "--json", "--plot", png)
    assert code == 0, err
    res = json.loads(out)
    for k in ("articulated", "ekf", "ekf_gated"):
        t = res[k]["translation_error"]
        assert 0 <= t["mean"] and res[k]["rotation_error"]["mean"] >= 0 and res[k]["nees"]["mean"] > 0
    assert png.exists() and png.read_bytes()[:4] == b"\x89PNG"


def test_slam_simulate_shorter_than_the_error_stride(run_cli):
    """Fewer steps than the pose-pair stride (5): the first and last poses still give an error."""
    code, out, err = run_cli("slam", "simulate", "--steps", "2", "--runs", "1", "--json")
    assert code == 0, err
    res = json.loads(out)
    assert all(math.isfinite(v["translation_error"]["mean"]) for v in res.values() if isinstance(v, dict) and "translation_error" in v)
    assert math.isfinite(res["articulated"]["translation_error"]["mean"])


def test_slam_simulate_named_world(run_cli):
    code, out, err = run_cli("slam", "simulate", "--world", "warehouse", "--steps", "120", "--runs", "2",
                             "--backends", "articulated,ekf_gated")
    assert code == 0, err
    rows = [line.split("  ")[0] for line in out.splitlines()]
    assert "warehouse" in out and "Articulated EKF SLAM" in rows and "EKF SLAM + chi2 gate" in rows
    assert "EKF SLAM" not in rows  # not asked for
    code, out, err = run_cli("slam", "simulate", "--steps", "20", "--runs", "1", "--backends", "ekf,ekf")
    assert code == 0 and [line.split("  ")[0] for line in out.splitlines()].count("EKF SLAM") == 1  # once


def test_slam_bad_options(run_cli, tmp_path):
    code, _, err = run_cli("slam", "simulate", "--landmarks", "1", "--prismatic", "1", "--revolute", "1")
    assert code == 2 and err.startswith("artmotion: error:")
    code, _, err = run_cli("slam", "simulate", "--landmarks", "1")  # the defaults' 1 + 1 do not fit: say so
    assert code == 2 and "1 each unless given" in err
    for args in (("--prismatic", "5"), ("--world", "corridor", "--landmarks", "30")):  # not silently ignored
        code, _, err = run_cli("slam", "simulate", *args)
        assert code == 2 and err.count("\n") == 1 and "--landmarks" in err
    code, _, err = run_cli("slam", "simulate", "--plot", tmp_path / "x.jpg", "--runs", "1", "--steps", "5")
    assert code == 2
    for args, word in ((("--world", "moon"), "--world"), (("--backends", "ekf,nope"), "--backends"),
                       (("--runs", "-1"), "--runs"), (("--seed", "-2"), "--seed"), (("--steps", "1"), "--steps"),
                       (("--landmarks", "10000000"), "--landmarks")):
        code, out, err = run_cli("slam", "simulate", *args)
        assert code == 2 and err.startswith("artmotion: error:") and word in err and "Traceback" not in err


def test_a_door_in_millimetres_says_the_radius_prior_rules_the_circle_out(tmp_path, run_cli):
    """With the default prior (5 cm - 1 m), a door written in millimetres is prismatic with 1.0
    although a circle fits it 20 times as closely: the answer now says why."""
    from artmotion.articulation.synthetic import synthetic_log

    P, _ = synthetic_log("door", seed=1)
    code, out, _ = run_cli("articulation", "fit", _write(tmp_path / "mm.txt", P * 1000))
    assert code == 0 and "note: the track bends on a circle of radius" in out and "--radius-range" in out
    code, out, _ = run_cli("articulation", "fit", tmp_path / "mm.txt", "--radius-range", "50", "1000", "--json")
    assert json.loads(out)["model"] == "revolute" and json.loads(out)["note"] is None
    D, _ = synthetic_log("drawer", seed=1)
    code, out, _ = run_cli("articulation", "fit", _write(tmp_path / "d.txt", D * 1000), "--json")
    assert json.loads(out)["model"] == "prismatic" and json.loads(out)["note"] is None


def test_one_pose_sample_prints_no_none(run_cli, tmp_path):
    """A pose track of one sample has no noise estimate: said in words (it printed "None")."""
    log = tmp_path / "one.csv"
    log.write_text("x,y,z,qx,qy,qz,qw\n0.1,0.2,0.3,0,0,0,1\n")
    code, out, err = run_cli("articulation", "fit", log)
    assert code == 0, err
    assert "None" not in out and "noise std: not estimated" in out
