#!/usr/bin/env python3
"""Figure of one nonlinear spring through two strain histories (docs/nonlinear.md).

Runs iem-spring with substeps, so the branches are drawn as curves, and draws the skeleton
(dashed) and the history points (dots, numbered in the order of the history):
(a) equal strengths (a shear spring), smax = 3 MPa: Masing loops, a loop closed by the
    memory rule, rejoining the skeleton in tension and at the mirror point in compression;
(b) tests/data/masing_history.txt with smax_pos = 3 MPa, smax_neg = 30 MPa.

    python postproc/scripts/plot_masing_history.py --iem-spring build/iem-spring \
        --out docs/img/masing_history.png
"""
import argparse
import os
import subprocess
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
EMAX = 30e9
# panel (a): strains in units of e_r = smax/Emax = 1e-4
HISTORY_A = [3.0, -2.0, 1.5, -0.5, 2.5, 4.0, -1.0, 1.0, -5.0]


def skeleton(e, emax, sp, sn):
    smax = np.where(e >= 0, sp, sn)
    return emax * e / (1.0 + emax * np.abs(e) / smax)


def run_spring(tool, history, sp, sn, substeps):
    """Strain, stress at every substep, and the indices of the history points."""
    out = subprocess.run([tool, history, "--emax", repr(EMAX), "--smax-pos", repr(sp),
                          "--smax-neg", repr(sn), "--substeps", str(substeps)],
                         capture_output=True, text=True, check=True).stdout
    data = np.loadtxt(out.splitlines(), ndmin=2)
    return data[:, 0], data[:, 1], np.arange(substeps - 1, len(data), substeps)


def panel(ax, tool, history, sp, sn, title, substeps=60):
    e, s, pts = run_spring(tool, history, sp, sn, substeps)
    lo, hi = min(e.min(), 0.0), max(e.max(), 0.0)
    pad = 0.08 * (hi - lo)
    es = np.linspace(lo - pad, hi + pad, 800)
    ax.plot(es * 1e3, skeleton(es, EMAX, sp, sn) / 1e6, "k--", lw=1, label="skeleton")
    e0 = np.concatenate([[0.0], e])
    s0 = np.concatenate([[0.0], s])
    ax.plot(e0 * 1e3, s0 / 1e6, "C0-", lw=1.6, label="spring")
    ax.plot(e[pts] * 1e3, s[pts] / 1e6, "o", color="C3", ms=4, label="history points")
    for k, i in enumerate(pts, start=1):
        ax.annotate(str(k), (e[i] * 1e3, s[i] / 1e6), textcoords="offset points",
                    xytext=(4, 4), fontsize=7, color="C3")
    ax.axhline(0, color="0.8", lw=0.6, zorder=0)
    ax.axvline(0, color="0.8", lw=0.6, zorder=0)
    ax.set_xlabel("strain [1e-3]")
    ax.set_ylabel("stress [MPa]")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="lower right")


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--iem-spring", default=os.path.join(ROOT, "build", "iem-spring"))
    ap.add_argument("--history", default=os.path.join(ROOT, "tests", "data", "masing_history.txt"))
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "img", "masing_history.png"))
    a = ap.parse_args()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    with tempfile.TemporaryDirectory() as tmp:
        ha = os.path.join(tmp, "history_a.txt")
        with open(ha, "w") as f:
            f.write("".join(f"{x * 1e-4!r}\n" for x in HISTORY_A))
        panel(axes[0], a.iem_spring, ha, 3e6, 3e6,
              "(a) equal strengths 3 MPa (shear spring)")
    panel(axes[1], a.iem_spring, a.history, 3e6, 30e6,
          "(b) tests/data/masing_history.txt, 3 MPa tension, 30 MPa compression")
    fig.tight_layout()
    fig.savefig(a.out, dpi=130)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
