"""Opening sequences: MOTChallenge folders, videos, image folders, and bad input."""

from __future__ import annotations

import shutil

import cv2
import numpy as np
import pytest
from _synth import H, W, moving_blob, write_mot_folder

from artmotion.errors import InputError
from artmotion.tracking import open_sequence


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


def test_an_avi_without_a_frame_rate_is_not_said_to_have_one(tmp_path, mot_folder):
    """A stream header with a rate of 0: FFmpeg says 25 frames/s, which was reported as known."""
    video = tmp_path / "clip.avi"
    wr = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (W, H))
    for png in sorted((mot_folder / "img1").glob("*.png")):
        wr.write(cv2.imread(str(png)))
    wr.release()
    assert open_sequence(video).fps_known
    data = bytearray(video.read_bytes())
    at = data.find(b"strh")
    assert data[at + 8:at + 12] == b"vids"
    data[at + 32:at + 36] = bytes(4)                    # dwRate
    video.write_bytes(bytes(data))
    seq = open_sequence(video)
    assert not seq.fps_known and seq.fps == 25


@pytest.mark.parametrize("damage", ["sample duration", "time scale"])
def test_an_mp4_without_a_frame_rate_is_not_said_to_have_one(tmp_path, mot_folder, damage):
    """A sample of duration 0 in the time-to-sample table, or a media time scale of 0: FFmpeg makes
    up a rate (0.83 frames/s for a 25 frames/s clip), which was reported as known."""
    video = tmp_path / "clip.mp4"
    wr = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (W, H))
    for png in sorted((mot_folder / "img1").glob("*.png")):
        wr.write(cv2.imread(str(png)))
    wr.release()
    seq = open_sequence(video)
    assert seq.fps_known and seq.fps == pytest.approx(10.0)
    data = bytearray(video.read_bytes())
    if damage == "sample duration":
        at = data.find(b"stts")                             # version/flags, entry count, then (count, delta)
        assert int.from_bytes(data[at + 8:at + 12], "big") >= 1
        data[at + 16:at + 20] = bytes(4)
    else:
        at = data.find(b"mdhd")                             # version 0: flags, two times, then the scale
        assert data[at + 4] == 0
        data[at + 16:at + 20] = bytes(4)
    video.write_bytes(bytes(data))
    seq = open_sequence(video)
    assert not seq.fps_known and seq.fps == 25


def test_a_folder_of_frames_with_a_bad_frame_is_an_error_even_beside_a_video(tmp_path, mot_folder):
    """A missing frame made the folder's one video (another take) be read instead, without a word;
    a folder holding only a video is still read as that video."""
    frames = tmp_path / "frames"
    frames.mkdir()
    for png in sorted((mot_folder / "img1").glob("*.png")):
        (frames / png.name).write_bytes(png.read_bytes())
    wr = cv2.VideoWriter(str(frames / "other_take.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (W, H))
    for _ in range(3):
        wr.write(np.zeros((H, W, 3), np.uint8))
    wr.release()
    assert open_sequence(frames).length == 6
    (frames / "000003.png").unlink()
    with pytest.raises(InputError, match="frame 3 is missing"):
        open_sequence(frames)
    for png in frames.glob("*.png"):
        png.unlink()
    seq = open_sequence(frames)
    assert seq.video == frames / "other_take.avi" and seq.name == "frames"


def test_img1_given_as_a_relative_path_is_named_by_its_sequence(mot_folder, monkeypatch):
    monkeypatch.chdir(mot_folder)
    assert open_sequence("img1").name == mot_folder.name


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


def test_an_unnumbered_image_among_frames_is_an_error(mot_folder):
    """The code before sorted by name when any image had no number: a missing frame went unseen
    and thumb.png became the last frame."""
    (mot_folder / "img1" / "000003.png").unlink()
    shutil.copy(mot_folder / "img1" / "000001.png", mot_folder / "img1" / "thumb.png")
    with pytest.raises(InputError, match=r"img1: 5 images are numbered frames and 1 are not \(e.g. thumb.png\)"):
        open_sequence(mot_folder / "img1")


@pytest.mark.parametrize("size", [(W + 1, H), (W, H - 1)])
def test_a_frame_one_pixel_off_is_an_error(mot_folder, size):
    """At full size every frame has the sequence's size exactly (the code before let 1 px pass,
    for the rounding of reduced decoding, and the video writer or KLT failed later)."""
    p = mot_folder / "img1" / "000004.png"
    cv2.imwrite(str(p), cv2.resize(cv2.imread(str(p)), size))
    seq = open_sequence(mot_folder)
    with pytest.raises(InputError, match=rf"000004\.png: image size {size[0]}x{size[1]} differs from the sequence's "):
        list(seq.frames())


@pytest.mark.parametrize("size", [(W - 1, H - 1), (W + 1, H), (1, 1)])
@pytest.mark.parametrize("suffix", [".png", ".jpg"])
def test_a_frame_one_pixel_off_is_an_error_at_reduced_size_too(mot_folder, size, suffix):
    """A reduced decode rounds the size: 639x479 decodes to 640x480's half size, and was accepted
    (tracking went on with a frame of another size); the error gave the reduced size doubled
    (642x480 for 641x480). The header's size is checked, and named."""
    for p in sorted((mot_folder / "img1").iterdir()):
        img = cv2.imread(str(p))
        p.unlink()
        if p.name.startswith("000004"):
            img = cv2.resize(img, size)
        cv2.imwrite(str(p.with_suffix(suffix)), img)
    ini = mot_folder / "seqinfo.ini"
    ini.write_text(ini.read_text().replace("imExt=.png", f"imExt={suffix}"))
    seq = open_sequence(mot_folder)
    for reduce in (1, 2):
        with pytest.raises(InputError, match=rf"000004\{suffix}: image size {size[0]}x{size[1]} differs from the sequence's "):
            list(seq.frames(reduce=reduce))


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


# --- damaged media is an error, never a gray frame (reliability, root cause 1) ---------------


def _jpeg_sequence(tmp_path, n: int = 8):
    frames, truth = moving_blob(n=n)
    root = write_mot_folder(tmp_path / "jseq", frames, [[k + 1, -1, *b, 0.9] for k, b in enumerate(truth)])
    for k, img in enumerate(frames, start=1):                       # JPEG frames instead of PNG
        (root / "img1" / f"{k:06d}.png").unlink()
        cv2.imwrite(str(root / "img1" / f"{k:06d}.jpg"), img)
    ini = root / "seqinfo.ini"
    ini.write_text(ini.read_text().replace("imExt=.png", "imExt=.jpg"))
    return root


@pytest.mark.parametrize("damage", ["truncated", "corrupt"])
def test_damaged_jpeg_frame_is_an_error(tmp_path, damage):
    root = _jpeg_sequence(tmp_path)
    f = root / "img1" / "000005.jpg"
    data = bytearray(f.read_bytes())
    if damage == "truncated":
        data = data[: len(data) // 2]
    else:
        rng = np.random.default_rng(3)
        k = len(data) // 3
        data[k:k + 500] = rng.integers(0, 256, 500, dtype=np.uint8).tobytes()
    f.write_bytes(bytes(data))
    assert cv2.imread(str(f)) is not None           # OpenCV would have decoded it, partly gray
    seq = open_sequence(root)
    with pytest.raises(InputError, match=r"000005\.jpg: (truncated|corrupt) JPEG"):
        list(seq.frames())


def _video(path, frames, fourcc="MJPG"):
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), 10.0, (W, H))
    for img in frames:
        out.write(img)
    out.release()
    return path


@pytest.mark.parametrize("cut", [16, 0.5])
def test_truncated_video_is_an_error(tmp_path, cut):
    """An AVI cut short of the size its header declares: OpenCV plays the frames left (all of
    them when only the index at the end is cut) and says nothing."""
    frames, _ = moving_blob(n=40)
    video = _video(tmp_path / "clip.avi", frames)
    data = video.read_bytes()
    video.write_bytes(data[: len(data) - (cut if isinstance(cut, int) else int(len(data) * cut))])
    with pytest.raises(InputError, match=r"clip\.avi: truncated: \d+ of the \d+ bytes its header declares"):
        open_sequence(video)


def test_a_video_that_ends_early_is_an_error(tmp_path):
    """Frames that do not decode at the end of a video whose header counts 40: FFmpeg reports the
    first of them as it fails to decode it; were it silent, the count would say it (below)."""
    frames, _ = moving_blob(n=40)
    video = _video(tmp_path / "clip.avi", frames)
    data = bytearray(video.read_bytes())
    data[len(data) // 2: -2000] = bytes(len(data) // 2 - 2000)
    video.write_bytes(bytes(data))
    seq = open_sequence(video)
    assert seq.length == 40                          # the header still says 40
    with pytest.raises(InputError, match=r"clip\.avi: damaged data at frame 20: FFmpeg decoded around it"):
        list(seq.frames())


def test_a_video_that_ends_early_in_silence_is_an_error(tmp_path, monkeypatch):
    """The same when FFmpeg says nothing (the frames after the 25th simply do not come)."""
    import artmotion.io.sequence as sequence_mod

    frames, _ = moving_blob(n=40)
    video = _video(tmp_path / "clip.avi", frames)
    read = sequence_mod.read_video_frame
    monkeypatch.setattr(sequence_mod, "read_video_frame",
                        lambda cap, path, number: read(cap, path, number) if number <= 25 else None)
    seq = open_sequence(video)
    with pytest.raises(InputError, match=r"clip\.avi: video ends after 25 of its 40 frames: frame 26 cannot be decoded"):
        list(seq.frames())


@pytest.mark.parametrize("count", [0, 3])
def test_a_header_that_counts_too_few_frames_loses_none(tmp_path, count):
    """An AVI whose stream header counts fewer frames than it holds (a recorder stopped before it
    wrote the count): every frame that decodes is read (not the first ``count``), and the
    sequence's length is the true count once read."""
    import struct

    frames, _ = moving_blob(n=20)
    video = _video(tmp_path / "clip.avi", frames)
    data = bytearray(video.read_bytes())
    at = data.find(b"strh")
    struct.pack_into("<I", data, at + 40, count)     # dwLength: the stream's frame count
    video.write_bytes(bytes(data))
    seq = open_sequence(video)
    read = [n for n, _ in seq.frames()]
    assert read == list(range(1, 21))
    assert seq.length == 20
    assert [n for n, _ in seq.frames()] == read      # read again, the same


def test_seqlength_must_match_the_video(tmp_path):
    frames, _ = moving_blob(n=12)
    root = tmp_path / "vseq"
    root.mkdir()
    _video(root / "clip.avi", frames)
    (root / "seqinfo.ini").write_text("[Sequence]\nname=v\nframeRate=10\nseqLength=500\n")
    with pytest.raises(InputError, match="says 500 frames but clip.avi has 12"):
        open_sequence(root)
    (root / "seqinfo.ini").write_text("[Sequence]\nname=v\nframeRate=10\nseqLength=12\n")
    assert open_sequence(root).length == 12


@pytest.mark.parametrize("line, needle", [("frameRate=inf", "out of range"), ("frameRate=nan", "out of range"),
                                          ("frameRate=-3", "out of range"), ("frameRate=1e400", "out of range"),
                                          ("seqLength=6.5", "not a whole number"), ("seqLength=inf", "out of range")])
def test_seqinfo_numbers_are_finite_and_in_range(mot_folder, line, needle):
    (mot_folder / "seqinfo.ini").write_text(f"[Sequence]\nname=b\n{line}\n")
    with pytest.raises(InputError, match=needle):
        open_sequence(mot_folder)


def test_seqinfo_syntax_error_is_one_line(mot_folder):
    (mot_folder / "seqinfo.ini").write_text("[Sequence]\nname=b\nthis is not a setting\n")
    with pytest.raises(InputError) as info:
        open_sequence(mot_folder)
    assert "seqinfo.ini:3:" in str(info.value) and "\n" not in str(info.value)


# --- anything is not a video (root cause 2) ---------------------------------------------------


def test_text_file_is_not_a_video(tmp_path):
    notes = tmp_path / "notes.txt"
    notes.write_text("hello\n" * 100)
    with pytest.raises(InputError, match="notes.txt: not a video file name"):
        open_sequence(notes)


@pytest.mark.parametrize("content, needle", [(b"hello world\n" * 50, "not a video"), ("jpeg", "is an image")])
def test_renamed_file_is_not_a_video(tmp_path, content, needle):
    fake = tmp_path / "clip.mp4"
    if content == "jpeg":
        frames, _ = moving_blob(n=1)
        content = cv2.imencode(".jpg", frames[0])[1].tobytes()
    fake.write_bytes(content)
    with pytest.raises(InputError, match=f"clip.mp4: {needle}"):
        open_sequence(fake)


# --- a companion file that is not a file (root cause 6) ---------------------------------------


def test_detections_that_are_a_folder_are_an_error(mot_folder):
    (mot_folder / "det" / "det.txt").unlink()
    (mot_folder / "det" / "det.txt").mkdir()
    with pytest.raises(InputError, match=r"det\.txt: not a file"):
        open_sequence(mot_folder)


def test_frames_that_are_not_files_are_errors_not_skipped(tmp_path):
    """A FIFO as seqinfo.ini was ignored (the folder then read as a folder of images); a folder, a
    pipe or a broken link named like the last frame was skipped (a lost frame); a missing frame's
    error named the next file as the culprit."""
    import os

    img = np.full((24, 32, 3), 90, np.uint8)
    seq = tmp_path / "seq"
    (seq / "img1").mkdir(parents=True)
    for k in (1, 2, 3):
        cv2.imwrite(str(seq / "img1" / f"{k:06d}.jpg"), img)
    os.mkfifo(seq / "seqinfo.ini")
    with pytest.raises(InputError, match="seqinfo.ini: not a file"):
        open_sequence(seq)
    folder = tmp_path / "frames"
    folder.mkdir()
    for k in (1, 2, 3):
        cv2.imwrite(str(folder / f"{k:06d}.jpg"), img)
    (folder / "000004.jpg").symlink_to(tmp_path / "gone.jpg")
    with pytest.raises(InputError, match="000004.jpg: named as an image but not a file"):
        open_sequence(folder)
    (folder / "000004.jpg").unlink()
    (folder / "000002.jpg").unlink()
    with pytest.raises(InputError, match=r"frame 2 is missing \(after 000001.jpg comes 000003.jpg;"):
        open_sequence(folder)


def _exif_oriented(jpeg: bytes, orientation: int) -> bytes:
    """``jpeg`` with an EXIF segment whose orientation tag is ``orientation``."""
    import struct

    tiff = b"II*\x00" + struct.pack("<IH", 8, 1) + struct.pack("<HHIHH", 0x0112, 3, 1, orientation, 0) + b"\0" * 4
    payload = b"Exif\x00\x00" + tiff
    return jpeg[:2] + b"\xff\xe1" + struct.pack(">H", len(payload) + 2) + payload + jpeg[2:]


def test_frames_are_read_as_stored_whatever_their_orientation_tag(tmp_path, mot_folder, run_cli):
    """Detections, ground truth and seqinfo.ini are in stored pixels: OpenCV's default turned the
    frames by their EXIF or container tag, so seqinfo.ini's size was refused and boxes beyond the
    turned frame were dropped without a word. The summary says the tag was not applied."""
    from artmotion.io.media import exif_orientation

    plain, turned = tmp_path / "plain", tmp_path / "turned"
    for root, orientation in ((plain, 1), (turned, 6)):
        shutil.copytree(mot_folder, root)
        for png in sorted((root / "img1").glob("*.png")):
            jpeg = cv2.imencode(".jpg", cv2.imread(str(png)))[1].tobytes()
            png.with_suffix(".jpg").write_bytes(_exif_oriented(jpeg, orientation))
            png.unlink()
        ini = root / "seqinfo.ini"
        ini.write_text(ini.read_text().replace(".png", ".jpg"))
    first = turned / "img1" / "000001.jpg"
    assert exif_orientation(np.fromfile(first, np.uint8)) == 6
    assert cv2.imread(str(first)).shape[:2] == (W, H)           # OpenCV's default turns it
    seq = open_sequence(turned)
    assert (seq.width, seq.height, seq.orientation) == (W, H, "turn 90°")
    assert all(img.shape[:2] == (H, W) for _, img in seq.frames())
    assert open_sequence(plain).orientation == ""
    outs = {}
    for root in (plain, turned):
        code, out, err = run_cli("track", root, "--out", tmp_path / f"{root.name}.txt")
        assert code == 0, err
        outs[root.name] = (tmp_path / f"{root.name}.txt").read_text()
        assert ("as stored (not turned as its orientation tag asks: turn 90°)" in out) == (root is turned)
    assert outs["turned"] == outs["plain"] and outs["plain"]

    # a video whose track header asks for a turn of 90 degrees
    video = tmp_path / "clip.mp4"
    wr = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (W, H))
    for png in sorted((mot_folder / "img1").glob("*.png")):
        wr.write(cv2.imread(str(png)))
    wr.release()
    data = bytearray(video.read_bytes())
    at = data.find(b"tkhd") + 4 + 4 + 4 * 5 + 8 + 8              # the version-0 header's matrix
    data[at:at + 36] = b"".join(v.to_bytes(4, "big", signed=True)
                                for v in (0, 0x10000, 0, -0x10000, 0, 0, 0, 0, 0x40000000))
    video.write_bytes(bytes(data))
    seq = open_sequence(video)
    assert (seq.width, seq.height, seq.orientation) == (W, H, "turn 90°")
    assert all(img.shape[:2] == (H, W) for _, img in seq.frames())


def test_every_reader_of_a_12_bit_sequence_sees_its_depth(tmp_path, run_cli):
    """12-bit frames in 16-bit PNGs: the depth was decided by tool train and tool track alone, so
    `track`, `run`'s annotated video and its pose crops read them by their top 8 bits (0-15:
    nearly black). It is now the sequence's: every reader sees the same frames, reduced or not,
    and `track` says so."""
    rng = np.random.default_rng(0)
    frames = tmp_path / "f12"
    frames.mkdir()
    for k, top in enumerate([4000, 4095, 3000], start=1):
        cv2.imwrite(str(frames / f"{k:06d}.png"), rng.integers(0, top + 1, (48, 64, 3)).astype(np.uint16))
    seq = open_sequence(frames)
    assert seq.depth == (12, 4095)
    for reduce in (1, 2):
        imgs = [img for _, img in seq.frames(reduce=reduce)]
        assert all(i.dtype == np.uint8 for i in imgs) and min(int(i.max()) for i in imgs) > 120  # (top 8 bits: 15)
        assert imgs[0].shape[:2] == (-(-48 // reduce), -(-64 // reduce))
    det = tmp_path / "det.txt"
    det.write_text("1,-1,10,10,8,16,0.9,-1,-1,-1\n")
    code, out, err = run_cli("track", frames, "--det", det)
    assert code == 0, err
    assert "(16-bit frames with values up to 4095 (in 5 spread over the sequence): read as 12-bit" in out
    eight = tmp_path / "f8"
    eight.mkdir()
    for k in (1, 2):
        cv2.imwrite(str(eight / f"{k:06d}.png"), np.full((48, 64, 3), 200, np.uint8))
    assert open_sequence(eight).depth is None


def test_a_mot_folder_without_seqinfo_reads_its_img1(mot_folder):
    """2DMOT2015's first release has no seqinfo.ini: the folder was 'no images in folder' though its
    frames were in img1/ (found by a fuzzing review). Its frames, detections and ground truth are
    read; the frame rate is assumed, and said to be."""
    (mot_folder / "seqinfo.ini").unlink()
    seq = open_sequence(mot_folder)
    assert seq.length == 6 and seq.name == "seq" and seq.det_path is not None and not seq.fps_known
    assert sum(1 for _ in seq.frames()) == 6
