"""Tests of the fracture commands (crack-map, fragments, curve, animate) and their modules,
on synthetic files in the agreed layout (conftest.write_fracture_file)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np
import pytest
from matplotlib.collections import LineCollection, PolyCollection
from PIL import Image

from conftest import (
    CMOD_A_UX,
    CMOD_B_UX,
    FAILURES,
    LOAD_POINT_UY,
    LOAD_Y,
    SAMPLE_TIMES,
    failed_by,
    grid,
    write_fracture_file,
)
from iem_post import animation, curves, fracture
from iem_post.cli import main
from iem_post.fracture_plots import plot_crack_map
from iem_post.reader import IemFile, InputError
from test_cli import _assert_clean_error, assert_png, printed_paths

if TYPE_CHECKING:
    from conftest import Synthetic

REFERENCE_CSV = "cmod, load_min, load_max\n0.0, 0, 100\n0.05, 800, 1200\n0.2, 200, 400\n"


def gif_frames(path: Path) -> int:
    """Number of pictures in the GIF ``path`` (which must be a real GIF)."""
    assert path.is_file(), path
    assert path.read_bytes()[:6] in (b"GIF87a", b"GIF89a")
    with Image.open(path) as image:
        return int(image.n_frames)


# ---------------------------------------------------------------------------- reading
def test_read_failed_springs(fracture_file: Synthetic) -> None:
    """Each frame's failed springs are those failed by its time, as written."""
    with IemFile(fracture_file.path) as data:
        for k, t in enumerate(fracture_file.frame_times):
            info, springs = fracture.read_failed_springs(data, k)
            expected = failed_by(float(t))
            assert info.index == k and len(springs) == len(expected)
            np.testing.assert_array_equal(springs.cell, [f[0] for f in expected])
            np.testing.assert_array_equal(springs.spring, [f[1] for f in expected])
            np.testing.assert_array_equal(springs.kind, [f[2] for f in expected])
            np.testing.assert_array_equal(springs.time, [f[3] for f in expected])
        _, springs = fracture.read_failed_springs(data, -1)
        kinds = [f[2] for f in FAILURES]
        assert springs.counts() == {name: kinds.count(k)
                                    for k, name in fracture.KIND_NAMES.items()}


def test_spring_segments(fracture_file: Synthetic) -> None:
    """An edge spring is drawn as its edge, a shear spring as a mark from its corner
    towards the cell's centre."""
    coords, cells = fracture_file.coordinates, fracture_file.cells
    springs = fracture.FailedSprings(
        cell=np.array([1, 7, 2]), spring=np.array([0, 3, 5]),
        kind=np.array([1, 1, 3]), time=np.zeros(3))
    seg = fracture.spring_segments(coords, cells, springs, mark=0.25)
    np.testing.assert_allclose(seg[0], coords[[cells[1, 0], cells[1, 1]]])  # bottom of cell 1
    np.testing.assert_allclose(seg[1], coords[[cells[7, 3], cells[7, 0]]])  # left of cell 7
    corner = coords[cells[2, 1]]  # SE corner of cell 2
    centre = coords[cells[2]].mean(axis=0)
    np.testing.assert_allclose(seg[2], [corner, corner + 0.25 * (centre - corner)])


def test_fragment_sizes_match_history(fracture_file: Synthetic) -> None:
    """The fragments computed from each frame's failed springs are those the history
    (written by hand) gives at the same time."""
    with IemFile(fracture_file.path) as data:
        history = fracture.read_fragment_history(data)
        np.testing.assert_array_equal(history.time, SAMPLE_TIMES)
        for k, t in enumerate(fracture_file.frame_times):
            _, springs = fracture.read_failed_springs(data, k)
            sizes = fracture.fragment_sizes(data.mesh.n_nodes, data.mesh.cells, springs)
            sample = int(np.flatnonzero(np.isclose(SAMPLE_TIMES, t))[0])
            assert sizes.sum() == data.mesh.n_nodes
            assert sizes.size == history.count[sample]
            padded = np.zeros(5, dtype=np.int64)
            padded[: min(5, sizes.size)] = sizes[:5]
            np.testing.assert_array_equal(padded, history.largest[sample])


def test_fragment_sizes_disconnected_grid() -> None:
    """On a larger grid, cutting every edge across one column gives two fragments whose
    sizes are the node columns on each side; an edge failed in only one of its two cells
    cuts nothing."""
    nx, ny = 6, 3
    coords, cells = grid(nx, ny, 1.0, 1.0)
    column = [c for c in range(cells.shape[0]) if c % nx == 2]
    cell = np.repeat(column, 2)
    spring = np.tile([0, 2], len(column))  # bottom and top of every cell in column 2
    springs = fracture.FailedSprings(cell=cell, spring=spring, kind=np.ones_like(cell),
                                     time=np.zeros(cell.size))
    sizes = fracture.fragment_sizes(coords.shape[0], cells, springs)
    np.testing.assert_array_equal(sizes, [4 * (ny + 1), 3 * (ny + 1)])
    half = fracture.FailedSprings(cell=np.array([0]), spring=np.array([1]),
                                  kind=np.array([1]), time=np.zeros(1))
    np.testing.assert_array_equal(fracture.fragment_sizes(coords.shape[0], cells, half),
                                  [coords.shape[0]])


def _sizes_by_search(n_nodes: int, cells: np.ndarray, failed: set[tuple[int, int]]) -> list[int]:
    """Fragment sizes by a plain depth-first search over the edges some cell holds intact."""
    neighbours: dict[int, set[int]] = {n: set() for n in range(n_nodes)}
    for c, corners in enumerate(cells.tolist()):
        for q in range(4):
            if (c, q) not in failed:
                a, b = corners[q], corners[(q + 1) % 4]
                neighbours[a].add(b)
                neighbours[b].add(a)
    seen: set[int] = set()
    sizes = []
    for start in range(n_nodes):
        if start in seen:
            continue
        stack, size = [start], 0
        seen.add(start)
        while stack:
            node = stack.pop()
            size += 1
            for other in neighbours[node] - seen:
                seen.add(other)
                stack.append(other)
        sizes.append(size)
    return sorted(sizes, reverse=True)


@pytest.mark.parametrize("fraction", [0.55, 0.7, 0.85])
def test_fragment_sizes_random(fraction: float) -> None:
    """On a random set of failed edge (and shear) springs the fragment sizes equal those of
    a plain graph search."""
    rng = np.random.default_rng(int(fraction * 100))
    coords, cells = grid(12, 9, 1.0, 1.0)
    chosen = np.flatnonzero(rng.random(cells.shape[0] * 8) < fraction)
    springs = fracture.FailedSprings(cell=chosen // 8, spring=chosen % 8,
                                     kind=np.ones(chosen.size, dtype=np.int32),
                                     time=np.zeros(chosen.size))
    failed = {(int(c), int(q)) for c, q in zip(chosen // 8, chosen % 8) if q < 4}
    expected = _sizes_by_search(coords.shape[0], cells, failed)
    got = fracture.fragment_sizes(coords.shape[0], cells, springs)
    assert len(expected) > 1
    np.testing.assert_array_equal(got, expected)


# ---------------------------------------------------------------------------- crack-map
def test_crack_map_command(fracture_file: Synthetic, capsys: pytest.CaptureFixture[str]) -> None:
    """crack-map draws the last frame by default and prints the counts by kind."""
    assert main(["crack-map", str(fracture_file.path)]) == 0
    out = capsys.readouterr().out
    path = fracture_file.path.parent / "frac_cracks_000002.png"
    assert printed_paths(out) == [path]
    assert "9 failed: 6 tension, 1 crushing, 1 shear, 1 pre-cut" in out
    assert_png(path)


def test_crack_map_frame_and_scale(
    fracture_file: Synthetic, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--frame, --scale and -o are honoured."""
    png = tmp_path / "maps" / "c.png"
    args = ["crack-map", str(fracture_file.path), "--frame", "1", "--scale", "auto", "-o", str(png)]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert printed_paths(out) == [png]
    assert "(frame 1, 5 failed: 4 tension, 0 crushing, 0 shear, 1 pre-cut)" in out
    assert_png(png)


def test_crack_map_figure_data(fracture_file: Synthetic) -> None:
    """The coloured segments carry the failure times, pre-cut ones are apart, and the title
    counts the springs by kind."""
    with IemFile(fracture_file.path) as data:
        _, springs = fracture.read_failed_springs(data, -1)
        frame = data.frame(-1)
        fig = plot_crack_map(data.mesh, frame.displacement, springs, scale=2.0, title="T")
        ax = fig.axes[0]
        lines = [c for c in ax.collections if isinstance(c, LineCollection)]
        timed = [c for c in lines if c.get_array() is not None]
        assert len(timed) == 1
        expected = [f[3] for f in failed_by(1.0) if f[2] != fracture.PRECUT]
        np.testing.assert_array_equal(timed[0].get_array(), expected)
        positions = data.mesh.coordinates + 2.0 * frame.displacement
        segments = fracture.spring_segments(positions, data.mesh.cells, springs)
        np.testing.assert_allclose(np.array(timed[0].get_segments()),
                                   segments[springs.kind != fracture.PRECUT])
        cells = [c for c in ax.collections if isinstance(c, PolyCollection)
                 and not isinstance(c, LineCollection)]
        assert len(cells) == 1 and len(cells[0].get_paths()) == data.mesh.n_cells
        assert "6 tension, 1 crushing, 1 shear, 1 pre-cut" in ax.get_title()


# ---------------------------------------------------------------------------- fragments
def test_fragments_command(fracture_file: Synthetic, capsys: pytest.CaptureFixture[str]) -> None:
    """fragments writes its figure and prints the last count and largest sizes."""
    assert main(["fragments", str(fracture_file.path)]) == 0
    captured = capsys.readouterr()
    path = fracture_file.path.parent / "frac_fragments.png"
    assert printed_paths(captured.out) == [path]
    assert "(3 fragments at t = 0.002 s; largest: 8, 6, 1)" in captured.out
    assert captured.err == ""  # the last frame agrees with the history
    assert_png(path)


def test_fragments_mismatch_warns(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A history that disagrees with the last frame's failed springs gives a warning."""
    truth = write_fracture_file(tmp_path / "bad.h5")
    with h5py.File(truth.path, "a") as h5:
        h5["history/fracture/fragments"][-1] = 4
    assert main(["fragments", str(truth.path), "-o", str(tmp_path / "f.png")]) == 0
    err = capsys.readouterr().err
    assert err.startswith("iem-post: warning: ") and "3 fragments" in err and "says 4" in err


def test_fragments_without_frame_springs(tmp_path: Path) -> None:
    """Without failed springs in the last frame the five largest of the history stand in."""
    truth = write_fracture_file(tmp_path / "nf.h5")
    with h5py.File(truth.path, "a") as h5:
        del h5["frames/frame_000002/failed_springs"]
    png = tmp_path / "f.png"
    assert main(["fragments", str(truth.path), "-o", str(png)]) == 0
    assert_png(png)


# ---------------------------------------------------------------------------- curve
def test_curve_command_csv(
    fracture_file: Synthetic, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """curve writes the figure and a CSV of the scaled load, displacement and CMOD."""
    png, csv = tmp_path / "c.png", tmp_path / "out" / "c.csv"
    rc = main(["curve", str(fracture_file.path), "--load", "load:y", "--load-scale=-1",
               "--displacement", "load_point", "--displacement-scale=-1e3",
               "--cmod", "a,b", "--cmod-scale", "1e3", "-o", str(png), "--csv", str(csv)])
    assert rc == 0
    out = capsys.readouterr().out
    assert printed_paths(out) == [png, csv]
    k = int(np.argmax(-LOAD_Y))
    assert f"peak load {-LOAD_Y[k]:.6g} at t = {SAMPLE_TIMES[k]:.6g} s" in out
    assert_png(png)
    table = np.genfromtxt(csv, delimiter=",", names=True)
    assert table.dtype.names == ("time", "displacement", "load", "cmod")
    np.testing.assert_allclose(table["time"], SAMPLE_TIMES)
    np.testing.assert_allclose(table["load"], -LOAD_Y)
    np.testing.assert_allclose(table["displacement"], -1e3 * LOAD_POINT_UY)
    np.testing.assert_allclose(table["cmod"], 1e3 * (CMOD_B_UX - CMOD_A_UX))


def test_curve_x_component_without_cmod(
    fracture_file: Synthetic, tmp_path: Path
) -> None:
    """BCNAME:x picks the x column; no --cmod, no cmod column."""
    csv = tmp_path / "c.csv"
    rc = main(["curve", str(fracture_file.path), "--load", "bc_2:x", "--displacement", "b:x",
               "-o", str(tmp_path / "c.png"), "--csv", str(csv)])
    assert rc == 0
    table = np.genfromtxt(csv, delimiter=",", names=True)
    assert table.dtype.names == ("time", "displacement", "load")
    np.testing.assert_allclose(table["load"], 5.0)
    np.testing.assert_allclose(table["displacement"], CMOD_B_UX)


def test_curve_reference_band(fracture_file: Synthetic, tmp_path: Path) -> None:
    """The reference band is drawn on the CMOD plot, scaled column-wise."""
    ref = tmp_path / "ref.csv"
    ref.write_text(REFERENCE_CSV)
    band = curves.read_reference(ref, (1e-3, 2.0))
    np.testing.assert_allclose(band.cmod, [0.0, 0.05e-3, 0.2e-3])
    np.testing.assert_allclose(band.load_max, [200.0, 2400.0, 800.0])
    with IemFile(fracture_file.path) as data:
        data_curves = curves.read_curves(data, ("load", "y"), ("load_point", "y"), ("a", "b"),
                                         load_scale=-1.0)
    fig = curves.plot_curves(data_curves, band)
    filled = [c for c in fig.axes[1].collections if isinstance(c, PolyCollection)]
    assert len(filled) == 1
    vertices = filled[0].get_paths()[0].vertices
    assert vertices[:, 0].max() == pytest.approx(0.2e-3)
    assert vertices[:, 1].max() == pytest.approx(2400.0)
    png = tmp_path / "c.png"
    rc = main(["curve", str(fracture_file.path), "--load", "load", "--load-scale", "-1",
               "--displacement", "load_point", "--cmod", "a,b", "--reference", str(ref),
               "--reference-scale", "1e-3,1", "-o", str(png)])
    assert rc == 0
    assert_png(png)


def test_curve_reference_shipped_table() -> None:
    """The experimental band shipped with the project reads (mm to m)."""
    path = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "fracture" / "gregoire2013_half_notched_beam.csv"
    if not path.is_file():
        pytest.skip("no shared fracture data here")
    band = curves.read_reference(path, (1e-3, 1.0))
    assert band.cmod.size > 100 and np.all(np.diff(band.cmod) >= 0)
    assert np.all(band.load_min <= band.load_max)
    assert 0.0 < band.cmod.max() < 1e-3


def test_curve_reference_needs_cmod(
    fracture_file: Synthetic, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--reference without --cmod is a usage error."""
    with pytest.raises(SystemExit) as exc:
        main(["curve", str(fracture_file.path), "--load", "load", "--displacement",
              "load_point", "--reference", str(tmp_path / "r.csv")])
    assert exc.value.code == 2
    assert "--cmod" in capsys.readouterr().err


def test_curve_bad_reference(
    fracture_file: Synthetic, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A reference without the needed columns, or missing, is a one-line error."""
    ref = tmp_path / "ref.csv"
    ref.write_text("x, y\n1, 2\n")
    base = ["curve", str(fracture_file.path), "--load", "load", "--displacement", "load_point",
            "--cmod", "a,b", "-o", str(tmp_path / "c.png")]
    assert main([*base, "--reference", str(ref)]) == 1
    _assert_clean_error(capsys, "lacks the column(s) cmod, load_min, load_max")
    assert main([*base, "--reference", str(tmp_path / "absent.csv")]) == 1
    _assert_clean_error(capsys, "cannot read the reference")
    assert not (tmp_path / "c.png").exists()


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["--load", "nobc", "--displacement", "load_point"],
         "no dataset /history/reactions/nobc (reactions in this file: bc_2, load)"),
        (["--load", "load", "--displacement", "nop"],
         "no dataset /history/probes/nop/displacement (probes in this file: a, b,"),
        (["--load", "load", "--displacement", "a", "--cmod", "a,zz"],
         "no dataset /history/probes/zz/displacement"),
    ],
)
def test_curve_missing_names(
    fracture_file: Synthetic, capsys: pytest.CaptureFixture[str], args: list[str], fragment: str
) -> None:
    """An unknown bc or probe names the dataset and lists what the file has."""
    assert main(["curve", str(fracture_file.path), *args]) == 1
    _assert_clean_error(capsys, fragment)


def test_parse_target() -> None:
    """NAME[:x|y] with y as the default component."""
    assert curves.parse_target("top") == ("top", "y")
    assert curves.parse_target("top:x") == ("top", "x")
    assert curves.parse_target("top:Y") == ("top", "y")
    assert curves.parse_target("a:b") == ("a:b", "y")


# ---------------------------------------------------------------------------- animate
@pytest.mark.parametrize("field", ["displacement", "velocity", "damage"])
def test_animate_gif(
    fracture_file: Synthetic, tmp_path: Path, capsys: pytest.CaptureFixture[str], field: str
) -> None:
    """animate writes a GIF with one picture per frame, for every field."""
    gif = tmp_path / f"{field}.gif"
    assert main(["animate", str(fracture_file.path), "--field", field, "-o", str(gif),
                 "--fps", "4"]) == 0
    out = capsys.readouterr().out
    assert printed_paths(out) == [gif]
    assert f"(3 pictures, field {field}," in out
    assert gif_frames(gif) == len(fracture_file.frame_times)


def test_animate_default_name_and_every(
    iem_file: Synthetic, capsys: pytest.CaptureFixture[str]
) -> None:
    """The default output is <stem>_<field>.gif next to the file; --every 2 keeps frames
    0 and 2. A run without fracture animates its node fields."""
    assert main(["animate", str(iem_file.path), "--every", "2", "--dpi", "50"]) == 0
    gif = iem_file.path.parent / "run_displacement.gif"
    assert printed_paths(capsys.readouterr().out) == [gif]
    assert gif_frames(gif) == 2


def test_animate_values_are_cell_means(fracture_file: Synthetic) -> None:
    """Node fields are animated as the cell mean of the corners' magnitudes."""
    with IemFile(fracture_file.path) as data:
        _, values = animation.cell_values(data, 2, "velocity")
        v = fracture_file.velocities[2]
        np.testing.assert_allclose(values, np.hypot(v[:, 0], v[:, 1])[fracture_file.cells]
                                   .mean(axis=1))
        _, damage = animation.cell_values(data, 1, "damage")
        assert damage.shape == (fracture_file.cells.shape[0],)


def test_animate_formats(
    fracture_file: Synthetic, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An unknown suffix is refused; .mp4 without ffmpeg is refused with a clear error."""
    avi = tmp_path / "a.avi"
    assert main(["animate", str(fracture_file.path), "-o", str(avi)]) == 1
    _assert_clean_error(capsys, "must end in .gif or .mp4")
    assert not avi.exists()
    mp4 = tmp_path / "a.mp4"
    try:
        animation.writer_for(mp4, 5)
    except InputError:
        assert main(["animate", str(fracture_file.path), "-o", str(mp4)]) == 1
        _assert_clean_error(capsys, "needs ffmpeg")
        assert not mp4.exists()
    else:
        assert main(["animate", str(fracture_file.path), "-o", str(mp4)]) == 0
        assert mp4.stat().st_size > 0


# ---------------------------------------------------------------------------- runs without fracture
@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["crack-map"], "no dataset /frames/frame_000002/failed_springs/cell"),
        (["fragments"], "no dataset /history/fracture/fragments"),
        (["animate", "--field", "damage"], "no dataset /frames/frame_000000/damage"),
        (["curve", "--load", "load", "--displacement", "tip"],
         "no dataset /history/reactions/load (this file has no /history/reactions)"),
    ],
)
def test_without_fracture(
    iem_file: Synthetic, capsys: pytest.CaptureFixture[str], args: list[str], fragment: str
) -> None:
    """A file without the datasets a command needs: exit 1, one line naming the dataset,
    nothing written."""
    before = set(iem_file.path.parent.iterdir())
    assert main([args[0], str(iem_file.path), *args[1:]]) == 1
    _assert_clean_error(capsys, fragment)
    assert set(iem_file.path.parent.iterdir()) == before


def test_fracture_commands_need_only_their_data(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run without fracture still has reactions: curve works, crack-map does not."""
    truth = write_fracture_file(tmp_path / "nofr.h5", fracture=False)
    assert main(["curve", str(truth.path), "--load", "load", "--displacement",
                 "load_point"]) == 0
    assert main(["crack-map", str(truth.path)]) == 1
    assert "written only by runs with &material fracture" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["crack-map", "fragments", "curve", "animate"])
def test_help(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    """--help works for every fracture command."""
    with pytest.raises(SystemExit) as exc:
        main([command, "--help"])
    assert exc.value.code == 0
    assert "usage: iem-post" in capsys.readouterr().out


def test_bad_failed_springs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Failed springs that refer to cells the mesh lacks are a one-line error."""
    truth = write_fracture_file(tmp_path / "bad.h5")
    with h5py.File(truth.path, "a") as h5:
        h5["frames/frame_000002/failed_springs/cell"][0] = 99
    assert main(["crack-map", str(truth.path)]) == 1
    _assert_clean_error(capsys, "refers to cells that do not exist")
