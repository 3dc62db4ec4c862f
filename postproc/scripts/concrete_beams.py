#!/usr/bin/env python3
"""The paper's concrete beams (Figs. 15-18): the numbers docs/fracture.md quotes, from the
outputs of inputs/concrete_cantilever_fracture.nml and inputs/concrete_beam_fracture.nml (run
by scripts/paper_figures.sh).

For each run it prints the initial slope of the load-deflection curve (a straight-line fit
over 10-50% of the peak load, before the peak) against the Timoshenko beam (Cowper's shear
coefficient), the peak load against the elastic cracking load (the load at which beam theory
puts f_t at the extreme fibre), the largest kinetic energy over the external work after the
first 10% of the run (the ramp and its transient), the damping and fracture energies over the
work, the failed springs by kind, and the path of the crack (the first failure, then the
lowest and highest failed tension spring at four times).

Usage: python3 postproc/scripts/concrete_beams.py --dir run/fracture
The scene constants below must match the two inputs.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import h5py
import numpy as np

from iem_post.references import (
    cantilever_tip_deflection_timoshenko,
    kappa_cowper,
    simply_supported_midspan_deflection_timoshenko,
)

E, NU, FT, H, T, L = 25.0e9, 0.1667, 2.5e6, 0.2, 0.1, 1.0
KINDS = {1: "tension", 2: "crushing", 3: "shear"}
SCENES = {
    # file stem: (kind, load bc, deflection probe, ramp end (s))
    "concrete_cantilever_fracture": ("cantilever", "tip", "tip", 0.01),
    "concrete_beam_fracture": ("simple", "load", "mid_bottom", 0.005),
}


def beam_theory(kind: str) -> tuple[float, float]:
    """Timoshenko stiffness P/w (N/m) and the elastic cracking load (N) of the scene."""
    k = kappa_cowper(NU)
    if kind == "cantilever":
        w1 = cantilever_tip_deflection_timoshenko(1.0, L, E, NU, H, T, kappa=k)
        moment_arm = L
    else:
        w1 = simply_supported_midspan_deflection_timoshenko(1.0, L, E, NU, H, T, kappa=k)
        moment_arm = L / 4.0
    return 1.0 / w1, FT * T * H**2 / 6.0 / moment_arm


def report(path: Path, kind: str, bc: str, probe: str, t_ramp: float) -> None:
    """Prints the measures of one run."""
    with h5py.File(path, "r") as f:
        h = f["history"]
        t = h["time"][:]
        load = -h["reactions"][bc][:, 1]
        w = -h["probes"][probe]["displacement"][:, 1]
        energy = {k: h["energy"][k][:] for k in h["energy"]}
        ev = {k: h["fracture/events"][k][:] for k in h["fracture/events"]}
        frame_t = f["frames/time"][:]
    i = int(np.argmax(load))
    fit = (load > 0.1 * load[i]) & (load < 0.5 * load[i]) & (np.arange(load.size) < i)
    slope = np.polyfit(w[fit], load[fit], 1)[0]
    k_th, p_cr = beam_theory(kind)
    after = t > max(0.1 * t[-1], 5.0 * t_ramp)
    work = energy["external_work"]
    ke = np.max(energy["kinetic"][after] / work[after])
    print(f"{path.name}:")
    print(f"  initial slope {slope:.4e} N/m, Timoshenko {k_th:.4e} N/m: {slope / k_th - 1:+.2%}")
    print(f"  peak load {load[i]:.0f} N at deflection {w[i] * 1e3:.3f} mm, t = {t[i]:.4f} s; "
          f"elastic cracking load {p_cr:.0f} N (ratio {load[i] / p_cr:.2f})")
    print(f"  final: deflection {w[-1] * 1e3:.3f} mm, load {load[-1]:.0f} N "
          f"({load[-1] / load[i]:.1%} of the peak)")
    print(f"  kinetic / work after the first 10% of the run: at most {ke:.2e}; "
          f"damping / work {energy['damping'][-1] / work[-1]:.2%}; "
          f"fracture / work {energy['fracture'][-1] / work[-1]:.1%}; "
          f"fracture energy {energy['fracture'][-1]:.3f} J (G_f x section = {100.0 * H * T:.3f} J)")
    counts = {name: int(np.sum(ev["kind"] == k)) for k, name in KINDS.items()}
    print(f"  failed springs: {counts}")
    if ev["time"].size:
        j = 0
        print(f"  first failure t = {ev['time'][j]:.4f} s ({KINDS.get(int(ev['kind'][j]))}) "
              f"at ({ev['x'][j]:.4f}, {ev['y'][j]:.4f}) m, deflection "
              f"{np.interp(ev['time'][j], t, w) * 1e3:.3f} mm")
        for frac in (0.25, 0.5, 0.75, 1.0):
            tt = t[0] + frac * (t[-1] - t[0])
            sel = ev["time"] <= tt
            tens = sel & (ev["kind"] == 1)
            ys = ev["y"][tens]
            span = f"y {ys.min():.4f}..{ys.max():.4f} m" if ys.size else "none"
            others = {KINDS[k]: int(np.sum(sel & (ev["kind"] == k))) for k in (2, 3)}
            print(f"  by t = {tt:.3f} s (deflection {np.interp(tt, t, w) * 1e3:.3f} mm): "
                  f"tension cracks over {span}; {others}")
    print(f"  frames: {frame_t.size}, every {frame_t[1] - frame_t[0]:.4f} s")


def main() -> None:
    """Reads the arguments and reports each run found."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dir", default="run/fracture", help="folder of the two outputs")
    args = parser.parse_args()
    for stem, (kind, bc, probe, t_ramp) in SCENES.items():
        path = Path(args.dir) / f"{stem}.h5"
        if path.exists():
            report(path, kind, bc, probe, t_ramp)
        else:
            print(f"{path}: not found")


if __name__ == "__main__":
    main()
