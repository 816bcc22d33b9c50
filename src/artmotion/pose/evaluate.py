"""Errors of Sec. 3.6 and the cross-validation experiment (Tables 3.1, 3.2, Fig. 3.4, 3.6).

* orientation error: the angle between the true and estimated stem directions (unit vectors from
  the Euler angles), i.e. the cosine distance turned back into degrees;
* any other angle (e.g. the jaw opening): ``|estimate - truth|``.
Folds are dealt at random (the usual k-fold, the thesis' protocol) or are contiguous blocks of
the sequence, so that every test fold is an unseen stretch of motion that can be filtered in time
(random folds put near-duplicate neighbouring frames into training).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from artmotion.errors import InputError
from artmotion.pose.filter import PoseFilter, accel_variance
from artmotion.pose.model import MIN_EXAMPLES, PoseRegressor, check_keypoints, check_views
from artmotion.pose.render import stem_direction


def orientation_error(true_deg: np.ndarray, est_deg: np.ndarray, euler: str = "ZYX") -> np.ndarray:
    """Per-row angle (degrees) between stem directions of two sets of Euler angles ``(n, 3)``."""
    a = stem_direction(true_deg, euler)
    b = stem_direction(est_deg, euler)
    c = np.clip((a * b).sum(1), -1.0, 1.0)
    return np.degrees(np.arccos(c))


@dataclass
class Columns:
    """Which label columns are the Euler angles of the stem and which is the opening."""

    orientation: list[int] = field(default_factory=list)
    others: list[int] = field(default_factory=list)
    euler: str = "ZYX"

    @classmethod
    def from_names(cls, names: Sequence[str], orientation: Sequence[str] | None = None, euler: str = "ZYX"):
        """``orientation`` defaults to ``yaw, pitch, roll`` when all three are label columns."""
        names = list(names)
        if orientation is None:
            orientation = ["yaw", "pitch", "roll"] if all(n in names for n in ("yaw", "pitch", "roll")) else []
        orientation = list(orientation)
        if orientation and len(orientation) != 3:
            raise InputError(f"--orientation needs 3 Euler-angle columns, got {orientation}")
        for n in orientation:
            if n not in names:
                raise InputError(f"orientation column {n!r} not among the labels {names}")
        if len(set(orientation)) != len(orientation):
            raise InputError(f"--orientation names a column twice: {orientation}")
        # SciPy's rule: three axes, all extrinsic (xyz) or all intrinsic (XYZ), none twice in a row
        if not (len(euler) == 3 and (set(euler) <= set("xyz") or set(euler) <= set("XYZ"))
                and euler[0] != euler[1] and euler[1] != euler[2]):
            raise InputError(f"--euler {euler!r}: expected three axes of 'xyz' (extrinsic) or 'XYZ' (intrinsic), "
                             "no axis twice in a row (e.g. ZYX)")
        idx = [names.index(n) for n in orientation]
        return cls(idx, [i for i in range(len(names)) if i not in idx], euler)


def errors(Y: np.ndarray, P: np.ndarray, cols: Columns, names: Sequence[str]) -> dict[str, np.ndarray]:
    """Per-frame errors: ``orientation`` (if Euler columns are known) and one per other angle."""
    out = {}
    if cols.orientation:
        out["orientation"] = orientation_error(Y[:, cols.orientation], P[:, cols.orientation], cols.euler)
    for k in range(Y.shape[1]):
        out[names[k]] = np.abs(Y[:, k] - P[:, k])
    return out


def result_keys(names: Sequence[str], cols: Columns, sets: Sequence[str] = ()) -> list[tuple[str, str]]:
    """The keys of one feature's results in ``pose eval`` (its tables and eval.json), each with what
    it holds: the run time, :func:`summary`'s keys and, prefixed ``"<set> "``, those of every unseen
    sequence in ``sets`` ("test", "dark")."""
    errs = [("orientation", "stem-orientation error")] if cols.orientation else []
    errs += [(n, f"error of column {n!r}") for n in names]
    keys = [("seconds", "the run time")]
    for s in ("", *sets):
        p, on = (f"{s} ", f" on the {s} sequence") if s else ("", "")
        for k, what in errs:
            keys += [(p + k, f"the {what}{on}"), (f"{p}{k} filtered", f"the filtered {what}{on}")]
        keys += [(f"{p}{n} in 3sd", f"the 3σ coverage of column {n!r}{on}") for n in names]
        keys.append((f"{p}all in 3sd", f"the 3σ coverage of all columns{on}"))
    return keys


def check_result_keys(names: Sequence[str], cols: Columns, sets: Sequence[str] = (), path=None) -> None:
    """An :class:`InputError` naming ``path`` (the labels) when two of :func:`result_keys` are one
    key (a label column ``orientation`` beside the stem's Euler columns, ``all``, ``seconds``,
    ``<column> filtered``, ``test <column>``, ...): one would hide the other in the tables and eval.json."""
    seen: dict[str, str] = {}
    for key, what in result_keys(names, cols, sets):
        if key in seen:
            raise InputError(f"label column names clash with the results of pose eval: {key!r} would be both "
                             f"{seen[key]} and {what}; rename the column", path=path, line=1)
        seen[key] = what


def least_examples(folds: int) -> int:
    """The fewest examples for ``folds``-fold cross-validation: two per fold, and every fold's
    training set (the others) at least the :data:`~artmotion.pose.model.MIN_EXAMPLES` a model
    needs (2 folds of 4 or 5 train on 2)."""
    n = 2 * folds
    while n - int(np.diff(np.linspace(0, n, folds + 1).astype(int)).max()) < MIN_EXAMPLES:
        n += 1
    return n


def cross_validate(X: np.ndarray, Y: np.ndarray, names: Sequence[str], folds: int = 5, progress: bool = False,
                   split: str = "random", seed: int = 0, views: np.ndarray | None = None,
                   keypoints: np.ndarray | None = None, **reg_kwargs):
    """Out-of-fold predictions: ``(mean, std, filtered_mean, filtered_std, fold_id)``.

    ``split="random"``: frames are dealt to folds at random (the usual k-fold protocol;
    neighbouring, nearly identical frames then fall on both sides, which flatters the error);
    ``"contiguous"``: each fold is a block of consecutive frames (an unseen stretch of motion).
    Filtering: with contiguous folds the Kalman filter runs over each test block; with random
    folds the out-of-fold predictions of all frames, in time order, are one sequence (every
    frame predicted by a model that never saw it) and the filter runs over that, with the mean
    of the folds' acceleration priors (each from training labels only). The filter here is the
    labels' own motion prior, untuned (the thesis's protocol; not :meth:`PoseRegressor.make_filter`,
    whose tuning on calibration rows the unseen-sequence figures use). ``views``: the crops'
    :func:`artmotion.pose.features.box_views`, for models that use them; ``keypoints``: the
    training crops' keypoints (:meth:`PoseRegressor.fit`), for the ``cnn`` feature's training.
    """
    n = len(X)
    keypoints = check_keypoints(keypoints, n)  # (sliced per fold below: checked whole first)
    views = None if views is None else check_views(views, n)
    if split not in ("contiguous", "random"):
        raise InputError(f"unknown split {split!r}; choose contiguous or random")
    least = least_examples(max(folds, 2))
    if folds < 2 or n < least:
        raise InputError(f"need at least {least} examples for {folds}-fold cross-validation, got {n}")
    edges = np.linspace(0, n, folds + 1).astype(int)
    mean = np.empty_like(Y)
    std = np.empty_like(Y)
    fmean = np.empty_like(Y)
    fstd = np.empty_like(Y)
    fold_id = np.empty(n, int)
    accel = []
    perm = np.random.default_rng(seed).permutation(n)
    it = range(folds)
    if progress:
        from tqdm import tqdm

        it = tqdm(it, desc="cross-validation", unit="fold", leave=False, disable=None)
    for f in it:
        if split == "contiguous":
            test = np.arange(edges[f], edges[f + 1])
        else:
            test = np.sort(perm[edges[f] : edges[f + 1]])
        train = np.setdiff1d(np.arange(n), test)
        reg = PoseRegressor(**reg_kwargs)
        # keep the training blocks in time order so the motion prior sees real sequences
        reg.fit(X[train], Y[train], names, views=None if views is None else views[train],
                keypoints=None if keypoints is None else keypoints[train])
        m, s = reg.predict(X[test], return_std=True, views=None if views is None else views[test])
        mean[test], std[test] = m, s
        accel.append(accel_variance(Y[train], frames=train))  # training labels, no gaps or seams
        if split == "contiguous":
            fmean[test], fstd[test] = PoseFilter(accel[-1]).filter(m, s)
        fold_id[test] = f
    if split == "random":
        fmean[:], fstd[:] = PoseFilter(np.mean(accel, axis=0)).filter(mean, std)
    return mean, std, fmean, fstd, fold_id


def summary(Y, mean, std, fmean, cols: Columns, names, smooth=None) -> dict[str, float]:
    """Mean errors of the raw (``mean``) and the filtered (``fmean``) predictions, and how often
    the ±3σ band holds the truth; with ``smooth = (mean, std)`` of the smoother, its errors
    (``"... smoothed"``) and band (``"all in 3sd smoothed"``) too."""
    raw = errors(Y, mean, cols, names)
    filt = errors(Y, fmean, cols, names)
    inside = np.abs(Y - mean) <= 3 * std
    res = {}
    for k, v in raw.items():
        res[f"{k}"] = float(v.mean())
        res[f"{k} filtered"] = float(filt[k].mean())
    if smooth is not None:
        for k, v in errors(Y, smooth[0], cols, names).items():
            res[f"{k} smoothed"] = float(v.mean())
        res["all in 3sd smoothed"] = float((np.abs(Y - smooth[0]) <= 3 * smooth[1]).all(1).mean())
    for j, n in enumerate(names):
        res[f"{n} in 3sd"] = float(inside[:, j].mean())
    res["all in 3sd"] = float(inside.all(1).mean())
    return res
