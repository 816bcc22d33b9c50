"""``artmotion tool train|track|eval``: surgical instruments (registered on the root app by :func:`register`)."""

from __future__ import annotations

import sys
import time
from collections import Counter
from pathlib import Path
from typing import Optional

import typer

from artmotion.errors import InputError, check_range

tool_app = typer.Typer(help="Surgical instruments: learn a head detector from annotated frames, track, score.",
                       no_args_is_help=True)


def _read_annotations(path: Path) -> dict:
    """:func:`~artmotion.tracking.instruments.annotations.read_tools_csv`, saying on stderr which of
    the file's columns it does not read (an export's ``label``, ``visible``: not taken into account)."""
    from artmotion.tracking.instruments.annotations import read_tools_csv

    extra: list[str] = []
    heads = read_tools_csv(path, extra)
    if extra:
        typer.echo(f"note: {path}: column{'s' if len(extra) > 1 else ''} {', '.join(map(repr, extra))} not read "
                   "(only frame,tool,y,x,scale,angle are)", err=True)
    return heads


def _say_depth(seq) -> None:
    """Say on stderr when 16-bit frames are read as fewer bits (a 12-bit camera's 0-4095 read by
    their top 8 bits are nearly black; :attr:`~artmotion.io.sequence.Sequence.depth`)."""
    from artmotion.io.media import depth_note

    if note := depth_note(seq.depth):
        typer.echo(f"note: {note}", err=True)


def _numbered_frames(source: str):
    """``(sequence, frame numbers)``: an image folder's frames are numbered by their file names'
    numbers (as in tools.csv; by position when some are missing); a video's are None
    (its frames count from 1). A number beyond what a predictions file holds (a date-stamped name)
    is an error naming its frame, before any work, not of the output file after the tracking."""
    from artmotion.io.mot import MAX_FRAME
    from artmotion.io.sequence import _frame_number, open_sequence

    seq = open_sequence(source)
    if seq.images is None:
        return seq, None
    numbers = [_frame_number(p) for p in seq.images]
    if any(n is None for n in numbers):  # (repeated numbers are already an error of open_sequence)
        return seq, list(range(1, len(seq.images) + 1))
    for n, p in zip(numbers, seq.images):
        if n is not None and n > MAX_FRAME:
            raise InputError(f"frame number {n} (the last number in the name) is beyond {MAX_FRAME}, the largest a "
                             "predictions file holds: rename the frames", path=p)
    return seq, numbers


@tool_app.command("train")
def train(
    frames: str = typer.Argument(..., metavar="FRAMES", help="Folder of frames whose file names carry the frame numbers."),
    tools_csv: Path = typer.Argument(..., metavar="TOOLS_CSV", help="Annotations: frame,tool,y,x,scale,angle."),
    model: Path = typer.Option(..., "--model", help="Model file to write."),
    epochs: int = typer.Option(30, "--epochs", help="Passes over the annotated frames."),
    threshold: float = typer.Option(0.05, "--threshold", help="Least score of a detection the tracker uses (model default)."),
    seed: int = typer.Option(0, "--seed", help="Random seed (augmentation, initial weights)."),
):
    """Learn an instrument-head detector (a small network trained on the CPU) from annotated frames."""
    from artmotion.errors import check_seed

    check_range("--epochs", epochs, 1, 1000, integer=True)
    check_range("--threshold", threshold, 0.0, 1.0, lo_open=True, hi_open=True)
    check_seed(seed)
    from artmotion.io import check_writable

    check_writable(model, inputs=(tools_csv, frames))  # before the training
    from artmotion.tracking.instruments.detector import ToolDetector, need_torch

    need_torch()
    heads = _read_annotations(tools_csv)
    seq, numbers = _numbered_frames(frames)
    if numbers is None:
        raise InputError("FRAMES must be a folder of frames (the annotations name frames by number)", path=frames)
    assert seq.images is not None
    by_number = dict(zip(numbers, seq.images))
    used = [n for n in sorted(heads) if n in by_number]
    if not used:
        raise InputError(f"no annotated frame is in {frames} (frame numbers {min(heads)}-{max(heads)})", path=tools_csv)
    from artmotion.io.media import read_frame
    from artmotion.tracking.instruments.detector import check_frame_size

    _say_depth(seq)   # (tool track reads its frames the same way)
    imgs = [read_frame(by_number[n], seq.bits) for n in used]
    (H, W), _ = Counter(img.shape[:2] for img in imgs).most_common(1)[0]
    for n, img in zip(used, imgs):  # one detector, one frame size: the odd frame named
        if img.shape[:2] != (H, W):
            raise InputError(f"image size {img.shape[1]}x{img.shape[0]} differs from the other training frames' "
                             f"{W}x{H}", path=by_number[n])
    check_frame_size(H, W, path=frames)
    for n, img in zip(used, imgs):  # a head is where the tool is seen: inside its frame
        h, w = img.shape[:2]
        out = [(x, y) for x, y in heads[n][:, :2] if not (0 <= x < w and 0 <= y < h)]
        if out:
            raise InputError(f"frame {n}: a head at ({out[0][0]:g}, {out[0][1]:g}) lies outside the {w}x{h} frame",
                             path=tools_csv)
    if len(used) < len(heads):
        typer.echo(f"note: {len(heads) - len(used)} annotated frame(s) have no image in {frames} and are left out", err=True)

    def progress(epoch: int, total: int, loss: float) -> None:
        if sys.stderr.isatty():
            typer.echo(f"\repoch {epoch}/{total}  loss {loss:.3f}", err=True, nl=epoch == total)

    det = ToolDetector(epochs=epochs, threshold=threshold, seed=seed).fit(imgs, [heads[n] for n in used], progress)
    det.save(model)
    k = sum(len(heads[n]) for n in used)
    typer.echo(f"trained on {len(used)} frames ({k} heads) in {det.train_seconds_:.0f} s; reports at most "
               f"{det.max_heads_} heads a frame (twice the most in a training frame); wrote {model}")


@tool_app.command("track")
def track(
    source: str = typer.Argument(..., metavar="SOURCE", help="Folder of frames or a video."),
    model: Path = typer.Option(..., "--model", help="Model from 'artmotion tool train'."),
    out: Path = typer.Option(..., "--out", help="Predictions CSV: frame,track,x,y,scale,angle,score."),
    threshold: Optional[float] = typer.Option(None, "--threshold", help="Least detection score (default: the model's)."),
    progress: bool = typer.Option(None, "--progress/--no-progress", help="Progress bar (default: on a terminal)."),
):
    """Find and track the instruments: one row per instrument per frame, with persistent identities.

    A head is reported once detections on 2 frames confirm it, from its first frame on. Frames of
    another size than the model's training frames are scaled to their area, as the same view at
    another resolution (the summary says so): a crop of the view, whose instruments keep their
    size, is better padded to the model's frame size (docs/surgical.md)."""
    from artmotion.io import check_writable
    from artmotion.tracking.instruments.annotations import write_predictions

    check_writable(out, inputs=(model, source))
    if threshold is not None:
        check_range("--threshold", threshold, 0.0, 1.0, lo_open=True, hi_open=True)
    seq, numbers = _numbered_frames(source)
    from artmotion.tracking.api import too_short
    from artmotion.tracking.instruments.detector import ToolDetector, check_frame_size, scale_to

    check_frame_size(seq.height, seq.width, path=seq.path, training=False)   # (1x1 frames were scaled x330)
    from artmotion.tracking.instruments.track import CONFIRM_HITS, ToolTracker, track_sequence

    det = ToolDetector.load(model)
    if threshold is not None:
        det.threshold = threshold
    _say_depth(seq)
    tracker = ToolTracker(det)
    t0 = time.perf_counter()
    pred = {numbers[i - 1] if numbers else i: rows
            for i, rows in track_sequence(seq, det, sys.stderr.isatty() if progress is None else progress,
                                          tracker=tracker)}
    seconds = time.perf_counter() - t0
    write_predictions(out, pred)
    if tracker.capped:
        typer.echo(f"note: on {tracker.capped} frame(s) the detector found more heads than the {det.max_heads_} a "
                   f"frame the model reports and left out a likely one (score {tracker.birth} or more): train it on "
                   "frames that show as many instruments", err=True)
    _say_unlike(det, tracker, seq)
    heads = sum(len(r) for r in pred.values())
    ids = len({int(t) for r in pred.values() for t in r[:, 0]})
    why = too_short(heads, len(pred), CONFIRM_HITS, "a head")
    why = f" ({why})" if why else ""
    f = scale_to(det.frame_shape_, (seq.height, seq.width))
    (h, w), scaled = det.frame_shape_, ""
    if f != 1.0:
        scaled = (f"; frames of {seq.width}x{seq.height} scaled x{f:.2f} to the model's {w}x{h} area "
                  "(the same view assumed)")
    typer.echo(f"{len(pred)} frames, {heads} heads of {ids} instruments{why} in {seconds:.1f} s "
               f"({len(pred) / max(seconds, 1e-9):.1f} frames/s){scaled}; wrote {out}")


def _say_unlike(det, tracker, seq) -> None:
    """Notes on stderr when the frames are unlike the model's training frames: nearly black, grey
    for a colour model (or colour for a grey one), upright for a model of wide frames (or wide for
    upright ones)."""
    from artmotion.tracking.instruments.track import DARK

    if tracker.first_max is not None and tracker.first_max < DARK:
        typer.echo(f"note: the frames are nearly black (the first one's brightest value is {tracker.first_max} of "
                   "255): the detector may find nothing", err=True)
    grey = getattr(det, "grey_", None)
    if grey is not None and tracker.first_grey is not None and grey != tracker.first_grey:
        typer.echo(f"note: the frames are {'grey' if tracker.first_grey else 'in colour'}, the model's training frames "
                   f"{'grey' if grey else 'in colour'}: its detections may be poor", err=True)
    h, w = det.frame_shape_
    if (seq.height > seq.width and w > h) or (seq.width > seq.height and h > w):
        typer.echo(f"note: frames of {seq.width}x{seq.height} for a model trained on frames of {w}x{h} (turned): "
                   "its detections may be poor", err=True)


@tool_app.command("eval")
def evaluate(
    gt: Path = typer.Argument(..., metavar="GT.csv", help="Annotations: frame,tool,y,x,scale,angle."),
    pred: Path = typer.Argument(..., metavar="PRED.csv", help="Predictions: frame,track,x,y,scale,angle,score."),
    radius: float = typer.Option(15.0, "--radius", help="A head is found within this many pixels."),
    fps: Optional[float] = typer.Option(None, "--fps", help="Frames per second of the tracker, to report."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
):
    """Score predictions: recall and precision of heads within --radius px, shaft angle error, identity switches.

    Only annotated frames are scored: those from GT.csv's first frame to its last, in the step of
    the frames it names (every frame, every 5th); one of them without a row shows no instrument.
    Predictions on other frames (nobody annotated them) are not counted as false, only reported as
    not scored."""
    import json

    from artmotion.tracking.instruments.annotations import read_predictions
    from artmotion.tracking.instruments.evaluate import evaluate_tools, format_report, grid_note

    check_range("--radius", radius, 0.0, 1e6, lo_open=True)
    if fps is not None:
        check_range("--fps", fps, 0.0, 1e9, lo_open=True)
    truth, predictions = _read_annotations(gt), read_predictions(pred)
    if note := grid_note(truth):        # (one stray row scored every frame: precision 1.0 -> 0.25)
        typer.echo(f"note: {gt}: {note}", err=True)
    try:
        res = evaluate_tools(truth, predictions, radius=radius, fps=fps)
    except InputError as exc:   # the frames of the two files do not meet
        raise InputError(exc.reason, path=pred) from None
    typer.echo(json.dumps(res, allow_nan=False) if as_json else format_report(res))


def register(app: typer.Typer) -> None:
    """Add the ``tool`` commands to the root artmotion app."""
    app.add_typer(tool_app, name="tool")
