"""An animation of a frame field on the (deformed) lattice: one picture per frame, written as
a GIF (matplotlib's PillowWriter) or, when ffmpeg is installed, an MP4."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib import animation

from .fracture import read_damage
from .fracture_plots import draw_cells, draw_outline, lattice_figure
from .plots import _magnitude
from .reader import IemFile, InputError

__all__ = ["ANIMATION_FIELDS", "writer_for", "cell_values", "write_animation"]

#: Animated fields and their colour-bar labels.
ANIMATION_FIELDS: dict[str, str] = {
    "displacement": "displacement magnitude |u| (m), cell mean",
    "velocity": "velocity magnitude |v| (m/s), cell mean",
    "damage": "damage (0 intact, 1 every spring failed)",
}


def writer_for(path: Path, fps: int) -> animation.AbstractMovieWriter:
    """The movie writer for ``path``'s suffix (.gif or .mp4); InputError if unusable."""
    suffix = path.suffix.lower()
    if suffix == ".gif":
        return animation.PillowWriter(fps=fps)
    if suffix == ".mp4":
        if not animation.writers.is_available("ffmpeg"):
            raise InputError(f"writing {path} needs ffmpeg, which is not installed "
                             "(not on PATH); write a .gif instead")
        return animation.FFMpegWriter(fps=fps)
    raise InputError(f"cannot write {path}: the output must end in .gif or .mp4")


def cell_values(data: IemFile, index: int, field: str) -> tuple[np.ndarray, np.ndarray]:
    """The displacement (n_nodes, 2) of frame ``index`` and ``field``'s value per cell
    (node fields: the mean of the corners' magnitudes)."""
    if field not in ANIMATION_FIELDS:
        raise ValueError(f"unknown field {field!r}; choose from {', '.join(ANIMATION_FIELDS)}")
    frame = data.frame(index)
    if field == "damage":
        return frame.displacement, read_damage(data, index)[1]
    nodal = frame.displacement if field == "displacement" else frame.velocity
    return frame.displacement, _magnitude(nodal)[data.mesh.cells].mean(axis=1)


def write_animation(
    data: IemFile,
    field: str,
    output: Path,
    fps: int = 5,
    scale: float | None = None,
    every: int = 1,
    dpi: int = 100,
) -> tuple[Path, int, float]:
    """Write every ``every``-th frame of ``field`` on the lattice at coordinates + scale *
    displacement (``scale`` None: the largest displacement of all frames drawn as 10% of the
    body's larger dimension) to ``output``; return the path, the pictures and the scale."""
    writer = writer_for(output, fps)
    if data.n_frames == 0:
        raise InputError(f"{data.path} holds no frames: nothing to animate")
    indices = list(range(0, data.n_frames, max(1, every)))
    mesh = data.mesh
    coords = mesh.coordinates

    # first pass: displacement extremes and the colour range over the frames drawn
    u_lo, u_hi = np.zeros(2), np.zeros(2)
    u_max, v_lo, v_hi = 0.0, np.inf, -np.inf
    for index in indices:
        disp, values = cell_values(data, index, field)
        if disp.size:
            u_lo, u_hi = np.minimum(u_lo, disp.min(axis=0)), np.maximum(u_hi, disp.max(axis=0))
            u_max = max(u_max, float(np.nanmax(_magnitude(disp))))
        finite = values[np.isfinite(values)]
        if finite.size:
            v_lo, v_hi = min(v_lo, float(finite.min())), max(v_hi, float(finite.max()))
    if scale is None:
        size = float(np.max(coords.max(axis=0) - coords.min(axis=0))) if coords.size else 0.0
        scale = 0.1 * size / u_max if u_max > 0.0 and size > 0.0 else 1.0
    if field == "damage":
        v_lo, v_hi = 0.0, 1.0
    elif not v_lo <= v_hi:
        v_lo, v_hi = 0.0, 1.0
    elif v_lo == v_hi:
        v_lo, v_hi = v_lo - 0.5 * (abs(v_lo) or 1.0), v_hi + 0.5 * (abs(v_hi) or 1.0)

    # a box holding every frame's deformed lattice (corners of the bounds, conservative)
    box = np.array([coords.min(axis=0) + scale * u_lo, coords.max(axis=0) + scale * u_hi])
    fig, ax = lattice_figure(np.concatenate([box, coords]))
    disp, values = cell_values(data, indices[0], field)
    cells = draw_cells(ax, mesh, coords + scale * disp, array=values, cmap="viridis")
    cells.set_clim(v_lo, v_hi)
    draw_outline(ax, mesh)
    fig.colorbar(cells, ax=ax, label=ANIMATION_FIELDS[field], shrink=0.9)
    title = ax.set_title(" ")

    def show(index: int) -> None:
        """Put frame ``index`` into the figure."""
        disp, values = cell_values(data, index, field)
        cells.set_verts((coords + scale * disp)[mesh.cells])
        cells.set_array(values)
        info = data.frames[index]
        title.set_text(f"{data.path.name}: {field}, frame {info.index} of {data.n_frames - 1}, "
                       f"t = {info.time:.6g} s, scale {scale:.4g}")

    show(indices[0])
    fig.canvas.draw()
    fig.set_layout_engine("none")  # freeze the layout so the pictures do not shift
    output.parent.mkdir(parents=True, exist_ok=True)
    with writer.saving(fig, str(output), dpi=dpi):
        for index in indices:
            show(index)
            writer.grab_frame()
    return output, len(indices), scale
