#!/usr/bin/env python3
"""Round-off of the force kernel against a 40-digit reference, for one or more builds.

Compiles benchmarks/kernel_accuracy/forces.f90 against each build's library (the build
folder's libiem.a and modules: a build of this repository, or a baseline from
benchmarks/baseline.sh), evaluates the nodal forces of a 24 x 12 grid of the paper's cell at
strains of about 1e-4 and 1e-5, and compares them with the gradient of the cell energy
evaluated in 40-digit arithmetic (mpmath; central differences with a step of 1e-18 m). Prints
the largest and the root-mean-square error over the largest force, per build, and the largest
difference between the builds. Usage (from the repository root):

    python3 benchmarks/kernel_accuracy.py build "$(dirname "$(bash benchmarks/baseline.sh f17bd0c)")"

Needs mpmath (pip install mpmath) and the MPI Fortran compiler wrapper (mpif90).
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
NX, NY = 24, 12
NN = (NX + 1) * (NY + 1)


def compile_driver(build: Path, exe: Path) -> None:
    """Compile the forces driver against a build folder's library and modules."""
    cmd = ["mpif90", "-O3", "-march=native", f"-I{build / 'modules'}",
           str(HERE / "kernel_accuracy" / "forces.f90"), str(build / "libiem.a"), "-o", str(exe),
           "-lhdf5_openmpi_fortran", "-lhdf5_openmpi"]
    subprocess.run(cmd, check=True)


def forces(exe: Path, s: float, folder: Path) -> tuple[np.ndarray, np.ndarray, tuple]:
    """Run the driver at size s: the displacements (NN, 2), forces (NN, 2) and constants."""
    subprocess.run([str(exe), f"{s:.3e}"], check=True, cwd=folder)
    d = np.fromfile(folder / "out.bin", dtype=np.float64)
    return d[3:3 + 2 * NN].reshape(NN, 2), d[3 + 2 * NN:].reshape(NN, 2), tuple(d[:3])


def reference(y: np.ndarray, consts: tuple) -> np.ndarray:
    """The nodal forces dPi/dx of the paper's cell energy, summed over the grid's cells, in
    40-digit arithmetic (central differences of the energy of each cell)."""
    import mpmath as mp
    mp.mp.dps = 40
    ce, ch, cg = (mp.mpf(c) for c in consts)
    l0 = mp.mpf("0.01")
    x = [[mp.mpf(n % (NX + 1)) * l0 + mp.mpf(y[n, 0]), mp.mpf(n // (NX + 1)) * l0 + mp.mpf(y[n, 1])]
         for n in range(NN)]

    def energy(p):
        e = [[p[(q + 1) % 4][0] - p[q][0], p[(q + 1) % 4][1] - p[q][1]] for q in range(4)]
        length = [mp.sqrt(v[0] ** 2 + v[1] ** 2) for v in e]
        eps = [length[q] / l0 - 1 for q in range(4)]
        u = [[e[q][0] / length[q], e[q][1] / length[q]] for q in range(4)]
        s = [-(u[q][0] * u[q - 1][0] + u[q][1] * u[q - 1][1]) for q in range(4)]
        return (ce * sum(v * v for v in eps) + ch * sum((eps[q] + eps[q - 1]) ** 2 for q in range(4))
                + cg * sum(v * v for v in s))

    f = [[mp.mpf(0), mp.mpf(0)] for _ in range(NN)]
    h = mp.mpf("1e-18")
    for j in range(NY):
        for i in range(NX):
            n0 = j * (NX + 1) + i
            nodes = [n0, n0 + 1, n0 + NX + 2, n0 + NX + 1]
            p = [list(x[m]) for m in nodes]
            for q in range(4):
                for d in range(2):
                    pp = [list(v) for v in p]
                    pm = [list(v) for v in p]
                    pp[q][d] += h
                    pm[q][d] -= h
                    f[nodes[q]][d] += (energy(pp) - energy(pm)) / (2 * h)
    return np.array([[float(a), float(b)] for a, b in f])


def main() -> int:
    """Compile, run and compare; print one line per build and size."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("builds", nargs="+", help="build folders (with libiem.a and modules/)")
    ap.add_argument("--sizes", type=float, nargs="+", default=[1e-6, 1e-7])
    args = ap.parse_args()
    try:
        import mpmath  # noqa: F401
    except ImportError:
        print("kernel_accuracy.py needs mpmath: pip install mpmath", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        exes = []
        for k, b in enumerate(args.builds):
            exe = folder / f"forces_{k}"
            compile_driver(Path(b).resolve(), exe)
            exes.append(exe)
        print("| build | size s (m) | max error / max force | rms error / max force |")
        print("|---|---|---|---|")
        for s in args.sizes:
            results = [forces(exe, s, folder) for exe in exes]
            ref = reference(results[0][0], results[0][2])
            scale = float(np.abs(ref).max())
            for b, (y, f, _) in zip(args.builds, results):
                if not np.array_equal(y, results[0][0]):
                    raise SystemExit("the builds' states differ")
                err = np.abs(f - ref)
                print(f"| {b} | {s:.0e} | {err.max() / scale:.2e} | "
                      f"{np.sqrt((err ** 2).mean()) / scale:.2e} |")
            for k in range(1, len(results)):
                print(f"\nlargest difference {args.builds[k]} - {args.builds[0]} at s = {s:.0e}: "
                      f"{np.abs(results[k][1] - results[0][1]).max() / scale:.2e} of the largest force")
    return 0


if __name__ == "__main__":
    sys.exit(main())
