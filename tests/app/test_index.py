import json

import cv2
import numpy as np
import pytest

from artmotion.app.index import EventIndex, parse_query
from artmotion.errors import InputError


def make_run(root, name, sentences, events=()):
    d = root / name
    d.mkdir(parents=True)
    manifest = {
        "name": name,
        "source": f"/videos/{name}",
        "sequence": {"length": 100, "fps": 25.0, "width": 640, "height": 480},
        "track_summary": [{"id": 1, "first_frame": 1, "last_frame": 50, "boxes": 50},
                          {"id": 2, "first_frame": 10, "last_frame": 100, "boxes": 91}],
        "events": list(events),
        "sentences": sentences,
    }
    (d / "run.json").write_text(json.dumps(manifest))
    return d


def S(text, verb, adj, tracks, f0, f1, subject="person"):
    return {"sentence": text, "subject": subject, "verb": verb, "adjective": adj, "tracks": tracks,
            "frame_start": f0, "frame_end": f1}


@pytest.fixture
def index(tmp_path):
    a = make_run(tmp_path, "campus", [
        S("Person 1 enters from the left (frames 1-1).", "enters", "left", [1], 1, 1),
        S("Person 1 exits to the right (frames 50-50).", "exits", "right", [1], 50, 50),
        S("Person 2 exits to the left (frames 100-100).", "exits", "left", [2], 100, 100),
        S("Person 1 and person 2 merge (frames 30-30).", "merge", None, [1, 2], 30, 30),
    ], events=[{"type": "enter", "frame": 1, "tracks": [1], "side": "left"}])
    b = make_run(tmp_path, "square", [
        S("Person 1 moves left and downwards (frames 5-40).", "moves", "left and downwards", [1], 5, 40),
        S("Person 1 and person 2 walk together to the right (frames 10-60).", "walk together", "right", [1, 2], 10, 60),
        S("Person 2 vanishes inside (frames 70-70).", "vanishes", "inside", [2], 70, 70),
    ])
    idx = EventIndex(tmp_path / "db.sqlite")
    idx.add_run(a)
    idx.add_run(b)
    yield idx
    idx.close()


def test_parse_query():
    q = parse_query("Person 3 exits left")
    assert (q.subject, q.track, q.verb, q.direction, q.unknown) == ("person", 3, "exits", "left", [])
    assert parse_query("man in red exits").unknown == ["man", "red"]
    assert parse_query("people walking together").verb == "interacts"
    # a number after "frame" is a frame, before "people" a count, else the track (its sign kept)
    q = parse_query("who enters at frame 21")
    assert (q.verb, q.frame, q.track) == ("enters", 21, None)
    assert parse_query("2 people walk together").track is None
    assert parse_query("person -5 exits").track == -5
    assert (parse_query("person 3 at frame 40").track, parse_query("person 3 at frame 40").frame) == (3, 40)
    # the grammar's two-person motions are verbs of their own, not "moves" (nor a direction)
    assert parse_query("move apart").verb == "moves apart"
    assert (parse_query("move away from each other").verb, parse_query("move away from each other").direction) \
        == ("moves apart", None)
    assert parse_query("people moving towards each other").verb == "approach each other"
    assert parse_query("person moves towards the bottom").direction == "downwards"


def test_two_people_moving_apart_are_found_before_anyone_moving(tmp_path):
    """'move apart' listed every 'Person N moves right' first (both filed as 'moves', same score)."""
    run = make_run(tmp_path, "pair", [
        S("Person 1 moves right (frames 1-20).", "moves", "right", [1], 1, 20),
        S("Person 1 and person 2 move apart (frames 5-20).", "move apart", None, [1, 2], 5, 20),
        S("Person 1 and person 2 move towards each other (frames 21-30).", "move towards each other", None,
          [1, 2], 21, 30),
    ])
    with EventIndex(tmp_path / "db.sqlite") as idx:
        idx.add_run(run)
        assert [h.sentence for h in idx.search("move apart")] == ["Person 1 and person 2 move apart (frames 5-20)."]
        assert [h.frame_start for h in idx.search("who moves towards each other")] == [21]
        assert [h.frame_start for h in idx.search("person moves")] == [1]


def test_a_frame_number_is_a_moment_not_a_track(index):
    """'exits at frame 50' looked for track 50 and answered "no match"."""
    hits = index.search("exits at frame 50")
    assert [h.sentence for h in hits] == ["Person 1 exits to the right (frames 50-50)."]
    assert [h.sentence for h in index.search("frame 20 moves")] == ["Person 1 moves left and downwards (frames 5-40)."]
    assert index.search("exits at frame 51") == []


def test_structured_search_best_first(index):
    hits = index.search("person exits left")
    assert [h.sentence for h in hits][:1] == ["Person 2 exits to the left (frames 100-100)."]
    assert all(h.verb == "exits" for h in hits)  # vanishes counts as an exit too
    assert hits[0].score > hits[-1].score
    assert {h.video for h in hits} == {"campus", "square"}


def test_track_and_video_filters(index):
    hits = index.search("person 2 merges")
    assert len(hits) == 1 and hits[0].tracks == [1, 2] and hits[0].frame_start == 30
    assert index.search("exits", video="square")[0].sentence.startswith("Person 2 vanishes")
    assert index.search("walk together")[0].video == "square"
    assert index.search("moves left")[0].adjective == "left and downwards"
    # a video by its source too (two videos may share a name); one the index lacks is an error
    assert [h.video for h in index.search("exits", video="/videos/square")] == ["square"]
    with pytest.raises(InputError, match="no video 'sqare' in the index"):
        index.search("exits", video="sqare")


def test_fulltext_fallback_and_empty(index):
    hits = index.search("frames inside")
    assert hits and hits[0].match == "fulltext" and "inside" in hits[0].sentence
    # every word must occur (stemmed): no flood of hits that share only "person"
    assert index.search("zebra inside") == []
    assert [(h.match, h.tracks) for h in index.search("inside")] == [("fulltext", [2])]
    # understood whole and nothing matches: no full-text guesses ("3" would match "24.3 s")
    assert index.search("person 3 merges") == []
    with pytest.raises(InputError):
        index.search("   ")


def test_numbers_in_a_query_are_never_matched_as_text(tmp_path):
    """A track id or frame the structured match does not find is not looked up as a word: "frame 0"
    found every sentence with "0.0 s", "person -2" found person 2 (full text splits off the minus)."""
    run = make_run(tmp_path, "yard", [
        S("Person 2 enters from the left at 0.0 s (frames 10-10).", "enters", "left", [2], 10, 10),
        S("Person 2 lingers near the gate at 2.0 s (frames 50-60).", "lingers", None, [2], 50, 60),
    ])
    with EventIndex(tmp_path / "n.sqlite") as idx:
        idx.add_run(run)
        assert idx.search("frame 0") == []
        assert idx.search("person -2") == []
        assert idx.search("lingers at frame 40") == []
        assert idx.search("person 1 gate") == []
        assert [h.frame_start for h in idx.search("gate at frame 55")] == [50]


def test_a_damaged_fulltext_index_is_no_empty_answer(index, tmp_path):
    """quick_check does not look inside FTS5's blocks: zeroed, they read as 'no match'."""
    import contextlib
    import sqlite3

    assert index.search("inside")
    with contextlib.closing(sqlite3.connect(index.path)) as conn, conn:
        conn.execute("UPDATE sentences_fts_data SET block = zeroblob(length(block)) WHERE id > 10")
    with EventIndex(index.path, write=False) as damaged:
        for query in ("inside", "zebra"):
            with pytest.raises(InputError, match="damaged index"):
                damaged.search(query)
        assert damaged.search("person 2 exits")    # structured answers do not read the full-text index


def test_readding_replaces_video(index, tmp_path):
    assert len(index.videos()) == 2
    index.add_run(tmp_path / "campus")
    vids = {v["name"]: v for v in index.videos()}
    assert len(vids) == 2 and vids["campus"]["sentences"] == 4 and vids["campus"]["events"] == 1
    # full-text rows of the replaced video are gone too: no duplicate hits
    assert len(index.search("merge")) == 1


def test_bad_run_and_bad_db(tmp_path, run_cli):
    (tmp_path / "empty").mkdir()
    code, _, err = run_cli("index", "add", tmp_path / "empty", "--db", tmp_path / "x.sqlite")
    assert code == 2 and "no finished run" in err and err.count("\n") == 1
    bad = tmp_path / "bad.sqlite"
    bad.write_bytes(b"this is not sqlite at all" * 100)
    code, _, err = run_cli("search", "person", "--db", bad)
    assert code == 2 and "bad.sqlite" in err
    code, _, err = run_cli("search", "person", "--db", tmp_path / "missing.sqlite")
    assert code == 2 and "no such index" in err


def test_cli_add_and_search_json(index, tmp_path, run_cli):
    db = tmp_path / "cli.sqlite"
    code, out, _ = run_cli("index", "add", tmp_path, "--db", db)  # a folder of run folders
    assert code == 0 and "2 videos" in out
    code, out, _ = run_cli("search", "person enters from the left", "--db", db, "--json")
    hits = json.loads(out)
    assert code == 0 and hits[0]["video"] == "campus" and hits[0]["frame_start"] == 1
    code, out, _ = run_cli("search", "zebra", "--db", db)
    assert code == 1 and "no match" in out
    # a copy of a run (the same source): it replaces the entry, and says so ("added" both, 1 video)
    import shutil

    shutil.copytree(tmp_path / "campus", tmp_path / "copies" / "campus2")
    code, out, _ = run_cli("index", "add", tmp_path / "copies" / "campus2", "--db", db)
    assert code == 0 and f"(replacing {(tmp_path / 'campus').resolve()}: a run of the same source)" in out
    assert "2 videos" in out
    code, out, _ = run_cli("index", "add", tmp_path / "copies" / "campus2", "--db", db)
    assert code == 0 and "(again)" in out


def test_runs_are_added_all_or_none(index, tmp_path, monkeypatch):
    """Several runs are added in one transaction: a full disk at the second left the first added
    while the command said only that the disk was full."""
    import sqlite3

    c = make_run(tmp_path / "more", "street", [S("Person 1 stays (frames 1-9).", "stays", None, [1], 1, 9)])
    d = make_run(tmp_path / "more", "park", [S("Person 2 stays (frames 1-9).", "stays", None, [2], 1, 9)])
    real, calls = EventIndex._insert, []

    def full_at_the_second(self, *args):
        calls.append(args)
        if len(calls) == 2:
            raise sqlite3.OperationalError("database or disk is full")
        return real(self, *args)

    monkeypatch.setattr(EventIndex, "_insert", full_at_the_second)
    with pytest.raises(InputError, match="cannot write the index: database or disk is full"):
        index.add_runs([(c, json.loads((c / "run.json").read_text())), (d, json.loads((d / "run.json").read_text()))])
    assert sorted(v["name"] for v in index.videos()) == ["campus", "square"]


def test_search_limit_must_be_a_whole_number_of_at_least_one(index):
    assert len(index.search("person exits left", limit=1)) == 1
    for bad in (-1, 0, 2.5, float("nan")):
        with pytest.raises(InputError, match="limit"):
            index.search("person exits left", limit=bad)
    with pytest.raises(InputError, match="text"):
        index.search(None)


def test_run_refuses_an_index_inside_its_run_folder(tmp_path, run_cli, sample_seq):
    """``make demo`` put its index in the run folder: the next run into that folder was refused (a
    folder holding more than a run is not replaced). The index belongs next to the folder."""
    code, _, err = run_cli("run", sample_seq, "--out", tmp_path / "run", "--index", tmp_path / "run" / "i.sqlite")
    assert code == 2 and err.strip().endswith("i.sqlite: is the run folder --out or inside it: keep the index "
                                              "outside it (next to it)"), err
    assert list(tmp_path.iterdir()) == []
    # the run folder itself as the index (failed after the whole run), or an index among the input's frames
    code, _, err = run_cli("run", sample_seq, "--out", tmp_path / "run", "--index", tmp_path / "run")
    assert code == 2 and "run: is the run folder --out or inside it" in err, err
    frames = tmp_path / "frames"
    frames.mkdir()
    for k in (1, 2):
        cv2.imwrite(str(frames / f"{k:06d}.png"), np.zeros((48, 64, 3), np.uint8))
    code, _, err = run_cli("run", frames, "--out", tmp_path / "run", "--index", frames / "i.sqlite")
    assert code == 2 and "i.sqlite: is inside the input folder" in err and err.count("\n") == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames"] and len(list(frames.iterdir())) == 2


@pytest.mark.parametrize("change", ["UPDATE sentences SET tracks = '[1e400]'", "UPDATE sentences SET tracks = '[1.5]'",
                                    "UPDATE sentences SET tracks = '{\"a\": 1}'", "UPDATE sentences SET sentence = ''"])
def test_damaged_sentence_rows_are_a_damaged_index(index, change):
    """Track ids of 1e400 came out as Infinity (`search --json` printed invalid JSON), an emptied
    sentence as a blank hit (found by a fuzzing review)."""
    import contextlib
    import sqlite3

    with contextlib.closing(sqlite3.connect(index.path)) as conn, conn:
        conn.execute(change)
    with EventIndex(index.path, write=False) as damaged, pytest.raises(InputError, match="damaged index"):
        damaged.search("person 2 exits")


@pytest.mark.parametrize("change", ["UPDATE videos SET fps = -1", "UPDATE videos SET fps = 'nan'",
                                    "UPDATE videos SET frames = 'x'"])
def test_a_damaged_video_row_is_a_damaged_index(index, change):
    import contextlib
    import sqlite3

    with contextlib.closing(sqlite3.connect(index.path)) as conn, conn:
        conn.execute(change)
    with EventIndex(index.path, write=False) as damaged, pytest.raises(InputError, match="damaged index"):
        damaged.videos()


@pytest.mark.parametrize("source", [None, ""])
def test_a_manifest_with_a_null_or_empty_source_is_refused(tmp_path, source):
    """No run writes it so; the index took the run folder for the source and listed the same
    video twice (found by a fuzzing review). A manifest without the key (an older one) is read."""
    d = make_run(tmp_path, "cam", [S("Person 1 enters from the left (frames 1-1).", "enters", "left", [1], 1, 1)])
    run = json.loads((d / "run.json").read_text())
    run["source"] = source
    (d / "run.json").write_text(json.dumps(run))
    with EventIndex(tmp_path / "db.sqlite") as idx, pytest.raises(InputError, match="'source' is empty"):
        idx.add_run(d)
    del run["source"]
    (d / "run.json").write_text(json.dumps(run))
    with EventIndex(tmp_path / "db2.sqlite") as idx:
        idx.add_run(d)
        assert len(idx.videos()) == 1


def test_a_journal_left_by_an_interrupted_write_is_named(index, tmp_path, run_cli):
    """A hot journal beside the index (a write killed mid-transaction) made search and index list,
    which open the file read-only, say "the file is read-only"; SQLite must roll it back first."""
    import shutil
    import sqlite3

    db = tmp_path / "db.sqlite"
    index.close()
    work = tmp_path / "work.sqlite"
    shutil.copy(db, work)
    c = sqlite3.connect(work, isolation_level=None)
    c.execute("PRAGMA cache_size = 1")
    c.execute("BEGIN IMMEDIATE")
    c.execute("UPDATE sentences SET sentence = sentence || ' X'")
    for _ in range(200):
        c.execute("INSERT INTO sentences(video_id, sentence, tracks) VALUES (1, ?, '[1]')", ("j" * 400,))
    crashed = tmp_path / "crashed.sqlite"
    shutil.copy(work, crashed)
    shutil.copy(tmp_path / "work.sqlite-journal", tmp_path / "crashed.sqlite-journal")
    c.execute("ROLLBACK")
    c.close()
    for args in (("search", "person exits", "--db", crashed), ("index", "list", "--db", crashed)):
        code, _, err = run_cli(*args)
        assert code == 2 and "an interrupted write left crashed.sqlite-journal beside it" in err, err
        assert err.count("\n") == 1
    sqlite3.connect(crashed).execute("PRAGMA integrity_check").fetchall()  # a client that writes rolls it back
    code, out, err = run_cli("search", "person exits", "--db", crashed)
    assert code == 0 and "Person 1 exits to the right" in out and " X" not in out, err


def test_index_list_keeps_a_video_on_one_line(tmp_path, run_cli):
    """A run named with a line break split its entry over two lines, and a manifest without its
    sequence (older runs have none) printed "None frames"."""
    run = make_run(tmp_path, "x", [S("Person 1 stays (frames 1-9).", "stays", None, [1], 1, 9)])
    manifest = json.loads((run / "run.json").read_text())
    manifest["name"] = "a\nb\tc"
    del manifest["sequence"]
    (run / "run.json").write_text(json.dumps(manifest))
    db = tmp_path / "db.sqlite"
    code, _, err = run_cli("index", "add", run, "--db", db)
    assert code == 0, err
    code, out, err = run_cli("index", "list", "--db", db)
    assert code == 0 and out == "a\\nb\\tc: frames unknown, 2 tracks, 0 events, 1 sentences\n", out + err
    code, out, _ = run_cli("search", "person stays", "--db", db)
    assert code == 0 and len(out.splitlines()) == 1 and "a\\nb\\tc" in out
