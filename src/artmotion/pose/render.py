"""Synthetic endoscope views of a two-jaw laparoscopic grasper with known joint angles.

The tool is a 5 mm cylinder stem through a fixed insertion point (trocar), a clevis and two jaws
hinged at the tip. Its pose is four angles (degrees): the stem orientation as intrinsic Z-Y-X
Euler angles ``yaw, pitch, roll`` relative to a base orientation pointing from the trocar into the
workspace (stem axis = tool x axis; roll turns the jaw plane about it), and the jaw ``opening``
(0-90°). Poses follow a pick-and-place script: minimum-jerk moves between random grasp and
release poses, jaws closing to grasp and opening to release.

The picture is drawn with OpenCV after a pinhole projection: a shaded cylinder (metallic
stripes), box-shaped jaws shaded by their face normals, a procedural tissue background (pink
multi-scale texture, vessels, wet glints) seen through an endoscope vignette, plus nuisances:
motion blur (the tool is rendered at sub-frame times and averaged), partial occlusion by a
second tool, specular highlights, smooth global lighting changes and sensor noise; ``dark=True``
renders a low-light sequence. Everything derives from one seed (``numpy.random.default_rng``),
so a seed always gives the same images.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from artmotion.errors import InputError, check_bool, check_range, check_seed
from artmotion.io import atomic_dir, atomic_write
from artmotion.io.atomic import outputs_of
from artmotion.io.media import write_image

ANGLES = ("yaw", "pitch", "roll", "opening")
EULER = "ZYX"  # intrinsic: yaw about z, pitch about y', roll about x'' (the stem axis)
WIDTH, HEIGHT = 640, 480
FOCAL = 520.0
RANGES = {"yaw": (-32.0, 32.0), "pitch": (-25.0, 25.0), "roll": (-50.0, 50.0), "opening": (0.0, 90.0),
          "depth": (95.0, 150.0)}
TROCAR = np.array([-95.0, -85.0, 35.0])  # insertion point in camera coordinates (mm)
AIM = np.array([0.0, 0.0, 120.0])  # where the base orientation points
STEM_R = 2.6
JAW_LEN, JAW_W0, JAW_W1, JAW_T = 15.0, 2.6, 1.1, 1.6
CLEVIS_LEN = 5.0


def _base_rotation() -> np.ndarray:
    x = AIM - TROCAR
    x /= np.linalg.norm(x)
    z = np.cross(x, np.array([0.0, -1.0, 0.0]))
    z /= np.linalg.norm(z)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)


R0 = _base_rotation()


def stem_direction(angles_deg: np.ndarray, euler: str = EULER) -> np.ndarray:
    """Unit stem directions ``(n, 3)`` of Euler angles ``(n, 3)`` in degrees (tool x axis).

    The fixed base rotation is left out: it does not change angles between directions.
    """
    a = np.atleast_2d(np.asarray(angles_deg, dtype=float))
    return Rotation.from_euler(euler, a, degrees=True).apply(np.array([1.0, 0.0, 0.0]))


# ----------------------------------------------------------------------------- pose script
def _minjerk(t: np.ndarray) -> np.ndarray:
    return t * t * t * (10 - 15 * t + 6 * t * t)


def pose_script(n: int, rng: np.random.Generator) -> np.ndarray:
    """``(n, 5)`` smooth pick-and-place trajectory: yaw, pitch, roll, opening (deg), depth (mm)."""
    keys_t, keys_v = [0], []

    def rnd(name):
        lo, hi = RANGES[name]
        return rng.uniform(lo, hi)

    cur = np.array([rnd("yaw"), rnd("pitch"), rnd("roll"), rng.uniform(30, 90), rnd("depth")])
    keys_v.append(cur.copy())
    t = 0
    holding = False
    while t < n + 60:
        # move: the stem goes to a new grasp / release pose
        nxt = cur.copy()
        nxt[[0, 1, 2, 4]] = [rnd("yaw"), rnd("pitch"), rnd("roll"), rnd("depth")]
        if not holding:  # approach with open jaws, at some random opening
            nxt[3] = rng.uniform(25, 90)
        else:
            nxt[3] = np.clip(cur[3] + rng.normal(0, 3), 0, 30)
        t += int(rng.integers(20, 46))
        keys_t.append(t)
        keys_v.append(nxt)
        cur = nxt
        # dwell: grasp (close) or release (open), quickly
        nxt = cur.copy()
        nxt[3] = rng.uniform(0, 25) if not holding else rng.uniform(40, 90)
        nxt[[0, 1, 2]] += rng.normal(0, 1.5, 3)
        holding = not holding
        t += int(rng.integers(5, 14))
        keys_t.append(t)
        keys_v.append(nxt)
        cur = nxt
    return _through_keys(np.array(keys_t), np.array(keys_v), n, rng)


def cover_script(n: int, rng: np.random.Generator, hop: tuple[int, int] = (4, 11)) -> np.ndarray:
    """``(n, 5)`` motion that covers the joint ranges evenly, for training sets.

    Key poses are a scrambled Sobol sequence over (yaw, pitch, roll, opening, depth) in their
    ranges, so that every region of the pose space, and every combination of the angles, is
    visited about equally (the pick-and-place script dwells near closed and wide-open jaws and
    leaves combinations out); a greedy nearest-neighbour tour visits them in turn by minimum-jerk
    moves of ``hop`` frames, so the frames between key poses are continuous motion (with its blur),
    as in a real recording."""
    from scipy.stats import qmc

    k = n // hop[0] + 2
    lo = np.array([RANGES[a][0] for a in (*ANGLES, "depth")])
    hi = np.array([RANGES[a][1] for a in (*ANGLES, "depth")])
    u = qmc.Sobol(5, scramble=True, seed=rng).random_base2(int(math.ceil(math.log2(k))))[:k]
    order, left = [0], np.ones(k, bool)
    left[0] = False
    for _ in range(k - 1):  # greedy tour: short moves between neighbouring key poses
        d = np.where(left, ((u - u[order[-1]]) ** 2).sum(1), np.inf)
        order.append(int(np.argmin(d)))
        left[order[-1]] = False
    kv = lo + (hi - lo) * u[order]
    kt = np.concatenate([[0], np.cumsum(rng.integers(hop[0], hop[1], k - 1))])
    return _through_keys(kt, kv, n, rng)


MOTIONS = {"script": pose_script, "cover": cover_script}


def _through_keys(kt: np.ndarray, kv: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Minimum-jerk moves through key poses ``kv`` at frames ``kt``, plus a little hand tremor."""
    frames = np.arange(n, dtype=float)
    seg = np.clip(np.searchsorted(kt, frames, side="right") - 1, 0, len(kt) - 2)
    t0, t1 = kt[seg], kt[seg + 1]
    s = _minjerk((frames - t0) / (t1 - t0))[:, None]
    traj = kv[seg] * (1 - s) + kv[seg + 1] * s
    # a little smooth hand tremor
    tremor = cv2.GaussianBlur(rng.normal(0, 1.0, (n, 5)).astype(np.float64), (1, 0), sigmaX=0, sigmaY=3)
    traj += tremor * np.array([0.6, 0.6, 0.8, 0.8, 0.5]) * 2.0
    for j, name in enumerate(("yaw", "pitch", "roll", "opening", "depth")):
        lo, hi = RANGES[name]
        traj[:, j] = np.clip(traj[:, j], lo, hi)
    return traj


# ----------------------------------------------------------------------------- drawing
def project(P: np.ndarray) -> np.ndarray:
    P = np.atleast_2d(P)
    return np.stack([FOCAL * P[:, 0] / P[:, 2] + WIDTH / 2, FOCAL * P[:, 1] / P[:, 2] + HEIGHT / 2], axis=1)


def _shade(color, level):
    return tuple(float(min(255.0, max(0.0, c * level))) for c in color)


def _draw_cylinder(img, A, B, radius, color, spec_shift=0.3, strips=10, glint=0.8):
    """Shaded cylinder from 3-D point A to B (clipped to z >= 12 mm)."""
    A, B = np.asarray(A, float), np.asarray(B, float)
    if A[2] < 12 and B[2] < 12:
        return
    if A[2] < 12:
        A = A + (B - A) * (12 - A[2]) / (B[2] - A[2])
    if B[2] < 12:
        B = B + (A - B) * (12 - B[2]) / (A[2] - B[2])
    a, b = project(np.stack([A, B]))
    d = b - a
    L = np.linalg.norm(d)
    if L < 1e-6:
        return
    nrm = np.array([-d[1], d[0]]) / L
    ra, rb = FOCAL * radius / A[2], FOCAL * radius / B[2]
    edges = np.linspace(-1, 1, strips + 1)
    for i in range(strips):
        s0, s1 = edges[i], edges[i + 1]
        sm = 0.5 * (s0 + s1)
        diffuse = math.sqrt(max(0.0, 1 - sm * sm))
        spec = glint * math.exp(-(((sm - spec_shift) / 0.18) ** 2))
        level = 0.25 + 0.75 * diffuse
        col = tuple(min(255.0, c * level + 255 * spec) for c in color)
        poly = np.array([a + nrm * ra * s0, b + nrm * rb * s0, b + nrm * rb * s1, a + nrm * ra * s1])
        cv2.fillConvexPoly(img, np.round(poly * 16).astype(np.int32), col, lineType=cv2.LINE_AA, shift=4)


def _jaw_faces(T: np.ndarray, R: np.ndarray, sign: float, opening: float):
    """Corners (camera frame) of one jaw and its 6 faces (index quads)."""
    half = math.radians(opening) / 2 * sign
    dirn = np.array([math.cos(half), math.sin(half), 0.0])
    side = np.array([-math.sin(half), math.cos(half), 0.0])  # in the jaw plane, across the jaw
    z = np.array([0.0, 0.0, 1.0])  # hinge axis
    pts = []
    for u, w in ((0.0, JAW_W0), (JAW_LEN, JAW_W1)):
        for sz in (-1, 1):
            for ss in (0, 1):
                off = side * sign * JAW_T * ss
                pts.append(dirn * u + z * (w / 2) * sz + off)
    pts = np.array(pts) @ R.T + T
    faces = [(0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5)]
    return pts, faces


def _draw_box(img, pts, faces, color, glint=0.8):
    centre = pts.mean(0)
    order = sorted(faces, key=lambda f: -pts[list(f)].mean(0)[2])
    proj = project(pts)
    for f in order:
        q = pts[list(f)]
        n = np.cross(q[1] - q[0], q[3] - q[0])
        nn = np.linalg.norm(n)
        if nn < 1e-9:
            continue
        n /= nn
        fc = q.mean(0)
        if np.dot(n, fc - centre) < 0:
            n = -n
        view = -fc / np.linalg.norm(fc)
        cosv = float(np.dot(n, view))
        if cosv <= 0:
            continue
        level = 0.2 + 0.8 * cosv
        spec = glint * cosv**25
        col = tuple(min(255.0, c * level + 255 * spec) for c in color)
        cv2.fillConvexPoly(img, np.round(proj[list(f)] * 16).astype(np.int32), col, lineType=cv2.LINE_AA, shift=4)


@dataclass
class ToolPose:
    yaw: float
    pitch: float
    roll: float
    opening: float
    depth: float
    origin: np.ndarray | None = None  # trocar in camera coordinates (the endoscope follows the tool)

    def rotation(self) -> np.ndarray:
        return R0 @ Rotation.from_euler(EULER, [self.yaw, self.pitch, self.roll], degrees=True).as_matrix()

    def tip(self) -> np.ndarray:
        return self.trocar() + self.rotation()[:, 0] * self.depth

    def trocar(self) -> np.ndarray:
        return TROCAR if self.origin is None else self.origin


#: the tool's named points :func:`keypoints` gives (and ``pose render`` writes into keypoints.csv):
#: where the jaws hinge, where the metal clevis meets the stem, and the two jaw tips
KEYPOINTS = ("hinge", "clevis", "jaw1", "jaw2")


def keypoints(pose: ToolPose) -> np.ndarray:
    """The image points ``(4, 2)`` (pixels of the frame) of :data:`KEYPOINTS` of the tool in ``pose``."""
    R = pose.rotation()
    tip = pose.tip()
    pts = [tip, tip - R[:, 0] * CLEVIS_LEN]
    for sign in (1.0, -1.0):  # the end of each jaw's inner (gripping) edge, as drawn: closed, they meet
        corners, _ = _jaw_faces(tip, R, sign, pose.opening)
        pts.append((corners[4] + corners[6]) / 2)  # the far end's two inner corners (u = JAW_LEN, ss = 0)
    return project(np.array(pts))


def draw_tool(img, pose: ToolPose, stem_color=(40, 40, 45), metal=(175, 175, 180), glint=0.8, spec_shift=0.3):
    """Draw the grasper; returns the 2-D points of its end effector (for the bounding box)."""
    R = pose.rotation()
    tip = pose.tip()
    x = R[:, 0]
    clevis0 = tip - x * CLEVIS_LEN
    stem0 = pose.trocar()
    jaws = [_jaw_faces(tip, R, s, pose.opening) for s in (1.0, -1.0)]
    items: list[tuple[float, Callable[[], object]]] = [
        (float(((stem0 + clevis0) / 2)[2]),
         lambda: _draw_cylinder(img, stem0, clevis0, STEM_R, stem_color, spec_shift, glint=glint * 0.5)),
        (float(((clevis0 + tip) / 2)[2]) - 1e-3,
         lambda: _draw_cylinder(img, clevis0, tip, STEM_R * 0.95, metal, spec_shift, glint=glint)),
    ]
    for pts, faces in jaws:
        items.append((float(pts.mean(0)[2]), partial(_draw_box, img, pts, faces, metal, glint)))
    for _, fn in sorted(items, key=lambda it: -it[0]):
        fn()
    key = [project(p) for p, _ in jaws]
    back = tip - x * (CLEVIS_LEN + 18.0)
    key.append(project(np.stack([back, clevis0, tip])))
    # cylinder outline points near the end effector so the box covers the stem's width
    return np.concatenate(key, axis=0), FOCAL * STEM_R / min(back[2], tip[2])


#: looks of the tool and the tissue (BGR): ``default``, and ``alt`` — fatty yellow tissue, a brass
#: end effector and a lighter stem — to measure how much a model trained on one look moves on another;
#: ``random`` (not in this table) draws a look per scene (:func:`random_look`)
STYLES = {
    "default": {"tissue": (0.42, 0.45, 0.78), "tissue_dark": (0.20, 0.18, 0.52), "stem": (40, 40, 45),
                "metal": (175, 175, 180)},
    "alt": {"tissue": (0.50, 0.74, 0.86), "tissue_dark": (0.22, 0.38, 0.58), "stem": (95, 88, 80),
            "metal": (110, 150, 190)},
}


def random_look(rng: np.random.Generator) -> dict:
    """A look drawn at random (domain randomisation): tissue of any colour between dark and light,
    a metal end effector grey to tinted (brass, bronze, bluish), a stem dark to mid grey."""
    tissue_c = rng.uniform(0.3, 0.9, 3)
    return {"tissue": tuple(tissue_c), "tissue_dark": tuple(tissue_c * rng.uniform(0.35, 0.7)),
            "metal": tuple(rng.uniform(110, 210) * rng.uniform(0.7, 1.3, 3)),
            "stem": tuple(rng.uniform(30, 110) * rng.uniform(0.8, 1.2, 3))}


def tissue(rng: np.random.Generator, w: int, h: int, look: dict | None = None) -> np.ndarray:
    """A procedural tissue texture ``(h, w, 3)`` float32 in [0, 1] (BGR): pinkish, or in the colours
    of ``look`` (a :data:`STYLES` entry or :func:`random_look`)."""
    look = STYLES["default"] if look is None else look
    acc = np.zeros((h, w), np.float32)
    for cells, amp in ((4, 0.5), (12, 0.3), (40, 0.15), (120, 0.08)):
        small = rng.normal(0, 1, (max(2, cells * h // w), cells)).astype(np.float32)
        acc += amp * cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)
    acc = (acc - acc.min()) / (np.ptp(acc) + 1e-6)
    base = np.array(look["tissue"], np.float32)  # BGR (default: pink)
    dark = np.array(look["tissue_dark"], np.float32)
    img = dark + (base - dark) * acc[..., None]
    vessels: np.ndarray = np.zeros((h, w), np.float32)
    for _ in range(int(rng.integers(5, 10))):
        p = rng.uniform([0, 0], [w, h])
        ang = rng.uniform(0, 2 * np.pi)
        pts = []
        for _ in range(30):
            ang += rng.normal(0, 0.25)
            p = p + 12 * np.array([math.cos(ang), math.sin(ang)])
            pts.append(p.copy())
        cv2.polylines(vessels, [np.array(pts, np.int32)], False, float(rng.uniform(0.4, 1.0)), int(rng.integers(1, 4)),
                      cv2.LINE_AA)
    vessels = cv2.GaussianBlur(vessels, (0, 0), 1.5)
    img = img * (1 - 0.45 * vessels[..., None]) + np.array([0.05, 0.05, 0.25], np.float32) * 0.3 * vessels[..., None]
    glints: np.ndarray = np.zeros((h, w), np.float32)
    for _ in range(int(rng.integers(15, 30))):
        c = tuple(int(v) for v in rng.uniform([0, 0], [w, h]))
        cv2.ellipse(glints, c, (int(rng.integers(1, 5)), int(rng.integers(1, 3))), float(rng.uniform(0, 180)), 0, 360, 1.0, -1)
    glints = cv2.GaussianBlur(glints, (0, 0), 1.2)
    return np.clip(img + 0.6 * glints[..., None], 0, 1)


def _smooth_series(rng, n, sigma, lo, hi):
    x = rng.normal(0, 1, n + 200)
    x = cv2.GaussianBlur(x.reshape(-1, 1), (1, 0), sigmaX=0, sigmaY=sigma).ravel()[100 : 100 + n]
    x = (x - x.mean()) / (x.std() + 1e-9)
    return lo + (hi - lo) * (0.5 + 0.5 * np.tanh(x))


@dataclass
class RenderedFrame:
    frame: np.ndarray  # BGR uint8
    box: tuple[int, int, int, int]  # x, y, w, h
    angles: np.ndarray  # yaw, pitch, roll, opening (deg)
    points: np.ndarray  # (4, 2) frame pixels of KEYPOINTS


def render_sequence(n: int, seed: int = 0, dark: bool = False, motion: str = "script", scenes: int = 1,
                    style: str = "default"):
    """Yield ``n`` :class:`RenderedFrame` of one sequence (deterministic for a seed).

    ``motion``: ``"script"`` (pick and place, :func:`pose_script`) or ``"cover"`` (even coverage
    of the joint ranges, :func:`cover_script`). ``scenes`` > 1 splits the sequence into that many
    stretches, each over its own tissue and tint (a training set that has seen one background
    learns that background). ``style``: the look of tool and tissue (:data:`STYLES`, or ``random``:
    a look of :func:`random_look` per scene); the same seed draws the same motion and scene in
    every style. The arguments are checked at the call, before the first frame is drawn."""
    _check_rendering(n, seed, dark, motion, scenes, style, ("n", "scenes"))
    return _render(n, seed, dark, motion, scenes, style)


def _check_rendering(n, seed, dark, motion, scenes, style, names: tuple[str, str]) -> None:
    """The options of :func:`render_sequence` and :func:`write_dataset` (``names``: what ``n`` and
    ``scenes`` go by there), each an :class:`InputError` naming it."""
    check_range(names[0], n, 1, MAX_POSES, integer=True)
    check_seed(seed)
    check_bool("dark", dark)
    if not isinstance(motion, str) or motion not in MOTIONS:
        raise InputError(f"unknown motion {motion!r}; choose one of {', '.join(MOTIONS)}")
    check_range(names[1], scenes, 1, n, integer=True)
    if not isinstance(style, str) or style not in (*STYLES, "random"):
        raise InputError(f"unknown style {style!r}; choose one of {', '.join(STYLES)}, random")


def _render(n: int, seed: int, dark: bool, motion: str, scenes: int, style: str):
    """:func:`render_sequence`'s frames, its arguments checked."""
    rng = np.random.default_rng([seed, 3])
    traj = MOTIONS[motion](n, rng)
    looks = ([random_look(np.random.default_rng([seed, 5, k])) for k in range(scenes)] if style == "random"
             else [STYLES[style]] * scenes)
    bg = tissue(rng, WIDTH + 80, HEIGHT + 60, looks[0])
    yy, xx = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float32)
    vign = np.clip(1.15 - 0.9 * (((xx - WIDTH / 2) / WIDTH) ** 2 + ((yy - HEIGHT / 2) / HEIGHT) ** 2) * 2.2, 0.25, 1.0)
    gain = _smooth_series(rng, n, 40, 0.7, 1.2)
    if dark:  # the same scene, motion and draws as the normal-light render of this seed, in low light
        gain = 0.18 + (gain - 0.7) * (0.35 - 0.18) / (1.2 - 0.7)
    tint = rng.uniform(0.9, 1.1, 3).astype(np.float32)
    scene_rng = np.random.default_rng([seed, 4])  # its own stream: one scene renders as before
    backgrounds = [bg] + [tissue(scene_rng, WIDTH + 80, HEIGHT + 60, looks[k]) for k in range(1, scenes)]
    tints = [tint] + [scene_rng.uniform(0.85, 1.15, 3).astype(np.float32) for _ in range(scenes - 1)]
    # (two series drawn and unused: kept so that a seed renders the same images as before)
    _smooth_series(rng, n, 50, 0, 80), _smooth_series(rng, n, 50, 0, 60)
    # second tool: on in ~40 % of frames, its tip wandering around the first tool's tip
    other_on = _smooth_series(rng, n, 30, 0, 1) > 0.6
    other_off = np.stack([_smooth_series(rng, n, 25, -28, 28), _smooth_series(rng, n, 25, -22, 22)], 1)
    trocar2 = np.array([110.0, -70.0, 40.0])
    spec_shift = _smooth_series(rng, n, 60, -0.2, 0.6)
    exposure = 0.8  # fraction of the frame interval the shutter is open
    # the endoscope is moved (translated) to keep the tip in view at a wandering image position
    aim_u = _smooth_series(rng, n, 45, -150, 150)
    aim_v = _smooth_series(rng, n, 45, -100, 100)

    def posed(p, i):
        pose = ToolPose(*p)
        tip = pose.tip()
        c = tip - np.array([aim_u[i] * tip[2] / FOCAL, aim_v[i] * tip[2] / FOCAL, tip[2]])
        c[2] = 0.0
        pose.origin = TROCAR - c
        return pose, c

    for i in range(n):
        bg, tint, look = backgrounds[i * scenes // n], tints[i * scenes // n], looks[i * scenes // n]
        pose_i, cam = posed(traj[i], i)
        ox = int(np.clip(40 + cam[0] * 0.6, 0, 80))
        oy = int(np.clip(30 + cam[1] * 0.6, 0, 60))
        base = np.ascontiguousarray(bg[oy : oy + HEIGHT, ox : ox + WIDTH] * 255.0)
        # motion blur: sub-frame renders between the previous and this pose, as many as the motion needs
        prev = traj[max(0, i - 1)]
        pose_p, _ = posed(prev, max(0, i - 1))
        disp = float(np.linalg.norm(project(pose_i.tip()) - project(pose_p.tip() - pose_p.origin + pose_i.origin)))
        disp += FOCAL * JAW_LEN / pose_i.tip()[2] * math.radians(abs(traj[i, 3] - prev[3]))
        sub = int(np.clip(math.ceil(exposure * disp / 2.0), 1, 8))
        acc = None
        for k in range(sub):
            a = 1.0 - exposure * k / max(1, sub - 1) if sub > 1 else 1.0
            pose = ToolPose(*(traj[i] * a + prev * (1 - a)))
            pose.origin = pose_i.origin
            img = base.copy()
            pts, rad = draw_tool(img, pose, stem_color=look["stem"], metal=look["metal"], glint=0.8,
                                 spec_shift=float(spec_shift[i]))
            if k == 0:
                key_pts, key_rad = pts, rad
            if other_on[i]:
                tip = pose.tip()
                tip2 = tip + np.array([other_off[i, 0], other_off[i, 1], -12.0])
                tro2 = trocar2 - cam
                d2 = tip2 - tro2
                d2 /= np.linalg.norm(d2)
                _draw_cylinder(img, tro2, tip2, STEM_R, (70, 68, 66), 0.1, glint=0.4)
                _draw_cylinder(img, tip2 - d2 * 6, tip2 + d2 * 8, STEM_R, (160, 160, 165), 0.1, glint=0.7)
            acc = img if acc is None else acc + img
        assert acc is not None  # sub >= 1
        img = acc / sub
        img = img * (vign[..., None] * gain[i] * tint)
        noise = 5.0 if dark else 2.5
        img += rng.normal(0, noise, img.shape).astype(np.float32)
        frame = np.clip(img, 0, 255).astype(np.uint8)
        x0, y0 = key_pts.min(0) - key_rad
        x1, y1 = key_pts.max(0) + key_rad
        w, h = x1 - x0, y1 - y0
        pad = 0.08 + rng.uniform(-0.04, 0.04, 4)  # detector jitter
        x0, x1 = x0 - pad[0] * w, x1 + pad[1] * w
        y0, y1 = y0 - pad[2] * h, y1 + pad[3] * h
        x0, y0 = max(0, int(round(x0))), max(0, int(round(y0)))
        x1, y1 = min(WIDTH, int(round(x1))), min(HEIGHT, int(round(y1)))
        yield RenderedFrame(frame, (x0, y0, max(2, x1 - x0), max(2, y1 - y0)), traj[i, :4].copy(), keypoints(pose_i))


#: the most poses one command renders (a 4000-frame sequence takes about a minute)
MAX_POSES = 1_000_000


#: what a rendering folder holds; ``rendering.json`` (how it was rendered) marks it as one
RENDERING = frozenset({"crops", "frames", "labels.csv", "keypoints.csv", "boxes.csv", "rendering.json"})


def write_dataset(out: str | Path, n: int = 4000, seed: int = 0, dark: bool = False, frames: bool = True,
                  progress: bool = False, motion: str = "script", scenes: int = 1, style: str = "default") -> Path:
    """Render ``n`` poses into ``out``: ``crops/*.png``, ``labels.csv``, ``keypoints.csv`` (the tool's
    :data:`KEYPOINTS` in pixels of each crop), ``frames/*.jpg`` and ``boxes.csv`` (with ``frames``
    only), ``rendering.json`` (the options it was rendered with).

    A new folder (or an earlier rendering in it) appears only when every file is written
    (:func:`artmotion.io.atomic_dir`): a failed or interrupted rendering leaves nothing."""
    _check_rendering(n, seed, dark, motion, scenes, style, ("--poses", "--scenes"))
    check_bool("frames", frames)
    check_bool("progress", progress)
    out = Path(out)
    with atomic_dir(out, replace=_is_rendering, outputs=RENDERING) as tmp:
        _write_dataset(tmp, n, seed, dark, frames, progress, motion, scenes, style)
        with atomic_write(tmp / "rendering.json") as fh:
            json.dump({"poses": n, "seed": seed, "motion": motion, "scenes": scenes, "style": style, "dark": dark,
                       "frames": frames}, fh, indent=1)
    return out


#: whether a folder holds an earlier rendering and nothing else (it is then replaced whole): its
#: rendering.json says so (a folder of crops and labels.csv may be a user's own)
_is_rendering = outputs_of("rendering.json", RENDERING, ("poses", "seed"),
                           inside={"crops": r"\d{6,}\.png", "frames": r"\d{6,}\.jpg"})


def _write_dataset(out: Path, n: int, seed: int, dark: bool, frames: bool, progress: bool, motion: str,
                   scenes: int, style: str = "default") -> None:
    (out / "crops").mkdir(parents=True, exist_ok=True)
    if frames:
        (out / "frames").mkdir(parents=True, exist_ok=True)
    it = render_sequence(n, seed, dark, motion, scenes, style)
    if progress:
        from tqdm import tqdm

        it = tqdm(it, total=n, desc="render", unit="frame", disable=None)
    rows, points, boxes = [], [], []
    for i, rf in enumerate(it, start=1):
        name = f"{i:06d}.png"
        x, y, w, h = rf.box
        write_image(out / "crops" / name, rf.frame[y : y + h, x : x + w])
        if frames:
            write_image(out / "frames" / f"{i:06d}.jpg", rf.frame, [cv2.IMWRITE_JPEG_QUALITY, 92])
        rows.append((name, *rf.angles))
        points.append((name, *(rf.points - (x, y)).ravel()))
        boxes.append((f"{i:06d}.jpg", x, y, w, h))
    for file, header, table in (("labels.csv", ANGLES, rows),
                                ("keypoints.csv", [f"{k}_{c}" for k in KEYPOINTS for c in "xy"], points)):
        with atomic_write(out / file) as fh:
            fh.write("image," + ",".join(header) + "\n")
            for r in table:
                fh.write(r[0] + "," + ",".join(f"{v:.4f}" for v in r[1:]) + "\n")
    if frames:
        with atomic_write(out / "boxes.csv") as fh:
            fh.write("image,x,y,w,h,frame_w,frame_h\n")
            for b in boxes:
                fh.write(",".join(str(v) for v in (*b, WIDTH, HEIGHT)) + "\n")
