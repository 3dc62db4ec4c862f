#!/usr/bin/env python3
"""Convergence of the simply supported beam (three-point bending, the paper's Fig. 11 scene):
the mid-span deflection relative to the end faces against the committed plane-stress FE
reference, for both cell laws and 2, 4, 8, 16 (32) cells through the depth.

The scene is inputs/simply_supported_static.nml (L = 1 m, h = 0.1 m, point supports at the
bottom corners, P = 1 kN at the top of mid-span) with nx = 10 ny square cells, one load step
relaxed to a relative residual of 1e-9 (1e-8 from 32 cells through the depth: the round-off
floor, docs/model.md). The quantity is ``d = u_y(L/2, 0) - (mean u_y over x = 0 + mean u_y
over x = L)/2`` (``iem_post.references.deflection_relative_to_end_faces``), which converges;
the raw ``u_y(L/2, 0)`` does not (a point support indents a 2D body by an amount that grows
like the log of the grid size), and is printed beside it. Usage (from the repository root):

    python3 benchmarks/three_point.py --iem build/iem [--depths 2 4 8 16]
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
from iem_post.references import deflection_relative_to_end_faces  # noqa: E402

SCENE = ib.ROOT / "inputs" / "simply_supported_static.nml"


def run_one(iem: str, folder: Path, ny: int, cell: str, ranks: int, mpiexec: str) -> dict:
    """One static run of the scene on a grid with ny cells through the depth."""
    tol = ib.static_tolerance(ny)
    text = SCENE.read_text()
    for old, new in (("nx = 80, ny = 8", f"nx = {10 * ny}, ny = {ny}, cell = '{cell}'"),
                     ("load_steps = 5", "load_steps = 1, max_iterations = 2000000"),
                     ("tolerance = 1.0e-7", f"tolerance = {tol:.1e}"),
                     ("'simply_supported_static.h5'", "'tp.h5'")):
        assert old in text, old
        text = text.replace(old, new)
    nml = folder / "tp.nml"
    nml.write_text(text)
    out, _ = ib.run(iem, nml, ranks, mpiexec)
    m = re.search(rf"done: \d+ load steps, (\d+) iterations in\s+{ib.NUM} s wall", out)
    with h5py.File(folder / "tp.h5", "r") as f:
        last = sorted(k for k in f["frames"] if k.startswith("frame_"))[-1]
        xy = f["mesh/coordinates"][:]
        u = f[f"frames/{last}/displacement"][:]
    d = deflection_relative_to_end_faces(xy, u, 0.5, 0.0)
    raw = float(u[((xy[:, 0] - 0.5) ** 2 + xy[:, 1] ** 2).argmin(), 1])
    return {"cell": cell, "ny": ny, "nodes": len(xy), "tol": tol, "d": d, "raw": raw,
            "iterations": int(m[1]), "wall": float(m[2])}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--iem", required=True)
    ib.add_sweep_args(ap, ("paper", "bending"))
    args = ap.parse_args()
    ref = float(ib.load_fe_references()["three_point_bending"]["d_mid"]["value"])
    iem = str(Path(args.iem).resolve())
    print(f"Reference d_mid = {ref:.8e} m (FE, committed). Machine: {ib.machine()}. "
          f"Build: {ib.build_info(iem)}. {args.ranks} rank(s).\n")
    for cell in args.cells:
        rows = []
        with tempfile.TemporaryDirectory() as tmp:
            for ny in args.depths:
                rows.append(run_one(iem, Path(tmp), ny, cell, args.ranks, args.mpiexec))
        print(f"Cell `{cell}`:\n")
        print("| cells through depth | grid | nodes | d (mm) | error of d | order | "
              "raw u_y(L/2, 0) (mm) | iterations | wall (s) |")
        print("|---|---|---|---|---|---|---|---|---|")
        prev = None
        for r in rows:
            err = r["d"] / ref - 1
            order = ib.order(prev, err) if prev is not None else ""
            print(f"| {r['ny']} | {10 * r['ny']} x {r['ny']} | {r['nodes']:,} | "
                  f"{-r['d'] * 1e3:.6f} | {err:+.2e} | {order} | {-r['raw'] * 1e3:.6f} | "
                  f"{r['iterations']} | {r['wall']:.2f} |")
            prev = err
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
