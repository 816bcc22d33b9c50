"""One video → tracks, events, sentences, metrics and an HTML report (thesis 6.2.1).

:func:`run_pipeline` writes into a run folder::

    results.txt     tracks, MOTChallenge text
    events.jsonl    enter / exit / merge / split events
    sentences.txt   one sentence per line
    report.html     self-contained report (opens in a browser with no server)
    run.json        manifest, written last: its presence marks the run as finished

Every file is written atomically, so an interrupted run leaves no half-written output and a
batch can resume by skipping folders that hold a ``run.json``.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from artmotion import __version__
from artmotion.errors import InputError
from artmotion.io import atomic_write, write_events, write_mot

MANIFEST = "run.json"


@dataclass
class RunResult:
    out_dir: Path
    name: str
    tracks: np.ndarray
    events: list
    sentences: list
    metrics: dict | None
    seconds: float

    @property
    def report(self) -> Path:
        return self.out_dir / "report.html"

    @property
    def num_tracks(self) -> int:
        return int(len(np.unique(self.tracks[:, 1]))) if len(self.tracks) else 0


def track_summary(tracks: np.ndarray) -> list[dict]:
    """Per track id: first and last frame and number of boxes."""
    out = []
    for tid in np.unique(tracks[:, 1]).astype(int) if len(tracks) else []:
        frames = tracks[tracks[:, 1] == tid, 0]
        out.append({"id": int(tid), "first_frame": int(frames.min()), "last_frame": int(frames.max()),
                    "boxes": int(len(frames))})
    return out


def _flat(triplet, object_class: str) -> dict:
    return {"sentence": triplet.sentence, "subject": object_class, "verb": triplet.verb,
            "adjective": triplet.adjective, "object": triplet.object, "tracks": [int(i) for i in triplet.tracks],
            "frame_start": int(triplet.frames[0]), "frame_end": int(triplet.frames[1])}


def describe_run(tracks, events, width, height, fps, object_class: str = "person",
                 poses: dict[int, tuple[np.ndarray, np.ndarray]] | None = None) -> list[dict]:
    """Sentences of one run (:func:`artmotion.language.describe.describe`) as flat dicts for the
    index: ``sentence, subject`` (the class word), ``verb, adjective, object, tracks, frame_start,
    frame_end``. ``poses`` maps a track id to its (frames, opening angles) for "opens"/"closes"."""
    from artmotion.language.describe import describe

    triplets = list(describe(tracks, events, classes=(object_class, {}), image_size=(width, height), fps=fps))
    empty = np.empty((0, 10))
    for tid, pose in sorted((poses or {}).items()):
        triplets += describe(empty, [], pose=pose, pose_subject=object_class, pose_track=tid, fps=fps)
    triplets.sort(key=lambda t: (t.frames[0], t.frames[1]))
    return [_flat(t, object_class) for t in triplets]


def track_poses(seq, tracks: np.ndarray, model_path, column: str | None = None,
                min_boxes: int = 5) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Per track, the Kalman-filtered opening angle of a pose model over the track's box crops.

    The pose model (``artmotion pose train``) sees each box's crop; its GP means and variances are
    filtered in time (Eq. 3.6-3.7). ``column`` is the angle to describe, by default the first
    whose name contains "open".
    """
    from artmotion.pose.model import PoseRegressor

    model = PoseRegressor.load(model_path)
    names = model.names_ or []
    if column is None:
        column = next((n for n in names if "open" in n.lower()), None)
    if column not in names:
        raise InputError(f"the pose model has no opening-angle column (angles: {', '.join(names)})", path=model_path)
    k = names.index(column)
    crops: dict[int, list] = {}
    for fno, frame in seq.frames():
        for r in tracks[tracks[:, 0] == fno]:
            x0, y0 = max(int(r[2]), 0), max(int(r[3]), 0)
            x1, y1 = min(int(r[2] + r[4]), frame.shape[1]), min(int(r[3] + r[5]), frame.shape[0])
            if x1 - x0 >= 4 and y1 - y0 >= 4:
                crops.setdefault(int(r[1]), []).append((fno, frame[y0:y1, x0:x1].copy()))
    out = {}
    dt = 1.0 / float(seq.fps) if seq.fps else 1.0
    for tid, items in crops.items():
        if len(items) < min_boxes:
            continue
        mean, std = model.predict([c for _, c in items], return_std=True)
        mean, _ = model.make_filter(dt).filter(mean, std)
        out[tid] = (np.array([f for f, _ in items]), np.asarray(mean)[:, k])
    return out


def run_pipeline(
    source: str | os.PathLike,
    out_dir: str | os.PathLike | None = None,
    det: str | os.PathLike | None = None,
    object_class: str = "person",
    experts: tuple[str, ...] | None = None,
    progress: bool = False,
    video: bool = True,
    pose_model: str | os.PathLike | None = None,
) -> RunResult:
    """Track ``source``, describe it in sentences, score it if ground truth is present, report.

    With ``pose_model`` (from ``artmotion pose train``) every track's crops also go through the
    pose regressor, and the tool's opening and closing become sentences.
    """
    from artmotion.app.report import write_report
    from artmotion.tracking import evaluate, open_sequence, track

    t0 = time.perf_counter()
    seq = open_sequence(source)
    out = Path(out_dir) if out_dir is not None else Path("runs") / seq.name
    kwargs = {"det": det, "progress": progress}
    if experts is not None:
        kwargs["experts"] = experts
    if video:
        kwargs["video"] = out / "annotated.mp4"
    result = track(seq, **kwargs)  # the opened sequence: not probed a second time
    tracks = np.asarray(result.tracks, dtype=float).reshape(-1, 10)
    events = list(result.events)
    poses = track_poses(seq, tracks, pose_model) if pose_model is not None else None
    sentences = describe_run(tracks, events, seq.width, seq.height, seq.fps, object_class=object_class, poses=poses)
    metrics = None
    if seq.gt_path is not None and Path(seq.gt_path).is_file():
        metrics = {k: float(v) for k, v in evaluate(seq.gt_path, tracks).items()}

    write_mot(out / "results.txt", tracks)
    write_events(out / "events.jsonl", events)
    with atomic_write(out / "sentences.txt") as fh:
        fh.writelines(s["sentence"] + "\n" for s in sentences)
    manifest = {
        "artmotion": __version__,
        "name": seq.name,
        "source": str(Path(source).resolve()),
        "sequence": {"length": seq.length, "fps": seq.fps, "width": seq.width, "height": seq.height},
        "files": {"results": "results.txt", "events": "events.jsonl", "sentences": "sentences.txt",
                  "report": "report.html", **({"video": "annotated.mp4"} if video else {})},
        "track_summary": track_summary(tracks),
        "events": events,
        "sentences": sentences,
        "metrics": metrics,
        "tracking_fps": float(result.fps),
    }
    write_report(out / "report.html", seq, tracks, manifest)
    manifest["seconds"] = round(time.perf_counter() - t0, 3)
    with atomic_write(out / MANIFEST) as fh:
        json.dump(manifest, fh, indent=1)
    return RunResult(out, seq.name, tracks, events, sentences, metrics, manifest["seconds"])


def is_finished(run_dir: str | os.PathLike) -> bool:
    return (Path(run_dir) / MANIFEST).is_file()


def load_run(run_dir: str | os.PathLike) -> dict:
    """Read a run folder's manifest (raises :class:`InputError` if it is missing or corrupt)."""
    path = Path(run_dir) / MANIFEST
    if not path.is_file():
        raise InputError(f"not a finished artmotion run (no {MANIFEST})", path=run_dir)
    try:
        run = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise InputError(f"corrupt manifest: {exc}", path=path) from None
    for key in ("name", "track_summary", "events", "sentences"):
        if key not in run:
            raise InputError(f"manifest lacks {key!r}", path=path)
    return run
