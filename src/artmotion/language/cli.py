"""CLI commands of :mod:`artmotion.language` (registered on the root app by :func:`register`).

``artmotion describe`` tells what happened in a tracking result; ``artmotion grounding dataset``
and ``artmotion grounding eval`` build and evaluate the shapes-and-colours grounding experiment.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Optional

import typer

from artmotion.errors import InputError, check_range, check_seed


def _size(text: str | None) -> tuple[float, float] | None:
    if text is None:
        return None
    from artmotion.io.mot import MAX_COORD

    m = re.fullmatch(r"\s*(\d+(?:\.\d*)?)\s*[xX]\s*(\d+(?:\.\d*)?)\s*", text)
    if not m or float(m.group(1)) <= 0 or float(m.group(2)) <= 0:
        raise InputError(f"--size {text!r}: expected WIDTHxHEIGHT, e.g. 640x480")
    w, h = (check_range("--size", float(v), 0.0, MAX_COORD, lo_open=True) for v in m.groups())
    return w, h


def describe_cmd(
    results: Path = typer.Argument(..., help="Tracks: MOTChallenge results file (frame,id,x,y,w,h,...)."),
    events: Optional[Path] = typer.Option(None, "--events", help="Events JSON lines written by the tracker."),
    pose: Optional[Path] = typer.Option(None, "--pose", help="Pose predictions PRED.csv (artmotion pose predict)."),
    cls: list[str] = typer.Option(["person"], "--class", help="Object class: NAME for all tracks, or ID=NAME (repeatable)."),
    size: Optional[str] = typer.Option(None, "--size", help="Image size WIDTHxHEIGHT (default: extent of the boxes)."),
    fps: Optional[float] = typer.Option(None, "--fps", help="Frame rate: say times in seconds too."),
    pose_column: Optional[str] = typer.Option(None, "--pose-column",
                                              help="Opening-angle column (default: first containing 'open')."),
    pose_subject: str = typer.Option("tool", "--pose-subject", help="Who opens and closes."),
    pose_track: Optional[int] = typer.Option(None, "--pose-track", help="Track id of the posed object."),
    open_above: Optional[float] = typer.Option(None, "--open-above", help="Angle at which it opens (hysteresis)."),
    close_below: Optional[float] = typer.Option(None, "--close-below", help="Angle at which it closes (hysteresis)."),
    as_json: bool = typer.Option(False, "--json", help="Print the triplets with their sentences as JSON."),
):
    """Describe tracks in sentences: who enters, exits, moves where, merges, splits, walks together."""
    from artmotion.io import read_events, read_mot
    from artmotion.io.media import MAX_FPS, MIN_FPS
    from artmotion.io.mot import MAX_ID, MOT17_CLASSES, check_ids, mot17_people, mot_columns
    from artmotion.io.table import MAX_ANGLE
    from artmotion.language.describe import check_image_size, describe, parse_classes, read_pose

    if fps is not None:
        check_range("--fps", fps, MIN_FPS, MAX_FPS)
    for name, angle in (("--open-above", open_above), ("--close-below", close_below)):
        if angle is not None:
            check_range(name, angle, -MAX_ANGLE, MAX_ANGLE)
    if pose is not None and open_above is not None and close_below is not None and close_below > open_above:
        raise InputError(f"--close-below {close_below:g} is above --open-above {open_above:g}")
    if pose_track is not None:
        check_range("--pose-track", pose_track, -MAX_ID, MAX_ID, integer=True)
    rows = read_mot(results)
    every_id = set(rows[:, 1].astype(int).tolist()) if len(rows) else set()
    if len(rows) and mot_columns(results) == 9 and all(int(c) == c and c in MOT17_CLASSES for c in rows[:, 7]):
        # MOT16/17 ground truth (its classes 1-13 in column 8): occluders, reflections, ... are no people
        people = mot17_people(rows)
        typer.echo(f"{results}: MOT16/17 ground truth: {len(people)} of {len(rows)} rows described (pedestrians "
                   "with consider = 1)", err=True)
        rows = people
    if len(rows) and (rows[:, 1] == -1).any():   # before check_ids: detections repeat -1 within a frame
        raise InputError(f"id -1 on {int((rows[:, 1] == -1).sum())} rows: MOTChallenge's 'no identity' (detections, "
                         "not tracks): track them first (artmotion track)", path=results)
    check_ids(rows, "results", results)   # one box per track and frame (a second would be dropped unsaid)
    classes = parse_classes(cls)
    evs = read_events(events) if events is not None else None
    pose_seq = None
    if pose is not None:
        frames, angles, _col = read_pose(pose, pose_column)
        pose_seq = (frames, angles)
    if not len(rows) and pose_seq is None and not evs:
        raise InputError("no tracks to describe", path=results)
    if len(rows):  # the events and the posed track belong to these results (as a run writes them)
        ids, last = set(rows[:, 1].astype(int).tolist()), int(rows[:, 0].max())
        for n, ev in enumerate(evs or [], start=1):
            unknown = [t for t in ev.get("tracks", []) if t not in ids]
            if unknown:
                raise InputError(f"event {n} names track {unknown[0]}, which is not in {results}", path=events)
            if ev["frame"] > last + 1:
                raise InputError(f"event {n} is at frame {ev['frame']}, after the results end (frame {last})",
                                 path=events)
            if ev.get("end_frame", ev["frame"]) > last + 1:   # (a span told as lasting past the results)
                raise InputError(f"event {n} ends at frame {ev['end_frame']}, after the results end (frame {last})",
                                 path=events)
        if pose_track is not None and pose_track not in ids:
            raise InputError(f"--pose-track {pose_track}: no such track in the results", path=results)
        for k, name in classes[1].items():
            if k not in ids:
                left = " among the pedestrians described (it is left out: not one with consider = 1)" \
                    if k in every_id else " in the results"
                raise InputError(f"--class {k}={name}: no such track{left}", path=results)
        first = int(rows[:, 0].min())
        if pose_seq is not None and (pose_seq[0].min() < first or pose_seq[0].max() > last):
            raise InputError(f"pose frames {pose_seq[0].min()}-{pose_seq[0].max()} are not within the results' "
                             f"frames {first}-{last}", path=pose)
    image_size = _size(size)
    if image_size is not None:
        check_image_size(rows, image_size, path=results)
    triplets = describe(
        rows, evs, pose=pose_seq, classes=classes, pose_subject=pose_subject,
        pose_track=pose_track, open_above=open_above, close_below=close_below,
        image_size=image_size, fps=fps,
    )
    if as_json:
        typer.echo(json.dumps([t.to_dict() for t in triplets], indent=1))
    else:
        for t in triplets:
            typer.echo(t.sentence)


grounding_app = typer.Typer(
    help="Ground spoken colour and shape words in images (compositional sparse model).",
    no_args_is_help=True,
)


@grounding_app.command("dataset")
def grounding_dataset(
    out: Path = typer.Argument(..., help="Folder to create: images/, speech/, index.csv."),
    seed: int = typer.Option(0, "--seed", help="Random seed (same seed, same dataset)."),
):
    """Make the thesis's 156 shapes-and-colours examples: images and spoken '<colour> <shape>'."""
    from artmotion.language.grounding.dataset import make_dataset, read_index

    index = make_dataset(out, seed=seed)
    typer.echo(f"wrote {index.parent} ({len(read_index(index))} examples, index {index.name})")


@grounding_app.command("eval")
def grounding_eval(
    dataset: Path = typer.Argument(..., help="Folder made by 'artmotion grounding dataset', or its index CSV."),
    out: Optional[Path] = typer.Option(None, "--out", help="Folder for report.json and PNGs (default: eval in the "
                                       "dataset's folder)."),
    seed: int = typer.Option(0, "--seed", help="Random seed of folds and dictionary learning."),
    as_json: bool = typer.Option(False, "--json", help="Print the accuracies as JSON."),
):
    """Retrieval (3-fold CV) and unseen colour–shape pairs, compositional vs paired model."""
    from artmotion.io import check_writable
    from artmotion.language.grounding.evaluate import evaluate, format_report

    check_seed(seed)
    out = out if out is not None else (dataset if dataset.is_dir() else dataset.parent) / "eval"
    check_writable(out / "report.json")  # before the evaluation
    report = evaluate(dataset, out=out, seed=seed)
    if report.get("note"):
        typer.echo(f"note: {report['note']}", err=True)
    if as_json:
        brief = {m: {part: report[m][part] for part in ("retrieval", "unseen")} for m in ("compositional", "paired")}
        typer.echo(json.dumps(brief, indent=1))
    else:
        typer.echo(format_report(report))


def register(app: typer.Typer) -> None:
    """Add this capability's commands to the root artmotion app."""
    app.command("describe")(describe_cmd)
    app.add_typer(grounding_app, name="grounding")
