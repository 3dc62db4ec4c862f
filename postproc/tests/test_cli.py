"""Tests of the iem-post command line, called through iem_post.cli.main."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np
import pytest
from matplotlib.image import imread

from iem_post.cli import main

if TYPE_CHECKING:
    from conftest import Synthetic

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
POSTPROC = Path(__file__).resolve().parents[1]


def assert_png(path: Path) -> np.ndarray:
    """Check ``path`` is a real, non-blank PNG image and return its pixels."""
    assert path.is_file(), path
    assert path.stat().st_size > 2000, path
    assert path.read_bytes()[:8] == PNG_MAGIC
    pixels = imread(path)
    assert pixels.ndim == 3 and pixels.shape[0] > 100 and pixels.shape[1] > 100
    assert pixels[..., :3].std() > 0.01  # something was drawn
    return pixels


def printed_paths(out: str) -> list[Path]:
    """The file paths at the start of each printed line."""
    return [Path(line.split("  ")[0]) for line in out.splitlines() if line.strip()]


def test_history_default_outdir(iem_file: Synthetic, capsys: pytest.CaptureFixture[str]) -> None:
    """history writes <stem>_probes.png and <stem>_energy.png next to the file and prints them."""
    assert main(["history", str(iem_file.path)]) == 0
    out = capsys.readouterr().out
    expected = [iem_file.path.parent / "run_probes.png", iem_file.path.parent / "run_energy.png"]
    assert printed_paths(out) == expected
    for path in expected:
        assert_png(path)


def test_history_outdir(
    iem_file: Synthetic,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """history -o writes into the given folder, creating it."""
    outdir = tmp_path / "plots" / "sub"
    assert main(["history", str(iem_file.path), "-o", str(outdir)]) == 0
    assert printed_paths(capsys.readouterr().out) == [
        outdir / "run_probes.png",
        outdir / "run_energy.png",
    ]
    assert_png(outdir / "run_probes.png")
    assert_png(outdir / "run_energy.png")


def test_frame_default_is_last(iem_file: Synthetic, capsys: pytest.CaptureFixture[str]) -> None:
    """frame without --frame draws the last frame with the auto scale."""
    assert main(["frame", str(iem_file.path)]) == 0
    out = capsys.readouterr().out
    disp = iem_file.displacements[2]
    auto = 0.1 * 2.0 / np.hypot(disp[:, 0], disp[:, 1]).max()
    assert f"(frame 2, scale {auto:.4g}, field umag)" in out
    path = iem_file.path.parent / "run_frame_000002.png"
    assert printed_paths(out) == [path]
    assert_png(path)


def test_frame_negative_index_and_output(
    iem_file: Synthetic, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--frame -2 is frame 1; -o and an explicit --scale are honoured."""
    png = tmp_path / "out" / "f.png"
    rc = main(["frame", str(iem_file.path), "--frame", "-2", "--scale", "50", "-o", str(png)])
    assert rc == 0
    out = capsys.readouterr().out
    assert "(frame 1, scale 50, field umag)" in out
    assert printed_paths(out) == [png]
    assert_png(png)


@pytest.mark.parametrize("field", ["umag", "ux", "uy", "vmag", "vx", "vy"])
def test_frame_fields(iem_file: Synthetic, tmp_path: Path, field: str) -> None:
    """Every colour field draws."""
    png = tmp_path / f"{field}.png"
    assert main(["frame", str(iem_file.path), "--field", field, "-o", str(png)]) == 0
    assert_png(png)


def test_frame_fields_differ(iem_file: Synthetic, tmp_path: Path) -> None:
    """Different fields give different pictures (the colouring really uses the field)."""
    a, b = tmp_path / "ux.png", tmp_path / "vy.png"
    main(["frame", str(iem_file.path), "--field", "ux", "--scale", "1", "-o", str(a)])
    main(["frame", str(iem_file.path), "--field", "vy", "--scale", "1", "-o", str(b)])
    pa, pb = imread(a), imread(b)
    assert pa.shape == pb.shape
    assert np.abs(pa - pb).mean() > 1e-3


def test_frame_auto_scale_zero_motion(
    make_iem_file: Callable[..., Synthetic], capsys: pytest.CaptureFixture[str]
) -> None:
    """With zero displacement everywhere the auto scale is 1."""
    truth = make_iem_file(zero_motion=True)
    assert main(["frame", str(truth.path), "--scale", "auto"]) == 0
    assert "scale 1," in capsys.readouterr().out


def test_summary(iem_file: Synthetic, capsys: pytest.CaptureFixture[str]) -> None:
    """summary prints counts, version, completion, final energies and max balance error."""
    assert main(["summary", str(iem_file.path)]) == 0
    out = capsys.readouterr().out
    assert "version:     1.2.3" in out
    assert "ranks:       4" in out
    assert "nodes:       15" in out
    assert "cells:       8 (4 x 2 cells)" in out
    assert "frames:      3 (t = 0 .. 0.002 s)" in out
    assert "samples:     5 (t = 0 .. 0.002 s)" in out
    assert "complete:    yes" in out
    assert "kinetic        0.02\n" in out
    assert "strain         0.040001\n" in out
    assert "external_work  0.06\n" in out
    assert "damping        0.001\n" in out
    assert "max balance error: 5e-08 (t = 0.0015 s)" in out


def test_all(iem_file: Synthetic, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """all writes the two history plots and the last frame."""
    outdir = tmp_path / "all"
    assert main(["all", str(iem_file.path), "-o", str(outdir)]) == 0
    paths = printed_paths(capsys.readouterr().out)
    assert paths == [
        outdir / "run_probes.png",
        outdir / "run_energy.png",
        outdir / "run_frame_000002.png",
    ]
    for path in paths:
        assert_png(path)


def _assert_clean_error(capsys: pytest.CaptureFixture[str], fragment: str) -> None:
    """One 'iem-post: error:' line containing ``fragment`` on stderr, and no traceback."""
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("iem-post: error: ")
    assert fragment in lines[0]
    assert "Traceback" not in captured.err + captured.out


@pytest.mark.parametrize("command", ["history", "frame", "summary", "all"])
def test_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str) -> None:
    """A missing file exits 1 with a clear message, for every command."""
    assert main([command, str(tmp_path / "absent.h5")]) == 1
    _assert_clean_error(capsys, "no such file")


def test_not_iem_hdf5(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """An HDF5 file that is not iem output exits 1."""
    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as h5:
        h5.attrs["program"] = "something_else"
    assert main(["summary", str(path)]) == 1
    _assert_clean_error(capsys, "not an iem output file")


def test_not_hdf5(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A non-HDF5 file exits 1."""
    path = tmp_path / "notes.h5"
    path.write_text("not hdf5\n")
    assert main(["history", str(path)]) == 1
    _assert_clean_error(capsys, "not an HDF5 file")


@pytest.mark.parametrize("index", ["3", "-4", "99"])
def test_frame_out_of_range(
    iem_file: Synthetic,
    capsys: pytest.CaptureFixture[str],
    index: str,
) -> None:
    """An out-of-range frame index exits 1 and writes nothing."""
    assert main(["frame", str(iem_file.path), "--frame", index]) == 1
    _assert_clean_error(capsys, f"frame {index} out of range")
    assert not list(iem_file.path.parent.glob("*.png"))


def test_incomplete_file_warns_but_works(
    make_iem_file: Callable[..., Synthetic], capsys: pytest.CaptureFixture[str]
) -> None:
    """An incomplete file gives a warning on stderr, then the command still succeeds."""
    truth = make_iem_file(complete=0)
    assert main(["summary", str(truth.path)]) == 0
    captured = capsys.readouterr()
    assert captured.err.startswith("iem-post: warning: ")
    assert "incomplete" in captured.err
    assert "complete:    NO" in captured.out


def test_complete_file_no_warning(iem_file: Synthetic, capsys: pytest.CaptureFixture[str]) -> None:
    """A complete file produces nothing on stderr."""
    assert main(["summary", str(iem_file.path)]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("bad", ["-1", "abc", "nan"])
def test_bad_scale_rejected(
    iem_file: Synthetic,
    capsys: pytest.CaptureFixture[str],
    bad: str,
) -> None:
    """A negative or non-numeric --scale is a usage error (exit 2)."""
    with pytest.raises(SystemExit) as exc:
        main(["frame", str(iem_file.path), f"--scale={bad}"])
    assert exc.value.code == 2
    assert "scale" in capsys.readouterr().err


@pytest.mark.parametrize("command", [[], ["history"], ["frame"], ["summary"], ["all"]])
def test_help(command: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    """--help works for the program and every sub-command."""
    with pytest.raises(SystemExit) as exc:
        main([*command, "--help"])
    assert exc.value.code == 0
    assert "usage: iem-post" in capsys.readouterr().out


def test_python_dash_m(iem_file: Synthetic) -> None:
    """python -m iem_post works with postproc on PYTHONPATH and returns the exit status."""
    env = dict(os.environ, PYTHONPATH=str(POSTPROC))
    ok = subprocess.run(
        [sys.executable, "-m", "iem_post", "summary", str(iem_file.path)],
        capture_output=True, text=True, env=env, check=False,
    )
    assert ok.returncode == 0, ok.stderr
    assert "nodes:       15" in ok.stdout
    bad = subprocess.run(
        [sys.executable, "-m", "iem_post", "frame", str(iem_file.path), "--frame", "5"],
        capture_output=True, text=True, env=env, check=False,
    )
    assert bad.returncode == 1
    assert "Traceback" not in bad.stderr and "out of range" in bad.stderr
