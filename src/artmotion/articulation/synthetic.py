"""Synthetic gripper logs of articulated mechanisms, with the failure shapes of real ones.

Real logs (Sturm et al. 2010) are a gripper's 3-D positions while a robot opens a door or a drawer:
the motion starts and stops smoothly, the gripper may hold still before the mechanism gives way,
and the track deviates from the ideal joint by white sensor noise *and* by slow, correlated
deviations (arm compliance, a handle that turns in the hand). :func:`synthetic_log` draws such logs,
and the shapes on which model choice is known to fail. :func:`part_video` renders a textured part
that turns or slides against a static background, for articulation from video.

==========================  ==========  =========================================================
kind                        joint       what makes it hard
==========================  ==========  =========================================================
``door``                    revolute    a plain hinge (radius 0.2-0.9 m, 0.9-1.6 rad)
``drawer``                  prismatic   a plain slide (0.25-0.5 m)
``curved_drawer``           prismatic   the pull traces a bent path (bend 2-8 mm: an "arc" of 2-8 m)
``hook_drawer``             prismatic   the first 3-8 cm hook sideways by 3-8 mm
``slipping_door``           revolute    the gripper slips off the handle 1-3 times by 2-6 cm
``back_and_forth_door``     revolute    a long log (750-1000 samples): opened, closed, opened
``static``                  static      a gripper holding a handle that does not move
==========================  ==========  =========================================================
"""

from __future__ import annotations

import numpy as np

from artmotion.errors import InputError, check_range

__all__ = ["KINDS", "part_video", "synthetic_log"]

#: kind -> true joint
KINDS = {
    "door": "revolute",
    "drawer": "prismatic",
    "curved_drawer": "prismatic",
    "hook_drawer": "prismatic",
    "slipping_door": "revolute",
    "back_and_forth_door": "revolute",
    "static": "static",
}


def _min_jerk(u: np.ndarray) -> np.ndarray:
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10.0 - 15.0 * u + 6.0 * u * u)


def _profile(n: int, rng: np.random.Generator, stops=(0.0, 1.0)) -> np.ndarray:
    """Motion from 0 to 1 (or through ``stops``) in ``n`` samples: still at first (0-15 % of the
    log), smooth (minimum-jerk) legs, still at the end (0-10 %)."""
    n0 = int(n * rng.uniform(0.0, 0.15))
    n1 = int(n * rng.uniform(0.0, 0.10))
    legs = len(stops) - 1
    moving = n - n0 - n1
    edges = np.linspace(0, moving, legs + 1).astype(int)
    parts = [np.full(n0, stops[0])]
    for i in range(legs):
        m = edges[i + 1] - edges[i]
        parts.append(stops[i] + (stops[i + 1] - stops[i]) * _min_jerk(np.arange(1, m + 1) / m))
    parts.append(np.full(n1, stops[-1]))
    return np.concatenate(parts)[:n]


def _smooth_noise(n: int, std: float, length: float, rng: np.random.Generator) -> np.ndarray:
    """``(n, 3)`` correlated deviations: white noise smoothed by a Gaussian of ``length`` samples."""
    k = np.arange(-int(3 * length), int(3 * length) + 1)
    g = np.exp(-0.5 * (k / length) ** 2)
    W = rng.normal(size=(n + len(k) - 1, 3))
    S = np.column_stack([np.convolve(W[:, i], g, mode="valid") for i in range(3)])
    return S * (std / max(float(S.std()), 1e-12))


def _frame(rng: np.random.Generator) -> np.ndarray:
    """A random rotation (columns: the mechanism's x, y, z axes in the world)."""
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    return Q * np.sign(np.diag(R))


def synthetic_log(kind: str, seed: int | np.random.Generator = 0) -> tuple[np.ndarray, str]:
    """A log ``(n, 3)`` in metres and its true joint; ``kind`` is one of :data:`KINDS`."""
    if kind not in KINDS:
        raise ValueError(f"unknown kind {kind!r}; one of {', '.join(KINDS)}")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    door = KINDS[kind] == "revolute"
    n = int(rng.integers(750, 1001)) if kind == "back_and_forth_door" else int(rng.integers(230, 701 if door else 301))
    # noise levels that cover the real logs': white 0.4-1 mm; slow deviations off the ideal joint
    # 1-4 mm (doors) and 1-2.6 mm (drawers) with autocorrelation times of 10-40 samples
    # (a gripper holding a handle that does not move pulls on nothing: 0.1-0.5 mm)
    white = rng.uniform(0.0003, 0.001)
    slow = rng.uniform(0.001, 0.004) if door else rng.uniform(0.0008, 0.0025)
    if kind == "static":
        slow = rng.uniform(0.0001, 0.0005)
    if kind == "back_and_forth_door":
        u = _profile(n, rng, stops=(0.0, 1.0, rng.uniform(0.1, 0.4), 1.0))
    else:
        u = _profile(n, rng)
    if door:
        r = rng.uniform(0.2, 0.9)
        th = rng.uniform(0.9, 1.6) * u
        P = np.column_stack([r * np.cos(th), r * np.sin(th), np.zeros(n)])
        if kind == "slipping_door":
            for _ in range(int(rng.integers(1, 4))):
                k0 = int(rng.integers(n // 10, n - n // 10))
                k1 = min(n, k0 + int(rng.integers(10, 41)))
                off = rng.uniform(0.02, 0.06) * np.array([1.0, 0.0, rng.choice([-1.0, 1.0])]) / np.sqrt(2.0)
                ramp = np.minimum(1.0, np.minimum(np.arange(k1 - k0) + 1, k1 - np.arange(k0, k1)) / 3.0)
                radial = np.column_stack([np.cos(th[k0:k1]), np.sin(th[k0:k1]), np.zeros(k1 - k0)])
                P[k0:k1] += ramp[:, None] * (off[0] * radial + np.array([0.0, 0.0, off[2]]))
    elif kind == "static":
        P = np.zeros((n, 3))
    else:
        L = rng.uniform(0.25, 0.5)
        s = L * u
        P = np.column_stack([s, np.zeros(n), np.zeros(n)])
        side = np.array([0.0, np.cos(a := rng.uniform(0, 2 * np.pi)), np.sin(a)])
        if kind == "curved_drawer":
            P += (rng.uniform(0.002, 0.008) * 4.0 * u * (1.0 - u))[:, None] * side
        elif kind == "hook_drawer":
            h = rng.uniform(0.03, 0.08)
            P += (rng.uniform(0.003, 0.008) * np.clip(1.0 - s / h, 0.0, 1.0) ** 2)[:, None] * side
    P = P + _smooth_noise(n, slow, rng.uniform(4.0, 15.0), rng) + rng.normal(0.0, white, (n, 3))
    return P @ _frame(rng).T + rng.uniform(-1.0, 1.0, 3), KINDS[kind]


def _globe(texture: np.ndarray, size: tuple[int, int], centre, amount: float, radius: float = 70.0):
    """``part_video``'s ball: a function of the motion ``q`` (0..1) giving the image of ``texture``
    wrapped round a ball (longitude across, latitude down) turned by ``amount * q`` degrees about
    its leaning axis, and the ball's mask."""
    import cv2

    from artmotion.geometry.rotations import axis_angle_to_matrix as turn

    w, h = size
    u, v = np.meshgrid(np.arange(w), np.arange(h))
    x, y = (u - centre[0]) / radius, (v - centre[1]) / radius
    inside = x * x + y * y < 1.0
    z = np.sqrt(np.clip(1.0 - x * x - y * y, 0.0, 1.0))                  # towards the camera
    P = np.stack([x, y, -z], -1)                                          # camera frame (z away from it)
    up = turn([0, 0, 1], np.radians(23.0)) @ turn([1, 0, 0], np.radians(20.0)) @ [0.0, 1.0, 0.0]
    side = np.cross(up, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    body = np.stack([side, up, np.cross(side, up)])                       # the ball's axes, as rows
    texture = np.hstack([texture, texture[:, ::-1]])                     # mirrored: no seam where it closes
    th, tw = texture.shape[:2]
    shade = (0.45 + 0.55 * z)[..., None]                                  # lit from the camera

    def image(q: float) -> tuple[np.ndarray, np.ndarray]:
        B = P @ (body @ turn(up, -np.radians(amount * q))).T             # the turn undone: body coordinates
        lon = np.arctan2(B[..., 0], B[..., 2])
        lat = np.arcsin(np.clip(B[..., 1], -1.0, 1.0))
        mx = ((lon + np.pi) / (2.0 * np.pi) * tw).astype(np.float32)
        my = ((lat + np.pi / 2.0) / np.pi * (th - 1)).astype(np.float32)
        img = cv2.remap(texture, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
        return np.clip(img * shade, 0, 255).astype(np.uint8), inside

    return image


def part_video(path, motion: str = "revolute", frames: int = 90, size: tuple[int, int] = (320, 240),
               amount: float | None = None, pivot: tuple[float, float] = (110.0, 120.0),
               direction: tuple[float, float] = (1.0, 0.3), seed: int = 0, fps: float = 30.0,
               hand: bool = False, exposure: bool = False):
    """Write a video (MJPG ``.avi``) of a textured part against a static textured background:
    ``revolute`` turns it about ``pivot`` (an axis towards the camera) by ``amount`` degrees
    (default 60), ``prismatic`` slides it along ``direction`` by ``amount`` px (default 80),
    ``static`` leaves it. Seen through a pinhole camera (60-degree field of view), a part facing
    the camera at ``pivot``'s depth: ``hinge`` turns it about the horizontal line through
    ``pivot`` (a lid on a hinge in the image plane; its top tilts away) by ``amount`` degrees
    (default 60), ``depth`` slides it towards the camera by ``amount`` times its distance (default
    0.3: a drawer pulled out at the viewer). The part rests for the first and last sixth of the
    frames. ``hand``: a textured blob (a hand) comes in from the image's lower edge while the part
    moves, passes over the part's middle, covering part of it, and goes out again; it is never
    still. ``swing``: a small part (60x40 px at ``pivot``) turns by ``amount`` degrees (default 25)
    about a point 200 px to its left, as the markers at the tip of a long handle (pliers): its
    points' paths are nearly straight, its turn is what says revolute. ``exposure``: the camera's
    automatic exposure steps once, half-way through the motion (every grey level x 0.75 + 10 from
    then on). ``globe``: a textured ball (radius 70 px, centred at ``pivot``, lit from the camera,
    seen under weak perspective) spins by ``amount`` degrees (default 90) about its axis, which
    leans from the image's vertical by 23° sideways and 20° towards the camera: a rigid part that
    is not flat, whose points pass behind it."""
    import cv2

    from artmotion.io.atomic import atomic_path, check_writable
    from artmotion.io.media import check_written_video, cv2_name

    check_writable(path)
    check_range("frames", frames, 1, 10**6, integer=True)

    if motion not in ("revolute", "prismatic", "static", "hinge", "depth", "swing", "globe"):
        raise InputError(f"unknown motion {motion!r} (revolute, prismatic, static, hinge, depth, swing or globe)")
    rng = np.random.default_rng(seed)
    w, h = size

    def texture(hh: int, ww: int) -> np.ndarray:
        t = cv2.GaussianBlur(rng.uniform(0, 255, (hh, ww)).astype(np.float32), (0, 0), 2.0)
        t = 255.0 * (t - t.min()) / max(float(np.ptp(t)), 1e-6)
        return cv2.cvtColor(t.astype(np.uint8), cv2.COLOR_GRAY2BGR)

    back = texture(h, w)
    part = texture(h, w)
    hand_tex = (texture(h, w).astype(np.float32) * [0.55, 0.7, 1.0]).astype(np.uint8) if hand else None
    mask = np.zeros((h, w), np.uint8)
    px, py = pivot
    pinhole = motion in ("hinge", "depth")
    if motion == "hinge":   # a lid standing on its hinge at the pivot's height
        corners = np.array([[px, py - 90], [px + 130, py - 90], [px + 130, py], [px, py]], np.float32)
    else:                   # (the corners of the part that the pinhole motions move)
        corners = np.array([[px, py - 30], [px + 90, py - 30], [px + 90, py + 30], [px, py + 30]], np.float32)
    if pinhole:
        cv2.fillConvexPoly(mask, corners.round().astype(np.int32), 255)
    elif motion == "swing":
        cv2.rectangle(mask, (int(px), int(py - 20)), (int(px + 60), int(py + 20)), 255, -1)
    else:
        cv2.rectangle(mask, (int(px), int(py - 22)), (int(px + 130), int(py + 22)), 255, -1)
    amount = ({"revolute": 60.0, "hinge": 60.0, "depth": 0.3, "swing": 25.0, "globe": 90.0}.get(motion, 80.0)
              if amount is None else amount)
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    focal = w / (2.0 * np.tan(np.radians(30.0)))
    centre = np.array([w / 2.0, h / 2.0])
    depth = 3.0 * focal                                  # the part's distance, in pixels at focal length

    def seen(q: float) -> np.ndarray:
        """The part's corners in the image after a motion of ``q`` (0..1) for the pinhole motions."""
        X = np.column_stack([(corners - centre) * depth / focal, np.full(4, depth)])   # camera coordinates
        if motion == "hinge":
            a = np.radians(amount * q)
            yh = (py - centre[1]) * depth / focal
            y, z = X[:, 1] - yh, X[:, 2] - depth
            X[:, 1], X[:, 2] = yh + y * np.cos(a) - z * np.sin(a), depth - y * np.sin(a) + z * np.cos(a)
        else:
            X[:, 2] -= amount * q * depth
        return (X[:, :2] / X[:, 2:] * focal + centre).astype(np.float32)

    if motion == "globe":
        globe = _globe(part, (w, h), pivot, amount)
    rest = frames // 6
    with atomic_path(path) as tmp:
        out = cv2.VideoWriter(cv2_name(tmp), cv2.VideoWriter.fourcc(*"MJPG"), fps, (w, h))
        if not out.isOpened():    # (a name OpenCV has no writer for: the file was left empty)
            raise InputError("cannot write an MJPG video under this name (give a name ending in .avi)", path=path)
        for f in range(frames):
            q = float(np.clip((f - rest) / max(frames - 2 * rest, 1), 0.0, 1.0))
            q = 0.5 - 0.5 * np.cos(np.pi * q)
            if motion == "globe":
                p, m = globe(q)
            elif pinhole:
                H = cv2.getPerspectiveTransform(corners, seen(q))
                p = cv2.warpPerspective(part, H, (w, h))
                m = cv2.warpPerspective(mask, H, (w, h)) > 127
            else:
                if motion in ("revolute", "swing"):
                    M = cv2.getRotationMatrix2D((px - (200.0 if motion == "swing" else 0.0), py), amount * q, 1.0)
                else:
                    s = amount * q if motion == "prismatic" else 0.0
                    M = np.array([[1.0, 0.0, s * d[0]], [0.0, 1.0, s * d[1]]])
                p = cv2.warpAffine(part, M, (w, h))
                m = cv2.warpAffine(mask, M, (w, h)) > 127
            img = back.copy()
            img[m] = p[m]
            if hand_tex is not None:
                # in from below at the start of the motion, over the part at its middle, out at its end
                u = (f - rest + 10) / max(frames - 2 * rest + 20, 1)
                if 0.0 < u < 1.0:
                    c = np.array([w * 0.3 + 0.4 * w * u, h + 40 - (h * 0.5 + 40) * np.sin(np.pi * u)])
                    g = np.zeros((h, w), np.uint8)
                    cv2.ellipse(g, (int(c[0]), int(c[1])), (34, 48), 20.0, 0.0, 360.0, 255, -1)
                    shift = np.array([[1, 0, c[0] - w / 2], [0, 1, c[1] - h / 2]], np.float32)
                    skin = cv2.warpAffine(hand_tex, shift, (w, h), borderMode=cv2.BORDER_REFLECT)
                    img[g > 0] = skin[g > 0]
            if exposure and f >= frames // 2:
                img = cv2.convertScaleAbs(img, alpha=0.75, beta=10.0)
            out.write(img)
        out.release()
        check_written_video(tmp, frames, where=path)     # (a full disk drops frames without a word)
    return path
