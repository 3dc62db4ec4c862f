#!/usr/bin/env python3
"""Convergence of iem on the issue-3 cantilever: static tip deflection and first period
against the plane-stress finite-element reference, 2 to 32 cells through the depth, with the
paper's cell and the bending-corrected cell.

Scene (benchmarks/iembench.py): L = 1 m, h = 0.1 m, t = 0.1 m, E = 25 GPa, nu = 0.2,
rho = 2400 kg/m^3, left edge clamped, uniform shear traction on the right edge (P = 1000 N
downwards), nx = 10 ny square cells.

* Static tip deflection u_y(L, h/2): ``analysis = 'static'``, one load step, kinetic dynamic
  relaxation to a relative residual of 1e-9 (1e-8 at 32 cells through the depth, where
  1e-9 is below the round-off floor); each grid is also relaxed to 10x that tolerance, and
  the change of u_y is reported (the relaxation error).
* First period: an undamped dynamic run under a step load of the same traction over three
  Timoshenko periods, history every T/800; the period is fitted to the tip history (see
  iembench.py: zero crossings, then a 4-mode least-squares fit), once with every sample and
  once with every other sample (T/400); both are reported.

Errors are relative to the reference and signed, iem / reference - 1 (negative: too stiff, a
smaller deflection or a shorter period); the observed order is log2(e_n / e_2n). Prints Markdown tables and writes a log-log plot of |error|
against cells through the depth. Usage (from the repository root, after building):

    python3 benchmarks/convergence.py --iem build/iem --png docs/img/convergence.png

Wall times are iem's own: the relaxation's (``done: ... s wall``) and the time loop's
(``performance: ...``), without start-up and output. Runs are on one rank unless --ranks.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import iembench as ib  # noqa: E402

CELLS = ("paper", "bending")


def run_all(args) -> dict:
    iem = str(Path(args.iem).resolve())
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for cell in args.cells:
            for ny in args.depths:
                tol = ib.static_tolerance(ny)
                s = ib.run_static(iem, folder, ny, cell, tol, args.ranks, args.mpiexec)
                s10 = ib.run_static(iem, folder, ny, cell, 10 * tol, args.ranks, args.mpiexec)
                d = ib.run_dynamic(iem, folder, ny, cell, args.dt_safety, args.periods,
                                   ranks=args.ranks, mpiexec=args.mpiexec)
                rows.append({"static": s, "static_loose": s10, "dynamic": d})
                print(f"# {cell} {ny}: u_y {s['uy']:.8e} m ({s['iterations']} iterations, "
                      f"{s['wall_iem']:.2f} s), period {d['period']:.8e} s "
                      f"({d['steps']} steps, {d['wall_iem']:.2f} s)", file=sys.stderr, flush=True)
    return {"rows": rows, "machine": ib.machine(), "build": ib.build_info(iem),
            "ranks": args.ranks, "dt_safety": args.dt_safety, "periods": args.periods}


def report(data: dict, ref: dict, png: str | None) -> None:
    rows = data["rows"]
    print(f"Reference: u_y(L, h/2) = {ref['uy_tip']:.6e} m, first period {ref['period']:.6e} s "
          f"({ref['source']}).")
    print(f"Machine: {data['machine']}. Build: {data['build']}. {data['ranks']} rank(s); "
          f"dynamic runs at dt_safety = {data['dt_safety']}, {data['periods']:g} periods.\n")
    errors = {}
    for cell in CELLS:
        sel = [r for r in rows if r["static"]["cell"] == cell]
        if not sel:
            continue
        print(f"### {'Paper' if cell == 'paper' else 'Bending-corrected'} cell (`cell = '{cell}'`)\n")
        print("| cells through depth | grid | nodes | u_y (mm) | error of u_y | order | "
              "period (ms) | error of period | order | wall static (s) | wall dynamic (s) |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        eu = [r["static"]["uy"] / ref["uy_tip"] - 1 for r in sel]
        et = [r["dynamic"]["period"] / ref["period"] - 1 for r in sel]
        errors[cell] = ([r["static"]["ny"] for r in sel], eu, et)
        for i, r in enumerate(sel):
            s, d = r["static"], r["dynamic"]
            ou = ib.order(eu[i - 1], eu[i]) if i else ""
            ot = ib.order(et[i - 1], et[i]) if i else ""
            print(f"| {s['ny']} | {s['nx']} x {s['ny']} | {s['nodes']:,} | {-1e3 * s['uy']:.5f} | "
                  f"{eu[i]:+.2e} | {ou} | {1e3 * d['period']:.5f} | {et[i]:+.2e} | {ot} | "
                  f"{s['wall_iem']:.2f} | {d['wall_iem']:.2f} |")
        print()
    print("### Checks of the measurement\n")
    print("| cell | cells through depth | static tol | iterations | u_y change at 10x tol | "
          "period: T/400 vs T/800 | crossings: T/400 vs T/800 | crossings vs fit | "
          "mean of response vs static u_y | energy error |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        s, s10, d = r["static"], r["static_loose"], r["dynamic"]
        print(f"| {s['cell']} | {s['ny']} | {s['tol']:.0e} | {s['iterations']} | "
              f"{abs(s10['uy'] / s['uy'] - 1):.1e} | {abs(d['period_half'] / d['period'] - 1):.1e} | "
              f"{abs(d['period_crossing_half'] / d['period_crossing'] - 1):.1e} | "
              f"{d['period_crossing'] / d['period'] - 1:+.1e} | {d['mean'] / s['uy'] - 1:+.1e} | "
              f"{d['energy_error']:.1e} |")
    print()
    if png:
        plot(errors, png)
        print(f"plot: {png}")


def plot(errors: dict, png: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    style = {"paper": ("o", "C0"), "bending": ("s", "C3")}
    for cell, (ny, eu, et) in errors.items():
        m, c = style[cell]
        ax.loglog(ny, np.abs(eu), m + "-", color=c, label=f"{cell}: static deflection")
        ax.loglog(ny, np.abs(et), m + "--", color=c, mfc="none", label=f"{cell}: first period")
    ny = np.array(sorted({n for v in errors.values() for n in v[0]}), float)
    ax.loglog(ny, 0.5 * (ny / ny[0]) ** -2, ":", color="grey", label="slope -2")
    ax.loglog(ny, 4e-3 * (ny / ny[0]) ** -1.5, "-.", color="grey", lw=0.8, label="slope -1.5")
    ax.set_xlabel("cells through the depth (nx = 10 ny)")
    ax.set_ylabel("|relative error| against the FE reference")
    ax.set_xticks(ny, [f"{int(n)}" for n in ny])
    ax.minorticks_off()
    ax.grid(True, which="major", alpha=0.3)
    ax.set_title("Cantilever L/h = 10: convergence of iem")
    ax.legend(fontsize=8)
    fig.tight_layout()
    ib.save_figure(fig, png)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--iem", help="path of the iem executable")
    ap.add_argument("--png", help="write the convergence plot here")
    ib.add_sweep_args(ap, CELLS)
    ap.add_argument("--dt-safety", type=float, default=0.9)
    ap.add_argument("--periods", type=float, default=3.0, help="length of the dynamic runs")
    return ib.measure_and_report(ap, run_all, report)


if __name__ == "__main__":
    sys.exit(main())
