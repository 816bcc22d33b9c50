"""Trial 26 (application layer): entries a batch cannot run are reported, an interrupted batch keeps
its lines and indexes its finished runs, a locked or closed index is said so (not "damaged"),
``search --video`` takes a relative source path and every track id of a query, "no match" exits 1
with --json too, a closed stdout pipe stops only the printing, and ``index add`` refuses a run
whose files changed since."""

from __future__ import annotations

import hashlib
import json
import os
import sqlite3
import subprocess
import sys
import textwrap

import pytest

from artmotion.app import EventIndex, run_pipeline
from artmotion.app.index import parse_query
from artmotion.app.pipeline import manifest_digest
from artmotion.errors import InputError


def small_sequence(dst, n=5):
    """The first ``n`` frames of the sample as a MOTChallenge folder with its detections."""
    from conftest import SAMPLE
    from test_pipeline import small_sequence as first_frames

    return first_frames(SAMPLE, dst, n)


def make_run(root, name, sentences, source=None):
    """A run folder of an older manifest (no file digests) with these sentences."""
    d = root / name
    d.mkdir(parents=True)
    ids = sorted({t for s in sentences for t in s["tracks"]})
    manifest = {
        "name": name, "source": source or f"/videos/{name}",
        "sequence": {"length": 100, "fps": 25.0, "width": 640, "height": 480},
        "track_summary": [{"id": i, "first_frame": 1, "last_frame": 50, "boxes": 50} for i in ids],
        "events": [], "sentences": sentences,
    }
    (d / "run.json").write_text(json.dumps(manifest))
    return d


def S(text, verb, tracks, f0=10, f1=10):
    return {"sentence": text, "subject": "person", "verb": verb, "adjective": None, "tracks": tracks,
            "frame_start": f0, "frame_end": f1}


def artmotion(*args, **kwargs):
    return subprocess.run([sys.executable, "-m", "artmotion", *map(str, args)], capture_output=True, text=True,
                          **kwargs)


# -- 1: entries of the batch's folder that are no item ------------------------------------------------


def test_batch_reports_each_entry_it_does_not_run(tmp_path, run_cli):
    """A nested folder, an empty folder and a text file were left out without a word; each is one
    "skipped" line now and counted among the skipped. Hidden entries, the default output folder
    and the --index file inside the folder are the batch's own or nobody's business: not reported."""
    archive = tmp_path / "archive"
    small_sequence(archive / "a")
    small_sequence(archive / "nested" / "b")          # not looked into: the README's batch takes DIR's entries
    (archive / "empty").mkdir()
    (archive / "notes.txt").write_text("to do\n")
    (archive / ".hidden").write_text("")
    db = archive / "idx.sqlite"
    code, out, err = run_cli("batch", archive, "--index", db)
    assert code == 0, err
    lines = out.splitlines()
    assert "skipped  nested: not a video, a folder of images or a MOTChallenge folder (the folders inside it are "\
           "not searched)" in lines, out
    assert "skipped  empty: an empty folder" in lines, out
    assert "skipped  notes.txt: not a video, a folder of images or a MOTChallenge folder" in lines, out
    assert any(line.startswith("done     a: ") for line in lines), out
    assert "1 done, 3 skipped, 0 failed" in out and ".hidden" not in out
    assert not (archive / "artmotion-runs" / "b").exists()
    code, out, err = run_cli("batch", archive, "--index", db)       # resumed: the outputs are not entries to report
    assert code == 0, err
    assert "artmotion-runs" not in out and "idx.sqlite:" not in out.replace(f"in {db}", ""), out
    assert "0 done, 4 skipped, 0 failed" in out and "skipped  a: already finished" in out



@pytest.mark.parametrize("change", ["det", "seqinfo", "gt"])
def test_batch_runs_again_an_item_whose_detections_or_seqinfo_changed(tmp_path, run_cli, change):
    """New detections, or another frame rate in seqinfo.ini, were skipped as "already finished":
    the frames had not changed, and the run kept its stale results."""
    archive = tmp_path / "archive"
    seq = small_sequence(archive / "a")
    out = tmp_path / "runs"
    code, _, err = run_cli("batch", archive, "--out", out)
    assert code == 0, err
    code, text, err = run_cli("batch", archive, "--out", out)
    assert code == 0 and "skipped  a: already finished" in text, text + err
    if change == "det":
        det = seq / "det" / "det.txt"
        det.write_text("".join(line + "\n" for line in det.read_text().splitlines()[::2]))
    elif change == "gt":
        gt = seq / "gt" / "gt.txt"
        gt.write_text("".join(line + "\n" for line in gt.read_text().splitlines()[1:]))
    else:
        ini = seq / "seqinfo.ini"
        ini.write_text(ini.read_text().replace("frameRate=25", "frameRate=5"))
    code, text, err = run_cli("batch", archive, "--out", out)
    assert code == 0 and "1 done, 0 skipped" in text, text + err
    if change == "seqinfo":
        assert json.loads((out / "a" / "run.json").read_text())["sequence"]["fps"] == 5

# -- 2: an interrupted batch --------------------------------------------------------------------------


@pytest.mark.parametrize("indexable", [True, False])
def test_interrupted_batch_keeps_its_lines_and_indexes_the_finished_runs(tmp_path, indexable):
    """Stdout a file: the "done" line of the item that finished before Ctrl-C was never written
    (the lines came at the end), and with --index its run was not indexed. When the runs cannot be
    indexed (here a run changed since), the one line says how to index them."""
    seq = small_sequence(tmp_path / "archive" / "a")
    small_sequence(tmp_path / "archive" / "b")
    run_pipeline(seq, tmp_path / "runs" / "a", video=False)
    if not indexable:
        (tmp_path / "runs" / "a" / "results.txt").write_text("")
    db = tmp_path / "idx.sqlite"
    # the batch as it is when a's run finished and b's had not: the signal arrives
    script = textwrap.dedent(f"""
        import signal, sys
        from pathlib import Path
        import artmotion.app.batch as batch
        from artmotion.cli import run

        def run_batch(root, out, on_progress=None, **kwargs):
            a = batch.ItemOutcome({str(seq)!r}, "done", str(Path(out) / "a"), 1.0, tracks=6, sentences=7)
            on_progress(a, 1, 2)
            raise batch.BatchInterrupted(signal.SIGINT, batch.BatchReport([a]), [{str(tmp_path / "archive" / "b")!r}])

        batch.run_batch = run_batch
        sys.argv = ["artmotion", "batch", {str(tmp_path / "archive")!r}, "--out", {str(tmp_path / "runs")!r},
                    "--index", {str(db)!r}]
        run()
    """)
    with open(tmp_path / "out.txt", "w") as out:
        proc = subprocess.run([sys.executable, "-c", script], stdout=out, stderr=subprocess.PIPE, text=True)
    assert proc.returncode == 130, proc.stderr
    assert (tmp_path / "out.txt").read_text() == "done     a: 6 tracks, 7 sentences, 1.0 s\n"
    assert proc.stderr.count("\n") == 1 and "1 of 2 items finished (kept)" in proc.stderr, proc.stderr
    if not indexable:
        assert "the finished runs are not indexed" in proc.stderr and "changed since the run: results.txt" in \
            proc.stderr and f"'artmotion index add {tmp_path / 'runs'} --db {db}'" in proc.stderr, proc.stderr
        assert not db.exists()
        return
    assert f"; indexed 1 runs in {db} (1 videos)" in proc.stderr, proc.stderr
    with EventIndex(db, write=False) as idx:
        assert [v["name"] for v in idx.videos()] == ["a"]


# -- 3: a locked, a closed index ----------------------------------------------------------------------


@pytest.fixture
def merges(tmp_path):
    run = make_run(tmp_path / "runs", "yard", [
        S("Person 2 and person 8 merge (frame 10).", "merge", [2, 8]),
        S("Person 4 and person 8 merge (frame 10).", "merge", [4, 8]),
        S("Person 4 moves right (frames 1-50).", "moves", [4], 1, 50),
    ], source=str(tmp_path / "videos" / "yard.mp4"))
    db = tmp_path / "idx.sqlite"
    with EventIndex(db) as idx:
        idx.add_run(run)
    return db


def test_a_locked_index_is_not_called_damaged(merges, tmp_path, run_cli, monkeypatch):
    """Another process writing to the index: "damaged index (database is locked); build a new one"
    would have the user throw a good index away."""
    import artmotion.app.index as index

    monkeypatch.setattr(index, "BUSY_TIMEOUT", 0.05, raising=False)     # (SQLite's wait: 5 s before)
    other = sqlite3.connect(merges, isolation_level=None)
    try:
        other.execute("BEGIN IMMEDIATE")       # a writer: adding waits for it, then gives up
        code, _, err = run_cli("index", "add", tmp_path / "runs", "--db", merges)
        assert code == 2 and err.count("\n") == 1, err
        assert "locked by another process" in err and "try again" in err and "damaged" not in err, err
        other.execute("COMMIT")
        other.execute("BEGIN EXCLUSIVE")       # a writer committing: even reading waits
        code, _, err = run_cli("search", "person", "--db", merges)
        assert code == 2 and "locked by another process" in err and "damaged" not in err, err
    finally:
        other.close()
    code, out, err = run_cli("search", "person", "--db", merges)      # the index was good all along
    assert code == 0, err


def test_a_closed_index_says_so(merges):
    idx = EventIndex(merges, write=False)
    idx.close()
    for use in (lambda: idx.search("person"), idx.videos, lambda: EventIndex.add_runs(idx, [])):
        with pytest.raises(InputError) as exc:
            use()
        assert "closed" in str(exc.value) and "damaged" not in str(exc.value), exc.value
    idx = EventIndex(merges)
    idx.close()
    with pytest.raises(InputError, match="the index is closed"):
        idx.add_run(merges.parent / "runs" / "yard")


# -- 4, 5, 6: search ----------------------------------------------------------------------------------


def test_search_video_takes_a_relative_source_path(merges, tmp_path, run_cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli("search", "person 4 moves", "--db", merges, "--video", "videos/yard.mp4")
    assert code == 0 and "Person 4 moves right" in out, (out, err)
    code, out, err = run_cli("search", "person 4 moves", "--db", merges, "--video", "yard.mp4")
    assert code == 2 and "no video 'yard.mp4'" in err     # (neither its name nor its source)


def test_search_counts_every_track_id_of_the_query(merges):
    """Only the first id counted: "Person 2 and person 8 merge" ranked level with the sentence
    naming both asked-for persons."""
    with EventIndex(merges, write=False) as idx:
        hits = idx.search("person 8 and person 4 merge")
    assert [h.tracks for h in hits] == [[4, 8], [2, 8]], hits
    assert hits[0].score > hits[1].score
    q = parse_query("person 8 and person 4 merge")
    assert (q.track, q.tracks) == (8, [8, 4])


def test_no_match_exits_1_with_json_too(merges, run_cli):
    code, out, _ = run_cli("search", "zebra", "--db", merges)
    assert (code, out) == (1, "no match\n")
    code, out, err = run_cli("search", "zebra", "--db", merges, "--json")
    assert code == 1 and json.loads(out) == [] and err == ""


# -- 7: a closed stdout pipe --------------------------------------------------------------------------


def test_a_closed_stdout_pipe_stops_the_printing_not_the_work(tmp_path):
    """``artmotion run … | head -1``: the first write after head left raised BrokenPipeError out of
    the command: exit 1 without a word, and the index of --index never written."""
    seq = small_sequence(tmp_path / "a")
    db = tmp_path / "idx.sqlite"
    read, write = os.pipe()
    os.close(read)                    # the reader is gone before anything is written
    try:
        run = subprocess.run([sys.executable, "-m", "artmotion", "run", seq, "--no-video", "--out", tmp_path / "run",
                              "--index", db], stdout=write, stderr=subprocess.PIPE, text=True)
        search = subprocess.run([sys.executable, "-m", "artmotion", "search", "person", "--db", db, "--limit", "500"],
                                stdout=write, stderr=subprocess.PIPE, text=True)
    finally:
        os.close(write)
    assert run.returncode == 0 and run.stderr == "", run.stderr
    assert (tmp_path / "run" / "run.json").is_file()
    with EventIndex(db, write=False) as idx:
        assert [v["name"] for v in idx.videos()] == ["a"]
    assert search.returncode == 0 and search.stderr == "", search.stderr



@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")
def test_a_full_stdout_is_one_line_and_the_work_is_done(tmp_path):
    """``artmotion run … --index I > /dev/full``: the printing's ENOSPC aborted the command after
    its run folder, leaving the index unwritten, with "error: No space left on device" naming no
    file. The work is done, and the one line says what was not printed."""
    seq = small_sequence(tmp_path / "a")
    db = tmp_path / "idx.sqlite"
    with open("/dev/full", "w") as full:
        run = subprocess.run([sys.executable, "-m", "artmotion", "run", seq, "--no-video", "--out", tmp_path / "run",
                              "--index", db], stdout=full, stderr=subprocess.PIPE, text=True)
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert run.stderr.startswith("artmotion: error: standard output: cannot write: No space left on device")
    assert (tmp_path / "run" / "run.json").is_file()
    with EventIndex(db, write=False) as idx:
        assert [v["name"] for v in idx.videos()] == ["a"]

# -- 8: a run whose files changed since ---------------------------------------------------------------


@pytest.mark.parametrize("change", ["truncate results.txt", "cut sentences.txt", "remove events.jsonl"])
def test_index_add_refuses_a_run_whose_files_changed(tmp_path, run_cli, change):
    """After results.txt was truncated or sentences.txt cut, ``index add`` took the manifest's
    counts as they were (``index list`` showed the old ones)."""
    res = run_pipeline(small_sequence(tmp_path / "a"), tmp_path / "run", video=False)
    db = tmp_path / "idx.sqlite"
    code, _, err = run_cli("index", "add", res.out_dir, "--db", db)       # as the run left it: added
    assert code == 0, err
    verb, name = change.split()
    path = res.out_dir / name
    if verb == "remove":
        path.unlink()
    else:
        text = path.read_text()
        path.write_text(text[: len(text) // 2] if verb == "truncate" else "".join(text.splitlines(True)[:-1]))
    before = db.read_bytes()
    code, _, err = run_cli("index", "add", res.out_dir, "--db", db)
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"artmotion: error: {res.out_dir}: changed since the run: {name}") and "run it again" in err
    assert db.read_bytes() == before
    code, _, err = run_cli("index", "add", res.out_dir, "--db", tmp_path / "new.sqlite")
    assert code == 2 and not (tmp_path / "new.sqlite").exists()
    manifest = json.loads((res.out_dir / "run.json").read_text())         # what the check goes by
    assert sorted(manifest["sha256"]) == ["events.jsonl", "results.txt", "sentences.txt"]


def test_index_add_refuses_a_manifest_edited_or_malformed_since_the_run(tmp_path, run_cli):
    """The index takes a run's sentences, events and tracks from run.json; only the files had
    digests, so a sentence edited in run.json alone was indexed (and found by search), as were a
    NaN token, a key given twice, a sentence of two lines and a manifest whose digests were
    emptied beside a changed sentences.txt."""
    res = run_pipeline(small_sequence(tmp_path / "a"), tmp_path / "run", video=False)
    path = res.out_dir / "run.json"
    good = path.read_text()
    manifest = json.loads(good)
    assert manifest["sentences"] and manifest["track_summary"]
    sentence = manifest["sentences"][0]["sentence"]

    def edited(change):
        m = json.loads(good)
        change(m)
        return json.dumps(m)

    cases = {
        "changed since the run: run.json": edited(lambda m: m["sentences"][0].update(sentence="Person 9 flies.")),
        "changed since the run: run.json ": edited(lambda m: m["track_summary"][0].update(boxes=1)),
        # its digests taken out: what it says the files hold is still compared with them
        " changed since the run: run.json": edited(lambda m: (m["sentences"][0].update(sentence="Person 9 flies."),
                                                              m.pop("sha256"), m.pop("manifest_sha256"))),
        # what no file holds (a sentence's tracks, frames, verb): the manifest's own digest
        " changed since the run: run.json ": edited(lambda m: m["sentences"][0].update(verb="enters", frame_start=2)),
        "'manifest_sha256' is not a SHA-256 digest": edited(lambda m: m.update(manifest_sha256="x")),
        "corrupt manifest: NaN is not a number JSON allows": good.replace('"tracking_fps": ', '"tracking_fps": NaN, "x": '),
        "corrupt manifest: key 'name' given twice": good.replace('"name": ', '"name": "other", "name": ', 1),
        "one line of text": edited(lambda m: m["sentences"][0].update(sentence=sentence + "\nPerson 9 flies.")),
        "'sha256' is not an object of the SHA-256 digests": edited(lambda m: m.update(sha256={})),
        "'tracking_fps' is not a finite number": good.replace('"tracking_fps": ', '"tracking_fps": 1e999, "x": '),
    }
    for needle, text in cases.items():
        path.write_text(text)
        code, _, err = run_cli("index", "add", res.out_dir, "--db", tmp_path / "idx.sqlite")
        assert code == 2 and needle.strip() in err and err.count("\n") == 1, (needle, err)
        assert not (tmp_path / "idx.sqlite").exists()
    path.write_text(good)
    sentences = res.out_dir / "sentences.txt"      # not UTF-8 (its digest matched): an internal error before
    text = sentences.read_bytes()
    sentences.write_bytes(b"\xff" + text)
    damaged = json.loads(good)
    damaged["sha256"]["sentences.txt"] = hashlib.sha256(b"\xff" + text).hexdigest()
    damaged["manifest_sha256"] = manifest_digest(damaged)
    path.write_text(json.dumps(damaged))
    code, _, err = run_cli("index", "add", res.out_dir, "--db", tmp_path / "idx.sqlite")
    assert code == 2 and "changed since the run: run.json" in err and err.count("\n") == 1, err
    sentences.write_bytes(text)
    path.write_text(good)
    assert run_cli("index", "add", res.out_dir, "--db", tmp_path / "idx.sqlite")[0] == 0


def test_is_finished_says_no_when_the_detections_cannot_be_read(tmp_path, monkeypatch):
    """The digest of the inputs was read outside the check that turns an unreadable input into
    "not finished": an OSError escaped and stopped the whole batch's planning."""
    from pathlib import Path

    from artmotion.app.pipeline import is_finished, run_pipeline

    seq = small_sequence(tmp_path / "a")
    run_pipeline(seq, tmp_path / "run", video=False)
    assert is_finished(tmp_path / "run", seq)
    real = Path.read_bytes

    def unreadable(self):
        if self.name == "det.txt":
            raise OSError(5, "Input/output error", str(self))
        return real(self)

    monkeypatch.setattr(Path, "read_bytes", unreadable)
    assert not is_finished(tmp_path / "run", seq)
