#!/usr/bin/env python3
"""The paper's nonlinear results (Figs. 10, 12, 13, 14), from the outputs of the four scenes
in inputs/ (run by scripts/paper_figures.sh):

* Fig. 10: cantilever tip load-deflection, static, material-nonlinear
  (cantilever_nonlinear_static.h5) against the fibre-section beam reference of the same
  hyperbolic law (iem_post.fibre_beam) and the elastic lines;
* Fig. 12: simply supported beam, mid-span deflection relative to the end faces
  (simply_supported_nonlinear_static.h5), the same comparison;
* Fig. 13: cantilever under a step tip load with damping 0.03, tip deflection against time
  (cantilever_nonlinear_dynamic.h5), with the static nonlinear and elastic deflections at the
  same load;
* Fig. 14: stress-strain loops of the top edge spring of the cell at the clamped top corner
  (spring probe root_top) with the spring's skeleton curve.

Usage: python3 postproc/scripts/paper_figures.py --dir run/paper --out docs/img
Prints, per figure, the numbers the text of docs/nonlinear.md quotes.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from iem_post import fibre_beam  # noqa: E402
from iem_post.references import (  # noqa: E402
    cantilever_tip_deflection_timoshenko,
    deflection_relative_to_end_faces,
    simply_supported_midspan_deflection_timoshenko,
)

E, NU, FT, FC, TAU, L, H, T = 25e9, 0.2, 3.0e6, 30.0e6, 6.0e6, 1.0, 0.1, 0.1


def total_load(h: h5py.File) -> float:
    """Full-scale load of the scene from its input text (traction x h x t, or point force)."""
    text = h.attrs["input_text"]
    text = text.decode() if isinstance(text, bytes) else str(text)
    for line in text.splitlines():
        line = line.split("!")[0]
        if "traction" in line:
            return abs(float(line.split("traction")[1].split("=")[1].split(",")[1])) * H * T
        if "force" in line and "kind = 'nodal'" in text:
            return abs(float(line.split("force")[1].split("=")[1].split(",")[1]))
    raise ValueError("no load found in the input text")


def fibre(scene: str, p: float) -> float:
    """The fibre-section beam's deflection at load p, elastic shear deformation included."""
    if scene == "cantilever":
        return fibre_beam.cantilever_tip_deflection(p, L=L, E=E, f_t=FT, f_c=FC, h=H, t=T, nu=NU,
                                                    shear=True)
    return fibre_beam.simply_supported_midspan_deflection(p, L=L, E=E, f_t=FT, f_c=FC, h=H, t=T,
                                                          nu=NU, shear=True)


def frames(h: h5py.File) -> list[str]:
    return sorted(k for k in h["frames"] if k.startswith("frame_"))


def fig_static(path: Path, scene: str, out: Path) -> None:
    with h5py.File(path, "r") as h:
        p_full = total_load(h)
        lf = h["history/static/load_factor"][:]
        if scene == "cantilever":
            d = -h["history/probes/tip/displacement"][:, 1]
        else:
            xy = h["mesh/coordinates"][:]
            d = np.array([-deflection_relative_to_end_faces(xy, h[f"frames/{k}/displacement"][:], 0.5, 0.0)
                          for k in frames(h)])
    p = lf * p_full
    ref = np.array([fibre(scene, pi) for pi in p])
    fine = path.with_name(path.stem + "_fine.h5")
    fine_d = None
    if fine.exists():
        with h5py.File(fine, "r") as h:
            fine_d = -h["history/probes/tip/displacement"][:, 1]
            fine_p = h["history/static/load_factor"][:] * total_load(h)
    if scene == "cantilever":
        elastic = cantilever_tip_deflection_timoshenko(1.0, L, E, NU, H, T) * p
    else:
        elastic = simply_supported_midspan_deflection_timoshenko(1.0, L, E, NU, H, T) * p
    lattice_elastic = d[1] / p[1] * p  # the lattice's own initial stiffness (first step)
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    ax.plot(d * 1e3, p / 1e3, "o-", ms=3, label="iem, nonlinear springs (80 x 8)")
    if fine_d is not None:
        ax.plot(fine_d * 1e3, fine_p / 1e3, "s-", ms=3, label="iem, nonlinear springs (160 x 16)")
    ax.plot(ref * 1e3, p / 1e3, "k--", label="fibre-section beam, same hyperbolic law")
    ax.plot(elastic * 1e3, p / 1e3, ":", color="gray", label="elastic (Timoshenko)")
    ax.plot(lattice_elastic * 1e3, p / 1e3, ":", color="C0", alpha=0.6,
            label="iem initial stiffness (80 x 8)")
    what = "tip deflection u_y(L, h/2)" if scene == "cantilever" else \
        "mid-span deflection relative to the end faces"
    ax.set_xlabel(f"{what} (mm)")
    ax.set_ylabel("load P (kN)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig_no = 10 if scene == "cantilever" else 12
    ax.set_title(f"Fig. {fig_no} analogue: {scene.replace('_', ' ')} "
                 f"(f_t = 3, f_c = 30, tau = 6 MPa)", fontsize=10)
    fig.tight_layout()
    fig.savefig(out / f"fig{fig_no}_{scene}_load_deflection.png", dpi=130)
    print(f"Fig. {fig_no} ({scene}): P (kN), iem (mm), fibre (mm), iem/fibre, iem/initial-line")
    for i in range(0, len(p), max(1, len(p) // 6)):
        if p[i] > 0:
            print(f"  {p[i] / 1e3:6.3f}  {d[i] * 1e3:8.4f}  {ref[i] * 1e3:8.4f}  {d[i] / ref[i]:6.3f}"
                  f"  {d[i] / lattice_elastic[i]:6.3f}")
    print(f"  last: {p[-1] / 1e3:6.3f}  {d[-1] * 1e3:8.4f}  {ref[-1] * 1e3:8.4f}  "
          f"{d[-1] / ref[-1]:6.3f}  {d[-1] / lattice_elastic[-1]:6.3f}")
    if fine_d is not None:
        print("  160 x 16: P (kN), iem (mm), iem/fibre")
        for i in range(0, len(fine_p), max(1, len(fine_p) // 6)):
            if fine_p[i] > 0:
                r = fibre(scene, fine_p[i])
                print(f"  {fine_p[i] / 1e3:6.3f}  {fine_d[i] * 1e3:8.4f}  {fine_d[i] / r:6.3f}")
        r = fibre(scene, fine_p[-1])
        print(f"  last: {fine_p[-1] / 1e3:6.3f}  {fine_d[-1] * 1e3:8.4f}  {fine_d[-1] / r:6.3f}")


def fig_dynamic(path: Path, static_path: Path | None, out: Path) -> None:
    with h5py.File(path, "r") as h:
        p = total_load(h)
        t = h["history/time"][:]
        u = -h["history/probes/tip/displacement"][:, 1]
        e = h["history/springs/root_top/strain"][:]
        s = h["history/springs/root_top/stress"][:]
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.plot(t * 1e3, u * 1e3, lw=1, label="iem, nonlinear springs, damping 0.03")
    elastic = cantilever_tip_deflection_timoshenko(p, L, E, NU, H, T)
    ax.axhline(elastic * 1e3, color="gray", ls=":", label="static elastic (Timoshenko)")
    ref = fibre("cantilever", p)
    ax.axhline(ref * 1e3, color="k", ls="--", label="static nonlinear, fibre-section beam")
    if static_path is not None and static_path.exists():
        with h5py.File(static_path, "r") as hs:
            lf = hs["history/static/load_factor"][:] * total_load(hs)
            ds = -hs["history/probes/tip/displacement"][:, 1]
        ax.axhline(np.interp(p, lf, ds) * 1e3, color="C1", ls="--", lw=1,
                   label="static nonlinear, iem (virgin loading)")
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("tip deflection (mm)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"Fig. 13 analogue: cantilever, step load P = {p:.0f} N", fontsize=10)
    fig.tight_layout()
    fig.savefig(out / "fig13_cantilever_step_response.png", dpi=130)
    last = t >= t[-1] - 0.02
    print(f"Fig. 13: P = {p:.0f} N, peak {u.max() * 1e3:.4f} mm at t = {t[u.argmax()] * 1e3:.2f} ms, "
          f"mean of the last 20 ms {u[last].mean() * 1e3:.4f} mm (range {np.ptp(u[last]) * 1e3:.2e} mm), "
          f"elastic static {elastic * 1e3:.4f} mm, fibre static {ref * 1e3:.4f} mm")

    j = 2  # the top edge spring (edge 3) of the cell at the clamped top corner
    er = FT / E
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    ax.plot(e[:, j] * 1e3, s[:, j] / 1e6, lw=0.8, label="top edge spring, clamped top cell")
    x = np.linspace(min(e[:, j].min(), -2 * er), e[:, j].max() * 1.05, 400)
    eq = E / (1 + NU)
    skel = np.where(x >= 0, eq * x / (1 + x / er), eq * x / (1 + np.abs(x) / (FC / E)))
    ax.plot(x * 1e3, skel / 1e6, "k--", lw=1, label="skeleton (hyperbola)")
    ax.set_xlabel("spring strain (1e-3)")
    ax.set_ylabel("spring stress (MPa)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("Fig. 14 analogue: stress-strain loops closing as the motion decays", fontsize=10)
    fig.tight_layout()
    # inset: the loops after the first peak, coloured by time, with the stress relative to
    # the chord of each loop removed (s - Eq e) so that their width shows
    after = np.arange(len(t)) >= int(np.argmax(e[:, j]))
    ins = ax.inset_axes([0.12, 0.12, 0.42, 0.42])
    sc = ins.scatter(e[after, j] * 1e3, (s[after, j] - eq * e[after, j]) / 1e6, c=t[after] * 1e3,
                     s=1.5, cmap="viridis")
    ins.set_title("after the first peak: s - Eq e (MPa)", fontsize=7)
    ins.tick_params(labelsize=6)
    cb = fig.colorbar(sc, ax=ins, fraction=0.05, pad=0.02)
    cb.ax.tick_params(labelsize=6)
    cb.set_label("t (ms)", fontsize=6)
    fig.savefig(out / "fig14_spring_loops.png", dpi=130)
    rev = np.sum(np.diff(np.sign(np.diff(e[:, j]))) != 0)
    print(f"Fig. 14: strain range {e[:, j].min():.3e} .. {e[:, j].max():.3e}, stress max "
          f"{s[:, j].max() / 1e6:.3f} MPa (skeleton limit {eq * er / 1e6:.3f}), {rev} reversals; "
          f"last 20 ms strain range {np.ptp(e[last, j]):.2e}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--dir", required=True, help="folder with the four scenes' .h5 files")
    ap.add_argument("--out", default="docs/img")
    a = ap.parse_args()
    d, out = Path(a.dir), Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    fig_static(d / "cantilever_nonlinear_static.h5", "cantilever", out)
    fig_static(d / "simply_supported_nonlinear_static.h5", "simply_supported", out)
    fig_dynamic(d / "cantilever_nonlinear_dynamic.h5", d / "cantilever_nonlinear_static.h5", out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
