"""Articulation from video (artmotion articulation video): synthetic parts, errors, outputs."""

import json
import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from artmotion.articulation.synthetic import part_video
from artmotion.articulation.video import analyze_video
from artmotion.articulation.video.joint import TEMPERATURE, classify_part, plane_rectifier
from artmotion.articulation.video.segment import chain_affines, factorise_motion, moving_tracks, noise_level
from artmotion.articulation.video.tracks import PointTracks, point_tracks
from artmotion.errors import InputError
from artmotion.geometry.affine import apply
from artmotion.io.sequence import open_sequence


def test_turning_part_is_revolute_about_its_pivot(tmp_path):
    v = part_video(tmp_path / "turn.avi", "revolute", pivot=(110, 120))
    res = analyze_video(v)
    assert res.camera == "static"
    assert res.model == "revolute", res.to_dict()
    ax = res.parts[0]["axis"]
    assert ax["towards_camera"]
    assert np.hypot(ax["point"][0] - 110, ax["point"][1] - 120) < 12
    assert 45 < res.parts[0]["range"]["degrees"] < 75


def test_sliding_part_is_prismatic_along_its_direction(tmp_path):
    v = part_video(tmp_path / "slide.avi", "prismatic", direction=(1.0, 0.3))
    res = analyze_video(v)
    assert res.model == "prismatic", res.to_dict()
    d = np.asarray(res.parts[0]["axis"]["direction"])
    cos = abs(d[:2] @ np.array([1.0, 0.3])) / (np.linalg.norm(d[:2]) * math.hypot(1.0, 0.3))
    assert cos > math.cos(math.radians(15))
    assert 60 < res.parts[0]["range"]["pixels"] < 100


def test_lid_on_a_hinge_in_the_image_plane_is_revolute_about_a_horizontal_axis(tmp_path):
    """A lid facing the camera tilts away about its bottom edge (perspective rendering): its points
    move along image lines, foreshortened in proportion to their distance from the hinge."""
    res = analyze_video(part_video(tmp_path / "lid.avi", "hinge", amount=60))
    assert res.model == "revolute", res.to_dict()
    ax = res.parts[0]["axis"]
    assert not ax["towards_camera"]
    assert abs(ax["direction"][0]) > math.cos(math.radians(15))
    assert 30 < res.parts[0]["range"]["degrees"] < 90


def test_drawer_pulled_towards_the_camera_is_prismatic_along_the_line_of_sight(tmp_path):
    res = analyze_video(part_video(tmp_path / "drawer.avi", "depth", amount=0.3))
    assert res.model == "prismatic", res.to_dict()
    assert abs(res.parts[0]["axis"]["direction"][2]) > math.cos(math.radians(15))


def test_a_handle_tip_turning_about_a_far_pivot_is_revolute(tmp_path):
    """The markers at the tip of a long handle (pliers): their paths are nearly straight (25° at
    200 px), the joint still revolute, its axis towards the camera."""
    res = analyze_video(part_video(tmp_path / "swing.avi", "swing"))
    assert res.model == "revolute", res.to_dict()
    assert res.parts[0]["axis"]["towards_camera"]


def test_a_ball_spinning_about_its_axis_is_revolute(tmp_path):
    """A rigid part that is not flat: a textured ball spinning 90° about its leaning axis, its
    points passing behind it. The part named lies on the ball and turns. (Its axis is not
    asserted: the parts are patches of the ball, each lifted as if flat; docs/articulation_video.md.)"""
    res = analyze_video(part_video(tmp_path / "globe.avi", "globe", seed=1))
    assert res.model == "revolute" and res.confidence > 0.7
    x, y = res.tracks.start[res.found[0].tracks].T
    assert np.mean(np.hypot(x - 110.0, y - 120.0) < 70.0) > 0.8


def test_a_video_tracks_samples_count_at_temperature_one(tmp_path):
    """A KLT track's samples are scored as their effectively independent count (Algorithm 1's
    temperature 1, not the logs' 0.25, under which a near-straight arc's evidence shrank to a near
    tie): the far-pivot turn's prismatic alternative falls at least a hundredfold."""
    res = analyze_video(part_video(tmp_path / "swing.avi", "swing", seed=1))
    hot = classify_part(res.tracks, res.found[0])
    cold = classify_part(res.tracks, res.found[0], temperature=0.25)
    assert TEMPERATURE == 1.0 and hot["model"] == cold["model"] == "revolute"
    assert hot["probabilities"]["prismatic"] < 0.01 * cold["probabilities"]["prismatic"], (hot, cold)


def test_exposure_step_darkens_the_second_half_and_a_turn_stays_revolute(tmp_path):
    v = part_video(tmp_path / "dark.avi", "revolute", exposure=True, frames=60)
    means = [float(img.mean()) for _, img in open_sequence(v).frames()]
    assert np.mean(means[32:]) < 0.85 * np.mean(means[:28])
    assert analyze_video(v).model == "revolute"


def test_video_without_motion_is_static_with_low_confidence(tmp_path):
    res = analyze_video(part_video(tmp_path / "still.avi", "static"))
    assert res.model == "static" and res.parts == [] and res.confidence <= 0.5


def test_plane_rectifier_recovers_a_slanted_plane():
    K = np.array([[1.0, 0.0], [0.4, 0.5]])
    K /= math.sqrt(np.linalg.det(K))
    L = [K @ np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]) @ np.linalg.inv(K)
         for a in np.linspace(0.0, 0.8, 12)]
    Kh = plane_rectifier(np.asarray(L))
    assert Kh is not None
    R = np.linalg.inv(Kh) @ L[-1] @ Kh
    assert np.allclose(R @ R.T, np.eye(2), atol=1e-6)
    # a hinge in the image plane (foreshortening along one axis) has no invariant ellipse
    assert plane_rectifier(np.asarray([np.diag([1.0, c]) for c in np.linspace(1.0, 0.3, 10)])) is None


@pytest.mark.parametrize("similarity", [False, True])
def test_factorised_motion_does_not_drift(similarity):
    """A rigid part turning and growing over 300 frames, its 30 tracks seen in stretches, 0.3 px of
    noise: the factorised maps stay within 1.5 px of the truth at every frame, the chained ones
    drift (each step's error adds up)."""
    rng = np.random.default_rng(3)
    F, n = 300, 30
    X = rng.uniform(-40, 40, (n, 2)) + [300, 200]
    a = np.linspace(0.0, 0.9, F)
    s = np.linspace(1.0, 1.3, F)
    L = s[:, None, None] * np.stack([np.stack([np.cos(a), -np.sin(a)], -1), np.stack([np.sin(a), np.cos(a)], -1)], 1)
    t = np.stack([np.linspace(0, 80, F), np.linspace(0, -30, F)], -1)
    A = np.concatenate([L, (t - np.einsum("fij,j->fi", L, [300, 200]) + [300, 200])[:, :, None]], axis=2)
    xy = apply(A[:, None], X[None]) + rng.normal(0, 0.3, (F, n, 2))
    for i in range(n):  # each track lost for a stretch
        k = rng.integers(0, F - 60)
        xy[k:k + rng.integers(10, 60), i] = np.nan
    idx = np.arange(n)
    truth = apply(A[:, None], X[None])

    def worst(M):
        return float(np.nanmax(np.linalg.norm(apply(M[:, None], X[None]) - truth, axis=2)))

    Mf, seg, rss, count = factorise_motion(xy, idx, similarity=similarity)
    Mc, *_ = chain_affines(xy, idx, similarity=similarity)
    assert (seg == 0).all() and count == 2 * int((~np.isnan(xy[:, :, 0])).sum())
    assert rss / count < 0.3**2 * 1.5
    assert worst(Mf) < 1.5
    assert worst(Mc) > 2 * worst(Mf)


def test_factorised_motion_down_weights_a_dragged_track():
    """Two of 12 tracks dragged 25 px off their points for 40 frames (an occluding hand): with the
    Student-t weights the maps stay within a pixel of the truth, by least squares they do not."""
    rng = np.random.default_rng(5)
    F, n = 120, 12
    X = rng.uniform(-30, 30, (n, 2)) + [200, 150]
    a = np.linspace(0.0, 0.6, F)
    L = np.stack([np.stack([np.cos(a), -np.sin(a)], -1), np.stack([np.sin(a), np.cos(a)], -1)], 1)
    A = np.concatenate([L, (np.array([200.0, 150.0]) - np.einsum("fij,j->fi", L, [200, 150]))[:, :, None]], axis=2)
    truth = apply(A[:, None], X[None])
    xy = truth + rng.normal(0, 0.2, (F, n, 2))
    xy[40:80, :2] += [25.0, 10.0]

    def worst(M):
        return float(np.max(np.linalg.norm(apply(M[:, None], X[None]) - truth, axis=2)))

    robust, *_ = factorise_motion(xy, np.arange(n), similarity=True)
    plain, *_ = factorise_motion(xy, np.arange(n), similarity=True, nu=None)
    assert worst(robust) < 1.0 < worst(plain)


def test_a_part_turning_about_a_hinge_ranks_by_how_far_its_far_end_moves():
    """A lid of 20 tracks turning 60° about a hinge in the image, from 2 to 100 px out (each moves
    as far as it lies from the hinge: median 51 px, far end 100 px), and a block of 20 tracks
    sliding 60 px: the lid moves further, so it is the first part. Ranked by the tracks' median
    move the block came first."""
    from artmotion.articulation.video.segment import rigid_parts

    rng = np.random.default_rng(0)
    F, n = 60, 20
    a = np.concatenate([np.zeros(10), np.linspace(0.0, math.pi / 3, F - 10)])
    r = np.linspace(2.0, 100.0, n) + rng.uniform(-0.5, 0.5, n)
    side = np.tile([-8.0, 8.0], n // 2)
    hinge = np.array([150.0, 300.0])
    # in the lid's frame: along it (r) and across it (side), turned by a about the hinge
    lid = hinge + np.stack([r * np.cos(a)[:, None] - side * np.sin(a)[:, None],
                            -(r * np.sin(a)[:, None] + side * np.cos(a)[:, None])], -1)
    block0 = rng.uniform(-25, 25, (n, 2)) + [450.0, 250.0]
    shift = np.concatenate([np.zeros(10), np.linspace(0.0, 60.0, F - 10)])
    block = block0[None] + np.stack([shift, np.zeros(F)], -1)[:, None]
    xy = np.concatenate([lid, block], axis=1) + rng.normal(0, 0.1, (F, 2 * n, 2))
    tracks = PointTracks(xy, 25.0, 640, 480)
    parts = rigid_parts(tracks, np.arange(2 * n), 0.1, max_parts=2)
    assert len(parts) == 2
    assert set(parts[0].tracks) == set(range(n)) and set(parts[1].tracks) == set(range(n, 2 * n))
    assert parts[0].motion > 85 and abs(parts[1].motion - 60) < 1


def _tracks(path) -> PointTracks:
    seq = open_sequence(path)
    return point_tracks((img for _, img in seq.frames()), seq.fps)


def test_tracks_rounded_to_whole_pixels_keep_their_answer(tmp_path):
    """Positions written as whole pixels (another tracker's export): most steps are 0, the noise
    fell to its floor and every still point's one-pixel flicker broke its rest — 'static', no part.
    The rounding is noise too (a step of two roundings, 1 / sqrt 6 px)."""
    from artmotion.articulation.video import analyze_tracks

    tracks = _tracks(part_video(tmp_path / "turn.avi", "revolute", pivot=(110, 120)))
    rounded = replace(tracks, xy=np.round(tracks.xy))
    assert noise_level(rounded) >= 1 / math.sqrt(6) > noise_level(tracks)
    assert analyze_tracks(tracks).model == analyze_tracks(rounded).model == "revolute"


def test_tracks_dragged_off_their_point_are_found_and_a_moving_part_keeps_its_own(tmp_path):
    """A part slides 80 px over the background: the tracks inside it move with their points (their
    first place now shows something else), while background tracks that its edge drags along
    leave their first place unchanged behind them."""
    tr = _tracks(part_video(tmp_path / "slide.avi", "prismatic", seed=0))
    x, y = tr.start.T
    checked = (tr.first == 0) & (tr.checks > 0)
    inside = checked & (x > 120) & (x < 230) & (y > 106) & (y < 134)     # the part: 110-240 x 98-142
    outside = checked & ((x < 100) | (x > 250) | (y < 90) | (y > 150))
    assert inside.sum() >= 10 and outside.sum() >= 10
    assert tr.slipped[inside].mean() <= 0.05
    assert tr.slipped[outside].mean() >= 0.3


def test_a_hand_passing_over_a_still_scene_leaves_fewer_moving_tracks(tmp_path):
    tr = _tracks(part_video(tmp_path / "still.avi", "static", seed=0, hand=True))
    sigma = noise_level(tr)
    unchecked = moving_tracks(replace(tr, slips=None, checks=None), sigma)
    assert len(moving_tracks(tr, sigma)) < 0.8 * len(unchecked)


def test_cli_json_and_outputs(tmp_path, run_cli):
    v = part_video(tmp_path / "turn.avi", "revolute")
    code, out, err = run_cli("articulation", "video", v, "--json", "--out", tmp_path / "res")
    assert code == 0, err
    d = json.loads(out)
    assert d["model"] == "revolute" and d["camera"] == "static"
    assert set(d["parts"][0]) >= {"model", "axis", "range", "points", "frames", "probabilities"}
    assert math.isclose(sum(d["parts"][0]["probabilities"].values()), 1.0, rel_tol=1e-9)
    assert d["parts"][0]["confidence"] == max(d["parts"][0]["probabilities"].values())
    assert json.loads((tmp_path / "res" / "result.json").read_text()) == d
    assert (tmp_path / "res" / "parts.png").stat().st_size > 1000
    code, out, err = run_cli("articulation", "video", v)
    assert code == 0 and "model: revolute" in out


@pytest.mark.parametrize("content", [b"", b"not a video at all", b"RIFF\x00\x00\x00\x00AVI LIST" + b"\x00" * 64])
def test_cli_unreadable_video_is_one_line_error(tmp_path, run_cli, content):
    bad = tmp_path / "bad.avi"
    bad.write_bytes(content)
    code, out, err = run_cli("articulation", "video", bad, "--out", tmp_path / "o")
    assert code == 2 and out == ""
    assert err.startswith("artmotion: error: ") and str(bad) in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists()



def test_cli_one_frame_is_one_line_error(tmp_path, run_cli):
    """One frame shows no motion at all: an error (it said 'static' with confidence 0.5)."""
    folder = tmp_path / "one"
    folder.mkdir()
    cv2.imwrite(str(folder / "000001.jpg"), np.random.default_rng(0).integers(0, 255, (120, 160, 3), dtype=np.uint8))
    code, out, err = run_cli("articulation", "video", folder, "--out", tmp_path / "o")
    assert code == 2 and out == "" and err.count("\n") == 1
    assert err.startswith(f"artmotion: error: {folder}: 1 frame") and not (tmp_path / "o").exists()

def test_cli_fps_of_a_folder_of_frames(tmp_path, run_cli):
    """A folder of frames says no frame rate: 25 is assumed and said so; --fps gives it (the time
    a part must rest first, and the motion models, are in seconds)."""
    v = part_video(tmp_path / "s.avi", "static", frames=12)
    folder = tmp_path / "frames"
    folder.mkdir()
    cap = cv2.VideoCapture(str(v))
    k = 0
    while True:
        ok, img = cap.read()
        if not ok:
            break
        k += 1
        cv2.imwrite(str(folder / f"{k:06d}.png"), img)
    cap.release()
    code, out, err = run_cli("articulation", "video", folder)
    assert code == 0 and "12 frames @ 25 fps (assumed; give --fps)" in out, (out, err)
    code, out, err = run_cli("articulation", "video", folder, "--fps", "12.5", "--json")
    assert code == 0 and json.loads(out)["fps"] == 12.5, err


def test_cli_bad_options(tmp_path, run_cli):
    v = tmp_path / "missing.avi"
    code, _, err = run_cli("articulation", "video", v)
    assert code == 2 and "no such file" in err
    v = part_video(tmp_path / "s.avi", "static", frames=12)
    for args in (("--focal", "0"), ("--focal", "nan"), ("--max-parts", "0"), ("--seed", "-1"), ("--fps", "0"),
                 ("--fps", "inf")):
        code, _, err = run_cli("articulation", "video", v, *args)
        assert code == 2 and err.startswith("artmotion: error: "), (args, err)


@pytest.mark.parametrize("kwargs, match", [
    ({"max_parts": 0}, "max_parts"), ({"max_parts": 21}, "max_parts"), ({"max_parts": 2.5}, "max_parts"),
    ({"focal": -500.0}, "focal"), ({"focal": float("nan")}, "focal"), ({"seed": -1}, "seed"),
])
def test_analyze_video_refuses_options_the_cli_refuses(kwargs, match):
    with pytest.raises(InputError, match=f"^{match} must be"):  # before the video is even opened
        analyze_video("/nonexistent/v.avi", **kwargs)


def test_a_clip_too_short_for_the_rest_test_says_so(tmp_path, run_cli):
    """At 240 frames/s, 60 frames last 0.25 s: no point can rest first and then move, and the answer
    read as 'nothing moves'; a clip without texture was called filmed by a moving camera."""
    v = part_video(tmp_path / "fast.avi", "revolute", frames=60, fps=240.0)
    code, out, err = run_cli("articulation", "video", v, "--json")
    d = json.loads(out)
    assert code == 0 and d["model"] == "static" and d["parts"] == [] and "too short to tell" in d["note"]
    flat = tmp_path / "flat.avi"
    wr = cv2.VideoWriter(str(flat), cv2.VideoWriter.fourcc(*"MJPG"), 30.0, (160, 120))
    for _ in range(30):
        wr.write(np.full((120, 160, 3), 128, np.uint8))
    wr.release()
    d = json.loads(run_cli("articulation", "video", flat, "--json")[1])
    assert d["camera"] == "static" and "no texture" in d["note"]
    d = json.loads(run_cli("articulation", "video", part_video(tmp_path / "ok.avi", "prismatic", frames=45), "--json")[1])
    assert d["model"] == "prismatic" and d["note"] is None


def test_draw_parts_on_grey_and_refuses_other_images(tmp_path):
    """draw_parts draws on BGR or grey uint8 (OpenCV's images); a float image was a raw cv2.error."""
    from artmotion.articulation.video import draw_parts, parts_strip

    res = analyze_video(part_video(tmp_path / "slide.avi", "prismatic"))
    assert res.found
    grey = np.full((res.tracks.height, res.tracks.width), 128, np.uint8)
    out = draw_parts(grey, res)
    assert out.shape == grey.shape + (3,) and out.dtype == np.uint8 and (out != 128).any()
    for bad in (grey.astype(np.float32) / 255, np.dstack([grey] * 4), grey.astype(np.uint16)):
        with pytest.raises(InputError, match="draw_parts draws on a BGR"):
            draw_parts(bad, res)
    with pytest.raises(InputError, match="no snapshots"):
        parts_strip(res)
