"""The annotated video for every frame size and rate artmotion reads."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from artmotion.tracking.video import MAX_VIDEO_SIDE, write_annotated


@pytest.mark.parametrize("size, fps", [((1, 40), 25.0), ((40, 1), 25.0), ((9000, 60), 25.0), ((64, 48), 0.001),
                                       ((64, 48), 0.5)])
def test_the_annotated_video_is_written_for_any_size_and_rate(tmp_path, size, fps):
    """A side of 1 pixel, a side over 8191 (MPEG-4 Part 2's limit) and a frame rate of 0.001 (the
    least artmotion reads) each failed: "cannot open a video writer (mp4v)", after the tracking."""
    w, h = size
    frames = [(k, np.full((h, w, 3), 40 * k, np.uint8)) for k in range(1, 4)]
    rows = np.array([[k, 1, 0, 0, max(1, w // 2), max(1, h // 2), 1, -1, -1, -1] for k in range(1, 4)], dtype=float)
    out = tmp_path / "a.mp4"
    write_annotated(out, frames, rows, fps, (w, h))
    cap = cv2.VideoCapture(str(out))
    if fps >= 0.01:             # (a rate the codec takes is kept: the video's times are the frames')
        assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(fps, rel=1e-3)
    got = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        got.append(img.shape)
    cap.release()
    assert len(got) == 3
    assert max(got[0][:2]) <= MAX_VIDEO_SIDE and min(got[0][:2]) >= 2
