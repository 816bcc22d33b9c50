"""Names the program is given do not choose where it writes, and names it cannot store as text are
refused before the work, not after it (a sequence's own seqinfo.ini name, a file name that is not
UTF-8, a manifest whose numbers are of the wrong kind)."""

from __future__ import annotations

import json
import os
import shutil
from types import SimpleNamespace

import pytest
from test_index_safety import _run
from test_pipeline import small_sequence

from artmotion.app import EventIndex, run_batch
from artmotion.app.pipeline import default_run_dir
from artmotion.errors import InputError
from artmotion.io import check_text

ODD = os.fsdecode(b"caf\xe9")      # a Latin-1 name: not UTF-8, read by Python as a lone surrogate


@pytest.mark.parametrize("name", ["../../escaped", "/tmp/elsewhere", "", ".", "..", "a/b"])
def test_a_sequence_name_does_not_choose_where_the_run_goes(tmp_path, name):
    src = tmp_path / "archive" / "cam1"
    src.mkdir(parents=True)
    root = tmp_path / "runs"
    out = default_run_dir(SimpleNamespace(name=name, path=src), "f" * 16, root=root)
    assert out.parent == root and out.name == "cam1"
    assert default_run_dir(SimpleNamespace(name="PETS09-S2L1", path=src), "f" * 16, root=root) == root / "PETS09-S2L1"


def test_a_manifest_of_the_wrong_kind_of_numbers_is_refused_and_the_index_kept(tmp_path, run_cli):
    db = tmp_path / "i.sqlite"
    assert run_cli("index", "add", _run(tmp_path / "r1"), "--db", db)[0] == 0
    bad = _run(tmp_path / "r2", name="cam2", source="/videos/cam2.mp4")
    past = _run(tmp_path / "r3", name="cam3", source="/videos/cam3.mp4")
    for folder, edit in ((bad, lambda m: m["sequence"].update(length=10.5)),
                         (past, lambda m: m["sentences"][0].update(frame_end=60))):
        manifest = json.loads((folder / "run.json").read_text())
        edit(manifest)
        (folder / "run.json").write_text(json.dumps(manifest))
        code, _, err = run_cli("index", "add", folder, "--db", db)
        assert code == 2 and "corrupt manifest" in err and err.count("\n") == 1, err
    code, out, _ = run_cli("index", "list", "--db", db)      # the index still reads, with the one good run
    assert code == 0 and "cam1" in out and "cam2" not in out and "cam3" not in out


def test_check_text():
    check_text("café/ünïcode")
    with pytest.raises(InputError, match="not UTF-8"):
        check_text(ODD)


def _odd_sequence(sample, dst):
    """A small sequence at ``dst``, a name that is not UTF-8 (made under another, then renamed:
    OpenCV cannot write there)."""
    return small_sequence(sample, dst.with_name("made"), n=4).rename(dst)


def test_names_that_are_not_text_are_refused_before_the_work(tmp_path, run_cli, monkeypatch, sample_seq):
    monkeypatch.chdir(tmp_path)
    seq = _odd_sequence(sample_seq, tmp_path / ODD)
    code, _, err = run_cli("run", seq, "--no-video", "--index", tmp_path / "i.sqlite")
    assert code == 2 and "not UTF-8" in err and err.count("\n") == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == [ODD]      # no run folder, no index
    code, _, err = run_cli("search", "person", "--video", ODD, "--db", tmp_path / "i.sqlite")
    assert code == 2 and "--video" in err and "damaged" not in err and err.count("\n") == 1, err


def test_a_run_folder_whose_name_is_not_text_is_named_not_the_index(tmp_path, run_cli):
    """index add of a run folder whose name is not UTF-8 called a healthy index damaged ("build a
    new one"), and a new one that was never made; now the folder is named, the index untouched."""
    good = _run(tmp_path / "good")
    db = tmp_path / "i.sqlite"
    assert run_cli("index", "add", good, "--db", db)[0] == 0
    before = db.read_bytes()
    odd = tmp_path / ODD
    shutil.copytree(good, odd)
    for index in (db, tmp_path / "new.sqlite"):
        code, _, err = run_cli("index", "add", odd, "--db", index)
        assert code == 2 and "not UTF-8" in err and "rename the folder" in err and "damaged" not in err, err
    assert db.read_bytes() == before and not (tmp_path / "new.sqlite").exists()
    (tmp_path / "link").symlink_to(odd)     # (the index keeps the folder resolved: the link's target)
    code, _, err = run_cli("index", "add", tmp_path / "link", "--db", db)
    assert code == 2 and "not UTF-8" in err and "damaged" not in err, err


@pytest.mark.parametrize("what", ["video", "out", "annotated"])
def test_opencv_is_never_given_a_name_that_is_not_text(tmp_path, run_cli, monkeypatch, sample_seq, what):
    """OpenCV kills the process (a segmentation fault) on such a name, for reading or writing."""
    monkeypatch.chdir(tmp_path)
    video = sample_seq / "TUD-Campus.mp4"
    if what == "video":
        odd = tmp_path / f"{ODD}.mp4"
        shutil.copy(video, odd)
        args = ("track", odd, "--out", "t.txt")
    elif what == "out":
        args = ("run", small_sequence(sample_seq, tmp_path / "seq", n=4), "--out", ODD)
    else:
        args = ("track", small_sequence(sample_seq, tmp_path / "seq", n=4), "--video", f"{ODD}.mp4", "--out", "t.txt")
    before = sorted(p.name for p in tmp_path.iterdir())
    code, _, err = run_cli(*args)
    assert code == 2 and "not UTF-8" in err and err.count("\n") == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_batch_item_whose_name_is_not_text_leaves_the_others_to_run(tmp_path, sample_seq):
    archive = tmp_path / "archive"
    small_sequence(sample_seq, archive / "good", n=4)
    _odd_sequence(sample_seq, archive / ODD)
    report = run_batch(archive, tmp_path / "runs", workers=1, processes=False)
    status = {os.path.basename(o.item): (o.status, o.message) for o in report.outcomes}
    assert status["good"][0] == "done"
    assert status[ODD][0] == "failed" and "not UTF-8" in status[ODD][1]     # (it was "ignored", exit 0)
    with EventIndex(tmp_path / "i.sqlite") as idx:      # the finished run goes into an index
        idx.add_run(tmp_path / "runs" / "good")
        assert [v["name"] for v in idx.videos()] == ["good"]


def test_a_batch_item_that_cannot_be_run_fails_the_batch(tmp_path, run_cli):
    """A video named by a link to nothing, or a sequence folder whose name is not UTF-8, was
    counted as skipped (exit 0); alone in the folder, it was "no sequences or videos found". They
    are items that failed (exit 2); a file that is no item is still left out and said."""
    archive = tmp_path / "archive"
    archive.mkdir()
    (archive / "dangling.mp4").symlink_to(tmp_path / "nowhere.mp4")
    (archive / "notes.txt").write_text("mine")
    (archive / "unmounted").symlink_to(tmp_path / "usb" / "MOT17-02")     # a sequence on a disk not there
    code, out, err = run_cli("batch", archive, "--out", tmp_path / "runs")
    assert code == 2 and "dangling.mp4: a link to nothing" in err and "unmounted: a link to nothing" in err, err
    assert "0 done, 1 skipped, 2 failed" in out, out
    (archive / "dangling.mp4").unlink()
    (archive / "unmounted").unlink()
    (archive / ODD).mkdir()                     # a folder that is no item, whatever its name: left out
    (archive / ODD / "notes.txt").write_text("mine")
    code, out, err = run_cli("batch", archive, "--out", tmp_path / "runs")
    assert code == 2 and "no sequences or videos found" in err, (out, err)
    (archive / ODD / "000001.png").write_bytes(b"")   # an item (a folder of images): fails
    code, out, err = run_cli("batch", archive, "--out", tmp_path / "runs")
    assert code == 2 and "not UTF-8" in err and "no sequences" not in err, (out, err)


def test_copies_of_one_source_at_two_paths_get_two_run_folders(tmp_path):
    """Two copies of one video (same content, other paths) fell back to the same NAME-<fingerprint>
    folder, the second run replacing the first without a word."""
    import json

    root = tmp_path / "runs"
    (root / "cam").mkdir(parents=True)
    first = tmp_path / "a" / "cam"
    (root / "cam" / "run.json").write_text(json.dumps({"source": str(first.resolve()), "fingerprint": "f" * 16}))
    outs = set()
    for copy in ("b", "c"):
        src = tmp_path / copy / "cam"
        src.mkdir(parents=True)
        out = default_run_dir(SimpleNamespace(name="cam", path=src), "f" * 16, root=root)
        assert out.parent == root and out.name.startswith("cam-")
        assert default_run_dir(SimpleNamespace(name="cam", path=src), "f" * 16, root=root) == out   # the same again
        outs.add(out)
    assert len(outs) == 2
