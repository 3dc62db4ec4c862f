"""Command-line interface: ``iem-post {history,frame,summary,all} FILE.h5 ...``."""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

import numpy as np

from . import __version__
from .plots import FIELDS, auto_scale, plot_energy, plot_frame, plot_probes, save_figure
from .reader import IemFile, IemFileError

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
    return parser


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


def _run(args: argparse.Namespace, out: TextIO) -> None:
    """Carry out the parsed command; raises IemFileError on bad input."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        data = IemFile(args.file)
    for warning in caught:
        print(f"{PROG}: warning: {warning.message}", file=sys.stderr)
    with data:
        if args.command == "summary":
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
    args = build_parser().parse_args(argv)
    try:
        _run(args, sys.stdout)
    except (IemFileError, OSError) as exc:  # OSError: e.g. an output folder not writable
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    return 0
