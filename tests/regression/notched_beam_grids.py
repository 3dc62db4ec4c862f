#!/usr/bin/env python3
"""Grid objectivity of the half-notched beam of Gregoire et al. (2013), called by CTest
(label `long`): the fracture issue's criterion.

The case (--case, inputs/notched_beam_gregoire.nml) is run on --grids (cells through the
depth, each run with nx = 3.5 ny made odd: benchmarks/notched_beam.py builds the variants and
measures them) up to --t-end (default 0.015 s: CMOD about 0.23 mm, past the peak and past the
CMOD at which the energies are compared). Checks, per grid: the run exits 0, its largest
energy-balance error is below 1e-3 and its kinetic energy stays below 2 % of the external work
from twice the ramp time on (the loading is quasi-static), the beam cracks (the load has a
peak inside the run and falls to below 80 % of it); across the grids (the criterion, halving
the cell twice): the peak load, the dissipated energy (/history/energy/fracture) when the CMOD first reaches
--cmod-energy (mm) and the dissipated energy at the end vary by less than 10 % (max/min - 1).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent.parent / "benchmarks"))
import regress as rg  # noqa: E402
import notched_beam as nb  # noqa: E402

CRITERION = 0.10


def main() -> int:
    """Parse arguments, run the grids and check the criterion."""
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--iem", required=True)
    ap.add_argument("--mpiexec", required=True)
    ap.add_argument("--mpiexec-flags", default="", help="extra mpiexec flags, ';'-separated")
    ap.add_argument("--case", required=True, help="namelist of the beam")
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--grids", type=int, nargs=3, default=[10, 20, 40])
    ap.add_argument("--t-end", type=float, default=0.015)
    ap.add_argument("--cmod-energy", type=float, default=0.2)
    args = ap.parse_args()
    nb.SCENE = Path(args.case).resolve()
    work = rg.scratch("notched_beam_grids")
    rows = []
    for ny in args.grids:
        nx, _ = nb.grid(ny)
        name = f"nb_{ny}"
        nml = work / f"{name}.nml"
        text = nb.scene(ny, f"{name}.h5", t_end=args.t_end)
        nml.write_text(text)
        if rg.run_ok(args, args.ranks, nml, work, f"{nx} x {ny} cells") is None:
            return 1
        r = nb.measure(work / f"{name}.h5", args.cmod_energy, nb.ramp_time(text))
        load = np.array(r["load"])
        rg.check(r["balance"] < 1e-3, f"{nx} x {ny}: energy-balance error {r['balance']:.1e} < 1e-3")
        rg.check(r["ke_over_w"] < 0.02,
                 f"{nx} x {ny}: kinetic / external work at most {r['ke_over_w']:.1e} < 0.02")
        rg.check(load[-1] < 0.8 * r["peak"],
                 f"{nx} x {ny}: the load falls past its peak {r['peak']:.1f} N to "
                 f"{load[-1]:.1f} N (< 80 %)")
        rg.check(np.isfinite(r["d_at_cmod"]),
                 f"{nx} x {ny}: the CMOD reaches {args.cmod_energy} mm (end: {r['cmod_end']:.3f})")
        rows.append(r)
        print(f"{nx} x {ny}: peak {r['peak']:.1f} N at CMOD {r['cmod_peak']:.4f} mm, dissipated "
              f"{r['d_at_cmod']:.5f} J at CMOD {args.cmod_energy} mm, {r['d_end']:.5f} J at the end",
              flush=True)
    for key, what in (("peak", "peak load"),
                      ("d_at_cmod", f"dissipated energy at CMOD {args.cmod_energy} mm"),
                      ("d_end", f"dissipated energy at t = {args.t_end} s")):
        values = [r[key] for r in rows]
        s = nb.spread(values) if all(v > 0 for v in values) else float("inf")
        rg.check(s < CRITERION, f"{what} across the grids {args.grids}: "
                                f"{', '.join(f'{v:.5g}' for v in values)}; "
                                f"max/min - 1 = {s:.1%} < {CRITERION:.0%}")
    if rg.FAILURES:
        print(f"{len(rg.FAILURES)} check(s) failed")
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
