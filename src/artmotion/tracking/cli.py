"""CLI commands of :mod:`artmotion.tracking` (registered on the root app by :func:`register`)."""

from __future__ import annotations

import typer

from artmotion.tracking.config import DETECT_EVERY, check_detect_every


def eval_command(
    gt: str = typer.Argument(..., metavar="GT.txt", help="Ground truth, MOTChallenge text (rows with conf 0 are ignored)."),
    results: str = typer.Argument(..., metavar="RESULTS.txt", help="Tracking results, MOTChallenge text."),
    json_out: bool = typer.Option(False, "--json", help="Print every score as JSON instead of a table."),
    iou: float = typer.Option(0.5, "--iou", help="IoU a match needs for CLEAR MOT and IDF1 (HOTA sweeps 0.05..0.95)."),
    rules: str = typer.Option("auto", "--rules", metavar="auto|mot15|mot17",
                              help="MOTChallenge rules: mot17 keeps pedestrians with consider=1 and removes "
                                   "result boxes on distractors; auto: mot17 for 9-column ground truth."),
) -> None:
    """Score tracking results: MOTA, MOTP, IDF1, HOTA, MT/PT/ML, FM, IDS, FP, FN (MOTChallenge rules)."""
    import json

    from artmotion.errors import InputError, check_range
    from artmotion.tracking.metrics import columns_of, evaluate, format_table, gt_rules

    check_range("--iou", iou, 0.0, 1.0, lo_open=True)
    scores = evaluate(gt, results, iou_threshold=iou, rules=rules)
    if not scores["GT_DETS"]:
        # nothing to score against: MOTA 0 would read as a result
        raise InputError("no ground truth: no boxes to score against (empty, or every box ignored)", path=gt)
    if rules == "auto":
        from artmotion.io import read_mot

        rules = gt_rules(read_mot(gt), columns_of(gt))
    scores["rules"] = rules
    if json_out:
        typer.echo(json.dumps(scores, indent=2))
    else:
        typer.echo(format_table(scores, gt=gt, results=results, iou_threshold=iou, rules=rules))


def track_command(
    source: str = typer.Argument(..., metavar="SOURCE",
                                 help="MOTChallenge folder (seqinfo.ini), video file, or folder of images."),
    det: str = typer.Option(None, "--det", metavar="DET.txt",
                            help="Detections, MOTChallenge text (default: SOURCE/det/det.txt, else the built-in detector)."),
    detector: str = typer.Option("auto", "--detector", metavar="auto|ssdlite|hog",
                                 help="Built-in person detector when there are no detections: ssdlite (a CNN), "
                                      "hog (OpenCV's HOG), auto: ssdlite when installed, else hog."),
    detect_every: int = typer.Option(DETECT_EVERY, "--detect-every", metavar="K",
                                     help="Run the built-in detector on every K-th frame and the last; the "
                                          "tracker carries the boxes in between."),
    out: str = typer.Option(None, "--out", metavar="RESULTS.txt", help="Write the tracks (MOTChallenge text)."),
    events: str = typer.Option(None, "--events", metavar="EVENTS.jsonl",
                               help="Write enter/exit/merge/split events (JSON lines)."),
    video: str = typer.Option(None, "--video", metavar="ANNOTATED.mp4", help="Write an annotated video."),
    experts: str = typer.Option(None, "--experts",
                                help="Comma-separated tracking experts to fuse (default: det,motion; also klt, blob, flow)."),
    online: bool = typer.Option(False, "--online", help="Causal results only (no second, offline pass)."),
    fps: float = typer.Option(None, "--fps", help="Frame rate (frames/s), in place of the input's own: a folder of "
                                                  "images says none (25 is assumed), a video's header may say it wrong."),
    bits: int = typer.Option(None, "--bits", help="Bits that 16-bit image frames hold (8-16), in place of what "
                                                   "frames spread over them show (a 12-bit camera's dark first "
                                                   "frames show fewer)."),
    progress: bool = typer.Option(None, "--progress/--no-progress",
                                  help="Progress bar on stderr (default: when stderr is a terminal)."),
) -> None:
    """Track people through occlusions (Product of Tracking Experts + group nodes)."""
    import contextlib
    import sys

    from artmotion.errors import InputError
    from artmotion.io import atomic_path, check_apart, check_writable, write_events, write_mot
    from artmotion.io.media import depth_note
    from artmotion.tracking import DEFAULT_EXPERTS, open_sequence, track
    from artmotion.tracking.api import too_short

    if video and not video.lower().endswith(".mp4"):
        raise InputError("--video writes an MP4 file: give a name ending in .mp4", path=video)
    check_detect_every(detect_every, "--detect-every")   # (track() names its argument)
    seq = open_sequence(source)  # (opened once: track() takes it as it is)
    seq.set_bits(bits)
    # before the work, so that no output is written when one cannot be (nor over an input: the
    # detections, given or the sequence's own)
    # (and the sequence's own seqinfo.ini and ground truth: an output over them broke the folder)
    check_writable(out, events, video, inputs=(*seq.inputs(), det))
    check_apart(video, (seq.video_home,))   # (a second video in a sequence folder of one makes it unreadable)
    if progress is None:
        progress = sys.stderr.isatty()
    # the outputs are written under temporary names and renamed together once all are written: a
    # full disk while writing one never leaves the others (a new video beside older results)
    with contextlib.ExitStack() as stack:
        tmp = {p: stack.enter_context(atomic_path(p)) for p in (out, events, video) if p}
        res = track(seq, det=det, experts=experts or DEFAULT_EXPERTS, online=online, progress=progress,
                    video=tmp.get(video), fps=fps, detector=detector, detect_every=detect_every)
        if out:
            write_mot(tmp[out], res.tracks)
        if events:
            write_events(tmp[events], res.events)
    counts: dict[str, int] = {}
    for ev in res.events:
        counts[ev["type"]] = counts.get(ev["type"], 0) + 1
    seq = res.sequence
    kinds = ", ".join(f"{counts[k]} {k}" for k in ("enter", "exit", "merge", "split") if k in counts)
    assumed = "" if seq.fps_known else " (assumed; give --fps)"
    stored = f" as stored (not turned as its orientation tag asks: {seq.orientation})" if seq.orientation else ""
    if note := depth_note(seq.depth):
        stored += f" ({note})"
    typer.echo(f"{seq.name}: {res.frames} frames {seq.width}x{seq.height}{stored} @ {seq.fps:g} fps{assumed}, "
               f"detections: {res.detector}, experts: {','.join(res.experts)}"
               f"{' (online)' if online else ''}")
    why = too_short(res.num_tracks, res.frames)
    typer.echo(f"{res.num_tracks} tracks, {len(res.tracks)} boxes, {len(res.events)} events"
               f"{' (' + kinds + ')' if kinds else ''}{': ' + why if why else ''}")
    typer.echo(f"{res.fps:.1f} frames/s ({res.seconds:.2f} s)")
    for what, path in (("tracks", out), ("events", events), ("video", video)):
        if path:
            typer.echo(f"{what}: {path}")


def register(app: typer.Typer) -> None:
    """Add this capability's commands to the root artmotion app."""
    app.command("eval")(eval_command)
    app.command("track")(track_command)
