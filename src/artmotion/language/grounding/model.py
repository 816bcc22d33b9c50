"""A trained compositional grounding model with file-level queries in both directions."""

from __future__ import annotations

import os

import numpy as np

from artmotion.errors import InputError
from artmotion.io.media import read_image
from artmotion.language.grounding.features import audio_feature, render_shape, visual_features
from artmotion.language.grounding.sparse import CompositionalSparse


class Grounder:
    """Speech -> colour, shape and an image; image -> speech features and the words they are nearest to.

    ``fit`` takes the feature dictionary of :func:`artmotion.language.grounding.evaluate.load_features`.
    """

    def __init__(self, seed: int = 0):
        self.seed = seed

    def fit(self, F: dict, idx: np.ndarray | None = None) -> Grounder:
        need = ("colors", "shapes", "color", "shape", "audio_seg")
        if not isinstance(F, dict) or any(k not in F for k in need):
            raise InputError(f"fit needs the feature dictionary of load_features (keys {', '.join(need)})")
        n = len(F["colors"])
        idx = np.arange(n) if idx is None else np.asarray(idx)
        if idx.dtype == bool and idx.shape == (n,):
            idx = np.flatnonzero(idx)
        if idx.ndim != 1 or idx.dtype.kind not in "iu" or not idx.size or (idx < -n).any() or (idx >= n).any():
            raise InputError(f"idx must be the indices of the examples to fit on (whole numbers in [0, {n}), at least "
                             f"one) or a mask of {n} booleans")
        self.model_ = CompositionalSparse(seed=self.seed).fit(
            [F["color"][idx], F["shape"][idx]], [a[idx] for a in F["audio_seg"]]
        )
        self.words_ = []
        for seg, labels in zip(F["audio_seg"], (F["colors"][idx], F["shapes"][idx])):
            names = np.unique(labels)
            self.words_.append((names, np.array([seg[idx][labels == n].mean(axis=0) for n in names])))
        return self

    def _check_fitted(self) -> None:
        if not hasattr(self, "model_"):
            raise InputError("Grounder is not fitted: call fit(features) first")

    def speech_to_visual(self, first_word: np.ndarray, second_word: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Colour (RGB in [0, 1]) and shape descriptor generated from two word features."""
        self._check_fitted()
        c, s = self.model_.audio_to_visual([np.atleast_2d(first_word), np.atleast_2d(second_word)])
        return c[0], s[0]

    def speech_files_to_image(self, first_wav: str | os.PathLike, second_wav: str | os.PathLike, size: int = 128):
        """Rendered RGB image (contour from the generated descriptor, filled with the generated colour)."""
        c, s = self.speech_to_visual(audio_feature(first_wav), audio_feature(second_wav))
        return render_shape(s, c, size=size)

    def image_to_speech(self, image: str | os.PathLike | np.ndarray) -> tuple[list[np.ndarray], list[str]]:
        """Audio features generated for each word segment, and the nearest known word of each."""
        self._check_fitted()
        img = image if isinstance(image, np.ndarray) else read_image(image)
        c, s = visual_features(img, where=None if isinstance(image, np.ndarray) else str(image))
        segs = [g[0] for g in self.model_.visual_to_audio([c[None], s[None]])]
        words = []
        for g, (names, protos) in zip(segs, self.words_):
            words.append(str(names[np.argmin(np.abs(protos - g).sum(axis=1))]))
        return segs, words
