"""CLI commands of :mod:`artmotion.pose` (registered on the root app by :func:`register`).

``artmotion pose render|train|predict|eval``; see docs/pose.md.
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Optional

import typer

from artmotion.errors import InputError, check_range, check_seed

if TYPE_CHECKING:
    import numpy as np

pose_app = typer.Typer(
    name="pose",
    help="Joint angles of an articulated tool from its bounding-box crop (GP regression + Kalman filter).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


BOXES_HELP = ("CSV 'image,x,y,w,h,frame_w,frame_h' (pose render writes boxes.csv): where each crop lies in its "
              "frame; the cnn feature then learns the camera's perspective. Only with --feature cnn (hog and lbp "
              "do not use it: an error).")
KEYPOINTS_HELP = ("CSV 'image,<point>_x,<point>_y,...' in pixels of each crop (pose render writes keypoints.csv): "
                  "the tool's points, which the cnn feature's network learns to find besides the angles (training "
                  "only; both cells empty: not known). Only with --feature cnn (an error with hog and lbp).")
EVAL_KEYPOINTS_HELP = ("CSV 'image,<point>_x,<point>_y,...' of IMAGES' crops (pose render writes keypoints.csv): "
                       "the cnn feature's network learns to find them in every fold's training (hog and lbp ignore "
                       "them; an error without --feature cnn).")
PREDICT_BOXES_HELP = ("CSV 'image,x,y,w,h,frame_w,frame_h' of the crops: needed by a model trained with --boxes, "
                      "an error with any other model (it would not use them).")


def _views(boxes: Path | None, paths) -> np.ndarray | None:
    from artmotion.pose.data import read_views

    return None if boxes is None else read_views(boxes, paths)


@pose_app.command("render")
def render_cmd(
    out: Path = typer.Argument(..., help="Output folder: crops/, labels.csv, keypoints.csv, frames/, boxes.csv, "
                                         "rendering.json."),
    poses: int = typer.Option(4000, "--poses", help="Number of frames (poses) of the sequence."),
    seed: int = typer.Option(0, "--seed", help="Random seed; a seed always gives the same images."),
    dark: bool = typer.Option(False, "--dark", help="Render a low-light sequence."),
    frames: bool = typer.Option(True, "--frames/--no-frames", help="Also write whole frames and boxes.csv."),
    motion: str = typer.Option("script", "--motion",
                               help="script (pick and place) or cover (even coverage of the joint ranges: training sets)."),
    scenes: int = typer.Option(1, "--scenes", help="Backgrounds (tissue and tint), each for an equal stretch of frames."),
    style: str = typer.Option("default", "--style",
                              help="Look of tool and tissue: default; alt (yellow tissue, brass jaws, lighter "
                                   "stem); random (a random look per scene). The same motion for a seed."),
):
    """Render a sequence of a two-jaw grasper seen by an endoscope."""
    from artmotion.pose.render import write_dataset

    t = time.perf_counter()
    write_dataset(out, poses, seed, dark, frames, progress=True, motion=motion, scenes=scenes, style=style)
    typer.echo(f"wrote {poses} crops and labels to {out} ({time.perf_counter() - t:.1f} s)")


@pose_app.command("train")
def train_cmd(
    images: Optional[Path] = typer.Argument(None, help="Folder of crops (any size): one sequence."),
    labels: Optional[Path] = typer.Argument(None, help="CSV 'image,<angle name>,...' in degrees."),
    model: Path = typer.Option(..., "--model", help="Model file to write (.npz)."),
    feature: str = typer.Option("hog", "--feature", help="hog, lbp or cnn (a small network trained here; needs PyTorch)."),
    boxes: Optional[Path] = typer.Option(None, "--boxes", help=BOXES_HELP),
    keypoints: Optional[Path] = typer.Option(None, "--keypoints", help=KEYPOINTS_HELP),
    sets: Optional[list[Path]] = typer.Option(None, "--set", help=(
        "A further training sequence: a folder as 'pose render' writes it (crops/, labels.csv and, for every set or "
        "none, boxes.csv: only --feature cnn uses it). Repeatable; the variance is calibrated on the end of every "
        "sequence.")),
    set_keypoints: bool = typer.Option(False, "--set-keypoints", help=(
        "Also learn the keypoints of each --set folder's keypoints.csv (cnn only; a set without one trains the "
        "angles only). Off by default: over six trainings a wash on average (docs/pose.md).")),
    method: str = typer.Option("auto", "--method", help="auto, exact or sparse GP."),
    inducing: int = typer.Option(1000, "--inducing", help="Inducing points of the sparse GP."),
    inducing_var: int = typer.Option(250, "--inducing-var", help=(
        "The sparse GP's variance from this many of its inducing points (0 = all: slower per frame).")),
    components: int = typer.Option(128, "--components", help="Principal components of the feature (0 = raw feature)."),
    steps: Optional[int] = typer.Option(None, "--steps", help=(
        "Training mini-batches of 64 crops of the cnn feature's network (default 3000); only with --feature cnn "
        "(hog and lbp train no network: an error).")),
    seed: int = typer.Option(0, "--seed"),
):
    """Learn one Gaussian process per angle from labelled crops (one sequence, or several with --set)."""
    import numpy as np

    from artmotion.io import check_writable
    from artmotion.pose.data import load_labelled, read_keypoints, read_views
    from artmotion.pose.model import CALIBRATED_MIN, MIN_EXAMPLES, PoseRegressor

    if (images is None) != (labels is None):
        raise InputError("IMAGES and LABELS go together")
    if images is None and not sets:
        raise InputError("give the training crops: IMAGES LABELS.csv, or --set DIR (one or more)")
    for option, given in (("--boxes", boxes), ("--keypoints", keypoints)):
        if images is None and given is not None:
            raise InputError(f"{option} goes with IMAGES (a --set folder has its own {option[2:]}.csv"
                             + (", read with --set-keypoints)" if option == "--keypoints" else ")"))
    seqs = [] if images is None or labels is None else [(images, labels, boxes, keypoints)]
    for d in sets or []:
        if not (d / "crops").is_dir() or not (d / "labels.csv").is_file():
            raise InputError("a training set is a folder with crops/ and labels.csv (pose render writes one)", path=d)
        bx, kp = (d / f if (d / f).is_file() else None for f in ("boxes.csv", "keypoints.csv"))
        seqs.append((d / "crops", d / "labels.csv", bx, kp if set_keypoints else None))
    seen: set[Path] = set()
    for im, *_ in seqs:
        if im.resolve() in seen:
            raise InputError("the same training sequence given twice", path=im)
        seen.add(im.resolve())
    if feature != "cnn":  # hog and lbp use neither where a crop lies nor keypoints: a set's files are not read
        seqs = [(i, lab, None, None) for i, lab, *_ in seqs]  # (--boxes, --keypoints with them: errors below)
    if len({b is None for _, _, b, _ in seqs}) > 1:
        raise InputError("boxes for some training sequences but not for all: "
                         + ", ".join(str(i) for i, _, b, _ in seqs if b is None) + " have none")
    check_writable(model, inputs=[f for seq in seqs for f in seq] + [boxes, keypoints])
    check_range("--components", components, 0, 100_000, integer=True)
    check_range("--inducing", inducing, 1, 1_000_000, integer=True)
    check_range("--inducing-var", inducing_var, 0, 1_000_000, integer=True)
    if steps is not None:
        check_range("--steps", steps, 1, 1_000_000, integer=True)
    check_seed(seed)
    reg = PoseRegressor(feature=feature, method=method, n_inducing=inducing, n_components=components or None,
                        seed=seed, progress=True, net_steps=3000 if steps is None else steps,
                        n_inducing_var=inducing_var or None)  # checks feature and method before any image is read
    if boxes is not None and feature != "cnn":
        raise InputError(f"--boxes needs --feature cnn (the {feature} feature does not use where a crop lies)")
    for option, asked in (("--keypoints", keypoints is not None), ("--set-keypoints", set_keypoints)):
        if asked and feature != "cnn":
            raise InputError(f"{option} needs --feature cnn (the {feature} feature trains no network to find them)")
    if steps is not None and feature != "cnn":
        raise InputError(f"--steps needs --feature cnn (the {feature} feature trains no network)")
    names: list[str] = []
    imgs: list = []
    Ys, Vs, groups = [], [], []  # Vs: views of every sequence, or of none (checked above)
    Ks: list = []  # keypoints of each sequence (None: it has none)
    point_names: list[str] = []
    for k, (im, lab, bx, kp) in enumerate(seqs):
        n_k, paths, imgs_k, Y_k = load_labelled(im, lab, progress=True)
        _depth_note(paths)
        if names and n_k != names:
            raise InputError(f"angles {','.join(n_k)} differ from the first sequence's {','.join(names)}", path=lab)
        names = n_k
        imgs += imgs_k
        Ys.append(Y_k)
        if bx is not None:
            Vs.append(read_views(bx, paths))
        if kp is not None:
            p_k, K_k = read_keypoints(kp, paths, [(c.shape[1], c.shape[0]) for c in imgs_k])
            if point_names and p_k != point_names:
                raise InputError(f"points {','.join(p_k)} differ from the first keypoints' {','.join(point_names)}",
                                 path=kp)
            point_names = p_k
        Ks.append(None if kp is None else K_k)
        groups += [k] * len(Y_k)
    Y = np.concatenate(Ys)
    if len(Y) < MIN_EXAMPLES:
        raise InputError(f"{len(Y)} labelled crops: training needs at least {MIN_EXAMPLES}",
                         path=seqs[0][1] if len(seqs) == 1 else None)
    views = np.concatenate(Vs) if Vs else None
    # a sequence without keypoints: none known in its crops (the network learns them from the others)
    points = (np.concatenate([np.full((len(y), 2 * len(point_names)), np.nan) if k_ is None else k_
                              for k_, y in zip(Ks, Ys)]) if point_names else None)
    t = time.perf_counter()
    reg.fit(imgs, Y, names, views=views, groups=groups, keypoints=points)
    reg.save(model)
    gp = reg.gp_
    assert gp is not None  # fitted
    hyp = ", ".join(f"{n}: l={h.length:.3g} sn={h.sn2 ** 0.5 * s:.3g}°" for n, h, s in zip(names, gp.hypers, gp.y_std))
    source = f" from {len(seqs)} sequences" if len(seqs) > 1 else ""
    points_note = f", its network also finding {len(point_names)} keypoints" if point_names else ""
    typer.echo(f"trained {gp.kind} GP on {len(Y)} crops{source}, {gp.n_outputs} angles, feature {feature}{points_note} "
               f"({time.perf_counter() - t:.1f} s) -> {model}")
    typer.echo(f"  {hyp}")
    if gp.held_out is None:  # (fit_gp calibrates on 10 held-out crops or more)
        typer.echo(f"note: {len(Y)} crops are too few to calibrate the standard deviations on held-out crops (that "
                   f"needs 10 of them, the last 20 % of each sequence: {CALIBRATED_MIN} crops of one sequence); they "
                   "are the GP's own and may be far too small", err=True)


def _depth_note(paths) -> None:
    """Say on stderr when 16-bit crops are read as fewer bits (12-bit crops, 0-4095, by their top 8
    bits were nearly black; :func:`~artmotion.io.media.frame_depth`, as `read_images` reads them)."""
    from artmotion.io.media import depth_note, frame_depth

    if note := depth_note(frame_depth(paths)):
        typer.echo(f"note: {note}", err=True)


@pose_app.command("predict")
def predict_cmd(
    model: Path = typer.Argument(..., help="Model file from 'artmotion pose train'."),
    images: Path = typer.Argument(..., help=("Folder of crops; file-name order (numbers as numbers: 2.png before "
                                             "10.png) is one sequence; hidden files (.*) are left out.")),
    out: Path = typer.Option(..., "--out", help="CSV 'image,<name>,<name>_std,...' to write."),
    smooth: bool = typer.Option(False, "--smooth", help="Kalman-smooth the sequence (Eq. 3.6-3.7 forward, "
                                "then Rauch-Tung-Striebel backward: each frame from past and future ones)."),
    boxes: Optional[Path] = typer.Option(None, "--boxes", help=PREDICT_BOXES_HELP),
):
    """Predict every angle (mean and standard deviation, degrees) of each crop."""
    from artmotion.io import check_writable
    from artmotion.pose.data import check_csv_names, list_images, read_images, write_predictions
    from artmotion.pose.model import PoseRegressor, is_foreign

    check_writable(out, inputs=(model, boxes, images))
    reg = PoseRegressor.load(model)
    if boxes is not None and not reg.uses_views_:
        raise InputError("this model was trained without --boxes (or not with --feature cnn) and would not use "
                         "them: drop --boxes", path=model)
    paths = list_images(images)
    check_csv_names(paths)
    views = _views(boxes, paths)
    if views is None and reg.uses_views_:
        raise InputError("this model was trained with --boxes: give the crops' boxes (--boxes)", path=model)
    imgs = read_images(paths, progress=True)
    _depth_note(paths)
    t = time.perf_counter()
    X = reg.features(imgs)  # once, for the prediction and the domain test below
    mean, std = reg.predict(X, return_std=True, views=views)
    far = reg.far_from_training(std)
    if smooth:
        mean, std = reg.make_filter().smooth(mean, std)
    dt = time.perf_counter() - t
    assert reg.names_ is not None  # set by load
    write_predictions(out, [p.name for p in paths], reg.names_, mean, std)
    typer.echo(f"predicted {len(paths)} crops ({len(paths) / max(dt, 1e-9):.0f} frames/s"
               f"{', Kalman-smoothed' if smooth else ''}) -> {out}")
    auc = reg.domain_auc(X, views)
    if is_foreign(auc):
        typer.echo(f"note: the crops are unlike the model's training crops (told from the nearest of them with "
                   f"AUC {auc:.2f}; docs/surgical.md): its angles may be far off", err=True)
    if far.any():
        spread = ", ".join(f"{n} {s:.3g}°" for n, s in zip(reg.names_, reg.prior_std()))
        typer.echo(f"note: {int(far.sum())} of {len(far)} crops are far from every training crop (no training crop "
                   f"explains half of their GP variance): the model knows nothing of them, and their standard "
                   f"deviation is only the spread of its training angles ({spread}): their angles may be far off",
                   err=True)


@pose_app.command("eval")
def eval_cmd(
    images: Path = typer.Argument(..., help="Folder of crops (one sequence in file-name order)."),
    labels: Path = typer.Argument(..., help="Labels CSV."),
    feature: list[str] = typer.Option(["hog", "lbp"], "--feature", help="Features to compare (repeatable)."),
    folds: int = typer.Option(5, "--folds", help="Cross-validation folds."),
    split: str = typer.Option("random", "--split",
                              help="random: frames dealt to folds at random (the usual k-fold, the thesis' protocol); "
                                   "contiguous: each fold an unseen block of frames."),
    test_images: Optional[Path] = typer.Option(None, "--test-images", help="Crops of an unseen normal-light sequence."),
    test_labels: Optional[Path] = typer.Option(None, "--test-labels", help="Labels of the unseen normal-light sequence."),
    dark_images: Optional[Path] = typer.Option(None, "--dark-images", help="Crops of an unseen dark sequence."),
    dark_labels: Optional[Path] = typer.Option(None, "--dark-labels", help="Labels of the unseen dark sequence."),
    boxes: Optional[Path] = typer.Option(None, "--boxes", help=BOXES_HELP),
    keypoints: Optional[Path] = typer.Option(None, "--keypoints", help=EVAL_KEYPOINTS_HELP),
    test_boxes: Optional[Path] = typer.Option(None, "--test-boxes", help="Boxes of the unseen normal-light sequence."),
    dark_boxes: Optional[Path] = typer.Option(None, "--dark-boxes", help="Boxes of the unseen dark sequence."),
    orientation: Optional[str] = typer.Option(None, "--orientation",
                                              help="Comma-separated Euler-angle columns of the stem "
                                                   "(default yaw,pitch,roll when present)."),
    euler: str = typer.Option("ZYX", "--euler", help="Euler convention of those columns (SciPy; upper case = intrinsic)."),
    out: Optional[Path] = typer.Option(None, "--out", help="Folder for tables (eval.md, eval.json) and predictions."),
    method: str = typer.Option("auto", "--method", help="auto, exact or sparse GP."),
):
    """Cross-validated errors per feature (Table 3.1), unseen-sequence errors (Table 3.2), 3-sigma coverage."""
    from artmotion.pose.data import load_labelled, read_keypoints, write_predictions
    from artmotion.pose.evaluate import Columns, check_result_keys, cross_validate, least_examples, summary
    from artmotion.pose.model import PoseRegressor

    if split not in ("contiguous", "random"):
        raise InputError(f"unknown split {split!r}; choose contiguous or random")
    check_range("--folds", folds, 2, 1000, integer=True)
    from artmotion.io import check_apart
    from artmotion.io.atomic import check_out_dir

    check_apart(out, (images, test_images, dark_images))
    regs = {f: PoseRegressor(feature=f, method=method) for f in feature}  # checks names before reading images
    if boxes is not None and "cnn" not in feature:
        raise InputError("--boxes needs --feature cnn (hog and lbp do not use where a crop lies)")
    if keypoints is not None and "cnn" not in feature:
        raise InputError("--keypoints needs --feature cnn (hog and lbp train no network to find them)")
    # the outputs, known from the options: checked before the work (a folder of the user's own that
    # holds one of them was refused only once the evaluation was done)
    sets = ["cv"] + [key for key, given in (("test", test_images), ("dark", dark_images)) if given is not None]
    outputs = ["eval.md", "eval.json"] + [f"{s}_{f}{kind}.csv" for s in sets for f in feature for kind in ("", "_filtered")]
    earlier = _earlier_evaluation       # an earlier evaluation is replaced
    if out is not None:
        check_out_dir(out, replace=earlier, outputs=outputs)
    names, paths, imgs, Y = load_labelled(images, labels, progress=True)
    _depth_note(paths)
    least = least_examples(folds)
    if len(Y) < least:
        raise InputError(f"{len(Y)} labelled crops: {folds}-fold cross-validation needs at least {least}", path=labels)
    views = _views(boxes, paths)
    points = None if keypoints is None else read_keypoints(keypoints, paths, [(c.shape[1], c.shape[0]) for c in imgs])[1]
    cols = Columns.from_names(names, orientation.split(",") if orientation else None, euler)
    check_result_keys(names, cols, sets[1:], path=labels)  # a column 'orientation' would hide the stem's error
    unseen = {}
    for key, (u_images, u_labels, u_boxes, opt) in {"test": (test_images, test_labels, test_boxes, "--test"),
                                                    "dark": (dark_images, dark_labels, dark_boxes, "--dark")}.items():
        if (u_images is None) != (u_labels is None):
            raise InputError(f"{opt}-images and {opt}-labels go together")
        if (u_boxes is None) != (views is None) and u_images is not None:
            raise InputError(f"--boxes and {opt}-boxes go together")
        if u_images is not None:
            assert u_labels is not None  # checked just above: both or neither
            unames, upaths, uimgs, uY = load_labelled(u_images, u_labels, progress=True)
            _depth_note(upaths)
            if unames != names:
                raise InputError(f"angle columns {unames} differ from the training labels {names}", path=u_labels)
            unseen[key] = (upaths, uimgs, uY, _views(u_boxes, upaths))
    from contextlib import nullcontext

    from artmotion.io import atomic_dir, atomic_write

    # a new --out folder appears only when every table and prediction in it is written
    with (atomic_dir(out, replace=earlier, outputs=outputs) if out is not None
          else nullcontext(None)) as dst:
        results = {}
        for f in feature:
            t = time.perf_counter()
            X = regs[f].features(imgs)
            mean, std, fmean, fstd, fold = cross_validate(X, Y, names, folds, progress=True, split=split, feature=f,
                                                          method=method, views=views, keypoints=points)
            res = summary(Y, mean, std, fmean, cols, names)
            res["seconds"] = time.perf_counter() - t
            if dst is not None:
                write_predictions(dst / f"cv_{f}.csv", [p.name for p in paths], names, mean, std)
                write_predictions(dst / f"cv_{f}_filtered.csv", [p.name for p in paths], names, fmean, fstd)
            if unseen:
                reg = regs[f].fit(X, Y, names, views=views, keypoints=points)
            for key, (upaths, uimgs, uY, uviews) in unseen.items():
                um, us = reg.predict(uimgs, return_std=True, views=uviews)
                ufm, ufs = reg.make_filter().filter(um, us)
                res.update({f"{key} {k}": v for k, v in summary(uY, um, us, ufm, cols, names).items()})
                if dst is not None:
                    write_predictions(dst / f"{key}_{f}.csv", [p.name for p in upaths], names, um, us)
                    write_predictions(dst / f"{key}_{f}_filtered.csv", [p.name for p in upaths], names, ufm, ufs)
            results[f] = res
        table = format_tables(results, names, cols, list(unseen), split)
        if dst is not None:
            with atomic_write(dst / "eval.md") as fh:
                fh.write(table + "\n")
            with atomic_write(dst / "eval.json") as fh:
                json.dump(results, fh, indent=1)
    typer.echo(table)


def _earlier_evaluation(folder: Path) -> bool:
    """Whether ``folder`` holds the outputs of an earlier ``pose eval`` and nothing else (it is then
    replaced whole): its eval.json (an object of results per feature), eval.md and prediction
    tables by their names — not any CSV (a labels file kept there, an input, went with it)."""
    from artmotion.io.atomic import outputs_of
    from artmotion.pose.features import FEATURES

    names = {"eval.md"} | {f"{s}_{f}{kind}.csv" for s in ("cv", "test", "dark") for f in FEATURES
                           for kind in ("", "_filtered")}
    return outputs_of("eval.json", names, accept=lambda data: bool(data) and set(data) <= set(FEATURES))(folder)


_UNSEEN_TITLES = {"test": "Unseen normal-light sequence", "dark": "Unseen dark sequence"}


def format_tables(results: dict, names, cols, unseen: Sequence[str] = (), split: str = "random") -> str:
    """Markdown tables of :func:`eval_cmd`'s results (cross-validation, 3σ coverage, unseen sequences)."""
    keys = (["orientation"] if cols.orientation else []) + [n for i, n in enumerate(names) if i in cols.others]
    lines = [f"Cross-validation, {split} folds (mean absolute error, degrees; 'orientation' = angle between stem directions)", ""]

    def table(prefix: str) -> list[str]:
        cells = keys + [f"{k} filtered" for k in keys]
        rows = ["| feature | " + " | ".join(cells) + " | all angles in 3σ |", "|" + "---|" * (len(cells) + 2)]
        for f, r in results.items():
            rows.append(f"| {f.upper()} | " + " | ".join(f"{r[prefix + k]:.2f}" for k in cells)
                        + f" | {100 * r[prefix + 'all in 3sd']:.1f}% |")
        return rows

    lines += table("")
    lines += ["", "Fraction of frames whose true angle lies inside the predicted ±3σ band", "",
              "| feature | " + " | ".join(names) + " |", "|" + "---|" * (len(names) + 1)]
    for f, r in results.items():
        lines.append(f"| {f.upper()} | " + " | ".join(f"{100 * r[n + ' in 3sd']:.1f}%" for n in names) + " |")
    for key in unseen:
        lines += ["", f"{_UNSEEN_TITLES[key]}, trained on the whole set (raw GP mean, then Kalman-filtered)", ""]
        lines += table(f"{key} ")
    if "test" in unseen and "dark" in unseen:
        lines += ["", "Dark / normal light, error ratio on the unseen sequences", "",
                  "| feature | " + " | ".join(keys) + " |", "|" + "---|" * (len(keys) + 1)]
        for f, r in results.items():
            lines.append(f"| {f.upper()} | " + " | ".join(f"{r['dark ' + k] / max(r['test ' + k], 1e-12):.2f}×"
                                                        for k in keys) + " |")
    return "\n".join(lines)


def register(app: typer.Typer) -> None:
    """Add this capability's commands to the root artmotion app."""
    app.add_typer(pose_app, name="pose")
