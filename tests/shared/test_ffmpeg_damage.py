"""Damage that FFmpeg decodes around. A video whose frame data is broken in the middle still
decodes: FFmpeg conceals the broken macroblocks (fills them from their neighbours) and says so only
in its log, so the frame came out partly wrong and the run succeeded. A cut MPEG program stream
(no frame count to compare with) ended on a partly decoded frame. Both are now errors naming the
file and the frame; a clean video gives none, and FFmpeg's lines never reach stderr."""

from __future__ import annotations

import os
import subprocess
import sys

import cv2
import numpy as np
import pytest
from _inputs import assert_one_line_error

from artmotion.errors import InputError
from artmotion.io.sequence import open_sequence

W, H, N = 320, 240, 60


def _write(path, fourcc: str):
    """A textured scene panning under a red disc, ``N`` frames."""
    bg = np.random.default_rng(0).integers(0, 256, (H, W, 3), dtype=np.uint8)
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), 25.0, (W, H))
    for f in range(N):
        img = np.roll(bg, 2 * f, axis=1)
        cv2.circle(img, (40 + 3 * f, H // 2), 20, (0, 0, 255), -1)
        out.write(img)
    out.release()
    assert path.stat().st_size > 0
    return path


def _broken(path, out):
    """``path`` with 200 bytes in its middle inverted (the container's structure is elsewhere)."""
    data = bytearray(path.read_bytes())
    mid = len(data) // 2
    for k in range(200):
        data[mid + 7 * k] ^= 0xFF
    out.write_bytes(bytes(data))
    return out


def _cut(path, out, share: float):
    """The first ``share`` of ``path``'s bytes, at ``out``."""
    data = path.read_bytes()
    out.write_bytes(data[: int(len(data) * share)])
    return out


def _frames(path):
    cap = cv2.VideoCapture(str(path))
    got = []
    while True:
        ok, img = cap.read()
        if not ok:
            return got
        got.append(img)


def test_a_frame_ffmpeg_conceals_is_an_error_at_that_frame(tmp_path):
    clean = _write(tmp_path / "clean.mp4", "mp4v")
    bad = _broken(clean, tmp_path / "bad.mp4")
    a, b = _frames(clean), _frames(bad)
    assert len(a) == len(b) == N                      # OpenCV alone: every frame, no word of the damage
    wrong = [k for k in range(N) if np.abs(a[k].astype(int) - b[k]).mean() > 1]
    assert wrong                                      # ... though some of them are wrong
    assert [n for n, _ in open_sequence(clean).frames()] == list(range(1, N + 1))
    with pytest.raises(InputError, match=rf"bad\.mp4: damaged data at frame {wrong[0] + 1}: FFmpeg decoded "
                                         r"around it \(mpeg4: "):
        list(open_sequence(bad).frames())


def test_a_cut_mpeg_stream_ends_on_an_error_not_a_partial_frame(tmp_path):
    """An MPEG program stream states no frame count: cut, its last frame decoded in part."""
    clean = _write(tmp_path / "clean.mpg", "PIM1")
    assert [n for n, _ in open_sequence(clean).frames()] == list(range(1, N + 1))
    cut = _cut(clean, tmp_path / "cut.mpg", 0.77)
    with pytest.raises(InputError, match=r"cut\.mpg: damaged data at (frame \d+|the end, after frame \d+): FFmpeg "
                                         r"decoded around it"):
        list(open_sequence(cut).frames())


def test_damage_ffmpeg_reports_while_opening_is_an_error(tmp_path):
    """Opening reads into the file: a cut FLV's damage is reported then, and then never again."""
    clean = _write(tmp_path / "clean.flv", "FLV1")
    assert [n for n, _ in open_sequence(clean).frames()] == list(range(1, N + 1))
    cut = _cut(clean, tmp_path / "cut.flv", 0.99)
    with pytest.raises(InputError, match=r"cut\.flv: damaged: FFmpeg found broken data while opening it \(flv: "):
        open_sequence(cut)


@pytest.mark.parametrize("said, mine, first", [
    (["[mpeg4 @ 0x55d0c0a8] illegal dc vlc", "[mpeg4 @ 0x55d0c0a8] Error at MB: 171"], {0, 1}, "mpeg4: illegal dc vlc"),
    # in colour (AV_LOG_FORCE_COLOR), the colour's end on a line of its own
    (["\x1b[0;36m[mpeg4 @ 0x7f0d200363c0] \x1b[0m\x1b[1;31mac-tex damaged at 19 9", "\x1b[0m"], {0, 1},
     "mpeg4: ac-tex damaged at 19 9"),
    # logged without a context: no prefix
    (["Truncating packet of size 5854 to 2620"], {0}, "Truncating packet of size 5854 to 2620"),
    # a prefix whose text msmpeg4 puts on the next line (a message FFmpeg logs without a context)
    (["[wmv1 @ 0x55d0c0a8] ", "error while decoding block: 19 x 0 (5)"], {0, 1},
     "error while decoding block: 19 x 0 (5)"),
    (["[wmv1 @ 0x1] ", "Traceback (most recent call last):"], {0}, None),
    # after another writer's unfinished line: FFmpeg's text starts after it
    (["\rbar 2[mpeg4 @ 0x1] illegal dc vlc"], {0}, "mpeg4: illegal dc vlc"),
    # another thread's line is not FFmpeg's
    (["track:  40%|####      | 28/71", "[h264 @ 0x1] no frame!"], {1}, "h264: no frame!"),
    ([], set(), None),
])
def test_which_lines_are_ffmpegs(said, mine, first):
    from artmotion.io.media import _ffmpeg_said

    got, said_first = _ffmpeg_said(said)
    assert (set(got), said_first) == (mine, first)


@pytest.mark.parametrize("said, damage", [
    (["[flv @ 0x55d0c0a8] Packet mismatch 0 113 34094"], "flv: Packet mismatch 0 113 34094"),
    # an audio stream's damage (no audio is read), and a header's timing FFmpeg replaces by a default
    (["[aac @ 0x1] channel element 1.0 is not allocated", "[mp3float @ 0x2] Header missing"], None),
    (["[mov,mp4,m4a,3gp,3g2,mj2 @ 0x3] Invalid mdhd time scale 0, defaulting to 1"], None),
    (["[aac @ 0x1] Input buffer exhausted", "[mov,mp4,m4a,3gp,3g2,mj2 @ 0x3] stream 0, offset 0x30: partial file"],
     "mov,mp4,m4a,3gp,3g2,mj2: stream 0, offset 0x30: partial file"),
])
def test_what_ffmpeg_says_while_opening(said, damage):
    from artmotion.io.media import _opening_damage

    assert _opening_damage(said) == damage


def _in_thread(fn, timeout=60.0):
    """``fn()`` on a daemon thread, its result or exception; an AssertionError if it does not end
    (a deadlock fails the test instead of hanging it)."""
    import threading

    out: list = []

    def run():
        try:
            out.append(("ok", fn()))
        except BaseException as exc:  # handed back
            out.append(("raised", exc))

    worker = threading.Thread(target=run, daemon=True)
    worker.start()
    worker.join(timeout)
    assert out, "did not end (deadlock)"
    kind, value = out[0]
    if kind == "raised":
        raise value
    return value


def test_other_output_passes_as_written_and_captures_nest(tmp_path, capfd):
    """What another writer puts on stderr during a capture (a progress bar's carriage returns) is
    passed on as it was written, without FFmpeg's lines; a capture inside another on one thread
    sees its own block's lines (it waited for itself before)."""
    from artmotion.io.media import _stderr_captured, ffmpeg_quiet, open_capture, read_video_frame

    def nest():
        with _stderr_captured(()) as outer:
            os.write(2, b"\rbar 1\rbar 2")
            os.write(2, b"[mpeg4 @ 0x55d0c0a8] illegal dc vlc\n")
            with _stderr_captured(()) as inner:
                os.write(2, b"[mjpeg @ 0x1] overread 8\n")
            os.write(2, b"\rbar 3")
        return outer, inner

    outer, inner = _in_thread(nest)
    assert inner == ["[mjpeg @ 0x1] overread 8"]
    assert "[mjpeg @ 0x1] overread 8" in outer and outer[-1] == "bar 3"      # the outer sees it all
    assert capfd.readouterr().err == "\rbar 1\rbar 2\rbar 3"

    bad = _broken(_write(tmp_path / "clean.mp4", "mp4v"), tmp_path / "bad.mp4")

    def read_inside_a_capture():
        with ffmpeg_quiet():
            cap = open_capture(bad)
            try:
                for number in range(1, N + 1):
                    read_video_frame(cap, bad, number)
            finally:
                cap.release()

    with pytest.raises(InputError, match="damaged data at frame "):
        _in_thread(read_inside_a_capture)


def _cli(*args, env=None):
    return subprocess.run([sys.executable, "-m", "artmotion", *map(str, args)], capture_output=True, text=True,
                          env={**os.environ, **(env or {})}, timeout=300)


def test_the_command_line_says_one_line_and_ffmpeg_stays_off_stderr(tmp_path):
    clean = _write(tmp_path / "clean.avi", "XVID")
    bad = _broken(clean, tmp_path / "bad.avi")
    res = _cli("articulation", "video", bad, "--json")
    assert_one_line_error(res.returncode, res.stderr, "bad.avi", "damaged data at frame ")
    assert res.stdout == ""
    res = _cli("articulation", "video", clean, "--json")
    assert res.returncode == 0 and res.stderr == "", res.stderr
    # FFmpeg in colour (its codes round every line, and end them on a line of their own)
    res = _cli("articulation", "video", bad, "--json", env={"AV_LOG_FORCE_COLOR": "1"})
    assert_one_line_error(res.returncode, res.stderr, "bad.avi", "damaged data at frame ")
    # FFmpeg's log sent to stdout by OpenCV's variables (the damage would pass unseen): not done
    res = _cli("articulation", "video", bad, "--json", env={"OPENCV_FFMPEG_LOGLEVEL": "16"})
    assert_one_line_error(res.returncode, res.stderr, "bad.avi", "damaged data at frame ")
    assert res.stdout == ""
    # ARTMOTION_DEBUG shows FFmpeg's own lines (and the traceback)
    res = _cli("articulation", "video", bad, "--json", env={"ARTMOTION_DEBUG": "1"})
    assert res.returncode != 0 and "[mpeg4 @ " in res.stderr, res.stderr
