"""`batch --scheduler` against a real Dask cluster on this machine (issue 13): a `dask scheduler`
and two `dask worker` processes; one worker is killed while it runs an item. Every item still ends
done or failed, none is lost and none is written twice. A scheduler that does not answer is one
line within seconds."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DASK = Path(sys.executable).with_name("dask")
ITEMS = 8


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _sequence(dst: Path, n: int = 120) -> None:
    sys.path.insert(0, str(ROOT / "tests" / "shared"))
    try:
        import _inputs
    finally:
        sys.path.pop(0)
    _inputs.sequence(dst, n=n)


@pytest.fixture
def cluster(tmp_path):
    """A scheduler and two single-threaded workers without nannies (a killed worker stays dead)."""
    if not DASK.exists():
        pytest.skip("the dask command is not installed")
    port = _free_port()
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    logs = tmp_path / "logs"
    logs.mkdir()
    files = {name: open(logs / f"{name}.log", "w") for name in ("scheduler", "a", "b")}  # noqa: SIM115
    procs = {"scheduler": subprocess.Popen(
        [str(DASK), "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
        stdout=subprocess.DEVNULL, stderr=files["scheduler"], env=env, start_new_session=True)}
    address = f"tcp://127.0.0.1:{port}"
    for name in ("a", "b"):
        procs[name] = subprocess.Popen(
            [str(DASK), "worker", address, "--name", name, "--nthreads", "1", "--no-nanny", "--no-dashboard",
             "--local-directory", str(tmp_path / f"worker-{name}")],
            stdout=subprocess.DEVNULL, stderr=files[name], env=env, start_new_session=True)
    from dask.distributed import Client

    client = Client(address, timeout="30s")
    try:
        client.wait_for_workers(2, timeout=60)
        yield address, client, procs
    finally:
        client.close()
        for p in procs.values():        # nothing of theirs is kept: no graceful shutdown needed
            if p.poll() is None:
                p.kill()
        for p in procs.values():
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
        for fh in files.values():
            fh.close()


@pytest.mark.slow
def test_batch_survives_a_killed_worker(tmp_path, cluster):
    address, client, procs = cluster
    archive = tmp_path / "archive"
    for i in range(ITEMS):
        _sequence(archive / f"s{i}")
    out = tmp_path / "runs"
    # every run.json ever seen, by item: a second write would show as a second inode
    seen: dict[str, set] = {}
    stop = threading.Event()

    def watch():
        while not stop.is_set():
            for manifest in out.glob("*/run.json"):
                if manifest.parent.name.startswith("."):
                    continue  # an attempt's temporary, renamed to the item's name when done
                try:
                    seen.setdefault(manifest.parent.name, set()).add(manifest.stat().st_ino)
                except FileNotFoundError:
                    pass
            time.sleep(0.01)

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    batch = subprocess.Popen([sys.executable, "-m", "artmotion", "batch", str(archive), "--out", str(out),
                              "--scheduler", address], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=dict(os.environ, PYTHONPATH=str(ROOT / "src")))
    # kill worker "a" while it runs an item, once some item has finished
    killed = False
    deadline = time.monotonic() + 60
    while not killed and batch.poll() is None and time.monotonic() < deadline:
        busy = {client.scheduler_info()["workers"][w]["name"]: keys for w, keys in client.processing().items()
                if w in client.scheduler_info()["workers"]}
        if busy.get("a") and list(out.glob("*/run.json")):
            procs["a"].send_signal(signal.SIGKILL)
            killed = True
        time.sleep(0.05)
    stdout, stderr = batch.communicate(timeout=120)
    stop.set()
    watcher.join()
    assert killed, f"worker a was never seen running an item\n{stdout}\n{stderr}"
    assert batch.returncode == 0, stderr
    done = [line.split()[1].rstrip(":") for line in stdout.splitlines() if line.startswith("done ")]
    assert sorted(done) == sorted(f"s{i}" for i in range(ITEMS)), stdout      # each item once, none lost
    assert f"{ITEMS} done, 0 skipped, 0 failed" in stdout
    assert sorted(p.name for p in out.iterdir()) == sorted(f"s{i}" for i in range(ITEMS))
    assert not [p for p in out.rglob("*") if ".tmp" in p.name], "a temporary of the killed attempt was left"
    assert all(len(inodes) == 1 for inodes in seen.values()), seen                 # none written twice
    assert set(seen) == {f"s{i}" for i in range(ITEMS)}
    for i in range(ITEMS):
        assert (out / f"s{i}" / "results.txt").is_file() and (out / f"s{i}" / "annotated.mp4").is_file()


def test_unreachable_scheduler_is_one_line_within_seconds(tmp_path):
    _sequence(tmp_path / "archive" / "s0", n=6)
    port = _free_port()            # nothing listens there
    t0 = time.monotonic()
    res = subprocess.run([sys.executable, "-m", "artmotion", "batch", str(tmp_path / "archive"), "--scheduler",
                          f"tcp://127.0.0.1:{port}"], capture_output=True, text=True, timeout=60,
                         env=dict(os.environ, PYTHONPATH=str(ROOT / "src")))
    assert time.monotonic() - t0 < 15
    assert res.returncode == 2 and res.stderr.count("\n") == 1, res.stderr
    assert res.stderr.startswith(f"artmotion: error: tcp://127.0.0.1:{port}: cannot reach a Dask scheduler")
    assert not (tmp_path / "archive" / "artmotion-runs").exists()
