"""``PoseRegressor.domain_auc``: whether crops are what a pose model was trained on."""

import math

import cv2
import numpy as np
import pytest

from artmotion.pose.data import read_labels
from artmotion.pose.model import DOMAIN_MIN, PoseRegressor, is_foreign
from artmotion.pose.render import write_dataset


@pytest.fixture(scope="module")
def model_and_crops(tmp_path_factory):
    root = tmp_path_factory.mktemp("domain")
    write_dataset(root, 240, seed=3, frames=False)
    _, names, Y = read_labels(root / "labels.csv")
    crops = [cv2.imread(str(root / "crops" / n)) for n in names]
    return PoseRegressor().fit(crops, Y), crops


def test_foreign_crops_are_told_and_known_ones_are_not(model_and_crops):
    reg, crops = model_and_crops
    rng = np.random.default_rng(0)
    noise = [cv2.GaussianBlur(rng.integers(0, 255, (60, 48, 3), np.uint8), (5, 5), 2) for _ in range(150)]
    auc = reg.domain_auc(noise)
    assert is_foreign(auc), auc
    assert not is_foreign(reg.domain_auc(crops))
    # a feature matrix is judged like the crops it comes from
    assert reg.domain_auc(reg.features(noise)) == pytest.approx(auc)


def test_too_few_or_too_alike_crops_are_not_judged(model_and_crops):
    reg, crops = model_and_crops
    assert math.isnan(reg.domain_auc(crops[: DOMAIN_MIN - 1]))
    # an instrument held still: a handful of points is told apart from anything in many dimensions,
    # so crops whose nearest training crops are that few are not judged (rather than called foreign)
    rng = np.random.default_rng(1)
    still = [np.clip(crops[0] + rng.normal(0, 2, crops[0].shape), 0, 255).astype(np.uint8) for _ in range(2 * DOMAIN_MIN)]
    auc = reg.domain_auc(still)
    assert math.isnan(auc) and not is_foreign(auc)
