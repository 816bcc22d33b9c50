import os
from pathlib import Path

import pytest
from hypothesis import settings

# tests never assert on time: hypothesis's 200 ms deadline per example failed on a first call that
# imported SciPy's rotations on a loaded machine
settings.register_profile("artmotion", deadline=None)
settings.load_profile("artmotion")

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
SAMPLE = ROOT / "data" / "TUD-Campus"

os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture
def sample_seq() -> Path:
    """The TUD-Campus sample shipped in the repository (video, det, gt)."""
    return SAMPLE


def shared_path(*parts: str) -> Path:
    """A path under ../shared/data; the test is skipped when it is absent."""
    p = SHARED.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"shared data not available: {p}")
    return p


@pytest.fixture
def run_cli(capsys):
    """Run ``artmotion ARGS`` in-process; return (exit code, stdout, stderr)."""
    from artmotion.cli import main

    def _run(*args):
        code = main([str(a) for a in args])
        out, err = capsys.readouterr()
        return code, out, err

    return _run
