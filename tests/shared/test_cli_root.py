from artmotion import __version__


def test_version(run_cli):
    code, out, _ = run_cli("--version")
    assert code == 0 and __version__ in out


def test_unknown_command_is_usage_error(run_cli):
    code, _, _ = run_cli("no-such-command")
    assert code == 2
