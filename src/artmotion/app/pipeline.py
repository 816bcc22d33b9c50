"""One video → tracks, events, sentences, metrics and an HTML report (thesis 6.2.1).

:func:`run_pipeline` writes into a run folder::

    results.txt     tracks, MOTChallenge text
    events.jsonl    enter / exit / merge / split events
    sentences.txt   one sentence per line
    report.html     self-contained report (opens in a browser with no server)
    run.json        manifest, written last: its presence marks the run as finished

Every file is written atomically, so an interrupted run leaves no half-written output and a
batch can resume by skipping folders that hold a ``run.json``. The manifest repeats what
``results.txt``, ``events.jsonl`` and ``sentences.txt`` say (the index reads it) and records
their SHA-256 (``"sha256"``): :func:`check_run_files` tells a run whose files changed since.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import time
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from artmotion import __version__
from artmotion.errors import InputError, check_bool
from artmotion.io import atomic_dir, atomic_write, check_apart, read_mot, write_events, write_mot
from artmotion.io.atomic import check_out_dir, outputs_of
from artmotion.io.events import event_problem, read_events
from artmotion.io.files import as_path, read_text, strict_json
from artmotion.io.media import MAX_FPS, MIN_FPS, cv2_name
from artmotion.io.mot import MAX_COORD, MAX_FRAME, MAX_ID
from artmotion.tracking.config import DETECT_EVERY

MANIFEST = "run.json"
#: the files whose content the manifest repeats, with their SHA-256 in it (``"sha256"``)
CHECKED_FILES = ("results.txt", "events.jsonl", "sentences.txt")


@dataclass
class RunResult:
    out_dir: Path
    name: str
    tracks: np.ndarray
    events: list
    sentences: list
    metrics: dict | None
    seconds: float
    #: whether the pose model applied to the run's crops (:func:`track_poses`), if one ran
    pose: dict | None = None
    #: frames of the input
    frames: int = 0
    #: 16-bit image files: ``(bits, largest value)`` of frames spread over them (:attr:`Sequence.depth`)
    depth: tuple[int, int | None] | None = None
    #: the sequence's ground truth, when it has a file of it (``None``: none); no ``metrics`` with
    #: one means it held no box to score against (empty, or every box ignored)
    gt_path: Path | None = None
    #: where the detections came from, as the tracker says it (a file's name and what it held, or
    #: the detector's)
    detections: str = ""

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

    triplets = list(describe(tracks, events, classes=(object_class, {}), image_size=(width, height), fps=fps,
                             size_known=True))
    empty = np.empty((0, 10))
    for tid, pose in sorted((poses or {}).items()):
        triplets += describe(empty, [], pose=pose, pose_subject=object_class, pose_track=tid, fps=fps)
    triplets.sort(key=lambda t: (t.frames[0], t.frames[1]))
    return [_flat(t, object_class) for t in triplets]


def load_pose_model(model_path, column: str | None = None):
    """The pose model and the index of its opening angle (``column``, by default the first
    angle whose name contains "open"); loaded and checked before any long work."""
    from artmotion.pose.model import PoseRegressor, is_opening

    model = PoseRegressor.load(model_path)
    names = model.names_ or []
    if column is None:
        column = next((n for n in names if is_opening(n)), None)
    if column not in names:
        raise InputError(f"the pose model has no opening-angle column (angles: {', '.join(names)})", path=model_path)
    return model, names.index(column)


def track_poses(seq, tracks: np.ndarray, model, k: int, min_boxes: int = 5
                ) -> tuple[dict[int, tuple[np.ndarray, np.ndarray]], dict]:
    """Per track, the Kalman-smoothed opening angle (angle ``k`` of the pose ``model``, see
    :func:`load_pose_model`) over the track's box crops, where the model applies.

    The pose model (``artmotion pose train``) sees each box's crop; its GP means and variances are
    smoothed in time (Eq. 3.6-3.7, forward and back). First the crops of all tracks are compared with the model's
    training crops (:meth:`~artmotion.pose.model.PoseRegressor.domain_auc`): when they are
    another domain (a model trained on renders, a real video), nothing is said about the opening.
    Returns the angles and ``{"crops", "domain_auc", "judged", "applies", "far"}`` (not judged: too
    few crops to tell; the model is then applied; ``far``: the crops far from every training crop,
    whose angles are the model's prior, :meth:`~artmotion.pose.model.PoseRegressor.far_from_training`).
    """
    from artmotion.pose.features import box_views
    from artmotion.pose.model import is_foreign

    crops: dict[int, list] = {}
    size = None
    with closing(seq.frames()) as frames:
        for fno, frame in frames:
            for r in tracks[tracks[:, 0] == fno]:
                x0, y0 = max(int(r[2]), 0), max(int(r[3]), 0)
                x1, y1 = min(int(r[2] + r[4]), frame.shape[1]), min(int(r[3] + r[5]), frame.shape[0])
                if x1 - x0 >= 4 and y1 - y0 >= 4:
                    crops.setdefault(int(r[1]), []).append((fno, frame[y0:y1, x0:x1].copy(), (x0, y0, x1 - x0, y1 - y0)))
            size = (frame.shape[1], frame.shape[0])
    tids = sorted(crops)
    items = [it for tid in tids for it in crops[tid]]
    views = box_views([b for _, _, b in items], size) if model.uses_views_ and items else None
    # the crops' features once, for the domain test and the prediction
    X = model.features([c for _, c, _ in items]) if items else []
    auc = model.domain_auc(X, views)
    judged = not np.isnan(auc)
    info = {"crops": len(items), "domain_auc": round(auc, 3) if judged else None, "judged": judged,
            "applies": not is_foreign(auc)}
    out: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    if not info["applies"] or not items:
        return out, info
    # every track's crops in one call (the model batches them), then each track smoothed in time
    mean, std = model.predict(X, return_std=True, views=views)
    info["far"] = int(model.far_from_training(std).sum())   # crops whose angles are the model's prior
    start = 0
    for tid in tids:
        its, rows = crops[tid], slice(start, start + len(crops[tid]))
        start = rows.stop
        if len(its) >= min_boxes:
            # the whole video is there: smoothed, each frame from past and future ones. The
            # model's motion prior is per frame (not per second, as this took it before), and
            # the frames a track missed are steps without a measurement
            fnos = np.array([f for f, _, _ in its])
            m, _ = model.make_filter().smooth(mean[rows], std[rows], frames=fnos)
            out[tid] = (fnos, m[:, k])
    return out, info


def run_pipeline(
    source: str | os.PathLike,
    out_dir: str | os.PathLike | None = None,
    det: str | os.PathLike | None = None,
    object_class: str = "person",
    experts: tuple[str, ...] | None = None,
    progress: bool = False,
    video: bool = True,
    pose_model: str | os.PathLike | None = None,
    batch: str | None = None,
    detector: str = "auto",
    detect_every: int = DETECT_EVERY,
    tool_model: str | os.PathLike | None = None,
    fps: float | None = None,
    bits: int | None = None,
    also_writes: tuple[str | os.PathLike, ...] = (),
) -> RunResult:
    """Track ``source``, describe it in sentences, score it if ground truth is present, report.

    With ``pose_model`` (from ``artmotion pose train``) every track's crops also go through the
    pose regressor, and the tool's opening and closing become sentences. ``batch``: the id of the
    batch that runs it, kept in the manifest (a batch never runs an item twice). ``detector``:
    the built-in detector when ``source`` has no detections (``auto``, ``ssdlite``, ``hog``), run
    on every ``detect_every``-th frame. ``tool_model`` (from ``artmotion tool train``): track
    surgical instruments with it instead of people; their entries and exits come from the tracks.
    ``fps``: the frame rate, when the input does not say it (a folder of images; else 25 is
    assumed) or says it wrong. ``bits``: the bits 16-bit image frames hold, when frames spread
    over them said it wrong (:meth:`~artmotion.io.sequence.Sequence.set_bits`). ``also_writes``:
    files the caller writes besides the run folder (an index), kept out of the folder of frames
    read as the run folder is (checked before the work).
    """
    from artmotion.language.describe import parse_classes
    from artmotion.tracking import open_sequence

    check_bool("video", video)
    t0 = time.perf_counter()
    if not isinstance(object_class, str):
        raise InputError(f"object_class must be a class name (text), got {type(object_class).__name__}")
    word, per_track = parse_classes([object_class])   # the word the sentences name, checked as describe's
    if per_track:
        raise InputError(f"--class {object_class!r}: run takes one NAME for every track")
    object_class = word
    seq = open_sequence(source)
    seq.set_fps(fps)
    seq.set_bits(bits)
    # everything that can be checked is checked before the long work: the pose model (loaded and
    # tried on a crop), the ground truth
    pose = load_pose_model(pose_model) if pose_model is not None else None
    tools = None
    if tool_model is not None:
        from artmotion.tracking.instruments.detector import ToolDetector, check_frame_size

        tools = ToolDetector.load(tool_model)
        check_frame_size(seq.height, seq.width, path=seq.path, training=False)
    gt = read_mot(seq.gt_path) if seq.gt_path is not None else None
    rules = "auto"
    if gt is not None:
        from artmotion.tracking.metrics import check_ids, check_rules, columns_of

        check_ids(gt, "ground truth", seq.gt_path)  # before the tracking, naming the file
        rules = check_rules(gt, rules, columns_of(seq.gt_path), seq.gt_path)
        if seq.images is not None:      # (a video's length is known once it is read: _run_into)
            _check_gt_frames(gt, seq.length, seq.gt_path)
    fingerprint = source_fingerprint(seq)
    inputs = input_digest(seq, det)
    out = Path(out_dir) if out_dir is not None else default_run_dir(seq, fingerprint)
    for path in (out, *also_writes):
        check_apart(path, (seq.folder,))
    if video:   # (annotated.mp4 in the folder of a sequence's single video makes it unreadable)
        check_apart(out, (seq.video_home,))
    check_out_dir(out, replace=_is_run, outputs=RUN_FILES)    # before the work, not after it
    if video:
        cv2_name(out)       # (OpenCV writes annotated.mp4 in it)
    # a new run folder (or a new run replacing an earlier one) appears only when it is complete
    with atomic_dir(out, replace=_is_run, outputs=RUN_FILES) as dst:
        if tools is not None:
            manifest, tracks = _run_tools_into(dst, seq, source, fingerprint, tools, object_class, progress, video,
                                               pose)
        else:
            detection = {"det": det, "detector": detector, "detect_every": detect_every}
            manifest, tracks = _run_into(dst, seq, source, fingerprint, detection, object_class, experts, progress,
                                         video, pose, gt, rules)
        manifest["inputs"] = inputs
        manifest["seconds"] = round(time.perf_counter() - t0, 3)
        if batch is not None:
            manifest["batch"] = batch
        manifest["manifest_sha256"] = manifest_digest(manifest)
        with atomic_write(dst / MANIFEST) as fh:
            json.dump(manifest, fh, indent=1, allow_nan=False)
    return RunResult(out, seq.name, tracks, manifest["events"], manifest["sentences"], manifest["metrics"],
                     manifest["seconds"], manifest.get("pose"), seq.length, seq.depth, seq.gt_path,
                     manifest.get("detections") or "")


#: the files of a run folder
RUN_FILES = frozenset({MANIFEST, "results.txt", "events.jsonl", "sentences.txt", "report.html", "annotated.mp4"})


#: whether a folder holds an earlier run and nothing else (a new run then replaces it whole)
_is_run = outputs_of(MANIFEST, RUN_FILES, ("files", "sentences"))


def _check_gt_frames(gt: np.ndarray, frames: int, path) -> None:
    """Ground truth of frames the sequence has, else an :class:`InputError` naming its file (boxes
    of a frame beyond the sequence were scored as missed: the metrics moved without a word; the
    detections are checked alike)."""
    if len(gt) and gt[:, 0].max() > frames:
        raise InputError(f"ground truth for frame {int(gt[:, 0].max())} but the sequence has {frames} frames", path=path)


def _run_into(out: Path, seq, source, fingerprint: str, detection: dict, object_class: str, experts,
              progress: bool, video: bool, pose, gt, rules: str = "auto") -> tuple[dict, np.ndarray]:
    """Track, describe, score and report ``seq`` into the folder ``out``; return the manifest (not
    written yet) and the tracks. ``detection``: :func:`~artmotion.tracking.track`'s ``det``,
    ``detector`` and ``detect_every``."""
    from artmotion.tracking import evaluate, track

    kwargs: dict = {**detection, "progress": progress}
    if object_class != "person":
        # The defaults were chosen on people (docs/tracking.md); an object whose motion they were
        # not chosen on (a tool's box grows and shrinks fast) gets data-independent settings and
        # noise levels estimated from its own detections.
        from artmotion.tracking import TrackerConfig

        kwargs["config"] = TrackerConfig.textbook(adapt_noise=True)
    if experts is not None:
        kwargs["experts"] = experts
    if video:
        kwargs["video"] = out / "annotated.mp4"
    result = track(seq, **kwargs)  # the opened sequence: not probed a second time
    tracks = np.asarray(result.tracks, dtype=float).reshape(-1, 10)
    events = list(result.events)
    poses, pose_info = track_poses(seq, tracks, *pose) if pose is not None else (None, None)
    sentences = describe_run(tracks, events, seq.width, seq.height, seq.fps, object_class=object_class, poses=poses)
    metrics = None
    if gt is not None and len(gt):
        if seq.images is None:      # (a folder of images was checked before the work)
            _check_gt_frames(gt, result.frames, seq.gt_path)
        scores = evaluate(gt, tracks, rules=rules)
        # ground truth whose boxes are all ignored (distractors, conf 0) is no ground truth
        metrics = {k: float(v) for k, v in scores.items()} if scores["GT_DETS"] else None

    return _write_run(out, seq, source, fingerprint, tracks, events, sentences, metrics, result.detector,
                      float(result.fps), video, pose_info), tracks


def _write_run(out: Path, seq, source, fingerprint: str, tracks: np.ndarray, events: list, sentences: list,
               metrics, detections, fps: float, video: bool, pose_info: dict | None = None) -> dict:
    """Write a run's files (all but the manifest) into ``out``; return the manifest. ``pose_info``:
    whether the pose model applied to the run's crops (:func:`track_poses`), if one ran."""
    from artmotion.app.report import write_report

    write_mot(out / "results.txt", tracks)
    write_events(out / "events.jsonl", events)
    with atomic_write(out / "sentences.txt") as fh:
        fh.writelines(s["sentence"] + "\n" for s in sentences)
    manifest = {
        "artmotion": __version__,
        "name": seq.name,
        "source": str(Path(source).resolve()),
        "fingerprint": fingerprint,
        "sequence": {"length": seq.length, "fps": seq.fps, "width": seq.width, "height": seq.height,
                     "bits": frame_bits(seq)},
        "files": {"results": "results.txt", "events": "events.jsonl", "sentences": "sentences.txt",
                  "report": "report.html", **({"video": "annotated.mp4"} if video else {})},
        "detections": detections,
        "track_summary": track_summary(tracks),
        "events": events,
        "sentences": sentences,
        "metrics": metrics,
        "tracking_fps": fps,
        **({"pose": pose_info} if pose_info is not None else {}),
        "sha256": {name: _sha256(out / name) for name in CHECKED_FILES},
    }
    write_report(out / "report.html", seq, tracks, manifest)
    return manifest


def _run_tools_into(out: Path, seq, source, fingerprint: str, tools, object_class: str, progress: bool,
                    video: bool, pose) -> tuple[dict, np.ndarray]:
    """:func:`_run_into` for surgical instruments: the tool tracker's heads as tracks (a square of
    the head's size), entries and exits from the tracks, opening and closing from the heads' crops
    where the pose model applies."""
    from artmotion.language.describe import events_from_tracks
    from artmotion.tracking.instruments.track import to_mot, track_sequence
    from artmotion.tracking.video import write_annotated

    t0 = time.perf_counter()
    tracks = to_mot(list(track_sequence(seq, tools, progress)))
    fps = len(seq) / max(time.perf_counter() - t0, 1e-9)
    events = events_from_tracks(tracks, (seq.width, seq.height))
    if video:
        write_annotated(out / "annotated.mp4", seq.frames(), tracks, seq.fps, (seq.width, seq.height), events=events)
    subject = "tool" if object_class == "person" else object_class
    poses, pose_info = track_poses(seq, tracks, *pose) if pose is not None else (None, None)
    sentences = describe_run(tracks, events, seq.width, seq.height, seq.fps, object_class=subject, poses=poses)
    manifest = _write_run(out, seq, source, fingerprint, tracks, events, sentences, None, "tool model", fps, video,
                          pose_info)
    return manifest, tracks


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def check_run_files(run_dir: str | os.PathLike, run: dict) -> None:
    """An :class:`InputError` naming the first file of the run folder whose content is not what its
    manifest ``run`` (:func:`load_run`) records (a ``results.txt`` truncated, a ``sentences.txt``
    cut since the run): the manifest's tracks, events and sentences would no longer be the run's.
    A manifest written before the SHA-256 were recorded is taken as it is."""
    for name, digest in sorted((run.get("sha256") or {}).items()):
        path = Path(run_dir) / name
        try:
            same = _sha256(path) == digest
        except FileNotFoundError:
            same = False
        except OSError as exc:
            raise InputError(f"cannot read {name}: {exc.strerror or exc}", path=run_dir) from None
        if not same:
            raise InputError(f"changed since the run: {name}{'' if path.exists() else ' (missing)'}; run it again",
                             path=run_dir)
    # the manifest's own copy of the run: its digest (what the sentences' tracks, frames and verbs
    # are, which no other file holds), and what it says the files hold, whenever they are there
    # (a manifest edited with its digests taken out said what it liked)
    changed = "manifest_sha256" in run and manifest_digest(run) != run["manifest_sha256"]
    folder = Path(run_dir)
    if not changed and all((folder / name).is_file() for name in CHECKED_FILES):
        try:
            changed = (read_text(folder / "sentences.txt", "a run's sentences file").splitlines()
                       != [s["sentence"] for s in run["sentences"]]
                       or read_events(folder / "events.jsonl") != run["events"]
                       or track_summary(read_mot(folder / "results.txt")) != run["track_summary"])
        except InputError:
            changed = True
    if changed:
        raise InputError(f"changed since the run: {MANIFEST} (it is not what the run wrote, or not what its files "
                         "hold); run it again", path=run_dir)


def manifest_digest(run: dict) -> str:
    """SHA-256 of a manifest's content (its ``manifest_sha256`` left out), as canonical JSON:
    what :func:`check_run_files` compares with the digest the run recorded."""
    body = {k: v for k, v in run.items() if k != "manifest_sha256"}
    body = json.loads(json.dumps(body, allow_nan=False))    # (as read back: tuples lists, number keys text)
    text = json.dumps(body, sort_keys=True, ensure_ascii=False, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()


def is_finished(run_dir: str | os.PathLike, source: str | os.PathLike | None = None, run: dict | None = None) -> bool:
    """``run_dir`` holds a finished run: a manifest as :func:`run_pipeline` writes it, not merely
    a file called run.json (the user's own, or an empty one). With ``source``: a finished run of
    that input as it is now (the manifest names its path and its :func:`source_fingerprint`), not
    of another video of the same name nor of a recording since replaced by a new one; nor a run
    whose files changed since (:func:`check_run_files`: it is run again). ``run``: the folder's
    manifest, if already read (:func:`load_run`)."""
    try:
        if run is None:
            run = load_run(run_dir)
        check_run_files(run_dir, run)
    except InputError:
        return False
    if source is None:
        return True
    if run.get("source") != str(Path(source).resolve()):
        return False
    from artmotion.tracking import open_sequence

    try:
        seq = open_sequence(source)
        fingerprint = source_fingerprint(seq)
        inputs = input_digest(seq)
    except (InputError, OSError):       # unreadable now: not finished (running it again says why)
        return False
    # a manifest that does not say the depth may be of a run that read 16-bit frames by their top 8
    # bits (12-bit ones nearly black): it is run again unless the frames are read that way now
    was = (run.get("sequence") or {}).get("bits")
    same_depth = seq.bits is None if was is None else was == frame_bits(seq)
    # (a manifest without the digest, of a run before it was kept, is run again)
    return run.get("fingerprint") == fingerprint and run.get("inputs") == inputs and same_depth


def frame_bits(seq) -> int:
    """The bits per sample the sequence's frames are read at (its :attr:`depth`): 8, 16 for 16-bit
    frames read by their top 8 bits, as OpenCV reads them, or fewer for those scaled from their
    range (12-bit values in 16-bit files)."""
    return seq.depth[0] if seq.depth is not None else 8


def load_run(run_dir: str | os.PathLike) -> dict:
    """Read a run folder's manifest; an :class:`InputError` naming it when it is missing, not
    JSON, or its fields are not what :func:`run_pipeline` writes (types checked)."""
    path = as_path(run_dir, "a run folder") / MANIFEST
    if not path.is_file():
        raise InputError(f"not a finished artmotion run (no {MANIFEST})", path=run_dir)
    try:
        run = strict_json(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:    # (NaN, a key twice: strict_json)
        raise InputError(f"corrupt manifest: {exc}", path=path) from None
    except RecursionError:
        raise InputError("corrupt manifest: nested too deeply", path=path) from None
    check_manifest(run, path)
    return run


def check_manifest(run, path: str | os.PathLike) -> None:
    """An :class:`InputError` naming ``path`` unless ``run`` is a manifest of the kind
    :func:`run_pipeline` writes (types, ranges, consistency: :func:`_manifest_problem`)."""
    problem = _manifest_problem(run)
    if problem:
        raise InputError(f"corrupt manifest: {problem}", path=path)


def _is_int(v, lo: int = -MAX_ID, hi: int = MAX_ID) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and lo <= v <= hi


def _is_frame(v) -> bool:
    return _is_int(v, 1, MAX_FRAME)


def _int_list(v) -> bool:
    return isinstance(v, list) and all(_is_int(x) for x in v)


def _is_number(v, lo: float, hi: float) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and lo <= v <= hi


def _manifest_problem(run) -> str | None:
    """What in a manifest is not of the right type or range, or ``None``. Events are checked by
    :func:`artmotion.io.events.event_problem`, as in an events file."""
    if not isinstance(run, dict):
        return "not a JSON object"
    for key in ("name", "track_summary", "events", "sentences"):
        if key not in run:
            return f"no {key!r}"
    if not isinstance(run["name"], str) or not run["name"]:
        return "'name' is not a non-empty string"
    for key in ("source", "fingerprint", "inputs", "batch", "detections"):
        if key in run and run[key] is not None and not isinstance(run[key], str):
            return f"{key!r} is not a string"
    if "source" in run and not run["source"]:    # (older manifests have none; no run writes it empty or null)
        return "'source' is empty"
    digests = run.get("sha256")
    if digests is not None and not (isinstance(digests, dict) and sorted(digests) == sorted(CHECKED_FILES) and all(
            isinstance(d, str) and len(d) == 64 for d in digests.values())):
        return f"'sha256' is not an object of the SHA-256 digests of {', '.join(CHECKED_FILES)}"
    own = run.get("manifest_sha256")
    if own is not None and not (isinstance(own, str) and re.fullmatch(r"[0-9a-f]{64}", own)):
        return "'manifest_sha256' is not a SHA-256 digest"
    for key in ("tracking_fps", "seconds"):
        if run.get(key) is not None and not _is_number(run[key], 0.0, 1e300):
            return f"{key!r} is not a finite number >= 0"
    seq = run.get("sequence", {})
    counts = {"length": (1, MAX_FRAME), "width": (1, int(MAX_COORD)), "height": (1, int(MAX_COORD)), "bits": (1, 16)}
    if not isinstance(seq, dict) or any(seq.get(k) is not None and not _is_int(seq[k], *r) for k, r in counts.items()) \
            or seq.get("fps") is not None and not _is_number(seq["fps"], MIN_FPS, MAX_FPS):
        return ("'sequence' is not an object of numbers in range (whole numbers: length in [1, 10000000], width "
                "and height in [1, 1e6], bits in [1, 16]; fps in [0.001, 1000])")
    if not isinstance(run["track_summary"], list) or not all(
            isinstance(t, dict) and _is_int(t.get("id")) and all(_is_frame(t.get(k)) for k in ("first_frame", "last_frame"))
            and _is_int(t.get("boxes"), 0, MAX_FRAME) for t in run["track_summary"]):
        return "'track_summary' is not a list of tracks (integer id, first_frame, last_frame, boxes; in range)"
    if not isinstance(run["events"], list):
        return "'events' is not a list of events"
    for k, ev in enumerate(run["events"]):
        problem = event_problem(ev)
        if problem is not None:
            return f"'events' item {k + 1}: {problem}"
    if not isinstance(run["sentences"], list) or not all(
            isinstance(x, dict) and isinstance(x.get("sentence"), str) and len(x["sentence"].splitlines()) == 1
            and _int_list(x.get("tracks", []))
            and all(x.get(k) is None or _is_frame(x.get(k)) for k in ("frame_start", "frame_end"))
            and all(x.get(k) is None or isinstance(x.get(k), str) for k in ("subject", "verb", "adjective"))
            for x in run["sentences"]):
        return "'sentences' is not a list of sentences (one line of text, track ids, integer frames; in range)"
    metrics = run.get("metrics")
    if metrics is not None and not (isinstance(metrics, dict) and all(
            _is_number(v, -1e300, 1e300) for v in metrics.values())):
        return "'metrics' is not an object of finite numbers"
    return _consistency_problem(run)


def _consistency_problem(run: dict) -> str | None:
    """What in a manifest of the right types contradicts itself, or ``None``: a track id twice, a
    track that ends before it begins, has more boxes than frames or ends after the sequence, a
    sentence that ends before it begins or after the sequence, an event or sentence naming a track that is not there,
    text that is not Unicode (a lone surrogate, which SQLite cannot store)."""
    length = run.get("sequence", {}).get("length")
    ids: set[int] = set()
    for t in run["track_summary"]:
        i, first, last = t["id"], t["first_frame"], t["last_frame"]
        if i in ids:
            return f"'track_summary': track {i} twice"
        ids.add(i)
        if first > last or t["boxes"] > last - first + 1:
            return f"'track_summary': track {i} has {t['boxes']} boxes in frames {first}-{last}"
        if length is not None and last > length:
            return f"'track_summary': track {i} ends at frame {last}, after the sequence's {length} frames"
    for what, items in (("events", run["events"]), ("sentences", run["sentences"])):
        for k, x in enumerate(items, start=1):
            unknown = [i for i in x.get("tracks", []) if i not in ids]
            if unknown:
                return f"'{what}' item {k} names track {unknown[0]}, which is not in 'track_summary'"
            if what == "sentences" and None not in (x.get("frame_start"), x.get("frame_end")) \
                    and x["frame_start"] > x["frame_end"]:
                return f"'sentences' item {k} ends (frame {x['frame_end']}) before it begins ({x['frame_start']})"
            if what == "sentences" and length is not None and max(x.get("frame_start") or 0, x.get("frame_end") or 0) > length:
                return f"'sentences' item {k} goes past the sequence's {length} frames"
    try:
        json.dumps(run, ensure_ascii=False).encode("utf-8")
    except UnicodeEncodeError:
        return "text that is not Unicode (a lone surrogate)"
    return None


def source_fingerprint(seq) -> str:
    """A fingerprint of a sequence's content (not its name or place): SHA-256 over the size and
    the first and last MiB of a video, or over the names and sizes of an image folder's frames and
    its first frame's bytes; cheap for any length."""
    h = hashlib.sha256()
    files = [seq.video] if seq.video is not None else list(seq.images)
    for p in files:
        h.update(f"{p.name}:{p.stat().st_size};".encode())
    with open(files[0], "rb") as fh:
        h.update(fh.read(1 << 20))
        if seq.video is not None and files[0].stat().st_size > 2 << 20:
            fh.seek(-(1 << 20), os.SEEK_END)
            h.update(fh.read())
    return h.hexdigest()[:16]


def input_digest(seq, det=None) -> str:
    """A digest of what a run reads besides the frames: the sequence's ``seqinfo.ini``, its
    detections (``det``, else the sequence's ``det/det.txt``) and ground truth, their sizes and
    whole contents (they are small). With :func:`source_fingerprint` it tells :func:`is_finished` that
    a run is of its input as it is now: new detections or another frame rate in ``seqinfo.ini``
    are run again (they were skipped as "already finished", the run's results stale)."""
    h = hashlib.sha256()
    folder = Path(seq.path)
    for what, p in (("seqinfo", folder / "seqinfo.ini" if folder.is_dir() else None),
                    ("det", Path(det) if det is not None else seq.det_path), ("gt", seq.gt_path)):
        if p is not None and Path(p).is_file():
            data = Path(p).read_bytes()
            h.update(f"{what}:{len(data)};".encode())
            h.update(data)
    return h.hexdigest()[:16]


def _folder_name(name: str, fallback: str) -> str:
    """``name`` if it is one plain path component (a sequence's name comes from its
    ``seqinfo.ini``, which must not choose where outputs land: ``../x``, ``/x``, ``.`` or nothing
    would put them outside ``runs/`` or make ``runs/`` itself the run); else ``fallback``."""
    seps = {os.sep, os.altsep or os.sep, "/"}
    if name in ("", ".", "..") or "\0" in name or any(c in name for c in seps):
        return fallback
    return name


def default_run_dir(seq, fingerprint: str, root: str | os.PathLike = "runs") -> Path:
    """``runs/NAME``, unless it holds the run of another source (another video called the same,
    e.g. every day's ``cam1.mp4``): then ``runs/NAME-<key>``, the key a hash of the source's path
    and its content's fingerprint, so no run replaces another's (the fingerprint alone put copies
    of one video at two paths in one folder, the second run replacing the first). A name that is
    not one plain path component (:func:`_folder_name`) gives way to the source's own file or
    folder name."""
    own = Path(seq.path).resolve()
    name = _folder_name(seq.name, _folder_name(own.stem if own.is_file() else own.name, "run"))
    out = Path(root) / name
    try:
        prev = json.loads((out / MANIFEST).read_text(encoding="utf-8")) if (out / MANIFEST).is_file() else None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        prev = None
    same = prev is None or (prev.get("fingerprint") == fingerprint and prev.get("source") == str(own))
    key = hashlib.sha256(f"{own}\0{fingerprint}".encode("utf-8", "surrogateescape")).hexdigest()
    return out if same else Path(root) / f"{name}-{key[:8]}"
