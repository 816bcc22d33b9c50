"""Opening sequences: MOTChallenge folders, videos, image folders, and bad input."""

from __future__ import annotations

import shutil

import cv2
import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.tracking import open_sequence

from _synth import H, W, moving_blob, write_mot_folder


@pytest.fixture
def mot_folder(tmp_path):
    frames, truth = moving_blob(n=6)
    rows = [[k + 1, -1, *b, 0.9] for k, b in enumerate(truth)]
    return write_mot_folder(tmp_path / "seq", frames, rows, fps=12.5, name="blobby")


def test_mot_folder(mot_folder):
    seq = open_sequence(mot_folder)
    assert (seq.name, seq.fps, seq.width, seq.height, seq.length) == ("blobby", 12.5, W, H, 6)
    assert seq.det_path == mot_folder / "det" / "det.txt" and seq.gt_path is None
    got = list(seq.frames())
    assert [n for n, _ in got] == [1, 2, 3, 4, 5, 6]
    img = got[0][1]
    assert img.dtype == np.uint8 and img.shape == (H, W, 3)


def test_sample_mot_folder_with_video(sample_seq):
    seq = open_sequence(sample_seq)
    assert seq.name == "TUD-Campus" and seq.fps == 25 and (seq.width, seq.height) == (640, 480)
    assert seq.length == 71 and seq.det_path.name == "det.txt" and seq.gt_path.name == "gt.txt"
    n = sum(1 for _ in seq.frames())
    assert n == 71


def test_video_file_and_image_folder(tmp_path, mot_folder):
    frames = [cv2.imread(str(p)) for p in sorted((mot_folder / "img1").glob("*.png"))]
    video = tmp_path / "clip.avi"
    wr = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (W, H))
    for f in frames:
        wr.write(f)
    wr.release()
    seq = open_sequence(video)
    assert seq.name == "clip" and seq.fps == pytest.approx(10.0) and seq.width == W
    assert sum(1 for _ in seq.frames()) == len(frames)
    folder = open_sequence(mot_folder / "img1")
    assert folder.length == 6 and folder.name == "seq" and folder.det_path is not None


def test_missing_source(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        open_sequence(tmp_path / "nope")


def test_empty_folder(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError) as e:
        open_sequence(tmp_path / "empty")
    assert "no images" in str(e.value) and "empty" in str(e.value)


def test_missing_frame_is_out_of_order(mot_folder):
    (mot_folder / "img1" / "000003.png").unlink()
    with pytest.raises(InputError, match="000004.png"):
        open_sequence(mot_folder)


def test_frame_count_disagrees_with_seqinfo(mot_folder):
    shutil.copy(mot_folder / "img1" / "000006.png", mot_folder / "img1" / "000007.png")
    with pytest.raises(InputError, match="seqinfo.ini says 6 frames"):
        open_sequence(mot_folder)


def test_corrupt_image_names_the_file(mot_folder):
    (mot_folder / "img1" / "000004.png").write_bytes(b"not a png")
    seq = open_sequence(mot_folder)
    with pytest.raises(InputError, match="000004.png"):
        list(seq.frames())


def test_broken_video(tmp_path):
    bad = tmp_path / "broken.mp4"
    bad.write_bytes(b"\x00" * 2048)
    with pytest.raises(InputError, match="broken.mp4"):
        open_sequence(bad)


def test_bad_seqinfo(mot_folder):
    (mot_folder / "seqinfo.ini").write_text("[Sequence]\nframeRate=fast\n")
    with pytest.raises(InputError, match="frameRate|framerate"):
        open_sequence(mot_folder)
