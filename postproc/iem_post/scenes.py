"""Measures and closed forms of the scenes with holes and layers (inputs/plate_hole.nml,
inputs/bimaterial_beam.nml, inputs/notched_beam.nml; docs/benchmarks.md).

- ``cell_strains`` / ``cell_stresses``: each cell's strains from its corners' displacements
  (the mean of the two opposite edges' strains, linearised: the small-strain form of the
  lattice's edge strains) and the stresses from them by Hooke's law with the cell's E, nu.
- ``hole_edge_stress``: sigma_xx at the top of a hole on the symmetry line x = 0, from the
  cells of the column x in [0, h] above the hole, extrapolated to the hole's edge.
- ``heywood_kt``: Heywood's stress concentration factor of a finite-width plate with a
  central circular hole in tension.
- ``layered_section`` / ``layered_cantilever_deflection``: the transformed section of a beam
  of bonded layers (neutral axis, EI, the shear stiffness from the shear-stress energy) and
  its Timoshenko tip deflection under an end load.

Only numpy is needed.
"""
from __future__ import annotations

from typing import Dict, Sequence, Tuple

import numpy as np


def cell_strains(coords: np.ndarray, cells: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Strains (eps_x, eps_y, gamma_xy) of each cell, shape (n_cells, 3).

    ``coords`` (n_nodes, 2) and ``u`` (n_nodes, 2) are node coordinates and displacements,
    ``cells`` (n_cells, 4) the corners counter-clockwise from the lower left (the layout of
    ``/mesh``). eps_x is the mean strain of the bottom and top edges, eps_y that of the right
    and left edges, gamma_xy the sum of the mean rotations of the vertical and horizontal edges
    (exact for any linear displacement field)."""
    x = np.asarray(coords, dtype=float)[cells]
    d = np.asarray(u, dtype=float)[cells]
    lx = x[:, 1, 0] - x[:, 0, 0]
    ly = x[:, 3, 1] - x[:, 0, 1]
    ex = ((d[:, 1, 0] - d[:, 0, 0]) + (d[:, 2, 0] - d[:, 3, 0])) / (2 * lx)
    ey = ((d[:, 3, 1] - d[:, 0, 1]) + (d[:, 2, 1] - d[:, 1, 1])) / (2 * ly)
    gxy = (((d[:, 3, 0] - d[:, 0, 0]) + (d[:, 2, 0] - d[:, 1, 0])) / (2 * ly)
           + ((d[:, 1, 1] - d[:, 0, 1]) + (d[:, 2, 1] - d[:, 3, 1])) / (2 * lx))
    return np.stack([ex, ey, gxy], axis=1)


def cell_stresses(strains: np.ndarray, E, nu, plane: str = "stress") -> np.ndarray:
    """Stresses (sigma_xx, sigma_yy, tau_xy) from strains (n, 3) by Hooke's law; ``E`` and
    ``nu`` are scalars or per-cell arrays; ``plane`` is 'stress' or 'strain'."""
    e = np.asarray(strains, dtype=float)
    E = np.asarray(E, dtype=float)
    nu = np.asarray(nu, dtype=float)
    if plane == "stress":
        c = E / (1 - nu**2)
        sx = c * (e[:, 0] + nu * e[:, 1])
        sy = c * (e[:, 1] + nu * e[:, 0])
    elif plane == "strain":
        c = E / ((1 + nu) * (1 - 2 * nu))
        sx = c * ((1 - nu) * e[:, 0] + nu * e[:, 1])
        sy = c * ((1 - nu) * e[:, 1] + nu * e[:, 0])
    else:
        raise ValueError(f"plane must be 'stress' or 'strain', not {plane!r}")
    txy = E / (2 * (1 + nu)) * e[:, 2]
    return np.stack([sx, sy, txy], axis=1)


def hole_edge_stress(coords: np.ndarray, cells: np.ndarray, u: np.ndarray, E: float,
                     nu: float, plane: str = "stress", n_fit: int = 3) -> Dict[str, float]:
    """sigma_xx at the top of a hole centred on the symmetry line x = 0 (the point (0, a)).

    The cells of the column x in [0, h] (the first column of the grid) that lie above the
    body's lowest cell of that column are sorted by height; sigma_xx of the first ``n_fit``
    (from ``cell_strains`` and ``cell_stresses``) is fitted by a polynomial of degree
    ``n_fit - 1`` in y and evaluated at the bottom edge of the first cell (the hole's edge,
    y = a on a grid with a/h whole). Returns ``extrapolated``, ``first_cell`` (the first
    cell's own value, at y = a + h/2), ``y_edge`` and ``h``."""
    xy = np.asarray(coords, dtype=float)
    cells = np.asarray(cells)
    corners = xy[cells]
    x0 = corners[:, 0, 0]
    col = np.where(np.abs(x0 - x0.min()) <= 1e-9 * max(1.0, float(np.ptp(xy[:, 0]))))[0]
    yc = corners[col, :, 1].mean(axis=1)
    order = np.argsort(yc)
    col, yc = col[order], yc[order]
    h = float(corners[col[0], 3, 1] - corners[col[0], 0, 1])
    # the cells of the column must follow one another from the hole's edge up
    if len(col) < n_fit or np.any(np.abs(np.diff(yc[:n_fit]) - h) > 1e-6 * h):
        raise ValueError("the first column does not hold n_fit adjacent cells above the hole")
    s = cell_stresses(cell_strains(xy, cells[col[:n_fit]], u), E, nu, plane)[:, 0]
    y_edge = float(corners[col[0], 0, 1])
    coef = np.polyfit(yc[:n_fit] - y_edge, s, n_fit - 1)
    return {"extrapolated": float(np.polyval(coef, 0.0)), "first_cell": float(s[0]),
            "y_edge": y_edge, "h": h}


def heywood_kt(d_over_w: float) -> Tuple[float, float]:
    """Heywood's factors of a plate of width W with a central hole of diameter d in tension:
    ``(K_tn, K_tg)``, on the net and on the gross stress, ``K_tn = 2 + (1 - d/W)^3``,
    ``K_tg = K_tn / (1 - d/W)`` (R. B. Heywood, Designing by Photoelasticity, 1952; quoted in
    Pilkey & Pilkey, Peterson's Stress Concentration Factors, ch. 4). Both tend to Kirsch's 3
    as d/W -> 0."""
    r = 1.0 - d_over_w
    ktn = 2.0 + r**3
    return ktn, ktn / r


def layered_section(layers: Sequence[Tuple[float, float, float]], t: float,
                    n_int: int = 2001) -> Dict[str, float]:
    """Transformed section of bonded layers, ``layers`` = ``(thickness, E, G)`` from the bottom
    up, width ``t``: ``y_na`` (neutral axis from the bottom), ``EI`` (about it), ``EA`` and
    ``GA_s``, the shear stiffness whose compliance is the energy of the beam-theory shear
    stress ``tau(y) = V Q*(y) / (EI t)`` (``Q*`` the E-weighted first moment of the section
    above y): ``1/GA_s = int Q*(y)^2 / (EI^2 t G(y)) dy``. A single layer gives
    ``GA_s = 5/6 G A``."""
    tops = np.cumsum([lay[0] for lay in layers])
    bots = tops - np.array([lay[0] for lay in layers])
    E = np.array([lay[1] for lay in layers])
    G = np.array([lay[2] for lay in layers])
    th = tops - bots
    ea = float(np.sum(E * th * t))
    y_na = float(np.sum(E * th * t * (bots + tops) / 2) / ea)
    ei = float(np.sum(E * t * (th**3 / 12 + th * ((bots + tops) / 2 - y_na) ** 2)))
    compliance = 0.0
    for k in range(len(layers)):
        y = np.linspace(bots[k], tops[k], n_int)
        q = np.zeros_like(y)  # Q*(y) = int_y^top E (s - y_na) t ds
        for m in range(len(layers)):
            lo = np.maximum(y, bots[m])
            hi = np.full_like(y, tops[m])
            part = np.where(hi > lo, E[m] * t * ((hi - y_na) ** 2 - (lo - y_na) ** 2) / 2, 0.0)
            q += part
        f = q**2 / (ei**2 * t * G[k])
        compliance += float(np.sum((f[1:] + f[:-1]) / 2 * np.diff(y)))
    return {"y_na": y_na, "EI": ei, "EA": ea, "GA_s": 1.0 / compliance}


def layered_cantilever_deflection(layers: Sequence[Tuple[float, float, float]], t: float,
                                  length: float, force: float) -> Dict[str, float]:
    """Tip deflection of a cantilever of bonded layers under an end load ``force``:
    bending ``P L^3 / (3 EI)`` and shear ``P L / GA_s`` of the transformed section
    (``layered_section``); returns them, their sum ``total`` and the section."""
    sec = layered_section(layers, t)
    bend = force * length**3 / (3 * sec["EI"])
    shear = force * length / sec["GA_s"]
    return {"bending": bend, "shear": shear, "total": bend + shear, **sec}
