"""Bad input to the search and video API (parse_query, analyze_video's snapshots) is an InputError
naming the parameter; valid input reads as before."""

import cv2
import numpy as np
import pytest

from artmotion.app import parse_query
from artmotion.articulation.video import analyze_video
from artmotion.errors import InputError


@pytest.mark.parametrize("query", [None, 3, b"person 3 exits", ["person", "exits"]])
def test_a_query_must_be_text(query):
    with pytest.raises(InputError, match="a query must be text"):
        parse_query(query)


def test_a_text_query_is_parsed_as_before():
    q = parse_query("Person 3 exits left at frame 40")
    assert (q.subject, q.track, q.verb, q.direction, q.frame) == ("person", 3, "exits", "left", 40)


@pytest.fixture
def frames(tmp_path):
    """Six still frames of a textured scene: nothing moves."""
    rng = np.random.default_rng(0)
    img = (rng.random((60, 80, 3)) * 255).astype(np.uint8)
    for i in range(6):
        cv2.imwrite(str(tmp_path / f"{i:04d}.png"), img)
    return tmp_path


@pytest.mark.parametrize("snapshots", [-1, 2.5, "4", None, float("nan"), 10**12])
def test_snapshots_must_be_a_whole_number_of_frames(frames, snapshots):
    with pytest.raises(InputError, match=r"snapshots must be a whole number in \[0, "):
        analyze_video(frames, snapshots=snapshots)


def test_snapshots_keep_frames_spread_over_the_video(frames):
    assert sorted(analyze_video(frames, snapshots=3).snapshots) == [0, 2, 5]
    assert sorted(analyze_video(frames, snapshots=3.0).snapshots) == [0, 2, 5]  # a whole float too
    assert analyze_video(frames).snapshots == {}
