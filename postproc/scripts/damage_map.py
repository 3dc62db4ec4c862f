#!/usr/bin/env python3
"""The damage of a fracture run's frame, optionally zoomed on a box, and which criteria the
damaged cells in that box have passed.

Draws the cells of frame N at ``coordinates + scale * displacement`` coloured by
``/frames/frame_NNNNNN/damage`` (0 intact .. 1 every spring failed), with the springs failed by
then (``failed_springs``) drawn black: unlike ``iem-post crack-map`` it shows the softening
zone, the springs past their onset that have not failed yet.

With ``--onsets EPS_T,EPS_C,GAMMA_S`` (the onset strains of tension, crushing and shear,
f_t/E', f_c/E' and tau/G) it also prints, for each cell in the box whose damage is at least
0.05, the largest strain each criterion has seen over the frames up to N, over its onset,
from the frames' displacements and the model's measures (the engineering strain of each edge,
the sine of each corner's angle change). A ratio above 1 means that criterion has softened
the cell. Frames are samples: a peak between two frames is missed, so the ratios are lower
bounds of the run's own history.

Usage: python3 postproc/scripts/damage_map.py FILE.h5 [--frame N] [--scale S]
           [--box X0,X1,Y0,Y1] [--onsets EPS_T,EPS_C,GAMMA_S] [-o PNG]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from matplotlib.collections import LineCollection

from iem_post import IemFile
from iem_post.fracture import read_damage, read_failed_springs, spring_segments
from iem_post.fracture_plots import draw_cells, lattice_figure
from iem_post.plots import save_figure


def floats(text: str, n: int) -> list[float]:
    """``n`` comma-separated numbers."""
    values = [float(v) for v in text.split(",")]
    if len(values) != n:
        raise argparse.ArgumentTypeError(f"expected {n} comma-separated numbers: {text!r}")
    return values


def largest_strains(data: IemFile, index: int, cells: np.ndarray) -> np.ndarray:
    """(len(cells), 3, 4): the largest tensile and compressive strain of edges 1-4 and the
    largest |shear| of corners 1-4 over frames 0..index."""
    mesh = data.mesh
    corners = mesh.cells[cells]
    x0 = mesh.coordinates[corners]
    out = np.zeros((cells.size, 3, 4))
    n_frames = index % len(data.frames) + 1
    for k in range(n_frames):
        x1 = x0 + data.frame(k).displacement[corners]
        for q in range(4):
            a0 = x0[:, (q + 1) % 4] - x0[:, q]
            a1 = x1[:, (q + 1) % 4] - x1[:, q]
            b1 = x1[:, (q - 1) % 4] - x1[:, q]
            la, lb = np.linalg.norm(a1, axis=1), np.linalg.norm(b1, axis=1)
            eps = la / np.linalg.norm(a0, axis=1) - 1.0
            shear = np.abs((a1 * b1).sum(axis=1) / (la * lb))
            out[:, 0, q] = np.maximum(out[:, 0, q], eps)
            out[:, 1, q] = np.maximum(out[:, 1, q], -eps)
            out[:, 2, q] = np.maximum(out[:, 2, q], shear)
    return out


def main() -> None:
    """Draws the damage map and prints the criteria of the damaged cells in the box."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("file", type=Path)
    parser.add_argument("--frame", type=int, default=-1)
    parser.add_argument("--scale", type=float, default=0.0)
    parser.add_argument("--box", type=lambda s: floats(s, 4), default=None,
                        help="X0,X1,Y0,Y1: draw and report only this part (m)")
    parser.add_argument("--onsets", type=lambda s: floats(s, 3), default=None,
                        help="EPS_T,EPS_C,GAMMA_S: print the criteria passed in the box")
    parser.add_argument("-o", "--output", type=Path, default=None)
    args = parser.parse_args()

    with IemFile(args.file) as data:
        mesh = data.mesh
        index = args.frame % len(data.frames)
        frame = data.frame(index)
        _, damage = read_damage(data, index)
        _, springs = read_failed_springs(data, index)
        positions = mesh.coordinates + args.scale * frame.displacement
        centres = mesh.coordinates[mesh.cells].mean(axis=1)
        if args.box:
            x0, x1, y0, y1 = args.box
            inside = ((centres[:, 0] >= x0) & (centres[:, 0] <= x1)
                      & (centres[:, 1] >= y0) & (centres[:, 1] <= y1))
            shown = positions[mesh.cells[inside]].reshape(-1, 2)
        else:
            inside = np.ones(mesh.n_cells, dtype=bool)
            shown = positions
        fig, ax = lattice_figure(shown, width=8.0)
        cells = draw_cells(ax, mesh, positions, array=damage, cmap="YlOrRd", clim=(0.0, 1.0))
        fig.colorbar(cells, ax=ax, label="damage", shrink=0.9)
        segments = spring_segments(positions, mesh.cells, springs)
        ax.add_collection(LineCollection(segments, colors="k", linewidths=1.5, zorder=4),
                          autolim=False)
        counts = ", ".join(f"{n} {name}" for name, n in springs.counts().items())
        ax.set_title(f"{args.file.name}: frame {index}, t = {frame.time:.4g} s, damage\n"
                     f"failed springs (black): {counts}")
        out = args.output or args.file.with_name(f"{args.file.stem}_damage_{index:06d}.png")
        print(save_figure(fig, out))

        if args.onsets:
            damaged = np.where(inside & (damage >= 0.05))[0]
            ratios = largest_strains(data, index, damaged) / np.array(args.onsets)[None, :, None]
            print("cell centre (m)      damage  tension/onset (edges 1-4)   "
                  "crushing/onset   shear/onset (corners 1-4)")
            for row, c in enumerate(damaged):
                t, c_, s = ratios[row]
                print(f"({centres[c, 0]:.4f}, {centres[c, 1]:.4f})  {damage[c]:.2f}   "
                      f"{' '.join(f'{v:6.1f}' for v in t)}   {c_.max():6.2f}   "
                      f"{' '.join(f'{v:6.1f}' for v in s)}")


if __name__ == "__main__":
    main()
