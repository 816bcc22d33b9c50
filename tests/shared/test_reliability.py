"""One test per root cause of issue 13 (reliability): damaged media, bad numbers and interrupted runs
never pass as success. Each fails on the code before the fix; the fuzz suite (test_fuzz.py) tries
the same readers with many more damaged inputs."""

from __future__ import annotations

import contextlib
import errno
import json
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import _inputs as inp
import cv2
import numpy as np
import pytest
from _inputs import assert_one_line_error, call, leftovers

from artmotion.errors import InputError

SRC = Path(__file__).resolve().parents[2] / "src"


def _cli(*args, timeout=120, **kw) -> subprocess.CompletedProcess:
    """``artmotion ARGS`` in a new process (its stderr at the file-descriptor level: what FFmpeg
    and OpenCV print there shows)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OPENCV_", "ARTMOTION_DEBUG"))}
    return subprocess.run([sys.executable, "-m", "artmotion", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=dict(env, PYTHONPATH=str(SRC)), **kw)


@pytest.fixture(scope="module")
def model(tmp_path_factory) -> Path:
    return inp.pose_model(tmp_path_factory.mktemp("model") / "m.npz")


# -- 1. damaged media accepted ---------------------------------------------------------------------


def test_1_damaged_media_is_never_a_success(tmp_path):
    """A truncated JPEG in a sequence, a video damaged in the middle and a seqLength that is not
    what is there are errors naming the file: `run` writes no run folder, `batch` marks the item
    failed, and FFmpeg's own messages do not add lines to the one line of the error."""
    archive = tmp_path / "archive"
    seq = inp.sequence(archive / "jpeg")
    victim = seq / "img1" / "000003.jpg"
    victim.write_bytes(victim.read_bytes()[: victim.stat().st_size // 2])
    code, _, err = call("run", seq, "--out", tmp_path / "run", "--no-video")
    assert_one_line_error(code, err, "000003.jpg", "truncated JPEG")
    assert not (tmp_path / "run").exists() and not leftovers(tmp_path)

    avi = inp.video(tmp_path / "v.avi", n=20)
    data = bytearray(avi.read_bytes())
    rng = np.random.default_rng(3)
    mid = len(data) // 2
    data[mid:mid + 3000] = rng.integers(0, 256, 3000, dtype=np.uint8).tobytes()
    damaged = archive / "damaged.avi"
    damaged.write_bytes(bytes(data))
    res = _cli("track", damaged, "--det", seq / "det" / "det.txt", "--out", tmp_path / "r.txt")
    # (FFmpeg reports the damaged frame as it decodes it: "damaged data at frame 9 ... (mjpeg: overread 8)")
    assert_one_line_error(res.returncode, res.stderr, "damaged.avi", "damaged data at frame 9:")
    assert not (tmp_path / "r.txt").exists()

    short = inp.sequence(archive / "short")
    (short / "seqinfo.ini").write_text(inp.SEQINFO.format(n=inp.N + 1))
    code, _, err = call("track", short)
    assert_one_line_error(code, err, "seqinfo.ini says 7 frames but img1/ has 6")

    code, out, err = call("batch", archive, "--out", tmp_path / "runs", "--workers", 1)
    assert code == 2 and "0 done, 0 skipped, 3 failed" in out, (out, err)
    lines = err.splitlines()
    assert len(lines) == 3 and all(line.startswith("artmotion: error: ") for line in lines), err
    assert not list((tmp_path / "runs").glob("*")) if (tmp_path / "runs").exists() else True


def test_1_an_image_bomb_is_refused_from_its_header(tmp_path):
    """A frame whose header claims 20000 x 20000 pixels (a PNG of a few hundred bytes that OpenCV
    would spend seconds and 1.2 GB decoding): one line naming it, before any pixel is decoded."""
    import struct
    import zlib

    seq = inp.sequence(tmp_path / "seq")
    frame = seq / "img1" / "000001.jpg"
    ok, png = cv2.imencode(".png", np.zeros((30, 50, 3), np.uint8))
    data = bytearray(png.tobytes())
    data[16:24] = struct.pack(">II", 20000, 20000)
    data[29:33] = struct.pack(">I", zlib.crc32(bytes(data[12:29])))
    frame.write_bytes(bytes(data))
    code, _, err = call("track", seq, "--out", tmp_path / "r.txt")
    assert_one_line_error(code, err, "000001.jpg", "20000x20000")
    assert not (tmp_path / "r.txt").exists()


@pytest.mark.parametrize("damage", ["cut", "zeros"])
def test_1_jpeg_damage_inside_the_image_data_is_an_error(tmp_path, damage):
    """Bytes cut from, or zeros put into, the middle of a JPEG's image data keep its structure
    intact; libjpeg decodes around the damage (a gray or shifted block) and says so only on
    stderr. That is an error naming the file, and stderr holds nothing else."""
    from artmotion.io.media import image_problem

    seq = inp.sequence(tmp_path / "seq")
    victim = seq / "img1" / "000004.jpg"
    data = victim.read_bytes()
    mid = (data.index(b"\xff\xda") + len(data)) // 2
    data = data[:mid] + data[mid + 200:] if damage == "cut" else data[:mid] + bytes(200) + data[mid:]
    victim.write_bytes(data)
    assert image_problem(np.frombuffer(data, np.uint8)) is None       # the structure is sound
    res = _cli("track", seq, "--out", tmp_path / "r.txt")
    assert_one_line_error(res.returncode, res.stderr, "000004.jpg", "corrupt image data (Corrupt JPEG data")
    assert not (tmp_path / "r.txt").exists()


@pytest.mark.parametrize("container", ["avi", "mkv"])      # a frame index / no frame count in the file
@pytest.mark.parametrize("declared", [inp.N - 2, inp.N + 2])
def test_1_seqlength_is_compared_with_the_frames_of_a_video(tmp_path, container, declared):
    seq = tmp_path / "seq"
    inp.video(seq / f"v.{container}")
    (seq / "seqinfo.ini").write_text(inp.SEQINFO.format(n=declared).replace("imDir=img1\n", ""))
    det = tmp_path / "det.txt"
    det.write_text("\n".join(inp.det_rows()) + "\n")
    code, _, err = call("track", seq, "--det", det, "--out", tmp_path / "r.txt")
    assert_one_line_error(code, err, f"{declared}")
    assert "seqinfo.ini" in err or f"v.{container}" in err
    assert not (tmp_path / "r.txt").exists()


def test_1_seqinfo_image_size_is_compared_with_the_frames(tmp_path):
    """imWidth/imHeight that are not the frames' size (the ground truth's pixels would not be the
    frames'): one line naming the first frame."""
    seq = inp.sequence(tmp_path / "seq")
    ini = seq / "seqinfo.ini"
    ini.write_text(ini.read_text().replace("imWidth=96", "imWidth=100"))
    code, _, err = call("track", seq, "--out", tmp_path / "r.txt")
    assert_one_line_error(code, err, "100x72", "96x72")
    assert not (tmp_path / "r.txt").exists()


# -- 2. anything is a video ------------------------------------------------------------------------


@pytest.mark.parametrize("name, content", [("notes.txt", b"hello\n"), ("clip.mp4", b"just some text\n" * 50),
                                           ("frame.avi", None)])
def test_2_only_video_content_is_a_video(tmp_path, name, content):
    path = tmp_path / name
    if content is None:         # a JPEG renamed .avi
        _, buf = cv2.imencode(".jpg", inp.frames(1)[0])
        content = buf.tobytes()
    path.write_bytes(content)
    code, _, err = call("track", path, "--out", tmp_path / "r.txt")
    assert_one_line_error(code, err, name)
    assert "video" in err and not (tmp_path / "r.txt").exists()


# -- 3. internal errors instead of answers ---------------------------------------------------------


def _damaged_models(model: Path, tmp: Path) -> dict[str, Path]:
    d = dict(np.load(model))
    out = {}
    truncated = tmp / "truncated.npz"
    truncated.write_bytes(model.read_bytes()[:3000])
    out["truncated"] = truncated
    renamed = tmp / "renamed.npz"
    renamed.write_text("1,1,10,10,20,40,1\n")
    out["renamed"] = renamed
    for key, change in {"shape": ("pca_components", d["pca_components"][:, :7]),
                        "inputs": ("X", d["X"][:, :2]),
                        "nan": ("hypers", d["hypers"] * np.nan),
                        "names": ("names", np.array(["opening"])),
                        "text": ("Ys", d["Ys"].astype("U8"))}.items():
        p = tmp / f"{key}.npz"
        np.savez(p, **(d | {change[0]: change[1]}))
        out[key] = p
    header = tmp / "header.npz"   # an array's header damaged: NumPy's header tokenizer fails
    data = model.read_bytes()
    at = data.rindex(b"'shape': (")
    header.write_bytes(data[:at] + b"'shap\0\0\0\0\0" + data[at + 10:])
    out["header"] = header
    return out


@pytest.mark.parametrize("kind", ["truncated", "renamed", "shape", "inputs", "nan", "names", "text", "header"])
def test_3_damaged_pose_model_is_one_line(tmp_path, model, kind):
    bad = _damaged_models(model, tmp_path)[kind]
    crops = model.parent / "m-crops"
    code, _, err = call("pose", "predict", bad, crops, "--out", tmp_path / "p.csv")
    assert_one_line_error(code, err, bad.name, "pose model")
    assert not (tmp_path / "p.csv").exists()


@pytest.mark.parametrize("args, needle", [
    (["pose", "render", "{tmp}/r", "--poses", "2", "--seed", "-1"], "--seed"),
    (["slam", "simulate", "--seed", "-1", "--runs", "1", "--steps", "5"], "--seed"),
    (["grounding", "dataset", "{tmp}/g", "--seed", "-1"], "--seed"),
    (["grounding", "eval", "{tmp}/g", "--seed", "-1"], "--seed"),
    (["pose", "train", "{tmp}/crops", "{tmp}/l.csv", "--model", "{tmp}/m.npz", "--seed", "-1"], "--seed"),
    (["slam", "simulate", "--landmarks", "1000000", "--runs", "1", "--steps", "5"], "--landmarks"),
    (["articulation", "fit", "{traj}", "--max-radius", "-1"], "--max-radius"),
    (["articulation", "fit", "{traj}", "--min-samples", "1000000000"], "--min-samples"),
    (["batch", "{tmp}", "--scheduler", "not a url"], "not a url"),
    (["batch", "{tmp}", "--workers", str(4 * (os.cpu_count() or 1) + 1)], "--workers"),  # processes, not a queue
    (["batch", "{tmp}", "--out", "{traj}"], "is not a folder"),  # one line up front, not one per item
    (["run", "{tmp}", "--class", "!!"], "--class '!!'"),        # the code before said "!! 1 stays in place"
    (["run", "{tmp}", "--class", "3=cart"], "one NAME"),
])
def test_3_bad_options_are_one_line(tmp_path, args, needle):
    traj = tmp_path / "arc.txt"
    traj.write_text(inp.trajectory())
    before = sorted(tmp_path.iterdir())
    code, _, err = call(*[a.format(tmp=tmp_path, traj=traj) for a in args])
    assert_one_line_error(code, err, needle)
    if needle == "--seed":
        assert "[0, 4294967295]" in err              # NumPy's rule, stated
    assert sorted(tmp_path.iterdir()) == before       # a failed command creates nothing


@pytest.mark.parametrize("where", ["events", "out"])
def test_3_an_output_that_cannot_be_written_fails_before_any_is(tmp_path, where):
    """``track --out A --events B`` where B (or A) lies under a file: one line, exit 2, and
    neither output written — the destinations are checked before the work."""
    seq = inp.sequence(tmp_path / "seq")
    blocker = tmp_path / "afile"
    blocker.write_text("a file, not a folder")
    good, bad = tmp_path / "good.txt", blocker / "x.txt"
    out, events = (good, bad) if where == "events" else (bad, good)
    code, _, err = call("track", seq, "--out", out, "--events", events)
    assert_one_line_error(code, err, "afile")
    assert not good.exists()
    code, _, err = call("track", seq, "--out", good, "--video", tmp_path / "ann.png")
    assert_one_line_error(code, err, "ann.png", ".mp4")
    assert not good.exists()


def test_3_an_output_over_an_input_or_a_device_is_refused(tmp_path):
    """``track --out`` naming its own detections (given or the sequence's det/det.txt), a pipe, or
    the same file as ``--events``: one line, exit 2, and the input untouched."""
    seq = inp.sequence(tmp_path / "seq")
    det = seq / "det" / "det.txt"
    before = det.read_bytes()
    code, _, err = call("track", seq, "--out", det)
    assert_one_line_error(code, err, "det.txt", "is also an input")
    code, _, err = call("track", seq, "--det", det, "--out", tmp_path / "seq" / "det" / ".." / "det" / "det.txt")
    assert_one_line_error(code, err, "is also an input")
    assert det.read_bytes() == before
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    code, _, err = call("track", seq, "--out", fifo)
    assert_one_line_error(code, err, "fifo", "not a regular file")
    assert fifo.is_fifo()
    code, _, err = call("track", seq, "--out", tmp_path / "r.txt", "--events", tmp_path / "r.txt")
    assert_one_line_error(code, err, "r.txt", "two outputs")
    assert not (tmp_path / "r.txt").exists()


def test_3_pose_outputs_never_replace_their_inputs(tmp_path, model):
    """``pose predict --out`` naming the model, ``pose train --model`` naming the labels."""
    crops = tmp_path / "crops"
    crops.mkdir()
    cv2.imwrite(str(crops / "a.png"), np.full((48, 64, 3), 128, np.uint8))
    m = tmp_path / "m.npz"
    shutil.copy(model, m)
    before = m.read_bytes()
    code, _, err = call("pose", "predict", m, crops, "--out", m)
    assert_one_line_error(code, err, "m.npz", "is also an input")
    assert m.read_bytes() == before
    labels = tmp_path / "labels.csv"
    labels.write_text("image,a\na.png,1\n")
    code, _, err = call("pose", "train", crops, labels, "--model", labels)
    assert_one_line_error(code, err, "labels.csv", "is also an input")
    assert labels.read_text() == "image,a\na.png,1\n"
    frame = (crops / "a.png").read_bytes()
    for args in (("predict", m, crops, "--out", crops / "a.png"), ("train", crops, labels, "--model", crops / "a.png"),
                 ("eval", crops, labels, "--out", crops / "eval")):
        code, _, err = call("pose", *args)
        assert_one_line_error(code, err, "inside the input folder")
    assert (crops / "a.png").read_bytes() == frame and sorted(p.name for p in crops.iterdir()) == ["a.png"]


def test_3_outputs_stay_out_of_the_frames_folder(tmp_path):
    """``track --out`` over a frame of the sequence, ``run --out`` into its frames folder: one line,
    exit 2, the frames as they were (the code before replaced the frame and exited 0); an output
    next to the frames, in the sequence's own folder, is fine."""
    seq = inp.sequence(tmp_path / "seq")
    first = seq / "img1" / "000001.jpg"
    before = first.read_bytes()
    code, _, err = call("track", seq, "--out", first)
    assert_one_line_error(code, err, "000001.jpg", "inside the input folder")
    code, _, err = call("run", seq, "--out", seq / "img1", "--no-video")
    assert_one_line_error(code, err, "img1", "inside the input folder")
    code, _, err = call("articulation", "video", seq / "img1", "--out", seq / "img1" / "parts")
    assert_one_line_error(code, err, "inside the input folder")
    assert first.read_bytes() == before and len(list((seq / "img1").iterdir())) == inp.N
    code, _, err = call("track", seq, "--out", seq / "tracks.txt")
    assert code == 0, err


def test_3_files_in_an_existing_folder_are_never_replaced(tmp_path):
    """``run --out`` and ``pose render`` into a folder that holds the user's own files: a file of
    the same name as an output is an error before any work, naming it, and stays as it was; with no
    such file the outputs join the folder and its other files stay (the code before wrote over a
    results.txt or labels.csv that was there)."""
    from artmotion.io import atomic_dir, atomic_write

    seq = inp.sequence(tmp_path / "seq")
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "results.txt").write_text("my own results\n")
    (mine / "notes.txt").write_text("notes\n")
    code, _, err = call("run", seq, "--out", mine, "--no-video")
    assert_one_line_error(code, err, "results.txt", "not only this command's earlier outputs")
    assert (mine / "results.txt").read_text() == "my own results\n"
    assert sorted(p.name for p in mine.iterdir()) == ["notes.txt", "results.txt"]
    (mine / "results.txt").unlink()
    code, _, err = call("run", seq, "--out", mine, "--no-video")
    assert code == 0, err
    assert (mine / "notes.txt").read_text() == "notes\n" and (mine / "run.json").is_file()
    assert not leftovers(tmp_path)

    renders = tmp_path / "renders"
    renders.mkdir()
    (renders / "labels.csv").write_text("image,a\n")
    code, _, err = call("pose", "render", renders, "--poses", "3", "--no-frames")
    assert_one_line_error(code, err, "labels.csv", "not only this command's earlier outputs")
    assert (renders / "labels.csv").read_text() == "image,a\n" and not (renders / "crops").exists()

    # the same command again into its own outputs replaces them; a look-alike marker is not its own
    answer = tmp_path / "answer"
    video = inp.video(tmp_path / "v.avi", n=8)
    for _ in range(2):
        code, _, err = call("articulation", "video", video, "--out", answer)
        assert code == 0, err
    (answer / "result.json").write_text('{"model": "mine"}')
    code, _, err = call("articulation", "video", video, "--out", answer)
    assert_one_line_error(code, err, "result.json", "not only this command's earlier outputs")
    assert (answer / "result.json").read_text() == '{"model": "mine"}'

    # an output the caller did not declare is caught before anything is moved in
    other = tmp_path / "other"
    other.mkdir()
    (other / "a.txt").write_text("A")
    (other / "b.txt").write_text("B")
    with pytest.raises(InputError, match="b.txt: exists, in a folder that is not only"):
        with atomic_dir(other, outputs=("c.txt",)) as dst:
            for name in ("c.txt", "b.txt"):
                with atomic_write(dst / name) as fh:
                    fh.write("new")
    assert {p.name: p.read_text() for p in other.iterdir()} == {"a.txt": "A", "b.txt": "B"}


def test_3_huge_trajectory_values_are_one_line(tmp_path):
    traj = tmp_path / "huge.txt"
    traj.write_text(inp.trajectory() + "1e308 1e308\n")
    code, _, err = call("articulation", "fit", traj, "--json")
    assert_one_line_error(code, err, "huge.txt:31", "out of range")


@pytest.mark.parametrize("field, value", [("frame", 10**30), ("length", True), ("fps", -1.0), ("width", 1e300),
                                          ("id", "1"), ("tracks", [1.5])])
def test_3_manifest_numbers_out_of_range_are_refused(tmp_path, field, value):
    run = inp.manifest()
    if field == "frame":
        run["events"][0]["frame"] = value
    elif field in ("length", "fps", "width"):
        run["sequence"][field] = value
    elif field == "id":
        run["track_summary"][0]["id"] = value
    else:
        run["sentences"][0]["tracks"] = value
    folder = inp.run_folder(tmp_path / "run", run)
    code, _, err = call("index", "add", folder, "--db", tmp_path / "db.sqlite")
    assert_one_line_error(code, err, "run.json", "corrupt manifest")
    assert not (tmp_path / "db.sqlite").exists()


@pytest.mark.parametrize("change, needle", [
    (lambda r: r["track_summary"].append(dict(r["track_summary"][0])), "track 1 twice"),
    (lambda r: r["track_summary"][0].update(first_frame=50, last_frame=1), "boxes in frames 50-1"),
    (lambda r: r["track_summary"][0].update(boxes=999), "999 boxes in frames 1-50"),
    (lambda r: r["track_summary"][0].update(last_frame=9999), "after the sequence's 50 frames"),
    (lambda r: r["sentences"][0].update(frame_start=50, frame_end=1), "ends (frame 1) before it begins"),
    (lambda r: r["sentences"][0].update(tracks=[424242]), "'sentences' item 1 names track 424242"),
    (lambda r: r["events"][0].update(tracks=[424242]), "'events' item 1 names track 424242"),
    (lambda r: r.update(name="cam\ud800"), "lone surrogate"),
])
def test_3_a_manifest_that_contradicts_itself_is_refused(tmp_path, change, needle):
    """Types right, contents impossible: the code before indexed them (``search`` then said
    "frames 50-1"), or called the index damaged (a track id twice, a lone surrogate)."""
    run = inp.manifest()
    change(run)
    folder = inp.run_folder(tmp_path / "run", run)
    code, _, err = call("index", "add", folder, "--db", tmp_path / "db.sqlite")
    assert_one_line_error(code, err, "run.json", "corrupt manifest", needle)
    assert not (tmp_path / "db.sqlite").exists()


def test_3_a_deeply_nested_manifest_is_one_line(tmp_path):
    """JSON nested beyond the parser's recursion limit is a corrupt manifest, not an internal error."""
    folder = tmp_path / "deep"
    folder.mkdir()
    (folder / "run.json").write_text("[" * 100_000 + "]" * 100_000)
    code, _, err = call("index", "add", folder, "--db", tmp_path / "db.sqlite")
    assert_one_line_error(code, err, "run.json", "nested too deeply")
    assert not (tmp_path / "db.sqlite").exists()


def test_3_damaged_index_is_one_line(tmp_path):
    db = tmp_path / "db.sqlite"
    assert call("index", "add", inp.run_folder(tmp_path / "r"), "--db", db)[0] == 0
    data = db.read_bytes()
    truncated = tmp_path / "truncated.sqlite"
    truncated.write_bytes(data[: len(data) // 2])
    corrupt = tmp_path / "corrupt.sqlite"
    flipped = bytearray(data)
    flipped[200::97] = bytes(len(flipped[200::97]))
    corrupt.write_bytes(bytes(flipped))
    for path in (truncated, corrupt):
        before = path.read_bytes()
        for args in (("index", "list"), ("search", "person exits"), ("index", "add", tmp_path / "r")):
            code, _, err = call(*args, "--db", path)
            assert_one_line_error(code, err, path.name, "damaged index")
        assert path.read_bytes() == before
    text = tmp_path / "text.sqlite"     # sound pages, a frame number that is text (the code before printed it)
    text.write_bytes(data)
    with contextlib.closing(sqlite3.connect(text)) as conn, conn:
        conn.execute("UPDATE sentences SET frame_start = 'abc'")
    code, _, err = call("search", "person exits", "--db", text)
    assert_one_line_error(code, err, "text.sqlite", "damaged index")


def test_3_scheduler_that_is_no_dask_scheduler_is_one_line(tmp_path):
    """Something that answers on the port but is not Dask (here: a plain TCP server sending text)."""
    import socket
    import threading

    inp.sequence(tmp_path / "archive" / "a")
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen()
    port = srv.getsockname()[1]

    def serve():
        try:
            while True:
                conn, _ = srv.accept()
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\n\r\n" * 64)
                conn.close()
        except OSError:
            pass

    threading.Thread(target=serve, daemon=True).start()
    try:
        t0 = time.monotonic()
        code, _, err = call("batch", tmp_path / "archive", "--scheduler", f"tcp://127.0.0.1:{port}")
    finally:
        srv.close()
    assert_one_line_error(code, err, f"tcp://127.0.0.1:{port}", "cannot reach a Dask scheduler")
    assert time.monotonic() - t0 < 15


# -- 4. NaN and infinity accepted ------------------------------------------------------------------


def test_4_nan_and_infinity_are_refused(tmp_path):
    seq = inp.sequence(tmp_path / "seq")
    (seq / "seqinfo.ini").write_text(inp.SEQINFO.format(n=inp.N).replace("frameRate=25", "frameRate=nan"))
    code, _, err = call("track", seq)
    assert_one_line_error(code, err, "seqinfo.ini", "[0.001, 1000]")

    res = tmp_path / "res.txt"
    res.write_text("\n".join(inp.gt_rows()) + "\n")
    code, _, err = call("describe", res, "--fps", "inf")
    assert_one_line_error(code, err, "--fps", "[0.001, 1000]")

    traj = tmp_path / "arc.txt"
    traj.write_text(inp.trajectory())
    for option in ("--noise-floor", "--max-radius"):
        code, out, err = call("articulation", "fit", traj, "--json", option, "nan")
        assert_one_line_error(code, err, option)
        assert out == ""                                   # no NaN written into JSON


def test_4_nan_model_parameters_are_refused(tmp_path, model):
    d = dict(np.load(model))
    for key in ("accel_var", "alpha", "var_scale", "y_mean"):
        bad = tmp_path / f"{key}.npz"
        np.savez(bad, **(d | {key: d[key] * np.inf}))
        code, _, err = call("pose", "predict", bad, model.parent / "m-crops", "--out", tmp_path / "p.csv")
        assert_one_line_error(code, err, bad.name, key)


def test_4_empty_ground_truth_is_no_ground_truth(tmp_path):
    res = tmp_path / "res.txt"
    res.write_text("\n".join(inp.gt_rows()) + "\n")
    for content in ("", "1,1,5,15,16,40,0,-1,-1,-1\n"):      # nothing, or only ignored boxes
        gt = tmp_path / "gt.txt"
        gt.write_text(content)
        code, out, err = call("eval", gt, res)
        assert_one_line_error(code, err, "gt.txt", "no ground truth")
        assert "MOTA" not in out
    # a run over a sequence with an empty gt/gt.txt reports no metrics instead of MOTA 0
    from artmotion.app.pipeline import run_pipeline

    seq = inp.sequence(tmp_path / "seq")
    (seq / "gt" / "gt.txt").write_text("")
    assert run_pipeline(seq, tmp_path / "run", video=False).metrics is None


def test_4_ground_truth_of_a_run_is_checked_before_the_tracking(tmp_path):
    """An id twice in one frame of the sequence's gt/gt.txt: the error names that file."""
    seq = inp.sequence(tmp_path / "seq")
    rows = inp.gt_rows()
    (seq / "gt" / "gt.txt").write_text("\n".join(rows + rows[:1]) + "\n")
    code, _, err = call("run", seq, "--out", tmp_path / "run")
    assert_one_line_error(code, err, "gt.txt", "appears more than once")
    assert not (tmp_path / "run").exists()


# -- 5. not atomic ---------------------------------------------------------------------------------


def test_5_full_disk_leaves_no_partial_video(tmp_path, monkeypatch):
    """OpenCV's writer drops frames silently when the disk is full; the video is checked."""
    import artmotion.tracking.video as video_mod

    real = cv2.VideoWriter

    class FullDisk:
        def __init__(self, *a):
            self.w, self.n = real(*a), 0

        def isOpened(self):
            return self.w.isOpened()

        def write(self, img):
            self.n += 1
            if self.n <= 3:                          # the disk fills up after three frames
                self.w.write(img)

        def release(self):
            self.w.release()

    monkeypatch.setattr(video_mod.cv2, "VideoWriter", FullDisk)
    seq = inp.sequence(tmp_path / "seq")
    out = tmp_path / "out"
    out.mkdir()
    code, _, err = call("track", seq, "--video", out / "ann.mp4", "--out", out / "res.txt")
    assert_one_line_error(code, err, "ann.mp4", "disk full")
    assert sorted(out.iterdir()) == []
    code, _, err = call("run", seq, "--out", tmp_path / "run")
    assert_one_line_error(code, err, "run/annotated.mp4")
    assert not (tmp_path / "run").exists() and not leftovers(tmp_path)


def test_5_sigterm_during_run_leaves_no_folder(tmp_path):
    seq = inp.sequence(tmp_path / "seq", n=400)
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-m", "artmotion", "run", str(seq), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, PYTHONPATH=str(SRC)))
    deadline = time.monotonic() + 120
    while not list(tmp_path.glob(".run.*/.annotated.mp4.*")) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)                    # until the annotated video is being written
    assert proc.poll() is None, "finished before it could be interrupted"
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert err.count("\n") == 1 and err.startswith("artmotion: terminated"), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["seq"], "a run folder or a temporary was left"


def test_5_error_line_is_not_swallowed_by_a_decoding_thread(capfd, monkeypatch):
    """A reader thread points the file descriptor 2 at a scratch file while a codec decodes; the
    error line printed meanwhile (a SIGTERM in CI once left an interrupted run with exit 143 and
    an empty stderr) waits for it instead of landing there."""
    import threading

    from artmotion import cli
    from artmotion.io import media

    decoding, done = threading.Event(), threading.Event()

    def slow_decode(buf, flags):
        decoding.set()
        time.sleep(0.5)
        return np.zeros((2, 2, 3), np.uint8)

    monkeypatch.setattr(cv2, "imdecode", slow_decode)
    monkeypatch.setattr(sys, "stderr", open(2, "w", closefd=False))   # the process's stderr, as in a run
    reader = threading.Thread(target=lambda: (media._decode(np.zeros(4, np.uint8), cv2.IMREAD_COLOR), done.set()))
    reader.start()
    assert decoding.wait(10)
    cli._fail("terminated by signal 15: nothing half-written was kept", 143)
    on_stderr = capfd.readouterr().err        # read before the decode ends
    reader.join()
    assert on_stderr == "artmotion: terminated by signal 15: nothing half-written was kept\n"


def test_5_pose_model_is_checked_before_tracking(tmp_path, model, monkeypatch):
    """A model whose arrays do not fit together used to load, and failed only after the whole
    video was tracked."""
    from artmotion.app.pipeline import run_pipeline
    from artmotion.errors import InputError
    from artmotion.tracking import api

    bad = _damaged_models(model, tmp_path)["shape"]

    def tracked(*a, **k):
        raise AssertionError("tracked before the model was checked")

    monkeypatch.setattr(api, "track", tracked)
    with pytest.raises(InputError, match="shape.npz: corrupt artmotion pose model"):
        run_pipeline(inp.sequence(tmp_path / "seq"), tmp_path / "run", pose_model=bad)
    assert not (tmp_path / "run").exists()


def test_5_failed_rendering_leaves_nothing(tmp_path, monkeypatch):
    from artmotion.io import atomic

    count = {"n": 0}
    real_replace = atomic.os.replace

    def replace(src, dst):                   # the disk is full at the fourth file
        count["n"] += 1
        if count["n"] == 4:
            raise OSError(errno.ENOSPC, "No space left on device", str(src))
        return real_replace(src, dst)

    monkeypatch.setattr(atomic.os, "replace", replace)
    code, _, err = call("pose", "render", tmp_path / "r", "--poses", 3)
    assert_one_line_error(code, err, "No space left on device")
    assert str(tmp_path / "r") in err
    assert sorted(tmp_path.iterdir()) == []


# -- 6. silently ignored input ---------------------------------------------------------------------


@pytest.mark.parametrize("event, needle", [
    ({"type": "teleport", "frame": 3, "tracks": [1]}, "unknown event type 'teleport'"),
    ({"type": "enter", "frame": 3, "tracks": [1], "side": "up"}, "unknown side 'up'"),
    ({"type": "enter", "frame": True, "tracks": [1]}, "'frame'"),
    ({"type": "merge", "frame": 3, "tracks": [1, 2], "group": "x"}, "'group'"),
    ('{"type": "enter", "frame": 3, "tracks": [1], "x": 1e999}', "'x'"),      # JSON's 1e999 reads as infinity
    ('{"type": "enter", "frame": 3, "tracks": [1], "y": NaN}', "NaN"),
])
def test_6_events_that_do_not_fit_are_errors(tmp_path, event, needle):
    res = tmp_path / "res.txt"
    res.write_text("\n".join(inp.gt_rows()) + "\n")
    ev = tmp_path / "ev.jsonl"
    ev.write_text(json.dumps(inp.EVENTS[0]) + "\n" + (event if isinstance(event, str) else json.dumps(event)) + "\n")
    code, _, err = call("describe", res, "--events", ev)
    assert_one_line_error(code, err, "ev.jsonl:2", needle)


def test_6_describe_names_a_detections_file_as_such(tmp_path):
    """A detections file has several id -1 rows in a frame: the answer says they are detections
    (track them first), not that id -1 appears twice in a frame."""
    det = tmp_path / "det.txt"
    det.write_text("1,-1,10,10,20,40,0.9,-1,-1,-1\n1,-1,50,10,20,40,0.8,-1,-1,-1\n2,-1,12,10,20,40,0.9,-1,-1,-1\n")
    code, _, err = call("describe", det)
    assert_one_line_error(code, err, "det.txt", "track them first")


def test_6_duplicate_csv_columns_and_a_folder_for_detections(tmp_path):
    res = tmp_path / "res.txt"
    res.write_text("\n".join(inp.gt_rows()) + "\n")
    pred = tmp_path / "PRED.csv"
    pred.write_text("image,opening,opening_std,opening,opening_std\n000001.png,10,1,50,1\n000002.png,20,1,60,1\n")
    code, _, err = call("describe", res, "--pose", pred)
    assert_one_line_error(code, err, "PRED.csv:1", "'opening' appears more than once")

    seq = inp.sequence(tmp_path / "seq")
    shutil.rmtree(seq / "det")
    (seq / "det" / "det.txt").mkdir(parents=True)        # not a file: no silent fall-back to HOG
    code, _, err = call("track", seq)
    assert_one_line_error(code, err, "det/det.txt", "not a file")

    index = tmp_path / "ds" / "index.csv"
    index.parent.mkdir()
    index.write_text("id,image,speech,speech_color,speech_shape,color,shape,color\n"
                     "000,a.png,a.wav,b.wav,c.wav,red,square,blue\n")
    code, _, err = call("grounding", "eval", index.parent)
    assert_one_line_error(code, err, "index.csv:1", "'color' appears more than once")


# -- 7. messages -----------------------------------------------------------------------------------


def test_7_messages_name_the_file_never_a_temporary(tmp_path, monkeypatch):
    from artmotion.io import atomic

    def replace(src, dst):                   # a write error reported on the temporary file
        raise OSError(errno.ENOSPC, "No space left on device", str(src))

    monkeypatch.setattr(atomic.os, "replace", replace)
    seq = inp.sequence(tmp_path / "seq")
    code, _, err = call("track", seq, "--out", tmp_path / "res.txt")
    assert_one_line_error(code, err, f"{tmp_path / 'res.txt'}: cannot write: No space left on device")
    code, _, err = call("run", seq, "--out", tmp_path / "run", "--no-video")
    assert_one_line_error(code, err, str(tmp_path / "run"), "No space left on device")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["seq"]


def test_7_internal_error_is_one_line_with_a_hint(tmp_path, monkeypatch):
    from artmotion.tracking import api

    def bug(*a, **k):
        raise ZeroDivisionError("division by zero\nsecond line")

    monkeypatch.setattr(api, "open_sequence", bug)
    code, _, err = call("track", tmp_path)
    assert code == 1 and err.count("\n") == 1, err
    assert err.startswith("artmotion: internal error: ZeroDivisionError") and "please report" in err


def test_7_native_library_messages_stay_off_stderr(tmp_path):
    """FFmpeg prints '[mjpeg @ 0x...] overread 8' for a truncated video; OpenCV '[ WARN:0] ...'."""
    avi = inp.video(tmp_path / "v.avi", n=20)
    half = tmp_path / "half.avi"
    half.write_bytes(avi.read_bytes()[: avi.stat().st_size * 2 // 3])
    det = tmp_path / "det.txt"
    det.write_text("\n".join(inp.det_rows(20)) + "\n")
    res = _cli("track", half, "--det", det)
    assert_one_line_error(res.returncode, res.stderr, "half.avi")
    data = bytearray(avi.read_bytes())
    data[12:16] = b"JUNK"     # OpenCV's AVI reader prints "Unexpected element. Expected: LIST. Got: JUNK."
    bad = tmp_path / "bad.avi"
    bad.write_bytes(bytes(data))
    for args in (("track", bad, "--det", det), ("articulation", "video", bad)):
        res = _cli(*args)
        assert_one_line_error(res.returncode, res.stderr, "bad.avi", "cannot open video")


# -- 8. interruption -------------------------------------------------------------------------------


def _start_batch(archive: Path, out: Path, workers: int, start_new_session: bool = False) -> subprocess.Popen:
    """``artmotion batch ARCHIVE --out OUT --workers N`` started in a process of its own."""
    return subprocess.Popen([sys.executable, "-m", "artmotion", "batch", str(archive), "--out", str(out),
                             "--workers", str(workers)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, PYTHONPATH=str(SRC)), start_new_session=start_new_session)


@pytest.mark.slow
def test_8_ctrl_c_in_batch_is_one_line_with_the_counts(tmp_path):
    archive = tmp_path / "archive"
    for i in range(8):
        inp.sequence(archive / f"s{i}", n=150)
    out = tmp_path / "runs"
    proc = _start_batch(archive, out, 2, start_new_session=True)
    deadline = time.monotonic() + 120
    while not list(out.glob("*/run.json")) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)                     # one item finished
    assert proc.poll() is None, "the batch finished before it could be interrupted"
    os.killpg(proc.pid, signal.SIGINT)       # Ctrl-C in a terminal: the whole process group
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith("artmotion: interrupted: ") and " of 8 items finished (kept)" in err and "not finished" in err
    finished = {p.parent.name for p in out.glob("*/run.json")}
    assert finished and all((out / name / "results.txt").is_file() for name in finished)
    assert not [p for p in out.iterdir() if p.name not in finished], "an unfinished run or temporary was left"



def _children(pid: int) -> list[tuple[int, str]]:
    """(pid, command line) of the processes whose parent is ``pid`` (Linux /proc)."""
    out = []
    for d in Path("/proc").iterdir():
        try:
            if d.name.isdigit() and int((d / "stat").read_text().rsplit(")", 1)[1].split()[1]) == pid:
                out.append((int(d.name), (d / "cmdline").read_bytes().replace(b"\0", b" ").decode()))
        except (OSError, ValueError, IndexError):
            continue
    return out


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_8_sigterm_while_batch_workers_start_is_one_line(tmp_path):
    """SIGTERM to the batch while its Dask workers start: multiprocessing's resource tracker (a
    process of its own, sharing stderr) warned about their semaphores after the one line."""
    archive = tmp_path / "archive"
    for i in range(3):
        inp.sequence(archive / f"s{i}")
    proc = _start_batch(archive, tmp_path / "runs", 4)
    deadline = time.monotonic() + 60
    while proc.poll() is None and time.monotonic() < deadline:
        if any("resource_tracker" in cmd for _, cmd in _children(proc.pid)):
            break
        time.sleep(0.005)
    assert proc.poll() is None, "the batch ended before its workers started"
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert err.startswith("artmotion: terminated by signal 15") and err.count("\n") == 1, err


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_8_an_interrupted_batch_leaves_no_partial_runs_and_counts_what_finished(tmp_path, sig):
    """Interrupted while its workers write runs: a run folder half-written by a worker was left
    (hidden, ``.NAME.xxxxxxxx.tmp``), and items its workers finished after the signal were said to
    be "not finished" (the next batch then skipped them as finished)."""
    archive = tmp_path / "archive"
    for i in range(4):
        inp.sequence(archive / f"s{i}", n=60)
    runs = tmp_path / "runs"
    proc = _start_batch(archive, runs, 2)
    deadline = time.monotonic() + 120
    while proc.poll() is None and time.monotonic() < deadline and not list(runs.glob(".s*.tmp")):
        time.sleep(0.005)                  # a worker is writing a run
    assert proc.poll() is None, "the batch ended before it could be interrupted"
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + sig and err.count("\n") == 1, err
    assert [p.name for p in runs.iterdir() if p.name.startswith(".")] == []
    finished = sum((runs / p.name / "run.json").exists() for p in runs.iterdir())
    assert f"{finished} of 4 items finished" in err, err


def _loaded(pid: int, name: str) -> bool:
    """Whether process ``pid`` has mapped a file whose path holds ``name`` (a library it imports)."""
    try:
        return name in Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return False


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_8_ctrl_c_while_batch_workers_start_is_one_line(tmp_path):
    """Ctrl-C (SIGINT to the whole process group) while a Dask worker process is starting: each
    worker printed a KeyboardInterrupt traceback (multiprocessing's resource tracker had unblocked
    SIGINT in the thread that spawns them)."""
    archive = tmp_path / "archive"
    for i in range(2):
        inp.sequence(archive / f"s{i}")
    proc = _start_batch(archive, tmp_path / "runs", 2, start_new_session=True)
    deadline = time.monotonic() + 60
    while proc.poll() is None and time.monotonic() < deadline:
        if any("multiprocessing.spawn" in cmd and _loaded(pid, "yaml") for pid, cmd in _children(proc.pid)):
            break                              # a worker is importing Dask (its configuration)
        time.sleep(0.002)
    assert proc.poll() is None, "the batch ended before its workers started"
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert err.startswith("artmotion: interrupted") and err.count("\n") == 1, err

# -- 9. index entries lost -------------------------------------------------------------------------


def test_9_a_batch_of_same_named_sequences_indexes_every_one(tmp_path):
    """The same sequence copied to four folders (each called 'tiny' by its seqinfo.ini): the batch
    indexes four runs, and the index keeps four videos, listed with their paths."""
    archive = tmp_path / "archive"
    for copy in ("a", "b", "c", "d"):
        inp.sequence(archive / copy)
    db = tmp_path / "db.sqlite"
    code, out, err = call("batch", archive, "--index", db, "--workers", 1)
    assert code == 0 and "indexed 4 runs" in out, (out, err)
    code, out, err = call("index", "list", "--db", db)
    lines = out.strip().splitlines()
    assert code == 0 and len(lines) == 4, out
    assert sorted(line.split(" (")[1].split("):")[0] for line in lines) == [
        str((archive / copy).resolve()) for copy in ("a", "b", "c", "d")]


def test_an_empty_name_or_value_is_refused_before_anything(tmp_path, run_cli, monkeypatch):
    """A path option took '' as the current folder: `articulation video X --out ''` wrote
    result.json and parts.png into it, `track ''` read it as frames, `eval '' gt.txt` named '.'."""
    monkeypatch.chdir(tmp_path)
    for args, what in ((("articulation", "video", "x.avi", "--out", ""), "--out is empty"),
                       (("articulation", "video", "x.avi", "--out="), "--out is empty"),
                       (("eval", "", "gt.txt"), "an argument is empty"),
                       (("track", ""), "an argument is empty")):
        code, out, err = run_cli(*args)
        assert code == 2 and err == f"artmotion: error: {what} (a file name or a value cannot be: a path option " \
                                     "took '' as the current folder)\n", err
    assert list(tmp_path.iterdir()) == []
    # (refused before the signal handlers are set: none of artmotion's is left behind in the process)
    import signal

    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
