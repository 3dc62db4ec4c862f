"""Fracture output of an iem run: failed springs and damage per frame, reactions, fragments.

Layout (docs/output.md): ``/frames/frame_NNNNNN/damage`` (n_cells,), the group
``/frames/frame_NNNNNN/failed_springs`` (``cell``, ``spring``, ``kind``, ``time``, equal
lengths), ``/history/reactions/<bc>`` (n_samples, 2) and ``/history/fracture/fragments``
(n_samples,) with ``largest_fragments`` (n_samples, 5). Spring numbers: 0-3 the edges bottom,
right, top, left (edge q joins corners q and q+1 of the cell, corners SW, SE, NE, NW); 4-7 the
shear springs at corners SW, SE, NE, NW. Kinds: 1 tension, 2 crushing, 3 shear, 4 pre-cut.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .reader import FrameInfo, IemFile, IemFileError

__all__ = [
    "KIND_NAMES",
    "PRECUT",
    "FailedSprings",
    "FragmentHistory",
    "require",
    "read_failed_springs",
    "read_damage",
    "read_reaction",
    "read_fragment_history",
    "spring_segments",
    "intact_edges",
    "fragment_sizes",
]

#: Failure kinds as written in ``kind``.
KIND_NAMES: dict[int, str] = {1: "tension", 2: "crushing", 3: "shear", 4: "pre-cut"}

#: The kind of a pre-cut spring.
PRECUT = 4

#: Hint added to the error for a dataset only runs with fracture write.
_FRACTURE_HINT = "written only by runs with &material fracture = .true."


@dataclass(frozen=True)
class FailedSprings:
    """The springs failed by their own criterion (or pre-cut) at one frame, sorted by
    (cell, spring): global 0-based ``cell``, ``spring`` 0-7, ``kind`` 1-4, ``time`` (s)."""

    cell: np.ndarray
    spring: np.ndarray
    kind: np.ndarray
    time: np.ndarray

    def __len__(self) -> int:
        """Number of failed springs."""
        return int(self.cell.shape[0])

    def counts(self) -> dict[str, int]:
        """Number failed by each kind name (every kind listed, zeros included)."""
        return {name: int(np.count_nonzero(self.kind == k)) for k, name in KIND_NAMES.items()}


@dataclass(frozen=True)
class FragmentHistory:
    """Fragment counts at the history samples: ``time`` (s), ``count`` (n_samples,) and
    ``largest`` (n_samples, 5): node counts of the five largest fragments, 0-padded."""

    time: np.ndarray
    count: np.ndarray
    largest: np.ndarray


def require(data: IemFile, name: str, hint: str = "") -> None:
    """Raise IemFileError naming dataset ``name`` when ``data`` lacks it."""
    if not data.has_dataset(name):
        extra = f" ({hint})" if hint else ""
        raise IemFileError(f"{data.path}: no dataset /{name.lstrip('/')}{extra}")


def read_failed_springs(data: IemFile, index: int = -1) -> tuple[FrameInfo, FailedSprings]:
    """The failed springs of frame ``index`` (negative counts from the end), checked."""
    info = data.frames[data.resolve_frame_index(index)]
    base = f"frames/{info.name}/failed_springs"
    arrays = {}
    for name in ("cell", "spring", "kind", "time"):
        require(data, f"{base}/{name}", _FRACTURE_HINT)
        arrays[name] = data.dataset(f"{base}/{name}", ndim=1)
    lengths = {name: a.shape[0] for name, a in arrays.items()}
    if len(set(lengths.values())) != 1:
        raise IemFileError(f"{data.path}: /{base} datasets differ in length: {lengths}")
    cell = arrays["cell"].astype(np.int64)
    spring = arrays["spring"].astype(np.int32)
    kind = arrays["kind"].astype(np.int32)
    n_cells = data.mesh.n_cells
    if cell.size and (cell.min() < 0 or cell.max() >= n_cells):
        raise IemFileError(f"{data.path}: /{base}/cell refers to cells that do not exist "
                           f"(the mesh has {n_cells})")
    if spring.size and (spring.min() < 0 or spring.max() > 7):
        raise IemFileError(f"{data.path}: /{base}/spring holds values outside 0..7")
    if kind.size and (kind.min() < 1 or kind.max() > 4):
        raise IemFileError(f"{data.path}: /{base}/kind holds values outside 1..4")
    springs = FailedSprings(cell=cell, spring=spring, kind=kind,
                            time=arrays["time"].astype(float))
    return info, springs


def read_damage(data: IemFile, index: int = -1) -> tuple[FrameInfo, np.ndarray]:
    """The per-cell damage (0 intact .. 1 every spring failed) of frame ``index``."""
    info = data.frames[data.resolve_frame_index(index)]
    name = f"frames/{info.name}/damage"
    require(data, name, _FRACTURE_HINT)
    values = data.dataset(name, ndim=1).astype(float)
    if values.shape[0] != data.mesh.n_cells:
        raise IemFileError(f"{data.path}: /{name} has {values.shape[0]} values but the mesh "
                           f"has {data.mesh.n_cells} cells")
    return info, values


def read_reaction(data: IemFile, bc: str) -> np.ndarray:
    """The reaction (n_samples, 2) of boundary condition ``bc`` (/history/reactions/<bc>)."""
    name = f"history/reactions/{bc}"
    if not data.has_dataset(name):
        found = data.group_members("history/reactions")
        hint = (f"reactions in this file: {', '.join(found)}" if found
                else "this file has no /history/reactions")
        require(data, name, hint)
    return data.history_series(name, width=2)


def read_fragment_history(data: IemFile) -> FragmentHistory:
    """Number of fragments and the five largest fragment sizes at every history sample."""
    for name in ("history/fracture/fragments", "history/fracture/largest_fragments"):
        require(data, name, _FRACTURE_HINT)
    count = data.history_series("history/fracture/fragments")
    largest = data.dataset("history/fracture/largest_fragments", ndim=2)
    time = data.history_time
    n = min(time.shape[0], count.shape[0], largest.shape[0])
    return FragmentHistory(time=time[:n], count=count[:n].astype(np.int64),
                           largest=largest[:n].astype(np.int64))


def spring_segments(positions: np.ndarray, cells: np.ndarray, springs: FailedSprings,
                    mark: float = 0.3) -> np.ndarray:
    """Segments (n_failed, 2, 2) to draw the failed springs at node ``positions``: an edge
    spring's edge; a shear spring's mark from its corner ``mark`` of the way to the cell's
    centre (so the mark shows which cell's corner failed)."""
    corners = positions[cells[springs.cell]]  # (n, 4, 2)
    if corners.shape[0] == 0:
        return np.zeros((0, 2, 2))
    rows = np.arange(corners.shape[0])
    q = springs.spring.astype(np.int64)
    edge = q < 4
    start = corners[rows, q % 4]
    end = np.empty_like(start)
    end[edge] = corners[rows[edge], (q[edge] + 1) % 4]
    centre = corners.mean(axis=1)
    shear = ~edge
    end[shear] = start[shear] + mark * (centre[shear] - start[shear])
    return np.stack([start, end], axis=1)


def intact_edges(cells: np.ndarray, springs: FailedSprings) -> np.ndarray:
    """Node pairs (k, 2) of the edges at least one of their cells holds intact (its edge
    spring not among the failed): the connections that make up the fragments."""
    if cells.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    n_cells = cells.shape[0]
    pairs = np.stack([cells, np.roll(cells, -1, axis=1)], axis=-1).reshape(-1, 2)
    failed = np.zeros((n_cells, 4), dtype=bool)
    edge = springs.spring < 4
    failed[springs.cell[edge], springs.spring[edge]] = True
    failed = failed.reshape(-1)
    lo = pairs.min(axis=1).astype(np.int64)
    hi = pairs.max(axis=1).astype(np.int64)
    key = lo * (int(hi.max()) + 1) + hi
    unique, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    intact = np.zeros(unique.shape[0], dtype=bool)
    np.logical_or.at(intact, inverse.reshape(-1), ~failed)
    return np.column_stack([lo[first], hi[first]])[intact]


def _components(n_nodes: int, pairs: np.ndarray) -> np.ndarray:
    """Root label of every node's connected component over the node ``pairs``."""
    parent = np.arange(n_nodes, dtype=np.int64)
    if pairs.size == 0:
        return parent
    a, b = pairs[:, 0], pairs[:, 1]
    while True:
        ra, rb = parent[a], parent[b]
        differ = ra != rb
        if not differ.any():
            return parent
        # hook the larger root onto the smaller one (no cycles), then compress fully
        np.minimum.at(parent, np.maximum(ra, rb)[differ], np.minimum(ra, rb)[differ])
        while True:
            grand = parent[parent]
            if np.array_equal(grand, parent):
                break
            parent = grand


def fragment_sizes(n_nodes: int, cells: np.ndarray, springs: FailedSprings) -> np.ndarray:
    """Node counts of all fragments (connected components of the nodes over intact edges),
    largest first."""
    labels = _components(n_nodes, intact_edges(cells, springs))
    sizes = np.bincount(labels, minlength=n_nodes)
    return np.sort(sizes[sizes > 0])[::-1].astype(np.int64)
