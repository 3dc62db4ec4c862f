#!/usr/bin/env python3
"""Throughput and memory of the elastic solver: node-steps per second, the share of time in
force evaluation, halo exchange and state updates, and peak memory per node.

Runs a clamped block (2:1, plane stress, edge load, no damping, RK4 or velocity Verlet at 0.9
of the stable step) of about 1e4, 1e5 and 1e6 nodes on the given rank counts, each for a
fixed amount of work, and prints a Markdown table with the parallel efficiency against the
1-rank run of the same size (strong scaling). With --weak the sizes are per rank (weak
scaling: the efficiency is the per-rank rate against the 1-rank run). Usage (from the
repository root, after building):

    python3 benchmarks/throughput.py --iem build/iem --ranks 1 2 [--sizes 1e4 1e5 1e6]
    python3 benchmarks/throughput.py --iem build/iem --ranks 1 2 4 8 16 --sizes 1e6 --weak

Figures come from iem's own end-of-run report (wall time of the time loop, per-part timers,
VmHWM of every rank). Compare ratios within one run of this script: machines are noisy.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

CASE = """&run
  t_end = {t_end:.6e}, output_interval = {t_end:.6e}, history_interval = {t_end:.6e}
  integrator = '{integrator}'
  output_file = 'bench.h5', overwrite = .true., progress_interval = 1.0e6
/
&geometry
  length = {length}, height = 1.0, thickness = 0.1, nx = {nx}, ny = {ny}, cell = '{cell}'
/
&material
  E = 25.0e9, nu = 0.2, density = 2400.0
/
&bc
  where = 'left', dofs = 'xy'
/
&load
  kind = 'edge', where = 'right', traction = 0.0, -1.0e5
/
"""


def run_case(iem: str, nodes: float, ranks: int, work: float, cell: str, mpiexec: str,
             folder: Path, integrator: str = "rk4") -> dict:
    """Run one case and parse iem's performance report."""
    ny = max(2, int(round((nodes / 2) ** 0.5)))
    nx = 2 * ny
    n_nodes = (nx + 1) * (ny + 1)
    # the stable step of a square cell of size 1/ny is about 1.8e-4/ny s for this material
    # with RK4 (1/sqrt(2) of that with velocity Verlet)
    steps = max(50, int(work / n_nodes))
    t_end = steps * 1.6e-4 / ny * (0.707 if integrator == "verlet" else 1.0)
    nml = folder / f"bench_{n_nodes}_{ranks}.nml"
    nml.write_text(CASE.format(t_end=t_end, length=2.0, nx=nx, ny=ny, cell=cell,
                               integrator=integrator))
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = [mpiexec, "-n", str(ranks), "--oversubscribe", "--bind-to", "core", iem, str(nml)]
    p = subprocess.run(cmd, cwd=folder, env=env, text=True, capture_output=True)
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{p.stdout[-2000:]}\n{p.stderr[-2000:]}")
    out = p.stdout
    num = r"([\d.]+(?:[eE][+-]?\d+)?)"
    perf = re.search(rf"performance:\s+{num} node-steps in\s+{num} s:\s+{num} node-steps/s", out)
    line = out.split("time in ", 1)[1].splitlines()[0]
    shares = {k.strip(): float(v) for k, v in re.findall(r"([a-z][a-z ]*?) ([\d.]+)%", line)}
    mem = re.search(r"memory: peak ([\d.]+) MB per rank \(largest\), ([\d.]+) MB in all", out)
    err = re.search(r"final energy-balance error ([\d.eE+-]+)", out)
    return {"nodes": n_nodes, "ranks": ranks, "steps": int(re.search(r"(\d+) steps to", out)[1]),
            "wall": float(perf[2]), "rate": float(perf[3]),
            "force": shares["force evaluation"], "halo": shares["halo exchange"],
            "update": shares["state updates"],
            "mem_rank": float(mem[1]), "mem_all": float(mem[2]), "err": float(err[1])}


def main() -> int:
    """Run the sweep and print the table."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--iem", required=True)
    ap.add_argument("--mpiexec", default="mpirun")
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--sizes", type=float, nargs="+", default=[1e4, 1e5, 1e6])
    ap.add_argument("--work", type=float, default=2e8, help="node-steps per run")
    ap.add_argument("--cell", default="paper", choices=["paper", "bending"])
    ap.add_argument("--integrator", default="rk4", choices=["rk4", "verlet"])
    ap.add_argument("--weak", action="store_true", help="sizes are nodes per rank")
    args = ap.parse_args()
    iem = str(Path(args.iem).resolve())
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for size in args.sizes:
            for ranks in args.ranks:
                total = size * ranks if args.weak else size
                work = args.work * ranks if args.weak else args.work
                r = run_case(iem, total, ranks, work, args.cell, args.mpiexec, Path(tmp),
                             args.integrator)
                r["size"] = size
                rows.append(r)
                print(f"# {r['nodes']} nodes on {ranks} ranks: {r['rate']:.3e} node-steps/s",
                      file=sys.stderr, flush=True)
    print(f"{'Weak' if args.weak else 'Strong'} scaling, {args.integrator}, {args.cell} cell.\n")
    print("| nodes | ranks | steps | wall (s) | node-steps/s | per rank | efficiency | force | "
          "halo | updates | peak MB/rank | energy error |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        base = [b for b in rows if b["size"] == r["size"] and b["ranks"] == 1]
        eff = f"{r['rate'] / r['ranks'] / base[0]['rate']:.0%}" if base else "-"
        print(f"| {r['nodes']:,} | {r['ranks']} | {r['steps']} | {r['wall']:.2f} | "
              f"{r['rate']:.3e} | {r['rate'] / r['ranks']:.3e} | {eff} | {r['force']:.0f}% | "
              f"{r['halo']:.0f}% | {r['update']:.0f}% | {r['mem_rank']:.1f} | {r['err']:.1e} |")
    one = [r for r in rows if r["ranks"] == 1]
    if len(one) >= 2 and not args.weak:
        a, b = one[-2], one[-1]
        per_node = (b["mem_all"] - a["mem_all"]) * 1048576 / (b["nodes"] - a["nodes"])
        print(f"\nmemory per node (slope of peak memory between {a['nodes']:,} and "
              f"{b['nodes']:,} nodes on 1 rank): {per_node:.0f} bytes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
