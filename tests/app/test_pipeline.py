"""End-to-end: the pipeline on the shipped sample, the HTML report in headless Chromium, batches."""

import errno
import os
import shutil
import subprocess

import cv2
import numpy as np
import pytest

from artmotion.app import EventIndex, load_run, run_batch, run_pipeline
from artmotion.io import read_mot


def small_sequence(sample, dst, n=20):
    """The first ``n`` frames of the sample as a MOTChallenge folder of images (fast to track)."""
    (dst / "img1").mkdir(parents=True)
    (dst / "det").mkdir()
    (dst / "gt").mkdir()
    cap = cv2.VideoCapture(str(sample / "TUD-Campus.mp4"))
    for i in range(1, n + 1):
        ok, frame = cap.read()
        assert ok
        cv2.imwrite(str(dst / "img1" / f"{i:06d}.jpg"), frame)
    cap.release()
    for sub in ("det/det.txt", "gt/gt.txt"):
        rows = [line for line in (sample / sub).read_text().splitlines() if int(line.split(",")[0]) <= n]
        (dst / sub).write_text("\n".join(rows) + "\n")
    ini = (sample / "seqinfo.ini").read_text()
    (dst / "seqinfo.ini").write_text(ini.replace("seqLength=71", f"seqLength={n}").replace("TUD-Campus", dst.name))
    return dst


@pytest.fixture(scope="module")
def sample_run(tmp_path_factory):
    from conftest import SAMPLE

    out = tmp_path_factory.mktemp("run") / "campus"
    return run_pipeline(SAMPLE, out)


def test_pipeline_writes_everything(sample_run):
    out = sample_run.out_dir
    for name in ("results.txt", "events.jsonl", "sentences.txt", "report.html", "run.json", "annotated.mp4"):
        assert (out / name).is_file(), name
    run = load_run(out)
    assert run["metrics"]["MOTA"] > 0.4  # ground truth ships with the sample
    assert len(read_mot(out / "results.txt")) == len(sample_run.tracks)
    assert run["sentences"] and all(s["sentence"].strip() for s in run["sentences"])
    assert not [p for p in out.iterdir() if p.name.endswith(".tmp") or ".tmp." in p.name]


def test_report_renders_in_headless_chromium(sample_run, tmp_path):
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        if os.environ.get("CI"):
            pytest.fail("chromium missing in CI: `make system-deps` should have installed it")
        pytest.skip("chromium not installed (make system-deps installs it)")
    report = sample_run.report
    flags = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             f"--user-data-dir={tmp_path / 'profile'}"]
    dom = subprocess.run(flags + ["--dump-dom", report.as_uri()], capture_output=True, text=True, timeout=120).stdout
    run = load_run(sample_run.out_dir)
    assert dom.count("<tr>") >= len(run["sentences"]) + 1
    assert 'id="metrics-table"' in dom and "MOTA" in dom and "<svg" in dom
    shot = tmp_path / "report.png"
    subprocess.run(flags + [f"--screenshot={shot}", "--window-size=1000,4000", report.as_uri()],
                   capture_output=True, timeout=120)
    img = cv2.imread(str(shot))
    assert img is not None and img.shape[1] == 1000
    # The embedded pictures (trajectories, key frames) were decoded: much of the page is not white.
    coloured = (img.astype(int).sum(axis=2) < 600).mean()
    assert coloured > 0.2


def test_batch_isolates_failures_and_resumes(tmp_path, monkeypatch):
    from conftest import SAMPLE

    archive = tmp_path / "archive"
    archive.mkdir()
    small_sequence(SAMPLE, archive / "good-a")
    small_sequence(SAMPLE, archive / "good-b")
    (archive / "corrupt.mp4").write_bytes(os.urandom(4096))
    small_sequence(SAMPLE, archive / "full-disk")
    out = tmp_path / "runs"

    import artmotion.io.atomic as atomic

    real_replace = os.replace

    def replace(src, dst):  # the disk is full where the third item writes
        if "full-disk" in str(dst):
            raise OSError(errno.ENOSPC, "No space left on device", str(dst))
        return real_replace(src, dst)

    monkeypatch.setattr(atomic.os, "replace", replace)
    report = run_batch(archive, out, workers=2, processes=False)
    status = {os.path.basename(o.item): o for o in report.outcomes}
    assert status["good-a"].status == status["good-b"].status == "done"
    assert status["corrupt.mp4"].status == "failed" and "corrupt.mp4" in status["corrupt.mp4"].message
    assert status["full-disk"].status == "failed" and "No space left" in status["full-disk"].message
    assert not (out / "full-disk" / "run.json").exists()
    finished = sorted(p.parent.name for p in out.glob("*/run.json"))
    assert finished == ["good-a", "good-b"]

    monkeypatch.setattr(atomic.os, "replace", real_replace)
    before = (out / "good-a" / "run.json").stat().st_mtime_ns
    again = run_batch(archive, out, workers=1, processes=False)
    status = {os.path.basename(o.item): o.status for o in again.outcomes}
    assert status == {"good-a": "skipped", "good-b": "skipped", "corrupt.mp4": "failed", "full-disk": "done"}
    assert (out / "good-a" / "run.json").stat().st_mtime_ns == before

    with EventIndex(tmp_path / "db.sqlite") as idx:
        for name in ("good-a", "good-b", "full-disk"):
            idx.add_run(out / name)
        assert len(idx.videos()) == 3


def test_batch_skips_only_runs_it_finished(tmp_path, run_cli):
    """A run.json that is not a manifest (the user's own file, an empty one) is no finished run:
    the code before skipped the item as "already finished" and exited 0. Here the item fails,
    naming the file, which stays as it was."""
    from conftest import SAMPLE

    archive = tmp_path / "archive"
    archive.mkdir()
    small_sequence(SAMPLE, archive / "a")
    small_sequence(SAMPLE, archive / "b")
    out = tmp_path / "runs"
    (out / "a").mkdir(parents=True)
    (out / "a" / "run.json").write_text('{"my": "own config"}')
    (out / "b").mkdir()
    (out / "b" / "run.json").write_text("")
    code, stdout, err = run_cli("batch", archive, "--out", out, "--workers", 1)
    assert code == 2 and "0 done, 0 skipped, 2 failed" in stdout, (stdout, err)
    assert err.count("not only this command's earlier outputs") == 2, err
    assert (out / "a" / "run.json").read_text() == '{"my": "own config"}' and (out / "b" / "run.json").read_text() == ""


def test_batch_fails_an_item_whose_folder_holds_another_sources_run(tmp_path):
    """Two archives batched into one ``--out``, each with an item ``a``: the code before skipped
    cam2's as "already finished" (runs/a held cam1's run). It fails now, naming the folder and the
    source it holds (even with ``--force``: that run is not this item's to replace), and the run is
    kept."""
    from conftest import SAMPLE

    for cam in ("cam1", "cam2"):
        small_sequence(SAMPLE, tmp_path / cam / "a", n=5)
    out = tmp_path / "runs"
    assert [o.status for o in run_batch(tmp_path / "cam1", out, processes=False).outcomes] == ["done"]
    manifest = (out / "a" / "run.json").read_bytes()
    for force in (False, True):
        [o] = run_batch(tmp_path / "cam2", out, force=force, processes=False).outcomes
        assert o.status == "failed", o
        assert o.message == f"{out / 'a'} holds the run of {(tmp_path / 'cam1' / 'a').resolve()}"
    assert (out / "a" / "run.json").read_bytes() == manifest


def test_batch_runs_again_an_item_whose_input_changed(tmp_path):
    """A recording replaced by a new one of the same name: the code before skipped it as "already
    finished" (the manifest's fingerprint was not compared); it runs again now, then is skipped."""
    from conftest import SAMPLE

    seq = small_sequence(SAMPLE, tmp_path / "cam1" / "a", n=5)
    out = tmp_path / "runs"
    assert [o.status for o in run_batch(tmp_path / "cam1", out, processes=False).outcomes] == ["done"]
    before = load_run(out / "a")["fingerprint"]
    (seq / "img1" / "000001.jpg").write_bytes((seq / "img1" / "000002.jpg").read_bytes())   # a new recording
    [o] = run_batch(tmp_path / "cam1", out, processes=False).outcomes
    assert o.status == "done", o
    assert load_run(out / "a")["fingerprint"] != before
    [o] = run_batch(tmp_path / "cam1", out, processes=False).outcomes
    assert o.status == "skipped", o


def test_batch_runs_again_a_run_that_read_12_bit_frames_by_their_top_8_bits(tmp_path):
    """The manifest records the depth the frames were read at (and batch's line says it). A run made
    before it did read 12-bit frames in 16-bit PNGs by their top 8 bits (nearly black), and batch
    skipped it as finished (its fingerprint is the same): it runs again now. An 8-bit run from
    before is still finished."""
    import json

    import numpy as np

    rng = np.random.default_rng(0)
    archive = tmp_path / "archive"
    for name, dtype, top in (("twelve", np.uint16, 4095), ("eight", np.uint8, 255)):
        (archive / name / "img1").mkdir(parents=True)
        (archive / name / "det").mkdir()
        for k in range(1, 4):
            frame = rng.integers(0, top + 1, (48, 64, 3)).astype(dtype)
            cv2.imwrite(str(archive / name / "img1" / f"{k:06d}.png"), frame)
        (archive / name / "det" / "det.txt").write_text("".join(f"{k},-1,10,10,8,16,0.9,-1,-1,-1\n" for k in (1, 2, 3)))
        (archive / name / "seqinfo.ini").write_text(f"[Sequence]\nname={name}\nimDir=img1\nframeRate=10\nseqLength=3\n"
                                                    "imWidth=64\nimHeight=48\nimExt=.png\n")
    out = tmp_path / "runs"

    def statuses():
        return {os.path.basename(o.item): o.status for o in run_batch(archive, out, processes=False).outcomes}

    notes = {os.path.basename(o.item): o.note for o in run_batch(archive, out, processes=False).outcomes}
    assert "read as 12-bit" in notes["twelve"] and notes["eight"] == ""  # batch's done line says it
    assert load_run(out / "twelve")["sequence"]["bits"] == 12 and load_run(out / "eight")["sequence"]["bits"] == 8
    assert statuses() == {"twelve": "skipped", "eight": "skipped"}
    for name in ("twelve", "eight"):  # as the code before wrote them
        path = out / name / "run.json"
        run = json.loads(path.read_text())
        del run["sequence"]["bits"], run["manifest_sha256"]
        path.write_text(json.dumps(run))
    assert statuses() == {"twelve": "done", "eight": "skipped"}
    assert load_run(out / "twelve")["sequence"]["bits"] == 12


def test_batch_runs_again_a_run_of_16_bit_frames_holding_8_bit_values(tmp_path):
    """16-bit PNGs whose values stay below 256 are read as 8 bits, scaled as they are; a run whose
    manifest does not say the depth read them by their top 8 bits (black). The check took the
    recorded 8 for "read as before" and skipped it."""
    import json

    import numpy as np

    seq = tmp_path / "archive" / "low"
    (seq / "img1").mkdir(parents=True)
    (seq / "det").mkdir()
    for k in (1, 2, 3):
        cv2.imwrite(str(seq / "img1" / f"{k:06d}.png"), np.full((48, 64, 3), 40 * k + 100, np.uint16))
    (seq / "det" / "det.txt").write_text("".join(f"{k},-1,10,10,8,16,0.9,-1,-1,-1\n" for k in (1, 2, 3)))
    (seq / "seqinfo.ini").write_text("[Sequence]\nname=low\nimDir=img1\nframeRate=10\nseqLength=3\n"
                                     "imWidth=64\nimHeight=48\nimExt=.png\n")
    out = tmp_path / "runs"
    [o] = run_batch(tmp_path / "archive", out, processes=False).outcomes
    assert o.status == "done" and "read as 8-bit" in o.note
    path = out / "low" / "run.json"
    run = json.loads(path.read_text())
    del run["sequence"]["bits"], run["manifest_sha256"]  # as the code before wrote it
    path.write_text(json.dumps(run))
    [o] = run_batch(tmp_path / "archive", out, processes=False).outcomes
    assert o.status == "done", o


def test_a_batch_item_that_fails_with_a_message_of_several_lines_is_reported_on_one(tmp_path, monkeypatch):
    """A library's error can run over several lines (GTSAM's indeterminate system does); the batch
    prints one line per failed item, so its outcome's message is one line."""
    from conftest import SAMPLE

    import artmotion.app.pipeline as pipeline

    def fails(*args, **kwargs):
        raise RuntimeError("Indeterminant linear system detected\n  near variable x3.\n\nThrown when ill-posed.")

    monkeypatch.setattr(pipeline, "run_pipeline", fails)
    small_sequence(SAMPLE, tmp_path / "archive" / "a", n=3)
    [o] = run_batch(tmp_path / "archive", tmp_path / "runs", processes=False).outcomes
    assert o.status == "failed" and o.internal
    assert "\n" not in o.message and "detected near variable x3. Thrown when ill-posed." in o.message, o.message


def test_batch_items_whose_folders_would_collide_keep_their_runs(tmp_path):
    """``clip.avi`` and ``clip.AVI`` both went to ``runs/clip-avi``: both "done", one run lost."""
    from artmotion.articulation.synthetic import part_video

    archive = tmp_path / "archive"
    archive.mkdir()
    part_video(archive / "clip.avi", "revolute", frames=8)
    part_video(archive / "clip.AVI", "prismatic", frames=8, seed=3)
    report = run_batch(archive, tmp_path / "runs", processes=False)
    assert [o.status for o in report.outcomes] == ["done", "done"], report.outcomes
    sources = {load_run(o.out_dir)["source"] for o in report.outcomes}
    assert sources == {str((archive / n).resolve()) for n in ("clip.avi", "clip.AVI")}


@pytest.mark.parametrize("inside", ["a", "."])
def test_batch_output_inside_an_item_is_one_line(tmp_path, run_cli, inside):
    """``--out`` inside an item's folder (the other items' runs would land among its frames) or the
    archive itself (each item's run folder would be the item): one line before any work."""
    from conftest import SAMPLE

    archive = tmp_path / "archive"
    archive.mkdir()
    small_sequence(SAMPLE, archive / "a")
    small_sequence(SAMPLE, archive / "b")
    before = sorted(p.relative_to(archive) for p in archive.rglob("*"))
    code, _, err = run_cli("batch", archive, "--out", archive / inside, "--workers", 1)
    assert code == 2 and err.count("\n") == 1 and "inside the input folder" in err, err
    assert sorted(p.relative_to(archive) for p in archive.rglob("*")) == before


def test_batch_cli_reports_failures(tmp_path, run_cli):
    archive = tmp_path / "a"
    archive.mkdir()
    (archive / "broken.avi").write_bytes(b"\x00" * 100)
    code, out, err = run_cli("batch", archive, "--out", tmp_path / "o")
    assert code == 2          # the item failed on bad input (1 is for bugs)
    assert out.startswith("0 done, 0 skipped, 1 failed") and "broken.avi" in err   # (no progress bar's line first)
    assert err.startswith("artmotion: error:") and err.count("\n") == 1, err
    code, _, err = run_cli("batch", tmp_path / "nothing-here")
    assert code == 2 and "not a folder" in err


def test_run_takes_the_frame_rate_of_a_folder_of_images(tmp_path, run_cli):
    """A folder of images says no frame rate (25 is assumed): --fps gives it, and a rate out of
    range is one line before any work."""
    import json

    from conftest import SAMPLE

    seq = small_sequence(SAMPLE, tmp_path / "s", n=8)
    frames = seq / "img1"
    code, out, err = run_cli("run", frames, "--det", seq / "det" / "det.txt", "--fps", "12.5", "--no-video",
                             "--out", tmp_path / "r")
    assert code == 0, err
    assert json.loads((tmp_path / "r" / "run.json").read_text())["sequence"]["fps"] == 12.5
    code, out, err = run_cli("run", frames, "--det", seq / "det" / "det.txt", "--fps", "0", "--out", tmp_path / "r2")
    assert code == 2 and err.startswith("artmotion: error: --fps") and err.count("\n") == 1, err
    assert not (tmp_path / "r2").exists()


def test_run_says_why_ground_truth_gave_no_metrics(tmp_path, run_cli, sample_seq):
    """An empty gt.txt gave no metrics and said nothing, where `eval` calls it an error."""
    seq = small_sequence(sample_seq, tmp_path / "seq", n=4)
    (seq / "gt" / "gt.txt").write_text("")
    code, out, err = run_cli("run", seq, "--out", tmp_path / "r", "--no-video")
    assert code == 0 and "metrics:" not in out and "holds no box to score against" in err, err
    code, out, err = run_cli("run", small_sequence(sample_seq, tmp_path / "full", n=4), "--out", tmp_path / "r2",
                             "--no-video")
    assert code == 0 and "metrics:" in out and "no metrics" not in err


def test_run_says_its_detections_file_was_empty(tmp_path, run_cli, sample_seq):
    """An empty det.txt gave 0 tracks and no word (track says "no detections in it")."""
    seq = small_sequence(sample_seq, tmp_path / "seq", n=4)
    (seq / "det" / "det.txt").write_text("")
    code, out, err = run_cli("run", seq, "--out", tmp_path / "r", "--no-video")
    assert code == 0 and "0 tracks" in out and "det.txt (no detections in it: nothing tracked)" in err, (out, err)


def test_run_refuses_ground_truth_of_frames_the_sequence_has_not(tmp_path, run_cli, sample_seq):
    """A gt.txt row of frame 500 in a 4-frame sequence was scored as a missed box (the metrics
    moved without a word), where the same row in det.txt is refused: refused too, before the work
    for a folder of images, once the video is read for a video; no run folder is left."""
    seq = small_sequence(sample_seq, tmp_path / "seq", n=4)
    with open(seq / "gt" / "gt.txt", "a") as fh:
        fh.write("500,1,10,10,20,40,1,-1,-1,-1\n")
    video = tmp_path / "video"
    shutil.copytree(sample_seq, video)
    with open(video / "gt" / "gt.txt", "a") as fh:
        fh.write("500,1,10,10,20,40,1,-1,-1,-1\n")
    for src, frames in ((seq, 4), (video, 71)):
        code, out, err = run_cli("run", src, "--out", tmp_path / "r", "--no-video")
        assert code == 2 and err.count("\n") == 1, err
        assert f"gt.txt: ground truth for frame 500 but the sequence has {frames} frames" in err
        assert not (tmp_path / "r").exists()


def test_a_detection_reaching_far_beyond_the_image_is_described(tmp_path):
    """A valid box whose centre lies far left of the image (it still overlaps it) made run fail
    after all its work: describe's check that a given image size fits the boxes ("is the image
    size right?") ran on the frames' own size."""
    from conftest import SAMPLE

    seq = small_sequence(SAMPLE, tmp_path / "wide", n=10)
    (seq / "det" / "det.txt").write_text("".join(f"{f},-1,-2000,100,2100,80,0.9,-1,-1,-1\n" for f in range(1, 11)))
    (seq / "gt" / "gt.txt").unlink()
    res = run_pipeline(seq, tmp_path / "run", video=False)
    assert res.sentences and (tmp_path / "run" / "run.json").is_file()


def test_describe_checks_a_given_size_unless_it_is_known():
    from artmotion.errors import InputError
    from artmotion.language.describe import describe

    rows = np.array([[f, 1, -2000, 100, 2100, 80, 1, -1, -1, -1] for f in range(1, 11)], dtype=float)
    with pytest.raises(InputError, match="is the image size right"):
        describe(rows, [], image_size=(640, 480))
    assert describe(rows, [], image_size=(640, 480), size_known=True)
    with pytest.raises(InputError, match="size_known must be True or False"):
        describe(rows, [], image_size=(640, 480), size_known="yes")


@pytest.mark.parametrize("size", [(1, 40), (40, 1), (2000, 1200), (40, 4000)])
def test_report_images_are_made_at_the_size_they_are_shown(tmp_path, size):
    """A frame 1 pixel wide failed run in the report's halving (cv2.resize to a size of 0: an
    internal error); the largest frames took 12 GB for images shown 960 pixels wide."""
    import base64
    import re

    w, h = size
    seq = tmp_path / "seq"
    (seq / "img1").mkdir(parents=True)
    (seq / "det").mkdir()
    rng = np.random.default_rng(0)
    for i in range(1, 4):
        cv2.imwrite(str(seq / "img1" / f"{i:06d}.png"), rng.integers(0, 255, (h, w, 3), dtype=np.uint8))
    box = f"0,0,{max(1, w // 2)},{max(1, h // 2)}"
    (seq / "det" / "det.txt").write_text("".join(f"{f},-1,{box},0.9,-1,-1,-1\n" for f in range(1, 4)))
    (seq / "seqinfo.ini").write_text(f"[Sequence]\nname=s\nimDir=img1\nframeRate=25\nseqLength=3\n"
                                     f"imWidth={w}\nimHeight={h}\nimExt=.png\n")
    run_pipeline(seq, tmp_path / "run", video=False)
    page = (tmp_path / "run" / "report.html").read_text()
    shapes = [cv2.imdecode(np.frombuffer(base64.b64decode(u), np.uint8), cv2.IMREAD_COLOR).shape
              for u in re.findall(r"data:image/jpeg;base64,([A-Za-z0-9+/=]+)", page)]
    assert shapes and all(s[1] <= 960 and s[0] <= 2880 for s in shapes), shapes
