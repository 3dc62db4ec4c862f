#!/usr/bin/env python3
"""Brazilian splitting test of a concrete disc (docs/benchmarks.md, "Fracture benchmarks").

Runs inputs/brazilian_disc.nml (or --case; its header gives the disc, the strips and why),
takes the load from the reaction of the loading strip (`top_strip`, sign flipped; the
reaction of `bottom_strip` is printed beside it), and the time the splitting crack has run
through: when 80 % of the x edges of the column of cells on the loaded diameter have failed in
tension (/history/fracture/events). The splitting load P is the largest load up to then; it
prints the splitting strength 2 P / (pi D t) against the input tensile strength and their
ratio, the platen travel at P, the dissipated energy when the crack has run through and at the
end, the kinetic energy over the external work (from a tenth of the run to the split), the
energy-balance error, the largest load of the whole run (the two halves, still held between
the strips, carry load again after the split until they break), and where the tension cracks
of the last frame lie (how many on the loaded diameter). D and t are read from the case (the disc's radius, the thickness),
f_t from its tensile_strength. --crack-map writes the crack map of the last frame with
iem-post (postproc). Usage (from the repository root):

    python3 benchmarks/brazilian.py --iem build/iem [--ranks 2] [--case inputs/brazilian_disc.nml]
        [--crack-map docs/img/brazilian_crack.png] [--keep DIR] [--crushing F_C G_C]
        [--t-end T]
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import iembench as ib  # noqa: E402

CASE = ib.ROOT / "inputs" / "brazilian_disc.nml"


def number(text: str, key: str, index: int = 0) -> float:
    """The index-th value given to key in a namelist text (the first match of key)."""
    m = re.search(rf"\b{key}\s*=\s*([^\n/]*)", text)
    if not m:
        raise SystemExit(f"the case gives no {key}")
    return float(m[1].split(",")[index])


def measure(h5: Path, case_text: str) -> dict:
    """Peak load, splitting strength and the run's checks from its output."""
    D = 2.0 * number(case_text, "radius")
    ft = number(case_text, "tensile_strength")
    xc = number(case_text, "center", 0)
    with h5py.File(h5, "r") as f:
        t_model = float(f["mesh"].attrs["thickness"])
        t = f["history/time"][:]
        load = -f["history/reactions/top_strip"][:, 1]
        bottom = f["history/reactions/bottom_strip"][:, 1]
        travel = -(f["history/probes/top/displacement"][:, 1]
                   - f["history/probes/bottom/displacement"][:, 1])
        e = {k: f[f"history/energy/{k}"][:] for k in f["history/energy"]}
        lx = float(f["mesh"].attrs["lx"])
        last = sorted(k for k in f["frames"] if k.startswith("frame_"))[-1]
        fs = f[f"frames/{last}/failed_springs"]
        cell, kind = fs["cell"][:], fs["kind"][:]
        cells = f["mesh/cells"][:]
        centres = f["mesh/coordinates"][:][cells].mean(axis=1)
        ev = f["history/fracture/events"]
        ev_t, ev_x, ev_kind = ev["time"][:], ev["x"][:], ev["kind"][:]
    # the splitting crack: tension failures of x edges in the column of cells on the loaded
    # diameter (their centres lie on x = xc); it has run through when 80 % of the column's
    # 2 x edges a cell have failed
    on_col = np.abs(centres[:, 0] - xc) < 0.25 * lx
    n_col = int(np.sum(on_col))
    col_events = np.sort(ev_t[(np.abs(ev_x - xc) < 0.25 * lx) & (ev_kind == 1)])
    through = float(col_events[int(0.8 * 2 * n_col) - 1]) if len(col_events) >= 0.8 * 2 * n_col \
        else float("inf")
    before = t <= through
    i = int(np.argmax(np.where(before, load, -np.inf)))
    p = float(load[i])
    tension = cell[kind == 1]
    on_diameter = int(np.sum(on_col[tension]))
    after = t > 0.1 * t[-1]
    w = e["external_work"]
    return {"D": D, "t": t_model, "ft": ft, "peak": p, "bottom_at_peak": float(bottom[i]),
            "time_peak": float(t[i]), "travel_peak_mm": float(travel[i] * 1e3),
            "t_through": through, "column_cells": n_col,
            "load_max": float(load.max()), "time_load_max": float(t[int(np.argmax(load))]),
            "f_split": 2.0 * p / (np.pi * D * t_model), "d_frac": float(e["fracture"][-1]),
            "d_frac_split": float(np.interp(through, t, e["fracture"]))
            if np.isfinite(through) else float("nan"),
            "balance": float(np.max(np.abs(e["balance_error"]))),
            "ke_over_w": float(np.max(e["kinetic"][after & before] /
                                      np.maximum(w[after & before], 1e-300))),
            "ke_at_peak": float(e["kinetic"][i] / max(w[i], 1e-300)),
            "tension_failed": int(len(tension)), "on_diameter": on_diameter,
            "other_kinds": {int(k): int(np.sum(kind == k)) for k in (2, 3)},
            "end_load": float(load[-1])}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--iem")
    ap.add_argument("--from-h5", help="measure this output of the case instead of running it")
    ap.add_argument("--mpiexec", default="mpirun")
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--case", default=str(CASE))
    ap.add_argument("--crack-map", help="PNG of the cracks of the last frame (iem-post crack-map)")
    ap.add_argument("--keep", help="folder to keep the run's input and output in")
    ap.add_argument("--crushing", type=float, nargs=2, metavar=("F_C", "G_C"),
                    help="turn on crushing: compressive_strength (Pa) and crushing_energy (N/m)")
    ap.add_argument("--t-end", type=float, help="end time, s (default: the case's)")
    args = ap.parse_args()
    text = Path(args.case).read_text()
    if args.from_h5:
        r = measure(Path(args.from_h5), text)
        return print_report(r, args, "?", float("nan"), "(measured from " + args.from_h5 + ")")
    if not args.iem:
        ap.error("--iem is required (or --from-h5)")
    iem = str(Path(args.iem).resolve())
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(args.keep) if args.keep else Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        text_run, n = re.subn(r"output_file\s*=\s*'[^']*'", "output_file = 'disc.h5'", text)
        if n != 1:
            raise SystemExit(f"{args.case}: expected one output_file")
        if args.crushing:
            text_run, n = re.subn(r"(fracture_energy\s*=\s*[-+0-9.eE]+)",
                                  rf"\g<1>, compressive_strength = {args.crushing[0]!r}, "
                                  rf"crushing_energy = {args.crushing[1]!r}", text_run)
            if n != 1:
                raise SystemExit(f"{args.case}: expected one fracture_energy")
        if args.t_end:
            text_run, n = re.subn(r"\bt_end\s*=\s*[-+0-9.eE]+", f"t_end = {args.t_end!r}",
                                  text_run)
            if n != 1:
                raise SystemExit(f"{args.case}: expected one t_end")
        nml = folder / "disc.nml"
        nml.write_text(text_run)
        t0 = time.perf_counter()
        out, _ = ib.run(iem, nml, args.ranks, args.mpiexec)
        wall = time.perf_counter() - t0
        r = measure(folder / "disc.h5", text)
        if args.crack_map:
            png = str(Path(args.crack_map).resolve())
            cmd = [sys.executable, "-m", "iem_post", "crack-map", str(folder / "disc.h5"), "-o", png]
            env = dict(ib.mpi_env(), PYTHONPATH=str(ib.ROOT / "postproc"))
            p = subprocess.run(cmd, text=True, capture_output=True, env=env)
            if p.returncode:
                raise SystemExit(p.stderr)
            print(p.stdout.strip())
    steps = re.search(r"done: (\d+) steps", out)[1]
    return print_report(r, args, steps, wall, f"{ib.machine()}; {ib.build_info(iem)}")


def print_report(r: dict, args, steps: str, wall: float, where: str) -> int:
    """Print the table and the crack counts of one run."""
    text = Path(args.case).read_text()
    print(f"Case {Path(args.case).name}: D = {r['D']} m, t = {r['t']} m, f_t = {r['ft']:.3e} Pa; "
          f"{args.ranks} rank(s); {where}\n")
    print("| splitting load P (N) | at t (ms) | platen travel (mm) | 2P/(pi D t) (MPa) "
          "| input f_t (MPa) | ratio | crack through at t (ms) | D_frac then (J) "
          "| largest load of the run (N) | energy-balance error | kinetic / external work "
          "| steps | wall (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    print(f"| {r['peak']:.0f} | {r['time_peak'] * 1e3:.2f} | {r['travel_peak_mm']:.4f} "
          f"| {r['f_split'] / 1e6:.3f} | {r['ft'] / 1e6:.3f} | {r['f_split'] / r['ft']:.3f} "
          f"| {r['t_through'] * 1e3:.2f} | {r['d_frac_split']:.4f} "
          f"| {r['load_max']:.0f} at {r['time_load_max'] * 1e3:.2f} ms | {r['balance']:.1e} "
          f"| {r['ke_over_w']:.1e} | {steps} | {wall:.0f} |")
    print(f"\nbottom strip's reaction at P {r['bottom_at_peak']:.0f} N; load at the end "
          f"{r['end_load']:.0f} N; kinetic / external work at P {r['ke_at_peak']:.1e}; "
          f"D_frac at the end {r['d_frac']:.4f} J (G_f D t = "
          f"{number(text, 'fracture_energy') * r['D'] * r['t']:.4f} J)")
    print(f"tension failures in the last frame: {r['tension_failed']}, of which "
          f"{r['on_diameter']} in the column of {r['column_cells']} cells on the loaded "
          f"diameter; crushing "
          f"{r['other_kinds'][2]}, shear {r['other_kinds'][3]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
