#!/usr/bin/env python3
"""Bitwise comparison of the current iem against a baseline build, scene by scene.

Runs every shipped scene (inputs/*.nml, or those named with --cases) with the baseline
executable and with the current one, on each rank count of --ranks (default 1 2 3), and
compares the two HDF5 outputs dataset by dataset: every dataset under /history, /frames
(each frame's fields, /frames/time and /frames/step) and /mesh must hold the same bits
(NaN counts as equal to NaN wherever both files have one). Attributes are not compared (the
version and the input file's text may differ by design). A dataset that the baseline wrote
and the current code did not is a difference; one that only the current code writes is
listed as new and not compared.

Usage (from the repository root; benchmarks/baseline.sh builds and prints the baseline):

    python tests/regression/compare_baseline.py --baseline "$(bash benchmarks/baseline.sh)" \
        --iem build/iem [--cases cantilever_elastic patch_tension] [--ranks 1 2 3] \
        [--tolerance '/history/energy/*=1e-12']
    python tests/regression/compare_baseline.py --files old.h5 new.h5 [--tolerance ...]
    python tests/regression/compare_baseline.py --self-test some_output.h5

--tolerance PATTERN=RTOL (repeatable; none by default) compares the datasets whose path
matches the shell pattern to a tolerance instead of bitwise: max |new - old| over the
dataset's largest magnitude <= RTOL (for a planned change of the order of global sums).
--integrator verlet (or rk4) runs the dynamic scenes with that integrator instead of the one
they name (the shipped ones use RK4; static scenes are left out).
--perturb-new 'OLD=>NEW' changes the current code's input only (a text substitution),
to show that a different input is caught; --self-test checks on copies of an output file
with one bit changed, a NaN, or a dataset removed, that each is caught.

Long scenes are shortened, the same way for both executables, so that each run takes
under about 20 s on one core of the development machine (SHORTEN below; --full runs them
as shipped). Prints one line per scene and rank count, 'identical' or the first differing
dataset (sorted by path) with its largest relative difference, then a summary; exit status
0 when everything matched, 1 on any difference or failed run, 2 on bad arguments.
"""
from __future__ import annotations

import argparse
import fnmatch
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parents[2]

# Text substitutions (OLD => NEW, each must occur once) that shorten a long scene for both
# executables; what is left still goes through every code path of the scene (loads, the
# nonlinear springs' reversals, several load steps, frames and history samples).
SHORTEN = {
    # 0.25 s of damped nonlinear dynamics (~140 s on one rank): the first swing (30 ms)
    "cantilever_nonlinear_dynamic": ["t_end = 0.25=>t_end = 0.03"],
    # 24 load steps to 1.2 kN (~50 s on one rank): 6 steps to 1.0 kN, as tests/CMakeLists.txt
    # does
    "cantilever_nonlinear_static": ["load_steps = 24=>load_steps = 6", "-1.2e5=>-1.0e5"],
    # 20 load steps to 4 kN (~14-28 s on one rank): 8 steps along the same ramp, as
    # tests/CMakeLists.txt does
    "simply_supported_nonlinear_static": ["load_steps = 20=>load_steps = 8"],
    # the concrete beams with fracture (2-3 min each on one rank): their elastic start (the
    # baseline before fracture refuses their fracture keys; a later baseline compares them)
    "concrete_cantilever_fracture": ["t_end = 0.6=>t_end = 0.15"],
    "concrete_beam_fracture": ["t_end = 0.8=>t_end = 0.1"],
}


@dataclass
class Outcome:
    """The comparison of two files: differences (failures), notes and tolerated datasets."""
    differences: list[tuple[str, float]] = field(default_factory=list)
    tolerated: list[tuple[str, float]] = field(default_factory=list)
    new_only: list[str] = field(default_factory=list)
    compared: int = 0


def datasets(f: h5py.File, groups: list[str]) -> dict[str, h5py.Dataset]:
    """Every dataset under the given top-level groups, by absolute path."""
    found: dict[str, h5py.Dataset] = {}
    for g in groups:
        if g not in f:
            continue
        f[g].visititems(lambda name, obj, g=g: found.__setitem__(f"/{g}/{name}", obj)
                        if isinstance(obj, h5py.Dataset) else None)
    return found


def same_bits(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Element-wise: the same bits, or NaN in both (for floating-point data)."""
    if a.dtype.kind == "f":
        ua = a.view(f"u{a.dtype.itemsize}")
        ub = b.view(f"u{b.dtype.itemsize}")
        return (ua == ub) | (np.isnan(a) & np.isnan(b))
    return a == b


def describe(path: str, a: np.ndarray, b: np.ndarray, same: np.ndarray) -> tuple[str, float]:
    """One line on how a dataset differs, and its largest difference relative to the largest
    magnitude of the baseline's dataset (inf where NaN or Inf appear in one file only)."""
    n_diff = int(np.count_nonzero(~same))
    first = np.unravel_index(int(np.argmin(same.ravel())), a.shape)
    idx = ",".join(str(int(i)) for i in first)
    if a.dtype.kind in "fiu":
        fa, fb = a.astype(np.float64), b.astype(np.float64)
        with np.errstate(invalid="ignore", over="ignore"):
            d = np.where(same, 0.0, np.abs(fa - fb))
        finite = np.isfinite(fa)
        scale = float(np.max(np.abs(fa[finite]))) if finite.any() else 0.0
        big = float(np.max(d)) if d.size else 0.0
        rel = big / scale if scale > 0 and np.isfinite(big) else (0.0 if big == 0 else np.inf)
        return (f"{path}: {n_diff} of {a.size} values differ, first at [{idx}] "
                f"{a[first].item()!r} vs {b[first].item()!r}; largest difference {big:.3e} = "
                f"{rel:.3e} relative", rel)
    return f"{path}: {n_diff} of {a.size} values differ, first at [{idx}]", np.inf


def compare_files(old: Path, new: Path, groups: list[str],
                  tolerances: list[tuple[str, float]]) -> Outcome:
    """Compare the datasets of two iem output files (old is the reference)."""
    out = Outcome()
    with h5py.File(old, "r") as fo, h5py.File(new, "r") as fn:
        do, dn = datasets(fo, groups), datasets(fn, groups)
        out.new_only = sorted(set(dn) - set(do))
        for path in sorted(do):
            out.compared += 1
            if path not in dn:
                out.differences.append((f"{path}: missing in the new file", np.inf))
                continue
            a, b = do[path][()], dn[path][()]
            a, b = np.asarray(a), np.asarray(b)
            if a.shape != b.shape or a.dtype != b.dtype:
                out.differences.append((f"{path}: shape/type {a.shape} {a.dtype} vs "
                                        f"{b.shape} {b.dtype}", np.inf))
                continue
            same = same_bits(a, b)
            if bool(np.all(same)):
                continue
            line, rel = describe(path, a, b, same)
            rtol = next((t for pat, t in tolerances if fnmatch.fnmatchcase(path, pat)), None)
            if rtol is not None and rel <= rtol:
                out.tolerated.append((f"{line} <= {rtol:g}", rel))
            else:
                out.differences.append((line + (f" > tolerance {rtol:g}" if rtol is not None
                                                else ""), rel))
    return out


def is_static(case: Path) -> bool:
    """Whether the scene is a static analysis."""
    return re.search(r"^\s*analysis\s*=\s*'static'", case.read_text(), re.M) is not None


def with_integrator(text: str, integrator: str) -> str:
    """The scene's text with its &run group naming the integrator (replaced or added)."""
    if re.search(r"\bintegrator\s*=", text):
        return re.sub(r"\bintegrator\s*=\s*'[^']*'", f"integrator = '{integrator}'", text,
                      count=1)
    return re.sub(r"^(\s*&run[^\n]*\n)", rf"\1  integrator = '{integrator}'\n", text, count=1,
                  flags=re.M)


def scene_input(case: Path, dst: Path, subs: list[str], integrator: str | None = None) -> None:
    """Write the scene with its output file renamed to out.h5, the substitutions made and,
    given, the integrator set."""
    text = case.read_text()
    if integrator:
        text = with_integrator(text, integrator)
    for sub in subs:
        old, new = sub.split("=>", 1)
        if text.count(old) != 1:
            raise SystemExit(f"compare_baseline: {case}: '{old}' must occur once (found "
                             f"{text.count(old)})")
        text = text.replace(old, new)
    lines = [ln for ln in text.splitlines() if "output_file" in ln]
    if len(lines) != 1:
        raise SystemExit(f"compare_baseline: {case}: expected one output_file line")
    start = lines[0].index("output_file")
    text = text.replace(lines[0], lines[0][:start] + "output_file = 'out.h5'", 1)
    dst.write_text(text)


def run(args: argparse.Namespace, exe: str, ranks: int, folder: Path) -> tuple[int, float, str]:
    """Run one executable on the scene in folder; exit status, wall time, output's end."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    cmd = [args.mpiexec, "-n", str(ranks), *args.mpiexec_flags.split(), exe, "case.nml"]
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, cwd=folder, env=env, text=True, capture_output=True,
                           timeout=args.timeout)
        rc, tail = p.returncode, (p.stdout[-1500:] + p.stderr[-1500:])
    except subprocess.TimeoutExpired:
        rc, tail = -1, f"timed out after {args.timeout} s"
    return rc, time.perf_counter() - t0, tail


def report(label: str, out: Outcome, verbose: bool) -> None:
    """Print one comparison's line (and, verbose, every differing dataset)."""
    extra = f"; new only (not compared): {', '.join(out.new_only)}" if out.new_only else ""
    if out.differences:
        worst = max(out.differences, key=lambda d: d[1])
        print(f"{label}: DIFFERENT in {len(out.differences)} of {out.compared} datasets; "
              f"first: {out.differences[0][0]}"
              + (f"; largest: {worst[0]}" if worst is not out.differences[0] else "")
              + extra, flush=True)
    elif out.tolerated:
        print(f"{label}: identical except {len(out.tolerated)} of {out.compared} datasets "
              f"within their tolerance{extra}", flush=True)
    else:
        print(f"{label}: identical ({out.compared} datasets{extra})", flush=True)
    if verbose:
        for line, _ in out.differences[1:] + out.tolerated:
            print(f"    {line}")


def parse_tolerances(items: list[str]) -> list[tuple[str, float]]:
    """PATTERN=RTOL items as (pattern, rtol) pairs."""
    pairs = []
    for item in items:
        pat, _, val = item.rpartition("=")
        try:
            pairs.append((pat if pat.startswith("/") else "/" + pat, float(val)))
        except ValueError:
            raise SystemExit(f"compare_baseline: --tolerance '{item}': expected PATTERN=RTOL")
    return pairs


def self_test(h5: Path, groups: list[str]) -> int:
    """Check that the comparison can fail: copies of an output file with one value changed
    in its last bit, set to NaN, or a dataset removed, must be found different, and the
    one-bit change accepted under a tolerance; the unchanged copy must be identical."""
    failures = 0
    with tempfile.TemporaryDirectory() as tmp:
        with h5py.File(h5, "r") as f:
            paths = sorted(p for p, d in datasets(f, groups).items()
                           if d.dtype.kind == "f" and d.size > 0)
        if not paths:
            raise SystemExit(f"compare_baseline: {h5} has no floating-point dataset")
        target = paths[len(paths) // 2]

        def variant(name: str, change) -> Path:
            dst = Path(tmp) / f"{name}.h5"
            shutil.copyfile(h5, dst)
            with h5py.File(dst, "r+") as f:
                change(f)
            return dst

        def flip(f: h5py.File) -> None:
            a = f[target][()]
            flat = a.reshape(-1).view(f"u{a.dtype.itemsize}")
            flat[flat.size // 2] ^= 1
            f[target][...] = a

        def nan(f: h5py.File) -> None:
            a = f[target][()]
            a.reshape(-1)[0] = np.nan
            f[target][...] = a

        cases = [("unchanged copy", variant("same", lambda f: None), [], False),
                 (f"last bit of one value of {target}", variant("flip", flip), [], True),
                 ("the same under a tolerance of 1e-12", Path(tmp) / "flip.h5",
                  [(target, 1e-12)], False),
                 (f"one value of {target} set to NaN", variant("nan", nan), [], True),
                 (f"{paths[0]} removed", variant("gone", lambda f: f.__delitem__(paths[0])),
                  [], True)]
        for what, path, tol, expect_diff in cases:
            out = compare_files(h5, path, groups, tol)
            ok = bool(out.differences) == expect_diff
            failures += not ok
            print(f"{'ok  ' if ok else 'FAIL'} {what}: "
                  f"{out.differences[0][0] if out.differences else 'no difference found'}")
    return 1 if failures else 0


def main() -> int:
    """Run and compare the scenes, or compare two given files."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--baseline", help="the baseline iem executable")
    ap.add_argument("--iem", default=str(ROOT / "build" / "iem"), help="the current iem")
    ap.add_argument("--cases", nargs="+", help="scene names (stems of inputs/*.nml) or paths")
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--tolerance", action="append", default=[], metavar="PATTERN=RTOL")
    ap.add_argument("--groups", nargs="+", default=["history", "frames", "mesh"])
    ap.add_argument("--full", action="store_true", help="run the scenes as shipped")
    ap.add_argument("--integrator", choices=["rk4", "verlet"],
                    help="run the dynamic scenes with this integrator (static ones left out)")
    ap.add_argument("--perturb-new", action="append", default=[], metavar="OLD=>NEW",
                    help="substitution in the current code's input only (to test the test)")
    ap.add_argument("--files", nargs=2, metavar=("OLD_H5", "NEW_H5"),
                    help="only compare two existing output files")
    ap.add_argument("--self-test", metavar="H5",
                    help="check on copies of this output file that changes are caught")
    ap.add_argument("--mpiexec", default="mpirun")
    ap.add_argument("--mpiexec-flags", default="", help="extra flags, space-separated")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per run")
    ap.add_argument("--work", help="folder for the runs (default: a temporary one, removed)")
    ap.add_argument("-v", "--verbose", action="store_true", help="list every difference")
    args = ap.parse_args()
    tolerances = parse_tolerances(args.tolerance)

    if args.self_test:
        return self_test(Path(args.self_test), args.groups)
    if args.files:
        out = compare_files(Path(args.files[0]), Path(args.files[1]), args.groups, tolerances)
        report(f"{args.files[0]} vs {args.files[1]}", out, args.verbose)
        return 1 if out.differences else 0
    if not args.baseline:
        ap.error("--baseline (or --files) is required")
    exes = {"old": str(Path(args.baseline).resolve()), "new": str(Path(args.iem).resolve())}
    for exe in exes.values():
        if not os.access(exe, os.X_OK):
            ap.error(f"{exe} is not an executable")
    if args.cases:
        cases = [Path(c) if c.endswith(".nml") else ROOT / "inputs" / f"{c}.nml"
                 for c in args.cases]
    else:
        cases = sorted((ROOT / "inputs").glob("*.nml"))
    for c in cases:
        if not c.is_file():
            ap.error(f"no scene {c}")
    if args.integrator:
        left = [c.stem for c in cases if is_static(c)]
        if left:
            print(f"static scenes left out (--integrator): {' '.join(left)}", flush=True)
        cases = [c for c in cases if not is_static(c)]

    work = Path(args.work) if args.work else Path(tempfile.mkdtemp(prefix="iem_compare_"))
    print(f"baseline {exes['old']}\ncurrent  {exes['new']}\nranks {args.ranks}; tolerances "
          f"{args.tolerance or 'none (all bitwise)'}", flush=True)
    t_all = time.perf_counter()
    failed: list[str] = []
    try:
        for case in cases:
            subs = [] if args.full else SHORTEN.get(case.stem, [])
            if subs:
                print(f"{case.stem}: shortened: {'; '.join(subs)}", flush=True)
            for n in args.ranks:
                label = f"{case.stem} on {n} rank{'s' if n > 1 else ''}"
                files, times = {}, {}
                for which, exe in exes.items():
                    folder = work / case.stem / f"np{n}" / which
                    shutil.rmtree(folder, ignore_errors=True)
                    folder.mkdir(parents=True)
                    scene_input(case, folder / "case.nml",
                                subs + (args.perturb_new if which == "new" else []),
                                args.integrator)
                    rc, times[which], tail = run(args, exe, n, folder)
                    if rc != 0:
                        print(f"{label}: the {which} run failed (exit status {rc}):\n{tail}",
                              flush=True)
                        break
                    files[which] = folder / "out.h5"
                if len(files) < 2:
                    failed.append(label)
                    continue
                out = compare_files(files["old"], files["new"], args.groups, tolerances)
                report(f"{label} ({times['old']:.1f} s old, {times['new']:.1f} s new)", out,
                       args.verbose)
                if out.differences:
                    failed.append(label)
    finally:
        if not args.work:
            shutil.rmtree(work, ignore_errors=True)
    total = len(cases) * len(args.ranks)
    print(f"summary: {total - len(failed)} of {total} identical"
          + (f"; different or failed: {', '.join(failed)}" if failed else "")
          + f"; {time.perf_counter() - t_all:.0f} s in all", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
