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

Side by side (old and new code, or two scenes, in one invocation): with --baseline OLD_IEM
the old and the new (--iem) executables run the same case on the same rank count,
interleaved (old, new, old, new, ...) --repeat times (default 5); with two or more --input
namelists (dynamic runs; their t_end sets the work, and frames and history samples written
inside the time loop count in its wall time) each runs in turn the same way and the rates
are compared per node with the first. It prints the median, min and max node-steps per
second of each, the median of the paired ratios new/old (each new run over the old run just
before it) with their min and max, and the ratio of the medians; the same for node-steps per
CPU second (iem's node-steps over the user + system time of all its processes, start-up and
output included), which a machine shared with other jobs disturbs less than wall time:

    python3 benchmarks/throughput.py --iem build/iem --baseline OLD_IEM --ranks 1 --sizes 1e5
    python3 benchmarks/throughput.py --iem build/iem --input rectangle.nml --input holed.nml
    python3 benchmarks/throughput.py --sizes 1e5 --write-case rectangle.nml   # the block

Figures come from iem's own end-of-run report (wall time of the time loop, per-part timers,
VmHWM of every rank; node-steps are iem's node count times its steps). Compare ratios
within one run of this script: machines are noisy.
"""
from __future__ import annotations

import argparse
import os
import re
import resource
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


def block_case(nodes: float, work: float, cell: str, integrator: str) -> tuple[str, int]:
    """The clamped 2:1 block of about `nodes` nodes run for about `work` node-steps: its
    namelist and its node count."""
    ny = max(2, int(round((nodes / 2) ** 0.5)))
    nx = 2 * ny
    n_nodes = (nx + 1) * (ny + 1)
    # the stable step of a square cell of size 1/ny is about 1.8e-4/ny s for this material
    # with RK4 (1/sqrt(2) of that with velocity Verlet)
    steps = max(50, int(work / n_nodes))
    t_end = steps * 1.6e-4 / ny * (0.707 if integrator == "verlet" else 1.0)
    return CASE.format(t_end=t_end, length=2.0, nx=nx, ny=ny, cell=cell,
                       integrator=integrator), n_nodes


def run_nml(iem: str, nml: Path, ranks: int, mpiexec: str, folder: Path) -> dict:
    """Run iem on a namelist in folder and parse its end-of-run performance report."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = [mpiexec, "-n", str(ranks), "--oversubscribe", "--bind-to", "core", iem, str(nml)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run(cmd, cwd=folder, env=env, text=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{p.stdout[-2000:]}\n{p.stderr[-2000:]}")
    return parse_report(p.stdout, ranks, cpu, " ".join(cmd))


def run_pair(iem: str, nml: Path, mpiexec: str, folder: Path, cores: tuple[int, int]) -> list[dict]:
    """Run iem on a namelist twice at once, one rank each, each pinned to one of two cores
    (in the subfolders pair0 and pair1 of folder, so that their output files differ), and
    parse both end-of-run reports."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    # each mpiexec is started on its core and binds nothing: its rank keeps that core
    cmd = [mpiexec, "-n", "1", "--bind-to", "none", iem, str(nml.resolve())]
    procs = []
    for i, core in enumerate(cores):
        where = folder / f"pair{i}"
        where.mkdir(exist_ok=True)
        # each its own TMPDIR: two mpiruns started together would share Open MPI's session
        # folder ($TMPDIR/ompi.<host>.<uid>) and can race on making it
        procs.append(subprocess.Popen(cmd, cwd=where, env=dict(env, TMPDIR=str(where.resolve())),
                                      text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                      preexec_fn=lambda c=core: os.sched_setaffinity(0, {c})))
    outs = [p.communicate() for p in procs]
    for p, (out, err) in zip(procs, outs):
        if p.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed:\n{out[-2000:]}\n{err[-2000:]}")
    return [parse_report(out, 1, float("nan"), " ".join(cmd)) for out, _ in outs]


def parse_report(out: str, ranks: int, cpu: float, cmd: str) -> dict:
    """iem's end-of-run performance report (the standard output of cmd, run on ranks ranks
    with cpu seconds of processor time in all) as a dict."""
    num = r"([\d.]+(?:[eE][+-]?\d+)?)"
    perf = re.search(rf"performance:\s+{num} node-steps in\s+{num} s:\s+{num} node-steps/s", out)
    if perf is None:
        raise SystemExit(f"{cmd}: no performance report (a static run?):\n{out[-1000:]}")
    line = out.split("time in ", 1)[1].splitlines()[0]
    shares = {k.strip(): float(v) for k, v in re.findall(r"([a-z][a-z ]*?) ([\d.]+)%", line)}
    mem = re.search(r"memory: peak ([\d.]+) MB per rank \(largest\), ([\d.]+) MB in all", out)
    err = re.search(r"final energy-balance error ([\d.eE+-]+)", out)
    cells = re.search(r"nodes, (\d+) cells", out)
    return {"nodes": int(re.search(r": (\d+) nodes", out)[1]), "ranks": ranks,
            "cells": int(cells[1]) if cells else None,
            "steps": int(re.search(r"(\d+) steps to", out)[1]),
            "wall": float(perf[2]), "rate": float(perf[3]),
            "cpu_rate": float(perf[1]) / cpu if cpu > 0 else float("nan"),
            "force": shares["force evaluation"], "halo": shares["halo exchange"],
            "update": shares["state updates"], "output": shares.get("output", 0.0),
            "mem_rank": float(mem[1]), "mem_all": float(mem[2]),
            "err": float(err[1]) if err else float("nan")}


def run_case(iem: str, nodes: float, ranks: int, work: float, cell: str, mpiexec: str,
             folder: Path, integrator: str = "rk4") -> dict:
    """Run one block case and parse iem's performance report."""
    text, n_nodes = block_case(nodes, work, cell, integrator)
    nml = folder / f"bench_{n_nodes}_{ranks}.nml"
    nml.write_text(text)
    return run_nml(iem, nml, ranks, mpiexec, folder)


def input_case(path: Path) -> str:
    """A namelist file's text with its output file renamed to bench.h5 (overwritten)."""
    text = re.sub(r",?[ \t]*\boverwrite\s*=\s*\.\w+\.", "", path.read_text(), flags=re.I)
    text, n = re.subn(r"output_file\s*=\s*'[^']*'",
                      "output_file = 'bench.h5', overwrite = .true.", text)
    if n != 1:
        raise SystemExit(f"{path}: expected one output_file = '...' setting")
    return text


def median(xs: list[float]) -> float:
    """The median of a non-empty list."""
    ys = sorted(xs)
    k = len(ys) // 2
    return ys[k] if len(ys) % 2 else 0.5 * (ys[k - 1] + ys[k])


def side_by_side(args: argparse.Namespace) -> int:
    """Run every binary on every case interleaved (A B A B ...), args.repeat times, on each
    rank count, and print median rates and the ratios new/old and case/first case."""
    exes = [("new", str(Path(args.iem).resolve()))]
    if args.baseline:
        exes.insert(0, ("old", str(Path(args.baseline).resolve())))
    if args.input:
        cases = [(Path(p).name, input_case(Path(p))) for p in args.input]
    else:
        cases = [(f"block {size:g}", block_case(size, args.work, args.cell, args.integrator)[0])
                 for size in args.sizes]
    rates: dict[tuple, list[float]] = {}
    cpu_rates: dict[tuple, list[float]] = {}
    nodes: dict[tuple, int] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for ci, (_, text) in enumerate(cases):
            (Path(tmp) / f"case{ci}.nml").write_text(text)
        for ranks in args.ranks:
            for rep in range(args.repeat):
                for ci, (label, _) in enumerate(cases):
                    for which, exe in exes:
                        r = run_nml(exe, Path(tmp) / f"case{ci}.nml", ranks, args.mpiexec,
                                    Path(tmp))
                        rates.setdefault((ranks, ci, which), []).append(r["rate"])
                        cpu_rates.setdefault((ranks, ci, which), []).append(r["cpu_rate"])
                        nodes[(ranks, ci, which)] = r["nodes"]
                        print(f"# {rep + 1}/{args.repeat} {label} on {ranks} ranks, {which}: "
                              f"{r['rate']:.3e} node-steps/s ({r['wall']:.2f} s)",
                              file=sys.stderr, flush=True)
    print(f"Side by side: {args.repeat} interleaved runs of each; binaries: "
          + ", ".join(f"{w} = {e}" for w, e in exes) + "\n")
    print("| case | nodes | ranks | binary | median node-steps/s | min | max | "
          "median per CPU s |")
    print("|---|---|---|---|---|---|---|---|")
    for key, xs in rates.items():
        ranks, ci, which = key
        print(f"| {cases[ci][0]} | {nodes[key]:,} | {ranks} | {which} | {median(xs):.3e} | "
              f"{min(xs):.3e} | {max(xs):.3e} | {median(cpu_rates[key]):.3e} |")

    def ratio_line(what: str, num: list[float], den: list[float]) -> str:
        pairs = [a / b for a, b in zip(num, den)]
        return (f"{what}: {median(pairs):.4f} median of {len(pairs)} paired ratios (min "
                f"{min(pairs):.4f}, max {max(pairs):.4f}); ratio of medians "
                f"{median(num) / median(den):.4f}")

    print()
    for ranks in args.ranks:
        for ci, (label, _) in enumerate(cases):
            if args.baseline:
                for kind, r in (("", rates), (" per CPU s", cpu_rates)):
                    print(ratio_line(f"new/old{kind}, {label}, {ranks} ranks",
                                     r[(ranks, ci, "new")], r[(ranks, ci, "old")]))
        for which, _ in exes:
            for ci, (label, _) in enumerate(cases[1:], start=1):
                for kind, r in (("", rates), (" per CPU s", cpu_rates)):
                    print(ratio_line(f"per node{kind} {label}/{cases[0][0]}, {which}, "
                                     f"{ranks} ranks", r[(ranks, ci, which)],
                                     r[(ranks, 0, which)]))
    return 0


def main() -> int:
    """Run the sweep and print the table."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--iem", help="the (new) iem executable (required but with --write-case)")
    ap.add_argument("--mpiexec", default="mpirun")
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--sizes", type=float, nargs="+", default=[1e4, 1e5, 1e6])
    ap.add_argument("--work", type=float, default=2e8, help="node-steps per run")
    ap.add_argument("--cell", default="paper", choices=["paper", "bending"])
    ap.add_argument("--integrator", default="rk4", choices=["rk4", "verlet"])
    ap.add_argument("--weak", action="store_true", help="sizes are nodes per rank")
    ap.add_argument("--baseline", metavar="OLD_IEM",
                    help="side by side: also run this (old) iem, interleaved with --iem")
    ap.add_argument("--input", action="append", metavar="NML",
                    help="side by side: run this namelist instead of the block (repeatable; "
                         "two or more: per-node ratio of each to the first)")
    ap.add_argument("--repeat", type=int, default=5, help="side by side: runs of each")
    ap.add_argument("--write-case", metavar="NML",
                    help="write the block of the first size (with --work, --cell, "
                         "--integrator) to this file and stop")
    args = ap.parse_args()
    if args.write_case:
        text, n_nodes = block_case(args.sizes[0], args.work, args.cell, args.integrator)
        Path(args.write_case).write_text(text.replace("'bench.h5'", "'block.h5'"))
        print(f"wrote {args.write_case}: {n_nodes:,} nodes")
        return 0
    if not args.iem:
        ap.error("--iem is required")
    if args.baseline or args.input:
        if args.weak:
            ap.error("--weak does not combine with --baseline or --input")
        if args.repeat < 1:
            ap.error("--repeat must be at least 1")
        return side_by_side(args)
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
