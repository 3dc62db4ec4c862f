"""Tests of iem_post.scenes: cell strains and stresses, the hole-edge measure, Heywood's
factor and the layered section."""
from __future__ import annotations

import numpy as np
import pytest

from iem_post.scenes import (cell_strains, cell_stresses, heywood_kt, hole_edge_stress,
                             layered_cantilever_deflection, layered_section)


def grid(nx: int, ny: int, h: float):
    """Node coordinates and cells (corners counter-clockwise from the lower left)."""
    x, y = np.meshgrid(np.arange(nx + 1) * h, np.arange(ny + 1) * h)
    xy = np.stack([x.ravel(), y.ravel()], axis=1)
    cells = []
    for j in range(ny):
        for i in range(nx):
            g = i + j * (nx + 1)
            cells.append([g, g + 1, g + nx + 2, g + nx + 1])
    return xy, np.array(cells)


def test_uniform_strain_gives_exact_stress():
    xy, cells = grid(3, 2, 0.1)
    ex, ey, gxy = 1e-3, -2e-4, 5e-4
    u = np.stack([ex * xy[:, 0] + gxy * xy[:, 1], ey * xy[:, 1]], axis=1)
    e = cell_strains(xy, cells, u)
    assert np.allclose(e, [ex, ey, gxy], rtol=0, atol=1e-15)
    s = cell_stresses(e, 200e9, 0.3)
    c = 200e9 / (1 - 0.09)
    assert np.allclose(s[:, 0], c * (ex + 0.3 * ey))
    assert np.allclose(s[:, 1], c * (ey + 0.3 * ex))
    assert np.allclose(s[:, 2], 200e9 / 2.6 * gxy)
    sp = cell_stresses(e, 200e9, 0.3, plane="strain")
    assert np.allclose(sp[:, 0], 200e9 / (1.3 * 0.4) * (0.7 * ex + 0.3 * ey))
    with pytest.raises(ValueError):
        cell_stresses(e, 200e9, 0.3, plane="axisymmetric")


def test_hole_edge_stress_extrapolates_a_quadratic_exactly():
    h = 0.1
    xy, cells = grid(2, 6, h)
    keep = np.arange(len(cells)) >= 4  # the two bottom rows are the "hole"
    sig = lambda y: 1.0 + 2.0 * y - 3.0 * y**2  # noqa: E731 -- sigma_xx along the column
    # u_x = x sig(y) / E, u_y = 0: eps_x = sig(y) / E on each horizontal edge; nu = 0
    E, nu = 1.0, 0.0
    u = np.stack([xy[:, 0] * sig(xy[:, 1]) / E, np.zeros(len(xy))], axis=1)
    m = hole_edge_stress(xy, cells[keep], u, E, nu)
    assert m["y_edge"] == pytest.approx(0.2)
    # the cell value is the mean of the bottom and top edges' strains
    ys = 0.2 + h * np.array([0.5, 1.5, 2.5])
    vals = (sig(ys - h / 2) + sig(ys + h / 2)) / 2
    assert m["first_cell"] == pytest.approx(vals[0])
    assert m["extrapolated"] == pytest.approx(np.polyval(np.polyfit(ys, vals, 2), 0.2))


def test_heywood_tends_to_kirsch():
    assert heywood_kt(0.0) == (3.0, 3.0)
    ktn, ktg = heywood_kt(0.1)
    assert ktn == pytest.approx(2.729) and ktg == pytest.approx(2.729 / 0.9)


def test_layered_section_one_layer_is_the_rectangle():
    E, G, h, t = 25e9, 25e9 / 2.4, 0.1, 0.1
    s = layered_section([(h, E, G)], t)
    assert s["y_na"] == pytest.approx(h / 2)
    assert s["EI"] == pytest.approx(E * t * h**3 / 12)
    assert s["GA_s"] == pytest.approx(5 / 6 * G * h * t, rel=1e-5)
    # two layers of one material are the same section
    s2 = layered_section([(0.03, E, G), (0.07, E, G)], t)
    assert s2["EI"] == pytest.approx(s["EI"]) and s2["GA_s"] == pytest.approx(s["GA_s"], rel=1e-5)


def test_layered_cantilever_transformed_section():
    g = lambda e: e / 2.4  # noqa: E731
    d = layered_cantilever_deflection([(0.025, 100e9, g(100e9)), (0.075, 25e9, g(25e9))],
                                      0.1, 1.0, 1000.0)
    # transformed section by hand: n = 4, bottom layer 4 x 0.1 wide
    a1, y1, a2, y2 = 0.4 * 0.025, 0.0125, 0.1 * 0.075, 0.0625
    yna = (a1 * y1 + a2 * y2) / (a1 + a2)
    i_tr = (0.4 * 0.025**3 / 12 + a1 * (y1 - yna) ** 2 + 0.1 * 0.075**3 / 12
            + a2 * (y2 - yna) ** 2)
    assert d["y_na"] == pytest.approx(yna)
    assert d["EI"] == pytest.approx(25e9 * i_tr)
    assert d["bending"] == pytest.approx(1000.0 / (3 * 25e9 * i_tr))
    assert 0 < d["shear"] < 0.02 * d["bending"]
