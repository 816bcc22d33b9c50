import json
import os
import shutil

import cv2
import numpy as np
import pytest
from conftest import shared_path

from artmotion.pose.data import read_labels
from artmotion.pose.evaluate import orientation_error
from artmotion.pose.render import write_dataset
from artmotion.tracking.instruments.annotations import read_tools_csv

N = 240


@pytest.fixture(scope="module")
def split(tmp_path_factory):
    """Rendered crops: every 4th frame held out for testing, the rest for training."""
    root = tmp_path_factory.mktemp("pose")
    write_dataset(root / "all", N, seed=5, frames=False)
    names, imgs, Y = read_labels(root / "all" / "labels.csv")
    for part in ("train", "test"):
        (root / part).mkdir()
    rows = {"train": [], "test": []}
    for i, (img, y) in enumerate(zip(imgs, Y)):
        part = "test" if i % 4 == 2 else "train"
        shutil.copy(root / "all" / "crops" / img, root / part / img)
        rows[part].append(img + "," + ",".join(f"{v:.4f}" for v in y))
    for part in rows:
        (root / f"{part}.csv").write_text("image," + ",".join(names) + "\n" + "\n".join(rows[part]) + "\n")
    return root


def test_render_is_deterministic(tmp_path, run_cli):
    for d in ("a", "b"):
        code, out, err = run_cli("pose", "render", tmp_path / d, "--poses", 3, "--seed", 7)
        assert code == 0, err
    assert (tmp_path / "a" / "labels.csv").read_text() == (tmp_path / "b" / "labels.csv").read_text()
    for name in ("000001.png", "000003.png"):
        a = cv2.imread(str(tmp_path / "a" / "crops" / name))
        b = cv2.imread(str(tmp_path / "b" / "crops" / name))
        assert np.array_equal(a, b)
    assert len(list((tmp_path / "a" / "frames").glob("*.jpg"))) == 3
    assert (tmp_path / "a" / "boxes.csv").read_text().startswith("image,x,y,w,h,frame_w,frame_h\n")
    run_cli("pose", "render", tmp_path / "c", "--poses", 3, "--seed", 8, "--no-frames")
    assert (tmp_path / "a" / "labels.csv").read_text() != (tmp_path / "c" / "labels.csv").read_text()
    # --dark: the same motion and scene as the normal-light render of that seed, in low light
    run_cli("pose", "render", tmp_path / "d", "--poses", 3, "--seed", 7, "--dark", "--no-frames")
    assert (tmp_path / "a" / "labels.csv").read_text() == (tmp_path / "d" / "labels.csv").read_text()
    # --style alt: the same motion (labels) in another look; an unknown style is one line
    run_cli("pose", "render", tmp_path / "e", "--poses", 3, "--seed", 7, "--style", "alt", "--no-frames")
    assert (tmp_path / "a" / "labels.csv").read_text() == (tmp_path / "e" / "labels.csv").read_text()
    alt = cv2.imread(str(tmp_path / "e" / "crops" / "000002.png")).astype(float)
    usual = cv2.imread(str(tmp_path / "a" / "crops" / "000002.png")).astype(float)
    assert alt.shape == usual.shape and np.abs(alt - usual).mean(axis=(0, 1))[1] > 20  # yellow, not pink: more green
    run_cli("pose", "render", tmp_path / "g", "--poses", 3, "--seed", 7, "--style", "random", "--no-frames")
    assert (tmp_path / "a" / "labels.csv").read_text() == (tmp_path / "g" / "labels.csv").read_text()
    rand = cv2.imread(str(tmp_path / "g" / "crops" / "000002.png")).astype(float)
    assert np.abs(rand - usual).mean() > 10 and np.abs(rand - alt).mean() > 10
    code, _, err = run_cli("pose", "render", tmp_path / "f", "--poses", 3, "--style", "gold")
    assert code == 2 and "unknown style" in err and not (tmp_path / "f").exists()
    light = cv2.imread(str(tmp_path / "a" / "crops" / "000002.png")).astype(float)
    dark = cv2.imread(str(tmp_path / "d" / "crops" / "000002.png")).astype(float)
    assert dark.shape == light.shape and dark.mean() < 0.45 * light.mean()


def test_eval_tables_on_unseen_sequences(split, run_cli, tmp_path):
    """``pose eval``: cross-validation, 3σ coverage, unseen normal and dark sequences and their ratio."""
    for name, extra in (("light", []), ("dark", ["--dark"])):
        code, _, err = run_cli("pose", "render", tmp_path / name, "--poses", 40, "--seed", 9, "--no-frames", *extra)
        assert code == 0, err
    code, out, err = run_cli("pose", "eval", split / "train", split / "train.csv", "--feature", "hog", "--folds", 3,
                             "--test-images", tmp_path / "light" / "crops", "--test-labels", tmp_path / "light" / "labels.csv",
                             "--dark-images", tmp_path / "dark" / "crops", "--dark-labels", tmp_path / "dark" / "labels.csv",
                             "--out", tmp_path / "ev")
    assert code == 0, err
    res = json.loads((tmp_path / "ev" / "eval.json").read_text())["hog"]
    for key in ("orientation", "opening", "test opening", "dark opening", "dark opening filtered", "all in 3sd"):
        assert np.isfinite(res[key]), key
    assert res["opening"] < 20 and res["orientation"] < 10  # far below chance on rendered crops
    assert "Dark / normal light" in out and "random folds" in out
    assert (tmp_path / "ev" / "dark_hog_filtered.csv").exists() and (tmp_path / "ev" / "cv_hog.csv").exists()
    # random folds: the out-of-fold predictions in time order are filtered as one sequence
    _, _, raw = read_labels(tmp_path / "ev" / "cv_hog.csv")
    _, _, filt = read_labels(tmp_path / "ev" / "cv_hog_filtered.csv")
    jitter = lambda P: np.abs(np.diff(P[:, 0::2], axis=0)).mean()  # noqa: E731
    assert np.isfinite(res["opening filtered"]) and jitter(filt) < 0.8 * jitter(raw)
    code, _, err = run_cli("pose", "eval", split / "train", split / "train.csv", "--dark-images", tmp_path / "dark" / "crops")
    assert code == 2 and "go together" in err


def test_train_predict_end_to_end(split, run_cli, tmp_path):
    model = tmp_path / "m.npz"
    code, out, err = run_cli("pose", "train", split / "train", split / "train.csv", "--model", model)
    assert code == 0, err
    assert "trained" in out
    pred = tmp_path / "pred.csv"
    code, out, err = run_cli("pose", "predict", model, split / "test", "--out", pred)
    assert code == 0, err
    names, imgs, P = read_labels(pred)
    assert names == ["yaw", "yaw_std", "pitch", "pitch_std", "roll", "roll_std", "opening", "opening_std"]
    tnames, timgs, Y = read_labels(split / "test.csv")
    assert imgs == timgs
    mean, std = P[:, 0::2], P[:, 1::2]
    assert np.all(std > 0)
    opening_err = np.abs(mean[:, 3] - Y[:, 3]).mean()
    orient_err = orientation_error(Y[:, :3], mean[:, :3]).mean()
    baseline = np.abs(Y[:, 3] - Y[:, 3].mean()).mean()
    assert opening_err < 10.0 and opening_err < 0.4 * baseline, (opening_err, baseline)
    assert orient_err < 8.0
    assert np.mean(np.abs(mean - Y) <= 3 * std) > 0.85
    code, out, err = run_cli("pose", "predict", model, split / "test", "--out", tmp_path / "s.csv", "--smooth")
    assert code == 0, err
    _, _, S = read_labels(tmp_path / "s.csv")
    assert not np.allclose(S[:, 0::2], mean)
    # crops unlike the training crops (real instruments) get a note (the domain test needs at least
    # 100 crops); the training crops themselves do not
    real = tmp_path / "real"
    real.mkdir()
    root = shared_path("surgical", "lap-tools")
    heads = read_tools_csv(root / "tools.csv")
    for f in sorted(heads)[:80]:
        img = cv2.imread(str(root / "frames" / f"{f:06d}.png"))
        for j, (x, y, s, _a) in enumerate(heads[f]):
            x0, y0 = int(max(0, x - s / 2)), int(max(0, y - s / 2))
            cv2.imwrite(str(real / f"{f}_{j}.png"), img[y0:int(y + s / 2), x0:int(x + s / 2)])
    code, out, err = run_cli("pose", "predict", model, real, "--out", tmp_path / "n.csv")
    assert code == 0 and "unlike the model's training crops" in err, (out, err)
    code, out, err = run_cli("pose", "predict", model, split / "train", "--out", tmp_path / "t.csv")
    assert code == 0 and "unlike" not in out, out


def test_python_api_lbp_and_model_roundtrip(split, tmp_path):
    from artmotion.pose.data import load_labelled
    from artmotion.pose.model import PoseRegressor

    from artmotion.errors import InputError

    names, _, imgs, Y = load_labelled(split / "train", split / "train.csv")
    # the variance from 20 of the 80 inducing inputs: kept by save/load
    reg = PoseRegressor(feature="lbp", method="sparse", n_inducing=80, n_inducing_var=20).fit(imgs, Y, names)
    assert len(reg.gp_.var_inducing) == 20 and reg.gp_.M[0].shape == (20, 20)
    m, s = reg.predict(imgs[:10], return_std=True)
    reg.save(tmp_path / "lbp.npz")
    back = PoseRegressor.load(tmp_path / "lbp.npz")
    m2, s2 = back.predict(imgs[:10], return_std=True)
    np.testing.assert_allclose(m, m2, atol=1e-6)
    np.testing.assert_allclose(s, s2, atol=1e-6)
    assert back.feature == "lbp" and back.names_ == names and back.n_inducing_var == 20
    with np.load(tmp_path / "lbp.npz") as z:
        d = dict(z)
    d["var_inducing"] = np.array([0, 0, 5])
    np.savez(tmp_path / "bad.npz", **d)
    with pytest.raises(InputError, match="var_inducing"):
        PoseRegressor.load(tmp_path / "bad.npz")
    del d["var_inducing"]        # a file from before: the variance from every inducing input
    np.savez(tmp_path / "old.npz", **d)
    old = PoseRegressor.load(tmp_path / "old.npz")
    assert old.gp_.var_inducing is None and old.n_inducing_var is None
    np.testing.assert_allclose(old.predict(imgs[:10]), m, atol=1e-6)


def test_default_model_pca_exact_roundtrip(split, tmp_path):
    """The default regressor (HOG, PCA, exact GP mean, local variance) survives save/load."""
    from artmotion.errors import InputError
    from artmotion.pose.data import load_labelled
    from artmotion.pose.model import PoseRegressor

    names, _, imgs, Y = load_labelled(split / "train", split / "train.csv")
    reg = PoseRegressor(n_components=16).fit(imgs, Y, names)
    assert reg.gp_.kind == "exact" and reg.pca_components_.shape == (16, 1488)
    m, s = reg.predict(imgs[:10], return_std=True)
    reg.save(tmp_path / "hog.npz")
    back = PoseRegressor.load(tmp_path / "hog.npz")
    assert back.n_components == 16 and back.neighbours == reg.neighbours
    m2, s2 = back.predict(imgs[:10], return_std=True)
    np.testing.assert_allclose(m, m2, atol=1e-4)
    np.testing.assert_allclose(s, s2, rtol=1e-4)
    # the filter tuned on the calibration rows (tune_filter) is kept; a file from before has none
    assert np.all(reg.smooth_std_ >= 1) and np.all(reg.filter_std_ >= 1)
    for a, b in ((reg.accel_var_, back.accel_var_), (reg.filter_std_, back.filter_std_),
                 (reg.smooth_std_, back.smooth_std_)):
        np.testing.assert_allclose(a, b)
    np.testing.assert_allclose(reg.make_filter().smooth(m, s), back.make_filter().smooth(m2, s2), rtol=1e-3)
    with np.load(tmp_path / "hog.npz") as z:
        d = dict(z)
    d["smooth_std"] = np.full(len(names), 0.5)
    np.savez(tmp_path / "bad.npz", **d)
    with pytest.raises(InputError, match="smooth_std"):
        PoseRegressor.load(tmp_path / "bad.npz")
    del d["smooth_std"], d["filter_std"]
    np.savez(tmp_path / "old.npz", **d)
    old = PoseRegressor.load(tmp_path / "old.npz")
    assert np.all(old.smooth_std_ == 1) and np.all(old.filter_std_ == 1)
    # angle names whose predictions' header repeats a column ('image'; 'yaw' beside 'yaw_std'): the
    # file predict wrote could not be read back; refused on load as train refuses such labels
    k = len(names)
    for clash in (["image", *names[1:]], ["yaw_std", "yaw", *[f"a{i}" for i in range(k - 2)]]):
        d["names"] = np.array(clash)
        np.savez(tmp_path / "clash.npz", **d)
        with pytest.raises(InputError, match="clash.npz: corrupt artmotion pose model: angle names .* put column"):
            PoseRegressor.load(tmp_path / "clash.npz")
        with pytest.raises(InputError, match="twice in the predictions' header"):
            PoseRegressor(n_components=4).fit(imgs[:20], Y[:20], clash)


def _one_line(code, err, needle):
    assert code == 2
    assert err.startswith("artmotion: error:") and err.count("\n") == 1, err
    assert needle in err, err


def test_bad_inputs(split, run_cli, tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    _one_line(*run_cli("pose", "train", empty, split / "train.csv", "--model", tmp_path / "m.npz")[::2], str(empty))

    bad = tmp_path / "bad"
    shutil.copytree(split / "test", bad)
    victim = sorted(bad.iterdir())[0]
    victim.write_bytes(b"not an image")
    _one_line(*run_cli("pose", "train", bad, split / "test.csv", "--model", tmp_path / "m.npz")[::2], victim.name)

    lines = (split / "test.csv").read_text().splitlines()
    nonnum = tmp_path / "nonnum.csv"
    nonnum.write_text("\n".join(lines[:3] + [lines[3].rsplit(",", 1)[0] + ",abc"] + lines[4:]) + "\n")
    _one_line(*run_cli("pose", "train", split / "test", nonnum, "--model", tmp_path / "m.npz")[::2], "nonnum.csv:4")

    short = tmp_path / "short.csv"
    short.write_text("\n".join(lines[:2] + [lines[2].rsplit(",", 1)[0]] + lines[3:]) + "\n")
    _one_line(*run_cli("pose", "train", split / "test", short, "--model", tmp_path / "m.npz")[::2], "short.csv:3")

    missing = tmp_path / "missing.csv"
    missing.write_text("\n".join(lines[:-1]) + "\n")
    unlabelled = lines[-1].split(",")[0]
    _one_line(*run_cli("pose", "train", split / "test", missing, "--model", tmp_path / "m.npz")[::2], unlabelled)
    _one_line(*run_cli("pose", "train", split / "test", split / "test.csv", "--model", tmp_path / "m.npz",
                       "--inducing-var", "-1")[::2], "--inducing-var")

    foreign = tmp_path / "foreign.npz"
    np.savez(foreign, X=np.zeros((3, 3)))
    _one_line(*run_cli("pose", "predict", foreign, split / "test", "--out", tmp_path / "p.csv")[::2], "foreign.npz")
    junk = tmp_path / "junk.model"
    junk.write_bytes(b"\x00garbage" * 10)
    _one_line(*run_cli("pose", "predict", junk, split / "test", "--out", tmp_path / "p.csv")[::2], "junk.model")
    assert not (tmp_path / "p.csv").exists()
    assert not (tmp_path / "m.npz").exists()
    # a bad Euler convention or a column named twice: refused before any training
    for opts, word in ((("--euler", "abc"), "--euler"), (("--euler", "xyZ"), "--euler"),
                       (("--orientation", "yaw,yaw,yaw"), "twice")):
        _one_line(*run_cli("pose", "eval", split / "test", split / "test.csv", *opts)[::2], word)


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """16 rendered crops with labels.csv and boxes.csv, and a hog model trained on them (no boxes)."""
    from artmotion.pose.data import load_labelled
    from artmotion.pose.model import PoseRegressor

    root = tmp_path_factory.mktemp("small") / "r"
    write_dataset(root, 16, seed=3)
    names, _, imgs, Y = load_labelled(root / "crops", root / "labels.csv")
    PoseRegressor(feature="hog").fit(imgs, Y, names).save(root / "m.npz")
    return root, root / "m.npz"


def test_predictions_quote_image_and_angle_names(small, run_cli, tmp_path):
    """A crop name with a comma, a quote or a line feed, and an angle column with a comma, are quoted
    in pose predict's and pose eval's CSV files, which read back as they were written; a name that
    no CSV file gives back as it is (a space at its start, a carriage return, bytes that
    are not UTF-8) is refused before any work."""
    import csv

    root, model = small
    crops = tmp_path / "crops"
    crops.mkdir()
    odd = [f"left,cam {i:02d}.png" for i in range(14)] + ['say "a".png', "two\nlines.png"]
    src = sorted((root / "crops").iterdir())
    for name, p in zip(odd, src):
        shutil.copy(p, crops / name)
    code, out, err = run_cli("pose", "predict", model, crops, "--out", tmp_path / "p.csv")
    assert code == 0, err
    names, imgs, P = read_labels(tmp_path / "p.csv")
    assert imgs == sorted(odd) and P.shape == (16, 8) and np.isfinite(P).all()
    assert names == ["yaw", "yaw_std", "pitch", "pitch_std", "roll", "roll_std", "opening", "opening_std"]
    # pose eval --out: the cross-validated predictions, also with a comma in an angle's name
    _, _, Y = read_labels(root / "labels.csv")
    with open(tmp_path / "labels.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["image", "yaw", "pitch", "roll", "jaw, deg"])
        w.writerows([name, *y] for name, y in zip(odd, Y))
    code, out, err = run_cli("pose", "eval", crops, tmp_path / "labels.csv", "--feature", "hog", "--folds", 2,
                             "--out", tmp_path / "ev")
    assert code == 0, err
    names, imgs, P = read_labels(tmp_path / "ev" / "cv_hog.csv")
    assert imgs == sorted(odd) and names[-2:] == ["jaw, deg", "jaw, deg_std"] and P.shape == (16, 8)
    for i, bad in enumerate((" lead.png", "cr\r.png")):
        folder = tmp_path / f"bad{i}"
        folder.mkdir()
        shutil.copy(src[0], folder / bad)
        code, out, err = run_cli("pose", "predict", model, folder, "--out", tmp_path / "q.csv")
        assert code == 2 and err.count("\n") == 1 and "rename the file" in err and "Traceback" not in err, (bad, err)
    assert not (tmp_path / "q.csv").exists()
    from artmotion.errors import InputError
    from artmotion.pose.data import check_csv_names

    with pytest.raises(InputError, match="bytes that are not UTF-8"):  # (the message holds the name: not via capsys)
        check_csv_names([tmp_path / os.fsdecode(b"not-utf8-\xff.png")])
    # label columns 'yaw' and 'yaw_std' would give predictions a header with 'yaw_std' twice
    (tmp_path / "std.csv").write_text((root / "labels.csv").read_text().replace("opening", "yaw_std", 1))
    code, out, err = run_cli("pose", "train", root / "crops", tmp_path / "std.csv", "--model", tmp_path / "x.npz")
    assert code == 2 and err.count("\n") == 1 and "std.csv:1:" in err and "'yaw_std'" in err, err
    assert not (tmp_path / "x.npz").exists()


def test_eval_refuses_label_columns_named_like_its_results(small, run_cli, tmp_path):
    """A label column whose name is a key of pose eval's results (e.g. 'orientation' beside the stem's
    Euler columns) would hide that result in the tables and eval.json: refused in one line naming
    the labels. Without Euler columns there is no stem error, and a column 'orientation' is the user's."""
    root, _ = small
    labels = (root / "labels.csv").read_text()
    assert labels.startswith("image,yaw,pitch,roll,opening\n")
    clashes = {"orientation": "'orientation' would be both the stem-orientation error and the error of column "
                              "'orientation'",
               "all": "'all in 3sd' would be both", "yaw filtered": "'yaw filtered' would be both",
               "seconds": "'seconds' would be both the run time"}
    for col, message in clashes.items():
        (tmp_path / "l.csv").write_text(labels.replace("opening", col, 1))
        code, out, err = run_cli("pose", "eval", root / "crops", tmp_path / "l.csv", "--feature", "hog", "--folds", 2,
                                 "--out", tmp_path / "ev")
        assert code == 2 and err.count("\n") == 1 and "l.csv:1:" in err and message in err, (col, err)
        assert not (tmp_path / "ev").exists()
    (tmp_path / "l.csv").write_text(labels.replace("yaw", "orientation", 1))
    code, out, err = run_cli("pose", "eval", root / "crops", tmp_path / "l.csv", "--feature", "hog", "--folds", 2,
                             "--out", tmp_path / "ev")
    assert code == 0, err
    res = json.loads((tmp_path / "ev" / "eval.json").read_text())["hog"]
    _, _, P = read_labels(tmp_path / "ev" / "cv_hog.csv")
    _, _, Y = read_labels(root / "labels.csv")
    assert res["orientation"] == pytest.approx(np.abs(P[:, 0] - Y[:, 0]).mean(), abs=1e-3)
    # result_keys are summary's keys; an unseen sequence's prefix can clash too
    from artmotion.errors import InputError
    from artmotion.pose.evaluate import Columns, check_result_keys, result_keys, summary

    names = ["yaw", "pitch", "roll", "opening"]
    cols = Columns.from_names(names)
    Z = np.zeros((3, 4))
    assert {k for k, _ in result_keys(names, cols)} == set(summary(Z, Z, Z + 1, Z, cols, names)) | {"seconds"}
    with pytest.raises(InputError, match="'test yaw' would be both the error of column 'test yaw' and the error of "
                                         "column 'yaw' on the test sequence"):
        check_result_keys(["yaw", "test yaw"], Columns.from_names(["yaw", "test yaw"]), ["test"], path="l.csv")


def test_boxes_are_refused_where_they_would_do_nothing(small, run_cli, tmp_path):
    """--boxes is used by the cnn feature only: with hog or lbp, and with a model trained without
    boxes, it is an error, before any work, rather than silently ignored."""
    root, model = small
    boxes = root / "boxes.csv"
    for args in (("train", root / "crops", root / "labels.csv", "--model", tmp_path / "m.npz", "--boxes", boxes),
                 ("train", root / "crops", root / "labels.csv", "--model", tmp_path / "m.npz", "--boxes", boxes,
                  "--feature", "lbp"),
                 ("predict", model, root / "crops", "--out", tmp_path / "p.csv", "--boxes", boxes),
                 ("eval", root / "crops", root / "labels.csv", "--folds", 2, "--out", tmp_path / "ev", "--boxes", boxes)):
        code, out, err = run_cli("pose", *args)
        assert code == 2 and err.count("\n") == 1 and "--boxes" in err, (args, err)
    assert not any((tmp_path / n).exists() for n in ("m.npz", "p.csv", "ev"))


@pytest.mark.parametrize("keep, folds", [(4, 2), (5, 2), (9, 5)])
def test_too_few_crops_for_the_folds_is_refused_with_the_real_minimum(small, run_cli, tmp_path, keep, folds):
    """Two folds of 4 or 5 crops train on 2: refused up front, naming the labels file and the
    number that is enough (it said 4 were enough for 2 folds, then failed with no file named)."""
    from artmotion.pose.evaluate import least_examples

    root, _ = small
    lines = (root / "labels.csv").read_text().splitlines()
    labels = tmp_path / "few.csv"
    labels.write_text("\n".join(lines[: keep + 1]) + "\n")
    crops = tmp_path / "crops"
    crops.mkdir()
    for line in lines[1: keep + 1]:
        name = line.split(",")[0]
        src = next((root / "crops").glob(name + ".*"), None) or root / "crops" / name
        shutil.copy(src, crops / src.name)
    need = least_examples(folds)
    assert keep < need
    _one_line(*run_cli("pose", "eval", crops, labels, "--feature", "hog", "--folds", folds)[::2],
              f"few.csv: {keep} labelled crops: {folds}-fold cross-validation needs at least {need}")
    # and the least number is enough
    labels.write_text("\n".join(lines[: need + 1]) + "\n")
    for line in lines[keep + 1: need + 1]:
        name = line.split(",")[0]
        src = next((root / "crops").glob(name + ".*"), None) or root / "crops" / name
        shutil.copy(src, crops / src.name)
    code, _, err = run_cli("pose", "eval", crops, labels, "--feature", "hog", "--folds", folds)
    assert code == 0, err


def test_eval_never_replaces_a_folder_of_the_users_files(split, tmp_path, run_cli):
    """Only a folder of an earlier evaluation's own outputs (by their names) is replaced: a labels
    file kept in --out (an input) and any other CSV of the user's stay, on a second run too."""
    args = ("pose", "eval", split / "train", None, "--feature", "hog", "--folds", 2, "--out")
    exp = tmp_path / "exp"
    exp.mkdir()
    shutil.copy(split / "train.csv", exp / "labels.csv")
    theirs = tmp_path / "theirs"
    theirs.mkdir()
    (theirs / "eval.json").write_text('{"experiment": "mine"}')
    (theirs / "measurements.csv").write_text("a,b\n")
    for labels, out, first in ((exp / "labels.csv", exp, 0), (split / "train.csv", theirs, 2)):
        before = {p.name: p.read_bytes() for p in out.iterdir()}
        a = list(args)
        a[3] = labels
        code, _, err = run_cli(*a, out)
        assert code == first, err
        code, _, err = run_cli(*a, out)          # again: the folder is not its own
        assert code == 2 and "exists" in err and err.count("\n") == 1, err
        assert all((out / n).read_bytes() == b for n, b in before.items())
    ours = tmp_path / "ours"                     # its own earlier outputs are replaced
    for _ in range(2):
        code, _, err = run_cli("pose", "eval", split / "train", split / "train.csv", "--feature", "hog", "--folds", 2,
                               "--out", ours)
        assert code == 0, err
