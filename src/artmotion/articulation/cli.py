"""CLI commands of :mod:`artmotion.articulation` (registered on the root app by :func:`register`).

``artmotion articulation fit TRAJ``, ``artmotion articulation video VIDEO`` and ``artmotion slam simulate``.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Optional

import typer

from artmotion.errors import InputError, check_range, check_seed

articulation_app = typer.Typer(help="Discover how things move: articulation models from trajectories.",
                               no_args_is_help=True)
slam_app = typer.Typer(help="SLAM with articulated landmarks on simulated worlds.", no_args_is_help=True)


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, list):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return str(v)


#: configuration entries that are positions (printed by :func:`_coords`)
_POSITIONS = ("centre", "origin", "point")


def _coords(v, resolution: float | None) -> str:
    """A position with its digits down to ``resolution`` (at least 4 significant; ``None``: 10):
    ``.4g`` printed a door's centre 4000 km from the origin as ``4e+06``."""
    if isinstance(v, list):
        return "[" + ", ".join(_coords(x, resolution) for x in v) + "]"
    if not isinstance(v, float) or v == 0.0 or not math.isfinite(v):
        return _fmt(v)
    digits = 10 if resolution is None else min(17, max(4, math.floor(math.log10(abs(v) / resolution)) + 1))
    return f"{v:.{digits}g}"


def _resolution(out: dict) -> float | None:
    """The digits positions are printed with: 1e-4 of the motion's extent (the circle's radius, the
    line's stroke), else a tenth of the noise, else ``None``."""
    cfg = out.get("configuration") or {}
    extent = cfg.get("radius")
    if extent is None and cfg.get("length_range"):
        extent = abs(cfg["length_range"][1] - cfg["length_range"][0])
    if isinstance(extent, float) and math.isfinite(extent) and extent > 0:
        return 1e-4 * extent
    noise = out.get("noise")
    return 0.1 * noise if isinstance(noise, float) and math.isfinite(noise) and noise > 0 else None


def _units(units: dict | None) -> str:
    """The header's units as the summary line says them (``""``: none given)."""
    units = units or {}
    said = []
    length, time = units.get("length"), units.get("time")
    if length is not None:
        said.append(f"positions in {length}" + ("" if length in ("m", "px") else ", converted to metres"))
    if time is not None:
        said.append(f"time in {time}" + ("" if time in ("s", "sec") else ", converted to seconds"))
    return "; " + "; ".join(said) if said else ""


@articulation_app.command("fit")
def fit(
    traj: Path = typer.Argument(..., help="Trajectory: rows 'x y', 'x y z' or 'x y z qx qy qz qw' (see --time)."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
    threshold: float = typer.Option(0.75, "--threshold", help="Decide a model when its probability passes this (tau)."),
    min_samples: int = typer.Option(7, "--min-samples", help="Samples before configurations are estimated."),
    time: Optional[bool] = typer.Option(None, "--time/--no-time",
                                        help="First column is time (default: header 't'/'time' or 4/8 columns)."),
    order: int = typer.Option(2, "--order", help="Taylor order of the motion variables (2 = constant velocity)."),
    noise_floor: float = typer.Option(0.0, "--noise-floor",
                                      help="Least observation noise std (data units, metres when the header gives a "
                                           "length unit); the noise is estimated per model."),
    radius_range: tuple[float, float] = typer.Option((0.05, 1.0), "--radius-range",
                                                     help="Prior range of a hinge's radius (data units, metres when "
                                                          "the header gives a length unit; 5 cm - 1 m)."),
):
    """Classify a trajectory online (static, prismatic, revolute; poses also planar, rigid)."""
    from artmotion.articulation.trajectory import fit_trajectory

    check_range("--threshold", threshold, 0.0, 1.0, lo_open=True, hi_open=True)
    check_range("--min-samples", min_samples, 3, 1_000_000, integer=True)
    check_range("--order", order, 1, 6, integer=True)
    check_range("--noise-floor", noise_floor, 0.0, 1e12)
    check_range("--radius-range", radius_range[0], 0.0, 1e12, lo_open=True)
    check_range("--radius-range", radius_range[1], 0.0, 1e12, lo_open=True)
    if not radius_range[1] > radius_range[0]:
        raise InputError(f"--radius-range LOW HIGH: the high end must exceed the low end, got {radius_range[0]:g} "
                         f"{radius_range[1]:g}")
    if not traj.exists():
        raise InputError("no such file", path=traj)
    out = fit_trajectory(traj, time=time, threshold=threshold, min_samples=min_samples, order=order,
                         noise_floor=noise_floor, radius_range=radius_range)
    if as_json:
        typer.echo(json.dumps(out, allow_nan=False))
        return
    n = out["samples"]
    typer.echo(f"{traj}: {n} samples ({out['input']}{', time column' if out['time_column'] else ''}"
               f"{_units(out.get('units'))})")
    dec = out["decided_at"]
    when = f"decided at sample {dec} ({100.0 * (dec + 1) / n:.0f}% of the track)" if dec is not None else "undecided"
    typer.echo(f"model: {out['model']}  ({when})")
    if out.get("note"):
        typer.echo(f"  note: {out['note']}")
    fd = out.get("first_decision")
    if fd and fd["model"] != out["model"]:
        typer.echo(f"  first passed the threshold: {fd['model']} at sample {fd['at']} (revised later)")
    if out.get("probabilities"):
        typer.echo("probabilities: " + ", ".join(f"{k} {v:.3f}" for k, v in out["probabilities"].items()))
    margin = out.get("margin") or {}
    if margin.get("log_odds") is not None:
        typer.echo(f"margin over {margin['runner_up']}: {margin['log_odds']:.1f} nats (log-odds)")
    if out.get("noise_per_model"):
        typer.echo("noise std per model: " + ", ".join(f"{k} {_fmt(v)}" for k, v in out["noise_per_model"].items()))
    if out["input"] == "pose":
        if out["noise"] is None:   # (one sample: no motion to estimate it from)
            typer.echo("noise std: not estimated (too few samples)")
        else:
            typer.echo(f"noise std: {_fmt(out['noise'])} (position), {_fmt(out['angular_noise'])} rad (orientation)")
        unused = [name for name, changed in (("--threshold", threshold != 0.75), ("--order", order != 2),
                                             ("--radius-range", tuple(radius_range) != (0.05, 1.0))) if changed]
        if unused:
            typer.echo(f"  ({', '.join(unused)}: options of Algorithm 1's point tracks; a pose track is classified "
                       "by its rigid motion, Sec. 4.3.2)")
    res = _resolution(out)
    for k, v in out.get("configuration", {}).items():
        typer.echo(f"  {k}: {_coords(v, res) if k in _POSITIONS else _fmt(v)}")
    if out.get("prediction"):
        typer.echo(f"next sample predicted at {_coords(out['prediction'][0], res)}")


@articulation_app.command("video")
def video(
    source: Path = typer.Argument(..., help="A video file or a folder of frames."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
    out: Optional[Path] = typer.Option(None, "--out", help="Folder for result.json and parts.png (tracks by part, axes)."),
    focal: Optional[float] = typer.Option(None, "--focal", help="Focal length in pixels (default: a 60-degree field of view)."),
    max_parts: int = typer.Option(3, "--max-parts", help="Most moving parts to look for."),
    seed: int = typer.Option(0, "--seed", help="Random seed of the part search (RANSAC)."),
    fps: Optional[float] = typer.Option(None, "--fps", help="Frame rate (frames/s), in place of the input's own: "
                                                           "a folder of frames says none (25 is assumed), a "
                                                           "video's header may say it wrong."),
    bits: Optional[int] = typer.Option(None, "--bits", help="Bits that 16-bit image frames hold (8-16), in place of "
                                                             "what frames spread over them show (a 12-bit camera's "
                                                             "dark first frames show fewer)."),
):
    """Find the parts that move in a video and name the joint of the one that moves most."""
    from artmotion.articulation.video import analyze_video

    if focal is not None:
        check_range("--focal", focal, 0.0, 1e7, lo_open=True)
    check_range("--max-parts", max_parts, 1, 20, integer=True)
    check_seed(seed)
    if fps is not None:
        from artmotion.io.media import MAX_FPS, MIN_FPS

        check_range("--fps", fps, MIN_FPS, MAX_FPS)
    from artmotion.io import check_apart

    check_apart(out, (source,))
    if out is not None:
        _check_video_out(out)     # before the tracking (a read-only folder failed after it)
    from artmotion.io.sequence import open_sequence

    seq = open_sequence(source)   # (opened here, so that an error names the option; analyze_video takes it as it is)
    seq.set_bits(bits)
    snapshots = 4 if out is not None else 0
    if sys.stderr.isatty():
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

        with Progress(TextColumn("tracking"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                      transient=True, console=Console(stderr=True)) as progress:
            task = progress.add_task("tracking", total=None)
            res = analyze_video(seq, focal=focal, max_parts=max_parts, seed=seed, snapshots=snapshots,
                                fps=fps, on_frame=lambda done, total: progress.update(task, completed=done, total=total))
    else:
        res = analyze_video(seq, focal=focal, max_parts=max_parts, seed=seed, snapshots=snapshots,
                            fps=fps)
    d = res.to_dict()
    if out is not None:
        _write_video_outputs(out, res, d)
    from artmotion.io.media import depth_note

    if note := depth_note(res.depth):
        typer.echo(f"note: {note}", err=True)
    if as_json:
        typer.echo(json.dumps(d, allow_nan=False))
        return
    assumed = "" if res.fps_known else " (assumed; give --fps)"
    stored = f" as stored (not turned as its orientation tag asks: {res.orientation})" if res.orientation else ""
    typer.echo(f"{source}: {d['frames']} frames{stored} @ {d['fps']:g} fps{assumed}, camera {d['camera']}, "
               f"noise {d['noise_px']:.2f} px")
    typer.echo(f"model: {d['model']}  (confidence {d['confidence']:.2f}){': ' + d['note'] if d['note'] else ''}")
    for k, p in enumerate(d["parts"], start=1):
        rng = p.get("range") or {}
        extent = (f", {rng['degrees']:.0f} degrees" if "degrees" in rng else
                  f", {rng['pixels']:.0f} px" if "pixels" in rng else "")
        typer.echo(f"  part {k}: {p['model']} ({p['confidence']:.2f}), {p['points']} points, frames "
                   f"{p['frames'][0]}-{p['frames'][1]}{extent}")
        ax = p.get("axis")
        if ax:
            where = "towards the camera" if ax.get("towards_camera") else "direction " + _fmt(ax["direction"])
            typer.echo(f"    axis through {_coords(ax['point'], 0.1)} px, {where}")
    if out is not None:
        typer.echo(f"wrote {out}/result.json, {out}/parts.png")


#: the outputs of ``articulation video --out``
_VIDEO_OUTPUTS = ("result.json", "parts.png")


def _earlier_video_outputs():
    from artmotion.io.atomic import outputs_of

    return outputs_of("result.json", _VIDEO_OUTPUTS, ("model", "parts", "camera"))   # an earlier answer is replaced


def _check_video_out(out: Path) -> None:
    from artmotion.io.atomic import check_out_dir

    check_out_dir(out, replace=_earlier_video_outputs(), outputs=_VIDEO_OUTPUTS)


def _write_video_outputs(out: Path, res, d: dict) -> None:
    """result.json and parts.png (four frames: the tracks so far, by part, and each part's axis)."""
    from artmotion.articulation.video import parts_strip
    from artmotion.io.atomic import atomic_dir, atomic_write
    from artmotion.io.media import write_image

    with atomic_dir(out, replace=_earlier_video_outputs(), outputs=_VIDEO_OUTPUTS) as tmp:
        with atomic_write(tmp / "result.json") as fh:
            json.dump(d, fh, indent=1, allow_nan=False)
        write_image(tmp / "parts.png", parts_strip(res))


#: the EKF's covariance has (4 * landmarks + 3)^2 entries at most: 1000 landmarks take 128 MB
MAX_LANDMARKS = 1000


@slam_app.command("simulate")
def simulate(
    world: Optional[str] = typer.Option(None, "--world",
                                        help="Named world: table4.2 (default), corridor, warehouse or moving-only."),
    backends: str = typer.Option("ekf,ekf_gated,articulated", "--backends",
                                 help="Comma-separated back ends: ekf, ekf_gated, articulated, "
                                      "articulated_delayed, graph (graph needs the slam extra)."),
    landmarks: Optional[int] = typer.Option(None, "--landmarks",
                                            help="Instead of --world: this many landmarks around the path."),
    prismatic: Optional[int] = typer.Option(None, "--prismatic",
                                            help="With --landmarks: how many slide back and forth (default 1)."),
    revolute: Optional[int] = typer.Option(None, "--revolute",
                                           help="With --landmarks: how many turn on a circle (default 1)."),
    steps: Optional[int] = typer.Option(None, "--steps", help="Time steps per run (0.1 s each); default: the world's."),
    runs: int = typer.Option(20, "--runs", help="Monte Carlo runs."),
    seed: int = typer.Option(0, "--seed", help="Random seed."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="Write a PNG of the last run (Fig. 4.6/4.7)."),
):
    """Compare SLAM back ends on simulated worlds with moving landmarks (Table 4.2 and more)."""
    from artmotion.articulation.slam.evaluate import BACKENDS, monte_carlo, plot_run
    from artmotion.articulation.slam.world import WORLDS

    if landmarks is None and (prismatic is not None or revolute is not None):
        raise InputError("--prismatic and --revolute count landmarks of --landmarks: give --landmarks too")
    if landmarks is not None and world is not None:
        raise InputError("give either --world or --landmarks (a ring of landmarks instead of a named world)")
    world = world or "table4.2"
    if world not in WORLDS:
        raise InputError(f"--world must be one of {', '.join(WORLDS)}, got {world!r}")
    names = list(dict.fromkeys(b.strip() for b in backends.split(",") if b.strip()))  # each once, in order
    unknown = [b for b in names if b not in BACKENDS]
    if not names or unknown:
        raise InputError(f"--backends must list some of {', '.join(BACKENDS)}, got {backends!r}")
    counts = None
    if landmarks is not None:
        check_range("--landmarks", landmarks, 1, MAX_LANDMARKS, integer=True)
        prismatic = check_range("--prismatic", 1 if prismatic is None else prismatic, 0, MAX_LANDMARKS, integer=True)
        revolute = check_range("--revolute", 1 if revolute is None else revolute, 0, MAX_LANDMARKS, integer=True)
        if prismatic + revolute > landmarks:
            raise InputError(f"--prismatic ({prismatic}) and --revolute ({revolute}; 1 each unless given) "
                             f"add up to more than --landmarks ({landmarks})")
        counts = (landmarks, prismatic, revolute)
    if steps is not None:
        check_range("--steps", steps, 2, 100_000, integer=True)
    check_range("--runs", runs, 1, 10_000, integer=True)
    check_seed(seed)
    if plot is not None and plot.suffix.lower() != ".png":
        raise InputError("--plot must name a .png file", path=plot)
    if plot is not None:
        from artmotion.io import check_writable

        check_writable(plot)  # before the simulation
    def simulate_all(on_run=None):
        return monte_carlo(runs=runs, steps=steps, world=world, seed=seed, backends=names, landmarks=counts,
                           keep_last=plot is not None, on_run=on_run)

    if sys.stderr.isatty():      # (a large world runs for minutes per run: say how far it is)
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

        with Progress(TextColumn("runs x back ends"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                      transient=True, console=Console(stderr=True)) as progress:
            task = progress.add_task("simulate", total=runs * len(names))
            res = simulate_all(lambda done, total: progress.update(task, completed=done, total=total))
    else:
        res = simulate_all()
    last = res.pop("_last", None)
    if plot is not None and last is not None:
        last_world, last_sim, last_results = last
        plot_run(last_world, last_sim, last_results, plot)
    if as_json:
        typer.echo(json.dumps(res, allow_nan=False))
        return
    what = (f"{landmarks} landmarks ({prismatic} prismatic, {revolute} revolute)" if counts
            else f"world {world}: {WORLDS[world][0]}")
    typer.echo(f"{runs} runs x {res['steps']} steps, {what}")
    typer.echo(f"{'':40s}{'translation [95% interval]':>28s}{'rotation':>10s}{'abs. transl.':>14s}{'NEES':>8s}")
    for name in names:
        r = res[name]
        t = r["translation_error"]
        ci = f"[{t['low']:6.3f}, {t['high']:6.3f}]" if t["low"] is not None else f"{'':16s}"
        typer.echo(f"{BACKENDS[name][0]:40s}{t['mean']:10.3f} {ci}{'':4s}"
                   f"{r['rotation_error']['mean']:10.3f}{r['absolute_translation_error']['mean']:14.3f}"
                   f"{r['nees']['mean']:8.1f}")
    typer.echo("errors of pose increments over all pose pairs (m, rad); absolute: mean pose error; "
               "NEES of the robot pose (3 if consistent)")
    if plot is not None:
        typer.echo(f"wrote {plot}")


def register(app: typer.Typer) -> None:
    """Add this capability's commands to the root artmotion app."""
    app.add_typer(articulation_app, name="articulation")
    app.add_typer(slam_app, name="slam")
