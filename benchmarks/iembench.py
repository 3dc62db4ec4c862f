"""Shared pieces of the accuracy benchmarks (benchmarks/convergence.py, benchmarks/pareto.py).

The scene is the cantilever of issue 3 (postproc/iem_post/references.py, ``ISSUE3``):
``[0, 1] x [0, 0.1]`` m, thickness 0.1 m, plane stress, E = 25 GPa, nu = 0.2,
rho = 2400 kg/m^3, left edge clamped, a uniform downward shear traction of 1e5 Pa on the
right edge (P = 1000 N in all), ``nx = 10 ny`` square cells. The quantities are the tip
deflection ``u_y(L, h/2)`` and the first period, compared with the committed plane-stress
finite-element references (``load_fe_references()``).

Period measurement. An undamped step load excites every bending mode; at the tip the second
mode (about 6 f1) has about 2.6% of the first mode's amplitude. Zero crossings of the tip
displacement minus its mean (as tests/regression/regress.py measures the period) are moved by
it by up to about 0.4% of a period each, so over three periods the crossing estimate is off by
a few 1e-4, more than the discretisation error of the finer grids. The period is therefore
taken from a least-squares fit of ``c + sum_k (a_k cos w_k t + b_k sin w_k t)``, k = 1..4
(variable projection, Gauss-Newton on the w_k, started from the crossing estimate and from
the periodogram peaks of the residual); the fit's constant ``c`` is the static deflection
about which the tip oscillates. The crossing estimate is reported beside it.

Only numpy and h5py are needed (and matplotlib for the plots, in the scripts).
"""
from __future__ import annotations

import json
import os
import platform
import re
import subprocess
import sys
import time
from datetime import date
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "postproc"))
from iem_post.references import ISSUE3, beam_references, load_fe_references  # noqa: E402

P = ISSUE3
TRACTION = P["P"] / (P["h"] * P["t"])  # 1e5 Pa

STATIC = """! {title}
&run
  analysis = 'static', t_end = 1.0, output_file = '{out}', overwrite = .true.
/
&static
  load_steps = 1, tolerance = {tol:.3e}, max_iterations = {max_it}, method = 'kinetic'
/
&geometry
  length = {L}, height = {h}, thickness = {t}, nx = {nx}, ny = {ny}, plane = 'stress', cell = '{cell}'
/
&material
  E = {E:.6e}, nu = {nu}, density = {rho}
/
&bc
  name = 'clamp', where = 'left', kind = 'fix', dofs = 'xy'
/
&load
  name = 'shear', kind = 'edge', where = 'right', traction = 0.0, {ty:.6e}
  time_function = 'ramp', t_start = 0.0, t_ramp = 1.0
/
&probe
  name = 'tip', x = {L}, y = {ymid}
/
"""

DYNAMIC = """! {title}
&run
  t_end = {t_end:.9e}, dt_safety = {safety}, integrator = '{integrator}'
  output_interval = {t_end:.9e}
  history_interval = {hist:.9e}, progress_interval = 1.0e6
  output_file = '{out}', overwrite = .true.
/
&geometry
  length = {L}, height = {h}, thickness = {t}, nx = {nx}, ny = {ny}, plane = 'stress', cell = '{cell}'
/
&material
  E = {E:.6e}, nu = {nu}, density = {rho}
/
&bc
  name = 'clamp', where = 'left', kind = 'fix', dofs = 'xy'
/
&load
  name = 'shear', kind = 'edge', where = 'right', traction = 0.0, {ty:.6e}
  time_function = 'step', t_start = 0.0
/
&probe
  name = 'tip', x = {L}, y = {ymid}
/
"""

NUM = r"([-+]?[\d.]+(?:[eE][+-]?\d+)?)"


# ---------------------------------------------------------------------------------------------
# references
# ---------------------------------------------------------------------------------------------

def references(path: str | None = None) -> dict:
    """FE references of the cantilever: ``{"uy_tip": m (signed), "period": s, "source": str}``.

    ``path`` may name a JSON file of the same layout as iem_post/data/fe_references.json, or
    a small ``{"uy_tip": ..., "f1": ...}`` file (a provisional reference)."""
    try:
        refs = load_fe_references(path)
    except FileNotFoundError as exc:
        raise SystemExit(
            "the FE reference postproc/iem_post/data/fe_references.json is missing "
            "(postproc/references/fe_reference.py writes it); give --reference FILE") from exc
    if "cantilever" in refs:
        if refs.get("quick"):
            raise SystemExit("the FE reference file is from a --quick run: not a reference")
        c = refs["cantilever"]
        uy, f1 = c["uy_tip"]["value"], c["f1"]["value"]
        src = (f"FE (scikit-fem Quad2, Richardson; {refs.get('generated_utc', '?')}; "
               f"rel. errors {c['uy_tip']['rel_error']:.0e}, {c['f1']['rel_error']:.0e})")
    else:
        uy, f1 = refs["uy_tip"], refs["f1"]
        src = refs.get("source", str(path))
    return {"uy_tip": float(uy), "period": 1.0 / float(f1), "source": src}


def period_guess() -> float:
    """First period of the Timoshenko beam (s): sets t_end and history_interval."""
    return 1.0 / beam_references()["cantilever"]["f1_timoshenko"]


# ---------------------------------------------------------------------------------------------
# running iem
# ---------------------------------------------------------------------------------------------

def mpi_env() -> dict:
    return dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
                OMPI_MCA_rmaps_base_oversubscribe="1")


def run(iem: str, nml: Path, ranks: int, mpiexec: str) -> tuple[str, float]:
    """Run iem on a namelist in its folder; return stdout and the process's wall time."""
    cmd = [mpiexec, "-n", str(ranks), iem, nml.name]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, cwd=nml.parent, env=mpi_env(), text=True, capture_output=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} (in {nml.parent}) failed:\n{p.stdout[-2000:]}\n"
                         f"{p.stderr[-2000:]}")
    return p.stdout, wall


def grid(ny: int) -> tuple[int, int]:
    """nx, ny of square cells with ny cells through the depth."""
    return int(round(ny * P["L"] / P["h"])), ny


def static_tolerance(ny: int) -> float:
    """Relaxation tolerance: 1e-9, loosened where the round-off floor of the residual (about
    3e-9 at 8 cells through the depth, growing like the square root of the node count; see
    docs/model.md, "Round-off floor") is near: 1e-8 at 32 and 2e-8 at 64."""
    return 1e-9 if ny <= 16 else 1e-8 * ny / 32


def run_static(iem: str, folder: Path, ny: int, cell: str, tol: float, ranks: int = 1,
               mpiexec: str = "mpirun") -> dict:
    """One static run (1 load step, kinetic dynamic relaxation): tip u_y, iterations, times."""
    nx, ny = grid(ny)
    name = f"static_{cell}_{ny}_{tol:.0e}"
    nml = folder / f"{name}.nml"
    nml.write_text(STATIC.format(title=name, out=f"{name}.h5", tol=tol, max_it=2_000_000,
                                 nx=nx, ny=ny, cell=cell, ty=-TRACTION, ymid=P["h"] / 2, **P))
    out, wall = run(iem, nml, ranks, mpiexec)
    m = re.search(rf"done: \d+ load steps, (\d+) iterations in\s+{NUM} s wall", out)
    with h5py.File(folder / f"{name}.h5", "r") as f:
        uy = float(f["history/probes/tip/displacement"][-1, 1])
        res = float(f["history/static/residual"][-1])
        node = f["history/probes/tip"].attrs
        assert abs(node["node_x"] - P["L"]) < 1e-12 and abs(node["node_y"] - P["h"] / 2) < 1e-12
        n_nodes = int(f["mesh/coordinates"].shape[0])
    (folder / f"{name}.h5").unlink()
    return {"ny": ny, "nx": nx, "nodes": n_nodes, "cell": cell, "tol": tol, "uy": uy,
            "residual": res, "iterations": int(m[1]), "wall_iem": float(m[2]),
            "wall_process": wall}


def run_dynamic(iem: str, folder: Path, ny: int, cell: str, safety: float, periods: float = 3.0,
                samples_per_period: int = 800, ranks: int = 1, mpiexec: str = "mpirun",
                integrator: str = "rk4") -> dict:
    """One undamped step-load run over ``periods`` first periods, history every
    T/``samples_per_period``: the period and the static deflection measured from the tip
    history, with every other sample too (the check of the sampling), and iem's timings."""
    nx, ny = grid(ny)
    tg = period_guess()
    name = f"dynamic_{cell}_{ny}_{safety:g}_{integrator}"
    nml = folder / f"{name}.nml"
    nml.write_text(DYNAMIC.format(title=name, out=f"{name}.h5", t_end=periods * tg,
                                  hist=tg / samples_per_period, safety=safety,
                                  integrator=integrator, nx=nx, ny=ny,
                                  cell=cell, ty=-TRACTION, ymid=P["h"] / 2, **P))
    out, wall = run(iem, nml, ranks, mpiexec)
    perf = re.search(rf"performance:\s+{NUM} node-steps in\s+{NUM} s:\s+{NUM} node-steps/s", out)
    steps = int(re.search(r"(\d+) steps to", out)[1])
    dt = float(re.search(rf"time step\s+{NUM} s", out)[1])
    energy = float(re.search(rf"final energy-balance error\s+{NUM}", out)[1])
    with h5py.File(folder / f"{name}.h5", "r") as f:
        t = f["history/time"][:]
        uy = f["history/probes/tip/displacement"][:, 1]
        n_nodes = int(f["mesh/coordinates"].shape[0])
    (folder / f"{name}.h5").unlink()
    full, half = measure(t, uy), measure(t[::2], uy[::2])
    return {"ny": ny, "nx": nx, "nodes": n_nodes, "cell": cell, "safety": safety, "dt": dt,
            "integrator": integrator,
            "steps": steps, "wall_iem": float(perf[2]), "rate": float(perf[3]),
            "wall_process": wall, "energy_error": energy, "samples": len(t),
            "period": full["period"], "mean": full["mean"],
            "period_crossing": full["period_crossing"], "mean_crossing": full["mean_crossing"],
            "fit_rms": full["rms"], "omegas": full["omegas"],
            "period_half": half["period"], "period_crossing_half": half["period_crossing"],
            "mean_half": half["mean"]}


# ---------------------------------------------------------------------------------------------
# period and mean of a step response
# ---------------------------------------------------------------------------------------------

def crossings(t: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Times where s crosses zero upwards (linear interpolation), as in regress.py."""
    i = np.where((s[:-1] < 0) & (s[1:] >= 0))[0]
    return t[i] - s[i] * (t[i + 1] - t[i]) / (s[i + 1] - s[i])


def crossing_period(t: np.ndarray, u: np.ndarray) -> tuple[float, float]:
    """Period from the upward zero crossings of u minus its mean over whole periods, and
    that mean (the estimate of tests/regression/regress.py)."""
    mean = float(np.mean(u))
    tc = crossings(t, u - mean)
    for _ in range(3):
        tc = crossings(t, u - mean)
        if len(tc) < 2:
            raise SystemExit("fewer than two upward zero crossings: run longer")
        sel = (t >= tc[0]) & (t <= tc[-1])
        mean = float(np.trapezoid(u[sel], t[sel]) / (tc[-1] - tc[0]))
    return float(np.mean(np.diff(tc))), mean


def _residual(t, u, omegas):
    cols = [np.ones_like(t)]
    for w in omegas:
        cols += [np.cos(w * t), np.sin(w * t)]
    a = np.array(cols).T
    c = np.linalg.lstsq(a, u, rcond=None)[0]
    return u - a @ c, c


def _refine(t, u, omegas, iterations=60):
    """Gauss-Newton on the frequencies of the variable-projection residual."""
    w = np.array(omegas, float)
    for _ in range(iterations):
        r, _ = _residual(t, u, w)
        jac = np.empty((len(t), len(w)))
        for k in range(len(w)):
            dw = w.copy()
            dw[k] += 1e-7 * w[k]
            jac[:, k] = (_residual(t, u, dw)[0] - r) / (1e-7 * w[k])
        step = np.linalg.lstsq(jac, -r, rcond=None)[0]
        w = w + step
        if np.max(np.abs(step / w)) < 1e-12:
            break
    r, c = _residual(t, u, w)
    return w, c, r


def _next_mode(t, u, omegas):
    """Frequency of the largest periodogram peak of the residual of the current fit."""
    r, _ = _residual(t, u, omegas)
    top = min(60 * omegas[0], np.pi / np.min(np.diff(t)))
    grid_w = np.linspace(0.5 * omegas[0], top, 12000)
    power = np.abs(np.exp(-1j * np.outer(grid_w, t)) @ r)
    near = np.any(np.abs(grid_w[:, None] - np.asarray(omegas)[None, :]) < 0.3 * omegas[0], axis=1)
    power[near] = 0
    return np.append(omegas, grid_w[int(np.argmax(power))])


def measure(t: np.ndarray, u: np.ndarray, modes: int = 4) -> dict:
    """Period and static deflection of a step response: crossing estimate, then the fit."""
    tc, mc = crossing_period(t, u)
    w = np.array([2 * np.pi / tc])
    w, c, r = _refine(t, u, w)
    for _ in range(modes - 1):
        w = _next_mode(t, u, w)
        w, c, r = _refine(t, u, w)
    period = float(2 * np.pi / w[0])
    if abs(period / tc - 1) > 0.01:
        raise SystemExit(f"the fit's period {period:.6e} s is far from the crossing estimate "
                         f"{tc:.6e} s: the fit failed")
    return {"period": period, "mean": float(c[0]), "period_crossing": tc, "mean_crossing": mc,
            "rms": float(np.sqrt(np.mean(r**2)) / np.ptp(u)),
            "omegas": [float(x) for x in w / w[0]]}


# ---------------------------------------------------------------------------------------------
# reporting
# ---------------------------------------------------------------------------------------------

def order(e_coarse: float, e_fine: float) -> str:
    """Observed order log2(e_n / e_2n), or '-' where the sign changes."""
    if e_coarse == 0 or e_fine == 0 or np.sign(e_coarse) != np.sign(e_fine):
        return "-"
    return f"{np.log2(e_coarse / e_fine):.2f}"


def machine() -> str:
    """Model name and core count (lscpu), compiler of the build, and the date."""
    model, cores = platform.processor() or "?", os.cpu_count()
    try:
        text = subprocess.run(["lscpu"], text=True, capture_output=True).stdout
        model = re.search(r"Model name:\s*(.+)", text)[1].strip()
    except (OSError, TypeError):
        pass
    return f"{model}, {cores} cores; {date.today().isoformat()}"


def build_info(iem: str) -> str:
    """Compiler and build type from the CMake cache beside the executable, if there is one."""
    cache = Path(iem).resolve().parent / "CMakeCache.txt"
    if not cache.exists():
        return "build: unknown (no CMakeCache.txt beside the executable)"
    text = cache.read_text(errors="replace")
    get = lambda k: (re.search(rf"^{k}:\w+=(.*)$", text, re.M) or [None, "?"])[1]  # noqa: E731
    fc = get("CMAKE_Fortran_COMPILER")
    try:
        ver = subprocess.run([fc, "--version"], text=True, capture_output=True).stdout.splitlines()[0]
    except (OSError, IndexError):
        ver = fc
    flags = Path(iem).resolve().parent / "CMakeFiles" / "iem.dir" / "flags.make"
    opt = ""
    if flags.exists():
        m = re.search(r"^Fortran_FLAGS\s*=(.*)$", flags.read_text(), re.M)
        opt = " (" + " ".join(f for f in m[1].split() if f.startswith(("-O", "-m", "-f"))
                              and not f.startswith(("-ffree", "-ffpe"))) + ")" if m else ""
    return f"{ver}; CMAKE_BUILD_TYPE={get('CMAKE_BUILD_TYPE')}{opt}"


def add_sweep_args(ap, cells) -> None:
    """The sweep options the study scripts share: MPI launcher, ranks, grids, cell laws."""
    ap.add_argument("--mpiexec", default="mpirun")
    ap.add_argument("--ranks", type=int, default=1)
    ap.add_argument("--depths", type=int, nargs="+", default=[2, 4, 8, 16, 32],
                    help="cells through the depth")
    ap.add_argument("--cells", nargs="+", default=list(cells), choices=cells)


def save_figure(fig, png: str) -> None:
    """Write a matplotlib figure to png, making its folder."""
    Path(png).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=120)


def measure_and_report(ap, run_all, report) -> int:
    """Shared end of the study scripts: add the reference and save/load options, then run the
    sweep (or load a saved one) and report it against the reference."""
    ap.add_argument("--reference", help="reference JSON (default: the committed FE references)")
    ap.add_argument("--save", help="write the raw measurements to this JSON file")
    ap.add_argument("--load", help="report from raw measurements saved by --save (no runs)")
    args = ap.parse_args()
    ref = references(args.reference)
    if args.load:
        data = json.loads(Path(args.load).read_text())
    else:
        if not args.iem:
            ap.error("--iem is required (or --load)")
        data = run_all(args)
        save(args.save, data)
    report(data, ref, args.png)
    return 0


def save(path: str | None, data: dict) -> None:
    if path:
        Path(path).write_text(json.dumps(data, indent=1) + "\n")
