#!/usr/bin/env python3
"""Speed against error: the undamped step-load cantilever of issue 3 over a fixed simulated
time (three first periods), for a sweep of grids x cell model x time integrator x dt_safety.

Each run (benchmarks/iembench.py, ``run_dynamic``) records iem's wall time of the time loop
and its node-steps per second (``performance:`` line: no start-up, no final output), and
two errors against the plane-stress FE reference (``load_fe_references()``): of the first
period, and of the static tip deflection measured as the mean about which the tip
oscillates (the constant of the fitted response; iembench.py says how). Prints a Markdown
table and writes a Pareto plot (|error| against wall time, log-log, one panel per quantity,
one marker per cell model, the Pareto front over all runs joined).

Both integrators' steps are set by stability, not accuracy: the time-integration error of
the first mode's period is (omega_1 dt)^4/120 ~ 1e-16 for RK4 and (omega_1 dt)^2/24 ~ 1e-8 for
velocity Verlet here, so dt_safety changes the wall time and not the error. Usage (from the
repository root):

    python3 benchmarks/pareto.py --iem build/iem --png docs/img/pareto.png
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import iembench as ib  # noqa: E402

CELLS = ("paper", "bending")
INTEGRATORS = ("rk4", "verlet")


def run_all(args) -> dict:
    iem = str(Path(args.iem).resolve())
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for cell in args.cells:
            for integ in args.integrators:
                for ny in args.depths:
                    for safety in args.dt_safety:
                        d = ib.run_dynamic(iem, Path(tmp), ny, cell, safety, args.periods,
                                           ranks=args.ranks, mpiexec=args.mpiexec,
                                           integrator=integ)
                        rows.append(d)
                        print(f"# {cell} {integ} {ny} {safety}: {d['steps']} steps, "
                              f"{d['wall_iem']:.2f} s, {d['rate']:.3e} node-steps/s",
                              file=sys.stderr, flush=True)
    return {"rows": rows, "machine": ib.machine(), "build": ib.build_info(iem),
            "ranks": args.ranks, "periods": args.periods}


def front(points: list[tuple[float, float]], same: float = 0.01) -> list[int]:
    """Indices of the Pareto-optimal points (smaller time and smaller error), by time.

    Errors within ``same`` (relative) of each other count as equal: runs that differ only in
    dt_safety or integrator have the same error to about 1e-5 (the time-integration error is
    negligible here), so the slower of them is not on the front."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    out, best = [], float("inf")
    for i in order:
        if points[i][1] < best * (1 - same):
            out.append(i)
            best = points[i][1]
    return out


def report(data: dict, ref: dict, png: str | None) -> None:
    rows = data["rows"]
    for r in rows:
        r["err_u"] = r["mean"] / ref["uy_tip"] - 1
        r["err_t"] = r["period"] / ref["period"] - 1
    fu = set(front([(r["wall_iem"], abs(r["err_u"])) for r in rows]))
    ft = set(front([(r["wall_iem"], abs(r["err_t"])) for r in rows]))
    print(f"Reference: u_y(L, h/2) = {ref['uy_tip']:.6e} m, first period {ref['period']:.6e} s "
          f"({ref['source']}).")
    print(f"Machine: {data['machine']}. Build: {data['build']}. {data['ranks']} rank(s); "
          f"{data['periods']:g} Timoshenko periods simulated.\n")
    print("| cell | integrator | cells through depth | nodes | dt_safety | steps | wall (s) | "
          "node-steps/s | error of u_y (mean) | error of period | Pareto front (u_y, period) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for i, r in enumerate(rows):
        mark = ", ".join(q for q, s in (("u_y", fu), ("period", ft)) if i in s) or ""
        print(f"| {r['cell']} | {integrator(r)} | {r['ny']} | {r['nodes']:,} | {r['safety']:g} | "
              f"{r['steps']} | "
              f"{r['wall_iem']:.3f} | {r['rate']:.3e} | {r['err_u']:+.2e} | {r['err_t']:+.2e} | "
              f"{mark} |")
    print()
    if png:
        plot(rows, png)
        print(f"plot: {png}")


def integrator(r: dict) -> str:
    """The run's integrator (runs saved before the integrator axis existed are RK4)."""
    return r.get("integrator", "rk4")


def plot(rows: list[dict], png: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6), sharex=True)
    style = {("paper", "rk4"): ("o", "C0"), ("bending", "rk4"): ("s", "C3"),
             ("paper", "verlet"): ("^", "C2"), ("bending", "verlet"): ("D", "C1")}
    safeties = sorted({r["safety"] for r in rows})
    for ax, key, what in ((axes[0], "err_u", "static tip deflection (mean of the response)"),
                          (axes[1], "err_t", "first period")):
        pts = [(r["wall_iem"], abs(r[key])) for r in rows]
        for (cell, integ), (m, c) in style.items():
            for s in safeties:
                sel = [r for r in rows if r["cell"] == cell and r["safety"] == s
                       and integrator(r) == integ]
                if not sel:
                    continue
                filled = s == max(safeties)
                ax.loglog([r["wall_iem"] for r in sel], [abs(r[key]) for r in sel], m, color=c,
                          mfc=c if filled else "none", ms=7, ls="none",
                          label=f"{cell}, {integ}, dt_safety {s:g}")
                for r in sel:
                    if filled:
                        ax.annotate(str(r["ny"]), (r["wall_iem"], abs(r[key])), fontsize=7,
                                    xytext=(4, 3), textcoords="offset points")
        idx = front(pts)
        ax.loglog([pts[i][0] for i in idx], [pts[i][1] for i in idx], "-", color="k", lw=1,
                  alpha=0.6, label="Pareto front")
        ax.set_xlabel("wall time of the time loop (s), 1 rank")
        ax.set_ylabel("|relative error| against the FE reference")
        ax.set_title(what, fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle("Cantilever step load, 3 periods, RK4 and velocity Verlet: error against "
                 "wall time "
                 "(labels: cells through the depth)", fontsize=10)
    fig.tight_layout()
    ib.save_figure(fig, png)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--iem", help="path of the iem executable")
    ap.add_argument("--png", help="write the Pareto plot here")
    ib.add_sweep_args(ap, CELLS)
    ap.add_argument("--dt-safety", type=float, nargs="+", default=[0.5, 0.9])
    ap.add_argument("--integrators", nargs="+", default=list(INTEGRATORS), choices=INTEGRATORS)
    ap.add_argument("--periods", type=float, default=3.0)
    return ib.measure_and_report(ap, run_all, report)


if __name__ == "__main__":
    sys.exit(main())
