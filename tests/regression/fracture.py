#!/usr/bin/env python3
"""Regression checks of fracture (docs/model.md, "Fracture"), called by CTest.

The case (--case, tests/data/fracture_bar_pull.nml) pulls a bar apart: its left end is held in x,
its right end moves at a constant velocity, and one crack opens across it.

  grids    at each --nx (ny scaled with it, so the cells keep their shape) the energy
           dissipated when the crack has formed, /history/energy/fracture at the end, is the
           fracture energy x the crack area (height x thickness) within --band (5 %): the
           crack band makes it independent of the cell size; the crack is complete (the
           dissipation has stopped growing and the stored energy is gone); and the largest
           stress the bar carries before any damage, from its strain energy
           (sigma = sqrt(2 E W / V), the bar in uniform uniaxial stress), is the tensile
           strength within [0.9, 1.05] (samples every 2 % of it, and the elastic waves of
           the suddenly applied velocity)
  ranks    on each of --ranks the history (every dataset under /history: energies with the
           fracture energy, probes, times) and the last frame are bitwise those of the first
  criteria the other criteria and the static path, each on its own small case in the folder
           of --case: a bar crushed (fracture_bar_crush.nml) dissipates the crushing energy
           over its section and carries at most the compressive strength times it; a layer
           sheared (fracture_layer_shear.nml) dissipates the shear fracture energy over its
           area and carries at most the shear strength times it (both within --band, the
           peaks within [0.9, 1.05]; the failures logged with their kind: crushing, shear);
           the bar of --case pulled apart in 20 static load steps dissipates the fracture
           energy over its section within --band (the dissipation does not depend on the
           load steps)
  restart  a run checkpointed while the crack opens, continued with restart on --ranks,
           gives bitwise the history and last frame of the uninterrupted run (written on the
           first of --ranks), on the same and on other rank counts
"""
from __future__ import annotations

import argparse
import re
import shutil
import sys
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import regress as rg  # noqa: E402  (check, run_ok, scratch, FAILURES)


def value(text: str, key: str) -> float:
    """The number given to key in a namelist text (exactly once)."""
    found = re.findall(rf"\b{key}\s*=\s*([-+0-9.eEdD]+)", text)
    if len(found) != 1:
        raise SystemExit(f"the case must give {key} exactly once")
    return float(found[0].replace("d", "e").replace("D", "e"))


def variant(src: Path, dst: Path, out: str, nx: int | None = None, ny: int | None = None,
            t_end: float | None = None, run_extra: str = "") -> Path:
    """Copy the case with another output file, grid, end time or extra &run keys."""
    text = src.read_text()
    text, n = re.subn(r"output_file\s*=\s*'[^']*'", f"output_file = '{out}'", text)
    if n != 1:
        raise SystemExit(f"{src}: expected one output_file")
    if nx is not None:
        text, n = re.subn(r"\bnx\s*=\s*\d+\s*,\s*ny\s*=\s*\d+", f"nx = {nx}, ny = {ny}", text)
        if n != 1:
            raise SystemExit(f"{src}: expected 'nx = .., ny = ..' once")
    if t_end is not None:
        text, n = re.subn(r"\bt_end\s*=\s*[-+0-9.eEdD]+", f"t_end = {t_end!r}", text)
        if n != 1:
            raise SystemExit(f"{src}: expected t_end once")
    if run_extra:
        text, n = re.subn(r"^&run\b", "&run\n  " + run_extra, text, count=1, flags=re.M)
        if n != 1:
            raise SystemExit(f"{src}: expected a &run group")
    dst.write_text(text)
    return dst


def cmd_grids(args: argparse.Namespace) -> None:
    """Dissipated energy and strength on several grids."""
    text = Path(args.case).read_text()
    e, ft, gf = value(text, "E"), value(text, "tensile_strength"), value(text, "fracture_energy")
    length, height = value(text, "length"), value(text, "height")
    thickness = value(text, "thickness")
    nx0, ny0 = int(value(text, "nx")), int(value(text, "ny"))
    want = gf * height * thickness
    volume = length * height * thickness
    work = rg.scratch("fracture_grids")
    rows = []
    for nx in args.nx:
        ny = max(1, round(nx * ny0 / nx0))
        nml = variant(Path(args.case), work / f"nx{nx}.nml", f"nx{nx}.h5", nx, ny, args.t_end)
        if rg.run_ok(args, args.ranks[0], nml, work, f"{nx} x {ny} cells") is None:
            return
        with h5py.File(work / f"nx{nx}.h5", "r") as f:
            diss = f["history/energy/fracture"][:]
            strain = f["history/energy/strain"][:]
        ratio = diss[-1] / want
        rg.check(abs(ratio - 1.0) <= args.band,
                 f"{nx} x {ny}: dissipated {diss[-1]:.5g} J = {ratio:.4f} x Gf h t "
                 f"({want:.4g} J), within {args.band:.0%}")
        tail = diss[-max(2, len(diss) // 10):]
        done = tail[0] == tail[-1] and strain[-1] <= 1e-3 * strain.max()
        rg.check(done, f"{nx} x {ny}: the crack is complete (dissipation constant over the last "
                       f"tenth of the run, stored energy {strain[-1] / strain.max():.1e} of its "
                       f"peak)")
        elastic = diss == 0.0
        rg.check(bool(elastic[0]) and not bool(elastic[-1]),
                 f"{nx} x {ny}: no dissipation at the start, dissipation at the end")
        peak = float(np.sqrt(2.0 * e * strain[elastic].max() / volume)) / ft
        rg.check(0.9 <= peak <= 1.05,
                 f"{nx} x {ny}: largest stress before damage {peak:.4f} x the tensile strength "
                 f"(from the strain energy), within [0.9, 1.05]")
        rows.append((nx, ny, ratio, peak))
    print("nx   ny   dissipated/(Gf h t)   peak stress/ft")
    for nx, ny, ratio, peak in rows:
        print(f"{nx:<4d} {ny:<4d} {ratio:<21.4f} {peak:.4f}")


def cmd_criteria(args: argparse.Namespace) -> None:
    """Crushing, shear and a static pull: dissipation and peak force."""
    folder = Path(args.case).parent
    work = rg.scratch("fracture_criteria")
    cases = [("fracture_bar_crush.nml", "compressive_strength", "crushing_energy", "push",
              0, 2, "crushing"),
             ("fracture_layer_shear.nml", "shear_strength", "shear_fracture_energy", "slide",
              0, 3, "shear")]
    for name, strength_key, energy_key, bc, comp, kind, label in cases:
        src = folder / name
        text = src.read_text()
        strength, energy = value(text, strength_key), value(text, energy_key)
        length, height = value(text, "length"), value(text, "height")
        thickness = value(text, "thickness")
        # the crushed band crosses the bar's section; the sheared band runs along the layer
        area = (height if label == "crushing" else length) * thickness
        nml = variant(src, work / name, f"{label}.h5")
        if rg.run_ok(args, args.ranks[0], nml, work, label) is None:
            continue
        with h5py.File(work / f"{label}.h5", "r") as f:
            diss = float(f["history/energy/fracture"][-1])
            force = float(np.abs(f[f"history/reactions/{bc}"][:, comp]).max())
            kinds = np.unique(f["history/fracture/events/kind"][:])
        ratio = diss / (energy * area)
        rg.check(abs(ratio - 1.0) <= args.band,
                 f"{label}: dissipated {diss:.5g} J = {ratio:.4f} x {energy_key} x area, "
                 f"within {args.band:.0%}")
        peak = force / (strength * area)
        rg.check(0.9 <= peak <= 1.05,
                 f"{label}: peak force {force:.5g} N = {peak:.4f} x {strength_key} x area, "
                 f"within [0.9, 1.05]")
        rg.check(list(kinds) == [kind], f"{label}: every failure logged as kind {kind} "
                                        f"(got {list(kinds)})")
    # the bar of --case pulled apart statically: its right end moved far past the crack
    # opening in 20 load steps
    text = Path(args.case).read_text()
    gf, height = value(text, "fracture_energy"), value(text, "height")
    thickness = value(text, "thickness")
    static = re.sub(r"&run\b[^/]*/", "&run\n  analysis = 'static', t_end = 1.0, "
                    "output_file = 'static.h5', overwrite = .true.\n/\n&static\n  "
                    "load_steps = 20, tolerance = 1.0e-6\n/", text, count=1, flags=re.S)
    static, n = re.subn(r"velocity\s*=\s*[-+0-9.eE]+\s*,", "velocity = 1.0e-4,", static)
    if n != 1:
        raise SystemExit(f"{args.case}: expected one velocity")
    (work / "static.nml").write_text(static)
    if rg.run_ok(args, args.ranks[0], work / "static.nml", work, "static pull") is None:
        return
    with h5py.File(work / "static.h5", "r") as f:
        diss = float(f["history/energy/fracture"][-1])
    ratio = diss / (gf * height * thickness)
    rg.check(abs(ratio - 1.0) <= args.band,
             f"static pull in 20 load steps: dissipated {diss:.5g} J = {ratio:.4f} x Gf h t, "
             f"within {args.band:.0%}")


def history_keys(f: h5py.File) -> list[str]:
    """Every dataset under /history, and the last frame's datasets."""
    keys: list[str] = []
    f["history"].visititems(lambda n, o: keys.append("history/" + n)
                            if isinstance(o, h5py.Dataset) else None)
    last = sorted(k for k in f["frames"] if k.startswith("frame_"))[-1]
    keys += [f"frames/{last}/{k}" for k in f[f"frames/{last}"]
             if isinstance(f[f"frames/{last}/{k}"], h5py.Dataset)]
    return sorted(keys)


def compare(ref: Path, other: Path, what: str) -> None:
    """Check that the histories and last frames of two outputs are bitwise equal."""
    with h5py.File(ref, "r") as a, h5py.File(other, "r") as b:
        keys = history_keys(a)
        rg.check(keys == history_keys(b), f"{what}: the same datasets ({len(keys)})")
        for k in keys:
            if k not in b:
                continue
            rg.check(np.array_equal(a[k][:], b[k][:]), f"{what}: {k} bitwise")
        rg.check(a["history/energy/fracture"][-1] > 0.0, f"{what}: the run dissipates energy")


def cmd_ranks(args: argparse.Namespace) -> None:
    """The same run on several rank counts."""
    work = rg.scratch("fracture_ranks")
    for n in args.ranks:
        nml = variant(Path(args.case), work / f"np{n}.nml", f"np{n}.h5", t_end=args.t_end)
        if rg.run_ok(args, n, nml, work, f"run on {n} ranks") is None:
            return
    for n in args.ranks[1:]:
        compare(work / f"np{args.ranks[0]}.h5", work / f"np{n}.h5",
                f"{n} ranks against {args.ranks[0]}")


def cmd_restart(args: argparse.Namespace) -> None:
    """Checkpoint while the crack opens, continue, compare with the uninterrupted run."""
    work = rg.scratch("fracture_restart")
    first = args.ranks[0]
    full = variant(Path(args.case), work / "full.nml", "full.h5", t_end=args.t_end)
    part = variant(Path(args.case), work / "a.nml", "a.h5", t_end=args.t_end,
                   run_extra=f"checkpoint_interval = {args.checkpoint!r}")
    if rg.run_ok(args, first, full, work, f"uninterrupted run on {first} ranks") is None:
        return
    p = rg.run_ok(args, first, part, work, f"run with checkpoints on {first} ranks")
    if p is None:
        return
    marks = [line for line in p.stdout.splitlines() if line.startswith("checkpoint:")]
    rg.check(len(marks) >= 1, f"checkpoints written: {len(marks)}")
    with h5py.File(work / "full.h5", "r") as f:
        t = f["history/time"][:]
        d = f["history/energy/fracture"][:]
    t_end = args.t_end if args.t_end is not None else value(Path(args.case).read_text(), "t_end")
    # the last checkpoint must fall while damage grows, so that its state matters
    t_chk = args.checkpoint * int(t_end / args.checkpoint - 1e-9)
    grows = d[np.searchsorted(t, t_chk)] > 0.0 and d[-1] > d[np.searchsorted(t, t_chk)]
    rg.check(bool(grows), f"the last checkpoint (t = {t_chk:.3g} s) falls while the crack opens")
    for n in args.ranks:
        b = work / f"b{n}.h5"
        shutil.copy(work / "a.h5", b)
        nml = variant(Path(args.case), work / f"b{n}.nml", b.name, t_end=args.t_end,
                      run_extra="restart = 'a.chk'")
        if rg.run_ok(args, n, nml, work, f"continued on {n} ranks") is None:
            continue
        compare(work / "full.h5", b, f"continued on {n} ranks")


def main() -> int:
    """Parse arguments and run one check."""
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("check", choices=["grids", "ranks", "restart", "criteria"])
    ap.add_argument("--iem", required=True, help="path of the iem executable")
    ap.add_argument("--mpiexec", required=True)
    ap.add_argument("--mpiexec-flags", default="", help="extra mpiexec flags, ';'-separated")
    ap.add_argument("--case", required=True, help="namelist of the bar")
    ap.add_argument("--ranks", type=int, nargs="+", default=[1])
    ap.add_argument("--nx", type=int, nargs="+", default=[20, 40, 80])
    ap.add_argument("--t-end", type=float, default=None,
                    help="end time of the runs (s; default: the case's)")
    ap.add_argument("--band", type=float, default=0.05,
                    help="grids: allowed relative error of the dissipated energy")
    ap.add_argument("--checkpoint", type=float, default=1.5e-3,
                    help="restart: checkpoint interval (s)")
    args = ap.parse_args()
    {"grids": cmd_grids, "ranks": cmd_ranks, "restart": cmd_restart,
     "criteria": cmd_criteria}[args.check](args)
    if rg.FAILURES:
        print(f"{len(rg.FAILURES)} check(s) failed")
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
