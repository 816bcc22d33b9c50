"""``--bits``: the depth of 16-bit frames when the frames spread over a sequence showed too few.

A 12-bit camera whose sampled frames are all dark (values under 1024) was read as 10-bit, and the
first bright frame stopped `track`, `run` and `articulation video` with an error that left the user
no way on; with values between 1024 and 2047 it was read by its top 8 bits (nearly black). The
depth can now be given."""

import cv2
import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.io.media import DEPTH_FRAMES, frame_depth
from artmotion.io.sequence import open_sequence


def _folder(path, tops, dtype=np.uint16):
    """Frames of noise up to ``tops[k]``; the frames :func:`frame_depth` does not sample are the
    bright ones of the tests below."""
    path.mkdir()
    rng = np.random.default_rng(0)
    for k, top in enumerate(tops, start=1):
        cv2.imwrite(str(path / f"{k:06d}.png"), rng.integers(top // 2, top + 1, (48, 64, 3)).astype(dtype))
    return path


@pytest.fixture
def dark_first(tmp_path):
    """Six 12-bit frames whose sampled five stay under 1024 (they show 10 bits); the fourth is bright."""
    tops = [1000, 1000, 1000, 4000, 1000, 1000]
    sampled = sorted(set(np.linspace(0, len(tops) - 1, DEPTH_FRAMES).round().astype(int).tolist()))
    assert 3 not in sampled
    return _folder(tmp_path / "f12", tops)


def test_track_stops_at_a_frame_beyond_the_depth_shown_and_takes_bits(dark_first, tmp_path, run_cli):
    assert frame_depth(sorted(dark_first.iterdir()))[0] == 10
    det = tmp_path / "det.txt"
    det.write_text("1,-1,10,10,8,16,0.9,-1,-1,-1\n")
    code, out, err = run_cli("track", dark_first, "--det", det)
    assert code == 2 and "Traceback" not in err
    assert err.count("\n") == 1 and "000004.png: values up to" in err and "give their depth with --bits" in err
    code, out, err = run_cli("track", dark_first, "--det", det, "--bits", 12)
    assert code == 0, err
    assert "(16-bit frames (--bits): read as 12-bit, 4095 scaled to 255)" in out
    seq = open_sequence(dark_first)
    seq.set_bits(12)
    imgs = [img for _, img in seq.frames()]
    assert int(imgs[3].max()) == round(4000 * 255 / 4095) and int(imgs[0].max()) < 64
    seq.set_bits(16)                                  # 16: by their top 8 bits, as OpenCV reads them
    assert seq.bits is None and int(next(iter(seq.frames()))[1].max()) == 1000 >> 8


def test_run_and_articulation_video_take_bits(dark_first, tmp_path):
    from artmotion.app.pipeline import run_pipeline
    from artmotion.articulation.video import analyze_video

    det = tmp_path / "det.txt"
    det.write_text("1,-1,10,10,8,16,0.9,-1,-1,-1\n")
    with pytest.raises(InputError, match="give their depth with --bits"):
        run_pipeline(dark_first, tmp_path / "run0", det=det, video=False)
    assert not (tmp_path / "run0").exists()
    res = run_pipeline(dark_first, tmp_path / "run", det=det, video=False, bits=12)
    assert res.depth == (12, None)
    with pytest.raises(InputError, match="give their depth with --bits"):
        analyze_video(dark_first)
    assert analyze_video(dark_first, bits=12).depth == (12, None)


@pytest.mark.parametrize("bits", [7, 17, 12.5, float("nan")])
def test_bits_out_of_range_is_one_line(bits, dark_first, run_cli):
    code, out, err = run_cli("track", dark_first, "--bits", bits)
    assert code == 2 and err.startswith("artmotion: error: ") and err.count("\n") == 1 and "--bits" in err


def test_bits_on_8_bit_frames_is_an_error(tmp_path, run_cli):
    eight = _folder(tmp_path / "f8", [200, 255], dtype=np.uint8)
    code, out, err = run_cli("track", eight, "--bits", 12)
    assert code == 2 and "--bits is for 16-bit image files; these frames are 8-bit" in err
    code, out, err = run_cli("articulation", "video", eight, "--bits", 12)
    assert code == 2 and "--bits is for 16-bit image files" in err


def test_the_depth_of_8_bit_pngs_comes_from_their_header(tmp_path, monkeypatch):
    """Opening a folder of 8-bit PNGs decoded its first frame twice (its size, then its depth);
    the depth now comes from the PNG header, and 16-bit ones are still decoded and measured."""
    import artmotion.io.media as media

    eight = _folder(tmp_path / "f8", [200, 255], dtype=np.uint8)
    sixteen = _folder(tmp_path / "f16", [4000, 4095], dtype=np.uint16)
    calls = []
    real = media.read_image
    monkeypatch.setattr(media, "read_image", lambda *a, **k: calls.append(a[0]) or real(*a, **k))
    assert media.frame_depth(sorted(eight.iterdir())) is None and calls == []
    assert media.frame_depth(sorted(sixteen.iterdir())) == (12, 4095) and len(calls) == 2
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "000001.png").write_bytes(b"\x89PNG\r\n\x1a\n")          # a header cut short: decoded, and refused
    with pytest.raises(InputError, match="000001.png"):
        media.frame_depth(sorted(bad.iterdir()))


def test_pose_predict_notes_the_depth_of_16_bit_crops(tmp_path, run_cli):
    """`pose` read 12-bit crops at their depth but, unlike the other commands, did not say so."""
    import _inputs as inp

    model = inp.pose_model(tmp_path / "model.npz")
    crops = tmp_path / "crops12"
    crops.mkdir()
    for p in sorted((tmp_path / "model-crops").iterdir()):
        cv2.imwrite(str(crops / p.name), (cv2.imread(str(p)).astype(np.uint16) * 16))   # 0-4080: 12 bits
    code, out, err = run_cli("pose", "predict", model, crops, "--out", tmp_path / "p.csv")
    assert code == 0, err
    assert "note: 16-bit frames with values up to" in err and "read as 12-bit, 4095 scaled to 255" in err
    code, out, err = run_cli("pose", "predict", model, tmp_path / "model-crops", "--out", tmp_path / "q.csv")
    assert code == 0 and "16-bit" not in err
