import pytest

from artmotion import __version__


def test_version(run_cli):
    code, out, _ = run_cli("--version")
    assert code == 0 and __version__ in out


def test_unknown_command_is_usage_error(run_cli):
    code, _, _ = run_cli("no-such-command")
    assert code == 2


def test_unknown_command_suggests_once(run_cli):
    code, _, err = run_cli("trak")
    assert code == 2 and err.count("Did you mean 'track'?") == 1


def test_a_command_runs_with_only_itself_built(run_cli):
    """Only the named command's click command is built (start-up); its help and a group's
    sub-command still work, and the root help lists everything."""
    code, out, _ = run_cli("track", "--help")
    assert code == 0 and "SOURCE" in out
    code, out, _ = run_cli("slam", "--help")
    assert code == 0 and "simulate" in out
    code, out, _ = run_cli("--help")
    assert code == 0 and all(name in out for name in ("track", "eval", "pose", "articulation", "slam", "run"))


def test_pruned_app_holds_only_the_named_command():
    from artmotion.cli import _app_for, app

    assert _app_for(["track", "x"]).registered_commands[0].name == "track"
    assert len(_app_for(["track"]).registered_commands) == 1 and not _app_for(["track"]).registered_groups
    assert [g.name for g in _app_for(["slam", "simulate"]).registered_groups] == ["slam"]
    assert _app_for(["--help"]) is app and _app_for(["nope"]) is app and _app_for([]) is app


@pytest.mark.parametrize("args, text", [
    (("run", "--help"), "runs/NAME"), (("batch", "--help"), "FOLDER/artmotion-runs"),
    (("search", "--help"), "ARTMOTION_INDEX"), (("articulation", "video", "--help"), "60-degree"),
])
def test_help_shows_the_defaults_it_describes(run_cli, args, text):
    """Rich read "[default: runs/NAME]" in a help text as markup and dropped it ("Run folder .")."""
    code, out, _ = run_cli(*args)
    assert code == 0 and text in out.replace("│", " ").replace("\n", " ").replace("  ", " "), out


def test_out_of_memory_is_one_line_not_a_bug(run_cli, monkeypatch, tmp_path):
    """A MemoryError (the largest frames, many workers) was "internal error ... (a bug: please report it)"."""
    import artmotion.tracking.metrics as metrics

    def too_big(*args, **kwargs):
        raise MemoryError("Unable to allocate 2.34 GiB")

    monkeypatch.setattr(metrics, "evaluate", too_big)
    gt = tmp_path / "gt.txt"
    gt.write_text("1,1,0,0,10,10,1,-1,-1,-1\n")
    code, _, err = run_cli("eval", gt, gt)
    assert code == 1 and err.startswith("artmotion: error: out of memory (Unable to allocate 2.34 GiB)"), err
    assert err.count("\n") == 1 and "bug" not in err


def test_an_image_that_does_not_decode_with_a_sound_header_may_be_memory(monkeypatch, tmp_path):
    """Under a memory limit OpenCV's decoder gives nothing for a valid 24-megapixel crop, which was
    called "corrupt or not an image"."""
    import cv2
    import numpy as np

    from artmotion.errors import InputError
    from artmotion.io import media

    p = tmp_path / "crop.png"
    cv2.imwrite(str(p), np.zeros((30, 40, 3), np.uint8))
    monkeypatch.setattr(cv2, "imdecode", lambda buf, flags: None)
    with pytest.raises(InputError, match=r"crop.png: cannot decode the image of 40x30 pixels \(corrupt data, or not "
                                         r"enough memory to decode it\)"):
        media.read_image(p)


def test_a_command_without_standard_output_still_succeeds(monkeypatch, tmp_path):
    """With no sys.stdout at all (pythonw, a daemon) the check of what printing failed called
    flush() on None: a command that succeeded said "internal error", exit 1."""
    import sys

    from artmotion.cli import main

    gt = tmp_path / "gt.txt"
    gt.write_text("1,1,0,0,10,10,1,-1,-1,-1\n")
    monkeypatch.setattr(sys, "stdout", None)
    assert main(["eval", str(gt), str(gt)]) == 0
