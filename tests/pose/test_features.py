import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.pose.features import extract, feature_dim


def _img(h=90, w=120, seed=0):
    rng = np.random.default_rng(seed)
    img = np.zeros((h, w, 3), np.uint8) + 60
    img[h // 3 : h // 2, :] = 200  # a horizontal bar
    img += rng.integers(0, 20, img.shape, dtype=np.uint8)
    return img


def test_dimensions_match_the_thesis():
    assert feature_dim("hog") == 1488
    assert feature_dim("lbp") == 696
    ims = [_img(), _img(30, 200), _img(480, 50)[:, :, 0]]  # any size, grey or colour
    assert extract(ims, "hog").shape == (3, 1488)
    assert extract(ims, "lbp").shape == (3, 696)


def test_hog_is_contrast_invariant_and_sees_orientation():
    a = _img()
    dim = a.astype(np.float32) / 255.0 * 0.4  # float images are taken as [0, 1]
    f = extract([a, dim, np.ascontiguousarray(a.transpose(1, 0, 2))], "hog")
    assert np.abs(f[0] - f[1]).max() < 0.05 * np.abs(f[0]).max()  # global contrast change
    assert np.linalg.norm(f[0] - f[2]) > 0.3 * np.linalg.norm(f[0])  # a rotated bar differs


def test_lbp_is_invariant_to_monotonic_intensity_change():
    a = (_img(48, 64)[:, :, 0] // 2).astype(np.uint8)  # grey, exactly the crop size: no resampling
    b = (2 * a.astype(np.int32) + 10).astype(np.uint8)  # strictly increasing grey-level map
    fa, fb = extract([a, b], "lbp")
    np.testing.assert_allclose(fa, fb, atol=1e-6)
    assert not np.allclose(fa, extract([a.T.copy()], "lbp")[0])
    assert np.all(fa >= 0)


def test_unknown_feature_is_an_input_error():
    with pytest.raises(InputError):
        extract([_img()], "sift")
