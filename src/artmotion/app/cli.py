"""CLI of the application layer: ``run``, ``index add``, ``index list``, ``search``, ``batch``."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Optional

import typer

from artmotion.errors import InputError, check_range
from artmotion.tracking.config import DETECT_EVERY, check_detect_every

DEFAULT_DB = "artmotion-index.sqlite"


def _db_option():
    return typer.Option(
        None, "--db", help=f"SQLite index file (default: $ARTMOTION_INDEX or ./{DEFAULT_DB})", show_default=False
    )


def _db_path(db: Optional[Path], must_exist: bool = False) -> Path:
    """The index file to use; checked to be an artmotion index when it exists (before any long
    work), required to exist with ``must_exist``."""
    from artmotion.app.index import check_index
    from artmotion.io import check_writable

    path = Path(db) if db is not None else Path(os.environ.get("ARTMOTION_INDEX", DEFAULT_DB))
    if path.exists():
        check_index(path)
    elif must_exist:
        raise InputError("no such index (add runs with 'artmotion index add')", path=path)
    if not must_exist:
        check_writable(path)  # its folder must take the new index (a read-only one failed after the work)
    return path


def _add_runs(db: Path, runs: list[Path]) -> tuple[int, list[str | None]]:
    """Read and check every run's manifest, then add them all to the index at ``db`` (created
    atomically if new); returns the number of videos in it and, per run, the run folder of the
    entry it replaced (the same source), if any."""
    from artmotion.app.index import IndexAppeared, building
    from artmotion.app.pipeline import load_run

    manifests = [(run, load_run(run)) for run in runs]
    while True:
        try:
            with building(db) as idx:
                added = idx.add_runs(manifests)
                return len(idx.videos()), [old for _, old in added]
        except IndexAppeared:       # another command created the index meanwhile: add to that one
            continue


def _label(name: str, source: str | None, shared: set) -> str:
    """A video's name, with its source path when another indexed video has the same name; a
    character that would not print as itself (a line break in a file's name) escaped, so that one
    video is one line."""
    text = f"{name} ({source})" if name in shared and source else name
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in text)


def _run_dirs(path: Path) -> list[Path]:
    """A run folder itself, or every run folder directly inside ``path`` (e.g. a batch's output)."""
    from artmotion.app.pipeline import MANIFEST

    if (path / MANIFEST).is_file():
        return [path]
    if path.is_dir():
        runs = sorted(p for p in path.iterdir() if (p / MANIFEST).is_file())
        if runs:
            return runs
    raise InputError(f"no finished run here (a folder with {MANIFEST}, or folders of them)", path=path)


def run_cmd(
    source: Path = typer.Argument(..., help="MOTChallenge sequence folder, video file or image folder."),
    out: Optional[Path] = typer.Option(None, "--out", help="Run folder (default: runs/NAME, or runs/NAME-<key> when that "
                                                             "holds another source's run)."),
    det: Optional[Path] = typer.Option(None, "--det", help="Detections (MOTChallenge text) instead of the built-in detector."),
    detector: str = typer.Option("auto", "--detector", metavar="auto|ssdlite|hog",
                                 help="Built-in person detector when there are no detections (auto: ssdlite when "
                                      "installed, else hog)."),
    detect_every: int = typer.Option(DETECT_EVERY, "--detect-every", metavar="K",
                                     help="Run the built-in detector on every K-th frame and the last."),
    object_class: str = typer.Option("person", "--class", help="Object class named in sentences."),
    video: bool = typer.Option(True, "--video/--no-video", help="Also write annotated.mp4."),
    index: Optional[Path] = typer.Option(None, "--index", help="Add the run to this SQLite event index."),
    pose_model: Optional[Path] = typer.Option(None, "--pose-model",
                                              help="Pose model (artmotion pose train): adds opens/closes sentences."),
    tool_model: Optional[Path] = typer.Option(None, "--tool-model",
                                              help="Tool model (artmotion tool train): track surgical instruments "
                                                   "instead of people."),
    fps: Optional[float] = typer.Option(None, "--fps", help="Frame rate (frames/s), in place of the input's own: a folder "
                                                            "of images says none (25 is assumed), a video's header may "
                                                            "say it wrong."),
    bits: Optional[int] = typer.Option(None, "--bits", help="Bits that 16-bit image frames hold (8-16), in place of "
                                                              "what frames spread over them show (a 12-bit camera's "
                                                              "dark first frames show fewer)."),
):
    """Video → tracks → events → sentences → HTML report (and metrics when ground truth is present)."""
    import sys

    from artmotion.app.pipeline import run_pipeline
    from artmotion.tracking.api import NO_DETECTIONS, too_short

    check_detect_every(detect_every, "--detect-every")   # (run_pipeline names its argument)
    db = _db_path(index) if index is not None else None       # a wrong index fails before the run
    if db is not None:
        from artmotion.io import check_text

        for path in (source.resolve(), *(() if out is None else (out.resolve(),))):
            check_text(path)
    where = Path(os.path.realpath(db)) if db is not None else None
    if where is not None and out is not None and Path(os.path.realpath(out)) in (where, *where.parents):
        # the next run into --out replaces the folder whole, or refuses a folder holding other files
        raise InputError("is the run folder --out or inside it: keep the index outside it (next to it)", path=db)
    # the progress bar only on a terminal: in a log, an error stays the one line on stderr
    res = run_pipeline(source, out, det=det, object_class=object_class, progress=sys.stderr.isatty(), video=video,
                       pose_model=pose_model, detector=detector, detect_every=detect_every, tool_model=tool_model,
                       fps=fps, bits=bits, also_writes=(db,) if db is not None else ())
    from artmotion.io.media import depth_note

    if note := depth_note(res.depth):
        typer.echo(f"note: {note}", err=True)
    why = too_short(res.num_tracks, res.frames)
    typer.echo(f"{res.name}: {res.num_tracks} tracks, {len(res.events)} events, {len(res.sentences)} sentences"
               f" in {res.seconds:.1f} s{': ' + why if why else ''}")
    for s in res.sentences[:10]:
        typer.echo(f"  {s['sentence']}")
    if len(res.sentences) > 10:
        typer.echo(f"  … {len(res.sentences) - 10} more in {res.out_dir / 'sentences.txt'}")
    if res.pose is not None and not res.pose["applies"]:
        typer.echo(f"pose model: not said whether anything opens or closes: the {res.pose['crops']} crops are unlike "
                   f"its training crops (told from the nearest of them with AUC {res.pose['domain_auc']:.2f})")
    if res.pose is not None and res.pose.get("far"):
        typer.echo(f"pose model: {res.pose['far']} of {res.pose['crops']} crops are far from every training crop: their "
                   "angles there are the model's prior (the spread of its training angles), not read off the crops")
    if res.pose is not None and res.pose["applies"] and not res.pose["judged"]:
        typer.echo(f"pose model: applied without knowing whether the {res.pose['crops']} crops are like its training "
                   f"crops (too few to tell)")
    if res.detections.endswith(NO_DETECTIONS):     # (an empty det.txt: said, as track says it)
        typer.echo(f"note: {res.detections}", err=True)
    if res.metrics is None and res.gt_path is not None:
        typer.echo(f"note: no metrics: {res.gt_path} holds no box to score against (empty, or every box ignored)",
                   err=True)
    if res.metrics:
        m = res.metrics
        typer.echo(f"metrics: MOTA {m['MOTA']:.3f}  IDF1 {m['IDF1']:.3f}  IDS {int(m['IDS'])}"
                   f"  FP {int(m['FP'])}  FN {int(m['FN'])}")
    typer.echo(f"report: {res.report}")
    if db is not None:
        _add_runs(db, [res.out_dir])
        typer.echo(f"indexed in {db}")


index_app = typer.Typer(help="The SQLite event index of many videos.", no_args_is_help=True)


@index_app.command("add")
def index_add(
    path: Path = typer.Argument(..., help="A run folder (from `artmotion run`) or a folder of run folders."),
    db: Optional[Path] = _db_option(),
):
    """Add runs to the event index (a run of a source already there replaces it)."""
    db_path = _db_path(db)
    runs = _run_dirs(path)
    count, replaced = _add_runs(db_path, runs)
    for run, old in zip(runs, replaced):
        same = old is not None and Path(old) == run.resolve()
        typer.echo(f"added {run}" + ("" if old is None else " (again)" if same else
                                     f" (replacing {old}: a run of the same source)"))
    typer.echo(f"{db_path}: {count} videos")


@index_app.command("list")
def index_list(db: Optional[Path] = _db_option(),
               as_json: bool = typer.Option(False, "--json", help="Print the videos as JSON.")):
    """List the indexed videos with their counts of tracks, events and sentences."""
    from artmotion.app.index import EventIndex

    with EventIndex(_db_path(db, must_exist=True), write=False) as idx:
        videos = idx.videos()
        shared = idx.shared_names()
    if as_json:
        typer.echo(json.dumps(videos, indent=1, allow_nan=False))
        return
    for v in videos:
        frames = "frames unknown" if v["frames"] is None else f"{v['frames']} frames"     # (a manifest without them)
        typer.echo(f"{_label(v['name'], v['source'], shared)}: {frames}, {v['tracks']} tracks, "
                   f"{v['events']} events, {v['sentences']} sentences")


def search_cmd(
    query: str = typer.Argument(..., help='What to find, e.g. "person exits left" or "person 3 merges".'),
    video: Optional[str] = typer.Option(None, "--video", help="Only this video: its name or its source (index list)."),
    limit: int = typer.Option(20, "--limit", min=1, help="Most hits to print, best first."),
    as_json: bool = typer.Option(False, "--json", help="Print the hits as JSON."),
    db: Optional[Path] = _db_option(),
):
    """Find the moments that match a query, best first."""
    from artmotion.app.index import EventIndex
    from artmotion.io import check_text

    if video is not None:
        check_text(video, "--video", "no video in the index is named so")
    with EventIndex(_db_path(db, must_exist=True), write=False) as idx:
        hits = idx.search(query, video=video, limit=limit)
        shared = idx.shared_names()
    if as_json:         # (no match: [] and exit status 1, as in text)
        typer.echo(json.dumps([h.as_dict() for h in hits], indent=1, allow_nan=False))
        if not hits:
            raise typer.Exit(1)
        return
    if not hits:
        typer.echo("no match")
        raise typer.Exit(1)
    for h in hits:
        how = "" if h.match == "structured" else "  (text match)"
        typer.echo(f"{h.score:5.2f}  {_label(h.video, h.source, shared)}  frames {h.frame_start}-{h.frame_end}  "
                   f"tracks {h.tracks}  {h.sentence}{how}")


def batch_cmd(
    folder: Path = typer.Argument(..., help="Folder of sequences (MOTChallenge folders, videos, image folders)."),
    out: Optional[Path] = typer.Option(None, "--out", help="Where run folders go (default: FOLDER/artmotion-runs)."),
    workers: int = typer.Option(1, "--workers", min=1, help="Local Dask workers (processes)."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Address of an existing Dask scheduler."),
    force: bool = typer.Option(False, "--force", help="Re-run items that already finished."),
    index: Optional[Path] = typer.Option(None, "--index", help="Add every finished run to this SQLite index."),
):
    """Run the pipeline on every item of FOLDER on Dask; failures are isolated and listed."""
    import sys

    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from artmotion.app.batch import BatchInterrupted, run_batch
    from artmotion.errors import ArtmotionError, one_line

    check_range("--workers", workers, 1, 4 * (os.cpu_count() or 1), integer=True)  # (4 processes per core at most)
    db = _db_path(index) if index is not None else None       # a wrong index fails before the batch
    try:
        # the bar on stderr, and only on a terminal (on stdout it left an empty line before the report);
        # the report's lines go above it only when stdout is that terminal too (else to stdout as they are)
        with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                      transient=True, console=Console(stderr=True), disable=not sys.stderr.isatty(),
                      redirect_stdout=sys.stdout.isatty()) as progress:
            task = progress.add_task("batch", total=None)

            def on_progress(outcome, done, total):
                progress.update(task, completed=done, total=total,
                                description=f"{Path(outcome.item).name}: {outcome.status}")
                # each line as the item ends (flushed: an interrupted batch kept none of them before)
                if outcome.status == "done":
                    typer.echo(f"done     {Path(outcome.item).name}: {outcome.tracks} tracks, {outcome.sentences} "
                               f"sentences, {outcome.seconds:.1f} s{f' ({outcome.note})' if outcome.note else ''}")
                elif outcome.status == "skipped":
                    typer.echo(f"skipped  {Path(outcome.item).name}: already finished")
                elif outcome.status == "ignored":   # (a name of bytes that are not UTF-8 written as \udce9)
                    typer.echo(one_line(f"skipped  {Path(outcome.item).name}: {outcome.message}"))
                sys.stdout.flush()

            report = run_batch(folder, out, workers=workers, scheduler=scheduler, force=force,
                               on_progress=on_progress, own=[db] if db is not None else [])
    except BatchInterrupted as exc:
        r = exc.report
        kept = r.by_status("done") + r.by_status("skipped")
        n_failed = len(r.by_status("failed"))
        exc.kept = (f"{len(kept)} of {len(kept) + n_failed + len(exc.not_run)} items finished (kept), {n_failed} failed, "
                    f"{len(exc.not_run)} not finished (nothing half-written was kept); run the same command again "
                    "to resume")
        if db is not None and kept:
            # the finished runs into the index (one transaction: all or none; the signals are held off)
            try:
                count, _ = _add_runs(db, [Path(o.out_dir) for o in kept])
                exc.kept += f"; indexed {len(kept)} runs in {db} ({count} videos)"
            except (ArtmotionError, OSError) as err:
                runs = out if out is not None else folder / "artmotion-runs"
                exc.kept += (f"; the finished runs are not indexed ({err}): add them with "
                             f"'artmotion index add {runs} --db {db}'")
        raise
    done, skipped, failed = (report.by_status(s) for s in ("done", "skipped", "failed"))
    ignored = report.by_status("ignored")
    if db is not None and done + skipped:
        count, _ = _add_runs(db, [Path(o.out_dir) for o in done + skipped])
        typer.echo(f"indexed {len(done) + len(skipped)} runs in {db} ({count} videos)")
    # (the entries of FOLDER that are no item count as skipped)
    typer.echo(f"{len(done)} done, {len(skipped) + len(ignored)} skipped, {len(failed)} failed in {report.seconds:.1f} s"
               f" on {report.workers} worker(s)")
    if failed:
        # one line per failed item; exit 2 when every failure is bad input, 1 when one is a bug
        for o in failed:
            where = "" if o.message.startswith(o.item) else f"{o.item}: "
            typer.echo(one_line(f"artmotion: {'internal error' if o.internal else 'error'}: {where}{o.message}"), err=True)
        raise typer.Exit(1 if any(o.internal for o in failed) else 2)


def register(app: typer.Typer) -> None:
    """Add the application's commands to the root ``artmotion`` app."""
    app.command("run")(run_cmd)
    app.add_typer(index_app, name="index")
    app.command("search")(search_cmd)
    app.command("batch")(batch_cmd)
