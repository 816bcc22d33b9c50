#!/usr/bin/env python
"""Run one peer tracker of the ``trackers`` package on one MOTChallenge sequence.

Runs in the peers' own environment (``make bench`` creates ``.venv-peers``: ``trackers`` pulls
``opencv-python``, which would replace the contrib ``cv2`` that artmotion needs), so it imports
nothing from artmotion: only NumPy, OpenCV and the peers.

    _peer_worker.py NAME SEQ_DIR DET_FILE OUT.txt [PARAMS_JSON]

NAME is ``sort``, ``bytetrack``, ``ocsort`` or ``botsort``; PARAMS_JSON, keyword arguments of the
tracker's constructor (e.g. ``{"track_activation_threshold": 0.5}``; default: its defaults). The
detections are fed as ``supervision.Detections`` (boxes and confidences, no detector model); scores outside [0, 1] are
replaced by their mid-rank, as artmotion does. Writes MOTChallenge rows and prints a JSON line
``{"frames", "seconds", "peak_bytes"}`` (seconds of the tracking loop, frame decoding included for
BoT-SORT, whose camera-motion compensation needs the images).
"""

from __future__ import annotations

import configparser
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

PEERS = {"sort": "SORTTracker", "bytetrack": "ByteTrackTracker", "ocsort": "OCSORTTracker",
         "botsort": "BoTSORTTracker"}


def _frames(seq: Path, length: int):
    import cv2

    videos = sorted(p for p in seq.iterdir() if p.suffix.lower() in (".mp4", ".avi", ".mkv", ".mov"))
    if (seq / "img1").is_dir():
        for p in sorted((seq / "img1").iterdir()):
            yield cv2.imread(str(p))
    elif videos:
        cap = cv2.VideoCapture(str(videos[0]))
        for _ in range(length):
            ok, img = cap.read()
            yield img if ok else None
        cap.release()


def main(name: str, seq: str, det: str, out: str, params: str = "{}") -> int:
    import supervision as sv
    import trackers

    seq_dir = Path(seq)
    ini = configparser.ConfigParser()
    ini.read(seq_dir / "seqinfo.ini")
    fps = float(ini["Sequence"]["frameRate"])
    length = int(ini["Sequence"]["seqLength"])
    d = np.loadtxt(det, delimiter=",", ndmin=2)
    s = d[:, 6]
    if len(s) and (s.min() < 0 or s.max() > 1):
        srt = np.sort(s)
        d[:, 6] = (np.searchsorted(srt, s, "left") + np.searchsorted(srt, s, "right")) / (2.0 * len(s))
    by_frame = {int(f): d[d[:, 0] == f] for f in np.unique(d[:, 0])}
    tracker = getattr(trackers, PEERS[name])(frame_rate=fps, **json.loads(params))
    images = _frames(seq_dir, length) if name == "botsort" else None
    rows = []
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter()
    for f in range(1, length + 1):
        img = next(images) if images is not None else None
        x = by_frame.get(f, np.zeros((0, 10)))
        xyxy = np.c_[x[:, 2], x[:, 3], x[:, 2] + x[:, 4], x[:, 3] + x[:, 5]].astype(np.float32).reshape(-1, 4)
        dets = sv.Detections(xyxy=xyxy, confidence=x[:, 6].astype(np.float32), class_id=np.zeros(len(x), int))
        t = tracker.update(dets, frame=img) if img is not None else tracker.update(dets)
        if len(t) == 0 or t.tracker_id is None:
            continue
        keep = t.tracker_id >= 0          # -1: not (yet) a confirmed track
        for (x1, y1, x2, y2), tid in zip(t.xyxy[keep], t.tracker_id[keep]):
            rows.append([f, int(tid) + 1, float(x1), float(y1), float(x2 - x1), float(y2 - y1), 1.0])
    seconds = time.perf_counter() - t0
    peak = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base) * 1024
    np.savetxt(out, np.array(rows, float).reshape(-1, 7), delimiter=",", fmt="%.3f")
    print(json.dumps({"frames": length, "seconds": seconds, "peak_bytes": peak}))
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:6]))
