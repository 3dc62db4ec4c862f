"""Tests of iem_post.plots: scale, cell fields, outline and the drawn figures' data."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import pytest
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure

from iem_post import plots
from iem_post.reader import IemFile

if TYPE_CHECKING:
    from conftest import Synthetic


def test_auto_scale_value(iem_file: Synthetic) -> None:
    """Auto scale makes the largest displacement 10% of the larger body dimension."""
    disp = iem_file.displacements[2]
    u_max = np.hypot(disp[:, 0], disp[:, 1]).max()
    expected = 0.1 * 2.0 / u_max  # body is 2.0 m x 0.5 m
    assert plots.auto_scale(iem_file.coordinates, disp) == pytest.approx(expected, rel=1e-12)
    moved = iem_file.coordinates + expected * disp
    shift = np.hypot(*(moved - iem_file.coordinates).T).max()
    assert shift == pytest.approx(0.2)


def test_auto_scale_zero_motion(iem_file: Synthetic) -> None:
    """With no displacement at all the auto scale is 1."""
    zero = np.zeros_like(iem_file.coordinates)
    assert plots.auto_scale(iem_file.coordinates, zero) == 1.0


def test_cell_field_is_corner_mean(iem_file: Synthetic) -> None:
    """Cell values are the mean of the four corner node values, for every field."""
    with IemFile(iem_file.path) as data:
        frame = data.frame(2)
        cells = data.mesh.cells
        u, v = iem_file.displacements[2], iem_file.velocities[2]
        expected = {
            "umag": np.hypot(u[:, 0], u[:, 1]),
            "ux": u[:, 0],
            "uy": u[:, 1],
            "vmag": np.hypot(v[:, 0], v[:, 1]),
            "vx": v[:, 0],
            "vy": v[:, 1],
        }
        for name, nodal in expected.items():
            values = plots.cell_field(frame, cells, name)
            assert values.shape == (8,)
            # cell 5 = (i=1, j=1): nodes 6, 7, 12, 11
            assert values[5] == pytest.approx(nodal[[6, 7, 12, 11]].mean())
            np.testing.assert_allclose(values, nodal[cells].mean(axis=1))
        with pytest.raises(ValueError, match="unknown field"):
            plots.cell_field(frame, cells, "pressure")


def test_boundary_edges(iem_file: Synthetic) -> None:
    """The outline of a 4 x 2 grid has 12 edges, all on the rectangle's border."""
    edges = plots.boundary_edges(iem_file.cells)
    assert edges.shape == (12, 2)
    xy = iem_file.coordinates[edges]  # (12, 2 ends, 2)
    on_border = (
        np.isclose(xy[..., 0], 0.0) | np.isclose(xy[..., 0], 2.0)
        | np.isclose(xy[..., 1], 0.0) | np.isclose(xy[..., 1], 0.5)
    )
    assert on_border.all()
    # no interior edge such as node 6 - node 7
    assert not any(set(e) == {6, 7} for e in edges.tolist())


def _collections(fig: Figure) -> tuple[PolyCollection, LineCollection]:
    """The PolyCollection and LineCollection of a frame figure's main axes."""
    ax = fig.axes[0]
    poly = [c for c in ax.collections if isinstance(c, PolyCollection)]
    lines = [c for c in ax.collections if isinstance(c, LineCollection)]
    assert len(poly) == 1 and len(lines) == 1
    return poly[0], lines[0]


def test_plot_frame_geometry_and_colours(iem_file: Synthetic) -> None:
    """Polygons sit at coordinates + scale * displacement and carry the cell field."""
    with IemFile(iem_file.path) as data:
        frame = data.frame(-1)
        fig = plots.plot_frame(data.mesh, frame, field="ux", scale=7.0)
    poly, outline = _collections(fig)
    deformed = iem_file.coordinates + 7.0 * iem_file.displacements[2]
    paths = poly.get_paths()
    assert len(paths) == 8
    np.testing.assert_allclose(paths[5].vertices[:4], deformed[[6, 7, 12, 11]])
    ux = iem_file.displacements[2][:, 0]
    np.testing.assert_allclose(poly.get_array(), ux[iem_file.cells].mean(axis=1))
    assert len(outline.get_segments()) == 12
    assert poly.get_linewidths()[0] > 0  # small mesh: cell edges drawn
    assert len(fig.axes) == 2  # plot + colour bar
    assert fig.axes[0].get_aspect() == 1.0


def test_plot_frame_dense_mesh_has_no_edges(
    iem_file: Synthetic,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Above DENSE_CELLS cells the polygons are drawn without edges."""
    monkeypatch.setattr(plots, "DENSE_CELLS", 4)
    with IemFile(iem_file.path) as data:
        fig = plots.plot_frame(data.mesh, data.frame(-1))
    poly, _ = _collections(fig)
    assert poly.get_linewidths()[0] == 0.0


def test_energy_log_scale(iem_file: Synthetic) -> None:
    """The balance error axis is logarithmic when the error has positive values."""
    with IemFile(iem_file.path) as data:
        fig = plots.plot_energy(data.history_time, data.energies)
    ax_energy, ax_error = fig.axes
    assert ax_error.get_yscale() == "log"
    labels = [line.get_label() for line in ax_energy.get_lines()]
    assert labels == ["kinetic", "strain", "external work", "damping dissipation"]
    np.testing.assert_allclose(ax_energy.get_lines()[0].get_ydata(), iem_file.energies["kinetic"])
    err = ax_error.get_lines()[0].get_ydata()
    assert np.isnan(err[0]) and err[3] == pytest.approx(5e-8)


def test_energy_linear_when_error_zero(iem_file: Synthetic) -> None:
    """An all-zero balance error stays on a linear axis."""
    with IemFile(iem_file.path) as data:
        energies = dict(data.energies, balance_error=np.zeros(5))
        fig = plots.plot_energy(data.history_time, energies)
    assert fig.axes[1].get_yscale() == "linear"


def test_probe_figure(iem_file: Synthetic) -> None:
    """Probe figure: one subplot per component, one line per probe with its values."""
    with IemFile(iem_file.path) as data:
        fig = plots.plot_probes(data.history_time, data.probes)
    assert len(fig.axes) == 2
    for component, ax in enumerate(fig.axes):
        (line,) = ax.get_lines()
        assert line.get_label().startswith("tip")
        np.testing.assert_allclose(line.get_ydata(), iem_file.probe_displacement[:, component])


def test_figures_without_history(make_iem_file: Callable[..., Synthetic]) -> None:
    """Empty history gives placeholder figures instead of errors."""
    truth = make_iem_file()
    with IemFile(truth.path) as data:
        fig_p = plots.plot_probes(np.zeros(0), {})
        fig_e = plots.plot_energy(np.zeros(0), {})
        assert data.n_samples == 5
    assert "no probes" in fig_p.axes[0].texts[0].get_text()
    assert "no energy" in fig_e.axes[0].texts[0].get_text()
