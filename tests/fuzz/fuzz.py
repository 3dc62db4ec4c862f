#!/usr/bin/env python3
"""Input fuzzer: mutated namelists against the rule every run of iem must obey.

A run either does what its input says (exit 0, its output written and marked complete = 1),
or refuses before it touches any file, with exactly one `iem: error:` line on stderr naming
the group, the variable or the file, and a documented exit status (2 refused, 3 run failed,
4 stopped by a signal after a checkpoint). Never a signal, a Fortran runtime error or
backtrace, a hang, a silently different run, or a created, changed or removed file when it
refuses.

Each shipped scene (inputs/*.nml) is first shrunk to a cheap base (a coarse grid, a short
t_end, two load steps) that must run to completion. Each case then applies one mutation,
chosen with a fixed seed (case k of seed s is the same on every machine), to one base, and
runs iem in a folder of its own seeded with an existing output file, its .xmf sidecar and a
checkpoint file (any bytes) under the names the input gives. Every file there is
checksummed before and after. What is acceptable is decided per case:

  * exit 0 and a complete output, with only that run's own output, sidecar and checkpoint
    changed or created; not for a mutation the documentation says must be refused
    (a non-finite or out-of-range value, a wrong-typed or empty value, an unknown key, ...);
  * a refusal: exit 2 (or 3), exactly one `iem: error:` line (rank 0 only), every file as
    it was;
  * exit 3 after the run started (a guard stopped it): one error line, only the run's own
    files changed, its output marked incomplete; not for a mutation that must be refused;
  * still running after the per-case time limit: SIGTERM to mpirun, then SIGKILL; counted
    as a "long valid run" when it printed no error and the mutation need not be refused.

Usage (CTest runs the first form, and `--long` under label long):
  fuzz.py --iem build/iem --mpiexec mpirun [--mpiexec-flags=--oversubscribe]
  fuzz.py ... --long                 thousands of cases
  fuzz.py ... --seed 7 --cases 500   another seed, another count
  fuzz.py ... --case 123 --keep      one case (its folder is kept and printed)
  fuzz.py ... --list                 print the cases (mutations) without running them

Failing inputs are saved under <work>/failures (work: ./fuzz_work, the build's test folder
under CTest) with a note of the mutation and the setup, to rerun by hand.
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import hashlib
import os
import re
import shutil
import signal
import stat as st
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mutations import (INPUT_NAME, Base, Case, load_bases, make_case, run_files,  # noqa: E402
                       sidecar_of)


# failure markers: a Fortran runtime error, a backtrace, a signal, an MPI abort
FORBIDDEN = ["Error termination", "Backtrace", "Program received signal", "At line ",
             "Fortran runtime error", "Fortran runtime warning", "MPI_ABORT", "Segmentation",
             "core dumped", "HDF5-DIAG", "ERROR STOP", "STOP "]
# a guard that fires on the initial state or a NaN stability limit: the input overflowed in
# setup, which should have refused it
SETUP_OVERFLOW = re.compile(r"stability limit (NaN|[-+]?Inf)|at step 0\b|step 0/|"
                            r"dt = (NaN|[-+]?Inf)", re.I)
# what a refusal's message must name: a group (&run, ...), a quoted value or path, a file
NAMES = re.compile(r"&(run|geometry|material|shape|damping|bc|load|probe|static|initial)\b|'[^']*'|"
                   r"\bfile\b|\.nml: line \d+")
MPIRUN_NOISE = re.compile(
    r"^(-{20,}|Primary job\s+terminated normally|a non-zero exit code|"
    r"(mpirun|mpiexec|orterun|prterun) (detected|noticed|has exited)|"
    r"the job to be terminated|\s+Process name:|\s+Exit code:|\s*$|Per user-direction)")


# ---- running a case ------------------------------------------------------------------------
def snapshot(folder: Path) -> dict[str, str]:
    """Every entry under folder: kind and content hash (files), target (links)."""
    snap = {}
    for dirpath, dirnames, filenames in os.walk(folder):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            rel = str(p.relative_to(folder))
            s = os.lstat(p)
            if st.S_ISLNK(s.st_mode):
                snap[rel] = "link:" + os.readlink(p)
            elif st.S_ISDIR(s.st_mode):
                snap[rel] = "dir"
            elif st.S_ISREG(s.st_mode):
                h = hashlib.sha256()
                with open(p, "rb") as f:
                    for chunk in iter(lambda: f.read(1 << 20), b""):
                        h.update(chunk)
                snap[rel] = "file:" + h.hexdigest()[:16]
            else:
                snap[rel] = "special:" + oct(s.st_mode)
    return snap


def diff(before: dict, after: dict) -> list[str]:
    out = []
    for k in sorted(set(before) | set(after)):
        if k not in after:
            out.append(f"removed {k}")
        elif k not in before:
            out.append(f"created {k}")
        elif before[k] != after[k]:
            out.append(f"changed {k}")
    return out


def complete_flag(path: Path):
    """The root attribute `complete` of an output file (None: unreadable or absent)."""
    try:
        import h5py
    except ImportError:
        with open(path, "rb") as f:
            return 1 if f.read(8) == b"\x89HDF\r\n\x1a\n" else None
    try:
        with h5py.File(path, "r") as f:
            return int(f.attrs.get("complete", 0))
    except (OSError, ValueError, KeyError):
        return None


def probe_exists(path: Path, name: str) -> bool:
    try:
        import h5py
        with h5py.File(path, "r") as f:
            return f"history/probes/{name}" in f
    except Exception:  # noqa: BLE001 - any failure to read is a missing probe
        return False


@dataclass
class Result:
    case: Case
    rc: int
    seconds: float
    timed_out: bool
    stderr: str
    stdout: str
    changes: list
    problems: list
    outcome: str            # ok-complete | refused | run-failed | long-run | FAIL
    folder: Path


OUTSIDE_LOCK = threading.Lock()


def prepare(c: Case, folder: Path, base: Base) -> Path:
    """Make the case's folder: the input, the seeded files, the special files."""
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    data = c.data.replace(b"{folder}", folder.name.encode())
    (folder / INPUT_NAME).write_bytes(data)
    text = data.decode("utf-8", "surrogateescape")  # file names keep their bytes
    names = set()
    for t in (base.text, text):
        try:
            names.update(run_files(t).values())
        except Exception:  # noqa: BLE001 - a garbled input names what it names
            pass
    for item in c.setup:
        p = folder / item[1]
        if item[0] == "dir":
            p.mkdir(parents=True, exist_ok=True)
        elif item[0] == "fifo":
            os.mkfifo(p)
        elif item[0] == "file":
            p.write_bytes(item[2])
        elif item[0] == "symlink":
            os.symlink(item[2], p)
    for n in sorted(names):
        if not n.strip() or n.startswith("/") or "\x00" in n or len(n) > 200:
            continue
        p = folder / n
        try:
            if p.resolve().parent != folder.resolve() or os.path.lexists(p):
                continue
            p.write_bytes(f"existing {n}: must not change unless this run writes it\n"
                          .encode("utf-8", "surrogateescape"))
        except OSError:
            pass
    return folder / INPUT_NAME


def own_files(c: Case, folder: Path, text: str) -> set[str]:
    """The entries (relative to the folder) a run of this input may write."""
    try:
        f = run_files(text)
    except Exception:  # noqa: BLE001
        return set()
    out = set()
    for p in f.values():
        q = Path(os.path.normpath(folder / p.replace("\n", "")))
        try:
            out.add(str(q.relative_to(folder)))
        except ValueError:
            pass
    return out


def evaluate(c: Case, folder: Path, rc: int, timed_out: bool, stderr: str,
             before: dict, after: dict, text: str) -> tuple[str, list[str], list[str]]:
    """The outcome of a case and what, if anything, is wrong with it."""
    problems = []
    changes = diff(before, after)
    lines = stderr.splitlines()
    errors = [l for l in lines if l.startswith("iem: error:")]
    stray = [l for l in lines if not l.startswith(("iem: error:", "iem: warning:"))
             and not MPIRUN_NOISE.match(l)]
    for marker in FORBIDDEN:
        if marker in stderr:
            problems.append(f"stderr has '{marker.strip()}'")
            break
    own = own_files(c, folder, text)
    foreign = [ch for ch in changes if ch.split(" ", 1)[1] not in own]
    if c.kind == "out.long_creatable":
        own_path = "/".join(["d" * 200] * 6) + "/long_out.h5"
        own |= {own_path, sidecar_of(own_path)}
        foreign = [ch for ch in changes if ch.split(" ", 1)[1] not in own]
    if timed_out and errors and rc in (2, 3):
        timed_out = False   # it failed just at the time limit: judge it as it ended
    if timed_out:
        if errors:
            problems.append("still running after printing an error")
        if c.must_refuse:
            problems.append(f"not refused ({c.must_refuse}): still running at the time limit")
        if foreign:
            problems.append("files outside its own changed")
        return ("long-run" if not problems else "FAIL"), problems, changes
    if rc < 0 or rc >= 128:
        problems.append(f"exit status {rc} (a signal)")
    elif rc not in (0, 2, 3, 4):
        problems.append(f"exit status {rc} (undocumented)")
    if rc == 0:
        if errors:
            problems.append("exit 0 with an error line")
        if c.must_refuse:
            problems.append(f"accepted ({c.must_refuse}): ran to exit 0")
        outp = folder / run_files(text)["output"].replace("\n", "") \
            if c.kind != "out.long_creatable" else folder / ("/".join(["d" * 200] * 6)
                                                             + "/long_out.h5")
        try:
            flag = complete_flag(outp) if outp.is_file() else None
        except ValueError:  # a NUL byte in the name: no such file can exist
            flag = None
        if flag != 1:
            problems.append(f"exit 0 but {outp.name} is not a complete output (complete={flag})")
        if c.probe_name and not probe_exists(outp, c.probe_name):
            problems.append(f"probe '{c.probe_name}' missing from the output")
        if foreign:
            problems.append("files other than its own output/sidecar/checkpoint changed")
        return ("ok-complete" if not problems else "FAIL"), problems, changes
    if len(errors) != 1:
        problems.append(f"{len(errors)} 'iem: error:' lines (want 1)")
    elif not timed_out and rc in (2, 3) and not changes and not NAMES.search(errors[0]):
        problems.append("the error names no group, variable or file")
    if stray and not problems:
        problems.append(f"stray stderr line: {stray[0][:100]!r}")
    if rc == 2 or (rc == 3 and not changes):
        if changes:
            problems.append("refused after touching files")
        if rc == 3 and c.must_refuse and not problems:
            problems.append(f"refused with exit 3 ({c.must_refuse}; bad input is exit 2)")
        return ("refused" if not problems else "FAIL"), problems, changes
    if rc == 3:
        if c.must_refuse:
            problems.append(f"not refused ({c.must_refuse}): started and failed (exit 3)")
        elif errors and SETUP_OVERFLOW.search(errors[0]):
            problems.append("accepted, then non-finite at the start (stability limit or "
                            "initial state): setup must refuse it")
        if foreign:
            problems.append("files other than its own output/sidecar/checkpoint changed")
        outp = folder / run_files(text)["output"].replace("\x00", "")
        if outp.is_file() and complete_flag(outp) == 1:
            problems.append("exit 3 but the output is marked complete")
        return ("run-failed" if not problems else "FAIL"), problems, changes
    if rc == 4:
        problems.append("exit 4 without a signal")
    return "FAIL", problems, changes


def kill_strays(folder: Path) -> None:
    """End processes of ours left running in the case folder (by pid, found by their cwd)."""
    for pid_dir in Path("/proc").iterdir():
        if not pid_dir.name.isdigit():
            continue
        try:
            if os.readlink(pid_dir / "cwd") == str(folder):
                os.kill(int(pid_dir.name), signal.SIGKILL)
        except OSError:
            pass


def run_case(args, c: Case, base: Base, work: Path, limit: float) -> Result:
    folder = (work / "cases" / f"c{c.index:06d}").resolve()
    nml = prepare(c, folder, base)
    text = nml.read_bytes().decode("utf-8", "surrogateescape")
    before = snapshot(folder)
    outside_before = {p: os.path.lexists(p) for p in c.outside}
    cmd = [args.mpiexec, "-n", str(c.ranks)] + [f for f in args.mpiexec_flags.split(";") if f]
    cmd += [args.iem, INPUT_NAME]
    shell = f"ulimit -v {args.mem_mb * 1024} 2>/dev/null; ulimit -c 0; exec \"$@\""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    env.setdefault("OMPI_MCA_odls_base_sigkill_timeout", "0")
    # the run's own temporary folder: Open MPI makes and removes its session directories
    # under $TMPDIR/ompi.<host>.<uid>, and two runs at once sharing that folder can race on it
    # (orte_init failing with "A call to mkdir was unable to create ... File exists")
    session = (work / "tmp" / f"c{c.index:06d}").resolve()
    session.mkdir(parents=True, exist_ok=True)
    env["TMPDIR"] = str(session)
    lock = OUTSIDE_LOCK if c.outside else None
    if lock:
        lock.acquire()
    try:
        t0 = time.monotonic()
        p = subprocess.Popen(["sh", "-c", shell, "sh"] + cmd, cwd=folder, env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             start_new_session=True)
        timed_out = False
        try:
            out, err = p.communicate(timeout=limit)
        except subprocess.TimeoutExpired:
            timed_out = True
            p.send_signal(signal.SIGTERM)
            try:
                out, err = p.communicate(timeout=5)
            except subprocess.TimeoutExpired:
                try:
                    os.killpg(p.pid, signal.SIGKILL)
                except OSError:
                    pass
                out, err = p.communicate()
        seconds = time.monotonic() - t0
        kill_strays(folder)
        after = snapshot(folder)
        stderr = err.decode("utf-8", "replace")
        outcome, problems, changes = evaluate(c, folder, p.returncode, timed_out, stderr,
                                              before, after, text)
        for path, existed in outside_before.items():
            if not existed and os.path.lexists(path):
                changes.append(f"created {path}")
                if outcome in ("refused", "FAIL"):
                    problems.append(f"created {path}")
                    outcome = "FAIL"
                os.remove(path)
    finally:
        if lock:
            lock.release()
        shutil.rmtree(session, ignore_errors=True)
    return Result(c, p.returncode, seconds, timed_out, stderr,
                  out.decode("utf-8", "replace"), changes, problems, outcome, folder)


# ---- the run -------------------------------------------------------------------------------
def check_bases(args, bases: list[Base], work: Path) -> list[str]:
    """Each base must run to a complete output; measures how long each takes."""
    bad = []
    for i, b in enumerate(bases):
        c = Case(-1 - i, b.name, "base", "the base itself", b.text.encode())
        res = run_case(args, c, b, work, limit=60)
        b.seconds = res.seconds
        if res.outcome != "ok-complete":
            bad.append(f"base {b.name}: {res.outcome} exit {res.rc}: {res.problems} "
                       f"{res.stderr.strip()[-500:]}")
        shutil.rmtree(res.folder, ignore_errors=True)
    return bad


def failure_class(res: Result) -> str:
    c = res.case
    where = f"&{c.group} {c.key}" if c.group and c.kind.startswith(("value", "key")) else \
        (f"&{c.group}" if c.group and c.kind.startswith("group") else "")
    why = res.problems[0]
    why = re.sub(r"\d+ 'iem", "N 'iem", why) if "want 1" in why else why
    why = re.sub(r"stray stderr line: .*", "stray stderr output", why)
    why = re.sub(r"exit 0 but .* is not", "exit 0 but output is not", why)
    return f"{c.kind} {where}: {why}".replace("  ", " ")


def report_failure(res: Result, failures_dir: Path) -> None:
    c = res.case
    name = f"case{c.index:06d}_{c.base}_{c.kind}"
    failures_dir.mkdir(parents=True, exist_ok=True)
    nml = res.folder / INPUT_NAME
    (failures_dir / f"{name}.nml").write_bytes(nml.read_bytes() if nml.is_file() else c.data)
    note = (f"case {c.index} (base {c.base}, {c.ranks} rank(s)): {c.kind}: {c.what}\n"
            f"must refuse: {c.must_refuse or '-'}\nsetup: {c.setup!r}\n"
            f"exit {res.rc}{' (timed out)' if res.timed_out else ''}, {res.seconds:.1f} s\n"
            f"problems: {res.problems}\nfile changes: {res.changes}\n"
            f"stderr:\n{res.stderr[:3000]}\n...\n{res.stderr[-3000:]}\nstdout tail:\n{res.stdout[-1500:]}\n")
    (failures_dir / f"{name}.txt").write_text(note, errors="backslashreplace")
    tail = "\n".join("      | " + l for l in res.stderr.strip().splitlines()
                     if not MPIRUN_NOISE.match(l))[-1200:]
    print(f"FAIL  case {c.index} [{c.base}, {c.ranks} rank(s)] {c.kind}: {c.what[:160]}\n"
          f"      exit {res.rc}{' (timed out)' if res.timed_out else ''}; "
          f"{'; '.join(res.problems)}\n"
          f"      files: {', '.join(res.changes) or 'unchanged'}\n{tail}", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--iem", required=True)
    ap.add_argument("--mpiexec", required=True)
    ap.add_argument("--mpiexec-flags", default="", help="';'-separated extra mpiexec flags")
    ap.add_argument("--seed", type=int, default=20240611)
    ap.add_argument("--cases", type=int, default=None, help="number of cases (default 240, "
                    "--long 3000)")
    ap.add_argument("--long", action="store_true", help="the long form: thousands of cases")
    ap.add_argument("--case", type=int, action="append", help="run only this case (repeatable)")
    ap.add_argument("--jobs", type=int, default=2, help="cases run at a time")
    ap.add_argument("--two-ranks", type=float, default=0.2, help="share of cases on 2 ranks")
    ap.add_argument("--time-limit", type=float, default=4.0, help="seconds per case")
    ap.add_argument("--mem-mb", type=int, default=3072, help="address-space limit per process")
    ap.add_argument("--work", default=None, help="scratch folder (default ./fuzz_work, "
                    "./fuzz_work_long with --long)")
    ap.add_argument("--keep", action="store_true", help="keep every case's folder")
    ap.add_argument("--list", action="store_true", help="print the cases, run nothing")
    args = ap.parse_args()
    sys.stdout.reconfigure(errors="backslashreplace")  # mutated file names are any bytes
    args.iem = str(Path(args.iem).resolve())
    n_cases = args.cases if args.cases is not None else (3000 if args.long else 240)

    bases = load_bases()
    indices = args.case if args.case else list(range(n_cases))
    cases = [make_case(i, args.seed, bases, args.two_ranks) for i in indices]
    if args.list:
        for c in cases:
            print(f"{c.index:6d} {c.base:36s} {c.ranks} {c.kind:22s} "
                  f"{'R' if c.must_refuse else '-'} {c.what[:120]}")
        return 0

    work = Path(args.work or ("fuzz_work_long" if args.long else "fuzz_work")).resolve()
    if not args.case:
        shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    bad = check_bases(args, bases, work)
    for b in bad:
        print("FAIL  " + b)
    if bad:
        print(f"0 passed, {len(bad)} failed (the bases do not run)")
        return 1
    slowest = max(b.seconds for b in bases)
    limit = max(args.time_limit, 4 * slowest)
    by_name = {b.name: b for b in bases}
    print(f"bases: {len(bases)} ({', '.join(f'{b.name} {b.seconds:.2f} s' for b in bases)}); "
          f"seed {args.seed}, {len(cases)} cases, {args.jobs} at a time, time limit {limit:.1f} s",
          flush=True)

    results: list[Result] = []
    failures_dir = work / "failures"
    with cf.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        futures = [pool.submit(run_case, args, c, by_name[c.base], work, limit) for c in cases]
        for fut in cf.as_completed(futures):
            res = fut.result()
            results.append(res)
            if res.outcome == "FAIL":
                report_failure(res, failures_dir)
            if res.outcome != "FAIL" and not args.keep and not args.case:
                shutil.rmtree(res.folder, ignore_errors=True)
            elif args.case:
                print(f"case {res.case.index}: {res.case.kind}: {res.case.what}\n"
                      f"  folder {res.folder}\n  exit {res.rc}, outcome {res.outcome} "
                      f"{res.problems}\n  files: {res.changes}\n  stderr: {res.stderr[-2000:]}")

    counts: dict[str, int] = {}
    for res in results:
        counts[res.outcome] = counts.get(res.outcome, 0) + 1
    failed = [r for r in results if r.outcome == "FAIL"]
    classes: dict[str, list[int]] = {}
    for res in failed:
        classes.setdefault(failure_class(res), []).append(res.case.index)
    if classes:
        print("\nfailure classes (count: mutation, problem; example cases):")
        for k, v in sorted(classes.items(), key=lambda kv: -len(kv[1])):
            print(f"  {len(v):4d}: {k}  (e.g. case {', '.join(map(str, sorted(v)[:3]))})")
        print(f"failing inputs saved under {failures_dir}")
    print(f"\noutcomes: complete runs {counts.get('ok-complete', 0)}, refused "
          f"{counts.get('refused', 0)}, guarded run failures (exit 3) "
          f"{counts.get('run-failed', 0)}, long valid runs (killed at {limit:.1f} s) "
          f"{counts.get('long-run', 0)}; {time.monotonic() - t0:.0f} s")
    print(f"{len(results) - len(failed)} passed, {len(failed)} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
