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

from artmotion.errors import ArtmotionError, InputError

VIDEO_SUFFIXES = {".mp4", ".avi", ".mov", ".mkv", ".mpg", ".mpeg", ".webm", ".m4v"}
IMAGE_SUFFIXES = {".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff"}


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
                q.suffix.lower() in IMAGE_SUFFIXES for q in p.iterdir() if q.is_file())):
            items.append(p)
        elif p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES:
            items.append(p)
    if not items:
        raise InputError("no sequences or videos found", path=root)
    return items


def item_name(item: Path) -> str:
    return item.stem if item.is_file() else item.name


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
    from dask.distributed import Client, LocalCluster, as_completed

    from artmotion.app.pipeline import is_finished

    t0 = time.perf_counter()
    items = find_items(root)
    out = Path(out) if out is not None else Path(root) / "artmotion-runs"
    report = BatchReport()
    todo = []
    for it in items:
        od = out / item_name(it)
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
            except (OSError, TimeoutError) as exc:
                raise InputError(f"cannot reach Dask scheduler: {exc}", path=scheduler) from None
        else:
            cluster = LocalCluster(n_workers=max(1, workers), threads_per_worker=1, processes=processes,
                                   dashboard_address=None, silence_logs=40)
            client = Client(cluster)
        try:
            report.workers = len(client.scheduler_info().get("workers", {}))
            futures = {client.submit(run_item, it, od, pure=False, key=f"artmotion-{i}-{item_name(Path(it))}"): (it, od)
                       for i, (it, od) in enumerate(todo)}
            for fut in as_completed(futures):
                it, od = futures[fut]
                try:
                    outcome = fut.result()
                except Exception as exc:  # the worker itself died (killed, out of memory)
                    outcome = ItemOutcome(it, "failed", od, message=f"worker lost: {type(exc).__name__}: {exc}")
                report.outcomes.append(outcome)
                if on_progress:
                    on_progress(outcome, len(report.outcomes), total)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    report.outcomes.sort(key=lambda o: o.item)
    report.seconds = time.perf_counter() - t0
    return report
