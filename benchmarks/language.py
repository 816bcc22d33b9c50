"""Benchmark of artmotion.language: accuracy and speed of grounding, speed of describe.

    .venv/bin/python benchmarks/language.py [--dataset out/bench/grounding] [--seed 0]

Makes the 156-example dataset when it is missing (needs espeak-ng), evaluates both models
(figures and report.json into docs/language/), times training and single queries, and rewrites
the block between the BENCH markers of docs/language.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from artmotion.io import atomic_write  # noqa: E402
from artmotion.language.describe import describe  # noqa: E402
from artmotion.language.grounding.dataset import make_dataset, read_index  # noqa: E402
from artmotion.language.grounding.evaluate import evaluate, load_features  # noqa: E402
from artmotion.language.grounding.features import audio_feature  # noqa: E402
from artmotion.language.grounding.model import Grounder  # noqa: E402
from artmotion.language.grounding.sparse import PairedSparse  # noqa: E402

BEGIN, END = "<!-- BENCH:BEGIN -->", "<!-- BENCH:END -->"


def ms(samples):
    return 1000 * statistics.median(samples)


def timed(fn, repeat=1):
    out = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return out


def synthetic_tracks(n_tracks=40, frames=300, seed=0):
    rng = np.random.default_rng(seed)
    rows = []
    for tid in range(1, n_tracks + 1):
        f0 = int(rng.integers(1, frames // 2))
        f1 = int(rng.integers(f0 + 30, frames + 1))
        x0, y0 = rng.uniform(0, 600), rng.uniform(0, 380)
        vx, vy = rng.normal(0, 2, 2)
        for f in range(f0, f1):
            rows.append([f, tid, x0 + vx * (f - f0), y0 + vy * (f - f0), 40, 100, 1, -1, -1, -1])
    return np.array(rows, float)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", default=str(ROOT / "out" / "bench" / "grounding"))
    ap.add_argument("--docs", default=str(ROOT / "docs" / "language.md"))
    ap.add_argument("--figures", default=str(ROOT / "docs" / "language"))
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    dataset = Path(args.dataset)

    t = {}
    if not (dataset / "index.csv").is_file():
        t["dataset"] = timed(lambda: make_dataset(dataset, seed=args.seed))[0]
    start = time.perf_counter()
    F = load_features(dataset)
    t["features"] = time.perf_counter() - start
    n = len(F["colors"])

    report = evaluate(dataset, args.figures, seed=args.seed, features=F)
    t["evaluation"] = report["seconds"]["evaluation"]

    # time the training of the models that the queries below use (Grounder.fit is the compositional
    # model on all examples plus its word prototypes)
    start = time.perf_counter()
    g = Grounder(seed=args.seed).fit(F)
    t["train_comp"] = time.perf_counter() - start
    X = np.hstack([F["color"], F["shape"]])
    start = time.perf_counter()
    paired = PairedSparse(seed=args.seed).fit(X, F["audio"])
    t["train_paired"] = time.perf_counter() - start
    a1, a2 = F["audio_seg"]
    q_comp = [timed(lambda i=i: g.speech_to_visual(a1[i], a2[i]))[0] for i in range(n)]
    q_paired = [timed(lambda i=i: paired.audio_to_visual(F["audio"][i]))[0] for i in range(n)]
    rows = read_index(dataset)[:20]
    g.speech_files_to_image(dataset / rows[0]["speech_color"], dataset / rows[0]["speech_shape"])  # warm-up
    q_file = [timed(lambda r=r: g.speech_files_to_image(dataset / r["speech_color"], dataset / r["speech_shape"]))[0] for r in rows]
    q_mfcc = [timed(lambda r=r: audio_feature(dataset / r["speech_color"]))[0] for r in rows]
    q_img = [timed(lambda r=r: g.image_to_speech(dataset / r["image"]))[0] for r in rows]
    tracks = synthetic_tracks()
    t_desc = timed(lambda: describe(tracks, image_size=(640, 480)), repeat=3)

    M = report["linking"]["vmeasure"]
    c, p = report["compositional"], report["paired"]
    lines = [
        BEGIN,
        f"_Measured {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC by `benchmarks/language.py` "
        f"(seed {args.seed}, {n} examples; {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} CPUs shared with other jobs, load average {os.getloadavg()[0]:.1f}; "
        f"Python {platform.python_version()}). Timings vary with the load._",
        "",
        "**Accuracy** (fractions of trials; retrieval: spoken colour/shape among the 5 nearest training "
        "examples, 3-fold CV; unseen: generated colour/shape recognised as the nearest prototype, "
        f"{len(report['holdouts'])} rounds of held-out pairs)",
        "",
        "| model | retrieval colour | retrieval shape | unseen colour | unseen shape | image→speech colour | image→speech shape |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, r in (("compositional", c), ("paired", p)):
        lines.append(
            f"| {name} | {r['retrieval']['color']:.3f} | {r['retrieval']['shape']:.3f} | {r['unseen']['color']:.3f} | "
            f"{r['unseen']['shape']:.3f} | {r['image_to_speech']['color']:.3f} | {r['image_to_speech']['shape']:.3f} |"
        )
    lines += [
        "",
        "Held-out pairs: " + "; ".join(", ".join(h) for h in report["holdouts"]) + ".",
        "",
        "**Table 5.1 from this data** — V-measure between the clusterings (k-means, k by silhouette) of "
        "each visual concept and each audio segment, on all examples:",
        "",
        "| | a1 (first word) | a2 (second word) |",
        "|---|---|---|",
        f"| v1 (mean RGB) | {M[0][0]:.2f} | {M[0][1]:.2f} |",
        f"| v2 (Fourier descriptor) | {M[1][0]:.2f} | {M[1][1]:.2f} |",
        "",
        f"Linking matrix by Hungarian assignment: H = {report['linking']['H']} (colour ↔ first word, shape ↔ second word).",
        "",
        "**Speed** (wall clock)",
        "",
        "| step | time |",
        "|---|---|",
    ]
    if "dataset" in t:
        lines.append(f"| make the dataset (156 images, 468 WAVs) | {t['dataset']:.1f} s |")
    lines += [
        f"| features of all examples (images + 3 WAVs each) | {t['features']:.1f} s |",
        f"| train compositional model on {n} examples (linking H + 2 paired models) | {t['train_comp']:.1f} s |",
        f"| train paired model on {n} examples | {t['train_paired']:.1f} s |",
        f"| whole evaluation (3 folds + {len(report['holdouts'])} hold-out rounds, both models) | {t['evaluation']:.1f} s |",
        f"| query: speech features → visual features, compositional (median of {n}) | {ms(q_comp):.2f} ms |",
        f"| query: speech features → visual features, paired (median of {n}) | {ms(q_paired):.2f} ms |",
        f"| query: two WAV files → rendered image, compositional (median of 20) | {ms(q_file):.1f} ms |",
        f"|   of which MFCC features of one WAV (median of 20) | {ms(q_mfcc):.1f} ms |",
        f"| query: image file → speech features and words (median of 20) | {ms(q_img):.1f} ms |",
        f"| `describe` 40 synthetic tracks × up to 300 frames | {ms(t_desc):.0f} ms |",
        END,
    ]
    block = "\n".join(lines)
    doc = Path(args.docs)
    text = doc.read_text(encoding="utf-8") if doc.exists() else ""
    if BEGIN in text and END in text:
        text = text[: text.index(BEGIN)] + block + text[text.index(END) + len(END):]
    else:
        text = text.rstrip() + "\n\n## Measured results\n\n" + block + "\n"
    with atomic_write(doc) as fh:
        fh.write(text)
    print(block)


if __name__ == "__main__":
    main()
