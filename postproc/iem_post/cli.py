"""Command-line interface: ``iem-post COMMAND FILE.h5 ...`` (history, frame, summary, all,
and for fracture runs crack-map, fragments, curve, animate)."""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TextIO

import numpy as np

from . import __version__
from .animation import ANIMATION_FIELDS, write_animation, writer_for
from .curves import parse_target, plot_curves, read_curves, read_reference, write_csv
from .fracture import fragment_sizes, read_failed_springs, read_fragment_history
from .fracture_plots import plot_crack_map, plot_fragments
from .plots import FIELDS, auto_scale, plot_energy, plot_frame, plot_probes, save_figure
from .reader import IemFile, IemFileError, InputError

__all__ = ["main", "build_parser"]

PROG = "iem-post"


def _scale_arg(text: str) -> float | None:
    """Parse --scale: a non-negative finite number, or 'auto' (returned as None)."""
    if text.strip().lower() == "auto":
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or 'auto', got {text!r}") from None
    if not math.isfinite(value) or value < 0.0:
        raise argparse.ArgumentTypeError(f"scale must be finite and >= 0, got {text!r}")
    return value


def _number(text: str) -> float:
    """Parse a finite number."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def _positive_int(text: str) -> int:
    """Parse an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return value


def _scale_pair(text: str) -> tuple[float, float]:
    """Parse 'A,B': two finite numbers (the reference's cmod and load factors)."""
    parts = text.split(",")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"expected two numbers 'CMOD,LOAD', got {text!r}")
    return _number(parts[0]), _number(parts[1])


def _probe_pair(text: str) -> tuple[str, str]:
    """Parse 'A,B': two probe names."""
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 2 or not all(parts):
        raise argparse.ArgumentTypeError(f"expected two probe names 'A,B', got {text!r}")
    return parts[0], parts[1]


def build_parser() -> argparse.ArgumentParser:
    """The argparse parser for all sub-commands."""
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Plots and summaries of iem (Infinitesimal Element Model) HDF5 output files.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(
        dest="command", required=True, metavar="COMMAND",
        help="one of the commands below; 'iem-post COMMAND --help' for its options",
    )

    def add_file(p: argparse.ArgumentParser) -> None:
        """Add the positional FILE.h5 argument."""
        p.add_argument("file", type=Path, metavar="FILE.h5", help="iem output file (HDF5)")

    def add_outdir(p: argparse.ArgumentParser) -> None:
        """Add the -o/--outdir option."""
        p.add_argument(
            "-o", "--outdir", type=Path, default=None, metavar="OUTDIR",
            help="folder for the PNG files (default: the folder of FILE.h5)",
        )

    p_hist = sub.add_parser(
        "history", help="plot probe displacements and energies against time",
        description="Write OUTDIR/<stem>_probes.png (probe u_x and u_y against time) and "
        "OUTDIR/<stem>_energy.png (kinetic, strain, external work, damping dissipation and "
        "the relative energy-balance error against time).",
    )
    add_file(p_hist)
    add_outdir(p_hist)

    p_frame = sub.add_parser(
        "frame", help="draw the deformed lattice of one frame",
        description="Draw the cells of frame N at coordinates + scale * displacement, "
        "coloured by a per-cell field (mean of the four corner values), with the "
        "undeformed outline drawn lightly.",
    )
    add_file(p_frame)
    p_frame.add_argument(
        "--frame", type=int, default=-1, metavar="N",
        help="frame index, 0-based; negative counts from the end (default: -1, the last)",
    )
    p_frame.add_argument(
        "--scale", type=_scale_arg, default=None, metavar="S|auto",
        help="displacement magnification; 'auto' (default) makes the largest displacement "
        "10%% of the body's larger dimension (1 if nothing moved)",
    )
    p_frame.add_argument(
        "--field", choices=list(FIELDS), default="umag",
        help="cell colour: umag (default, |u|), ux, uy, vmag (|v|), vx, vy",
    )
    p_frame.add_argument(
        "-o", "--output", type=Path, default=None, metavar="PNG",
        help="image to write (default: <stem>_frame_NNNNNN.png next to FILE.h5)",
    )

    p_sum = sub.add_parser(
        "summary", help="print mesh, run and energy facts",
        description="Print nodes, cells, ranks, version, frames, history samples, whether "
        "the run completed, the final energies and the largest energy-balance error.",
    )
    add_file(p_sum)

    p_all = sub.add_parser(
        "all", help="history plots plus the last frame",
        description="Write the history plots and the last frame (auto scale, |u|) into OUTDIR.",
    )
    add_file(p_all)
    add_outdir(p_all)
    _add_fracture_commands(sub, add_file)
    return parser


def _add_fracture_commands(
    sub: argparse._SubParsersAction,  # type: ignore[type-arg]
    add_file: Callable[[argparse.ArgumentParser], None],
) -> None:
    """Add the crack-map, fragments, curve and animate sub-commands."""
    p_crack = sub.add_parser(
        "crack-map", help="draw the failed springs of a frame (fracture runs)",
        description="Draw the lattice of frame N (undeformed, or at coordinates + scale * "
        "displacement) with the springs failed by then as segments: an edge spring as its "
        "edge, a shear spring as a short mark from its corner towards the cell's centre; "
        "coloured by time of failure, pre-cut springs in grey. Reads "
        "/frames/frame_NNNNNN/failed_springs.",
    )
    add_file(p_crack)
    p_crack.add_argument(
        "--frame", type=int, default=-1, metavar="N",
        help="frame index, 0-based; negative counts from the end (default: -1, the last)",
    )
    p_crack.add_argument(
        "--scale", type=_scale_arg, default=0.0, metavar="S|auto",
        help="displacement magnification (default 0: the undeformed lattice); 'auto' makes "
        "the largest displacement 10%% of the body's larger dimension",
    )
    p_crack.add_argument(
        "-o", "--output", type=Path, default=None, metavar="PNG",
        help="image to write (default: <stem>_cracks_NNNNNN.png next to FILE.h5)",
    )

    p_frag = sub.add_parser(
        "fragments", help="plot the number and sizes of fragments (fracture runs)",
        description="Plot the number of fragments and the five largest fragment sizes "
        "(nodes) against time (/history/fracture/fragments, largest_fragments), and the "
        "fragment sizes at the end as a rank plot and a histogram: of all fragments of the "
        "last frame (computed from its failed springs) when it has them, else of the five "
        "largest of the last sample.",
    )
    add_file(p_frag)
    p_frag.add_argument(
        "-o", "--output", type=Path, default=None, metavar="PNG",
        help="image to write (default: <stem>_fragments.png next to FILE.h5)",
    )

    p_curve = sub.add_parser(
        "curve", help="load-displacement and load-CMOD curves",
        description="Plot a load against a probe displacement and, with --cmod, against the "
        "crack-mouth opening. Load = component of /history/reactions/BCNAME (the force the "
        "bc's prescribed dofs exert on the body, N; a bc without a name is bc_K, K its "
        "1-based place in the input) times --load-scale: use a negative scale to plot a "
        "pushing load as positive, and a factor to convert per thickness (e.g. the "
        "specimen's thickness over the model's). Displacement = component of "
        "/history/probes/PROBE/displacement in m times --displacement-scale; CMOD = u_x(B) - u_x(A) (A the probe left of the "
        "notch, B right of it; positive when opening), in m times --cmod-scale. The "
        "--reference table is multiplied by --reference-scale "
        "CMOD,LOAD to bring it into the plot's units: for a table in mm and N against a "
        "model in m, --reference-scale 1e-3,1 (or --cmod-scale 1e3 and the table as it is). "
        "Write negative factors with '=', e.g. --load-scale=-20.",
    )
    add_file(p_curve)
    p_curve.add_argument(
        "--load", required=True, metavar="BCNAME[:x|y]",
        help="the bc whose reaction is the load, and its component (default y)",
    )
    p_curve.add_argument(
        "--displacement", required=True, metavar="PROBE[:x|y]",
        help="the probe whose displacement is the abscissa, and its component (default y)",
    )
    p_curve.add_argument(
        "--cmod", type=_probe_pair, default=None, metavar="PROBE_A,PROBE_B",
        help="also plot the load against CMOD = u_x(PROBE_B) - u_x(PROBE_A)",
    )
    p_curve.add_argument(
        "--load-scale", type=_number, default=1.0, metavar="F",
        help="factor on the reaction (default 1; -1 flips the sign)",
    )
    p_curve.add_argument(
        "--displacement-scale", type=_number, default=1.0, metavar="F",
        help="factor on the displacement (default 1: m; 1e3 for mm, -1e3 for mm downwards; "
        "write a negative value as --displacement-scale=-1e3)",
    )
    p_curve.add_argument(
        "--cmod-scale", type=_number, default=1.0, metavar="F",
        help="factor on the CMOD (default 1: m; 1e3 for mm)",
    )
    p_curve.add_argument(
        "--reference", type=Path, default=None, metavar="CSV",
        help="a CSV with the columns cmod, load_min, load_max (header line first), drawn "
        "as a shaded band on the load-CMOD plot (needs --cmod)",
    )
    p_curve.add_argument(
        "--reference-scale", type=_scale_pair, default=(1.0, 1.0), metavar="CMOD,LOAD",
        help="factors on the reference's cmod and on its loads (default 1,1)",
    )
    p_curve.add_argument(
        "-o", "--output", type=Path, default=None, metavar="PNG",
        help="image to write (default: <stem>_curve.png next to FILE.h5)",
    )
    p_curve.add_argument(
        "--csv", type=Path, default=None, metavar="OUT.csv",
        help="also write the plotted curves: time, displacement, load[, cmod]",
    )

    p_anim = sub.add_parser(
        "animate", help="animate a frame field on the deformed lattice",
        description="Write one picture per frame of a field on the lattice at coordinates + "
        "scale * displacement as a GIF (Pillow) or an MP4 (needs ffmpeg). displacement and "
        "velocity are drawn as the cell mean of the corners' magnitudes; damage is "
        "/frames/frame_NNNNNN/damage (fracture runs). The colour range and the view are "
        "fixed over the animation.",
    )
    add_file(p_anim)
    p_anim.add_argument(
        "--field", choices=list(ANIMATION_FIELDS), default="displacement",
        help="the field (default displacement)",
    )
    p_anim.add_argument(
        "-o", "--output", type=Path, default=None, metavar="OUT.gif|OUT.mp4",
        help="animation to write (default: <stem>_<field>.gif next to FILE.h5)",
    )
    p_anim.add_argument("--fps", type=_positive_int, default=5, metavar="N",
                        help="pictures per second (default 5)")
    p_anim.add_argument(
        "--scale", type=_scale_arg, default=None, metavar="S|auto",
        help="displacement magnification; 'auto' (default) makes the largest displacement "
        "of all frames 10%% of the body's larger dimension",
    )
    p_anim.add_argument("--every", type=_positive_int, default=1, metavar="K",
                        help="use every K-th frame (default 1: all)")
    p_anim.add_argument("--dpi", type=_positive_int, default=100, metavar="DPI",
                        help="resolution (default 100; a GIF is held in memory until written)")


def _outdir(file: Path, outdir: Path | None) -> Path:
    """The output folder: the one given, else the input file's folder."""
    return outdir if outdir is not None else file.parent


def _write_history(data: IemFile, outdir: Path) -> list[Path]:
    """Write the probe and energy figures and return their paths."""
    stem = data.path.stem
    time = data.history_time
    probes_png = save_figure(
        plot_probes(time, data.probes, title=f"{data.path.name}: probe displacements"),
        outdir / f"{stem}_probes.png",
    )
    energy_png = save_figure(
        plot_energy(time, data.energies, title=f"{data.path.name}: energy balance"),
        outdir / f"{stem}_energy.png",
    )
    return [probes_png, energy_png]


def _write_frame(
    data: IemFile, index: int, scale: float | None, field: str, output: Path | None
) -> tuple[Path, int, float]:
    """Draw frame ``index``; return the image path, resolved frame index and scale used."""
    frame = data.frame(index)
    mesh = data.mesh
    used = auto_scale(mesh.coordinates, frame.displacement) if scale is None else scale
    how = " (auto)" if scale is None else ""
    title = (
        f"{data.path.name}: frame {frame.index} of {data.n_frames - 1}, "
        f"t = {frame.time:.6g} s (step {frame.step}), scale = {used:.4g}{how}"
    )
    if output is None:
        output = data.path.parent / f"{data.path.stem}_frame_{frame.index:06d}.png"
    path = save_figure(plot_frame(mesh, frame, field=field, scale=used, title=title), output)
    return path, frame.index, used


def _fmt(value: float) -> str:
    """Format a float compactly for the summary."""
    return f"{value:.6g}"


def _summary(data: IemFile, out: TextIO) -> None:
    """Print the summary of ``data`` to ``out``."""
    mesh = data.mesh
    frames = data.frames
    grid = f" ({mesh.nx} x {mesh.ny} cells)" if mesh.nx is not None and mesh.ny is not None else ""
    lines = [
        f"file:        {data.path}",
        f"version:     {data.version if data.version is not None else 'unknown'}",
        f"ranks:       {data.n_ranks if data.n_ranks is not None else 'unknown'}",
        f"nodes:       {mesh.n_nodes}",
        f"cells:       {mesh.n_cells}{grid}",
    ]
    if frames:
        lines.append(
            f"frames:      {len(frames)} (t = {_fmt(frames[0].time)} .. {_fmt(frames[-1].time)} s)"
        )
    else:
        lines.append("frames:      0")
    time = data.history_time
    if time.size:
        lines.append(f"samples:     {time.size} (t = {_fmt(time[0])} .. {_fmt(time[-1])} s)")
    else:
        lines.append("samples:     0")
    lines.append(f"complete:    {'yes' if data.complete else 'NO (run died or still running)'}")
    energies = data.energies
    finals = {k: v[-1] for k, v in energies.items() if v.size}
    if finals:
        lines.append("final energies (J):")
        order = ["kinetic", "strain", "external_work", "damping"]
        for key in order + sorted(k for k in finals if k not in order and k != "balance_error"):
            if key in finals:
                lines.append(f"  {key:<14s} {_fmt(float(finals[key]))}")
    err = energies.get("balance_error")
    if err is not None and err.size and np.isfinite(err).any():
        worst = int(np.nanargmax(err))
        lines.append(
            f"max balance error: {_fmt(float(err[worst]))} (t = {_fmt(float(time[worst]))} s)"
            if worst < time.size else f"max balance error: {_fmt(float(err[worst]))}"
        )
    else:
        lines.append("max balance error: n/a")
    print("\n".join(lines), file=out)


def _crack_map(data: IemFile, args: argparse.Namespace, out: TextIO) -> None:
    """Draw the failed springs of one frame and print the image path and counts."""
    info, springs = read_failed_springs(data, args.frame)
    frame = data.frame(info.index)
    mesh = data.mesh
    scale = auto_scale(mesh.coordinates, frame.displacement) if args.scale is None else args.scale
    shape = "undeformed" if scale == 0.0 else f"displacement scale {scale:.4g}"
    title = (f"{data.path.name}: frame {info.index} of {data.n_frames - 1}, "
             f"t = {info.time:.6g} s, {shape}")
    output = args.output or data.path.parent / f"{data.path.stem}_cracks_{info.index:06d}.png"
    fig = plot_crack_map(mesh, frame.displacement, springs, scale=scale, title=title)
    path = save_figure(fig, output)
    counts = ", ".join(f"{n} {name}" for name, n in springs.counts().items())
    print(f"{path}  (frame {info.index}, {len(springs)} failed: {counts})", file=out)


def _fragments(data: IemFile, args: argparse.Namespace, out: TextIO) -> None:
    """Plot the fragment history and the final sizes; print the image path and the counts."""
    history = read_fragment_history(data)
    sizes, label = None, ""
    if data.n_frames:
        try:
            info, springs = read_failed_springs(data, -1)
        except IemFileError:
            info = None  # no failed springs in the last frame: the 5 largest stand in
        if info is not None:
            sizes = fragment_sizes(data.mesh.n_nodes, data.mesh.cells, springs)
            label = f"all {sizes.size} fragments at t = {info.time:.6g} s (frame {info.index})"
            if (history.time.size and math.isclose(info.time, history.time[-1], rel_tol=1e-12)
                    and sizes.size != history.count[-1]):
                print(f"{PROG}: warning: the last frame's failed springs make {sizes.size} "
                      f"fragments, /history/fracture/fragments says {history.count[-1]}",
                      file=sys.stderr)
    fig = plot_fragments(history, sizes, label, title=f"{data.path.name}: fragments")
    path = save_figure(fig, args.output or data.path.parent / f"{data.path.stem}_fragments.png")
    if history.time.size:
        largest = ", ".join(str(int(n)) for n in history.largest[-1] if n > 0)
        print(f"{path}  ({history.count[-1]} fragments at t = {history.time[-1]:.6g} s; "
              f"largest: {largest or 'none'})", file=out)
    else:
        print(f"{path}  (no history samples)", file=out)


def _curve(data: IemFile, args: argparse.Namespace, out: TextIO) -> None:
    """Plot the load curves (and the reference band), optionally write the CSV; print both."""
    reference = (read_reference(args.reference, args.reference_scale)
                 if args.reference is not None else None)
    curves = read_curves(data, parse_target(args.load), parse_target(args.displacement),
                         args.cmod, args.load_scale, args.displacement_scale, args.cmod_scale)
    fig = plot_curves(curves, reference, title=f"{data.path.name}: load curves")
    path = save_figure(fig, args.output or data.path.parent / f"{data.path.stem}_curve.png")
    if curves.time.size:
        k = curves.peak()
        at = f"displacement {curves.displacement[k]:.6g}"
        if curves.cmod is not None:
            at += f", CMOD {curves.cmod[k]:.6g}"
        print(f"{path}  (peak load {curves.load[k]:.6g} at t = {curves.time[k]:.6g} s, {at})",
              file=out)
    else:
        print(f"{path}  (no history samples)", file=out)
    if args.csv is not None:
        print(write_csv(curves, args.csv), file=out)


def _animate(data: IemFile, args: argparse.Namespace, out: TextIO) -> None:
    """Write the animation and print its path, picture count and scale."""
    output = args.output or data.path.parent / f"{data.path.stem}_{args.field}.gif"
    path, count, scale = write_animation(data, args.field, output, fps=args.fps,
                                         scale=args.scale, every=args.every, dpi=args.dpi)
    print(f"{path}  ({count} pictures, field {args.field}, scale {scale:.4g}, "
          f"{args.fps} per second)", file=out)


#: Sub-commands of fracture runs and the functions that carry them out.
_FRACTURE_COMMANDS = {
    "crack-map": _crack_map,
    "fragments": _fragments,
    "curve": _curve,
    "animate": _animate,
}


def _run(args: argparse.Namespace, out: TextIO) -> None:
    """Carry out the parsed command; raises IemFileError on bad input."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        data = IemFile(args.file)
    for warning in caught:
        print(f"{PROG}: warning: {warning.message}", file=sys.stderr)
    with data:
        if args.command in _FRACTURE_COMMANDS:
            _FRACTURE_COMMANDS[args.command](data, args, out)
        elif args.command == "summary":
            _summary(data, out)
        elif args.command == "history":
            for path in _write_history(data, _outdir(args.file, args.outdir)):
                print(path, file=out)
        elif args.command == "frame":
            path, index, scale = _write_frame(data, args.frame, args.scale, args.field, args.output)
            print(f"{path}  (frame {index}, scale {scale:.4g}, field {args.field})", file=out)
        elif args.command == "all":
            outdir = _outdir(args.file, args.outdir)
            for path in _write_history(data, outdir):
                print(path, file=out)
            if data.n_frames:
                target = outdir / f"{data.path.stem}_frame_{data.n_frames - 1:06d}.png"
                path, index, scale = _write_frame(data, -1, None, "umag", target)
                print(f"{path}  (frame {index}, scale {scale:.4g}, field umag)", file=out)
            else:
                print(f"{PROG}: note: {data.path} holds no frames; no frame drawn", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point: parse ``argv`` (default sys.argv[1:]), run, return the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command == "curve" and args.reference is not None and args.cmod is None:
        parser.error("curve: --reference is a load-CMOD band and needs --cmod PROBE_A,PROBE_B")
    try:
        if args.command == "animate" and args.output is not None:
            writer_for(args.output, args.fps)  # refuse an unusable format before any work
        _run(args, sys.stdout)
    except (IemFileError, InputError, OSError) as exc:  # OSError: e.g. an output folder not writable
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    return 0
