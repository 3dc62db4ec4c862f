#!/usr/bin/env python3
"""Cost of nonlinear (hyperbolic, Masing) springs per node-step against the elastic springs.

Runs inputs/cantilever_nonlinear_dynamic.nml (80 x 8, step load, mass damping) for a short
time, as it is (nonlinear) and with the nonlinear springs switched off (elastic), with RK4
and with velocity Verlet, and prints iem's own node-steps per second (time loop only) and
the ratios. Repeats each run and reports the median. Usage (from the repository root):

    python3 benchmarks/nonlinear_cost.py --iem build/iem [--repeat 3] [--t-end 0.04]
"""
from __future__ import annotations

import argparse
import re
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import iembench as ib  # noqa: E402

SCENE = ib.ROOT / "inputs" / "cantilever_nonlinear_dynamic.nml"


def variant(text: str, nonlinear: bool, integrator: str, t_end: float) -> str:
    text = re.sub(r"t_end = [0-9.eE+-]+", f"t_end = {t_end}", text, count=1)
    text = text.replace("dt_safety = 0.9", f"dt_safety = 0.9, integrator = '{integrator}'")
    if not nonlinear:
        text = "\n".join(line for line in text.splitlines()
                         if "nonlinear = .true." not in line and "_strength" not in line)
    return text


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--iem", required=True)
    ap.add_argument("--mpiexec", default="mpirun")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--t-end", type=float, default=0.04)
    args = ap.parse_args()
    iem = str(Path(args.iem).resolve())
    base = SCENE.read_text()
    rates = {}
    with tempfile.TemporaryDirectory() as tmp:
        for integrator in ("rk4", "verlet"):
            for nonlinear in (False, True):
                nml = Path(tmp) / f"run_{integrator}_{int(nonlinear)}.nml"
                nml.write_text(variant(base, nonlinear, integrator, args.t_end))
                got = []
                for _ in range(args.repeat):
                    out, _ = ib.run(iem, nml, 1, args.mpiexec)
                    got.append(float(re.search(rf"node-steps/s \(\s*{ib.NUM} per rank", out)[1]))
                rates[integrator, nonlinear] = statistics.median(got)
    print(f"Machine: {ib.machine()}. Build: {ib.build_info(iem)}. 1 rank, "
          f"t_end = {args.t_end} s, median of {args.repeat}.\n")
    print("| integrator | elastic node-steps/s | nonlinear node-steps/s | nonlinear cost / elastic |")
    print("|---|---|---|---|")
    for integrator in ("rk4", "verlet"):
        el, nl = rates[integrator, False], rates[integrator, True]
        print(f"| {integrator} | {el:.3e} | {nl:.3e} | {el / nl:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
