"""Tests of iem_post.reader against synthetic files with known contents."""

from __future__ import annotations

import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np
import pytest

from iem_post.reader import (
    FrameIndexError,
    IemFile,
    IemFileError,
    IncompleteFileWarning,
)

if TYPE_CHECKING:
    from conftest import Synthetic


def test_root_attributes(iem_file: Synthetic) -> None:
    """Program, version, ranks and completion come back decoded."""
    with IemFile(iem_file.path) as data:
        assert data.program == "iem"
        assert data.version == "1.2.3"
        assert data.n_ranks == 4
        assert data.complete is True
        assert data.attributes["units"] == "SI: m, kg, s, N, Pa, J"


def test_mesh(iem_file: Synthetic) -> None:
    """Mesh arrays and attributes match what was written, numbering per docs/output.md."""
    with IemFile(iem_file.path) as data:
        mesh = data.mesh
        assert (mesh.n_nodes, mesh.n_cells) == (15, 8)
        assert (mesh.nx, mesh.ny) == (4, 2)
        assert mesh.lx == pytest.approx(0.5) and mesh.ly == pytest.approx(0.25)
        assert mesh.thickness == pytest.approx(0.01)
        assert mesh.plane == "stress"
        np.testing.assert_array_equal(mesh.coordinates, iem_file.coordinates)
        np.testing.assert_array_equal(mesh.cells[0], [0, 1, 6, 5])
        np.testing.assert_array_equal(mesh.cells[-1], [8, 9, 14, 13])
        np.testing.assert_allclose(mesh.coordinates[7], [1.0, 0.25])  # node i=2, j=1
        assert mesh.extent == pytest.approx((2.0, 0.5))


def test_frames_list(iem_file: Synthetic) -> None:
    """Frames come in order with their time and step."""
    with IemFile(iem_file.path) as data:
        frames = data.frames
        assert [f.name for f in frames] == [f"frame_{k:06d}" for k in range(3)]
        assert [f.index for f in frames] == [0, 1, 2]
        np.testing.assert_allclose([f.time for f in frames], iem_file.frame_times)
        assert [f.step for f in frames] == [0, 100, 200]


@pytest.mark.parametrize("index, expected", [(0, 0), (1, 1), (2, 2), (-1, 2), (-3, 0)])
def test_frame_arrays(iem_file: Synthetic, index: int, expected: int) -> None:
    """Frame arrays, including negative indices, hold the written values."""
    with IemFile(iem_file.path) as data:
        frame = data.frame(index)
        assert frame.index == expected
        assert frame.time == pytest.approx(iem_file.frame_times[expected])
        np.testing.assert_array_equal(frame.displacement, iem_file.displacements[expected])
        np.testing.assert_array_equal(frame.velocity, iem_file.velocities[expected])


@pytest.mark.parametrize("index", [3, 10, -4])
def test_frame_out_of_range(iem_file: Synthetic, index: int) -> None:
    """Out-of-range indices raise FrameIndexError with the valid range."""
    with IemFile(iem_file.path) as data, pytest.raises(FrameIndexError, match="0..2"):
        data.frame(index)


def test_history(iem_file: Synthetic) -> None:
    """History time, energies and probes hold the written values."""
    with IemFile(iem_file.path) as data:
        np.testing.assert_allclose(data.history_time, [0.0, 5e-4, 1e-3, 1.5e-3, 2e-3])
        np.testing.assert_array_equal(data.history_step, [0, 50, 100, 150, 200])
        energies = data.energies
        assert set(energies) == {"kinetic", "strain", "external_work", "damping", "balance_error"}
        for name, series in iem_file.energies.items():
            np.testing.assert_array_equal(energies[name], series)
        probes = data.probes
        assert list(probes) == ["tip"]
        tip = probes["tip"]
        assert tip.node == 14
        assert (tip.node_x, tip.node_y) == (2.0, 0.5)
        assert (tip.x, tip.y) == (pytest.approx(1.99), pytest.approx(0.49))
        np.testing.assert_array_equal(tip.displacement, iem_file.probe_displacement)
        assert tip.velocity.shape == (5, 2)


def test_fixed_length_padded_strings(make_iem_file: Callable[..., Synthetic]) -> None:
    """Fortran-style blank-padded fixed-length string attributes are accepted and stripped."""
    truth = make_iem_file(fixed_strings=True)
    with IemFile(truth.path) as data:
        assert data.program == "iem"
        assert data.version == "1.2.3"
        assert data.mesh.plane == "stress"


def test_complete_file_does_not_warn(iem_file: Synthetic) -> None:
    """A complete file opens without any warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        IemFile(iem_file.path).close()


@pytest.mark.parametrize("complete", [0, None])
def test_incomplete_file_warns(
    make_iem_file: Callable[..., Synthetic],
    complete: int | None,
) -> None:
    """complete == 0 or absent gives an IncompleteFileWarning, but the data still reads."""
    truth = make_iem_file(complete=complete)
    with pytest.warns(IncompleteFileWarning, match="incomplete"):
        data = IemFile(truth.path)
    with data:
        assert data.complete is False
        assert data.n_frames == 3


def test_missing_file(tmp_path: Path) -> None:
    """A missing file raises IemFileError."""
    with pytest.raises(IemFileError, match="no such file"):
        IemFile(tmp_path / "nope.h5")


def test_not_hdf5(tmp_path: Path) -> None:
    """A file that is not HDF5 raises IemFileError."""
    path = tmp_path / "text.h5"
    path.write_text("hello\n")
    with pytest.raises(IemFileError, match="not an HDF5 file"):
        IemFile(path)


def test_other_program(make_iem_file: Callable[..., Synthetic]) -> None:
    """An HDF5 file whose program is not 'iem' is refused."""
    truth = make_iem_file(program="other")
    with pytest.raises(IemFileError, match="program = 'other'"):
        IemFile(truth.path)


def test_no_program_attribute(tmp_path: Path) -> None:
    """An HDF5 file without the program attribute is refused."""
    path = tmp_path / "plain.h5"
    with h5py.File(path, "w") as h5:
        h5["x"] = np.arange(3)
    with pytest.raises(IemFileError, match="no 'program' attribute"):
        IemFile(path)


def test_partially_written_frame_skipped(iem_file: Synthetic) -> None:
    """A frame group still lacking its datasets (run in progress) is not listed."""
    with h5py.File(iem_file.path, "a") as h5:
        h5.create_group("frames/frame_000003")["displacement"] = np.zeros((15, 2))
    with IemFile(iem_file.path) as data:
        assert data.n_frames == 3
        assert data.frame(-1).index == 2


def test_missing_mesh_is_clear_error(iem_file: Synthetic) -> None:
    """A missing mesh dataset raises IemFileError naming it."""
    with h5py.File(iem_file.path, "a") as h5:
        del h5["mesh/cells"]
    with IemFile(iem_file.path) as data, pytest.raises(IemFileError, match="mesh/cells"):
        _ = data.mesh


def test_file_is_read_only(iem_file: Synthetic) -> None:
    """The reader opens the file read-only."""
    with IemFile(iem_file.path) as data:
        assert data._h5.mode == "r"
