import os
from pathlib import Path

import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.io import atomic_write, read_events, read_mot, write_events, write_mot


def write(tmp_path, text, name="det.txt"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_read_mot_pads_and_roundtrips(tmp_path):
    p = write(tmp_path, "1,-1,10,20,30,40,0.9\n2,-1,11,21,30,40,0.8,-1,-1,-1\n\n")
    rows = read_mot(p)
    assert rows.shape == (2, 10)
    assert rows[0, 6] == pytest.approx(0.9) and rows[0, 7] == -1
    out = tmp_path / "res.txt"
    write_mot(out, rows[::-1])
    again = read_mot(out)
    np.testing.assert_allclose(again[:, :7], rows[:, :7], atol=1e-2)


@pytest.mark.parametrize(
    "text,needle,line",
    [
        ("1,-1,10,20,30,40,0.9\n2,-1,abc,20,30,40,0.9\n", "non-numeric", 2),
        ("1,-1,10,20,nan,40,0.9\n", "NaN", 1),
        ("1,-1,10,20,0,40,0.9\n", "non-positive box size", 1),
        ("1,-1,10,20\n", "expected 6 to 10 values", 1),
        ("0,-1,10,20,5,5,1\n", "positive integer", 1),
        ("1,-1,10,20,5,5,1\n2,,10,20,5,5,1\n", "empty field 2", 2),  # would shift every column
        ("1,-1,1_0,20,5,5,1\n", "non-numeric", 1),  # not ten, as Python's float() would have it
        ("1,1,1000001,10,5,5\n", "box 1000001,10,5,5 out of range", 1),  # not 1e+06, the bound itself
    ],
)
def test_read_mot_errors_name_file_and_line(tmp_path, text, needle, line):
    p = write(tmp_path, text)
    with pytest.raises(InputError) as exc:
        read_mot(p)
    msg = str(exc.value)
    assert needle in msg and f"det.txt:{line}:" in msg and "\n" not in msg


def test_read_mot_trailing_comma_and_spaces(tmp_path):
    p = write(tmp_path, "1,-1,10,20,5,5,0.5,\n2, -1, 10, 20, 5, 5\n3 -1 10 20 5 5\n4, -1 10 20 5 5\n")
    np.testing.assert_allclose(read_mot(p)[:, :7], [[1, -1, 10, 20, 5, 5, 0.5], [2, -1, 10, 20, 5, 5, 1],
                                                    [3, -1, 10, 20, 5, 5, 1], [4, -1, 10, 20, 5, 5, 1]])


def test_read_mot_order_and_empty(tmp_path):
    p = write(tmp_path, "2,-1,10,20,5,5,1\n1,-1,10,20,5,5,1\n")
    assert read_mot(p).shape == (2, 10)
    with pytest.raises(InputError, match="out of order"):
        read_mot(p, require_sorted=True)
    empty = write(tmp_path, "", "empty.txt")
    assert read_mot(empty).shape == (0, 10)
    with pytest.raises(InputError, match="empty"):
        read_mot(empty, allow_empty=False)
    with pytest.raises(InputError, match="no such file"):
        read_mot(tmp_path / "missing.txt")


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_write(target) as fh:
            fh.write("half")
            raise RuntimeError("boom")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


class _Interrupt(BaseException):
    """What the command line's signal handler raises (``Interrupted``), as a test double."""


def test_interrupt_as_the_temporary_name_is_created_leaves_nothing(tmp_path, monkeypatch):
    """A signal handled just after the temporary file or folder was created, before the writer
    holds its name (CI caught a video's temporary file left this way), leaves nothing behind."""
    from artmotion.io.atomic import atomic_dir, atomic_path

    real_open, real_mkdir = os.open, os.mkdir

    def open_then_interrupt(name, *args, **kw):
        fd = real_open(name, *args, **kw)
        if ".tmp" in os.fspath(name):
            os.close(fd)
            raise _Interrupt
        return fd

    def mkdir_then_interrupt(name, *args, **kw):
        real_mkdir(name, *args, **kw)
        if ".tmp" in os.fspath(name):
            raise _Interrupt

    monkeypatch.setattr(os, "open", open_then_interrupt)
    with pytest.raises(_Interrupt):
        with atomic_path(tmp_path / "ann.mp4"):
            pass
    monkeypatch.setattr(os, "open", real_open)
    monkeypatch.setattr(os, "mkdir", mkdir_then_interrupt)
    with pytest.raises(_Interrupt):
        with atomic_dir(tmp_path / "report"):
            pass
    assert list(tmp_path.iterdir()) == []


def test_interrupted_swap_puts_the_earlier_outputs_back(tmp_path, monkeypatch):
    """A folder of the command's own earlier outputs is swapped for the new ones by two renames; an
    interruption between them puts the earlier outputs back instead of losing both."""
    from artmotion.io import atomic
    from artmotion.io.atomic import atomic_dir

    out = tmp_path / "run"
    out.mkdir()
    (out / "a.txt").write_text("earlier")
    real_replace, calls = os.replace, []

    def replace_once(src, dst):
        calls.append(src)
        real_replace(src, dst)
        if len(calls) == 1:         # the earlier outputs moved aside; the new ones not yet in
            raise _Interrupt

    monkeypatch.setattr(atomic.os, "replace", replace_once)
    with pytest.raises(_Interrupt):
        with atomic_dir(out, replace=lambda p: True) as tmp:
            (tmp / "a.txt").write_text("new")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    assert (out / "a.txt").read_text() == "earlier"


def test_events_roundtrip_and_validation(tmp_path):
    evs = [{"type": "enter", "frame": 3, "tracks": [1], "side": "left"},
           {"type": "merge", "frame": 9, "tracks": [1, 2], "group": 100}]
    p = tmp_path / "e.jsonl"
    write_events(p, evs)
    assert read_events(p) == evs
    bad = write(tmp_path, '{"type": "enter", "frame": 3}\n', "bad.jsonl")
    with pytest.raises(InputError, match="bad.jsonl:1:"):
        read_events(bad)
    bad2 = write(tmp_path, "not json\n", "bad2.jsonl")
    with pytest.raises(InputError, match="not JSON"):
        read_events(bad2)
    # (the code before read them, and describe said "Person 1 and person 1 merge")
    for line, needle in (('{"type": "merge", "frame": 3, "tracks": [1, 1]}', "names a track twice"),
                         ('{"type": "split", "frame": 3, "tracks": [1]}', "a split is of two tracks or more")):
        with pytest.raises(InputError, match=needle):
            read_events(write(tmp_path, line + "\n", "bad3.jsonl"))


def test_kl_matrix_is_kl_divergence_exactly():
    """The association's matrix of KL costs equals the pairwise ``kl_divergence`` to the last bit
    (equal costs must stay equal: a near-tie decides an assignment), capped, ``None`` at the cap."""
    from artmotion.tracking.appearance import kl_divergence, kl_matrix, rgb_histogram

    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
    hs = [rgb_histogram(img, [x, y, 30, 60]) for x, y in rng.integers(0, 100, (12, 2))] + [None]
    K = kl_matrix(hs, hs, cap=3.0)
    for a, p in enumerate(hs):
        for b, q in enumerate(hs):
            assert K[a, b] == min(kl_divergence(p, q), 3.0)
    assert np.all(np.diag(K)[:-1] == 0.0)
    where = rng.random(K.shape) < 0.3        # only the pairs a gate lets through: the same numbers there
    assert np.array_equal(kl_matrix(hs, hs, cap=3.0, where=where), np.where(where, K, 3.0))
    assert np.all(kl_matrix(hs, hs, cap=3.0, where=np.zeros(K.shape, bool)) == 3.0)
    with pytest.raises(ValueError, match="8-bit"):
        rgb_histogram(img.astype(float), [0, 0, 30, 60])


def test_image_size_from_the_header():
    """PNG and JPEG sizes from their headers, also behind a large EXIF segment; other data: None."""
    import cv2

    from artmotion.io.media import _image_structure

    def _header_size(buf):
        return _image_structure(buf)[1]

    img = np.zeros((30, 50, 3), np.uint8)
    assert _header_size(cv2.imencode(".png", img)[1]) == (50, 30)
    jpg = cv2.imencode(".jpg", img)[1].tobytes()
    exif = b"\xff\xe1" + (65533).to_bytes(2, "big") + b"\0" * 65531   # a 64 KB APP1 segment first
    assert _header_size(np.frombuffer(jpg[:2] + exif + jpg[2:], np.uint8)) == (50, 30)
    assert _header_size(np.frombuffer(b"GIF89a" + b"\0" * 20, np.uint8)) is None
    assert _header_size(np.frombuffer(b"\xff\xd8\xff", np.uint8)) is None


def test_tiffs_artmotion_cannot_take_are_named(tmp_path):
    """A TIFF of several pages decoded to its first page, said nothing; one of float samples was
    'corrupt or not an image'. A reduced-resolution page (a thumbnail) is no second page."""
    import cv2

    from artmotion.io.media import read_image

    img = np.full((30, 50, 3), 90, np.uint8)
    for name, ok in (("one.tif", cv2.imwrite(str(tmp_path / "one.tif"), img)),
                     ("u16.tif", cv2.imwrite(str(tmp_path / "u16.tif"), img.astype(np.uint16) * 257)),
                     ("two.tif", cv2.imwritemulti(str(tmp_path / "two.tif"), [img, img])),
                     ("float.tif", cv2.imwrite(str(tmp_path / "float.tif"), img.astype(np.float32) / 255))):
        assert ok, name
    assert read_image(tmp_path / "one.tif").shape == (30, 50, 3)
    assert read_image(tmp_path / "u16.tif").shape == (30, 50, 3)
    with pytest.raises(InputError, match="two.tif: a TIFF of 2 pages"):
        read_image(tmp_path / "two.tif")
    with pytest.raises(InputError, match="float.tif: a TIFF of floating-point samples"):
        read_image(tmp_path / "float.tif")
    data = bytearray((tmp_path / "two.tif").read_bytes())     # mark the second page a thumbnail
    second = int.from_bytes(data[4:8], "little")
    second = int.from_bytes(data[second + 2 + 12 * int.from_bytes(data[second:second + 2], "little"):][:4], "little")
    entries = int.from_bytes(data[second:second + 2], "little")
    tags = [second + 2 + 12 * k for k in range(entries)]
    e = next(e for e in tags if int.from_bytes(data[e:e + 2], "little") == 254)   # NewSubfileType
    assert int.from_bytes(data[e + 8:e + 12], "little") & 1 == 0     # OpenCV's: a page (2), full size
    data[e + 2:e + 12] = (4).to_bytes(2, "little") + (1).to_bytes(4, "little") + (1).to_bytes(4, "little")
    (tmp_path / "thumb.tif").write_bytes(bytes(data))
    assert read_image(tmp_path / "thumb.tif").shape == (30, 50, 3)


def test_check_writable(tmp_path):
    from artmotion.io import check_writable

    check_writable(None, tmp_path / "new" / "deeper" / "out.txt")  # folders to be made: fine
    assert not (tmp_path / "new").exists()  # nothing created
    (tmp_path / "f").write_text("x")
    with pytest.raises(InputError, match="a file is where a folder would be"):
        check_writable(tmp_path / "f" / "out.txt")
    with pytest.raises(InputError, match="is a folder"):
        check_writable(tmp_path)
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere")
    with pytest.raises(InputError, match="a file is where a folder would be"):
        check_writable(tmp_path / "dangling" / "out.txt")
    check_writable(tmp_path / "f")  # an existing file is overwritten: fine


def test_check_writable_refuses_devices_pipes_and_inputs(tmp_path):
    """A device or pipe as an output would be replaced by the rename (as root, even /dev/null); an
    output that is an input (or another output) would destroy it."""
    from artmotion.io import atomic_write, check_writable

    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for path in (fifo, Path(os.devnull)):
        with pytest.raises(InputError, match="not a regular file"):
            check_writable(path)
        with pytest.raises(InputError, match="not a regular file"), atomic_write(path) as fh:
            fh.write("x")
    assert fifo.is_fifo() and Path(os.devnull).is_char_device()
    src = tmp_path / "det.txt"
    src.write_text("1,-1,0,0,1,1,1,-1,-1,-1\n")
    with pytest.raises(InputError, match="is also an input"):
        check_writable(tmp_path / "out.txt", tmp_path / "sub" / ".." / "det.txt", inputs=(None, src))
    (tmp_path / "link.txt").symlink_to(src)
    with pytest.raises(InputError, match="is also an input"):
        check_writable(tmp_path / "link.txt", inputs=(src,))
    with pytest.raises(InputError, match="two outputs"):
        check_writable(tmp_path / "a.txt", tmp_path / "./a.txt")
    assert src.read_text().startswith("1,")


def test_an_output_inside_an_input_folder_is_refused(tmp_path):
    """An output in a folder of input frames would replace a frame or become one more frame; next
    to the folder it is fine."""
    from artmotion.io import check_apart, check_writable

    frames = tmp_path / "frames"
    (frames / "sub").mkdir(parents=True)
    (frames / "000001.png").write_bytes(b"png")
    for out in (frames / "000001.png", frames / "new.png", frames / "sub" / "x.csv", frames, frames / "sub" / ".."):
        with pytest.raises(InputError, match="inside the input folder"):
            check_writable(out, inputs=(None, frames))
        with pytest.raises(InputError, match="inside the input folder"):
            check_apart(out, (frames,))
    (tmp_path / "link").symlink_to(frames)
    with pytest.raises(InputError, match="inside the input folder"):
        check_apart(tmp_path / "link" / "a.png", (frames,))
    check_writable(tmp_path / "frames.csv", tmp_path / "framesx" / "a.png", inputs=(frames,))
    check_apart(tmp_path / "out", (frames, tmp_path / "frames.csv"))  # a file input is no folder
    assert (frames / "000001.png").read_bytes() == b"png"


def test_more_boxes_in_one_frame_than_artmotion_reads(tmp_path):
    """A frame of tens of thousands of boxes (a detector's output before non-maximum suppression)
    is refused when read: tracking it took hours and scoring it ran out of memory."""
    from artmotion.io.mot import MAX_BOXES_PER_FRAME
    from artmotion.tracking.metrics import evaluate

    rows = "".join(f"1,-1,{k % 500},{k // 500},20,40,0.9\n" for k in range(MAX_BOXES_PER_FRAME + 1))
    path = write(tmp_path, rows + "2,-1,0,0,20,40,0.9\n", "det.txt")
    with pytest.raises(InputError, match=f"det.txt:{MAX_BOXES_PER_FRAME + 1}: more than {MAX_BOXES_PER_FRAME} "
                                         "boxes in frame 1"):
        read_mot(path)
    assert len(read_mot(write(tmp_path, rows.split("\n", 1)[1], "ok.txt"))) == MAX_BOXES_PER_FRAME
    arr = np.zeros((MAX_BOXES_PER_FRAME + 1, 7))
    arr[:, 0], arr[:, 4:7] = 3, 1
    with pytest.raises(InputError, match=f"{MAX_BOXES_PER_FRAME + 1} boxes in frame 3"):
        evaluate(arr, arr[:5])
    from artmotion.tracking.instruments.annotations import read_tools_csv
    from artmotion.tracking.instruments.evaluate import evaluate_tools

    with pytest.raises(InputError, match=f"{MAX_BOXES_PER_FRAME + 1} rows"):
        evaluate_tools({1: np.ones((MAX_BOXES_PER_FRAME + 1, 4))}, {1: np.ones((1, 6))})
    csv = "frame,tool,y,x,scale,angle\n" + "".join(f"0,{k},5,5,9,0\n" for k in range(MAX_BOXES_PER_FRAME + 1))
    with pytest.raises(InputError, match=f"more than {MAX_BOXES_PER_FRAME} rows in frame 0"):
        read_tools_csv(write(tmp_path, csv, "tools.csv"))


def test_output_folders_through_links_and_checked_before_the_work(tmp_path):
    """An output folder named by a link to a folder is written where the link points (the rename
    onto the link failed after the whole run: "Not a directory"); a link to nothing, a folder of the
    user's that holds an output's name, and a folder of files are refused before any work."""
    from artmotion.io.atomic import atomic_dir, check_out_dir

    target = tmp_path / "target"
    target.mkdir()
    link = tmp_path / "link"
    link.symlink_to(target)
    check_out_dir(link, outputs=("a.txt",))
    with atomic_dir(link, outputs=("a.txt",)) as tmp:
        (tmp / "a.txt").write_text("new")
    assert (target / "a.txt").read_text() == "new" and link.is_symlink()
    dangling = tmp_path / "dangling"
    dangling.symlink_to(tmp_path / "nowhere")
    with pytest.raises(InputError, match="is a link to no folder"):
        check_out_dir(dangling)
    with pytest.raises(InputError, match="a.txt: exists, in a folder that is not only this command.s earlier outputs"):
        check_out_dir(target, outputs=("b.txt", "a.txt"))
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match="exists and is not a folder"):
        check_out_dir(tmp_path / "file")
    with pytest.raises(InputError, match="a file is where a folder would be"):
        check_out_dir(tmp_path / "file" / "sub" / "out")


def test_commands_refuse_an_output_folder_before_the_work(tmp_path, run_cli):
    """A folder of the user's that holds a file of an output's name was refused only after the
    evaluation (minutes of work): the names are known from the options and checked first (here the
    inputs do not even exist: the output folder is what is named)."""
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "cv_hog.csv").write_text("the user's own\n")
    (mine / "retrieval.png").write_bytes(b"the user's own")
    for args, name in ((("pose", "eval", tmp_path / "none", tmp_path / "none.csv", "--feature", "hog", "--out", mine),
                        "cv_hog.csv"),
                       (("grounding", "eval", tmp_path / "none", "--out", mine), "retrieval.png")):
        code, _, err = run_cli(*args)
        assert code == 2 and f"{mine / name}: exists, in a folder that is not only this command's earlier outputs" in err, err
    assert sorted(p.name for p in mine.iterdir()) == ["cv_hog.csv", "retrieval.png"]


def test_an_inputs_error_inside_an_output_block_names_the_input(tmp_path):
    """``track`` writes its outputs under temporary names around the whole work: an error reading
    an input was reported as "cannot write" on an output, and the output's new folders were left."""
    from artmotion.io.atomic import atomic_dir, atomic_path

    for block in (lambda: atomic_path(tmp_path / "new" / "deep" / "o.txt"), lambda: atomic_dir(tmp_path / "new" / "run")):
        with pytest.raises(PermissionError) as info:
            with block():
                raise PermissionError(13, "Permission denied", "/data/seq/img1/000005.jpg")
        assert info.value.filename == "/data/seq/img1/000005.jpg"
        assert list(tmp_path.iterdir()) == []
    with pytest.raises(InputError, match=r"o.txt: cannot write: No space left on device"):
        with atomic_path(tmp_path / "new" / "o.txt") as tmp:
            raise OSError(28, "No space left on device", str(tmp))
    assert list(tmp_path.iterdir()) == []


def test_an_output_folder_made_at_the_same_moment_by_another_process_is_used_and_kept(tmp_path, monkeypatch):
    """Two of a batch's workers writing into one new --out: both see it missing, one makes it, and
    the other's mkdir failed ('cannot create output folder: File exists'), failing its item."""
    import artmotion.io.atomic as atomic

    out = tmp_path / "runs"
    real = os.path.lexists
    seen = []

    def racing(p):          # "missing" when looked at; made by the other worker before our mkdir
        if Path(p) == out and not seen:
            seen.append(p)
            out.mkdir()
            return False
        return real(p)

    monkeypatch.setattr(atomic.os.path, "lexists", racing)
    with pytest.raises(RuntimeError):
        with atomic_write(out / "a.txt") as fh:
            fh.write("x")
            raise RuntimeError("the work fails")
    assert seen and out.is_dir()            # the other worker's folder is not removed
    with atomic_write(out / "b.txt") as fh:
        fh.write("y")
    assert (out / "b.txt").read_text() == "y"


def test_an_empty_output_folder_is_filled_in_place(tmp_path, monkeypatch):
    """An empty folder given as the output (a mount point, a shared folder with its own group and
    mode) was replaced by a renamed one: a mount point failed with "Device or resource busy" after
    the work, and a shared folder lost its group and setgid bit. It is filled in place; a folder of
    the command's earlier outputs keeps its mode when swapped, and on a mount point it is swapped in
    place (the earlier outputs moved aside, then dropped)."""
    from artmotion.io import atomic
    from artmotion.io.atomic import atomic_dir

    out = tmp_path / "shared"
    out.mkdir()
    os.chmod(out, 0o2770)
    inode = os.stat(out).st_ino
    with atomic_dir(out, replace=lambda p: True) as tmp:
        (tmp / "a.txt").write_text("first")
    assert os.stat(out).st_ino == inode and os.stat(out).st_mode & 0o7777 == 0o2770
    assert sorted(p.name for p in out.iterdir()) == ["a.txt"]
    with atomic_dir(out, replace=lambda p: True) as tmp:     # the earlier outputs, swapped
        (tmp / "b.txt").write_text("second")
    assert os.stat(out).st_mode & 0o7777 == 0o2770 and sorted(p.name for p in out.iterdir()) == ["b.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shared"]

    monkeypatch.setattr(atomic.os.path, "ismount", lambda p: os.fspath(p) == os.fspath(out))
    inode = os.stat(out).st_ino
    with atomic_dir(out, replace=lambda p: True) as tmp:     # a mount point: swapped in place
        (tmp / "c.txt").write_text("third")
    assert os.stat(out).st_ino == inode and sorted(p.name for p in out.iterdir()) == ["c.txt"]
    with pytest.raises(_Interrupt):                          # interrupted: the earlier outputs stay
        with atomic_dir(out, replace=lambda p: True) as tmp:
            (tmp / "d.txt").write_text("fourth")
            raise _Interrupt
    assert sorted(p.name for p in out.iterdir()) == ["c.txt"] and (out / "c.txt").read_text() == "third"


def test_an_interrupted_move_into_a_folder_takes_the_new_outputs_out(tmp_path, monkeypatch):
    """Outputs moved one by one into an existing folder: an interruption half-way leaves the folder
    as it was, not with some of the new outputs."""
    from artmotion.io import atomic
    from artmotion.io.atomic import atomic_dir

    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    real_move, calls = atomic._move_new, []

    def move_then_interrupt(src, dst):
        real_move(src, dst)
        calls.append(dst)
        if len(calls) == 2:
            raise _Interrupt

    monkeypatch.setattr(atomic, "_move_new", move_then_interrupt)
    with pytest.raises(_Interrupt):
        with atomic_dir(out, outputs=("a.txt", "b.txt", "c.txt")) as tmp:
            for name in ("a.txt", "b.txt", "c.txt"):
                (tmp / name).write_text("new")
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_a_long_output_name_gets_a_temporary_name_that_fits(tmp_path):
    """A 246-character name: its temporary name (a dot, the name, 8 characters, .tmp) was over the
    file systems' 255 bytes, and the command failed naming the temporary file."""
    from artmotion.io.atomic import atomic_dir, atomic_write

    name = "v" * 246
    with atomic_dir(tmp_path / name) as tmp:
        (tmp / "a.txt").write_text("x")
    with atomic_write(tmp_path / (name[:-4] + "é.txt")) as fh:
        fh.write("x")
    assert sorted(len(os.fsencode(p.name)) for p in tmp_path.iterdir()) == [246, 248]


def test_a_refused_output_folder_says_what_else_it_holds(tmp_path):
    """A folder of earlier outputs plus a file of the user's is not replaced; the message said the
    outputs had not been written by this command (they had): it now names what else is there."""
    from artmotion.io.atomic import check_out_dir

    out = tmp_path / "run"
    out.mkdir()
    (out / "run.json").write_text("{}")
    (out / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match=r"run.json: exists, in a folder that is not only this command's "
                                         r"earlier outputs \(it also holds notes.txt\)"):
        check_out_dir(out, replace=lambda p: False, outputs=("results.txt", "run.json"))


def test_a_file_of_the_users_inside_an_earlier_outputs_subfolder_keeps_the_folder(tmp_path, run_cli):
    """pose render checked only the names at the top of an earlier rendering: a file the user had
    put in its crops/ (or a folder in it) was deleted without a word when it was rendered again.
    Now the folder is refused, as for a file of the user's beside the outputs; the earlier
    rendering alone is still replaced."""
    from artmotion.io.atomic import outputs_of

    out = tmp_path / "r"
    assert run_cli("pose", "render", out, "--poses", 3, "--no-frames")[0] == 0
    code, _, err = run_cli("pose", "render", out, "--poses", 2, "--no-frames")     # its own: replaced
    assert code == 0 and len(list((out / "crops").iterdir())) == 2, err
    for mine in (out / "crops" / "precious.txt", out / "crops" / "sub" / "mine.txt"):
        mine.parent.mkdir(exist_ok=True)
        mine.write_text("the user's own")
        code, _, err = run_cli("pose", "render", out, "--poses", 2, "--no-frames")
        assert code == 2 and "exists, in a folder that is not only this command's earlier outputs" in err, err
        assert mine.read_text() == "the user's own"
        mine.unlink()
        if mine.parent.name == "sub":
            mine.parent.rmdir()
    # the test itself: a folder where the command writes a file, or a file where it writes a folder
    test = outputs_of("m.json", {"a.csv", "crops"}, inside={"crops": r"\d+\.png"})
    (tmp_path / "t").mkdir()
    (tmp_path / "t" / "m.json").write_text("{}")
    (tmp_path / "t" / "crops").mkdir()
    (tmp_path / "t" / "crops" / "000001.png").write_bytes(b"")
    assert test(tmp_path / "t")
    (tmp_path / "t" / "a.csv").mkdir()
    assert not test(tmp_path / "t")
    (tmp_path / "t" / "a.csv").rmdir()
    (tmp_path / "t" / "crops" / "000001.png").unlink()
    (tmp_path / "t" / "crops").rmdir()
    (tmp_path / "t" / "crops").write_text("")
    assert not test(tmp_path / "t")


def test_an_output_named_by_a_link_into_no_folder_is_refused_before_anything_is_made(tmp_path):
    """A file output named by a link to a file whose folder did not exist made that folder (and
    its parents) wherever the link pointed; a link to a new file in a folder that exists is still
    written through."""
    from artmotion.io.atomic import check_writable

    link = tmp_path / "dangling.csv"
    link.symlink_to(tmp_path / "nowhere" / "deeper" / "x.csv")
    with pytest.raises(InputError, match="dangling.csv: is a link to .*x.csv, in a folder that does not exist"):
        check_writable(link)
    with pytest.raises(InputError, match="in a folder that does not exist"):
        with atomic_write(link) as fh:
            fh.write("x\n")
    assert not (tmp_path / "nowhere").exists()
    fresh = tmp_path / "fresh.csv"
    fresh.symlink_to(tmp_path / "new.csv")
    with atomic_write(fresh) as fh:
        fh.write("x\n")
    assert fresh.is_symlink() and (tmp_path / "new.csv").read_text() == "x\n"


def test_an_output_named_by_a_link_is_written_through_it(tmp_path):
    """The atomic rename put a plain file in place of a link named as the output: a link to a
    file lost its target's update, and ``--out /dev/stdout`` with stdout redirected replaced the
    system's /dev/stdout. The target is written and the link kept; a link into /dev or /proc is
    refused before anything is written."""
    from artmotion.io.atomic import check_writable

    target = tmp_path / "target.csv"
    target.write_text("old\n")
    link = tmp_path / "latest.csv"
    link.symlink_to(target)
    check_writable(link)
    with atomic_write(link) as fh:
        fh.write("new\n")
    assert link.is_symlink() and target.read_text() == "new\n"
    stream = tmp_path / "out.csv"
    stream.symlink_to("/proc/self/fd/1")
    for call in (lambda: check_writable(stream), lambda: atomic_write(stream).__enter__()):
        with pytest.raises(InputError, match="a link to a stream of the process"):
            call()
    assert stream.is_symlink() and sorted(p.name for p in tmp_path.iterdir()) == ["latest.csv", "out.csv", "target.csv"]
    loop, back = tmp_path / "loop1", tmp_path / "loop2"      # a loop of links: refused, the links kept
    loop.symlink_to(back)
    back.symlink_to(loop)
    for call in (lambda: check_writable(loop), lambda: atomic_write(loop).__enter__()):
        with pytest.raises(InputError, match="a link that loops"):
            call()
    assert loop.is_symlink() and back.is_symlink()


def test_a_file_output_ending_with_a_slash_is_refused(tmp_path):
    """``--model newdir/`` wrote a file called ``newdir``: a name ending with a slash means a folder."""
    from artmotion.io.atomic import check_writable

    for call in (lambda: check_writable(f"{tmp_path}/newdir/"), lambda: atomic_write(f"{tmp_path}/newdir/").__enter__()):
        with pytest.raises(InputError, match="ends with a slash"):
            call()
    assert list(tmp_path.iterdir()) == []


def test_a_frame_folder_leaves_hidden_files_out_and_names_two_frames_of_one_number(tmp_path):
    """macOS puts a ``._NAME`` file beside every copied image: it was read as a frame (or made two
    frames of one number, without naming them)."""
    import cv2

    from artmotion.io.sequence import open_sequence

    img = np.full((24, 32, 3), 90, np.uint8)
    for k in (1, 2, 3):
        cv2.imwrite(str(tmp_path / f"{k:06d}.png"), img)
    (tmp_path / "._000001.png").write_bytes(b"\x00\x05\x16\x07 not an image")
    (tmp_path / ".000004.png").write_bytes(b"hidden")
    assert open_sequence(tmp_path).length == 3
    cv2.imwrite(str(tmp_path / "frame2.png"), img)
    with pytest.raises(InputError, match=r"two images have frame number 2: 000002.png and frame2.png"):
        open_sequence(tmp_path)


def test_a_name_another_writer_made_meanwhile_is_not_replaced(tmp_path, monkeypatch):
    """Two writers into one folder: the names were checked free and then renamed in, so a name the
    other writer made between the two was replaced without a word. A file is linked in (which never
    replaces a name) and a folder claims its name first; the other writer's outputs stay."""
    from artmotion.io import atomic
    from artmotion.io.atomic import atomic_dir

    out = tmp_path / "out"
    out.mkdir()
    real_check = atomic._check_free

    def check_then_other_writer(folder, names):
        real_check(folder, names)
        if folder == out and not (out / "a.txt").exists():
            (out / "a.txt").write_text("the other writer's")
            (out / "sub").mkdir()

    monkeypatch.setattr(atomic, "_check_free", check_then_other_writer)
    for name in ("a.txt", "sub"):
        with pytest.raises(InputError, match=f"{name}: exists, in a folder that is not only"):
            with atomic_dir(out, outputs=(name,)) as tmp:
                (tmp / "a.txt").write_text("mine") if name == "a.txt" else (tmp / "sub").mkdir()
        monkeypatch.setattr(atomic, "_check_free", real_check)
    assert (out / "a.txt").read_text() == "the other writer's" and sorted(p.name for p in out.iterdir()) == ["a.txt", "sub"]


def test_a_long_extension_and_a_long_run_name_get_temporary_names(tmp_path):
    """A name whose 'extension' is 246 bytes looped for ever cutting the temporary name's prefix;
    the temporary folders of a long-named run were not found as stale (their names are cut)."""
    from artmotion.io.atomic import _fresh, stale_dirs

    with atomic_write(tmp_path / ("a." + "b" * 245)) as fh:
        fh.write("x")
    assert (tmp_path / ("a." + "b" * 245)).read_text() == "x"
    run = tmp_path / ("v" * 246)
    left = _fresh(tmp_path, f".{run.name}.", ".tmp", True, [])
    assert stale_dirs(run) == [left]


def test_a_file_output_given_with_a_slash_on_the_command_line_is_refused(tmp_path, run_cli):
    """A command's Path option drops the slash of ``--model newdir/`` before the output is written:
    a file called ``newdir`` was written."""
    from artmotion.io import atomic

    try:
        code, _, err = run_cli("slam", "simulate", "--runs", 1, "--steps", 5, "--plot", f"{tmp_path}/p.png/")
    finally:
        atomic.SLASHED.clear()
    assert code == 2 and "p.png: ends with a slash" in err, err
    assert list(tmp_path.iterdir()) == []


def test_a_folder_output_given_with_a_slash_is_written(tmp_path, run_cli):
    """``--out result/`` (a folder, as tab completion types it) was refused as a file name ending
    with a slash after the command's work: ``run``, ``articulation video``, ``pose render``."""
    from artmotion.io import atomic
    from artmotion.io.atomic import atomic_dir

    with atomic_dir(f"{tmp_path}/made/") as tmp:
        (tmp / "a.txt").write_text("x")
    assert (tmp_path / "made" / "a.txt").read_text() == "x"
    try:
        code, _, err = run_cli("pose", "render", f"{tmp_path}/crops/", "--poses", 3, "--no-frames")
    finally:
        atomic.SLASHED.clear()
    assert code == 0 and (tmp_path / "crops" / "labels.csv").is_file(), err


def test_write_mot_refuses_ground_truths_columns_it_would_drop(tmp_path):
    """Columns 8-10 were written -1 whatever they held: MOT16/17 ground truth lost its class and
    visibility in a round trip, and its scores changed. Results (-1 there) are written as before."""
    from artmotion.io import write_mot

    gt = np.array([[1, 1, 10, 10, 20, 40, 1, 7, 0.5, -1.0]])     # a distractor, half visible
    with pytest.raises(InputError, match="columns 8-10 hold values other than -1"):
        write_mot(tmp_path / "gt.txt", gt)
    assert not (tmp_path / "gt.txt").exists()
    write_mot(tmp_path / "res.txt", np.array([[1, 1, 10, 10, 20, 40, 0.9, -1, -1, -1]]))
    assert (tmp_path / "res.txt").read_text() == "1,1,10.00,10.00,20.00,40.00,0.9,-1,-1,-1\n"


def test_a_file_name_that_is_no_name_is_an_input_error(tmp_path):
    """None or a number where a file name goes raised a TypeError from deep inside (and a name
    given as bytes broke the error message naming it)."""
    from artmotion.app import EventIndex, load_run, run_pipeline
    from artmotion.articulation.trajectory import read_trajectory
    from artmotion.io import atomic_write, check_text, check_writable, read_mot, write_mot
    from artmotion.io.sequence import open_sequence
    from artmotion.pose import PoseRegressor
    from artmotion.tracking import track

    calls = [lambda v: track(v), lambda v: run_pipeline(v, tmp_path / "o"), lambda v: load_run(v),
             lambda v: EventIndex(v), lambda v: read_mot(v), lambda v: write_mot(v, np.zeros((0, 10))),
             lambda v: read_trajectory(v), lambda v: PoseRegressor.load(v), lambda v: atomic_write(v).__enter__(),
             lambda v: open_sequence(v), lambda v: check_writable(v or 5)]       # (check_writable skips None)
    for call in calls:
        for value in (None, 5):
            with pytest.raises(InputError, match="must be a file name"):
                call(value)
    with pytest.raises(InputError, match="not UTF-8") as err:
        check_text(b"/tmp/caf\xe9")
    assert err.value.path == os.fsdecode(b"/tmp/caf\xe9")
    assert list(tmp_path.iterdir()) == []


def test_an_event_repeated_on_two_lines_is_an_error(tmp_path):
    """A repeated line of an events file was told twice by describe (a repeated results row is refused)."""
    p = tmp_path / "ev.jsonl"
    write_events(p, [{"type": "enter", "frame": 1, "tracks": [1]}, {"type": "exit", "frame": 9, "tracks": [1]}])
    again = '{"tracks": [1], "frame": 1, "type": "enter"}'      # the first event, its keys in another order
    p.write_text(p.read_text() + again + "\n")
    with pytest.raises(InputError, match=r"ev.jsonl:3: the same event as line 1"):
        read_events(p)


def test_a_signal_while_the_swapped_out_outputs_are_removed_does_not_leave_them(tmp_path, monkeypatch):
    """An interrupt while the earlier outputs, swapped out for the new ones, were being removed cut
    the removal: they stayed for good as a hidden .NAME.xxxxxxxx.old.tmp folder, half deleted
    (index add then refused the folder of runs). The removal now finishes first."""
    import shutil
    import signal

    from artmotion.io import atomic

    out = tmp_path / "out"
    out.mkdir()
    for k in range(5):
        (out / f"old{k}.txt").write_text("old")
    real = shutil.rmtree

    def interrupted_rmtree(path, *args, **kwargs):
        signal.raise_signal(signal.SIGINT)        # as Ctrl-C, at the first removal
        real(path, *args, **kwargs)

    monkeypatch.setattr(atomic.shutil, "rmtree", interrupted_rmtree)
    with pytest.raises(KeyboardInterrupt):
        with atomic.atomic_dir(out, replace=lambda p: True) as tmp:
            (tmp / "new.txt").write_text("new")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert sorted(p.name for p in out.iterdir()) == ["new.txt"]


def test_a_read_only_file_system_is_named_so(tmp_path, monkeypatch):
    """On a read-only mount access() fails too: the check said "permission denied" (to root)."""
    import os
    from types import SimpleNamespace

    from artmotion.io import atomic

    monkeypatch.setattr(atomic.os, "statvfs", lambda p: SimpleNamespace(f_flag=os.ST_RDONLY))
    monkeypatch.setattr(atomic.os, "access", lambda p, mode: False)
    with pytest.raises(InputError, match="cannot write: read-only file system"):
        atomic.check_can_create_in(tmp_path)
