"""Process whole archives on Dask distributed: one pipeline run per sequence or video.

Each item runs in isolation (its failure is caught and listed, it stops nothing else); finished
items (a ``run.json`` in their output folder) are skipped, so an interrupted batch resumes where
it stopped. A local cluster is started by default; give a scheduler address to use an existing one.
"""

from __future__ import annotations

import os
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from artmotion.errors import ArtmotionError, InputError, Interrupted
from artmotion.io.media import IMAGE_EXTS, VIDEO_EXTS


def find_items(root: str | os.PathLike) -> list[Path]:
    """Sequences in ``root``: MOTChallenge folders (``seqinfo.ini``), video files, image folders."""
    root = Path(root)
    if not root.is_dir():
        raise InputError("not a folder", path=root)
    items = []
    for p in sorted(root.iterdir()):
        if p.name.startswith("."):
            continue
        if p.is_dir() and ((p / "seqinfo.ini").is_file() or any(
                q.suffix.lower() in IMAGE_EXTS for q in p.iterdir() if q.is_file())):
            items.append(p)
        elif p.is_file() and p.suffix.lower() in VIDEO_EXTS:
            items.append(p)
    if not items:
        raise InputError("no sequences or videos found", path=root)
    return items


def item_name(item: Path) -> str:
    return item.stem if item.is_file() else item.name


def item_dirs(items: list[Path], out: Path) -> list[Path]:
    """Each item's run folder in ``out``: its name, or, where two items would share a name
    (``v.mp4`` and ``v.mov``, a folder ``v`` and ``v.avi``), the name with the file's extension."""
    names = [item_name(it) for it in items]
    shared = {n for n in names if names.count(n) > 1}
    dirs = []
    for it, n in zip(items, names):
        if n in shared:
            n = f"{n}-{it.suffix.lstrip('.').lower()}" if it.is_file() else f"{n}-folder"
        dirs.append(out / n)
    return dirs


def _check_scheduler(address: str) -> None:
    """A scheduler address Dask can parse (``tcp://HOST:PORT``), before any work starts."""
    from distributed.comm import parse_address, parse_host_port

    try:
        _, loc = parse_address(address)
        parse_host_port(loc)
    except (ValueError, TypeError) as exc:
        raise InputError(f"not a Dask scheduler address ({exc}); give tcp://HOST:PORT", path=address) from None


def _start_local_cluster(workers: int, processes: bool):
    """A local Dask cluster whose worker processes ignore the terminal's Ctrl-C (SIGINT is
    blocked while they start, and they inherit the mask): only this process reacts to it, stops
    the batch and closes them."""
    import signal

    from dask.distributed import LocalCluster

    blocked = processes and hasattr(signal, "pthread_sigmask")
    if blocked:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        return LocalCluster(n_workers=max(1, workers), threads_per_worker=1, processes=processes,
                            dashboard_address=None, silence_logs=40)
    finally:
        if blocked:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


class BatchInterrupted(Interrupted):
    """The batch was interrupted; ``report`` holds what finished (kept) and what did not run."""

    def __init__(self, signum: int, report: "BatchReport", not_run: list[str]):
        super().__init__(signum)
        self.report = report
        self.not_run = not_run


@dataclass
class ItemOutcome:
    item: str
    status: str  # "done", "skipped" or "failed"
    out_dir: str
    seconds: float = 0.0
    message: str = ""
    tracks: int = 0
    sentences: int = 0


@dataclass
class BatchReport:
    outcomes: list[ItemOutcome] = field(default_factory=list)
    seconds: float = 0.0
    workers: int = 0

    def by_status(self, status: str) -> list[ItemOutcome]:
        return [o for o in self.outcomes if o.status == status]

    @property
    def failed(self) -> list[ItemOutcome]:
        return self.by_status("failed")


def run_item(item: str, out_dir: str, single_thread: bool = True) -> ItemOutcome:
    """Run the pipeline on one item; never raises (the failure is the outcome)."""
    from artmotion.app.pipeline import run_pipeline

    t0 = time.perf_counter()
    if single_thread:
        import cv2

        cv2.setNumThreads(1)
    try:
        res = run_pipeline(item, out_dir, progress=False)
        return ItemOutcome(item, "done", out_dir, time.perf_counter() - t0,
                           tracks=res.num_tracks, sentences=len(res.sentences))
    except ArtmotionError as exc:
        msg = str(exc)
    except OSError as exc:
        msg = f"{exc.filename + ': ' if exc.filename else ''}{exc.strerror or exc}"
    except Exception as exc:  # a bug in one item must not stop the archive
        tb = traceback.extract_tb(exc.__traceback__)
        where = f" at {Path(tb[-1].filename).name}:{tb[-1].lineno}" if tb else ""
        msg = f"internal error {type(exc).__name__}: {exc}{where}"
    return ItemOutcome(item, "failed", out_dir, time.perf_counter() - t0, message=msg)


def run_batch(
    root: str | os.PathLike,
    out: str | os.PathLike | None = None,
    workers: int = 1,
    scheduler: str | None = None,
    force: bool = False,
    processes: bool = True,
    on_progress: Callable[[ItemOutcome, int, int], None] | None = None,
) -> BatchReport:
    """Run :func:`artmotion.app.pipeline.run_pipeline` on every item of ``root`` on Dask.

    ``processes=False`` runs the local workers as threads of this process (cheaper to start; for
    tests and small archives).
    """
    from dask.distributed import Client, as_completed

    from artmotion.app.pipeline import is_finished

    if scheduler:
        _check_scheduler(scheduler)
    t0 = time.perf_counter()
    items = find_items(root)
    out = Path(out) if out is not None else Path(root) / "artmotion-runs"
    report = BatchReport()
    todo = []
    for it, od in zip(items, item_dirs(items, out)):
        if not force and is_finished(od):
            report.outcomes.append(ItemOutcome(str(it), "skipped", str(od), message="already finished"))
        else:
            todo.append((str(it), str(od)))
    total = len(items)
    for o in report.outcomes:
        if on_progress:
            on_progress(o, len(report.outcomes), total)
    if todo:
        cluster = None
        if scheduler:
            try:
                client = Client(scheduler, timeout="10s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise InputError(f"cannot reach Dask scheduler: {exc}", path=scheduler) from None
        else:
            cluster = _start_local_cluster(workers, processes)
            client = Client(cluster)
        try:
            report.workers = len(client.scheduler_info().get("workers", {}))
            futures = {client.submit(run_item, it, od, pure=False, key=f"artmotion-{i}-{item_name(Path(it))}"): (it, od)
                       for i, (it, od) in enumerate(todo)}
            try:
                for fut in as_completed(futures):
                    it, od = futures[fut]
                    try:
                        outcome = fut.result()
                    except Exception as exc:  # the worker itself died (killed, out of memory)
                        outcome = ItemOutcome(it, "failed", od, message=f"worker lost: {type(exc).__name__}: {exc}")
                    report.outcomes.append(outcome)
                    if on_progress:
                        on_progress(outcome, len(report.outcomes), total)
            except Interrupted as exc:
                import logging

                logging.getLogger("distributed").setLevel(logging.CRITICAL)   # no shutdown noise
                finished = {o.item for o in report.outcomes}
                not_run = [it for it, _ in todo if it not in finished]
                client.cancel(list(futures))
                report.seconds = time.perf_counter() - t0
                raise BatchInterrupted(exc.signum, report, not_run) from None
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    report.outcomes.sort(key=lambda o: o.item)
    report.seconds = time.perf_counter() - t0
    return report
