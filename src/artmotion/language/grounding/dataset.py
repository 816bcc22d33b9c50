"""The shapes-and-colours grounding dataset (thesis 5.5.1, Table 5.2).

156 examples: an image of one coloured shape lying on a table-like background, at a random
rotation, position and scale, with camera noise (illumination gradient, blur, sensor noise); and
machine speech of "<colour> <shape>" from espeak-ng at random speeds, both as one utterance and
word by word (segmented audio). ``index.csv`` lists every example's files and labels; features are
computed by :mod:`artmotion.language.grounding.features`.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np

from artmotion.errors import InputError, check_seed
from artmotion.io import atomic_dir, atomic_path, atomic_write
from artmotion.io.atomic import outputs_of
from artmotion.io.media import write_image
from artmotion.io.table import cell_number, read_csv

COLORS = ("blue", "green", "red", "yellow")
SHAPES = ("circle", "halfcircle", "rectangle", "rhombus", "square", "triangle", "trapezium", "hexagon")

#: Table 5.2: examples per shape (rows) and colour (blue, green, red, yellow).
TABLE_5_2 = {
    "circle": (6, 6, 2, 6),
    "halfcircle": (6, 4, 4, 4),
    "rectangle": (6, 6, 6, 2),
    "rhombus": (10, 0, 0, 0),
    "square": (10, 10, 10, 10),
    "triangle": (8, 6, 8, 6),
    "trapezium": (0, 0, 10, 0),
    "hexagon": (0, 0, 0, 10),
}

#: What espeak-ng is asked to say for each word.
SPOKEN = {"halfcircle": "half circle"}

_RGB = {"blue": (35, 75, 200), "green": (40, 150, 65), "red": (205, 40, 40), "yellow": (230, 200, 35)}

INDEX_COLUMNS = (
    "id", "image", "speech", "speech_color", "speech_shape", "color", "shape",
    "rotation", "scale", "x", "y", "speed", "speed_color", "speed_shape",
)


#: the index's numeric columns (where an example's shape is drawn, how it moves)
NUMBERS = ("rotation", "scale", "x", "y", "speed", "speed_color", "speed_shape")


def counts(table: dict | None = None) -> list[tuple[str, str, int]]:
    """``(colour, shape, n)`` for every non-empty cell of ``table`` (default Table 5.2)."""
    table = TABLE_5_2 if table is None else table
    return [(c, s, n) for s, row in table.items() for c, n in zip(COLORS, row) if n]


def shape_polygon(shape: str, n: int = 160) -> np.ndarray:
    """Unit-size outline of a shape, ``(N, 2)``, centred on its centroid."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    if shape == "circle":
        p = np.column_stack([np.cos(t), np.sin(t)])
    elif shape == "halfcircle":
        a = np.linspace(0, np.pi, n // 2)
        p = np.vstack([np.column_stack([np.cos(a), np.sin(a)]), [[-1, 0], [0, 0], [1, 0]]])
    elif shape == "rectangle":
        p = np.array([[-1, -0.5], [1, -0.5], [1, 0.5], [-1, 0.5]])
    elif shape == "square":
        p = np.array([[-0.8, -0.8], [0.8, -0.8], [0.8, 0.8], [-0.8, 0.8]])
    elif shape == "rhombus":
        p = np.array([[-1.1, 0], [0, -0.62], [1.1, 0], [0, 0.62]])
    elif shape == "triangle":
        a = np.pi / 2 + np.arange(3) * 2 * np.pi / 3
        p = 1.1 * np.column_stack([np.cos(a), np.sin(a)])
    elif shape == "trapezium":
        p = np.array([[-1.1, -0.45], [1.1, -0.45], [0.55, 0.45], [-0.55, 0.45]])
    elif shape == "hexagon":
        a = np.arange(6) * np.pi / 3
        p = np.column_stack([np.cos(a), np.sin(a)])
    else:
        raise ValueError(f"unknown shape {shape!r}")
    return p - p.mean(axis=0) if shape != "halfcircle" else p - np.array([0, 4 / (3 * np.pi)])


def table_background(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """A low-saturation wood-like table top (float RGB 0..255)."""
    base = np.array([172, 158, 138], float) + rng.normal(0, 4, 3)
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    ang = rng.uniform(-0.3, 0.3)
    u = xx * np.cos(ang) + yy * np.sin(ang)
    grain = 6 * np.sin(u / rng.uniform(5, 11) + 2 * np.sin(yy / rng.uniform(25, 60)))
    grain += 4 * np.sin(u / rng.uniform(1.5, 3.0))
    img = base[None, None, :] + grain[..., None] * np.array([1.0, 0.95, 0.85])
    return img


def render_example(rng: np.random.Generator, color: str, shape: str, h: int = 240, w: int = 320):
    """An image (BGR uint8) of one shape and its pose ``(rotation_deg, scale_px, x, y)``."""
    img = table_background(rng, h, w)
    scale = rng.uniform(28, 52)
    rot = rng.uniform(0, 360)
    r = np.deg2rad(rot)
    R = np.array([[np.cos(r), -np.sin(r)], [np.sin(r), np.cos(r)]])
    poly = shape_polygon(shape) @ R.T * scale
    ext = np.abs(poly).max(axis=0) + 6
    cx = rng.uniform(ext[0], w - ext[0])
    cy = rng.uniform(ext[1], h - ext[1])
    pts = poly + [cx, cy]
    rgb = np.clip(np.array(_RGB[color], float) + rng.normal(0, 10, 3), 0, 255)
    layer = np.zeros((h, w), np.uint8)
    cv2.fillPoly(layer, [np.round(pts * 16).astype(np.int32)], 255, lineType=cv2.LINE_AA, shift=4)
    alpha = layer.astype(float)[..., None] / 255.0
    # a soft shadow to the lower right, then the shape
    shadow = cv2.GaussianBlur(np.roll(layer, (4, 4), axis=(0, 1)).astype(float) / 255.0, (9, 9), 3)[..., None]
    img = img * (1 - 0.25 * shadow)
    img = img * (1 - alpha) + rgb[None, None, :] * alpha
    # camera: illumination gradient, blur, sensor noise
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    g = rng.uniform(0.85, 1.05) + rng.uniform(-0.12, 0.12) * (xx / w - 0.5) + rng.uniform(-0.12, 0.12) * (yy / h - 0.5)
    img = img * g[..., None]
    img = cv2.GaussianBlur(img, (3, 3), rng.uniform(0.4, 1.0))
    img = img + rng.normal(0, rng.uniform(2, 6), img.shape)
    bgr = np.clip(img, 0, 255).astype(np.uint8)[:, :, ::-1].copy()
    return bgr, (rot, scale, cx, cy)


def espeak_path() -> str:
    """Path of espeak-ng (or espeak); :class:`InputError` saying how to install it if missing."""
    exe = shutil.which("espeak-ng") or shutil.which("espeak")
    if exe is None:
        raise InputError(
            "espeak-ng is not installed; it speaks the dataset's words "
            "(install it with 'apt-get install espeak-ng' or 'make system-deps')"
        )
    return exe


def speak(text: str, path: str | os.PathLike, speed: int, exe: str | None = None) -> None:
    """Write ``text`` spoken at ``speed`` words per minute to a WAV file, atomically.

    espeak-ng writes the WAV to its standard output and this process writes the file: espeak-ng
    writing a file itself says nothing of a full disk (it exits 0 with the speech cut where the
    room ended and a header made to match). On a pipe it cannot go back to fill in the header's
    sizes, so they are set here."""
    exe = exe or espeak_path()
    try:
        proc = subprocess.run([exe, "-v", "en-us", "-s", str(int(speed)), "--stdout", text],
                              capture_output=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise InputError(f"espeak-ng failed: {exc}", path=path) from None
    wav = bytearray(proc.stdout)
    data = wav.find(b"data", 12, 200)
    if proc.returncode != 0 or wav[:4] != b"RIFF" or wav[8:12] != b"WAVE" or data < 0 or len(wav) < 100:
        msg = proc.stderr.decode("utf-8", "replace").strip().splitlines()
        raise InputError(f"espeak-ng failed: {msg[0] if msg else 'no audio written'}", path=path)
    wav[4:8] = (len(wav) - 8).to_bytes(4, "little")
    wav[data + 4:data + 8] = (len(wav) - data - 8).to_bytes(4, "little")
    with atomic_path(path, suffix=".wav") as tmp:
        tmp.write_bytes(wav)


#: the file that marks a folder as a dataset this command made (what it was made from)
MARKER = "dataset.json"
#: what a dataset folder holds
DATASET = frozenset({"images", "speech", "index.csv", MARKER})
#: an earlier dataset of this command, and nothing else: it is then replaced whole. The marker is
#: what tells it from a dataset of the user's own recordings in the same layout (images/, speech/,
#: index.csv: what ``grounding eval`` reads), which is never replaced
_is_dataset = outputs_of(MARKER, DATASET, ("seed", "examples"),
                         inside={"images": rf"\d{{3,}}_({'|'.join(COLORS)})_({'|'.join(SHAPES)})\.png",
                                 "speech": r"\d{3,}_(full|color|shape)\.wav"})


def make_dataset(out: str | os.PathLike, seed: int = 0, table: dict | None = None) -> Path:
    """Write the 156 examples under ``out`` (images/, speech/, index.csv, and dataset.json, which
    says it was made here); return the index path.

    ``table`` (shape -> counts per colour in :data:`COLORS` order) replaces Table 5.2, e.g. for a
    smaller test set.
    """
    check_seed(seed)
    exe = espeak_path()
    out = Path(out)
    with atomic_dir(out, replace=_is_dataset, outputs=DATASET) as tmp:
        examples = _write_examples(tmp, seed, table, exe)
        with atomic_write(tmp / MARKER) as fh:
            json.dump({"made_by": "artmotion grounding dataset", "seed": seed, "examples": examples}, fh)
    index = out / "index.csv"
    return index


def _write_examples(out: Path, seed: int, table: dict | None, exe: str) -> int:
    """The examples' images, speech and index.csv in ``out``; how many."""
    rng = np.random.default_rng(seed)
    items = [(c, s) for c, s, n in counts(table) for _ in range(n)]
    order = rng.permutation(len(items))
    rows = []
    for i, k in enumerate(order):
        color, shape = items[k]
        ex = f"{i:03d}"
        img, (rot, scale, x, y) = render_example(rng, color, shape)
        img_rel = f"images/{ex}_{color}_{shape}.png"
        write_image(out / img_rel, img)
        speeds = rng.integers(110, 221, size=3)
        words = (color, SPOKEN.get(shape, shape))
        rel = (f"speech/{ex}_full.wav", f"speech/{ex}_color.wav", f"speech/{ex}_shape.wav")
        speak(" ".join(words), out / rel[0], speeds[0], exe)
        speak(words[0], out / rel[1], speeds[1], exe)
        speak(words[1], out / rel[2], speeds[2], exe)
        rows.append(
            dict(zip(INDEX_COLUMNS, (
                ex, img_rel, rel[0], rel[1], rel[2], color, shape,
                f"{rot:.1f}", f"{scale:.1f}", f"{x:.1f}", f"{y:.1f}", *map(int, speeds),
            )))
        )
    index = out / "index.csv"
    with atomic_write(index) as fh:
        w = csv.DictWriter(fh, fieldnames=INDEX_COLUMNS, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    return len(rows)


def read_index(dataset: str | os.PathLike) -> list[dict]:
    """Rows of ``DATASET/index.csv``; :class:`InputError` naming the file and line if malformed."""
    dataset = Path(dataset)
    index = dataset / "index.csv" if dataset.is_dir() else dataset
    if not index.is_file():
        raise InputError("no index.csv (make one with 'artmotion grounding dataset')", path=index)
    need = ("id", "image", "speech", "speech_color", "speech_shape", "color", "shape")
    header, table = read_csv(index, need=need, what="grounding index CSV")
    rows = []
    seen: set[str] = set()
    for lineno, values in table:
        row: dict[str, str | int] = dict(zip(header, values))
        if any(not row[c] for c in need):
            raise InputError("empty field", path=index, line=lineno)
        # labels checked here, before the features of every example are computed
        for column, known in (("color", COLORS), ("shape", SHAPES)):
            if row[column] not in known:
                raise InputError(f"{column} {row[column]!r} is none of {', '.join(known)}", path=index, line=lineno)
        if row["id"] in seen:
            raise InputError(f"id {row['id']!r} appears twice", path=index, line=lineno)
        seen.add(str(row["id"]))
        for column in NUMBERS:
            if row.get(column):
                cell_number(str(row[column]), column, index, lineno, -1e6, 1e6)
        row["_line"] = lineno
        rows.append(row)
    if not rows:
        raise InputError("index has no examples", path=index)
    return rows
