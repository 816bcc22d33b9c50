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
