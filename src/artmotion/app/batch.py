"""Process whole archives on Dask distributed: one pipeline run per sequence or video.

Each item runs in isolation (its failure is caught and listed, it stops nothing else); finished
items (a ``run.json`` of the same input, unchanged, in their output folder) are skipped, so an
interrupted batch resumes where it stopped; a run folder holding another input's run fails its
item. A local cluster is started by default; give a scheduler address to use an existing one.
"""

from __future__ import annotations

import os
import time
import traceback
import unicodedata
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

from artmotion._native import signals_held
from artmotion.app.pipeline import is_finished, load_run
from artmotion.errors import ArtmotionError, InputError, Interrupted, one_line
from artmotion.io import check_apart, check_text
from artmotion.io.atomic import check_can_create_in
from artmotion.io.media import IMAGE_EXTS, VIDEO_EXTS, depth_note

#: why an entry of a batch's folder is not run
NOT_AN_ITEM = "not a video, a folder of images or a MOTChallenge folder"


def scan(root: str | os.PathLike) -> tuple[list[Path], list[tuple[Path, str]], list[tuple[Path, str]]]:
    """The entries of ``root`` (not those inside its folders; hidden ones left out): the items
    (MOTChallenge folders with a ``seqinfo.ini``, video files, image folders), every other entry
    with why it is none (a batch reports them: they were silently left out), and the items that
    cannot be run, with why (an item whose name is not UTF-8, a link to nothing: an unmounted
    disk's sequence or video; a batch counts them as failed, not as left out)."""
    root = Path(root)
    if not root.is_dir():
        raise InputError("not a folder", path=root)
    items: list[Path] = []
    others: list[tuple[Path, str]] = []
    broken: list[tuple[Path, str]] = []

    def item(p: Path) -> None:          # (sent to the workers as text: a name that is not fails)
        try:
            check_text(p, "the workers are sent it as text")
        except InputError as exc:
            broken.append((p, exc.reason))
        else:
            items.append(p)

    for p in sorted(root.iterdir()):
        if p.name.startswith("."):
            continue
        if p.is_symlink() and not p.exists():
            broken.append((p, "a link to nothing (no such file or folder)"))
            continue
        if p.is_dir():
            try:
                entries = list(p.iterdir())
            except OSError as exc:      # (no permission: one line for it, not the batch stopped)
                others.append((p, f"cannot read this folder: {exc.strerror or exc}"))
                continue
            if (p / "seqinfo.ini").is_file() or any(q.suffix.lower() in IMAGE_EXTS for q in entries if q.is_file()):
                item(p)
            elif not entries:
                others.append((p, "an empty folder"))
            elif any(q.is_dir() for q in entries):
                others.append((p, f"{NOT_AN_ITEM} (the folders inside it are not searched)"))
            else:
                others.append((p, NOT_AN_ITEM))
        elif p.is_file() and p.suffix.lower() in VIDEO_EXTS:
            item(p)
        else:
            others.append((p, NOT_AN_ITEM))
    return items, others, broken


def find_items(root: str | os.PathLike) -> list[Path]:
    """Sequences in ``root``: MOTChallenge folders (``seqinfo.ini``), video files, image folders."""
    items, _, _ = scan(root)
    if not items:
        raise InputError("no sequences or videos found", path=root)
    return items


def item_name(item: Path) -> str:
    return item.stem if item.is_file() else item.name


def _fold(name: str) -> str:
    """A name as a case-insensitive file system compares it (macOS, Windows: ``Clip`` is ``clip``)."""
    return unicodedata.normalize("NFC", name).casefold()


def item_dirs(items: list[Path], out: Path) -> list[Path]:
    """Each item's run folder in ``out``: its name, or, where two items would share a name
    (``v.mp4`` and ``v.mov``, a folder ``v`` and ``v.avi``), the name with the file's extension.

    Names are compared without case (``clip.avi`` and ``clip.AVI`` on a file system that cannot
    tell ``clip-avi`` from ``clip-AVI``) and a name so made is checked against the others too
    (``x.avi`` beside a folder ``x-avi``): it takes ``-2``, ``-3``... until it is free, so no two
    items share a folder (one's result lost, or reported for the other). The items are taken in
    sorted order, so the same items always get the same folders; an item whose name is shared
    with none keeps it (an earlier batch's finished runs are found again)."""
    names = {it: item_name(it) for it in items}
    counts = Counter(_fold(n) for n in names.values())
    shared = {f for f, c in counts.items() if c > 1}
    taken = set(counts) - shared
    for it in sorted(names, key=str):
        n = names[it]
        if _fold(n) in shared:
            n = f"{n}-{it.suffix.lstrip('.').lower()}" if it.is_file() else f"{n}-folder"
            base, k = n, 1
            while _fold(n) in taken:
                k += 1
                n = f"{base}-{k}"
            taken.add(_fold(n))
            names[it] = n
    return [out / names[it] for it in items]


def _check_scheduler(address: str) -> None:
    """A scheduler address Dask can parse (``tcp://HOST:PORT``), before any work starts."""
    from distributed.comm import parse_address, parse_host_port

    try:
        _, loc = parse_address(address)
        parse_host_port(loc)
    except (ValueError, TypeError) as exc:
        raise InputError(f"not a Dask scheduler address ({exc}); give tcp://HOST:PORT", path=address) from None


#: how long a batch waits for a scheduler that does not answer
CONNECT_TIMEOUT = 5.0


def _connect(address: str):
    """A client of the Dask scheduler at ``address``; one :class:`InputError` naming it when
    nothing answers there within :data:`CONNECT_TIMEOUT` seconds or what answers is no Dask
    scheduler (whatever the error Dask's connection code raises for it)."""
    from dask.distributed import Client

    try:
        return Client(address, timeout=f"{CONNECT_TIMEOUT:g}s")
    except Exception as exc:        # refused, timed out, garbage from another kind of server
        first = (str(exc).strip().splitlines() or [""])[0][:200]
        raise InputError(f"cannot reach a Dask scheduler there ({type(exc).__name__}{': ' + first if first else ''})",
                         path=address) from None


def _start_local_cluster(workers: int, processes: bool):
    """A local Dask cluster whose worker processes ignore the terminal's Ctrl-C (they preload
    :mod:`artmotion.app._dask_worker`; SIGINT is held back here while they start): only this
    process reacts to it, stops the batch and closes them."""
    import logging
    import signal

    from dask.distributed import LocalCluster

    # a worker process starts with the signal mask of the thread that spawns it, a thread of Dask's
    # that inherits this one's; but multiprocessing's resource tracker, started on first use from
    # that thread, unblocks SIGINT there after it has started (a Ctrl-C then reached each worker
    # while it unpickled its start-up data: a traceback each): it is started here first
    blocked = processes and hasattr(signal, "pthread_sigmask")
    if blocked:
        from multiprocessing import resource_tracker

        resource_tracker.ensure_running()
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    # SIGTERM or SIGHUP while a worker is being spawned would stop this process between starting
    # the worker and handing it its start-up data (it prints a traceback once this one is gone):
    # held back until the cluster is up
    cluster = None
    try:
        with signals_held(processes):
            try:
                cluster = LocalCluster(n_workers=max(1, workers), threads_per_worker=1, processes=processes,
                                       dashboard_address=None, silence_logs=logging.CRITICAL,
                                       **({"preload": ["artmotion.app._dask_worker"]} if processes else {}))
            finally:
                if blocked:
                    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})   # a Ctrl-C held back lands here
    except BaseException:
        if cluster is not None:
            _quietly_close(cluster)
        raise
    return cluster


def _silence_dask() -> None:
    """No more of Dask's log messages (its shutdown after an interruption is noisy)."""
    import logging

    logging.getLogger("distributed").setLevel(logging.CRITICAL)


def _quietly_close(*closables) -> None:
    """Close a Dask client and cluster after an interruption, without their shutdown messages."""
    _silence_dask()
    for c in closables:
        if c is not None:
            try:
                c.close()
            except Exception:       # already half-closed: nothing more to do
                pass


class BatchInterrupted(Interrupted):
    """The batch was interrupted; ``report`` holds what finished (kept) and what did not run."""

    def __init__(self, signum: int, report: BatchReport, not_run: list[str]):
        super().__init__(signum)
        self.report = report
        self.not_run = not_run


@dataclass
class ItemOutcome:
    item: str
    #: "done", "skipped" (finished before), "failed", or "ignored" (an entry of the folder that is
    #: no item: ``message`` says why; the command line counts it as skipped)
    status: str
    out_dir: str
    seconds: float = 0.0
    message: str = ""
    tracks: int = 0
    sentences: int = 0
    #: the failure is a bug (or a lost worker), not bad input
    internal: bool = False
    #: how a done item's frames were read, when not as OpenCV reads them (:func:`depth_note`)
    note: str = ""

    def __post_init__(self) -> None:
        self.message = one_line(self.message)  # the command line prints one line per failed item


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


def _finished_by(out_dir: str, batch: str | None, item: str | None = None) -> ItemOutcome | None:
    """The outcome of the run in ``out_dir`` when batch ``batch`` finished it (its manifest says
    so: an earlier batch's run, which ``--force`` runs again, is not), else ``None``."""
    if batch is None or not is_finished(out_dir):
        return None
    try:
        run = load_run(out_dir)
    except ArtmotionError:
        return None
    if run.get("batch") != batch:
        return None
    return ItemOutcome(item or str(run.get("source")), "done", out_dir, run.get("seconds") or 0.0,
                       tracks=len(run["track_summary"]), sentences=len(run["sentences"]))


def run_item(item: str, out_dir: str, single_thread: bool = True, batch: str | None = None) -> ItemOutcome:
    """Run the pipeline on one item; never raises (the failure is the outcome).

    ``batch``: the batch's id. Dask runs an item again when the worker that ran it is lost before
    its result was collected; if an earlier attempt of the same batch finished it, its run is
    reported instead of written a second time."""
    from artmotion._native import quiet_native_logs
    from artmotion.app.pipeline import run_pipeline

    t0 = time.perf_counter()
    quiet_native_logs()              # a damaged item is one line in the report, not FFmpeg's chatter
    if single_thread:
        import cv2

        cv2.setNumThreads(1)
    internal = False
    done = _finished_by(out_dir, batch, item)
    if done is not None:
        return done
    try:
        res = run_pipeline(item, out_dir, progress=False, batch=batch)
        return ItemOutcome(item, "done", out_dir, time.perf_counter() - t0, note=depth_note(res.depth),
                           tracks=res.num_tracks, sentences=len(res.sentences))
    except ArtmotionError as exc:
        msg = str(exc)
    except OSError as exc:
        msg = f"{exc.filename + ': ' if exc.filename else ''}{exc.strerror or exc}"
    except Exception as exc:  # a bug in one item must not stop the archive
        tb = traceback.extract_tb(exc.__traceback__)
        where = f" at {Path(tb[-1].filename).name}:{tb[-1].lineno}" if tb else ""
        msg = f"internal error {type(exc).__name__}: {exc}{where}"
        internal = True
    return ItemOutcome(item, "failed", out_dir, time.perf_counter() - t0, message=msg, internal=internal)


def _remove_stale_temporaries(out_dirs: list[str]) -> None:
    """Remove the temporary folders that runs killed with their worker left next to their run
    folders (``.NAME.xxxxxxxx.tmp``, see :func:`artmotion.io.atomic_dir`): the item was run again
    or reported failed, and nothing else writes such names."""
    import shutil

    from artmotion.io.atomic import stale_dirs

    for od in out_dirs:
        for tmp in stale_dirs(od):
            shutil.rmtree(tmp, ignore_errors=True)


def run_batch(
    root: str | os.PathLike,
    out: str | os.PathLike | None = None,
    workers: int = 1,
    scheduler: str | None = None,
    force: bool = False,
    processes: bool = True,
    on_progress: Callable[[ItemOutcome, int, int], None] | None = None,
    own: Iterable[str | os.PathLike] = (),
) -> BatchReport:
    """Run :func:`artmotion.app.pipeline.run_pipeline` on every item of ``root`` on Dask.

    ``processes=False`` runs the local workers as threads of this process (cheaper to start; for
    tests and small archives). The entries of ``root`` that are no item are reported ``"ignored"``
    (with why), except ``out`` (or a folder holding it) and the caller's ``own`` outputs (an
    index file). ``on_progress(outcome, reported, total)`` is called in this thread as each
    outcome is known.
    """
    import uuid

    from dask.distributed import Client, as_completed

    if scheduler:
        _check_scheduler(scheduler)
    t0 = time.perf_counter()
    out = Path(out) if out is not None else Path(root) / "artmotion-runs"
    for path in (Path(root).resolve(), out.resolve()):
        check_text(path, "the workers are sent it as text")
    if os.path.lexists(out) and not out.is_dir():  # one error now, not one per item later
        raise InputError("is not a folder: the batch writes a run folder per item in it", path=out)
    items, others, broken = scan(root)
    if not items and not broken:
        raise InputError("no sequences or videos found", path=root)
    mine = {Path(os.path.realpath(p)) for p in (out, *own)}
    outs = item_dirs(items, out)
    check_apart(out, items)          # one error now, not one per item later (nor runs in an item's folder)
    for item_path, item_out in zip(items, outs):
        check_apart(item_out, (item_path,))
    report = BatchReport()
    for entry, why in others:
        real = Path(os.path.realpath(entry))
        if not any(real == p or real in p.parents for p in mine):
            report.outcomes.append(ItemOutcome(str(entry), "ignored", "", message=why))
    report.outcomes += [ItemOutcome(str(entry), "failed", "", message=why) for entry, why in broken]
    todo: list[tuple[str, str]] = []
    for item_path, item_out in zip(items, outs):
        try:
            run = load_run(item_out)
        except InputError:
            run = None
        other = None if run is None else run.get("source")
        if other is not None and other != str(item_path.resolve()):
            # another archive's video of the same name, batched into the same folder: that run is
            # neither this item's (to skip) nor this batch's to replace
            report.outcomes.append(ItemOutcome(str(item_path), "failed", str(item_out),
                                               message=f"{item_out} holds the run of {other}"))
        elif not force and run is not None and is_finished(item_out, item_path, run=run):
            report.outcomes.append(ItemOutcome(str(item_path), "skipped", str(item_out), message="already finished"))
        else:
            todo.append((str(item_path), str(item_out)))
    total = len(report.outcomes) + len(todo)
    for o in report.outcomes:
        if on_progress:
            on_progress(o, len(report.outcomes), total)
    if todo:
        check_can_create_in(out)     # (a read-only folder: the cluster started, then every item failed)
        cluster = None
        interrupted: Interrupted | None = None
        if scheduler:
            client = _connect(scheduler)
        else:
            cluster = _start_local_cluster(workers, processes)
            try:
                client = Client(cluster)
            except BaseException:
                _quietly_close(cluster)
                raise
        try:
            report.workers = len(client.scheduler_info().get("workers", {}))
            batch = uuid.uuid4().hex[:12]
            futures = {client.submit(run_item, it, od, batch=batch, pure=False,
                                     key=f"artmotion-{batch}-{i}-{item_name(Path(it))}"): (it, od)
                       for i, (it, od) in enumerate(todo)}
            try:
                for fut in as_completed(futures):
                    it, od = futures[fut]
                    try:
                        outcome = fut.result()
                    except Exception as exc:  # the worker itself died (killed, out of memory)
                        outcome = ItemOutcome(it, "failed", od, message=f"worker lost: {type(exc).__name__}: {exc}",
                                              internal=True)
                    report.outcomes.append(outcome)
                    if on_progress:
                        on_progress(outcome, len(report.outcomes), total)
            except Interrupted as exc:
                _silence_dask()
                client.cancel(list(futures))
                interrupted = exc
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
        if interrupted is not None:
            # the local cluster's workers are gone: an item one of them finished after the signal
            # counts as finished; what they left half-written is stale (an existing cluster's
            # workers may still be writing theirs)
            reported = {o.item for o in report.outcomes}
            for it, od in todo:
                done = _finished_by(od, batch, it) if it not in reported and cluster is not None else None
                if done is not None:
                    done.message = "finished as the batch stopped"
                    report.outcomes.append(done)
                    if on_progress:
                        on_progress(done, len(report.outcomes), total)
            if cluster is not None:
                _remove_stale_temporaries([od for _, od in todo])
            finished = {o.item for o in report.outcomes}
            report.seconds = time.perf_counter() - t0
            raise BatchInterrupted(interrupted.signum, report, [it for it, _ in todo if it not in finished])
        # every item ended: what is left of attempts killed with their worker is stale (not after
        # an interruption, when an existing cluster's workers may still be finishing theirs)
        _remove_stale_temporaries([od for _, od in todo])
    report.outcomes.sort(key=lambda o: o.item)
    report.seconds = time.perf_counter() - t0
    return report
