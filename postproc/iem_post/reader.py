"""Read-only access to the HDF5 output file of an iem run (layout: docs/output.md)."""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any

import h5py
import numpy as np

__all__ = [
    "IemFile",
    "IemFileError",
    "InputError",
    "FrameIndexError",
    "IncompleteFileWarning",
    "Mesh",
    "FrameInfo",
    "Frame",
    "Probe",
]

_FRAME_NAME = re.compile(r"^frame_(\d+)$")


class IemFileError(Exception):
    """The file is missing, unreadable, or not a well-formed iem output file."""


class InputError(Exception):
    """An input other than the iem file (a reference table, an output format) is unusable."""


class FrameIndexError(IemFileError, IndexError):
    """A frame index lies outside the frames the file holds."""


class IncompleteFileWarning(UserWarning):
    """The file comes from a run that has not finished normally (``complete`` != 1)."""


@dataclass(frozen=True)
class Mesh:
    """The lattice: node coordinates, cell connectivity, masses and grid attributes."""

    coordinates: np.ndarray
    cells: np.ndarray
    mass: np.ndarray | None
    nx: int | None
    ny: int | None
    lx: float | None
    ly: float | None
    thickness: float | None
    plane: str | None

    @property
    def n_nodes(self) -> int:
        """Number of nodes."""
        return int(self.coordinates.shape[0])

    @property
    def n_cells(self) -> int:
        """Number of cells."""
        return int(self.cells.shape[0])

    @property
    def extent(self) -> tuple[float, float]:
        """Width and height of the undeformed body's bounding box."""
        if self.n_nodes == 0:
            return 0.0, 0.0
        span = self.coordinates.max(axis=0) - self.coordinates.min(axis=0)
        return float(span[0]), float(span[1])


@dataclass(frozen=True)
class FrameInfo:
    """Position, group name, time and step of one output frame."""

    index: int
    name: str
    time: float
    step: int


@dataclass(frozen=True)
class Frame:
    """One output frame: its info plus nodal displacement and velocity (n_nodes, 2)."""

    info: FrameInfo
    displacement: np.ndarray
    velocity: np.ndarray

    @property
    def index(self) -> int:
        """Non-negative position of the frame in the file."""
        return self.info.index

    @property
    def time(self) -> float:
        """Time of the frame (s)."""
        return self.info.time

    @property
    def step(self) -> int:
        """Step number of the frame."""
        return self.info.step


@dataclass(frozen=True)
class Probe:
    """Time history of one probe node plus the point it was requested at."""

    name: str
    displacement: np.ndarray
    velocity: np.ndarray
    x: float | None
    y: float | None
    node: int | None
    node_x: float | None
    node_y: float | None


def _decode(value: Any) -> Any:
    """Turn an HDF5 attribute value into a plain Python scalar or string."""
    if isinstance(value, np.ndarray) and value.size == 1:
        value = value.reshape(-1)[0]
    if isinstance(value, (bytes, np.bytes_)):
        value = bytes(value).decode("utf-8", errors="replace")
    if isinstance(value, str):
        # Fortran writes fixed-length strings padded with blanks or NULs.
        return value.rstrip("\x00 ").strip()
    if isinstance(value, np.generic):
        return value.item()
    return value


def _as_int(value: Any) -> int | None:
    """Convert a decoded attribute to int, or None when absent or not numeric."""
    try:
        return None if value is None else int(value)
    except (TypeError, ValueError):
        return None


def _as_float(value: Any) -> float | None:
    """Convert a decoded attribute to float, or None when absent or not numeric."""
    try:
        return None if value is None else float(value)
    except (TypeError, ValueError):
        return None


def _open_read_only(path: Path) -> h5py.File:
    """Open ``path`` read-only without file locking (the solver may still hold it open)."""
    try:
        try:
            return h5py.File(path, "r", locking=False)
        except (TypeError, ValueError):  # HDF5 library without the locking option
            return h5py.File(path, "r")
    except OSError as exc:
        raise IemFileError(f"cannot open {path}: {exc}") from exc


class IemFile:
    """Read-only view of one iem output file; use as a context manager or call close()."""

    def __init__(self, path: str | Path, *, warn_incomplete: bool = True) -> None:
        """Open ``path`` read-only, check it is iem output and warn if the run is incomplete."""
        self.path = Path(path)
        if not self.path.exists():
            raise IemFileError(f"no such file: {self.path}")
        if not self.path.is_file():
            raise IemFileError(f"not a regular file: {self.path}")
        if not h5py.is_hdf5(self.path):
            raise IemFileError(f"not an HDF5 file (so not an iem output file): {self.path}")
        self._h5 = _open_read_only(self.path)
        self._mesh: Mesh | None = None
        self._frames: list[FrameInfo] | None = None
        try:
            program = self.attr("program")
            if program != "iem":
                found = "no 'program' attribute" if program is None else f"program = {program!r}"
                raise IemFileError(f"not an iem output file ({found}): {self.path}")
            if warn_incomplete and not self.complete:
                warnings.warn(
                    f"{self.path} is incomplete (complete != 1): the run died or is still "
                    "running, so the data may be partial",
                    IncompleteFileWarning,
                    stacklevel=2,
                )
        except BaseException:
            self.close()
            raise

    # ------------------------------------------------------------------ lifecycle
    def close(self) -> None:
        """Close the underlying HDF5 file (idempotent)."""
        h5 = getattr(self, "_h5", None)
        if h5 is not None and h5.id.valid:
            h5.close()

    def __enter__(self) -> IemFile:
        """Return self for use in a ``with`` block."""
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        """Close the file at the end of a ``with`` block."""
        self.close()

    # ------------------------------------------------------------------ helpers
    def _dataset(self, name: str, ndim: int | None = None, width: int | None = None) -> np.ndarray:
        """Read dataset ``name`` fully, raising IemFileError if missing or misshapen."""
        obj = self._h5.get(name)
        if not isinstance(obj, h5py.Dataset):
            raise IemFileError(f"{self.path}: missing dataset {name}")
        data = np.asarray(obj[()])
        if ndim is not None and data.ndim != ndim:
            raise IemFileError(f"{self.path}: {name} has shape {data.shape}, expected {ndim}-D")
        if width is not None and data.shape[-1] != width:
            raise IemFileError(
                f"{self.path}: {name} has shape {data.shape}, expected {width} columns"
            )
        return data

    def _optional_1d(self, name: str) -> np.ndarray:
        """Read 1-D dataset ``name`` if present, else an empty array."""
        obj = self._h5.get(name)
        if isinstance(obj, h5py.Dataset) and obj.ndim == 1:
            return np.asarray(obj[()])
        return np.zeros(0)

    def has_dataset(self, name: str) -> bool:
        """True when ``name`` (a path inside the file) is a dataset."""
        return isinstance(self._h5.get(name.lstrip("/")), h5py.Dataset)

    def dataset(self, name: str, ndim: int | None = None, width: int | None = None) -> np.ndarray:
        """Read dataset ``name`` fully, raising IemFileError if missing or misshapen."""
        return self._dataset(name.lstrip("/"), ndim=ndim, width=width)

    def history_series(self, name: str, width: int | None = None) -> np.ndarray:
        """A 1-D (or, with ``width``, 2-D) history dataset cut to the number of samples."""
        return self._history_series(name.lstrip("/"), width=width)

    def group_members(self, name: str) -> list[str]:
        """Names of the members of group ``name`` (sorted), or [] if there is no such group."""
        group = self._h5.get(name.lstrip("/"))
        return sorted(group) if isinstance(group, h5py.Group) else []

    def attr(self, name: str, obj: str = "/") -> Any:
        """Decoded attribute ``name`` of object ``obj`` (default the root), or None."""
        target = self._h5.get(obj)
        if target is None or name not in target.attrs:
            return None
        return _decode(target.attrs[name])

    # ------------------------------------------------------------------ root attributes
    @property
    def attributes(self) -> dict[str, Any]:
        """All root attributes, decoded."""
        return {key: _decode(val) for key, val in self._h5.attrs.items()}

    @property
    def program(self) -> str | None:
        """Root ``program`` attribute (``iem``)."""
        return self.attr("program")

    @property
    def version(self) -> str | None:
        """Code version that wrote the file."""
        value = self.attr("version")
        return None if value is None else str(value)

    @property
    def n_ranks(self) -> int | None:
        """Number of MPI ranks of the run that wrote the file."""
        return _as_int(self.attr("n_ranks"))

    @property
    def complete(self) -> bool:
        """True when the run ended normally (``complete`` == 1)."""
        return _as_int(self.attr("complete")) == 1

    @property
    def continuations(self) -> list[dict[str, Any]]:
        """One dict per continuation from a checkpoint (``/continuations``), in order:
        checkpoint, time, step, n_ranks, date, samples, frames; empty if never continued."""
        group = self._h5.get("continuations")
        if group is None:
            return []
        return [{key: _decode(val) for key, val in group[name].attrs.items()}
                for name in sorted(group)]

    # ------------------------------------------------------------------ mesh
    @property
    def mesh(self) -> Mesh:
        """The lattice (read once, then cached on this object)."""
        if self._mesh is None:
            coords = self._dataset("mesh/coordinates", ndim=2, width=2).astype(float, copy=False)
            cells = self._dataset("mesh/cells", ndim=2, width=4).astype(np.int64, copy=False)
            if cells.size and (cells.min() < 0 or cells.max() >= coords.shape[0]):
                raise IemFileError(f"{self.path}: /mesh/cells refers to nodes that do not exist")
            mass = self._dataset("mesh/mass", ndim=1) if "mesh/mass" in self._h5 else None
            self._mesh = Mesh(
                coordinates=coords,
                cells=cells,
                mass=mass,
                nx=_as_int(self.attr("nx", "mesh")),
                ny=_as_int(self.attr("ny", "mesh")),
                lx=_as_float(self.attr("lx", "mesh")),
                ly=_as_float(self.attr("ly", "mesh")),
                thickness=_as_float(self.attr("thickness", "mesh")),
                plane=self.attr("plane", "mesh"),
            )
        return self._mesh

    # ------------------------------------------------------------------ frames
    @property
    def frames(self) -> list[FrameInfo]:
        """Frames in time order (groups with both datasets written)."""
        if self._frames is None:
            group = self._h5.get("frames")
            found: list[tuple[int, str]] = []
            if isinstance(group, h5py.Group):
                for name, obj in group.items():
                    match = _FRAME_NAME.match(name)
                    if (
                        match
                        and isinstance(obj, h5py.Group)
                        and "displacement" in obj
                        and "velocity" in obj
                    ):
                        found.append((int(match.group(1)), name))
            found.sort()
            table_time = self._optional_1d("frames/time")
            table_step = self._optional_1d("frames/step")
            infos = []
            for position, (number, name) in enumerate(found):
                path = f"frames/{name}"
                time = _as_float(self.attr("time", path))
                step = _as_int(self.attr("step", path))
                if time is None and number < table_time.size:
                    time = float(table_time[number])
                if step is None and number < table_step.size:
                    step = int(table_step[number])
                infos.append(
                    FrameInfo(
                        index=position,
                        name=name,
                        time=float("nan") if time is None else time,
                        step=-1 if step is None else step,
                    )
                )
            self._frames = infos
        return self._frames

    @property
    def n_frames(self) -> int:
        """Number of frames in the file."""
        return len(self.frames)

    def resolve_frame_index(self, index: int) -> int:
        """Map a possibly negative frame index to 0..n_frames-1, or raise FrameIndexError."""
        n = self.n_frames
        if n == 0:
            raise FrameIndexError(f"{self.path} holds no frames")
        if not -n <= index < n:
            raise FrameIndexError(
                f"frame {index} out of range: {self.path} holds {n} frame(s), "
                f"valid indices are 0..{n - 1} or -{n}..-1"
            )
        return index % n

    def frame(self, index: int = -1) -> Frame:
        """Frame ``index`` (negative counts from the end) with its displacement and velocity."""
        info = self.frames[self.resolve_frame_index(index)]
        n_nodes = self.mesh.n_nodes
        arrays = []
        for name in ("displacement", "velocity"):
            data = self._dataset(f"frames/{info.name}/{name}", ndim=2, width=2).astype(float)
            if data.shape[0] != n_nodes:
                raise IemFileError(
                    f"{self.path}: /frames/{info.name}/{name} has {data.shape[0]} rows "
                    f"but the mesh has {n_nodes} nodes"
                )
            arrays.append(data)
        return Frame(info=info, displacement=arrays[0], velocity=arrays[1])

    # ------------------------------------------------------------------ history
    def _n_samples(self) -> int:
        """Number of history samples (length of /history/time, 0 if absent)."""
        obj = self._h5.get("history/time")
        return int(obj.shape[0]) if isinstance(obj, h5py.Dataset) and obj.ndim == 1 else 0

    def _history_series(self, name: str, width: int | None = None) -> np.ndarray:
        """A history dataset cut to the number of samples in /history/time."""
        data = self._dataset(name, ndim=1 if width is None else 2, width=width)
        return data[: self._n_samples()].astype(float, copy=False)

    @property
    def n_samples(self) -> int:
        """Number of history samples."""
        return self._n_samples()

    @property
    def history_time(self) -> np.ndarray:
        """Times of the history samples (s); empty if the file has no history."""
        if self._n_samples() == 0:
            return np.zeros(0)
        return self._dataset("history/time", ndim=1).astype(float)

    @property
    def history_step(self) -> np.ndarray:
        """Step numbers of the history samples; empty if absent."""
        if self._n_samples() == 0 or "history/step" not in self._h5:
            return np.zeros(0, dtype=np.int64)
        return self._dataset("history/step", ndim=1)[: self._n_samples()].astype(np.int64)

    @property
    def energies(self) -> dict[str, np.ndarray]:
        """Energy series by name (kinetic, strain, external_work, damping, balance_error)."""
        group = self._h5.get("history/energy")
        if not isinstance(group, h5py.Group):
            return {}
        return {
            name: self._history_series(f"history/energy/{name}")
            for name, obj in group.items()
            if isinstance(obj, h5py.Dataset)
        }

    @property
    def probes(self) -> dict[str, Probe]:
        """Probe histories by name, in the file's (alphabetical) order."""
        group = self._h5.get("history/probes")
        if not isinstance(group, h5py.Group):
            return {}
        result = {}
        for name, obj in group.items():
            if not isinstance(obj, h5py.Group):
                continue
            base = f"history/probes/{name}"
            result[name] = Probe(
                name=name,
                displacement=self._history_series(f"{base}/displacement", width=2),
                velocity=self._history_series(f"{base}/velocity", width=2),
                x=_as_float(self.attr("x", base)),
                y=_as_float(self.attr("y", base)),
                node=_as_int(self.attr("node", base)),
                node_x=_as_float(self.attr("node_x", base)),
                node_y=_as_float(self.attr("node_y", base)),
            )
        return result
