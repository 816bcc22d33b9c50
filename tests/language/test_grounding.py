"""End to end: dataset, features, models and evaluation; bad input through the CLI."""

import csv
import json
import shutil

import cv2
import numpy as np
import pytest
import soundfile as sf

from artmotion.errors import InputError
from artmotion.language.grounding import dataset as ds

from .test_features import draw, tone

HAVE_ESPEAK = shutil.which("espeak-ng") is not None or shutil.which("espeak") is not None
needs_espeak = pytest.mark.skipif(not HAVE_ESPEAK, reason="espeak-ng not installed (make system-deps installs it)")

SMALL = {  # 4 colours x 4 shapes, 3 examples each
    "circle": (3, 3, 3, 3),
    "rectangle": (3, 3, 3, 3),
    "square": (3, 3, 3, 3),
    "triangle": (3, 3, 3, 3),
}


def test_table_5_2_counts():
    c = ds.counts()
    assert sum(n for *_, n in c) == 156
    per_colour = {col: sum(n for cc, _, n in c if cc == col) for col in ds.COLORS}
    assert per_colour == {"blue": 46, "green": 32, "red": 40, "yellow": 38}


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory):
    if not HAVE_ESPEAK:
        pytest.skip("espeak-ng not installed (make system-deps installs it)")
    out = tmp_path_factory.mktemp("grounding") / "small"
    ds.make_dataset(out, seed=3, table=SMALL)
    return out


def test_12_bit_images_are_read_at_their_depth(small_dataset, tmp_path):
    """A dataset of 12-bit images (16-bit PNGs of values up to 4095) was read by their top 8 bits,
    nearly black (colour 0.05 instead of 0.87): now at the depth the images imply, as pose reads
    its crops, and the report says so."""
    from artmotion.language.grounding.evaluate import load_features

    deep = tmp_path / "deep"
    shutil.copytree(small_dataset, deep)
    for png in (deep / "images").glob("*.png"):
        img = cv2.imread(str(png))
        cv2.imwrite(str(png), img.astype(np.uint16) * 16)
    plain, twelve = load_features(small_dataset), load_features(deep)
    assert plain["depth"] is None and twelve["depth"][0] == 12
    np.testing.assert_allclose(twelve["color"], plain["color"], atol=0.02)


@needs_espeak
def test_dataset_is_deterministic(tmp_path):
    tiny = {"circle": (1, 0, 1, 0)}
    a, b = tmp_path / "a", tmp_path / "b"
    ds.make_dataset(a, seed=5, table=tiny)
    ds.make_dataset(b, seed=5, table=tiny)
    assert (a / "index.csv").read_bytes() == (b / "index.csv").read_bytes()
    rows = list(csv.DictReader(open(a / "index.csv")))
    assert len(rows) == 2 and {r["color"] for r in rows} == {"blue", "red"}
    for r in rows:
        for col in ("image", "speech", "speech_color", "speech_shape"):
            assert (a / r[col]).read_bytes() == (b / r[col]).read_bytes(), col
        y, sr = sf.read(a / r["speech"])
        assert len(y) > 0.2 * sr


@needs_espeak
def test_end_to_end_cli(small_dataset, tmp_path, run_cli):
    out = tmp_path / "eval"
    code, stdout, err = run_cli("grounding", "eval", small_dataset, "--out", out, "--json")
    assert code == 0, err
    res = json.loads(stdout)
    assert set(res) == {"compositional", "paired"}
    for model in res.values():
        for part in ("retrieval", "unseen"):
            assert 0 <= model[part]["color"] <= 1 and 0 <= model[part]["shape"] <= 1
    comp = res["compositional"]
    assert comp["retrieval"]["color"] >= 0.9 and comp["retrieval"]["shape"] >= 0.8, res
    assert comp["unseen"]["color"] >= 0.8 and comp["unseen"]["shape"] >= 0.6, res
    # the thesis's claim: words composed anew are understood by the compositional model only
    assert comp["unseen"]["color"] > res["paired"]["unseen"]["color"], res
    report = json.loads((out / "report.json").read_text())
    assert report["linking"]["H"] == [[1, 0], [0, 1]]  # colour is the first word, shape the second
    assert report["n_examples"] == 48
    for png in report["figures"]:
        img = cv2.imread(str(out / png))
        assert img is not None and img.size > 0
    assert "unseen_confusion.png" in report["figures"] and "unseen_renders.png" in report["figures"]


@needs_espeak
def test_grounder_both_directions(small_dataset):
    from artmotion.language.grounding.evaluate import load_features
    from artmotion.language.grounding.model import Grounder

    F = load_features(small_dataset)
    rows = list(csv.DictReader(open(small_dataset / "index.csv")))
    g = Grounder().fit(F, np.arange(1, len(rows)))
    r = rows[0]
    img = g.speech_files_to_image(small_dataset / r["speech_color"], small_dataset / r["speech_shape"], size=64)
    assert img.shape == (64, 64, 3)
    _, words = g.image_to_speech(small_dataset / r["image"])
    assert words[0] == r["color"]


def test_grounder_refuses_images_and_indices_it_cannot_use(small_dataset):
    """A grey or float image crashed inside OpenCV; an index past the examples inside NumPy."""
    from artmotion.language.grounding.evaluate import load_features
    from artmotion.language.grounding.model import Grounder

    F = load_features(small_dataset)
    n = len(F["colors"])
    for idx in ([0, 1, n + 5], [], [[0, 1]], [0.5, 1.5]):
        with pytest.raises(InputError, match="idx must be the indices"):
            Grounder().fit(F, np.array(idx))
    g = Grounder().fit(F, np.arange(n) > 0)
    for image in (np.zeros((64, 64), np.uint8), np.zeros((64, 64, 3))):
        with pytest.raises(InputError, match="image must be a BGR uint8 image"):
            g.image_to_speech(image)
    from artmotion.io.media import read_image

    first = next(csv.DictReader(open(small_dataset / "index.csv")))["image"]
    assert len(g.image_to_speech(read_image(small_dataset / first))[1]) == 2
    from artmotion.language.grounding.features import visual_features

    with pytest.raises(InputError, match="image must be a BGR uint8 image"):    # (cv2.error inside)
        visual_features(np.zeros((64, 64), np.uint8))


def _write_index(folder, rows):
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / "index.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=ds.INDEX_COLUMNS[:7])
        w.writeheader()
        w.writerows(rows)


def _row(i, **kw):
    r = dict(id=f"{i:03d}", image=f"images/{i}.png", speech=f"speech/{i}_full.wav",
             speech_color=f"speech/{i}_color.wav", speech_shape=f"speech/{i}_shape.wav", color="red", shape="square")
    r.update(kw)
    return r


def _good_files(folder, i, sr=16000):
    (folder / "images").mkdir(parents=True, exist_ok=True)
    (folder / "speech").mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(folder / f"images/{i}.png"), draw("square", 10, 40))
    for part in ("full", "color", "shape"):
        sf.write(folder / f"speech/{i}_{part}.wav", tone(sr), sr)


def _one_line_error(code, err, *needles):
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    for n in needles:
        assert n in err, (n, err)


def test_eval_bad_input(tmp_path, run_cli):
    code, _, err = run_cli("grounding", "eval", tmp_path / "nothing")
    _one_line_error(code, err, "index.csv")

    d = tmp_path / "missing"
    _write_index(d, [_row(0)])
    code, _, err = run_cli("grounding", "eval", d)
    _one_line_error(code, err, "images/0.png", "no such file")

    d = tmp_path / "notaudio"
    _good_files(d, 0)
    (d / "speech/0_color.wav").write_text("hello, I am text")
    _write_index(d, [_row(0)])
    code, _, err = run_cli("grounding", "eval", d)
    _one_line_error(code, err, "0_color.wav", "not a readable audio")

    d = tmp_path / "silent"
    _good_files(d, 0)
    sf.write(d / "speech/0_shape.wav", np.zeros(8000, np.float32), 16000)
    _write_index(d, [_row(0)])
    code, _, err = run_cli("grounding", "eval", d)
    _one_line_error(code, err, "0_shape.wav", "silent")

    d = tmp_path / "noshape"
    _good_files(d, 0)
    cv2.imwrite(str(d / "images/0.png"), ds.table_background(np.random.default_rng(0), 240, 320).astype(np.uint8))
    _write_index(d, [_row(0)])
    code, _, err = run_cli("grounding", "eval", d)
    _one_line_error(code, err, "images/0.png", "no shape found")

    d = tmp_path / "badindex"
    d.mkdir()
    (d / "index.csv").write_text("id,image\n0,a.png\n")
    code, _, err = run_cli("grounding", "eval", d)
    _one_line_error(code, err, "index.csv:1", "lacks columns")

    # labels are checked before any example's features (which take minutes on a whole dataset)
    for name, rows, needle in (("purple", [_row(0), _row(1, color="purple")], "index.csv:3"),
                               ("blob", [_row(0, shape="blob")], "index.csv:2"),
                               ("twice", [_row(0), _row(0)], "appears twice")):
        d = tmp_path / name
        _write_index(d, rows)  # (no images nor speech: they are never read)
        code, _, err = run_cli("grounding", "eval", d)
        _one_line_error(code, err, needle)
    d = tmp_path / "nan"
    d.mkdir()
    (d / "index.csv").write_text(",".join(ds.INDEX_COLUMNS[:8]) + "\n" + ",".join(_row(0).values()) + ",nan\n")
    code, _, err = run_cli("grounding", "eval", d)
    _one_line_error(code, err, "index.csv:2", "rotation")

    d = tmp_path / "toofew"
    for i in range(3):
        _good_files(d, i)
    _write_index(d, [_row(i) for i in range(3)])
    code, _, err = run_cli("grounding", "eval", d)
    _one_line_error(code, err, "too few examples (3)")
    # the index CSV given instead of its folder: the default output folder is beside it, not under it
    code, _, err = run_cli("grounding", "eval", d / "index.csv")
    _one_line_error(code, err, "too few examples (3)")


def test_dataset_without_espeak(tmp_path, run_cli, monkeypatch):
    monkeypatch.setattr(ds.shutil, "which", lambda name: None)
    code, _, err = run_cli("grounding", "dataset", tmp_path / "d")
    _one_line_error(code, err, "espeak-ng is not installed")
    assert not (tmp_path / "d" / "index.csv").exists()


@needs_espeak
def test_speech_on_a_full_disk_is_an_error(tmp_path, monkeypatch):
    """espeak-ng writing a WAV itself exits 0 on a full disk, the speech cut where the room ended
    and a header made to match: the WAV comes through a pipe and is written here, where a full disk
    is an error."""
    import errno
    from pathlib import Path

    from artmotion.errors import InputError
    from artmotion.language.grounding.dataset import speak

    def full(self, data):
        raise OSError(errno.ENOSPC, "No space left on device", str(self))

    with monkeypatch.context() as m:
        m.setattr(Path, "write_bytes", full)
        with pytest.raises(InputError, match="s.wav: cannot write: No space left on device"):
            speak("the red square is above the blue circle", tmp_path / "s.wav", 150)
    assert list(tmp_path.iterdir()) == []
    speak("red square", tmp_path / "ok.wav", 150)
    head = (tmp_path / "ok.wav").read_bytes()
    assert int.from_bytes(head[4:8], "little") + 8 == len(head)      # the sizes filled in


def test_unseen_pair_test_names_the_dataset_and_plain_labels(tmp_path):
    """A smaller but valid dataset: the error named no file and printed np.str_('blue')."""
    from artmotion.errors import InputError
    from artmotion.language.grounding.evaluate import HOLDOUTS, holdout_rounds

    colors = np.array(["blue", "blue", "green", "red"])
    shapes = np.array(["square", "circle", "triangle", "square"])
    with pytest.raises(InputError) as e:
        holdout_rounds(colors, shapes, path=tmp_path / "six.csv")
    msg = str(e.value)
    assert msg.startswith(str(tmp_path / "six.csv")) and "np.str_" not in msg and "leaves no training example" in msg
    with pytest.raises(InputError, match="no colour–shape pair of the unseen-pair test is in the dataset"):
        holdout_rounds(["red"] * 3, ["circle"] * 3, holdouts=[[("blue", "square")]], path=tmp_path / "x.csv")
    full = [(c, s) for c in ds.COLORS for s in ds.SHAPES] * 2
    rounds = holdout_rounds([c for c, _ in full], [s for _, s in full], HOLDOUTS)
    assert len(rounds) == len(HOLDOUTS) and all(held.sum() == 2 * len(p) for p, held in rounds)


@needs_espeak
def test_eval_and_dataset_never_remove_the_users_files(small_dataset, tmp_path, run_cli):
    """An earlier report is replaced only when its folder holds its outputs alone (a PNG of the
    user's there went with it on the second run), never inside the dataset; a dataset in the same
    layout that this command did not make (a user's recordings) is never replaced."""
    figs = tmp_path / "figs"
    figs.mkdir()
    (figs / "my_plot.png").write_bytes(b"theirs")
    assert run_cli("grounding", "eval", small_dataset, "--out", figs)[0] == 0
    code, _, err = run_cli("grounding", "eval", small_dataset, "--out", figs)
    assert code == 2 and err.count("\n") == 1 and (figs / "my_plot.png").read_bytes() == b"theirs", err
    images = sorted(p.name for p in (small_dataset / "images").iterdir())
    code, _, err = run_cli("grounding", "eval", small_dataset, "--out", small_dataset / "images")
    assert code == 2 and "inside the input folder" in err, err
    assert sorted(p.name for p in (small_dataset / "images").iterdir()) == images
    mine = tmp_path / "mine"
    for sub in ("images", "speech"):
        (mine / sub).mkdir(parents=True)
    (mine / "images" / "my_recording.png").write_bytes(b"theirs")
    (mine / "speech" / "my_voice.wav").write_bytes(b"theirs")
    (mine / "index.csv").write_text("id,image\n")
    code, _, err = run_cli("grounding", "dataset", mine)
    assert code == 2 and err.count("\n") == 1, err
    assert (mine / "images" / "my_recording.png").read_bytes() == b"theirs"
    assert (mine / "speech" / "my_voice.wav").read_bytes() == b"theirs"
    again = tmp_path / "again"                  # a dataset it made is made anew in place
    for _ in range(2):
        ds.make_dataset(again, seed=5, table={"circle": (1, 0, 1, 0)})
    assert json.loads((again / ds.MARKER).read_text())["examples"] == 2
    (again / "images" / "my_notes.txt").write_text("mine")   # a file of the user's put in it: kept
    with pytest.raises(InputError, match="not only this command's earlier outputs"):
        ds.make_dataset(again, seed=5, table={"circle": (1, 0, 1, 0)})
    assert (again / "images" / "my_notes.txt").read_text() == "mine"
