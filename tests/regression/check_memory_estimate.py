"""The memory estimate that iem logs before it allocates (src/core/iem_memory.f90) against
the peak resident memory it reports at the end of the run: from 1e5 to 2e5 nodes the peak
must grow by the estimate's growth within 30% (the program's fixed ~20-25 MB, which depends on
the phase that makes the peak, cancels), with a checkpoint written (its buffers are part of
the estimate): 1 rank with RK4 and with velocity Verlet, and 2 ranks (the largest peak of
the ranks, none of which holds an array over the whole body)."""

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

CASE = """&run
  t_end = {t_end:.6e}, output_interval = {t_end:.6e}, history_interval = {t_end:.6e}
  checkpoint_interval = {t_chk:.6e}, integrator = '{integrator}'
  output_file = 'm.h5', overwrite = .true., progress_interval = 1.0e6
/
&geometry
  length = 2.0, height = 1.0, thickness = 0.1, nx = {nx}, ny = {ny}
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

UNITS = {"B": 1.0, "KiB": 2.0**10, "MiB": 2.0**20, "GiB": 2.0**30, "TiB": 2.0**40}


def run(args, folder: Path, ny: int, ranks: int, integrator: str) -> tuple[float, float]:
    """Estimated bytes of a rank and measured peak bytes (largest rank) of one run."""
    t_end = 4 * 1.6e-4 / ny
    (folder / "m.nml").write_text(CASE.format(t_end=t_end, t_chk=t_end / 2, nx=2 * ny, ny=ny,
                                              integrator=integrator))
    cmd = [args.mpiexec, *[f for f in args.mpiexec_flags.split(";") if f], "-n", str(ranks),
           args.iem, "m.nml"]
    p = subprocess.run(cmd, cwd=folder, text=True, capture_output=True, timeout=300,
                       env=dict(os.environ))
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stdout[-2000:]}{p.stderr[-2000:]}")
    est = re.search(r"memory: about ([\d.e+]+) (\w+) needed on each of", p.stdout)
    peak = re.search(r"memory: peak ([\d.]+) MB per rank \(largest\)", p.stdout)
    if not est or not peak:
        sys.exit(f"no memory lines in the output of {' '.join(cmd)}:\n{p.stdout[-2000:]}")
    if "checkpoint:" not in p.stdout:
        sys.exit("no checkpoint was written")
    return float(est[1]) * UNITS[est[2]], float(peak[1]) * 2.0**20


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--iem", required=True)
    ap.add_argument("--mpiexec", required=True)
    ap.add_argument("--mpiexec-flags", default="")
    ap.add_argument("--tolerance", type=float, default=0.30)
    args = ap.parse_args()
    failed = 0
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for ranks, integrator in [(1, "rk4"), (1, "verlet"), (2, "rk4")]:
            est_1, peak_1 = run(args, folder, 224, ranks, integrator)
            est_2, peak_2 = run(args, folder, 317, ranks, integrator)
            ratio = (est_2 - est_1) / (peak_2 - peak_1)
            ok = abs(ratio - 1.0) <= args.tolerance
            failed += not ok
            mib = 2.0**20
            print(f"{'ok  ' if ok else 'FAIL'} {ranks} rank(s), {integrator}, 101,025 -> "
                  f"202,125 nodes: estimate {est_1 / mib:.1f} -> {est_2 / mib:.1f} MiB, "
                  f"measured peak {peak_1 / mib:.1f} -> {peak_2 / mib:.1f} MiB: "
                  f"ratio of the growths {ratio:.2f}")
    print("all checks passed" if not failed else f"{failed} check(s) failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
