"""The offline pass: the duplicate test (offline.duplicates: one person detected twice) and
stitching across a gap (offline.stitch), with a still and with a panning camera."""

import numpy as np

from artmotion.tracking.camera import CameraPath
from artmotion.tracking.config import TrackerConfig
from artmotion.tracking.offline import duplicates, stitch
from artmotion.tracking.state import DETECTED, INTERPOLATED


def _walker(x0, vx, frames, w=40.0, h=120.0, y=100.0, score=0.9, dx=0.0, dy=0.0, jitter=0.0, seed=0):
    rng = np.random.default_rng(seed)
    return {f: [np.array([x0 + vx * f + dx + rng.normal(0, jitter), y + dy + rng.normal(0, jitter), w, h]), DETECTED, score]
            for f in frames}


def _upper_body(person: dict, score: float, frames) -> dict:
    """A box on the upper half of ``person``'s box, moving with it."""
    out = {}
    for f in frames:
        x, y, w, h = person[f][0]
        out[f] = [np.array([x + 0.1 * w, y + 0.02 * h, 0.8 * w, 0.5 * h]), DETECTED, score]
    return out


def test_upper_body_box_moving_with_the_person_is_dropped():
    person = _walker(10, 2.0, range(1, 61), jitter=0.5)
    pieces = {1: person, 2: _upper_body(person, 0.6, range(20, 41)), 3: _walker(400, -1.0, range(1, 61))}
    out = duplicates(pieces, share=0.2, drift=0.06)
    assert set(out) == {1, 3} and out[1] == person


def test_person_walking_behind_another_is_kept():
    """Nested in the nearer person's box for a while, but moving across it: two people."""
    near = _walker(100, 0.0, range(1, 61), w=60, h=180, y=60)
    far = _walker(90, 1.0, range(1, 61), w=30, h=90, y=80)       # crosses the near box
    out = duplicates({1: near, 2: far}, share=0.2, drift=0.06)
    assert set(out) == {1, 2}


def test_weaker_container_loses_the_shared_frames_only():
    """The detector's larger-scale second box (weaker) around a person: it loses the frames it
    shares with the person's own box; the person's track is whole."""
    person = _walker(200, 1.0, range(1, 81), score=0.9)
    big = {f: [person[f][0] + np.array([-15.0, -30.0, 30.0, 60.0]), DETECTED, 0.4] for f in range(1, 81)}
    big.update({f: [np.array([600.0, 100, 50, 150]), DETECTED, 0.4] for f in range(81, 91)})
    out = duplicates({1: person, 2: big}, share=0.2, drift=0.06)
    assert out[1] == person and sorted(out[2]) == list(range(81, 91))


def test_undetected_frames_count_as_no_support():
    """A container kept alive by interpolation has no detector support on those frames."""
    person = _walker(200, 1.0, range(1, 41), score=0.6)
    big = {f: [person[f][0] + np.array([-10.0, -20.0, 20.0, 40.0]), INTERPOLATED, 0.0] for f in range(1, 41)}
    big[1][1], big[1][2] = DETECTED, 0.99
    out = duplicates({1: person, 2: big}, share=0.2, drift=0.06)
    assert out[1] == person and 2 not in out


def test_rarely_nested_track_and_off_switch():
    person = _walker(10, 2.0, range(1, 101))
    brief = _upper_body(person, 0.5, range(1, 11))
    brief.update(_walker(600, 0.0, range(11, 101), score=0.5))    # nested on 10 % of its frames
    pieces = {1: person, 2: brief}
    assert set(duplicates(pieces, share=0.2, drift=0.06)) == {1, 2}
    assert duplicates(pieces, share=0.0, drift=0.06) is pieces
    assert TrackerConfig().duplicate_share > 0 and TrackerConfig.textbook().duplicate_share == 0


def test_partly_nested_weaker_track_loses_only_the_nested_frames():
    """Nested on a third of its frames: those go, the rest (a person of its own) stays."""
    person = _walker(10, 2.0, range(1, 101))
    other = _upper_body(person, 0.5, range(1, 31))
    other.update(_walker(600, 0.0, range(31, 91), score=0.5))
    out = duplicates({1: person, 2: other}, share=0.2, drift=0.06)
    assert out[1] == person and sorted(out[2]) == list(range(31, 91))


# --------------------------------------------------------------------------- stitching
HIST = np.full(8, 1 / 8)
STITCH = TrackerConfig(stitch=True, max_gap=2.0, stitch_dist=0.25, stitch_kl=1.5, max_interp=2.0)


def _stitch(pieces: dict, camera=None):
    return stitch(pieces, {i: HIST for i in pieces}, STITCH, fps=10.0, camera=camera)


def test_stitch_joins_a_walker_across_a_gap_and_fills_it_linearly():
    a, b = _walker(100, 4.0, range(1, 11)), _walker(100, 4.0, range(21, 31))
    far = _walker(400, 4.0, range(21, 31))
    out, relabel, _ = _stitch({1: a, 2: b, 3: far})
    assert relabel == {2: 1} and set(out) == {1, 3}
    assert sorted(out[1]) == list(range(1, 31))
    for f in range(11, 21):
        box, kind, _ = out[1][f]
        assert kind == INTERPOLATED
        np.testing.assert_allclose(box, [100 + 4.0 * f, 100, 40, 120], atol=1e-6)
    # switched off, nothing joins
    off, relabel, _ = stitch({1: a, 2: b}, {1: HIST, 2: HIST}, TrackerConfig(stitch=False), fps=10.0)
    assert relabel == {} and set(off) == {1, 2}


def test_stitch_takes_the_camera_motion_out_of_the_gap():
    """A person standing still while the camera pans 15 px/frame during the gap only: in the
    image they jump 150 px, which only the camera explains."""
    cam = CameraPath()
    pan = np.array([[1.0, 0.0, -15.0], [0.0, 1.0, 0.0]])
    for f in range(11, 21):
        cam.add(f, pan)
    a, b = _walker(300, 0.0, range(1, 11)), _walker(150, 0.0, range(21, 31))
    # without the camera's motion, a still person 150 px away is someone else
    _, relabel, _ = _stitch({1: a, 2: b})
    assert relabel == {}
    out, relabel, _ = _stitch({1: a, 2: b}, camera=cam)
    assert relabel == {2: 1}
    for f in range(11, 21):
        # the filled box stays on the person's spot in the world, which the camera moves
        np.testing.assert_allclose(out[1][f][0], [300 - 15.0 * (f - 10), 100, 40, 120], atol=1e-6)
    np.testing.assert_allclose(cam.from_ref(25, cam.to_ref(25, [5, 6, 7, 8])), [[5, 6, 7, 8]], atol=1e-9)


def test_camera_path_composes_the_steps_and_scales_the_boxes():
    """Two steps, a zoom by 2 about the origin then a shift: a box of frame 3 maps back to frame 1
    by undoing both; frames before the first step and between steps keep the last map."""
    cam = CameraPath()
    cam.add(2, np.array([[2.0, 0.0, 0.0], [0.0, 2.0, 0.0]]))
    cam.add(3, np.array([[1.0, 0.0, 10.0], [0.0, 1.0, -4.0]]))
    box = np.array([50.0, 60.0, 20.0, 40.0])          # centre (60, 80) in frame 3
    # undo the shift: centre (50, 84); undo the zoom: centre (25, 42), size (10, 20)
    np.testing.assert_allclose(cam.to_ref(3, box), [[20.0, 32.0, 10.0, 20.0]], atol=1e-9)
    np.testing.assert_allclose(cam.to_ref(1, box), [box], atol=1e-9)
    np.testing.assert_allclose(cam.to_ref(7, box), cam.to_ref(3, box), atol=1e-9)
    np.testing.assert_allclose(cam.from_ref(3, cam.to_ref(3, box)), [box], atol=1e-9)
    assert not CameraPath() and cam
