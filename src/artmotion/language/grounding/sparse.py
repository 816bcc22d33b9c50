"""Paired and compositional sparse models linking visual and audio features (thesis 5.3).

Paired model (Eq. 5.1–5.3): visual ``x`` and audio ``y`` share one sparse code ``alpha``,
``x = U alpha`` and ``y = V alpha``. Both dictionaries are learned together as one dictionary on
the concatenated, normalised features (scikit-learn's dictionary learning: l1 penalty ``lam`` on
the codes, every atom ``[U; V]`` in the unit ball). Mapping speech to vision encodes ``y`` on
``V`` alone (Eq. 5.3, lasso) and returns ``U alpha``; vision to speech is the mirror.

Compositional model (Eq. 5.4–5.7): the visual features fall into concepts (colour, shape) and the
speech into segments (words). A linking matrix ``H`` (a permutation) says which segment speaks of
which concept; it is estimated by clustering each concept and each segment separately, scoring
every (concept, segment) pair by the V-measure between their clusterings, and taking the Hungarian
assignment of highest total V-measure. Then one paired model is learned per linked pair.

Normalisation: each block (a concept, a segment, the whole utterance) is standardised per
dimension with the training mean and deviation, then divided by ``sqrt(dim)`` so that every block
has unit expected squared norm whatever its size.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy.optimize import linear_sum_assignment
from sklearn.base import BaseEstimator
from sklearn.cluster import KMeans
from sklearn.decomposition import DictionaryLearning
from sklearn.exceptions import ConvergenceWarning
from sklearn.linear_model import lars_path_gram
from sklearn.metrics import silhouette_score, v_measure_score

from artmotion.errors import InputError, check_range, check_seed, float_array

LAMBDA = 0.15
#: largest number of atoms or iterations the models take
_MAX_COUNT = 2**31 - 1


def _features(name: str, X, dim: int | None = None) -> np.ndarray:
    """``X`` as an ``(N, d)`` float array of finite numbers (``d == dim`` when given), else an
    :class:`InputError` naming ``name``."""
    X = np.atleast_2d(float_array(X, f"{name} features"))
    if X.ndim != 2:
        raise InputError(f"{name} features must be an (examples, dimensions) array, got shape {X.shape}")
    if X.shape[1] == 0:
        raise InputError(f"{name} features have no dimensions: at least one is needed")
    if dim is not None and X.shape[1] != dim:
        raise InputError(f"{name} features must have {dim} dimensions (as in training), got {X.shape[1]}")
    if not np.all(np.isfinite(X)):
        raise InputError(f"{name} features contain NaN or infinite values")
    return X


def _is_block_list(blocks) -> bool:
    """Feature arrays given as a list (or tuple) of them, or as one 3-D array."""
    return isinstance(blocks, (list, tuple)) or (isinstance(blocks, np.ndarray) and blocks.ndim == 3)


def _blocks(visual, audio) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """``visual`` concepts and ``audio`` segments checked: lists (or tuples) of feature arrays,
    as many of each (at least one), every one of finite numbers and all with the same examples
    (rows); else an :class:`InputError` naming the block."""
    for name, blocks, one in (("visual", visual, "concept"), ("audio", audio, "segment")):
        if not _is_block_list(blocks):
            shape = f" of shape {blocks.shape}" if isinstance(blocks, np.ndarray) else ""
            raise InputError(f"{name} must be a list of feature arrays, one per {one}, got {type(blocks).__name__}{shape}")
    if len(visual) != len(audio) or not len(visual):
        raise InputError(f"need as many visual concepts as audio segments (at least one), "
                         f"got {len(visual)} and {len(audio)}")
    named = [(f"visual concept {i + 1}", X) for i, X in enumerate(visual)] + \
        [(f"audio segment {j + 1}", Y) for j, Y in enumerate(audio)]
    arrays = [_features(name, X) for name, X in named]
    n = len(arrays[0])
    for (name, _), X in zip(named, arrays):
        if len(X) != n:
            raise InputError(f"{name} has {len(X)} examples (rows) but {named[0][0]} has {n}: every concept "
                             f"and segment must hold the same examples, row by row")
    return arrays[: len(visual)], arrays[len(visual):]


def _check_model_params(model) -> tuple[int, int]:
    """The parameters of a :class:`PairedSparse` or :class:`CompositionalSparse` checked, as
    ``fit`` needs them (scikit-learn style: a parameter may be set after the model is made);
    ``n_atoms`` and ``max_iter`` as ints."""
    n_atoms = check_range("n_atoms", model.n_atoms, 1, _MAX_COUNT, integer=True)
    check_range("lam", model.lam, 0.0, math.inf, hi_open=True)
    max_iter = check_range("max_iter", model.max_iter, 0, _MAX_COUNT, integer=True)
    check_seed(model.seed, "seed")
    return n_atoms, max_iter


def _not_fitted(cls: str) -> InputError:
    return InputError(f"{cls} is not fitted: call fit() first")


class BlockScaler:
    """Standardise a feature block and weigh it to unit expected squared norm."""

    def fit(self, X: np.ndarray) -> BlockScaler:
        X = np.asarray(X, dtype=float)
        self.mean_ = X.mean(axis=0)
        sd = X.std(axis=0)
        self.scale_ = np.where(sd > 1e-8 * (np.abs(self.mean_).max() + 1), sd, 1.0) * np.sqrt(X.shape[1])
        return self

    def transform(self, X: np.ndarray) -> np.ndarray:
        self._check_fitted()
        return (np.asarray(X, dtype=float) - self.mean_) / self.scale_

    def inverse(self, Z: np.ndarray) -> np.ndarray:
        self._check_fitted()
        return np.asarray(Z, dtype=float) * self.scale_ + self.mean_

    def _check_fitted(self) -> None:
        if not hasattr(self, "mean_"):
            raise _not_fitted("BlockScaler")


class PairedSparse(BaseEstimator):
    """Two dictionaries ``U`` (visual) and ``V`` (audio) coupled by shared l1-sparse codes."""

    def __init__(self, n_atoms: int = 48, lam: float = LAMBDA, max_iter: int = 60, seed: int = 0):
        self.n_atoms, self.lam, self.max_iter, self.seed = n_atoms, lam, max_iter, seed

    def fit(self, X: np.ndarray, Y: np.ndarray) -> PairedSparse:
        """Learn from visual ``X (N, dx)`` and audio ``Y (N, dy)`` of the same ``N`` examples.

        ``n_atoms`` a whole number >= 1, ``lam`` a finite number >= 0, ``max_iter`` a whole number
        >= 0, ``seed`` NumPy's; else an :class:`InputError`."""
        n_atoms, max_iter = _check_model_params(self)
        X, Y = _features("visual", X), _features("audio", Y)
        if len(X) != len(Y):
            raise InputError(f"visual and audio features must pair up row by row, got {len(X)} and {len(Y)} rows")
        if len(X) < 2:
            raise InputError("need at least two paired examples")
        self.sx_, self.sy_ = BlockScaler().fit(X), BlockScaler().fit(Y)
        Z = np.hstack([self.sx_.transform(X), self.sy_.transform(Y)])
        k = int(min(n_atoms, len(X)))
        dl = DictionaryLearning(
            n_components=k, alpha=self.lam, max_iter=max_iter, tol=1e-6,
            fit_algorithm="cd", transform_algorithm="lasso_lars", random_state=self.seed,
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            dl.fit(Z)
        D = dl.components_
        self.dx_ = X.shape[1]
        self.U_, self.V_ = D[:, : self.dx_].copy(), D[:, self.dx_ :].copy()  # atoms as rows
        self.gram_u_, self.gram_v_ = self.U_ @ self.U_.T, self.V_ @ self.V_.T
        return self

    @staticmethod
    def _encode(Z: np.ndarray, D: np.ndarray, lam: float, gram: np.ndarray) -> np.ndarray:
        """Eq. 5.3: ``argmin_a 0.5 ||z - a D||^2 + lam ||a||_1`` for every row ``z`` (exact, LARS)."""
        nf = D.shape[1]
        out = np.zeros((len(Z), len(D)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            for i, z in enumerate(Z):
                _, _, coefs = lars_path_gram(Xy=D @ z, Gram=gram, n_samples=nf, alpha_min=lam / nf, method="lasso")
                out[i] = coefs[:, -1]
        return out

    def _fitted(self) -> None:
        if not hasattr(self, "U_"):
            raise _not_fitted(type(self).__name__)

    def codes_from_audio(self, Y: np.ndarray) -> np.ndarray:
        self._fitted()
        Y = _features("audio", Y, self.V_.shape[1])
        return self._encode(self.sy_.transform(Y), self.V_, self.lam, self.gram_v_)

    def codes_from_visual(self, X: np.ndarray) -> np.ndarray:
        self._fitted()
        X = _features("visual", X, self.dx_)
        return self._encode(self.sx_.transform(X), self.U_, self.lam, self.gram_u_)

    def audio_to_visual(self, Y: np.ndarray) -> np.ndarray:
        """``phi^-1``: visual features generated from audio features."""
        self._fitted()
        return self.sx_.inverse(self.codes_from_audio(Y) @ self.U_)

    def visual_to_audio(self, X: np.ndarray) -> np.ndarray:
        """``phi``: audio features generated from visual features."""
        self._fitted()
        return self.sy_.inverse(self.codes_from_visual(X) @ self.V_)


# ---------------------------------------------------------------------------------------------
# linking matrix H


def cluster_labels(X: np.ndarray, k: int | None = None, k_range=(2, 10), seed: int = 0) -> np.ndarray:
    """K-means labels of standardised ``X``; ``k`` by the best silhouette when not given."""
    Z = BlockScaler().fit(X).transform(X)
    ks = [k] if k else list(range(k_range[0], min(k_range[1], len(Z) - 1) + 1))
    best, best_s = None, -np.inf
    for kk in ks:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            lab = KMeans(n_clusters=kk, n_init=4, random_state=seed).fit_predict(Z)
        if len(ks) == 1:
            return lab
        if len(np.unique(lab)) < 2:
            continue
        s = silhouette_score(Z, lab)
        if s > best_s:
            best, best_s = lab, s
    return best if best is not None else np.zeros(len(Z), int)


def vmeasure_matrix(visual: list[np.ndarray], audio: list[np.ndarray], seed: int = 0) -> np.ndarray:
    """``M[i, j]`` = V-measure between the clusterings of visual concept ``i`` and audio segment ``j``."""
    lv = [cluster_labels(X, seed=seed) for X in visual]
    la = [cluster_labels(Y, seed=seed) for Y in audio]
    return np.array([[v_measure_score(a, b) for b in la] for a in lv])


def estimate_linking(visual: list[np.ndarray], audio: list[np.ndarray], seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Linking matrix ``H`` (``H[i, j] = 1``: visual concept ``i`` is spoken in segment ``j``) and
    the V-measure matrix it was chosen from (Hungarian assignment of maximal total V-measure).

    ``visual`` and ``audio``: lists of feature arrays, as many of each, all of the same examples
    (rows) and finite; else an :class:`InputError` naming the block."""
    visual, audio = _blocks(visual, audio)
    check_seed(seed, "seed")
    M = vmeasure_matrix(visual, audio, seed=seed)
    rows, cols = linear_sum_assignment(-M)
    H = np.zeros_like(M, dtype=int)
    H[rows, cols] = 1
    return H, M


class CompositionalSparse(BaseEstimator):
    """One paired sparse model per (visual concept, audio segment) pair linked by ``H``."""

    def __init__(self, n_atoms: int = 24, lam: float = LAMBDA, max_iter: int = 60, seed: int = 0):
        self.n_atoms, self.lam, self.max_iter, self.seed = n_atoms, lam, max_iter, seed

    def fit(self, visual: list[np.ndarray], audio: list[np.ndarray], H: np.ndarray | None = None) -> CompositionalSparse:
        """Learn ``H`` (unless given) and the paired model of every linked pair.

        ``visual``, ``audio``: lists of feature arrays (one per concept, one per segment), all of
        the same examples (rows); the parameters as :meth:`PairedSparse.fit` takes them."""
        _check_model_params(self)
        visual, audio = _blocks(visual, audio)
        if H is None:
            H, M = estimate_linking(visual, audio, seed=self.seed)
        else:
            M = None
            H = np.asarray(H)
            n = len(visual)
            if H.shape != (n, n) or not np.all((H == 0) | (H == 1)) or not (
                    np.all(H.sum(axis=0) == 1) and np.all(H.sum(axis=1) == 1)):
                raise InputError(f"H must be a permutation matrix of shape ({n}, {n}): 0s and 1s, "
                                 f"one 1 per row and per column")
        self.H_, self.vmeasure_ = np.asarray(H, int), M
        self.link_ = [int(np.argmax(self.H_[i])) for i in range(len(visual))]  # concept -> segment
        self.models_ = [
            PairedSparse(self.n_atoms, self.lam, self.max_iter, self.seed).fit(visual[i], audio[j])
            for i, j in enumerate(self.link_)
        ]
        return self

    def _check_blocks(self, blocks, what: str) -> None:
        if not hasattr(self, "models_"):
            raise _not_fitted(type(self).__name__)
        if not _is_block_list(blocks):
            raise InputError(f"expected a list of {len(self.models_)} {what} (feature arrays), got {type(blocks).__name__}")
        if len(blocks) != len(self.models_):
            raise InputError(f"expected {len(self.models_)} {what}, got {len(blocks)}")

    def audio_to_visual(self, audio: list[np.ndarray]) -> list[np.ndarray]:
        """Visual concept features generated from the audio segments (Eq. 5.6 then ``H``)."""
        self._check_blocks(audio, "audio segments")
        return [m.audio_to_visual(audio[j]) for m, j in zip(self.models_, self.link_)]

    def visual_to_audio(self, visual: list[np.ndarray]) -> list[np.ndarray]:
        """Audio segment features generated from the visual concepts, in segment order."""
        self._check_blocks(visual, "visual concepts")
        out: list = [None] * len(self.link_)
        for i, (m, j) in enumerate(zip(self.models_, self.link_)):
            out[j] = m.visual_to_audio(visual[i])
        return out
