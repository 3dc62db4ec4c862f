"""Figures of fracture runs: the crack map of a frame and the fragment history.

Like :mod:`iem_post.plots`, every function builds a Figure on its own Agg canvas.
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from .fracture import PRECUT, FailedSprings, FragmentHistory, spring_segments
from .plots import DENSE_CELLS, _new_figure, _no_data, boundary_edges
from .reader import Mesh

__all__ = ["lattice_figure", "draw_cells", "plot_crack_map", "plot_fragments"]

#: Colour map of the failure times.
TIME_CMAP = "plasma"


def lattice_figure(points: np.ndarray, width: float = 10.0) -> tuple[Figure, Axes]:
    """A figure whose single axes frames ``points`` (k, 2) with a small margin, equal aspect."""
    points = points[np.isfinite(points).all(axis=1)]
    if points.size == 0:
        points = np.zeros((1, 2))
    lo, hi = points.min(axis=0), points.max(axis=0)
    span = hi - lo
    pad = 0.04 * max(float(span.max()), 1e-30)
    w, h = float(span[0]) + 2 * pad, float(span[1]) + 2 * pad
    fig = _new_figure(width, float(np.clip(0.85 * width * h / w + 1.6, 3.0, 10.0)))
    ax = fig.add_subplot()
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    return fig, ax


def draw_cells(ax: Axes, mesh: Mesh, positions: np.ndarray, **style: object) -> PolyCollection:
    """Add the cells at node ``positions`` as a PolyCollection (thin edges unless dense)."""
    dense = mesh.n_cells > DENSE_CELLS
    options: dict[str, object] = {
        "linewidths": 0.0 if dense else (0.3 if mesh.n_cells <= 2_000 else 0.1),
        "edgecolors": "face" if dense else (0.15, 0.15, 0.15, 0.35),
        "antialiaseds": not dense,
        "zorder": 1,
    }
    options.update(style)
    cells = PolyCollection(positions[mesh.cells], **options)
    ax.add_collection(cells, autolim=False)
    return cells


def draw_outline(ax: Axes, mesh: Mesh) -> None:
    """Add the undeformed outline of the body, dashed in grey."""
    outline = LineCollection(mesh.coordinates[boundary_edges(mesh.cells)], colors="0.55",
                             linewidths=0.8, linestyles="--", alpha=0.7, zorder=2)
    ax.add_collection(outline, autolim=False)


def _crack_width(n_cells: int) -> float:
    """Line width of a failed spring, thinner on finer meshes."""
    return 2.0 if n_cells <= 2_000 else (1.0 if n_cells <= DENSE_CELLS else 0.5)


def plot_crack_map(
    mesh: Mesh,
    displacement: np.ndarray,
    springs: FailedSprings,
    scale: float = 0.0,
    title: str = "",
) -> Figure:
    """The lattice at ``coordinates + scale * displacement`` with the failed springs drawn as
    segments (edge springs: the edge; shear springs: a mark at the corner) coloured by their
    time of failure, pre-cut ones in grey."""
    positions = mesh.coordinates + scale * displacement
    fig, ax = lattice_figure(np.concatenate([positions, mesh.coordinates]))
    draw_cells(ax, mesh, positions, facecolors="0.93")
    if scale > 0.0:
        draw_outline(ax, mesh)

    segments = spring_segments(positions, mesh.cells, springs)
    width = _crack_width(mesh.n_cells)
    widths = np.where(springs.spring < 4, width, 0.75 * width)
    precut = springs.kind == PRECUT
    if precut.any():
        ax.add_collection(LineCollection(segments[precut], colors="0.45",
                                         linewidths=widths[precut], zorder=3), autolim=False)
    timed = ~precut
    cracks = LineCollection(segments[timed], array=springs.time[timed], cmap=TIME_CMAP,
                            linewidths=widths[timed], zorder=4, capstyle="round")
    ax.add_collection(cracks, autolim=False)
    times = springs.time[timed]
    times = times[np.isfinite(times)]
    lo, hi = (float(times.min()), float(times.max())) if times.size else (0.0, 1.0)
    if lo == hi:
        lo, hi = lo - 0.5 * (abs(lo) or 1.0), hi + 0.5 * (abs(hi) or 1.0)
    cracks.set_clim(lo, hi)
    fig.colorbar(cracks, ax=ax, label="time of failure (s)", shrink=0.9)
    if precut.any():
        ax.legend(handles=[Line2D([], [], color="0.45", lw=width, label="pre-cut")],
                  loc="upper right", fontsize="small")
    counts = springs.counts()
    summary = ", ".join(f"{n} {name}" for name, n in counts.items())
    ax.set_title(f"{title}\nfailed springs: {summary}" if title else
                 f"failed springs: {summary}")
    return fig


def plot_fragments(
    history: FragmentHistory,
    final_sizes: np.ndarray | None = None,
    final_label: str = "",
    title: str = "",
) -> Figure:
    """Number of fragments and the five largest fragment sizes against time, and the sizes
    at the end: a rank plot and a histogram of ``final_sizes`` (all fragments) when given,
    else of the five largest of the last sample."""
    fig = _new_figure(11.0, 8.0)
    if title:
        fig.suptitle(title)
    if history.time.size == 0:
        return _no_data(fig, "no history samples")
    (ax_count, ax_largest), (ax_rank, ax_hist) = fig.subplots(2, 2)

    ax_count.plot(history.time, history.count, "o-", ms=3, drawstyle="steps-post",
                  color="tab:blue")
    ax_count.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax_count.set_xlabel("time (s)")
    ax_count.set_ylabel("number of fragments")
    ax_count.grid(True, alpha=0.3)

    largest = history.largest.astype(float)
    largest[largest <= 0] = np.nan
    for k in range(largest.shape[1]):
        ax_largest.plot(history.time, largest[:, k], "o-", ms=3, drawstyle="steps-post",
                        label=f"#{k + 1}")
    finite = largest[np.isfinite(largest)]
    if finite.size and finite.max() > 10.0 * finite.min():
        ax_largest.set_yscale("log")
    else:
        ax_largest.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax_largest.set_xlabel("time (s)")
    ax_largest.set_ylabel("fragment size (nodes)")
    ax_largest.set_title("largest fragments", fontsize="medium")
    ax_largest.grid(True, which="both", alpha=0.3)
    ax_largest.legend(fontsize="small", loc="best")
    for ax in (ax_count, ax_largest):
        ax.xaxis.set_major_locator(MaxNLocator(6))
        ax.ticklabel_format(axis="x", style="sci", scilimits=(-3, 4))

    if final_sizes is None:
        sizes = history.largest[-1]
        sizes = sizes[sizes > 0]
        label = f"five largest at t = {history.time[-1]:.6g} s"
    else:
        sizes = np.asarray(final_sizes)
        label = final_label or "all fragments at the end"
    sizes = np.sort(sizes)[::-1]
    if sizes.size:
        ax_rank.plot(np.arange(1, sizes.size + 1), sizes, "o-", ms=3, color="tab:purple")
        top = int(sizes.max())
        if top > 10 * int(sizes.min()) or sizes.size > 20:
            ax_rank.set_xscale("log")
            ax_rank.set_yscale("log")
        else:
            ax_rank.xaxis.set_major_locator(MaxNLocator(integer=True))
            ax_rank.yaxis.set_major_locator(MaxNLocator(integer=True))
        if top <= 40:  # one bar per size
            edges = np.arange(0.5, top + 1.5)
        else:  # logarithmic bins
            edges = np.unique(np.floor(np.logspace(0.0, np.log10(top + 1.0), 30)))
            ax_hist.set_xscale("log")
        ax_hist.hist(sizes, bins=edges, color="tab:green", edgecolor="k", linewidth=0.5)
        ax_hist.yaxis.set_major_locator(MaxNLocator(integer=True))
        if top <= 40:
            ax_hist.xaxis.set_major_locator(MaxNLocator(integer=True))
    else:
        for ax in (ax_rank, ax_hist):
            ax.text(0.5, 0.5, "no fragments", ha="center", va="center", transform=ax.transAxes)
    ax_rank.set_xlabel("rank")
    ax_rank.set_ylabel("fragment size (nodes)")
    ax_rank.set_title(f"sizes by rank: {label}", fontsize="medium")
    ax_rank.grid(True, which="both", alpha=0.3)
    ax_hist.set_xlabel("fragment size (nodes)")
    ax_hist.set_ylabel("number of fragments")
    ax_hist.set_title(f"histogram: {label}", fontsize="medium")
    ax_hist.grid(True, alpha=0.3)
    return fig
