#!/usr/bin/env python3
"""The bad-input corpus: every case must be refused cleanly.

Each `*.nml` here is one case: its `! expect: TEXT` line names what the single error line
must contain. Before a case runs, its folder is seeded with the files a run of it would
write (output, its .xmf sidecar, the checkpoint: names from the case's `output_file` and
`checkpoint_file`, with their defaults) holding known bytes, unless the case says
`! seed: none`. More set-up lines:
  ! setup: touch NAME         a regular file
  ! setup: mkdir NAME         a folder
  ! setup: fifo NAME          a named pipe
  ! setup: link NAME -> DEST  a symbolic link (DEST need not exist)
  ! setup: write NAME: TEXT   a regular file holding TEXT, with Python escapes (\\n, \\x00)
A case passes when iem exits with status 2, prints exactly one `iem: error:` line (from rank
0 only) that contains the expected text, prints no runtime error or backtrace, and no file
or folder of the case's folder is created, changed or removed (checksums before and after).
A few cases that are not namelists (the input file is missing, a folder, a pipe, binary)
are made here in code.
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import hashlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
RUNTIME_NOISE = ("Backtrace", "Error termination", "Program received signal", "At line ",
                 "Fortran runtime error")


def mpi_command(args: argparse.Namespace, nranks: int, nml: str) -> list[str]:
    """The mpiexec command line of one iem run."""
    flags = [f for f in args.mpiexec_flags.split(";") if f]
    return [args.mpiexec, "-n", str(nranks), *flags, args.iem, nml]


def snapshot(folder: Path) -> dict[str, str]:
    """Kind and checksum of every entry below folder (links are not followed)."""
    out = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            p = Path(root) / name
            rel = str(p.relative_to(folder))
            if p.is_symlink():
                out[rel] = "link:" + os.readlink(p)
            elif p.is_dir():
                out[rel] = "dir"
            elif p.is_fifo():
                out[rel] = "fifo"
            else:
                out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def run_case(args: argparse.Namespace, work: Path, nml_name: str, expect: str,
             timeout: float = 60) -> tuple[bool, str]:
    """Run iem on work/nml_name and judge the outcome; (passed, one-line report)."""
    before = snapshot(work)
    # the run's own TMPDIR: Open MPI makes and removes its session directories under
    # $TMPDIR/ompi.<host>.<uid>, and runs at once sharing that folder can race on it
    session = tempfile.mkdtemp(prefix="iem-mpi-")
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", TMPDIR=session)
    try:
        p = subprocess.run(mpi_command(args, 2, nml_name), cwd=work, env=env, text=True,
                           capture_output=True, timeout=timeout, errors="replace")
    except subprocess.TimeoutExpired:
        return False, f"{nml_name}: no answer within {timeout} s (a hang)"
    finally:
        shutil.rmtree(session, ignore_errors=True)
    after = snapshot(work)
    errors = [line for line in p.stderr.splitlines() if line.startswith("iem: error")]
    noise = [n for n in RUNTIME_NOISE if n in p.stderr or n in p.stdout]
    changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
    ok = (p.returncode == 2 and len(errors) == 1 and expect in errors[0] and not noise
          and not changed)
    report = (f"{nml_name}: exit {p.returncode}, {len(errors)} error line(s), names "
              f"'{expect}', no runtime error, no file changed")
    if ok:
        return True, report + "\n   " + errors[0]
    detail = f"\n   changed: {changed}\n   runtime noise: {noise}\n   stderr: " + \
        p.stderr.strip()[-1500:]
    return False, report + detail


def seed_names(text: str) -> list[str]:
    """The files a run of this namelist would write: output, sidecar, checkpoint."""
    m = re.search(r"output_file\s*=\s*'([^']*)'", text)
    out = m.group(1) if m else "iem_out.h5"
    m = re.search(r"checkpoint_file\s*=\s*'([^']*)'", text)
    stem = out.rsplit(".", 1)[0] if "." in out.rsplit("/", 1)[-1][1:] else out
    chk = m.group(1) if m else stem + ".chk"
    xmf = stem + ".xmf" if not out.endswith(".xmf") else out + ".xmf"
    return [out, xmf, chk]


def prepare(case: Path, work: Path) -> str:
    """Lay out a namelist case's folder; returns its expected text."""
    text = case.read_text(errors="replace")
    m = re.search(r"^! expect: (.+)$", text, re.M)
    if not m:
        raise SystemExit(f"{case.name}: has no '! expect:' line")
    shutil.copy(case, work / case.name)
    if not re.search(r"^! seed: none$", text, re.M):
        for name in seed_names(text):
            target = work / name
            if target.parent.is_dir() and not target.exists() and not target.is_symlink():
                target.write_bytes(b"seeded " + name.encode() + b": must stay as it is\n")
    for kind, arg in re.findall(r"^! setup: (touch|mkdir|fifo|link|write) (.+)$", text, re.M):
        if kind == "write":
            name, _, content = arg.partition(": ")
            (work / name.strip()).write_bytes(
                content.encode("latin-1").decode("unicode_escape").encode("latin-1"))
            continue
        target = work / arg.split(" -> ")[0].strip()
        if target.is_file() or target.is_symlink():
            target.unlink()  # a set-up line replaces a seeded file of the same name
        if kind == "touch":
            target.write_text("do not overwrite me\n")
        elif kind == "mkdir":
            target.mkdir(parents=True, exist_ok=True)
        elif kind == "fifo":
            os.mkfifo(target)
        else:
            target.symlink_to(arg.split(" -> ")[1].strip())
    return m.group(1).strip()


def coded_cases(root: Path) -> list[tuple[Path, str, str]]:
    """Cases made here: (folder, input name, expected text)."""
    cases = []
    d = root / "input_missing"
    d.mkdir()
    cases.append((d, "no_such_case.nml", "cannot open the input file 'no_such_case.nml': no such"))
    d = root / "input_is_folder"
    d.mkdir()
    (d / "case.nml").mkdir()
    cases.append((d, "case.nml", "'case.nml': it is a folder"))
    d = root / "input_is_fifo"
    d.mkdir()
    os.mkfifo(d / "case.nml")
    cases.append((d, "case.nml", "'case.nml': it is not a regular file"))
    d = root / "input_binary"
    d.mkdir()
    (d / "case.nml").write_bytes(b"\x89HDF\r\n\x1a\n\x00\x00\x00\x00\x00\x08\x08\x00")
    cases.append((d, "case.nml", "a control character"))
    d = root / "input_nul_in_path"
    d.mkdir()
    (d / "case.nml").write_bytes(
        b"&run t_end = 1e-4, output_file = 'out\x00.h5' /\n&geometry length = 1, height = 0.2, "
        b"nx = 4, ny = 1 /\n&material E = 2e11, nu = 0.3, density = 7800 /\n")
    cases.append((d, "case.nml", "a control character (byte 0)"))
    d = root / "unknown_option"
    d.mkdir()
    (d / "case.nml").write_text("&run t_end = 1e-4 /\n")
    cases.append((d, "--frobnicate", "unknown option '--frobnicate'"))
    return cases


def main() -> int:
    """Run every case (two at a time) and print one line per case."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--iem", required=True)
    ap.add_argument("--mpiexec", required=True)
    ap.add_argument("--mpiexec-flags", default="")
    ap.add_argument("--corpus", default=str(HERE))
    ap.add_argument("-k", default="", help="run only cases whose name contains this")
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    args.iem = str(Path(args.iem).resolve())

    root = Path.cwd() / "input_errors_work"
    shutil.rmtree(root, ignore_errors=True)
    root.mkdir(parents=True)
    jobs = []
    for case in sorted(Path(args.corpus).glob("*.nml")):
        if args.k not in case.name:
            continue
        work = root / case.stem
        work.mkdir()
        jobs.append((work, case.name, prepare(case, work)))
    jobs += [c for c in coded_cases(root) if args.k in c[0].name]
    with cf.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        results = list(pool.map(lambda j: run_case(args, *j), jobs))
    failed = 0
    for ok, report in results:
        print(("ok    " if ok else "FAIL  ") + report)
        failed += not ok
    print(f"{len(results) - failed} passed, {failed} failed")
    if not args.k and len(results) < 10:
        print("the corpus has fewer than 10 cases")
        return 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
