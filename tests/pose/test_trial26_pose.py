"""Trial 26: crops in number order without hidden files, boxes and --steps where they do not apply,
a model of a few near-identical crops says what its variance is worth, labels matched like boxes."""

import cv2
import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.pose.data import list_images, load_labelled, read_labels
from artmotion.pose.model import CALIBRATED_MIN, PoseRegressor

NAMES = ["yaw", "opening"]


def _crops(folder, names, seed=0, size=(40, 32)):
    """Noise crops named ``names``, each with a bright bar whose angle is its label."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    labels = {}
    for k, name in enumerate(names):
        img = rng.integers(0, 60, (size[1], size[0], 3), dtype=np.uint8)
        a = float(rng.uniform(0, 180))
        c, s = np.cos(np.radians(a)), np.sin(np.radians(a))
        cv2.line(img, (int(20 - 15 * c), int(16 - 15 * s)), (int(20 + 15 * c), int(16 + 15 * s)), (255, 255, 255), 3)
        cv2.imwrite(str(folder / name), img)
        labels[name] = (a, float(k % 7))
    return labels


def _labels_csv(path, labels, rename=lambda n: n):
    path.write_text("image," + ",".join(NAMES) + "\n"
                    + "".join(f"{rename(n)},{a:.3f},{b:.3f}\n" for n, (a, b) in labels.items()))
    return path


def test_crops_are_listed_in_number_order_without_hidden_files(tmp_path, run_cli):
    """'10.png' came before '2.png' (text order), so --smooth smoothed a scrambled sequence; a macOS
    '._1.png' beside the crops made predict fail ('cannot decode image') and train ('no label')."""
    names = [f"{i}.png" for i in (1, 2, 3, 10, 11, 20)] + [f"{i}.png" for i in range(4, 10)]
    labels = _crops(tmp_path / "crops", names)
    (tmp_path / "crops" / "._1.png").write_bytes(b"\x00\x05\x16\x07 macOS resource fork")
    assert [p.name for p in list_images(tmp_path / "crops")] == [f"{i}.png" for i in range(1, 12)] + ["20.png"]
    csv = _labels_csv(tmp_path / "labels.csv", labels)
    code, out, err = run_cli("pose", "train", tmp_path / "crops", csv, "--model", tmp_path / "m.npz")
    assert code == 0, err
    code, out, err = run_cli("pose", "predict", tmp_path / "m.npz", tmp_path / "crops", "--out", tmp_path / "p.csv",
                             "--smooth")
    assert code == 0, err
    _, images, _ = read_labels(tmp_path / "p.csv")
    assert images == [f"{i}.png" for i in range(1, 12)] + ["20.png"]


def test_hog_ignores_the_sets_boxes_and_refuses_steps(tmp_path, run_cli):
    """hog and lbp do not use boxes: a set without boxes.csv beside one with it is no error for them
    (it still is for cnn); --steps (the cnn network's) is refused with them, as --boxes is."""
    for k, with_boxes in enumerate((True, False)):
        d = tmp_path / f"set{k}"
        labels = _crops(d / "crops", [f"{i:06d}.png" for i in range(1, 13)], seed=k)
        _labels_csv(d / "labels.csv", labels)
        if with_boxes:
            (d / "boxes.csv").write_text("image,x,y,w,h,frame_w,frame_h\n"
                                         + "".join(f"{n},10,10,40,32,320,240\n" for n in labels))
    sets = ("--set", tmp_path / "set0", "--set", tmp_path / "set1")
    for feature in ("hog", "lbp"):
        code, out, err = run_cli("pose", "train", *sets, "--feature", feature, "--model", tmp_path / f"{feature}.npz")
        assert code == 0 and "from 2 sequences" in out, err
        code, out, err = run_cli("pose", "train", *sets, "--feature", feature, "--steps", 100,
                                 "--model", tmp_path / "x.npz")
        assert code == 2 and err.count("\n") == 1 and f"--steps needs --feature cnn (the {feature} feature" in err, err
    code, out, err = run_cli("pose", "train", *sets, "--feature", "cnn", "--model", tmp_path / "x.npz")
    assert code == 2 and "boxes for some training sequences but not for all" in err, err
    assert not (tmp_path / "x.npz").exists()


def test_a_model_of_a_few_near_identical_crops_says_its_variance_means_little(tmp_path, run_cli):
    """Trained on 4 renders of nearly one pose, a model gave every other crop a std of 0.02° while
    erring by 37°, without a word: its variance is uncalibrated (too few crops to hold any out) and,
    far from its training crops, only the tiny spread of its training angles."""
    rng = np.random.default_rng(3)
    base = rng.integers(0, 255, (32, 40, 3), dtype=np.uint8)
    (tmp_path / "few").mkdir()
    rows = []
    for i in range(4):
        img = np.clip(base.astype(int) + rng.integers(-2, 3, base.shape), 0, 255).astype(np.uint8)
        cv2.imwrite(str(tmp_path / "few" / f"{i:06d}.png"), img)
        rows.append(f"{i:06d}.png,{25 + 0.01 * i},{50 - 0.01 * i}")
    (tmp_path / "few.csv").write_text("image,yaw,opening\n" + "\n".join(rows) + "\n")
    code, out, err = run_cli("pose", "train", tmp_path / "few", tmp_path / "few.csv", "--model", tmp_path / "m.npz")
    assert code == 0, err
    assert "4 crops are too few to calibrate the standard deviations" in err and str(CALIBRATED_MIN) in err
    _crops(tmp_path / "other", [f"{i:06d}.png" for i in range(6)], seed=9)
    code, out, err = run_cli("pose", "predict", tmp_path / "m.npz", tmp_path / "other", "--out", tmp_path / "p.csv")
    assert code == 0, err
    assert "6 of 6 crops are far from every training crop" in err and "yaw 0.0" in err, err
    # a model's own training crops are not far from it
    reg = PoseRegressor.load(tmp_path / "m.npz")
    _, std = reg.predict(reg.features(np.stack([cv2.imread(str(p)) for p in list_images(tmp_path / "few")])),
                         return_std=True)
    assert not reg.far_from_training(std).any()


@pytest.mark.parametrize("n, calibrated", [(CALIBRATED_MIN - 1, False), (CALIBRATED_MIN, True)])
def test_the_fewest_crops_whose_variance_is_calibrated(n, calibrated):
    rng = np.random.default_rng(0)
    X = rng.normal(size=(n, 5))
    reg = PoseRegressor(method="exact", n_components=None).fit(X, X[:, :2] @ np.ones((2, 1)))
    assert (reg.gp_.held_out is not None) == calibrated


def test_labels_name_crops_with_or_without_their_extension(tmp_path):
    """A label '000001' or '000001.PNG' for the crop '000001.png' was 'image has no label' (boxes.csv
    was matched without the extension); exact names still match, and one label for two crops is an
    error naming both."""
    names = [f"{i:06d}.png" for i in range(1, 5)]
    labels = _crops(tmp_path / "crops", names)
    forms = {names[0]: "000001", names[1]: "000002.PNG", names[2]: "000003.png", names[3]: "000004.jpg"}
    csv = _labels_csv(tmp_path / "l.csv", labels, forms.get)
    got_names, paths, imgs, Y = load_labelled(tmp_path / "crops", csv)
    assert [p.name for p in paths] == names and len(imgs) == 4
    np.testing.assert_allclose(Y, [labels[n] for n in names], atol=1e-3)
    # a second crop of number 1: the label '000001' would name both
    cv2.imwrite(str(tmp_path / "crops" / "000001.jpg"), cv2.imread(str(tmp_path / "crops" / names[0])))
    with pytest.raises(InputError, match=r"label '000001' names two images: 000001.jpg and 000001.png") as info:
        load_labelled(tmp_path / "crops", csv)
    assert info.value.path == str(csv)
    # with its own exact label each is matched
    labels["000001.jpg"] = (1.0, 2.0)
    load_labelled(tmp_path / "crops", _labels_csv(tmp_path / "exact.csv", labels))
    # two labels for one crop, neither exact
    (tmp_path / "crops" / "000001.jpg").unlink()
    (tmp_path / "two.csv").write_text((tmp_path / "l.csv").read_text() + "000001.PNG,1,2\n")
    with pytest.raises(InputError, match=r"labels '000001' and '000001.PNG' both name image 000001.png"):
        load_labelled(tmp_path / "crops", tmp_path / "two.csv")


def test_a_model_file_with_a_damaged_compression_field_is_one_line(tmp_path):
    """A pose model whose zip entry names an unknown compression method (found by the fuzz test)
    raised zipfile's NotImplementedError out of ``load``: an internal error, not a one-line one."""
    from artmotion.errors import InputError
    from artmotion.pose.model import PoseRegressor

    rng = np.random.default_rng(0)
    crops = [rng.integers(0, 255, (48, 64, 3), dtype=np.uint8) for _ in range(12)]
    reg = PoseRegressor(n_components=4).fit(crops, rng.normal(size=(12, 2)), names=["a", "b"])
    good = tmp_path / "m.npz"
    reg.save(good)
    raw = bytearray(good.read_bytes())
    at = raw.index(b"PK\x01\x02") + 10            # the first entry's compression method (central directory)
    raw[at:at + 2] = (99).to_bytes(2, "little")
    bad = tmp_path / "bad.npz"
    bad.write_bytes(bytes(raw))
    with pytest.raises(InputError, match="not an artmotion pose model"):
        PoseRegressor.load(bad)


def test_far_from_training_checks_its_standard_deviations(tmp_path):
    """A (2, 5) array for a 2-angle model was reshaped into 5 answers; NaN said "not far"."""
    rng = np.random.default_rng(0)
    reg = PoseRegressor(method="exact").fit(rng.random((30, 3)), rng.random((30, 2)))
    _, std = reg.predict(rng.random((4, 3)), return_std=True)
    assert reg.far_from_training(std).shape == (4,)
    for bad in (np.ones((2, 5)), np.full((3, 2), np.nan), -std, "abc"):
        with pytest.raises(InputError, match=r"std must be an (\(n, 2\) )?array"):
            reg.far_from_training(bad)


def test_a_model_file_declaring_more_data_than_it_holds_or_tiny_hypers_is_one_line(tmp_path):
    """A header declaring a 10^12-element array was a MemoryError (exit 1), a length scale of
    1e-200 a ZeroDivisionError in the kernel (found by the file fuzzing of the thirty-fourth session)."""
    import io
    import zipfile

    from artmotion.errors import InputError
    from artmotion.pose.model import PoseRegressor

    rng = np.random.default_rng(0)
    crops = [rng.integers(0, 255, (48, 64, 3), dtype=np.uint8) for _ in range(12)]
    reg = PoseRegressor(n_components=4).fit(crops, rng.normal(size=(12, 2)), names=["a", "b"])
    good = tmp_path / "m.npz"
    reg.save(good)
    with np.load(good) as z:
        d = {k: z[k] for k in z.files}
    tiny = tmp_path / "tiny.npz"
    np.savez(tiny, **{**d, "hypers": np.full_like(d["hypers"], 1e-200)})
    with pytest.raises(InputError, match=r"tiny.npz: corrupt artmotion pose model: 'hypers'"):
        PoseRegressor.load(tiny).predict(crops)
    hdr = b"{'descr': '<f4', 'fortran_order': False, 'shape': (1000000, 1000000), }"
    pad = 64 - (10 + len(hdr) + 1) % 64
    npy = b"\x93NUMPY\x01\x00" + (len(hdr) + pad + 1).to_bytes(2, "little") + hdr + b" " * pad + b"\n" + b"\0" * 64
    huge = tmp_path / "huge.npz"
    with zipfile.ZipFile(huge, "w") as zf:
        for k, v in d.items():
            if k == "X":
                zf.writestr("X.npy", npy)
            else:
                b = io.BytesIO()
                np.save(b, v)
                zf.writestr(k + ".npy", b.getvalue())
    with pytest.raises(InputError, match=r"huge.npz: corrupt artmotion pose model: array 'X.npy' declares shape"):
        PoseRegressor.load(huge)
    assert np.isfinite(PoseRegressor.load(good).predict(crops)).all()
