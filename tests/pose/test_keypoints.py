"""Keypoints of the tool (hinge, clevis, jaw tips) as auxiliary targets of the cnn feature's
network: rendered into keypoints.csv, read as fractions of each crop, moved with the box jitter
of the augmentation, learned besides the angles and dropped from the trained network."""

import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.pose.data import load_labelled, read_keypoints
from artmotion.pose.render import KEYPOINTS, RENDERING, ToolPose, keypoints, project, write_dataset

pytest.importorskip("torch")


def test_keypoints_follow_the_jaws_and_the_stem():
    closed, open_ = ToolPose(10.0, -5.0, 30.0, 0.0, 120.0), ToolPose(10.0, -5.0, 30.0, 60.0, 120.0)
    c, o = keypoints(closed), keypoints(open_)
    assert c.shape == (len(KEYPOINTS), 2)
    np.testing.assert_allclose(c[2], c[3], atol=1e-9)      # closed: the two jaw tips meet
    assert np.linalg.norm(o[2] - o[3]) > 5                # open: they part
    np.testing.assert_allclose(c[:2], o[:2])              # the hinge and the clevis do not move with the jaws
    np.testing.assert_allclose(c[0], project(closed.tip())[0])
    # the hinge, the clevis and the stem's entry point lie on one image line (the stem's axis)
    a, b, e = c[0], c[1], project(closed.trocar())[0]
    u, v = b - a, e - a
    assert abs(u[0] * v[1] - u[1] * v[0]) / np.linalg.norm(u) / np.linalg.norm(v) < 1e-6


def test_render_writes_keypoints_of_each_crop(tmp_path):
    root = tmp_path / "r"
    write_dataset(root, 120, seed=4, frames=False, motion="cover")
    assert "keypoints.csv" in RENDERING and (root / "keypoints.csv").is_file()
    names, paths, imgs, Y = load_labelled(root / "crops", root / "labels.csv")
    sizes = np.array([(c.shape[1], c.shape[0]) for c in imgs])
    points, K = read_keypoints(root / "keypoints.csv", paths, sizes)
    assert points == list(KEYPOINTS) and K.shape == (120, 2 * len(KEYPOINTS))
    # the box is made around the end effector: the hinge and the clevis lie inside their crop
    assert np.all((K[:, :4] > 0) & (K[:, :4] < 1))
    # the jaw tips part (in pixels) as the jaws open (seen: rank correlation 0.96)
    from scipy.stats import spearmanr

    P = K * np.tile(sizes, len(KEYPOINTS))
    assert spearmanr(np.hypot(*(P[:, 4:6] - P[:, 6:8]).T), Y[:, names.index("opening")])[0] > 0.8


def test_read_keypoints_checks_its_file(tmp_path):
    crops = [tmp_path / "000001.png", tmp_path / "000002.png"]
    sizes = [(100, 50), (40, 20)]
    f = tmp_path / "keypoints.csv"
    f.write_text("image,a_x,a_y,b_x,b_y\n000001.png,50,25,10,5\n000002.png,,,4,2\n")
    names, K = read_keypoints(f, crops, sizes)
    assert names == ["a", "b"]
    np.testing.assert_allclose(K, [[0.5, 0.5, 0.1, 0.1], [np.nan, np.nan, 0.1, 0.1]])
    f.write_text("image,a_x,a_y\n000001.png,,\n000002.png,-4,30\n")   # none known; just outside the crop
    np.testing.assert_allclose(read_keypoints(f, crops, sizes)[1], [[np.nan, np.nan], [-0.1, 1.5]])
    bad = {
        "image,a_x,a_z\n000001.png,1,2\n000002.png,1,2\n": "keypoints.csv:1: header must be",
        "image,a_x,a_y\n000001.png,1,\n000002.png,1,2\n": "keypoints.csv:2: point 'a' has an x or a y but not both",
        "image,a_x,a_y\n000001.png,1,2\n": "no row of keypoints for image '000002.png'",
        "image,a_x,a_y\n000001.png,1,2\n000002.png,1,2\n000001.jpg,1,2\n": "keypoints.csv:4: a second row of keypoints",
        "image,a_x,a_y\n000001.png,1,nan\n000002.png,1,2\n": "keypoints.csv:2: a_y",
        "image,a_x,a_y\n000001.png,1,2\n000002.png,1\n": "keypoints.csv:3: expected 3 values",
        "image,a_x,a_y\n000001.png,,\n000002.png,,\n": "keypoints.csv: no keypoint is known in any row",
        "image,a_x,a_y\n000001.png,1,2\n000002.png,9999,2\n":   # 250 widths of its 40-px crop: frame pixels?
            "keypoints.csv: the keypoints of image '000002.png' lie more than 100 crop widths",
    }
    for text, message in bad.items():
        f.write_text(text)
        with pytest.raises(InputError, match=message):
            read_keypoints(f, crops, sizes)


def test_augmentation_moves_the_keypoints_with_the_crop():
    """The box jitter shifts and scales a crop: its keypoints go where the content went."""
    from artmotion.pose.cnn import augment

    rng = np.random.default_rng(0)
    n, h, w = 64, 48, 64
    pts = np.column_stack([rng.uniform(0.25, 0.75, n), rng.uniform(0.25, 0.75, n)])
    yy, xx = np.mgrid[0:h, 0:w]
    crops = np.zeros((n, h, w, 3), np.float32)
    for i, (u, v) in enumerate(pts):
        crops[i][(xx - u * w) ** 2 + (yy - v * h) ** 2 < 9] = 1.0   # a bright dot at the point
    out, moved = augment(crops, np.random.default_rng(1), pts)
    assert moved is not None and moved.shape == pts.shape
    # where the dot is now: the brightness-weighted centre of the augmented crop above its median
    err_moved, err_still = [], []
    for i in range(n):
        g = out[i].mean(2)
        wgt = np.clip(g - np.median(g), 0, None) ** 4
        c = np.array([(wgt * xx).sum() / w, (wgt * yy).sum() / h]) / wgt.sum()
        err_moved.append(np.hypot(*((c - moved[i]) * (w, h))))
        err_still.append(np.hypot(*((c - pts[i]) * (w, h))))
    assert np.median(err_moved) < 1.0 < np.median(err_still), (np.median(err_moved), np.median(err_still))
    same, none = augment(crops, np.random.default_rng(1))
    assert none is None and np.array_equal(same, out)   # the same crops with or without points


def _dots(n: int, rng: np.random.Generator):
    """Noise crops, each with a dot whose place (x / w, y / h) is the keypoint, and angles that do
    not depend on the crop."""
    h, w = 48, 64
    yy, xx = np.mgrid[0:h, 0:w]
    pts = rng.uniform(0.2, 0.8, (n, 2))
    crops = rng.uniform(0.3, 0.5, (n, h, w, 3)).astype(np.float32)
    for i, (u, v) in enumerate(pts):
        crops[i][(xx - u * w) ** 2 + (yy - v * h) ** 2 < 16] = 1.0
    return crops, rng.normal(size=(n, 2)), pts


def test_network_learns_the_keypoints_into_its_feature_and_drops_their_read_out():
    """Trained with the dots' places as keypoints, the network's feature tells where the dot is
    (a linear fit on it, scored on other crops); trained on the angles alone (which say nothing
    of the dot), it does not. Rows whose keypoints are NaN are left out of their loss."""
    from sklearn.linear_model import Ridge

    from artmotion.pose import cnn

    crops, Y, pts = _dots(400, np.random.default_rng(0))
    test, _, tpts = _dots(200, np.random.default_rng(1))

    def r2(net):
        fit = Ridge(1e-2).fit(cnn.embed(net, crops), pts)
        return fit.score(cnn.embed(net, test), tpts)

    with_points = cnn.fit_net(crops, Y, steps=300, batch=32, points=pts, point_weight=2.0)
    assert with_points.head.out_features == 2          # the angles only
    half = pts.copy()
    half[::2] = np.nan                                  # half the crops without keypoints
    with_half = cnn.fit_net(crops, Y, steps=300, batch=32, points=half, point_weight=2.0)
    assert all(np.isfinite(p.detach().numpy()).all() for p in with_half.parameters())
    without = cnn.fit_net(crops, Y, steps=300, batch=32)
    scores = r2(with_points), r2(with_half), r2(without)
    # (seen: 0.998 and 0.998 against 0.75: the unexplained share ten times smaller and more)
    assert min(scores[:2]) > 0.95 and 1 - scores[2] > 5 * (1 - min(scores[:2])), scores


def test_pose_regressor_checks_its_keypoints():
    from artmotion.pose.model import PoseRegressor

    crops, Y, pts = _dots(12, np.random.default_rng(2))
    reg = PoseRegressor(feature="cnn", net_steps=2, n_components=None)
    bad = {
        "rows of x, y pairs": pts[:, :1],
        "rows of x, y pairs ": pts[:5],
        "infinite": np.where(np.arange(12)[:, None] == 3, np.inf, pts),
        "an x but no y": np.where([[True, False]], np.nan, pts),
        "from their crops' corners": pts * 1000,
    }
    for message, K in bad.items():
        with pytest.raises(InputError, match=message.strip()):
            reg.fit(crops, Y, keypoints=K)
    with pytest.raises(InputError, match="keypoint_weight"):
        PoseRegressor(feature="cnn", net_steps=2, keypoint_weight=-1).fit(crops, Y, keypoints=pts)
    reg.fit(crops, Y, keypoints=np.where(np.arange(12)[:, None] < 6, np.nan, pts))   # some not known: fine
    assert reg.net_.head.out_features == 2
    PoseRegressor(feature="hog").fit(crops, Y, keypoints=pts[:, :1])   # hog trains no network: not used
    # cross-validation trains each fold's network with that fold's keypoints
    from artmotion.pose.evaluate import cross_validate

    X = reg.features(crops)
    mean = cross_validate(X, Y, ["a", "b"], 2, feature="cnn", net_steps=2, n_components=None, keypoints=pts)[0]
    assert mean.shape == Y.shape and np.isfinite(mean).all()
    with pytest.raises(InputError, match="rows of x, y pairs"):
        cross_validate(X, Y, ["a", "b"], 2, feature="cnn", net_steps=2, keypoints=pts[:, :1])
    for short in (pts[:5], pts[:5].tolist()):   # too few rows: one line, not an IndexError in a fold
        with pytest.raises(InputError, match="12 rows of x, y pairs"):
            cross_validate(X, Y, ["a", "b"], 2, feature="hog", keypoints=short)


def test_cli_trains_with_the_sets_keypoints(run_cli, tmp_path):
    import shutil

    a, b = tmp_path / "a", tmp_path / "b"
    write_dataset(a, 60, seed=1, frames=False)
    write_dataset(b, 60, seed=2, frames=False)
    model = tmp_path / "m.npz"
    code, out, err = run_cli("pose", "train", "--set", a, "--set", b, "--model", model, "--feature", "cnn",
                             "--steps", 10)
    assert code == 0 and "keypoints" not in out, err    # off by default
    code, out, err = run_cli("pose", "train", "--set", a, "--set", b, "--model", model, "--feature", "cnn",
                             "--steps", 10, "--set-keypoints")
    assert code == 0 and "its network also finding 4 keypoints" in out, err
    (b / "keypoints.csv").unlink()        # a set without keypoints: its crops train the angles only
    code, out, err = run_cli("pose", "train", "--set", a, "--set", b, "--model", model, "--feature", "cnn",
                             "--steps", 10, "--set-keypoints")
    assert code == 0 and "4 keypoints" in out, err
    code, out, err = run_cli("pose", "train", "--set", a, "--model", tmp_path / "h.npz")
    assert code == 0 and "keypoints" not in out, err   # hog: not read
    other = tmp_path / "other.csv"
    shutil.copy(a / "keypoints.csv", other)
    other.write_text(other.read_text().replace("hinge_", "pivot_", 2))
    bad = {
        (b / "crops", b / "labels.csv", "--keypoints", other, "--set", a, "--feature", "cnn", "--set-keypoints"):
            "points hinge,clevis,jaw1,jaw2 differ from the first keypoints' pivot,clevis,jaw1,jaw2",
        (b / "crops", b / "labels.csv", "--keypoints", a / "keypoints.csv"): "--keypoints needs --feature cnn",
        ("--set", a, "--set-keypoints"): "--set-keypoints needs --feature cnn",
        ("--keypoints", a / "keypoints.csv", "--set", a): "--keypoints goes with IMAGES",
    }
    code, out, err = run_cli("pose", "eval", a / "crops", a / "labels.csv", "--keypoints", a / "keypoints.csv")
    assert code == 2 and "--keypoints needs --feature cnn" in err and err.count("\n") == 1, err
    for args, message in bad.items():
        code, out, err = run_cli("pose", "train", *args, "--model", tmp_path / "x.npz", "--steps", 10)
        assert code == 2 and message in err and err.count("\n") == 1, (args, err)
    assert not (tmp_path / "x.npz").exists()
