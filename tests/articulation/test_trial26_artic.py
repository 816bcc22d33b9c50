"""User trial 26 (articulation): units in a trajectory header, the radius note, digits of large
coordinates, PointTracks' checks, a video's orientation tag, option messages, a 1-sample log."""

import json
import re

import cv2
import numpy as np
import pytest

from artmotion.articulation.trajectory import fit_trajectory
from artmotion.errors import InputError


def _circle(n=100, seed=0, radius=0.4, offset=(1.0, 2.0, 0.5)):
    rng = np.random.default_rng(seed)
    th = np.linspace(0, 1.5, n)
    c = np.asarray(offset, float)
    return np.stack([c[0] + radius * np.cos(th), c[1] + radius * np.sin(th), np.full(n, c[2])], 1) \
        + rng.normal(0, 0.001, (n, 3))


def _csv(path, header, cols):
    with open(path, "w") as fh:
        fh.write(header + "\n")
        for row in np.column_stack(cols):
            fh.write(",".join(repr(float(v)) if not float(v).is_integer() else str(int(v)) for v in row) + "\n")
    return path


# 1. units in the header -------------------------------------------------------------------------

def test_a_length_unit_in_the_header_is_converted_to_metres(tmp_path, run_cli):
    """'t,x_mm,y_mm,z_mm' holding a 400 mm circle was fitted as metres: prismatic, with a note to
    give --radius-range in the data's units. The same log in any declared unit gives one answer."""
    X = _circle()
    t = np.arange(len(X)) * 0.1
    ref = fit_trajectory(_csv(tmp_path / "m.csv", "t,x,y,z", [t, *X.T]))
    assert ref["model"] == "revolute" and ref["units"] == {"length": None, "time": None}
    for unit, scale in (("mm", 1e3), ("cm", 1e2), ("m", 1.0), ("km", 1e-3)):
        res = fit_trajectory(_csv(tmp_path / f"{unit}.csv", f"t,x_{unit},y_{unit},z_{unit}", [t, *(X * scale).T]))
        assert res["model"] == "revolute" and res["note"] is None, unit
        assert res["decided_at"] == ref["decided_at"] and res["units"]["length"] == unit
        assert np.allclose(res["configuration"]["centre"], ref["configuration"]["centre"], atol=1e-9), unit
        assert res["configuration"]["radius"] == pytest.approx(ref["configuration"]["radius"], rel=1e-9)
    code, out, err = run_cli("articulation", "fit", tmp_path / "mm.csv")
    assert code == 0 and "positions in mm, converted to metres" in out and "model: revolute" in out, err
    # x(mm) is the same unit
    res = fit_trajectory(_csv(tmp_path / "p.csv", "t,x(mm),y(mm),z(mm)", [t, *(X * 1e3).T]))
    assert res["model"] == "revolute" and res["units"]["length"] == "mm"


def test_a_time_unit_in_the_header_is_converted_to_seconds(tmp_path, run_cli):
    """time_ms, time_us and time_ns give the answer of seconds; real nanosecond stamps (1.7e18)
    were refused as 'time out of range' with no hint."""
    X = _circle()
    t = np.arange(len(X)) * 0.1
    ref = fit_trajectory(_csv(tmp_path / "s.csv", "time_s,x,y,z", [t, *X.T]))
    for unit, scale in (("ms", 1e3), ("us", 1e6), ("ns", 1e9)):
        stamps = 1_700_000_000 * scale + t * scale
        res = fit_trajectory(_csv(tmp_path / f"{unit}.csv", f"time_{unit},x,y,z", [stamps, *X.T]))
        assert res["model"] == ref["model"] == "revolute" and res["decided_at"] == ref["decided_at"], unit
        assert res["units"]["time"] == unit
        assert res["configuration"]["radius"] == pytest.approx(ref["configuration"]["radius"], rel=1e-6)
    # nanosecond stamps without a unit: the error says what to do
    p = _csv(tmp_path / "bare.csv", "timestamp,x,y,z", [1_700_000_000e9 + t * 1e9, *X.T])
    code, out, err = run_cli("articulation", "fit", p)
    assert code == 2 and "time out of range" in err and "time_ns" in err and err.count("\n") == 1


@pytest.mark.parametrize("header, needle", [
    ("t,x_mm,y_m,z_mm", "must have one unit"),
    ("t,x_mm,y,z", "must have one unit"),
    ("x,y,z,qx_m,qy,qz,qw", "a quaternion has no unit"),
])
def test_a_unit_that_cannot_be_honoured_is_refused(tmp_path, run_cli, header, needle):
    p = tmp_path / "f.csv"
    n = len(header.split(","))
    p.write_text(header + "\n" + "\n".join(",".join(["0"] * (n - 1) + ["1"]) for _ in range(3)) + "\n")
    code, out, err = run_cli("articulation", "fit", p)
    assert code == 2 and out == "" and err.startswith(f"artmotion: error: {p}:1: header: ") and needle in err, err


# 2. the radius note at the range's low end ------------------------------------------------------

def test_a_circle_smaller_than_the_radius_range_gets_the_note(tmp_path, run_cli):
    """A door written in kilometres (a 0.4 mm circle) came out revolute with 0.57 and no word on
    the radius prior; the note is given at or below the low end as above the high end."""
    X = _circle() * 1e-3
    p = tmp_path / "km.txt"
    np.savetxt(p, X)
    code, out, err = run_cli("articulation", "fit", p, "--json")
    res = json.loads(out)
    assert code == 0 and res["note"] and "at or below the prior range" in res["note"] and "--radius-range" in res["note"]
    np.savetxt(tmp_path / "m.txt", _circle())
    assert json.loads(run_cli("articulation", "fit", tmp_path / "m.txt", "--json")[1])["note"] is None


# 3. digits of large coordinates -----------------------------------------------------------------

def _printed(out: str, label: str) -> np.ndarray:
    m = re.search(re.escape(label) + r" \[([^\]]*)\]", out)
    assert m, (label, out)
    return np.array([float(v) for v in m.group(1).split(",")])


def test_large_coordinates_are_printed_to_a_usable_resolution(tmp_path, run_cli):
    """'centre: [5e+05, 4e+06, 100.5]' where the JSON had 500000.9993..., 4000001.9995...: every
    coordinate line now shows the digits down to well below a millimetre here."""
    off = np.array([500000.0, 4000000.0, 100.0])
    np.savetxt(tmp_path / "door.txt", _circle() + off)
    rng = np.random.default_rng(1)
    s = np.linspace(0, 0.5, 100)[:, None]
    np.savetxt(tmp_path / "drawer.txt", off + s * [0.6, 0.8, 0.0] + rng.normal(0, 0.001, (100, 3)))
    from scipy.spatial.transform import Rotation

    ang = np.linspace(0, 1.2, 100)
    pos = off + np.stack([0.4 * np.cos(ang), 0.4 * np.sin(ang), np.zeros(100)], 1)
    np.savetxt(tmp_path / "pose.txt", np.column_stack([pos, Rotation.from_euler("z", ang[:, None]).as_quat()]))
    for name, label in (("door", "centre:"), ("drawer", "origin:"), ("pose", "point:")):
        code, out, err = run_cli("articulation", "fit", tmp_path / f"{name}.txt")
        assert code == 0, err
        res = json.loads(run_cli("articulation", "fit", tmp_path / f"{name}.txt", "--json")[1])
        key = label[:-1]
        assert np.allclose(_printed(out, label)[:2], res["configuration"][key][:2], rtol=0, atol=1e-3), (name, out)
        assert np.allclose(_printed(out, "predicted at")[:2], res["prediction"][0][:2], rtol=0, atol=1e-3), name


# 4. PointTracks' checks -------------------------------------------------------------------------

def _xy(frames=20, tracks=30):
    xy = np.random.default_rng(0).uniform(0, 100, (frames, tracks, 2))
    xy[min(3, frames - 1), 4] = np.nan          # track 4 not seen in frame 3: legitimate
    return xy


@pytest.mark.parametrize("make, needle", [
    (lambda xy: ((xy[..., 0], 30.0, 640, 480), {}), "xy must be an array of shape (frames, tracks, 2)"),
    (lambda xy: (("abc", 30.0, 640, 480), {}), "xy must be an array of numbers"),
    (lambda xy: ((xy, 0.0, 640, 480), {}), "fps"),
    (lambda xy: ((xy, float("nan"), 640, 480), {}), "fps"),
    (lambda xy: ((xy, 30.0, -640, 480), {}), "width"),
    (lambda xy: ((xy, 30.0, 640, -480), {}), "height"),
    (lambda xy: ((xy, 30.0, 640.5, 480), {}), "width"),
    (lambda xy: ((np.where(np.arange(30)[None, :, None] == 2, np.inf, xy), 30.0, 640, 480), {}), "xy must hold finite"),
    (lambda xy: ((np.where((np.arange(2) == 0)[None, None], np.nan, xy), 30.0, 640, 480), {}), "one coordinate NaN"),
    (lambda xy: ((xy, 30.0, 640, 480), {"slips": np.zeros(3), "checks": np.zeros(3)}), "slips must be 30"),
    (lambda xy: ((xy, 30.0, 640, 480), {"slips": np.ones(30), "checks": np.zeros(30)}), "no more slips than checks"),
    # (1e30 wrapped round to -9.2e18 as a count)
    (lambda xy: ((xy, 30.0, 640, 480), {"slips": np.full(30, 1e30), "checks": np.full(30, 1e30)}),
     "slips must be 30 whole numbers in [0, 20]"),
])
def test_point_tracks_refuse_bad_arguments_by_name(make, needle):
    from artmotion.articulation.video.tracks import PointTracks

    args, kwargs = make(_xy())
    with pytest.raises(InputError, match=re.escape(needle)):
        PointTracks(*args, **kwargs)


def test_analyze_tracks_needs_two_frames_and_takes_untracked_entries():
    """An empty track matrix was 'attempt to get argmax of an empty sequence'; NaN entries (a
    track not seen in a frame) stay legitimate."""
    from artmotion.articulation.video import analyze_tracks
    from artmotion.articulation.video.tracks import PointTracks

    for xy in (np.zeros((0, 0, 2)), _xy(frames=1)):
        with pytest.raises(InputError, match="motion needs at least two"):
            analyze_tracks(PointTracks(xy, 10.0, 640, 480))
    with pytest.raises(InputError, match="tracks must be a PointTracks"):
        analyze_tracks(_xy())
    tr = PointTracks(_xy(), 10, 640.0, 480)
    assert tr.width == 640 and isinstance(tr.width, int) and tr.fps == 10.0
    assert analyze_tracks(tr).model in ("static", "prismatic", "revolute")


# 5. a video's orientation tag -------------------------------------------------------------------

def _exif_oriented(jpeg: bytes, orientation: int) -> bytes:
    """``jpeg`` with an EXIF segment whose orientation tag is ``orientation``."""
    import struct

    tiff = b"II*\x00" + struct.pack("<IH", 8, 1) + struct.pack("<HHIHH", 0x0112, 3, 1, orientation, 0) + b"\0" * 4
    payload = b"Exif\x00\x00" + tiff
    return jpeg[:2] + b"\xff\xe1" + struct.pack(">H", len(payload) + 2) + payload + jpeg[2:]


def test_video_says_frames_are_read_as_stored_whatever_their_orientation_tag(tmp_path, run_cli):
    """'articulation video' read a turned video as stored without a word (track says it)."""
    from artmotion.articulation.synthetic import part_video

    v = part_video(tmp_path / "s.avi", "static", frames=12)
    folders = {o: tmp_path / f"o{o}" for o in (1, 6)}
    cap = cv2.VideoCapture(str(v))
    k = 0
    for folder in folders.values():
        folder.mkdir()
    while True:
        ok, img = cap.read()
        if not ok:
            break
        k += 1
        jpeg = cv2.imencode(".jpg", img)[1].tobytes()
        for o, folder in folders.items():
            (folder / f"{k:06d}.jpg").write_bytes(_exif_oriented(jpeg, o))
    cap.release()
    for o, folder in folders.items():
        code, out, err = run_cli("articulation", "video", folder)
        assert code == 0, err
        assert ("as stored (not turned as its orientation tag asks: turn 90°)" in out) == (o == 6), out
        d = json.loads(run_cli("articulation", "video", folder, "--json")[1])
        assert d["orientation"] == ("turn 90°" if o == 6 else None)


# 6. option messages and --fps -------------------------------------------------------------------

def test_option_messages_name_the_option_and_the_problem(tmp_path, run_cli):
    np.savetxt(tmp_path / "door.txt", _circle())
    code, out, err = run_cli("articulation", "fit", tmp_path / "door.txt", "--radius-range", "1", "0.05")
    assert code == 2 and "--radius-range" in err and "high end must exceed the low end" in err, err
    from artmotion.articulation.synthetic import part_video

    v = part_video(tmp_path / "s.avi", "static", frames=12, fps=30.0)
    code, out, err = run_cli("articulation", "video", v, "--fps", "0")
    assert code == 2 and err.startswith("artmotion: error: --fps must be"), err


def test_fps_help_says_it_replaces_the_input_s_own(tmp_path, run_cli):
    """The help said 'when the input does not say it' but --fps replaced a video's own rate, as in
    track and run: the help now says what it does."""
    code, out, err = run_cli("articulation", "video", "--help")
    text = " ".join(re.sub(r"[│\s]+", " ", out).split())
    assert code == 0 and "in place of the input's own" in text and "when the input does not say it" not in text
    from artmotion.articulation.synthetic import part_video

    v = part_video(tmp_path / "s.avi", "static", frames=12, fps=30.0)
    assert json.loads(run_cli("articulation", "video", v, "--fps", "12.5", "--json")[1])["fps"] == 12.5


# 7. a 1-sample point log ------------------------------------------------------------------------

def test_a_one_sample_point_log_says_not_estimated_as_a_pose_log_does(tmp_path, run_cli):
    np.savetxt(tmp_path / "p.txt", _circle()[:1])
    np.savetxt(tmp_path / "q.txt", [[1.0, 2.0, 0.5, 0, 0, 0, 1]])
    for name in ("p.txt", "q.txt"):
        res = json.loads(run_cli("articulation", "fit", tmp_path / name, "--json")[1])
        assert res["model"] == "undecided" and res["noise"] is None and res["motion"] == [], (name, res)
    res = fit_trajectory(tmp_path / "p.txt", noise=0.01)      # a noise given is kept
    assert res["noise"] == 0.01 and res["motion"] == []


@pytest.mark.parametrize("header, said", [
    ("time_seconds,x,y,z", "time in s)"), ("timestamp_utc,x,y,z", "time column)"),
    ("time_from_start,x,y,z", "time column)"), ("time_usec,x,y,z", "time in us, converted to seconds"),
    ("t,x_meters,y_meters,z_meters", "positions in m)"), ("t,x1_mm,y1_mm,z1_mm", "positions in mm, converted"),
    ("t,x_\u03bcm,y_\u03bcm,z_\u03bcm", "positions in \u00b5m, converted"), ("x1,y1,z1", "(point3d)"),
])
def test_headers_read_before_units_were_honoured_still_are(tmp_path, run_cli, header, said):
    """Suffixes that are no unit (``timestamp_utc``, a marker's ``x1``) are read as before, and the
    usual spellings of a unit (``seconds``, ``meters``, ``usec``, a Greek mu) are units."""
    n = 12
    cols = [np.arange(n) * 0.1 + k for k in range(len(header.split(",")))]
    p = _csv(tmp_path / "h.csv", header, cols)
    code, out, err = run_cli("articulation", "fit", p)
    assert code == 0 and said in out.splitlines()[0], (out, err)
