"""Shared fixtures: small synthetic iem output files written exactly per docs/output.md."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np
import pytest

NX, NY = 4, 2
LX, LY = 0.5, 0.25
N_FRAMES = 3
SAMPLE_TIMES = np.linspace(0.0, 2.0e-3, 5)
BALANCE_ERROR = np.array([0.0, 1.0e-8, 2.0e-8, 5.0e-8, 3.0e-8])


@dataclass
class Synthetic:
    """Expected contents of a synthetic file, for checking what the reader returns."""

    path: Path
    coordinates: np.ndarray
    cells: np.ndarray
    displacements: list[np.ndarray] = field(default_factory=list)
    velocities: list[np.ndarray] = field(default_factory=list)
    frame_times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    frame_steps: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    energies: dict[str, np.ndarray] = field(default_factory=dict)
    probe_displacement: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    probe_node: int = 0


def grid(nx: int, ny: int, lx: float, ly: float) -> tuple[np.ndarray, np.ndarray]:
    """Node coordinates and counter-clockwise cells of an nx x ny grid, global numbering."""
    j, i = np.meshgrid(np.arange(ny + 1), np.arange(nx + 1), indexing="ij")
    coords = np.column_stack([i.ravel() * lx, j.ravel() * ly]).astype(np.float64)
    cj, ci = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    n0 = (ci + cj * (nx + 1)).ravel()
    cells = np.column_stack([n0, n0 + 1, n0 + nx + 2, n0 + nx + 1]).astype(np.int64)
    return coords, cells


def _string_attr(obj: h5py.HLObject, name: str, value: str, fixed: bool) -> None:
    """Store a string attribute as variable-length UTF-8, or Fortran-style blank-padded bytes."""
    if fixed:
        obj.attrs.create(name, np.bytes_(value.ljust(32)), dtype=h5py.string_dtype("ascii", 32))
    else:
        obj.attrs[name] = value


def write_iem_file(
    path: Path,
    *,
    complete: int | None = 1,
    program: str = "iem",
    fixed_strings: bool = False,
    n_frames: int = N_FRAMES,
    zero_motion: bool = False,
) -> Synthetic:
    """Write a 4 x 2-cell iem output file with frames, one probe and energies; return truth."""
    coords, cells = grid(NX, NY, LX, LY)
    x, y = coords[:, 0], coords[:, 1]
    truth = Synthetic(path=path, coordinates=coords, cells=cells)
    truth.frame_times = np.arange(n_frames) * 1.0e-3
    truth.frame_steps = np.arange(n_frames, dtype=np.int64) * 100
    for k in range(n_frames):
        amp = 0.0 if zero_motion else float(k)
        disp = np.column_stack([1.0e-3 * amp * x, -2.0e-4 * amp * x * (1.0 + y)])
        vel = np.column_stack([0.1 * amp * y, 0.05 * amp * x])
        truth.displacements.append(disp)
        truth.velocities.append(vel)

    t = SAMPLE_TIMES
    truth.energies = {
        "kinetic": 10.0 * t,
        "strain": 20.0 * t + 1.0e-6,
        "external_work": 30.0 * t,
        "damping": 0.5 * t,
        "balance_error": BALANCE_ERROR.copy(),
    }
    truth.probe_node = NX + NY * (NX + 1)  # upper-right corner
    truth.probe_displacement = np.column_stack([1.0 * t, -2.0 * t])

    with h5py.File(path, "w") as h5:
        _string_attr(h5, "program", program, fixed_strings)
        _string_attr(h5, "file_type", "iem_output", fixed_strings)
        _string_attr(h5, "version", "1.2.3", fixed_strings)
        h5.attrs["n_ranks"] = np.int32(4)
        _string_attr(h5, "input_file", "inputs/test.nml", fixed_strings)
        _string_attr(h5, "input_text", "&run\n/\n", fixed_strings)
        _string_attr(h5, "analysis", "dynamic", fixed_strings)
        _string_attr(h5, "units", "SI: m, kg, s, N, Pa, J", fixed_strings)
        if complete is not None:
            h5.attrs["complete"] = np.int32(complete)

        mesh = h5.create_group("mesh")
        mesh["coordinates"] = coords
        mesh["cells"] = cells
        mesh["mass"] = np.full(coords.shape[0], 0.25)
        mesh.attrs["nx"] = np.int32(NX)
        mesh.attrs["ny"] = np.int32(NY)
        mesh.attrs["lx"] = LX
        mesh.attrs["ly"] = LY
        mesh.attrs["thickness"] = 0.01
        _string_attr(mesh, "plane", "stress", fixed_strings)

        frames = h5.create_group("frames")
        frames["time"] = truth.frame_times
        frames["step"] = truth.frame_steps
        for k in range(n_frames):
            g = frames.create_group(f"frame_{k:06d}")
            g["displacement"] = truth.displacements[k]
            g["velocity"] = truth.velocities[k]
            g.attrs["time"] = np.float64(truth.frame_times[k])
            g.attrs["step"] = np.int64(truth.frame_steps[k])

        hist = h5.create_group("history")
        hist["time"] = t
        hist["step"] = np.arange(t.size, dtype=np.int64) * 50
        energy = hist.create_group("energy")
        for name, series in truth.energies.items():
            energy[name] = series
        probe = hist.create_group("probes/tip")
        probe["displacement"] = truth.probe_displacement
        probe["velocity"] = np.ones((t.size, 2))
        probe.attrs["x"] = 1.99
        probe.attrs["y"] = 0.49
        probe.attrs["node"] = np.int64(truth.probe_node)
        probe.attrs["node_x"] = coords[truth.probe_node, 0]
        probe.attrs["node_y"] = coords[truth.probe_node, 1]
    return truth


@pytest.fixture
def iem_file(tmp_path: Path) -> Synthetic:
    """A complete synthetic iem output file in a fresh temporary folder."""
    return write_iem_file(tmp_path / "run.h5")


@pytest.fixture
def make_iem_file(tmp_path: Path) -> Callable[..., Synthetic]:
    """Factory writing a synthetic file named ``name`` in tmp_path with write_iem_file options."""

    def make(name: str = "run.h5", **options: object) -> Synthetic:
        """Write tmp_path/name and return its expected contents."""
        return write_iem_file(tmp_path / name, **options)  # type: ignore[arg-type]

    return make


# ---------------------------------------------------------------------------- fracture runs
#: Failed springs of the synthetic fracture run: (cell, spring, kind, time). Column 1's
#: horizontal edges (cells 1 and 5, bottom and top) fail by 0.7 ms, cutting the body into the
#: nodes with i <= 1 (6) and i >= 2 (9); by 1.9 ms the upper-right node (14) loses both its
#: edges (cell 7, right and top): 8 + 6 + 1. The pre-cut edge (cell 0, right), the shear
#: spring (cell 2, SE corner) and the crushed edge (cell 6, left) each leave the other cell of
#: their edge intact, so they cut nothing.
FAILURES = [
    (0, 1, 4, 0.0),
    (1, 0, 1, 0.5e-3),
    (1, 2, 1, 0.6e-3),
    (5, 0, 1, 0.6e-3),
    (5, 2, 1, 0.7e-3),
    (2, 5, 3, 1.2e-3),
    (6, 3, 2, 1.5e-3),
    (7, 1, 1, 1.8e-3),
    (7, 2, 1, 1.9e-3),
]
#: Fragment counts and the five largest at SAMPLE_TIMES (0, 0.5, 1, 1.5, 2 ms), by hand.
FRAGMENTS = np.array([1, 1, 2, 2, 3], dtype=np.int64)
LARGEST = np.array(
    [[15, 0, 0, 0, 0], [15, 0, 0, 0, 0], [9, 6, 0, 0, 0], [9, 6, 0, 0, 0], [8, 6, 1, 0, 0]],
    dtype=np.int64,
)
#: Reactions of the bc 'load' (y) and probe histories at SAMPLE_TIMES.
LOAD_Y = np.array([0.0, -600.0, -1000.0, -700.0, -300.0])
LOAD_POINT_UY = -1.0e-4 * np.arange(5)
CMOD_A_UX = -1.0e-5 * np.arange(5)
CMOD_B_UX = 2.0e-5 * np.arange(5)


def failed_by(time: float) -> list[tuple[int, int, int, float]]:
    """The FAILURES with a failure time <= ``time``, sorted by (cell, spring)."""
    return sorted((f for f in FAILURES if f[3] <= time), key=lambda f: (f[0], f[1]))


def write_fracture_file(path: Path, *, fracture: bool = True, **options: object) -> Synthetic:
    """A synthetic file (write_iem_file) plus reactions, three more probes and, with
    ``fracture``, damage and failed springs per frame and the fragment history."""
    truth = write_iem_file(path, **options)  # type: ignore[arg-type]
    n_samples = SAMPLE_TIMES.size
    with h5py.File(path, "a") as h5:
        hist = h5["history"]
        hist["reactions/load"] = np.column_stack([np.zeros(n_samples), LOAD_Y])
        hist["reactions/bc_2"] = np.column_stack([np.full(n_samples, 5.0), np.zeros(n_samples)])
        for name, ux, uy in (
            ("load_point", np.zeros(n_samples), LOAD_POINT_UY),
            ("a", CMOD_A_UX, np.zeros(n_samples)),
            ("b", CMOD_B_UX, np.zeros(n_samples)),
        ):
            probe = hist.create_group(f"probes/{name}")
            probe["displacement"] = np.column_stack([ux, uy])
            probe["velocity"] = np.zeros((n_samples, 2))
        if not fracture:
            return truth
        for k, t in enumerate(truth.frame_times):
            group = h5[f"frames/frame_{k:06d}"]
            failed = failed_by(float(t))
            damage = np.zeros(NX * NY)
            for cell, *_ in failed:
                damage[cell] += 1.0 / 8.0
            group["damage"] = damage
            springs = group.create_group("failed_springs")
            springs["cell"] = np.array([f[0] for f in failed], dtype=np.int64)
            springs["spring"] = np.array([f[1] for f in failed], dtype=np.int32)
            springs["kind"] = np.array([f[2] for f in failed], dtype=np.int32)
            springs["time"] = np.array([f[3] for f in failed], dtype=np.float64)
        frac = hist.create_group("fracture")
        frac["fragments"] = FRAGMENTS
        frac["largest_fragments"] = LARGEST
    return truth


@pytest.fixture
def fracture_file(tmp_path: Path) -> Synthetic:
    """A complete synthetic output file of a run with fracture."""
    return write_fracture_file(tmp_path / "frac.h5")
