"""benchmarks/device_scaling.sh end to end, with a stand-in iem and mpirun: every section
runs, its tables land in $OUT/tables.md, and the build is chosen by the processor's flags."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# prints an end-of-run report in iem's words for the block namelist it is given (1e7
# node-steps/s a rank, 20 MB plus 120 bytes a node)
FAKE_IEM = r'''#!PYTHON
import re, sys
text = open(sys.argv[-1]).read()
nx = int(re.search(r"nx = (\d+)", text)[1]); ny = int(re.search(r"ny = (\d+)", text)[1])
t_end = float(re.search(r"t_end = ([\d.eE+-]+)", text)[1])
verlet = "verlet" in text
steps = max(1, int(round(t_end / (1.6e-4 / ny * (0.707 if verlet else 1.0)))))
nodes = (nx + 1) * (ny + 1)
ranks = int(sys.argv[1]) if len(sys.argv) > 2 else 1
rate = 1.0e7 * ranks
wall = nodes * steps / rate
mb = 20 + nodes / ranks * 120 / 1048576
print(f"iem 0.1.0: {nodes} nodes, {nx * ny} cells ({nx} x {ny}), {ranks} ranks")
print(f"time step 1e-7 s; {steps} steps to {t_end} s")
print(f"done: {steps} steps in {wall} s wall; final energy-balance error 0.1E-2")
print(f"performance:  {nodes * steps:.3E} node-steps in  {wall:.3E} s:  {rate:.3E} node-steps/s")
print("time in force evaluation 70.0%, halo exchange 1.0%, state updates 28.0%, output 1.0% "
      "(largest over ranks)")
print(f"memory: peak {mb:.1f} MB per rank (largest), {mb * ranks:.1f} MB in all")
'''

# runs the command after mpirun's options (the first argument that is an executable file),
# telling it the rank count as its first argument
FAKE_MPIRUN = r'''#!/usr/bin/env bash
n=1; a=("$@")
for ((i = 0; i < ${#a[@]}; i++)); do
  [[ ${a[i]} == -n ]] && n=${a[i+1]}
  if [[ -f ${a[i]} && -x ${a[i]} ]]; then exec "${a[i]}" "$n" "${a[@]:i+1}"; fi
done
echo "fake mpirun: no executable in $*" >&2; exit 1
'''


def write_exe(path: Path, text: str) -> None:
    """Write an executable script."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text.replace("PYTHON", sys.executable))
    path.chmod(0o755)


@pytest.mark.skipif(shutil.which("taskset") is None or shutil.which("timeout") is None,
                    reason="needs taskset and timeout")
def test_device_scaling_runs_every_section(tmp_path: Path):
    work = tmp_path / "repo"
    work.mkdir()
    (work / "benchmarks").symlink_to(ROOT / "benchmarks", target_is_directory=True)
    (work / "postproc").symlink_to(ROOT / "postproc", target_is_directory=True)
    devrun = work / ".devrun"
    for arch in ("native", "v3"):
        for which in ("new", "base"):
            write_exe(devrun / arch / which / "iem", FAKE_IEM)
    # a feature no processor has: the x86-64-v3 builds must run
    (devrun / "native" / "flags").write_text("avx2\nno_such_feature\n")
    (devrun / "lib").mkdir()
    write_exe(tmp_path / "bin" / "mpirun", FAKE_MPIRUN)
    out = tmp_path / "out"
    env = dict(os.environ, PATH=f"{tmp_path / 'bin'}:{os.environ['PATH']}", OUT=str(out),
               PY=sys.executable, SCALE="0.01", BUDGET="300", SPEED_ARGS="--repeat 1")
    p = subprocess.run(["bash", str(ROOT / "benchmarks" / "device_scaling.sh")], cwd=work,
                       env=env, text=True, capture_output=True, timeout=280)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-2000:]
    assert "no no_such_feature: the x86-64-v3 builds run" in p.stdout
    tables = (out / "tables.md").read_text()
    for name in ("ceiling", "strong_rk4_1", "strong_rk4_2", "strong_rk4_3", "weak_rk4",
                 "weak2_rk4", "strong_verlet", "speed"):
        assert f"## {name}\n" in tables, name
    assert "skipped" not in p.stdout
    assert "| all " in tables and "| alone (core 0) | 1 | 1.000e+07 |" in tables
    assert tables.count("Strong scaling, rk4, paper cell.") == 3
    assert tables.count("Strong scaling, verlet, paper cell.") == 3
    assert "Weak scaling, rk4, paper cell." in tables
    assert "| RK4 bytes per node (1e5 to 1e6) |" in tables
    assert (out / "speed.json").is_file()


def test_device_scaling_needs_the_prepared_builds(tmp_path: Path):
    p = subprocess.run(["bash", str(ROOT / "benchmarks" / "device_scaling.sh")], cwd=tmp_path,
                       env=dict(os.environ, OUT=str(tmp_path / "out")), text=True,
                       capture_output=True, timeout=60)
    assert p.returncode == 2
    assert "run benchmarks/device_prepare.sh first" in p.stderr


@pytest.mark.parametrize("script", sorted((ROOT / "benchmarks").glob("*.sh")),
                         ids=lambda p: p.name)
def test_shell_scripts_parse(script: Path):
    p = subprocess.run(["bash", "-n", str(script)], text=True, capture_output=True)
    assert p.returncode == 0, p.stderr
