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


def track_summary(tracks: np.ndarray) -> list[dict]:
    """Per track id: first and last frame and number of boxes."""
    out = []
    for tid in np.unique(tracks[:, 1]).astype(int) if len(tracks) else []:
        frames = tracks[tracks[:, 1] == tid, 0]
        out.append({"id": int(tid), "first_frame": int(frames.min()), "last_frame": int(frames.max()),
                    "boxes": int(len(frames))})
    return out


def describe_run(tracks, events, width, height, fps, object_class: str = "person") -> list[dict]:
    """Sentences of one run (:func:`artmotion.language.describe`) as flat dicts for the index:
    ``sentence, subject`` (the class word), ``verb, adjective, object, tracks, frame_start, frame_end``."""
    from artmotion.language.describe import describe

    out = []
    for t in describe(tracks, events, classes=(object_class, {}), image_size=(width, height), fps=fps):
        out.append({"sentence": t.sentence, "subject": object_class, "verb": t.verb, "adjective": t.adjective,
                    "object": t.object, "tracks": [int(i) for i in t.tracks],
                    "frame_start": int(t.frames[0]), "frame_end": int(t.frames[1])})
    return out


def run_pipeline(
    source: str | os.PathLike,
    out_dir: str | os.PathLike | None = None,
    det: str | os.PathLike | None = None,
    object_class: str = "person",
    experts: tuple[str, ...] | None = None,
    progress: bool = False,
    video: bool = True,
) -> RunResult:
    """Track ``source``, describe it in sentences, score it if ground truth is present, report."""
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
    result = track(source, **kwargs)
    tracks = np.asarray(result.tracks, dtype=float).reshape(-1, 10)
    events = list(result.events)
    sentences = describe_run(tracks, events, seq.width, seq.height, seq.fps, object_class=object_class)
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
        "tracking_fps": float(getattr(result, "fps", 0.0) or 0.0),
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
