"""Property-based fuzzing of every command that reads a file (issue 13).

Each test takes a small valid input (``_inputs.py``), damages it the way a disk, a network copy
or a hand edit does — truncation, random bytes, NaN/inf/huge/negative numbers, values of the
wrong type, empty files — runs the command in this process and asserts what every command owes
its user: no traceback; exit status 0 (the damage left a valid input) or 2 (bad input) with
exactly one line ``artmotion: error: ...`` on stderr that names no temporary file; and no output,
temporary or partial file left behind by a failed command. Damage that can never leave a valid
input (an empty file, a NaN where every value is checked) must give exit 2.

``ARTMOTION_FUZZ_EXAMPLES`` sets the number of examples per test (default 40: the whole suite runs
in about half a minute on two cores; 800 examples each found nothing more, in four minutes).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import shutil
import tempfile
from pathlib import Path

import _inputs as inp
import numpy as np
import pytest
from _inputs import call, leftovers
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

FUZZ = settings(max_examples=int(os.environ.get("ARTMOTION_FUZZ_EXAMPLES", "40")), deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

#: number texts that are never a valid value of anything (NaN, infinities, huge, not numbers)
BAD_NUMBERS = ["nan", "NaN", "inf", "-inf", "Infinity", "1e308", "-1e308", "1e999", "-1", "-0.5", str(2**70),
               str(-2**70), "1.5", "abc", "", "0x1F", "1,5", " "]
#: the same as JSON values, with wrong types
BAD_JSON = st.one_of(st.none(), st.booleans(), st.integers(-2**80, 2**80),
                     st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=6),
                     st.lists(st.one_of(st.integers(-5, 5), st.floats(), st.text(max_size=2)), max_size=3),
                     st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))


# -- the pristine inputs, made once ---------------------------------------------------------------


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    import cv2
    import soundfile as sf

    from artmotion.language.grounding.dataset import render_example

    root = tmp_path_factory.mktemp("pristine")
    inp.sequence(root / "seq")
    inp.video(root / "video.avi")
    (root / "det.txt").write_text("\n".join(inp.det_rows()) + "\n")
    (root / "gt.txt").write_text("\n".join(inp.gt_rows()) + "\n")
    (root / "res.txt").write_text("\n".join(inp.gt_rows()) + "\n")
    (root / "events.jsonl").write_text("".join(json.dumps(e) + "\n" for e in inp.EVENTS))
    (root / "traj.txt").write_text(inp.trajectory())
    (root / "poses.txt").write_text("".join(f"{k} {0.1 * k:.2f} 0 0 0 0 {np.sin(0.05 * k):.6f} {np.cos(0.05 * k):.6f}\n"
                                            for k in range(12)))
    inp.pose_model(root / "model.npz")
    (root / "PRED.csv").write_text("image,opening,opening_std\n" + "".join(
        f"{k:06d}.png,{30 + 20 * np.sin(k / 2):.3f},1.0\n" for k in range(1, 13)))
    inp.run_folder(root / "run")
    assert call("index", "add", root / "run", "--db", root / "index.sqlite")[0] == 0
    ds = root / "grounding"
    (ds / "images").mkdir(parents=True)
    (ds / "speech").mkdir()
    t = np.arange(8000) / 16000
    rows = []
    rng = np.random.default_rng(0)
    for i, (colour, shape) in enumerate((("red", "square"), ("blue", "circle"))):
        img, _ = render_example(rng, colour, shape)
        cv2.imwrite(str(ds / "images" / f"{i}.png"), img)
        for part in ("full", "color", "shape"):
            sf.write(ds / "speech" / f"{i}_{part}.wav",
                     (0.3 * np.sin(np.pi * t / 0.5) * np.sin(2 * np.pi * (300 + 100 * i) * t)).astype(np.float32),
                     16000)
        rows.append(f"{i:03d},images/{i}.png,speech/{i}_full.wav,speech/{i}_color.wav,speech/{i}_shape.wav,"
                    f"{colour},{shape}")
    (ds / "index.csv").write_text("id,image,speech,speech_color,speech_shape,color,shape\n" + "\n".join(rows) + "\n")
    return root


class Case:
    """A scratch folder with copies of pristine inputs; removed afterwards."""

    def __init__(self, base: Path, *names: str):
        self.dir = Path(tempfile.mkdtemp(prefix="case-", dir=base.parent))
        for name in names:
            src = base / name
            (shutil.copytree if src.is_dir() else shutil.copy2)(src, self.dir / name)

    def __enter__(self):
        return self.dir

    def __exit__(self, *exc):
        shutil.rmtree(self.dir, ignore_errors=True)


def check(result, work: Path, outputs=(), must_fail: bool = False) -> None:
    """What every command owes its user (see the module doc)."""
    code, out, err = result
    assert "Traceback" not in out + err, err
    assert code in (0, 2), f"exit {code}: {err}"
    if must_fail:
        assert code == 2, f"damaged input accepted:\n{out}"
    if code == 2:
        inp.assert_one_line_error(code, err)
        for o in outputs:
            assert not Path(o).exists(), f"{o} written by a failed command"
    assert not leftovers(work), leftovers(work)


# -- damage ----------------------------------------------------------------------------------------


@st.composite
def damaged_bytes(draw, data: bytes):
    """``data`` truncated, overwritten in places, with bytes inserted, or replaced by random bytes."""
    n = len(data)
    how = draw(st.sampled_from(["truncate", "overwrite", "insert", "random"]))
    if how == "truncate":
        return data[: draw(st.integers(0, n - 1))]
    if how == "overwrite":
        b = bytearray(data)
        start = draw(st.integers(0, n - 1))
        patch = draw(st.binary(min_size=1, max_size=64))
        b[start:start + len(patch)] = patch
        return bytes(b[:n])
    if how == "insert":
        k = draw(st.integers(0, n))
        return data[:k] + draw(st.binary(min_size=1, max_size=64)) + data[k:]
    return draw(st.binary(max_size=512))


_NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


@st.composite
def damaged_numbers(draw, text: str, bad=BAD_NUMBERS):
    """``text`` with one to three of its numbers replaced by a bad number text."""
    spans = [m.span() for m in _NUMBER.finditer(text)]
    picks = sorted(set(draw(st.lists(st.integers(0, len(spans) - 1), min_size=1, max_size=3))), reverse=True)
    for k in picks:
        a, b = spans[k]
        text = text[:a] + draw(st.sampled_from(bad)) + text[b:]
    return text


@st.composite
def damaged_text(draw, text: str):
    """Numbers replaced, lines dropped or duplicated or shuffled, a junk line, or the bytes damaged."""
    how = draw(st.sampled_from(["numbers", "numbers", "lines", "junk", "bytes"]))
    if how == "numbers":
        return draw(damaged_numbers(text)).encode()
    lines = text.splitlines(keepends=True)
    if how == "lines":
        k = draw(st.integers(0, len(lines) - 1))
        op = draw(st.sampled_from(["drop", "twice", "swap"]))
        if op == "drop":
            del lines[k]
        elif op == "twice":
            lines.insert(k, lines[k])
        else:
            j = draw(st.integers(0, len(lines) - 1))
            lines[k], lines[j] = lines[j], lines[k]
        return "".join(lines).encode()
    if how == "junk":
        k = draw(st.integers(0, len(lines)))
        lines.insert(k, draw(st.text(max_size=40)) + "\n")
        return "".join(lines).encode("utf-8", "surrogatepass")
    return draw(damaged_bytes(text.encode()))


def non_finite_field(text: bytes) -> bool:
    """Whether a line of ``text`` that is not a comment has a field that reads as NaN or infinity
    (every reader of numeric text refuses such a line)."""
    for line in text.decode("utf-8", "replace").splitlines():
        if line.strip().startswith("#"):
            continue
        for tok in re.split(r"[,\s;]+", line.strip()):
            try:
                if not math.isfinite(float(tok)):
                    return True
            except ValueError:
                continue
    return False


def _paths(obj, prefix=()):
    """Every key path into a JSON value."""
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _paths(v, prefix + (i,))


@st.composite
def damaged_json(draw, obj):
    """``obj`` with one value replaced by a bad one (wrong type, NaN, huge) or one key removed."""
    obj = json.loads(json.dumps(obj))
    paths = [p for p in _paths(obj) if p]
    path = draw(st.sampled_from(paths))
    parent = obj
    for k in path[:-1]:
        parent = parent[k]
    if draw(st.booleans()) and isinstance(parent, dict):
        del parent[path[-1]]
    else:
        parent[path[-1]] = draw(BAD_JSON)
    return obj


# -- images and video ------------------------------------------------------------------------------


@FUZZ
@given(data=st.data())
def test_fuzz_image_sequence(base, data):
    with Case(base, "seq") as work:
        victim = work / "seq" / "img1" / f"{data.draw(st.integers(1, inp.N)):06d}.jpg"
        victim.write_bytes(data.draw(damaged_bytes(victim.read_bytes())))
        check(call("track", work / "seq", "--out", work / "res.txt"), work, [work / "res.txt"])


@FUZZ
@given(data=st.data())
def test_fuzz_crop_image(base, data):
    with Case(base, "model-crops") as work:
        victim = sorted((work / "model-crops").iterdir())[data.draw(st.integers(0, 11))]
        victim.write_bytes(data.draw(damaged_bytes(victim.read_bytes())))
        out = work / "pred.csv"
        check(call("pose", "predict", base / "model.npz", work / "model-crops", "--out", out), work, [out])


@FUZZ
@given(data=st.data())
def test_fuzz_video(base, data):
    with Case(base, "video.avi") as work:
        video = work / "video.avi"
        video.write_bytes(data.draw(damaged_bytes(video.read_bytes())))
        out = work / "res.txt"
        check(call("track", video, "--det", base / "det.txt", "--out", out), work, [out])


# -- MOTChallenge text, seqinfo.ini ----------------------------------------------------------------


@FUZZ
@given(data=st.data(), which=st.sampled_from(["det", "gt", "res"]))
def test_fuzz_mot_text(base, data, which):
    with Case(base, "seq") as work:
        name = {"det": "det.txt", "gt": "gt.txt", "res": "res.txt"}[which]
        bad = work / name
        damage = data.draw(damaged_text((base / name).read_text()))
        bad.write_bytes(damage)
        nan = non_finite_field(damage)
        if which == "det":
            out = work / "res.txt"
            check(call("track", work / "seq", "--det", bad, "--out", out), work, [out], must_fail=nan)
        elif which == "gt":
            check(call("eval", bad, base / "res.txt"), work, must_fail=nan or not damage.strip())
        else:
            check(call("eval", base / "gt.txt", bad), work, must_fail=nan)
            check(call("describe", bad), work, must_fail=nan or not damage.strip())


SEQINFO_BAD = st.sampled_from(BAD_NUMBERS + ["../../etc", "img1/../img1", ".png", "x" * 300, "\x00"])


@FUZZ
@given(key=st.sampled_from(["frameRate", "seqLength", "imDir", "imExt", "name", "[Sequence]", "imWidth"]),
       value=SEQINFO_BAD, drop=st.booleans())
def test_fuzz_seqinfo(base, key, value, drop):
    with Case(base, "seq") as work:
        ini = work / "seq" / "seqinfo.ini"
        lines = ini.read_text().splitlines()
        k = next(i for i, line in enumerate(lines) if line.startswith(key))
        if drop:
            del lines[k]
        else:
            lines[k] = f"{key}={value}" if key != "[Sequence]" else value
        ini.write_text("\n".join(lines) + "\n", encoding="utf-8", errors="surrogateescape")
        out = work / "res.txt"
        must = not drop and key in ("frameRate", "seqLength", "imWidth") and not (key == "frameRate" and value == "1.5")
        check(call("track", work / "seq", "--out", out), work, [out], must_fail=must)


# -- CSV -------------------------------------------------------------------------------------------


@FUZZ
@given(data=st.data())
def test_fuzz_labels_csv(base, data):
    with Case(base, "model-labels.csv") as work:
        labels = work / "model-labels.csv"
        damage = data.draw(damaged_text(labels.read_text()))
        labels.write_bytes(damage)
        model = work / "m.npz"
        nan = non_finite_field(damage)
        check(call("pose", "train", base / "model-crops", labels, "--model", model, "--components", 4),
              work, [model], must_fail=nan or not damage.strip())


@FUZZ
@given(data=st.data())
def test_fuzz_pose_predictions_csv(base, data):
    with Case(base, "PRED.csv") as work:
        pred = work / "PRED.csv"
        pred.write_bytes(data.draw(damaged_text(pred.read_text())))
        check(call("describe", base / "res.txt", "--pose", pred), work)


@FUZZ
@given(data=st.data())
def test_fuzz_grounding_index_csv(base, data):
    with Case(base, "grounding") as work:
        index = work / "grounding" / "index.csv"
        index.write_bytes(data.draw(damaged_text(index.read_text())))
        # two examples are too few to evaluate: every run ends in an error, after reading everything
        check(call("grounding", "eval", work / "grounding", "--out", work / "eval"), work, [work / "eval"],
              must_fail=True)


# -- JSON: events, run.json ------------------------------------------------------------------------


@FUZZ
@given(data=st.data(), raw=st.booleans())
def test_fuzz_events(base, data, raw):
    with Case(base, "events.jsonl") as work:
        ev = work / "events.jsonl"
        if raw:
            ev.write_bytes(data.draw(damaged_text(ev.read_text())))
        else:
            events = data.draw(damaged_json(inp.EVENTS))
            ev.write_text("".join(json.dumps(e) + "\n" for e in events) if isinstance(events, list)
                          else json.dumps(events) + "\n")
        check(call("describe", base / "res.txt", "--events", ev), work)


@FUZZ
@given(data=st.data(), raw=st.booleans())
def test_fuzz_run_manifest(base, data, raw):
    with Case(base, "run") as work:
        manifest = work / "run" / "run.json"
        if raw:
            manifest.write_bytes(data.draw(damaged_bytes(manifest.read_bytes())))
        else:
            manifest.write_text(json.dumps(data.draw(damaged_json(inp.manifest()))))
        db = work / "index.sqlite"
        result = call("index", "add", work / "run", "--db", db)
        check(result, work, [db])
        if result[0] == 0:          # what was accepted can be listed and searched
            check(call("index", "list", "--db", db), work)
            found = call("search", "person exits left", "--db", db)
            if found[0] == 1:       # search's "no match" (exit 1, like grep's)
                assert found[1] == "no match\n" and found[2] == "", found
            else:
                check(found, work)


# -- pose models -----------------------------------------------------------------------------------


@st.composite
def damaged_arrays(draw, arrays: dict):
    arrays = dict(arrays)
    key = draw(st.sampled_from(sorted(arrays)))
    a = arrays[key]
    how = draw(st.sampled_from(["nan", "inf", "negate", "huge", "truncate", "transpose", "text", "scalar", "empty",
                                "drop", "int", "bool"]))
    if how == "drop":
        del arrays[key]
        return arrays
    numeric = np.issubdtype(a.dtype, np.number)
    if how in ("nan", "inf", "huge", "negate") and numeric:
        f = a.astype(float)
        with np.errstate(all="ignore"):
            arrays[key] = {"nan": f * np.nan, "inf": f * np.inf, "huge": f * 1e308 + 1e308, "negate": -f - 1}[how]
    elif how == "truncate" and a.ndim:
        arrays[key] = a[: draw(st.integers(0, max(0, len(a) - 1)))]
    elif how == "transpose" and a.ndim == 2:
        arrays[key] = a.T
    elif how == "text":
        arrays[key] = a.astype(str)
    elif how == "scalar":
        arrays[key] = np.array(draw(st.one_of(st.integers(-10, 10**6), st.floats(allow_nan=True), st.text(max_size=4))))
    elif how == "empty":
        arrays[key] = np.zeros((0,) * max(1, a.ndim))
    elif how == "int" and numeric:
        arrays[key] = a.astype(np.int64)
    elif how == "bool":
        arrays[key] = a.astype(bool) if numeric else a
    return arrays


@FUZZ
@given(data=st.data(), raw=st.booleans())
def test_fuzz_pose_model(base, data, raw):
    with Case(base) as work:
        model = work / "model.npz"
        if raw:
            model.write_bytes(data.draw(damaged_bytes((base / "model.npz").read_bytes())))
        else:
            with np.load(base / "model.npz") as z:
                np.savez(model, **data.draw(damaged_arrays({k: z[k] for k in z.files})))
        out = work / "pred.csv"
        result = call("pose", "predict", model, base / "model-crops", "--out", out)
        check(result, work, [out])
        if result[0] == 0:          # an accepted model predicts finite numbers
            values = np.loadtxt(out, delimiter=",", skiprows=1, usecols=range(1, 5))
            assert np.all(np.isfinite(values))


# -- the SQLite index ------------------------------------------------------------------------------


@FUZZ
@given(data=st.data(), command=st.sampled_from(["list", "search", "add"]))
def test_fuzz_index(base, data, command):
    with Case(base, "run") as work:
        db = work / "index.sqlite"
        db.write_bytes(data.draw(damaged_bytes((base / "index.sqlite").read_bytes())))
        before = hashlib.sha256(db.read_bytes()).hexdigest()
        args = {"list": ("index", "list"), "search": ("search", "person exits"),
                "add": ("index", "add", work / "run")}[command]
        result = call(*args, "--db", db)
        check(result, work)
        if command != "add" or result[0] == 2:      # never written into, unless a run was added to it
            assert hashlib.sha256(db.read_bytes()).hexdigest() == before


# -- articulation logs -----------------------------------------------------------------------------


@FUZZ
@given(data=st.data(), which=st.sampled_from(["traj.txt", "poses.txt"]))
def test_fuzz_trajectory(base, data, which):
    with Case(base, which) as work:
        traj = work / which
        damage = data.draw(damaged_text(traj.read_text()))
        traj.write_bytes(damage)
        result = call("articulation", "fit", traj, "--json")
        check(result, work, must_fail=not damage.strip() or non_finite_field(damage))
        if result[0] == 0:          # valid JSON, no NaN in it
            json.loads(result[1], parse_constant=lambda c: pytest.fail(f"{c} in the JSON output"))


# -- numbers on the command line -------------------------------------------------------------------

INT_BAD = st.one_of(st.sampled_from(BAD_NUMBERS), st.integers(max_value=-1).map(str),
                    st.integers(min_value=2**40).map(str))
FLOAT_ANY = st.one_of(st.sampled_from(BAD_NUMBERS), st.floats().map(repr), st.integers(-10**12, 10**12).map(str))

# (arguments, option, values): the arguments make every command cheap whatever the option's value
OPTIONS = [
    (["track", "{seq}", "--out", "{work}/res.txt"], "--fps", FLOAT_ANY),
    (["eval", "{gt}", "{res}"], "--iou", FLOAT_ANY),
    (["describe", "{res}"], "--fps", FLOAT_ANY),
    (["describe", "{res}", "--pose", "{pred}"], "--open-above", FLOAT_ANY),
    (["describe", "{res}", "--pose", "{pred}"], "--close-below", FLOAT_ANY),
    (["describe", "{res}", "--pose", "{pred}"], "--pose-track", INT_BAD),
    (["describe", "{res}"], "--size", st.tuples(FLOAT_ANY, FLOAT_ANY).map("x".join)),
    (["articulation", "fit", "{traj}"], "--threshold", FLOAT_ANY),
    (["articulation", "fit", "{traj}"], "--noise-floor", FLOAT_ANY),
    (["articulation", "fit", "{traj}"], "--max-radius", FLOAT_ANY),
    (["articulation", "fit", "{traj}"], "--min-samples", INT_BAD),
    (["articulation", "fit", "{traj}"], "--order", INT_BAD),
    (["slam", "simulate", "--runs", "1", "--steps", "3", "--landmarks", "3"], "--seed", INT_BAD),
    (["slam", "simulate", "--runs", "1", "--steps", "3"], "--landmarks", INT_BAD),
    (["slam", "simulate", "--runs", "1", "--landmarks", "3"], "--steps", INT_BAD),
    (["slam", "simulate", "--steps", "3", "--landmarks", "3"], "--runs", INT_BAD),
    (["slam", "simulate", "--runs", "1", "--steps", "3", "--landmarks", "3"], "--prismatic", INT_BAD),
    (["pose", "render", "{work}/r", "--no-frames"], "--poses", INT_BAD),
    (["pose", "render", "{work}/r", "--poses", "2", "--no-frames"], "--seed", INT_BAD),
    (["pose", "train", "{crops}", "{labels}", "--model", "{work}/m.npz"], "--seed", INT_BAD),
    (["pose", "train", "{crops}", "{labels}", "--model", "{work}/m.npz"], "--components", INT_BAD),
    (["pose", "train", "{crops}", "{labels}", "--model", "{work}/m.npz"], "--inducing", INT_BAD),
    (["pose", "eval", "{crops}", "{labels}", "--feature", "hog"], "--folds", INT_BAD),
    (["grounding", "dataset", "{work}/g"], "--seed", INT_BAD),
    (["grounding", "eval", "{grounding}"], "--seed", INT_BAD),
    (["search", "person", "--db", "{db}"], "--limit", INT_BAD),
    (["batch", "{work}/none"], "--workers", INT_BAD),
]


@FUZZ
@given(data=st.data(), k=st.integers(0, len(OPTIONS) - 1))
def test_fuzz_numeric_options(base, data, k):
    args, option, values = OPTIONS[k]
    value = data.draw(values)
    with Case(base) as work:
        where = {"seq": base / "seq", "gt": base / "gt.txt", "res": base / "res.txt", "pred": base / "PRED.csv",
                 "traj": base / "traj.txt", "crops": base / "model-crops", "labels": base / "model-labels.csv",
                 "grounding": base / "grounding", "db": base / "index.sqlite", "work": work}
        result = call(*[a.format(**where) for a in args], option, value)
        written = [work / "res.txt", work / "r", work / "m.npz", work / "g"]
        check(result, work, written, must_fail=value.strip().lower() in ("nan", "inf", "-inf", "infinity", "abc", ""))
        if result[0] == 0 and result[1].lstrip().startswith(("{", "[")):
            json.loads(result[1], parse_constant=lambda c: pytest.fail(f"{c} in the JSON output"))
