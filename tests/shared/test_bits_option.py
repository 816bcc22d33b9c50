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
