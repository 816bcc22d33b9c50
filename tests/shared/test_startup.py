"""`artmotion --help` and every command's --help stay light: they must not import the numeric
stack (the start-up time itself is measured by benchmarks/startup.py; tests never time)."""

from __future__ import annotations

import subprocess
import sys

import pytest

HEAVY = ("numpy", "cv2", "scipy", "sklearn", "dask", "matplotlib", "torch")
PROBE = """
import sys
from artmotion.cli import main
try:
    main({args!r})
except SystemExit:
    pass
print("imported:" + ",".join(m for m in {heavy!r} if m in sys.modules))
"""


@pytest.mark.parametrize("args", [["--help"], ["track", "--help"], ["run", "--help"], ["batch", "--help"],
                                  ["pose", "--help"], ["articulation", "--help"], ["describe", "--help"]])
def test_help_does_not_import_the_numeric_stack(args):
    out = subprocess.run([sys.executable, "-c", PROBE.format(args=args, heavy=HEAVY)], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "Usage" in out.stdout
    last = out.stdout.strip().splitlines()[-1]
    assert last == "imported:", f"artmotion {' '.join(args)} {last}"
