#!/usr/bin/env python3
"""Regression checks of /history/reactions and /history/fracture (docs/output.md), called by
CTest (tests/CMakeLists.txt). Subcommands:

  bar        the bar pulled apart (tests/data/fracture_bar_history.nml) on several rank counts: the
             reactions, events and fragments bitwise the same; the pull reaction peaks at the
             tensile strength times the section; the bar ends in two fragments; the events
             are tension failures in canonical order; a pre-cut column is logged once at
             t = 0 (kind 4) and splits the bar from the start
  restart    the bar interrupted at a checkpoint (before and after it breaks) and continued:
             its reactions, events and fragments equal the uninterrupted run's, bitwise (also
             with velocity Verlet and stiffness damping, --sub: the reactions of the step a
             run continues from are the checkpointed ones, not those of the integrator's
             resume)
  reactions  a static case (inputs/cantilever_static.nml): the clamp's reaction balances
             the applied load within what the relaxation's tolerance allows
"""
from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import regress as rg  # noqa: E402

FT, AREA = 3.0e6, 0.01 * 0.01          # tensile strength (Pa), bar section (m^2)
SERIES = ("reactions", "fracture")     # the groups under /history these checks cover


def series_of(path: Path) -> dict[str, np.ndarray]:
    """Every dataset under /history/reactions and /history/fracture, by path."""
    out: dict[str, np.ndarray] = {}
    with h5py.File(path, "r") as f:
        for group in SERIES:
            if group in f["history"]:
                f["history"][group].visititems(
                    lambda name, obj, g=group: out.__setitem__(f"{g}/{name}", obj[:])
                    if isinstance(obj, h5py.Dataset) else None)
    return out


def same_series(a: dict, b: dict, what: str) -> None:
    """The same datasets, bitwise."""
    rg.check(sorted(a) == sorted(b), f"{what}: the same datasets ({len(a)})")
    bad = [k for k in a if k in b and not (a[k].dtype == b[k].dtype and
                                           np.array_equal(a[k], b[k]))]
    rg.check(not bad, f"{what}: bitwise equal" + (f" (differ: {bad})" if bad else ""))


def bar_case(work: Path, name: str, subs: list[str]) -> Path:
    """The bar's namelist in work, writing name.h5, with OLD=>NEW substitutions."""
    nml = rg.with_output(Path(rg_args.case), work / f"{name}.nml", f"{name}.h5")
    rg.substitute(nml, rg_args.sub + subs)
    return nml


def cmd_bar(args: argparse.Namespace) -> None:
    """The bar on args.ranks rank counts, then pre-cut (see the module's doc)."""
    work = rg.scratch("fracture_bar" + rg.sub_tag(args.sub))
    runs = {}
    for n in args.ranks:
        if rg.run_ok(args, n, bar_case(work, f"np{n}", []), work, f"bar on {n} ranks"):
            runs[n] = series_of(work / f"np{n}.h5")
    if len(runs) != len(args.ranks):
        return
    ref = runs[args.ranks[0]]
    for n in args.ranks[1:]:
        same_series(ref, runs[n], f"{n} ranks against {args.ranks[0]}")
    with h5py.File(work / f"np{args.ranks[0]}.h5", "r") as f:
        time = f["history/time"][:]
        n_nodes = len(f["mesh/coordinates"])
        names = sorted(f["history/reactions"])
        bcs = {k: f["history/reactions"][k].attrs["bcs"].decode() for k in names}
    rg.check(names == ["bottom", "left", "pull"] and bcs == {"left": "1", "bottom": "2",
                                                              "pull": "3"},
             f"one reaction series a &bc, named as the &bc, with its index: {bcs}")
    pull, left = ref["reactions/pull"], ref["reactions/left"]
    rg.check(pull.shape == (len(time), 2), f"reactions (n_samples, 2): {pull.shape}")
    peak = float(pull[:, 0].max())
    rg.check(abs(peak / (FT * AREA) - 1.0) < 0.03,
             f"pull reaction peaks at {peak:.2f} N, tensile strength x section "
             f"{FT * AREA:.1f} N (within 3%)")
    rg.check(bool(np.all(pull[:, 1] == 0.0)) and bool(np.all(left[:, 1] == 0.0)),
             "no y reaction where the &bc prescribes x only")
    rg.check(abs(pull[-1, 0]) < 0.05 * peak and abs(left[-1, 0]) < 0.05 * peak,
             f"once broken the supports hold no load: {pull[-1, 0]:.2f}, {left[-1, 0]:.2f} N")
    # the left support holds the pull (minus inertia): the same peak, opposite sign
    rg.check(abs(float(-left[:, 0].min()) / peak - 1.0) < 0.05,
             f"left reaction peaks at {-left[:, 0].min():.2f} N against the pull")
    frag, big = ref["fracture/fragments"], ref["fracture/largest_fragments"]
    rg.check(frag.shape == time.shape and big.shape == (len(time), 5),
             f"fragments {frag.shape}, largest_fragments {big.shape}")
    rg.check(frag[0] == 1 and frag[-1] == 2 and bool(np.all(np.diff(frag) >= 0)),
             f"one piece at first, two at the end, never fewer ({frag[0]} -> {frag[-1]})")
    rg.check(int(big[-1].sum()) == n_nodes and big[-1, 0] >= big[-1, 1] > 0 and
             bool(np.all(big[-1, 2:] == 0)),
             f"largest fragments {big[-1].tolist()} hold all {n_nodes} nodes")
    rg.check(bool(np.all(big[frag == 1, 0] == n_nodes)), "one fragment: all nodes in it")
    t, kind = ref["fracture/events/time"], ref["fracture/events/kind"]
    cell, spring = ref["fracture/events/cell"], ref["fracture/events/spring"]
    x, y = ref["fracture/events/x"], ref["fracture/events/y"]
    rg.check(len(t) > 0 and bool(np.all(kind == 1)),
             f"{len(t)} events, all tension failures (kinds {sorted(set(kind.tolist()))})")
    order = np.lexsort((spring, cell, t))
    rg.check(bool(np.all(order == np.arange(len(t)))), "events sorted by (time, cell, spring)")
    keys = cell.astype(np.int64) * 8 + spring
    rg.check(len(np.unique(keys)) == len(keys), "each spring fails once")
    rg.check(bool(np.all((spring >= 0) & (spring <= 7))) and
             bool(np.all((t > 0) & (t <= time[-1]))),
             "events: springs 0-7, times within the run")
    # the count changes only at samples that logged failures (since the previous sample)
    changed = np.flatnonzero(np.diff(frag)) + 1
    logged = [bool(np.any((t > time[i - 1]) & (t <= time[i]))) for i in changed]
    rg.check(len(changed) > 0 and all(logged),
             f"the fragments change at samples {time[changed].tolist()} s, each with failures "
             f"logged since the previous sample")
    # edge events lie at the centres of the failed edges: on the grid's half lines
    lx, ly = 0.005, 0.005
    edge = spring < 4
    on_grid = np.isclose((x[edge] / (lx / 2)) % 1, 0) | np.isclose((x[edge] / (lx / 2)) % 1, 1)
    rg.check(bool(np.all(on_grid)) and bool(np.all(np.isclose(y[edge] / (ly / 2),
                                                               np.round(y[edge] / (ly / 2))))),
             "edge events at edge centres")

    # pre-cut: a column of cells cut at x = 0.05 m: the bar is in two pieces from t = 0, each
    # cut spring logged once, at the t = 0 sample, kind 4
    cut = "&shape kind = 'rectangle', box = 0.051, 0.054, 0.0, 0.01, material = 'crack' /\n&bc"
    runs = {}
    for n in (1, args.ranks[-1]):
        nml = bar_case(work, f"cut{n}", [f"&bc\n  name = 'left'=>{cut}\n  name = 'left'"])
        if rg.run_ok(args, n, nml, work, f"pre-cut bar on {n} ranks"):
            runs[n] = series_of(work / f"cut{n}.h5")
    if len(runs) != 2:
        return
    same_series(runs[1], runs[args.ranks[-1]], f"pre-cut bar: {args.ranks[-1]} ranks against 1")
    c = runs[1]
    pre = c["fracture/events/kind"] == 4
    rg.check(int(pre.sum()) == 8 and bool(np.all(c["fracture/events/time"][pre] == 0.0)),
             f"pre-cut: 8 edge springs (2 cells) logged at t = 0 with kind 4 ({int(pre.sum())})")
    rg.check(sorted(set(c["fracture/events/spring"][pre].tolist())) == [0, 1, 2, 3] and
             bool(np.all(np.isclose(c["fracture/events/x"][pre], [0.0525, 0.055, 0.0525, 0.05]
                                    * 2))),
             "pre-cut events at the centres of the cut cells' edges")
    rg.check(bool(np.all(c["fracture/fragments"] == 2)), "pre-cut: two fragments throughout")


def cmd_restart(args: argparse.Namespace) -> None:
    """Interrupted at a checkpoint and continued (see the module's doc)."""
    work = rg.scratch("fracture_restart" + rg.sub_tag(args.sub))
    n = args.ranks[0]
    if not rg.run_ok(args, n, bar_case(work, "full", []), work, f"uninterrupted bar on {n} ranks"):
        return
    full = series_of(work / "full.h5")
    t_break = float(full["fracture/events/time"].min())
    for label, every in (("before", 2.5e-3), ("after", 3.5e-3)):
        interval = f"output_interval = 5.0e-4, checkpoint_interval = {every}"
        a = bar_case(work, f"a_{label}", [f"output_interval = 5.0e-4=>{interval}"])
        if not rg.run_ok(args, n, a, work, f"bar with a checkpoint at {every} s"):
            continue
        rg.check((every < t_break) == (label == "before"),
                 f"checkpoint at {every} s is {label} the break at {t_break:.4e} s")
        for m in args.ranks:
            b = f"b_{label}_{m}"
            shutil.copy(work / f"a_{label}.h5", work / f"{b}.h5")
            nml = bar_case(work, b, [f"output_interval = 5.0e-4=>{interval}, "
                                     f"restart = 'a_{label}.chk', checkpoint_file = '{b}.chk'"])
            # the copied output runs on past the checkpoint: continuing cuts it back first
            if rg.run_ok(args, m, nml, work, f"continued from {label} the break on {m} ranks"):
                same_series(full, series_of(work / f"{b}.h5"),
                            f"continued from {label} the break on {m} ranks against uninterrupted")


def cmd_reactions(args: argparse.Namespace) -> None:
    """A static case: the reactions balance the applied loads. With the residual r on the
    free dofs, sum(R) = -sum(f_ext) + sum(r) and |sum(r)| <= sqrt(n_free) ||r|| <=
    sqrt(n_free) x residual x F_ref, F_ref = ||f_ext|| <= the total load P."""
    work = rg.scratch("reactions_" + Path(args.case).stem)
    nml = rg.with_output(Path(args.case), work / "static.nml", "static.h5")
    if not rg.run_ok(args, args.ranks[0], nml, work, "static run"):
        return
    with h5py.File(work / "static.h5", "r") as f:
        clamp = f["history/reactions/clamp"][:]
        lf = f["history/static/load_factor"][:]
        res = f["history/static/residual"][:]
        n_nodes = len(f["mesh/coordinates"])
        names = sorted(f["history/reactions"])
    rg.check(names == ["clamp"], f"one reaction series, the clamp's ({names})")
    load = 1.0e5 * 0.1 * 0.1 * lf           # the shear traction on the free end, downwards
    bound = np.sqrt(2.0 * n_nodes) * res * load + 1e-6
    err_y = np.abs(clamp[:, 1] - load)
    err_x = np.abs(clamp[:, 0])
    print("clamp reaction y:", clamp[:, 1].tolist(), "load:", load.tolist())
    rg.check(bool(np.all(err_y <= bound)),
             f"the clamp holds the load: |R_y - P| = {err_y.max():.2e} N <= "
             f"{bound[1:].min():.2e} N (relative {(err_y[1:] / load[1:]).max():.1e})")
    rg.check(bool(np.all(err_x <= bound)), f"no net horizontal reaction ({err_x.max():.2e} N)")


def main() -> int:
    global rg_args
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("check", choices=["bar", "restart", "reactions"])
    ap.add_argument("--iem", required=True, help="path of the iem executable")
    ap.add_argument("--mpiexec", required=True)
    ap.add_argument("--mpiexec-flags", default="", help="extra mpiexec flags, ';'-separated")
    ap.add_argument("--case", required=True, help="namelist")
    ap.add_argument("--ranks", type=int, nargs="+", default=[1])
    ap.add_argument("--sub", action="append", default=[],
                    help="OLD=>NEW substitution in the bar's namelist (repeatable; \\n: newline)")
    rg_args = args = ap.parse_args()
    {"bar": cmd_bar, "restart": cmd_restart, "reactions": cmd_reactions}[args.check](args)
    if rg.FAILURES:
        print(f"{len(rg.FAILURES)} check(s) failed")
        return 1
    print("all checks passed")
    return 0


rg_args: argparse.Namespace
if __name__ == "__main__":
    sys.exit(main())
