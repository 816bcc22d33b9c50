"""Linking matrix and sparse models on synthetic features with known structure."""

import numpy as np
import pytest

from artmotion.language.grounding.sparse import (
    CompositionalSparse,
    PairedSparse,
    estimate_linking,
)


def synthetic(n=120, seed=0, perm=(2, 0, 1)):
    """Three visual concepts with 3, 4 and 5 categories; audio segment perm[i] speaks of concept i
    through a random linear map plus noise."""
    rng = np.random.default_rng(seed)
    ks, dims = (3, 4, 5), (3, 12, 8)
    labels = [rng.integers(0, k, n) for k in ks]
    visual, audio = [], [None] * 3
    for i, (k, d) in enumerate(zip(ks, dims)):
        centres = rng.normal(0, 3, (k, d))
        visual.append(centres[labels[i]] + rng.normal(0, 0.3, (n, d)))
        words = rng.normal(0, 3, (k, 20))
        audio[perm[i]] = words[labels[i]] @ rng.normal(0, 1, (20, 30)) + rng.normal(0, 0.5, (n, 30))
    return visual, audio, labels


@pytest.mark.parametrize("perm", [(2, 0, 1), (0, 1, 2), (1, 2, 0)])
def test_linking_matrix_recovers_permutation(perm):
    visual, audio, _ = synthetic(perm=perm, seed=sum(perm))
    H, M = estimate_linking(visual, audio)
    expected = np.zeros((3, 3), int)
    expected[np.arange(3), perm] = 1
    assert (H == expected).all(), M
    assert (M[np.arange(3), perm] > 0.8).all()


def test_paired_model_maps_both_ways():
    visual, audio, labels = synthetic(perm=(0, 1, 2))
    X, Y = visual[1], audio[1]
    m = PairedSparse(n_atoms=24, seed=0).fit(X[:90], Y[:90])
    gx = m.audio_to_visual(Y[90:])
    gy = m.visual_to_audio(X[90:])
    assert gx.shape == X[90:].shape and gy.shape == Y[90:].shape
    # generated features are nearest to their own category
    cent = np.array([X[:90][labels[1][:90] == c].mean(0) for c in range(4)])
    pred = np.argmin(np.abs(gx[:, None] - cent[None]).sum(-1), axis=1)
    assert (pred == labels[1][90:]).mean() > 0.9
    centy = np.array([Y[:90][labels[1][:90] == c].mean(0) for c in range(4)])
    pred = np.argmin(np.abs(gy[:, None] - centy[None]).sum(-1), axis=1)
    assert (pred == labels[1][90:]).mean() > 0.9


def test_compositional_generalises_to_unseen_combinations():
    visual, audio, labels = synthetic(n=200, perm=(1, 0, 2), seed=3)
    visual, audio = visual[:2], audio[:2]  # two concepts; segment j speaks of concept 1-j
    seen = ~((labels[0] == 0) & (labels[1] == 0))
    m = CompositionalSparse(n_atoms=16, seed=0).fit([v[seen] for v in visual], [a[seen] for a in audio])
    assert (m.H_ == np.array([[0, 1], [1, 0]])).all()
    gen = m.audio_to_visual([a[~seen] for a in audio])
    for i, k in enumerate((3, 4)):
        cent = np.array([visual[i][seen][labels[i][seen] == c].mean(0) for c in range(k)])
        pred = np.argmin(np.abs(gen[i][:, None] - cent[None]).sum(-1), axis=1)
        assert (pred == 0).mean() > 0.9


def test_deterministic_for_a_seed():
    visual, audio, _ = synthetic()
    a = PairedSparse(n_atoms=12, seed=4).fit(visual[0], audio[1]).audio_to_visual(audio[1][:5])
    b = PairedSparse(n_atoms=12, seed=4).fit(visual[0], audio[1]).audio_to_visual(audio[1][:5])
    assert np.array_equal(a, b)


def test_models_before_fit_and_non_finite_features_are_input_errors():
    from artmotion.errors import InputError

    with pytest.raises(InputError, match="not fitted"):
        CompositionalSparse().audio_to_visual([np.zeros((1, 13))] * 2)
    with pytest.raises(InputError, match="not fitted"):
        PairedSparse().audio_to_visual(np.zeros((1, 13)))
    with pytest.raises(InputError, match="not fitted"):
        PairedSparse().codes_from_visual(np.zeros((1, 5)))
    rng = np.random.default_rng(0)
    X, Y = rng.normal(size=(20, 5)), rng.normal(size=(20, 7))
    with pytest.raises(InputError, match="pair up row by row"):
        PairedSparse().fit(X, Y[:5])
    for v in (np.nan, np.inf):
        bad = Y.copy()
        bad[0, 0] = v
        with pytest.raises(InputError, match="audio features contain NaN or infinite"):
            PairedSparse().fit(X, bad)
    m = PairedSparse(n_atoms=6).fit(X, Y)
    bad = Y[:2].copy()
    bad[1, 3] = np.nan
    with pytest.raises(InputError, match="audio features contain NaN or infinite"):
        m.audio_to_visual(bad)
    with pytest.raises(InputError, match="7 dimensions"):
        m.audio_to_visual(Y[:2, :3])
    with pytest.raises(InputError, match="permutation matrix"):
        CompositionalSparse(n_atoms=4).fit([X, X], [Y, Y], H=np.ones((2, 2)))
