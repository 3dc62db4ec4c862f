"""Figures for iem output: probe histories, energy balance and deformed lattice frames.

Every function builds a :class:`matplotlib.figure.Figure` attached to an Agg canvas, so
nothing depends on a display or on pyplot's global state.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure

from .reader import Frame, Mesh, Probe

__all__ = [
    "FIELDS",
    "DENSE_CELLS",
    "auto_scale",
    "node_field",
    "cell_field",
    "boundary_edges",
    "plot_probes",
    "plot_energy",
    "plot_frame",
    "save_figure",
]

#: Above this many cells the cell edges are not drawn (linewidth 0).
DENSE_CELLS = 20_000

#: Energy series drawn in the energy figure, with their legend labels.
ENERGY_LABELS: dict[str, str] = {
    "kinetic": "kinetic",
    "strain": "strain",
    "external_work": "external work",
    "damping": "damping dissipation",
}


def _magnitude(values: np.ndarray) -> np.ndarray:
    """Euclidean norm of each row of an (n, 2) array."""
    return np.hypot(values[:, 0], values[:, 1])


#: Colour fields: name -> (colour-bar label, node values from a frame).
FIELDS: dict[str, tuple[str, Callable[[Frame], np.ndarray]]] = {
    "umag": ("displacement magnitude |u| (m)", lambda f: _magnitude(f.displacement)),
    "ux": ("displacement u_x (m)", lambda f: f.displacement[:, 0]),
    "uy": ("displacement u_y (m)", lambda f: f.displacement[:, 1]),
    "vmag": ("velocity magnitude |v| (m/s)", lambda f: _magnitude(f.velocity)),
    "vx": ("velocity v_x (m/s)", lambda f: f.velocity[:, 0]),
    "vy": ("velocity v_y (m/s)", lambda f: f.velocity[:, 1]),
}


def _new_figure(width: float, height: float) -> Figure:
    """A Figure of the given size (inches) on its own Agg canvas, with constrained layout."""
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Figure, path: str | Path, dpi: int = 150) -> Path:
    """Write ``fig`` as an image to ``path`` (parents created) and return the path."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    return out


def auto_scale(coordinates: np.ndarray, displacement: np.ndarray, fraction: float = 0.1) -> float:
    """Scale making the largest displacement ``fraction`` of the body's larger dimension."""
    if displacement.size == 0 or coordinates.size == 0:
        return 1.0
    magnitude = _magnitude(displacement)
    finite = magnitude[np.isfinite(magnitude)]
    u_max = float(finite.max()) if finite.size else 0.0
    span = coordinates.max(axis=0) - coordinates.min(axis=0)
    length = float(np.max(span))
    if u_max <= 0.0 or not np.isfinite(length) or length <= 0.0:
        return 1.0
    return fraction * length / u_max


def node_field(frame: Frame, field: str) -> np.ndarray:
    """Nodal values of colour field ``field`` (one of FIELDS) for ``frame``."""
    if field not in FIELDS:
        raise ValueError(f"unknown field {field!r}; choose from {', '.join(FIELDS)}")
    return FIELDS[field][1](frame)


def cell_field(frame: Frame, cells: np.ndarray, field: str) -> np.ndarray:
    """Per-cell mean of the four corner values of colour field ``field``."""
    return node_field(frame, field)[cells].mean(axis=1)


def boundary_edges(cells: np.ndarray) -> np.ndarray:
    """Node pairs (k, 2) of the edges that belong to exactly one cell: the body's outline."""
    if cells.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    edges = np.stack([cells, np.roll(cells, -1, axis=1)], axis=-1).reshape(-1, 2)
    lo = edges.min(axis=1).astype(np.int64)
    hi = edges.max(axis=1).astype(np.int64)
    key = lo * (int(hi.max()) + 1) + hi
    _, first, counts = np.unique(key, return_index=True, return_counts=True)
    return edges[first[counts == 1]]


def _common_length(time: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cut a time series and its values to their common length (guards partial files)."""
    n = min(time.shape[0], values.shape[0])
    return time[:n], values[:n]


def _no_data(fig: Figure, message: str) -> Figure:
    """Write ``message`` in the middle of an otherwise empty figure."""
    ax = fig.add_subplot()
    ax.text(0.5, 0.5, message, ha="center", va="center", transform=ax.transAxes)
    ax.set_axis_off()
    return fig


def plot_probes(time: np.ndarray, probes: Mapping[str, Probe], title: str = "") -> Figure:
    """Probe displacement u_x and u_y against time, one subplot per component."""
    fig = _new_figure(9.0, 6.5)
    if title:
        fig.suptitle(title)
    if not probes or time.size == 0:
        return _no_data(fig, "no probes in this file" if not probes else "no history samples")
    axes = fig.subplots(2, 1, sharex=True)
    for component, (ax, label) in enumerate(zip(axes, ("u_x", "u_y"))):
        for name, probe in probes.items():
            t, u = _common_length(time, probe.displacement)
            where = "" if probe.node is None else f" (node {probe.node})"
            ax.plot(t, u[:, component], label=f"{name}{where}")
        ax.set_ylabel(f"displacement {label} (m)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small", loc="best")
    axes[-1].set_xlabel("time (s)")
    return fig


def plot_energy(time: np.ndarray, energies: Mapping[str, np.ndarray], title: str = "") -> Figure:
    """Energies against time (top) and the relative balance error (bottom, log if positive)."""
    fig = _new_figure(9.0, 7.0)
    if title:
        fig.suptitle(title)
    if time.size == 0 or not energies:
        return _no_data(fig, "no energy history in this file")
    ax_energy, ax_error = fig.subplots(2, 1, sharex=True, height_ratios=(2, 1))
    for key, label in ENERGY_LABELS.items():
        if key in energies:
            t, e = _common_length(time, energies[key])
            ax_energy.plot(t, e, label=label)
    ax_energy.set_ylabel("energy (J)")
    ax_energy.grid(True, alpha=0.3)
    ax_energy.legend(fontsize="small", loc="best")

    if "balance_error" in energies:
        t, err = _common_length(time, energies["balance_error"])
        positive = np.isfinite(err) & (err > 0.0)
        if positive.any():
            ax_error.semilogy(t, np.where(positive, err, np.nan), color="tab:red")
            ax_error.set_ylabel("relative balance error\n(log scale)")
        else:
            ax_error.plot(t, err, color="tab:red")
            ax_error.set_ylabel("relative balance error")
        ax_error.grid(True, which="both", alpha=0.3)
    else:
        ax_error.text(0.5, 0.5, "no balance_error series", ha="center", va="center",
                      transform=ax_error.transAxes)
    ax_error.set_xlabel("time (s)")
    return fig


def plot_frame(
    mesh: Mesh,
    frame: Frame,
    field: str = "umag",
    scale: float = 1.0,
    title: str = "",
) -> Figure:
    """Deformed lattice (coordinates + scale * displacement) coloured by the cell field."""
    values = cell_field(frame, mesh.cells, field)
    deformed = mesh.coordinates + scale * frame.displacement
    verts = deformed[mesh.cells]  # (n_cells, 4, 2)

    points = np.concatenate([deformed, mesh.coordinates])
    points = points[np.isfinite(points).all(axis=1)]
    if points.size == 0:
        points = np.zeros((1, 2))
    lo, hi = points.min(axis=0), points.max(axis=0)
    span = hi - lo
    pad = 0.04 * max(float(span.max()), 1e-30)
    width, height = float(span[0]) + 2 * pad, float(span[1]) + 2 * pad
    fig = _new_figure(10.0, float(np.clip(8.5 * height / width + 1.2, 3.0, 10.0)))
    ax = fig.add_subplot()

    dense = mesh.n_cells > DENSE_CELLS
    edge_width = 0.0 if dense else (0.3 if mesh.n_cells <= 2_000 else 0.1)
    cells = PolyCollection(
        verts,
        array=values,
        cmap="viridis",
        linewidths=edge_width,
        edgecolors="face" if dense else (0.15, 0.15, 0.15, 0.6),
        antialiaseds=not dense,
        zorder=1,
    )
    ax.add_collection(cells, autolim=False)
    finite = values[np.isfinite(values)]
    if finite.size:
        vmin, vmax = float(finite.min()), float(finite.max())
        if vmin == vmax:
            vmin, vmax = vmin - 0.5 * (abs(vmin) or 1.0), vmax + 0.5 * (abs(vmax) or 1.0)
        cells.set_clim(vmin, vmax)

    edges = boundary_edges(mesh.cells)
    outline = LineCollection(
        mesh.coordinates[edges],
        colors="0.55",
        linewidths=0.8,
        linestyles="--",
        alpha=0.7,
        zorder=2,
        label="undeformed outline",
    )
    ax.add_collection(outline, autolim=False)

    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    fig.colorbar(cells, ax=ax, label=FIELDS[field][0], shrink=0.9)
    ax.set_title(title or f"t = {frame.time:.6g} s, displacement scale {scale:.4g}")
    return fig
