#!/usr/bin/env python3
"""Set-up at scale: wall time and peak memory of iem's set-up against the size of the body at
fixed nodes per rank, for a rectangle and for the same rectangle with a circular hole.

The rectangle is the benchmark block of benchmarks/throughput.py (clamped 2:1 block, plane
stress, edge load, RK4, paper's cell) run for one time step, writing the mesh and the frames
of its first and last step only; the holed one adds a `&shape` circle of `material = 'void'`
(centre of the block, radius a quarter of its height), so that the body is not uniform and
keeps a cell map of the whole grid. Each size in --per-rank runs on every rank count in
--ranks with that many nodes per rank (total = nodes per rank x ranks), so a set-up that
scales keeps the set-up's peak memory per rank flat along a column of equal nodes per rank.

The figures come from iem's own log: the line `set-up: X s, peak Y MB per rank (largest)`
(the wall time of the set-up, from the validated configuration to the model and its time
step: the body, the partition, each rank's lattice and halo, the model; not the output file
nor the state, allocated after it; and the peak resident memory, VmHWM, of every rank by
then, the largest) and
`memory: peak Y MB per rank (largest)` (the whole run's). Usage (from the repository root,
after building):

    python3 benchmarks/setup_scaling.py --iem build/iem [--ranks 1 2] \\
        [--per-rank 1e5 1e6 5e6 1e7] [--scenes rectangle hole]
    python3 benchmarks/setup_scaling.py --per-rank 1e5 --write-case hole.nml --scenes hole

It prints a Markdown table per scene: nodes, ranks, nodes per rank, set-up wall time, set-up
peak memory per rank (largest) and per node of a rank, the whole run's peak per rank; then,
for each size per rank, how much more a rank holds on the largest rank count than on one
(the terms that grow with the global size), per node of the whole body.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from throughput import CASE  # noqa: E402  (the benchmark block)

HOLE = """&shape
  name = 'hole', kind = 'circle', center = 1.0, 0.5, radius = 0.25, material = 'void'
/
"""


def setup_case(nodes: float, scene: str) -> tuple[str, int]:
    """The 2:1 block of about `nodes` grid nodes (with a hole for scene 'hole'), run for one
    time step: its namelist and its grid's node count."""
    ny = max(4, int(round((nodes / 2) ** 0.5)))
    nx = 2 * ny
    # RK4's step for this material is about 4.5e-4/ny s (0.88 of its limit): one step
    t_end = 2 * 1.6e-4 / ny
    text = CASE.format(t_end=t_end, length=2.0, nx=nx, ny=ny, cell="paper", integrator="rk4")
    if scene == "hole":
        text += HOLE
    return text, (nx + 1) * (ny + 1)


def run_one(iem: str, nml: Path, ranks: int, mpiexec: str, folder: Path) -> dict:
    """Run iem on a namelist in folder; parse its size, set-up and end-of-run memory lines."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    cmd = [mpiexec, "-n", str(ranks), iem, str(nml)]
    p = subprocess.run(cmd, cwd=folder, env=env, text=True, capture_output=True)
    out = p.stdout
    for f in folder.glob("bench*"):
        if f.suffix != ".nml":
            f.unlink()
    if p.returncode != 0:
        return {"error": f"exit status {p.returncode}: "
                         f"{(p.stderr.strip() or out.strip()).splitlines()[-1:]}"}
    setup = re.search(r"set-up: ([\d.]+) s, peak ([\d.]+) MB per rank \(largest\)", out)
    run = re.search(r"memory: peak ([\d.]+) MB per rank \(largest\)", out)
    size = re.search(r": (\d+) nodes, (\d+) cells", out)
    if not (setup and run and size):
        return {"error": "no set-up or memory line in iem's log:\n" + out[-1500:]}
    return {"nodes": int(size[1]), "ranks": ranks, "setup_s": float(setup[1]),
            "setup_mb": float(setup[2]), "run_mb": float(run[1])}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--iem", help="the iem executable (required but with --write-case)")
    ap.add_argument("--mpiexec", default="mpirun")
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--per-rank", type=float, nargs="+", default=[1e5, 1e6, 5e6, 1e7],
                    help="grid nodes per rank")
    ap.add_argument("--scenes", nargs="+", default=["rectangle", "hole"],
                    choices=["rectangle", "hole"])
    ap.add_argument("--write-case", metavar="NML",
                    help="write the case of the first --per-rank size and scene, and stop")
    args = ap.parse_args()
    if args.write_case:
        text, n = setup_case(args.per_rank[0], args.scenes[0])
        Path(args.write_case).write_text(text.replace("'bench.h5'", "'setup.h5'"))
        print(f"wrote {args.write_case}: {args.scenes[0]}, {n:,} grid nodes")
        return 0
    if not args.iem:
        ap.error("--iem is required")
    iem = str(Path(args.iem).resolve())
    failed = False
    with tempfile.TemporaryDirectory() as tmp:
        for scene in args.scenes:
            print(f"\n{scene}: set-up at fixed nodes per rank\n")
            print("| nodes | ranks | nodes/rank | set-up (s) | set-up peak MB/rank | "
                  "bytes/node of a rank | run peak MB/rank |")
            print("|---|---|---|---|---|---|---|")
            rows = {}
            for per_rank in args.per_rank:
                for ranks in args.ranks:
                    text, n_grid = setup_case(per_rank * ranks, scene)
                    nml = Path(tmp) / f"bench_{scene}_{n_grid}_{ranks}.nml"
                    nml.write_text(text)
                    r = run_one(iem, nml, ranks, args.mpiexec, Path(tmp))
                    if "error" in r:
                        failed = True
                        print(f"| {n_grid:,} (grid) | {ranks} | - | failed: {r['error']} |")
                        continue
                    rows[(per_rank, ranks)] = r
                    npr = r["nodes"] / ranks
                    print(f"| {r['nodes']:,} | {ranks} | {npr:,.0f} | {r['setup_s']:.2f} | "
                          f"{r['setup_mb']:.1f} | {r['setup_mb'] * 1048576 / npr:.0f} | "
                          f"{r['run_mb']:.1f} |", flush=True)
            lo, hi = min(args.ranks), max(args.ranks)
            for per_rank in args.per_rank:
                a, b = rows.get((per_rank, lo)), rows.get((per_rank, hi))
                if a and b and hi > lo:
                    extra = (b["setup_mb"] - a["setup_mb"]) * 1048576
                    print(f"\n{per_rank:g} nodes per rank, {hi} ranks against {lo}: set-up peak "
                          f"{extra / 1048576:+.1f} MB per rank = {extra / b['nodes']:+.1f} "
                          f"bytes per node of the body ({b['nodes']:,} nodes), set-up time "
                          f"x{b['setup_s'] / max(a['setup_s'], 1e-9):.2f}")
            for ranks in args.ranks:
                pts = sorted((r["nodes"], r["setup_mb"]) for (_, k), r in rows.items()
                             if k == ranks)
                if len(pts) >= 2:
                    (n0, m0), (n1, m1) = pts[-2], pts[-1]
                    print(f"\n{ranks} rank(s): set-up peak per rank grows "
                          f"{(m1 - m0) * 1048576 / (n1 - n0):.1f} bytes per node of the body "
                          f"(between {n0:,} and {n1:,} nodes)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
