#!/usr/bin/env python3
"""Convergence of the plate with a hole (Kirsch) and of the two-material beam with the grid
(docs/benchmarks.md, "Plate with a circular hole" and "Two-material beam").

Kirsch: inputs/plate_hole.nml (a quarter plate, hole radius a = 10 mm, d/W = 0.1, S = 100 MPa)
on a/h = 5, 10, 20 (40) cells per hole radius, one load step relaxed to 1e-8; K_t is the
peak sigma_xx at the top of the hole over S, from the cells of the column x in [0, h],
extrapolated quadratically from the first three cells to the hole's edge
(iem_post.scenes.hole_edge_stress); the first cell's own value and the linear extrapolation
from two cells are printed beside it. Reference: Heywood's K_t = 3.032 on the gross stress.

Two-material beam: inputs/bimaterial_beam.nml (cantilever, a stiff bottom quarter of the depth)
with 4, 8, 16 (32) cells through the depth, both cell laws, one load step relaxed to 1e-8
(the round-off floor of the residual is near 1e-9 with the stiff layer),
tip deflection over the transformed-section closed form
(iem_post.scenes.layered_cantilever_deflection), beside the same grid with one material
(the layer made of concrete) over Timoshenko. Usage (from the repository root):

    python3 benchmarks/scenes.py --iem build/iem [--kirsch 5 10 20 40] [--beam 4 8 16 32]
"""
from __future__ import annotations

import argparse
import re
import sys
import tempfile
from pathlib import Path

import h5py

sys.path.insert(0, str(Path(__file__).resolve().parent))
import iembench as ib  # noqa: E402
from iem_post.scenes import (  # noqa: E402
    heywood_kt, hole_edge_stress, layered_cantilever_deflection)

PLATE = ib.ROOT / "inputs" / "plate_hole.nml"
BEAM = ib.ROOT / "inputs" / "bimaterial_beam.nml"


def edit(src: Path, dst: Path, subs: list[tuple[str, str]]) -> Path:
    """Copy a scene with text substitutions (each must occur)."""
    text = src.read_text()
    for old, new in subs:
        assert old in text, old
        text = text.replace(old, new)
    dst.write_text(text)
    return dst


def iterations(out: str) -> tuple[int, float]:
    """Relaxation iterations and iem's wall time from its last line."""
    m = re.search(rf"done: \d+ load steps, (\d+) iterations in\s+{ib.NUM} s wall", out)
    return int(m[1]), float(m[2])


def kirsch(iem: str, folder: Path, n_over: int, ranks: int, mpiexec: str) -> dict:
    """One plate run with a/h = n_over: K_t by three measures."""
    nml = edit(PLATE, folder / "plate.nml", [("cell_size = 0.002", f"cell_size = {0.01 / n_over:.6g}"),
                                             ("'plate_hole.h5'", "'plate.h5'")])
    out, _ = ib.run(iem, nml, ranks, mpiexec)
    it, wall = iterations(out)
    with h5py.File(folder / "plate.h5", "r") as f:
        last = sorted(k for k in f["frames"] if k.startswith("frame_"))[-1]
        xy, cells = f["mesh/coordinates"][:], f["mesh/cells"][:]
        u = f[f"frames/{last}/displacement"][:]
    q = hole_edge_stress(xy, cells, u, 200e9, 0.3, n_fit=3)
    lin = hole_edge_stress(xy, cells, u, 200e9, 0.3, n_fit=2)
    (folder / "plate.h5").unlink()
    return {"n": n_over, "cells": len(cells), "kt": q["extrapolated"] / 100e6,
            "kt_lin": lin["extrapolated"] / 100e6, "kt_first": q["first_cell"] / 100e6,
            "iterations": it, "wall": wall}


def beam(iem: str, folder: Path, ny: int, cell: str, one: bool, ranks: int, mpiexec: str) -> float:
    """Tip deflection (m, downwards positive) of the two-material beam, or of the same beam
    with one material."""
    subs = [("nx = 80, ny = 8", f"nx = {10 * ny}, ny = {ny}, cell = '{cell}'"),
            ("load_steps = 5", "load_steps = 1, max_iterations = 2000000"),
            ("tolerance = 1.0e-8", f"tolerance = {max(1e-8, ib.static_tolerance(ny)):.1e}"),
            ("'bimaterial_beam.h5'", "'beam.h5'")]
    if one:
        subs.append(("name = 'stiff', E = 100.0e9, nu = 0.2, density = 7800.0",
                     "name = 'stiff', E = 25.0e9, nu = 0.2, density = 2400.0"))
    nml = edit(BEAM, folder / "beam.nml", subs)
    ib.run(iem, nml, ranks, mpiexec)
    with h5py.File(folder / "beam.h5", "r") as f:
        d = -float(f["history/probes/tip/displacement"][-1, 1])
    (folder / "beam.h5").unlink()
    return d


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--iem", required=True)
    ap.add_argument("--mpiexec", default="mpirun")
    ap.add_argument("--ranks", type=int, default=1)
    ap.add_argument("--kirsch", type=int, nargs="*", default=[5, 10, 20],
                    help="cells per hole radius a/h (empty: skip)")
    ap.add_argument("--beam", type=int, nargs="*", default=[4, 8, 16],
                    help="cells through the beam's depth, multiples of 4 (empty: skip)")
    args = ap.parse_args()
    iem = str(Path(args.iem).resolve())
    print(f"Machine: {ib.machine()}. Build: {ib.build_info(iem)}. {args.ranks} rank(s).\n")
    if args.kirsch:
        ref = heywood_kt(0.1)[1]
        print(f"Plate with a hole: Heywood K_t = {ref:.4f} (d/W = 0.1), Kirsch 3.\n")
        print("| a/h | cells | K_t (quadratic, 3 cells) | error | K_t (linear, 2 cells) | "
              "K_t (first cell) | iterations | wall (s) |")
        print("|---|---|---|---|---|---|---|---|")
        with tempfile.TemporaryDirectory() as tmp:
            for n in args.kirsch:
                r = kirsch(iem, Path(tmp), n, args.ranks, args.mpiexec)
                print(f"| {n} | {r['cells']:,} | {r['kt']:.4f} | {r['kt'] / ref - 1:+.2%} | "
                      f"{r['kt_lin']:.4f} | {r['kt_first']:.4f} | {r['iterations']} | "
                      f"{r['wall']:.1f} |", flush=True)
        print()
    if args.beam:
        g = lambda e: e / (2 * (1 + 0.2))  # noqa: E731
        two = layered_cantilever_deflection([(0.025, 100e9, g(100e9)), (0.075, 25e9, g(25e9))],
                                            0.1, 1.0, 1000.0)
        one = layered_cantilever_deflection([(0.1, 25e9, g(25e9))], 0.1, 1.0, 1000.0)
        print(f"Two-material beam: closed form {two['total'] * 1e3:.5f} mm (bending "
              f"{two['bending'] * 1e3:.5f}, shear {two['shear'] * 1e3:.5f}; y_na = "
              f"{two['y_na'] * 1e3:.3f} mm, EI = {two['EI']:.5e} N m^2, GA_s = "
              f"{two['GA_s']:.5e} N); one material (Timoshenko) {one['total'] * 1e3:.5f} mm.\n")
        print("| cell | cells through depth | two materials (mm) | / closed form | "
              "one material / Timoshenko | two / one |")
        print("|---|---|---|---|---|---|")
        with tempfile.TemporaryDirectory() as tmp:
            for cell in ("paper", "bending"):
                for ny in args.beam:
                    d2 = beam(iem, Path(tmp), ny, cell, False, args.ranks, args.mpiexec)
                    d1 = beam(iem, Path(tmp), ny, cell, True, args.ranks, args.mpiexec)
                    r2, r1 = d2 / two["total"], d1 / one["total"]
                    print(f"| {cell} | {ny} | {d2 * 1e3:.5f} | {r2:.5f} | {r1:.5f} | "
                          f"{r2 / r1:.5f} |", flush=True)
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
