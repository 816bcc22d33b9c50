"""Visual and audio features: invariances and bad input."""

import cv2
import numpy as np
import pytest
import soundfile as sf

from artmotion.errors import InputError
from artmotion.language.grounding.dataset import shape_polygon, table_background
from artmotion.language.grounding.features import (
    AUDIO_DIM,
    SHAPE_DIM,
    audio_feature,
    audio_feature_from_samples,
    render_shape,
    segment_shape,
    visual_features,
)


def draw(shape, rot_deg, scale, cx=160, cy=120, rgb=(205, 40, 40), seed=0):
    rng = np.random.default_rng(seed)
    img = table_background(rng, 240, 320)
    r = np.deg2rad(rot_deg)
    R = np.array([[np.cos(r), -np.sin(r)], [np.sin(r), np.cos(r)]])
    pts = shape_polygon(shape) @ R.T * scale + [cx, cy]
    mask = np.zeros((240, 320), np.uint8)
    cv2.fillPoly(mask, [np.round(pts * 16).astype(np.int32)], 255, lineType=cv2.LINE_AA, shift=4)
    a = mask[..., None] / 255.0
    img = img * (1 - a) + np.array(rgb, float) * a + rng.normal(0, 3, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)[:, :, ::-1].copy()


@pytest.mark.parametrize("shape", ["triangle", "rectangle", "halfcircle", "trapezium", "square"])
def test_shape_descriptor_invariant_to_rotation_scale_position(shape):
    ref_c, ref = visual_features(draw(shape, 0, 40))
    assert ref.shape == (SHAPE_DIM,)
    others = {s: visual_features(draw(s, 0, 40))[1] for s in ("circle", "triangle", "rectangle", "halfcircle", "trapezium", "square") if s != shape}
    nearest_other = min(np.abs(ref - o).sum() for o in others.values())
    for rot, scale, cx, cy in [(37, 40, 160, 120), (140, 30, 90, 80), (255, 52, 200, 140), (90, 45, 150, 110)]:
        c, d = visual_features(draw(shape, rot, scale, cx, cy, seed=rot))
        dist = np.abs(d - ref).sum()
        assert dist < 0.35 * nearest_other, (rot, scale, dist, nearest_other)
        assert np.abs(c - ref_c).max() < 0.03


def test_colour_feature_is_mean_rgb():
    c, _ = visual_features(draw("square", 20, 40, rgb=(40, 150, 65)))
    assert np.allclose(c, np.array([40, 150, 65]) / 255, atol=0.03)


def test_no_shape_is_an_input_error():
    img = table_background(np.random.default_rng(0), 240, 320).astype(np.uint8)
    with pytest.raises(InputError, match="no shape"):
        segment_shape(img, where="empty.png")


def test_render_shape_from_descriptor():
    _, d = visual_features(draw("triangle", 10, 40))
    img = render_shape(d, np.array([1.0, 0, 0]), size=96)
    red = (img[..., 0] > 200) & (img[..., 1] < 50)
    assert img.shape == (96, 96, 3) and 0.15 < red.mean() < 0.6


def tone(sr=16000, dur=0.5, f=440.0):
    t = np.arange(int(sr * dur)) / sr
    env = np.sin(np.pi * t / dur)
    return (0.3 * env * np.sin(2 * np.pi * f * t)).astype(np.float32)


def test_audio_feature_shape_and_speed_robustness(tmp_path):
    sr = 16000
    a = audio_feature_from_samples(tone(sr, 0.5, 440), sr)
    b = audio_feature_from_samples(tone(sr, 0.8, 440), sr)  # the same sound, slower
    c = audio_feature_from_samples(tone(sr, 0.5, 1500), sr)
    assert a.shape == (AUDIO_DIM,)
    assert np.abs(a - b).sum() < 0.5 * np.abs(a - c).sum()
    p = tmp_path / "tone.wav"
    sf.write(p, tone(sr), sr)
    assert np.allclose(audio_feature(p), a, rtol=1e-3, atol=0.05)  # 16-bit PCM


def test_bad_audio_is_an_input_error(tmp_path):
    notaudio = tmp_path / "x.wav"
    notaudio.write_text("this is not a wav file\n")
    with pytest.raises(InputError, match="x.wav: not a readable audio"):
        audio_feature(notaudio)
    silent = tmp_path / "silent.wav"
    sf.write(silent, np.zeros(16000, np.float32), 16000)
    with pytest.raises(InputError, match="silent.wav: silent"):
        audio_feature(silent)
    with pytest.raises(InputError, match="no such file"):
        audio_feature(tmp_path / "nope.wav")
    cut = tmp_path / "cut.wav"     # libsndfile reads the third that is left without a word
    sf.write(cut, tone(16000), 16000)
    cut.write_bytes(cut.read_bytes()[: cut.stat().st_size // 3])
    with pytest.raises(InputError, match=r"cut.wav: truncated: \d+ of the \d+ bytes its header declares"):
        audio_feature(cut)
    slow = tmp_path / "slow.wav"   # 1 Hz: a second of "speech" in one sample
    sf.write(slow, np.full(100, 0.5, np.float32), 1)
    with pytest.raises(InputError, match="slow.wav: sample rate 1 Hz: speech needs at least 8000 Hz"):
        audio_feature(slow)
