#!/usr/bin/env python3
"""Cost of a run that may fracture, before anything has failed, against the same run without
fracture (issue 11's speed target: at most 1.2 times).

A concrete cantilever (1 m x 0.1 m, 1 mm cells: 1.0e5 nodes, E = 25 GPa) under a tip shear
traction stepped on at t = 0, run for a fixed number of steps, with and without
`fracture = .true.` (f_t = 3 MPa, G_f = 100 J/m^2: nothing reaches the onset in that time,
which the script checks from /history/energy/fracture), with RK4 and with velocity Verlet.
With --every the material has every criterion (f_c = 30 MPa, G_c = 44 kJ/m^2, shear strength
3 MPa, G_s = 100 J/m^2; none reached either). The two variants run in interleaved pairs; it
prints iem's own node-steps per second (time loop only) of each and the median of the
per-pair ratios. Usage (from the repository root):

    python3 benchmarks/fracture_cost.py --iem build/iem [--repeat 5] [--nx 1000] [--every]
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


def scene(nx: int, integrator: str, fracture: bool, out: Path, every: bool = False) -> str:
    """The namelist of the scene; every: crushing and shear criteria too."""
    ny = max(1, nx // 10)
    material = "E = 25.0e9, nu = 0.2, density = 2400.0"
    if fracture:
        material += ", fracture = .true., tensile_strength = 3.0e6, fracture_energy = 100.0"
        if every:
            material += (",\n  compressive_strength = 30.0e6, crushing_energy = 44000.0, "
                         "shear_strength = 3.0e6, shear_fracture_energy = 100.0")
    # about 300 steps at 0.9 of the RK4 limit of 1 mm cells (Verlet: about 200)
    t_end = 1.0e-4 * 1000.0 / nx
    return f"""&run
  t_end = {t_end}, dt_safety = 0.9, integrator = '{integrator}'
  output_interval = 1.0, history_interval = 1.0, output_file = '{out}', overwrite = .true.
/
&geometry
  length = 1.0, height = 0.1, thickness = 0.1, nx = {nx}, ny = {ny}, plane = 'stress'
/
&material
  {material}
/
&bc
  name = 'clamp', where = 'left', kind = 'fix', dofs = 'xy'
/
&load
  name = 'tip', kind = 'edge', where = 'right', traction = 0.0, -1.0e5
  time_function = 'step', t_start = 0.0
/
"""


def dissipated(path: Path) -> float:
    import h5py
    with h5py.File(path, "r") as f:
        return float(f["history/energy/fracture"][-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--iem", required=True)
    ap.add_argument("--mpiexec", default="mpirun")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--nx", type=int, default=1000)
    ap.add_argument("--every", action="store_true", help="crushing and shear criteria too")
    args = ap.parse_args()
    iem = str(Path(args.iem).resolve())
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for integrator in ("rk4", "verlet"):
            rates = {False: [], True: []}
            ratios = []
            for _ in range(args.repeat):
                pair = {}
                for fracture in (False, True):
                    out = Path(tmp) / f"run_{integrator}_{int(fracture)}.h5"
                    nml = Path(tmp) / f"run_{integrator}_{int(fracture)}.nml"
                    nml.write_text(scene(args.nx, integrator, fracture, out, args.every))
                    text, _ = ib.run(iem, nml, 1, args.mpiexec)
                    pair[fracture] = float(re.search(rf"node-steps/s \(\s*{ib.NUM} per rank", text)[1])
                    rates[fracture].append(pair[fracture])
                    if fracture and dissipated(out) != 0.0:
                        print("error: a spring failed in the fracture variant; the comparison "
                              "is not of an idle fracture state", file=sys.stderr)
                        return 1
                ratios.append(pair[False] / pair[True])
            rows.append((integrator, statistics.median(rates[False]),
                         statistics.median(rates[True]), statistics.median(ratios),
                         min(ratios), max(ratios)))
    nodes = (args.nx + 1) * (max(1, args.nx // 10) + 1)
    print(f"Machine: {ib.machine()}. Build: {ib.build_info(iem)}. 1 rank, {nodes} nodes, "
          f"{args.repeat} interleaved pairs; criteria: "
          f"{'tension, crushing, shear' if args.every else 'tension'}; nothing failed "
          "(history/energy/fracture = 0).\n")
    print("| integrator | elastic node-steps/s | fracture on, idle | cost ratio (median of pairs) | min | max |")
    print("|---|---|---|---|---|---|")
    for integrator, el, fr, ratio, lo, hi in rows:
        print(f"| {integrator} | {el:.3e} | {fr:.3e} | {ratio:.3f} | {lo:.3f} | {hi:.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
