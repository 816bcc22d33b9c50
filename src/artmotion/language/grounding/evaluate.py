"""Evaluation of the grounding models (thesis 5.5): retrieval by 3-fold CV and unseen pairs.

Retrieval (5.5.3): the dataset is split in 3 folds; a model learned on two folds generates visual
features from each test example's speech; the ``k = 5`` training examples nearest to the generated
features (l1 distance in the colour subspace, resp. the shape subspace) are retrieved, and the
trial succeeds when the spoken colour (shape) is among them.

Generalisation (5.5.4): every example of some colour–shape pairs is held out (three rounds of four
pairs; the first is the thesis's blue circle, green rectangle, red square, yellow halfcircle), the
models learn from the rest and generate visual features from the held-out speech; the generated
colour (shape) is recognised as the nearest colour (shape) prototype, the mean feature of that
colour (shape) over the training examples. Confusion matrices and rendered images are saved.

The compositional model hears the words one by one (segmented audio) and links them to colour and
shape by ``H``; the paired model hears the whole utterance and generates colour and shape at once.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
from sklearn.model_selection import KFold

from artmotion.errors import InputError
from artmotion.io import atomic_dir, atomic_write, save_figure
from artmotion.io.atomic import check_apart, check_out_dir, outputs_of
from artmotion.io.media import depth_note, frame_depth, read_frame, read_image
from artmotion.language.grounding.dataset import COLORS, SHAPES, read_index
from artmotion.language.grounding.features import audio_feature, render_shape, visual_features
from artmotion.language.grounding.sparse import CompositionalSparse, PairedSparse, estimate_linking

#: Held-out colour–shape pairs, one round per line; every colour and shape stays in training.
HOLDOUTS = (
    (("blue", "circle"), ("green", "rectangle"), ("red", "square"), ("yellow", "halfcircle")),
    (("blue", "triangle"), ("green", "circle"), ("red", "halfcircle"), ("yellow", "square")),
    (("blue", "square"), ("green", "triangle"), ("red", "rectangle"), ("yellow", "circle")),
)


def input_folders(dataset: str | os.PathLike) -> set[Path]:
    """The folders that hold the images and speech of ``DATASET/index.csv`` (an output written in
    one of them would become an input, or replace the folder with them)."""
    dataset = Path(dataset)
    base = dataset if dataset.is_dir() else dataset.parent
    return {(base / r[c]).parent for r in read_index(dataset) for c in ("image", "speech", "speech_color", "speech_shape")}


def load_features(dataset: str | os.PathLike, progress=None) -> dict:
    """Features of every example in ``DATASET/index.csv``; bad items raise :class:`InputError`."""
    dataset = Path(dataset)
    rows = read_index(dataset)
    base = dataset if dataset.is_dir() else dataset.parent
    # 16-bit images at the depth images spread over the dataset imply (a 12-bit camera's read by
    # their top 8 bits were nearly black: colour 0.05 instead of 0.87), as pose reads its crops
    depth = frame_depth([base / r["image"] for r in rows])
    C, S, A, A1, A2 = [], [], [], [], []
    for n, r in enumerate(rows):
        img_path = base / r["image"]
        c, s = visual_features(read_frame(img_path, depth[0] if depth else None), where=str(img_path))
        C.append(c)
        S.append(s)
        A.append(audio_feature(base / r["speech"]))
        A1.append(audio_feature(base / r["speech_color"]))
        A2.append(audio_feature(base / r["speech_shape"]))
        if progress:
            progress(n + 1, len(rows))
    return {
        "color": np.array(C), "shape": np.array(S), "audio": np.array(A),
        "audio_seg": [np.array(A1), np.array(A2)],
        "colors": np.array([r["color"] for r in rows]), "shapes": np.array([r["shape"] for r in rows]),
        "ids": [r["id"] for r in rows],
        "images": [str(base / r["image"]) for r in rows],
        "depth": depth,
    }


def _fit_both(F: dict, idx: np.ndarray, seed: int) -> tuple[CompositionalSparse, PairedSparse]:
    comp = CompositionalSparse(seed=seed).fit([F["color"][idx], F["shape"][idx]], [a[idx] for a in F["audio_seg"]])
    paired = PairedSparse(seed=seed).fit(np.hstack([F["color"][idx], F["shape"][idx]]), F["audio"][idx])
    return comp, paired


def _generate(comp, paired, F, idx) -> dict:
    gc, gs = comp.audio_to_visual([a[idx] for a in F["audio_seg"]])
    gp = paired.audio_to_visual(F["audio"][idx])
    return {"compositional": (gc, gs), "paired": (gp[:, :3], gp[:, 3:])}


def _l1(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs(a[:, None, :] - b[None, :, :]).sum(axis=2)


def retrieval(F: dict, *, folds: int = 3, k: int = 5, seed: int = 0, example_pair: str = "blue halfcircle") -> dict:
    """Top-``k`` retrieval success rates of colour and shape for both models (3-fold CV)."""
    n = len(F["colors"])
    if n < 2 * folds:
        raise InputError(f"too few examples ({n}) for {folds}-fold cross-validation")
    hits: dict[str, dict[str, list]] = {m: {"color": [], "shape": []} for m in ("compositional", "paired")}
    speech: dict[str, dict[str, list]] = {m: {"color": [], "shape": []} for m in ("compositional", "paired")}
    example: dict = {}  # Fig 5.8: one utterance, its generated features and retrieved neighbours
    pair = np.char.add(np.char.add(F["colors"], " "), F["shapes"])
    found = np.flatnonzero(pair == example_pair)
    want = int(found[0]) if len(found) else 0
    for tr, te in KFold(folds, shuffle=True, random_state=seed).split(np.arange(n)):
        comp, paired = _fit_both(F, tr, seed)
        for model, (gc, gs) in _generate(comp, paired, F, te).items():
            for concept, gen, db, labels in (
                ("color", gc, F["color"][tr], F["colors"]), ("shape", gs, F["shape"][tr], F["shapes"])
            ):
                nn = np.argsort(_l1(gen, db), axis=1, kind="stable")[:, :k]
                hits[model][concept] += [labels[te[i]] in set(labels[tr][nn[i]]) for i in range(len(te))]
                if want in te:
                    i = int(np.flatnonzero(te == want)[0])
                    ex = example.setdefault(model, {"utterance": str(pair[want]), "color": gc[i], "shape": gs[i]})
                    ex["neighbours_" + concept] = [int(j) for j in tr[nn[i]]]
        # image -> speech: recognise the generated words by the nearest word prototype
        seg = comp.visual_to_audio([F["color"][te], F["shape"][te]])
        for concept, gen, ref, labels in (
            ("color", seg[0], F["audio_seg"][0][tr], F["colors"]), ("shape", seg[1], F["audio_seg"][1][tr], F["shapes"])
        ):
            speech["compositional"][concept] += list(_nearest_label(gen, ref, labels[tr]) == labels[te])
        gen = paired.visual_to_audio(np.hstack([F["color"][te], F["shape"][te]]))
        pred = _nearest_label(gen, F["audio"][tr], pair[tr])
        speech["paired"]["color"] += [p.split()[0] == c for p, c in zip(pred, F["colors"][te])]
        speech["paired"]["shape"] += [p.split()[1] == s for p, s in zip(pred, F["shapes"][te])]
    rate = lambda d: {c: float(np.mean(v)) for c, v in d.items()}  # noqa: E731
    out = {m: {"retrieval": rate(hits[m]), "image_to_speech": rate(speech[m])} for m in hits}
    out["example"] = example
    return out


def _nearest_label(gen: np.ndarray, ref: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Label of the nearest prototype (mean of ``ref`` per label, l1 distance)."""
    names = np.unique(labels)
    protos = np.array([ref[labels == c].mean(axis=0) for c in names])
    return names[np.argmin(_l1(gen, protos), axis=1)]


def holdout_rounds(colors, shapes, holdouts=HOLDOUTS, path=None) -> list[tuple[list, np.ndarray]]:
    """The rounds of the unseen-pair test that the labels allow: each round's held-out pairs present
    in the data, and which examples they hold out. An :class:`InputError` naming ``path`` when no
    held-out pair is in the data, or when holding a round's pairs out leaves a colour or a shape
    without a training example. Labels only: checked before any feature is computed."""
    colors, shapes = np.asarray(colors, dtype=str), np.asarray(shapes, dtype=str)
    present = set(zip(colors.tolist(), shapes.tolist()))
    rounds = []
    for pairs in holdouts:
        pairs = [tuple(p) for p in pairs if tuple(p) in present]
        if not pairs:
            continue
        held = np.array([(c, s) in pairs for c, s in zip(colors.tolist(), shapes.tolist())])
        lost = (set(colors[held]) - set(colors[~held])) | (set(shapes[held]) - set(shapes[~held]))
        if lost:
            raise InputError(f"holding out {', '.join(' '.join(p) for p in pairs)} (the unseen-pair test) leaves no "
                             f"training example of {', '.join(sorted(lost))}", path=path)
        rounds.append((pairs, held))
    if not rounds:
        every = sorted({" ".join(p) for pairs in holdouts for p in pairs})
        raise InputError(f"no colour–shape pair of the unseen-pair test is in the dataset (it holds out "
                         f"{', '.join(every)})", path=path)
    return rounds


def unseen(F: dict, *, holdouts=HOLDOUTS, seed: int = 0) -> dict:
    """Recognition of colour and shape generated from the speech of held-out colour–shape pairs."""
    res: dict[str, dict[str, list]] = {m: {"true": [], "color": [], "shape": [], "renders": []}
                                       for m in ("compositional", "paired")}
    used = []
    for rnd, (pairs, held) in enumerate(holdout_rounds(F["colors"], F["shapes"], holdouts)):
        tr, te = np.flatnonzero(~held), np.flatnonzero(held)
        used.append([" ".join(p) for p in pairs])
        comp, paired = _fit_both(F, tr, seed)
        for model, (gc, gs) in _generate(comp, paired, F, te).items():
            pc = _nearest_label(gc, F["color"][tr], F["colors"][tr])
            ps = _nearest_label(gs, F["shape"][tr], F["shapes"][tr])
            r = res[model]
            r["true"] += [(F["colors"][i], F["shapes"][i]) for i in te]
            r["color"] += list(pc)
            r["shape"] += list(ps)
            if rnd == 0:  # one rendered image per held-out pair (its first example)
                for p in pairs:
                    i = next(j for j, t in enumerate(te) if (F["colors"][t], F["shapes"][t]) == tuple(p))
                    r["renders"].append((" ".join(p), gc[i], gs[i]))
    out: dict[str, Any] = {}
    for model, r in res.items():
        tc = [t[0] for t in r["true"]]
        ts = [t[1] for t in r["true"]]
        out[model] = {
            "color": float(np.mean([a == b for a, b in zip(tc, r["color"])])),
            "shape": float(np.mean([a == b for a, b in zip(ts, r["shape"])])),
            "confusion": {
                "color": _confusion(tc, r["color"], COLORS),
                "shape": _confusion(ts, r["shape"], SHAPES),
            },
            "renders": r["renders"],
            "n": len(tc),
        }
    out["holdouts"] = used
    return out


def _confusion(true, pred, names) -> list[list[int]]:
    ix = {n: i for i, n in enumerate(names)}
    M = np.zeros((len(names), len(names)), int)
    for t, p in zip(true, pred):
        M[ix[t], ix[p]] += 1
    return M.tolist()


# ---------------------------------------------------------------------------------------------
# figures


#: the figures :func:`save_figures` may write (some only when their data are there)
FIGURES = ("fourier_harmonics.png", "retrieval.png", "retrieval_example.png", "unseen_renders.png",
           "unseen_confusion.png")


def save_figures(report: dict, F: dict, out: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    # Fig 5.7: a triangle's contour from 2 and 10 harmonics
    tri = np.flatnonzero(F["shapes"] == "triangle")
    if len(tri):
        coeffs = F["shape"][tri[0]].reshape(-1, 4)
        fig, axes = plt.subplots(1, 3, figsize=(7.5, 2.7))
        for ax, h in zip(axes, (2, 10, 20)):
            c = coeffs.copy()
            c[h:] = 0
            ax.imshow(render_shape(c.ravel(), F["color"][tri[0]]))
            ax.set_title(f"{h} harmonics")
            ax.axis("off")
        save_figure(fig, out / "fourier_harmonics.png", dpi=110, bbox_inches="tight")
        written.append("fourier_harmonics.png")
    # Fig 5.9: retrieval
    fig, axes = plt.subplots(1, 2, figsize=(7, 2.8))
    for ax, concept in zip(axes, ("shape", "color")):
        vals = [report[m]["retrieval"][concept] for m in ("compositional", "paired")]
        ax.bar(["compositional", "paired"], vals, color=["tab:blue", "tab:gray"])
        ax.set_ylim(0, 1.05)
        ax.set_title(f"{concept}: correct in top 5")
        for x, v in enumerate(vals):
            ax.text(x, v + 0.02, f"{v:.2f}", ha="center")
    save_figure(fig, out / "retrieval.png", dpi=110, bbox_inches="tight")
    written.append("retrieval.png")
    # Fig 5.8: one utterance, the image generated from it and the retrieved neighbours
    ex = report.get("_example") or {}
    if ex and "images" in F:
        fig, axes = plt.subplots(2, 9, figsize=(15, 3.8), squeeze=False)
        for r, model in enumerate(("compositional", "paired")):
            e = ex[model]
            axes[r][0].imshow(render_shape(e["shape"], e["color"]))
            axes[r][0].set_title(f'{model}\n"{e["utterance"]}"', fontsize=8)
            for c, (concept, idx) in enumerate((("color", e["neighbours_color"][:4]), ("shape", e["neighbours_shape"][:4]))):
                for j, i in enumerate(idx):
                    ax = axes[r][1 + 4 * c + j]
                    ax.imshow(read_image(F["images"][i])[:, :, ::-1])
                    ax.set_title(f"{concept} #{j + 1}: {F['colors'][i]} {F['shapes'][i]}", fontsize=7)
            for ax in axes[r]:
                ax.axis("off")
        fig.tight_layout()
        save_figure(fig, out / "retrieval_example.png", dpi=72, bbox_inches="tight")
        written.append("retrieval_example.png")
    # Fig 5.10: images generated from unseen utterances
    un = report["_unseen"]
    renders = {m: un[m]["renders"] for m in ("compositional", "paired")}
    ncol = len(renders["compositional"])
    if ncol:
        fig, axes = plt.subplots(2, ncol, figsize=(2.2 * ncol, 4.6), squeeze=False)
        for r, model in enumerate(("compositional", "paired")):
            for c, (name, col, shp) in enumerate(renders[model]):
                ax = axes[r][c]
                ax.imshow(render_shape(shp, col))
                ax.set_title(f'"{name}"' if r == 0 else "", fontsize=9)
                ax.set_xticks([])
                ax.set_yticks([])
                if c == 0:
                    ax.set_ylabel(model)
        save_figure(fig, out / "unseen_renders.png", dpi=110, bbox_inches="tight")
        written.append("unseen_renders.png")
    # Fig 5.11: confusion matrices of recognised colour and shape on unseen pairs
    fig, axes = plt.subplots(2, 2, figsize=(10, 8.5))
    for c, model in enumerate(("compositional", "paired")):
        for r, (concept, names) in enumerate((("color", COLORS), ("shape", SHAPES))):
            M = np.array(un[model]["confusion"][concept])
            rows = [i for i in range(len(names)) if M[i].sum()]
            ax = axes[r][c]
            ax.imshow(M[rows], cmap="Blues", vmin=0)
            ax.set_xticks(range(len(names)), names, rotation=60, fontsize=8)
            ax.set_yticks(range(len(rows)), [names[i] for i in rows], fontsize=8)
            for y, i in enumerate(rows):
                for x in range(len(names)):
                    if M[i, x]:
                        ax.text(x, y, str(M[i, x]), ha="center", va="center", fontsize=8)
            ax.set_title(f"{model}: {concept} ({un[model][concept]:.2f})", fontsize=10)
            ax.set_xlabel("recognised")
    fig.tight_layout()
    save_figure(fig, out / "unseen_confusion.png", dpi=110, bbox_inches="tight")
    written.append("unseen_confusion.png")
    return written


# ---------------------------------------------------------------------------------------------


def evaluate(dataset: str | os.PathLike, out: str | os.PathLike | None = None, *, seed: int = 0,
             features: dict | None = None, holdouts=HOLDOUTS, figures: bool = True) -> dict:
    """Run both evaluations; write ``report.json`` and PNGs under ``out`` (if given)."""
    # an earlier report is replaced: a folder of its outputs by name (any PNG of the user's there
    # keeps the folder theirs), never a folder holding the dataset's images or speech
    earlier = outputs_of("report.json", FIGURES, ("linking", "holdouts"))
    outputs = ("report.json",) + (FIGURES if figures else ())
    if out is not None:
        check_out_dir(out, replace=earlier, outputs=outputs)     # before the work, not after it
        check_apart(out, input_folders(dataset))
    t0 = time.perf_counter()
    F = features if features is not None else load_features(dataset)
    t_feat = time.perf_counter() - t0
    if len(F["colors"]) < 6:
        raise InputError(f"too few examples ({len(F['colors'])}) to evaluate: at least 6 are needed", path=dataset)
    holdout_rounds(F["colors"], F["shapes"], holdouts, path=dataset)     # (before the models' fits)
    H, M = estimate_linking([F["color"], F["shape"]], F["audio_seg"], seed=seed)
    t1 = time.perf_counter()
    ret = retrieval(F, seed=seed)
    un = unseen(F, holdouts=holdouts, seed=seed)
    t_eval = time.perf_counter() - t1
    report: dict[str, Any] = {
        m: {
            "retrieval": ret[m]["retrieval"],
            "unseen": {"color": un[m]["color"], "shape": un[m]["shape"]},
            "image_to_speech": ret[m]["image_to_speech"],
            "unseen_confusion": un[m]["confusion"],
        }
        for m in ("compositional", "paired")
    }
    report["linking"] = {
        "visual": ["color (RGB)", "shape (Fourier)"], "audio": ["segment 1", "segment 2"],
        "vmeasure": np.round(M, 3).tolist(), "H": H.tolist(),
    }
    report["holdouts"] = un["holdouts"]
    report["n_examples"] = int(len(F["colors"]))
    report["note"] = depth_note(F.get("depth")) or None     # how 16-bit images were read (None: as 8-bit ones)
    report["seconds"] = {"features": round(t_feat, 2), "evaluation": round(t_eval, 2)}
    if out is not None:
        out = Path(out)
        # a new folder appears only with every figure and the report in it
        with atomic_dir(out, replace=earlier, outputs=outputs) as dst:
            report["_unseen"], report["_example"] = un, ret["example"]
            report["figures"] = save_figures(report, F, dst) if figures else []
            del report["_unseen"], report["_example"]
            with atomic_write(dst / "report.json") as fh:
                json.dump(report, fh, indent=1)
        report["out"] = str(out)
    return report


def format_report(report: dict) -> str:
    lines = [f"{report['n_examples']} examples; linking V-measure (rows colour, shape; columns segment 1, 2): "
             f"{report['linking']['vmeasure']}  H = {report['linking']['H']}",
             f"{'model':<14} {'retrieval colour':>16} {'retrieval shape':>16} {'unseen colour':>14} {'unseen shape':>13}"]
    for m in ("compositional", "paired"):
        r = report[m]
        lines.append(f"{m:<14} {r['retrieval']['color']:>16.3f} {r['retrieval']['shape']:>16.3f} "
                     f"{r['unseen']['color']:>14.3f} {r['unseen']['shape']:>13.3f}")
    lines.append("held out: " + "; ".join(", ".join(r) for r in report["holdouts"]))
    if "out" in report:
        lines.append(f"report and figures in {report['out']}")
    return "\n".join(lines)
