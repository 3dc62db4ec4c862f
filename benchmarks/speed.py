#!/usr/bin/env python3
"""Speed figures of an old and a new build side by side (issue 12's targets), in one table.

Every measurement runs both executables interleaved (old, new, old, new, ...), --repeat times
(default 5; 3 with --quick), each run on the same namelist, and the table gives for each
figure the median of the old and of the new runs with their min and max, the median of the
paired ratios new/old (each new run over the old run just before it, or the figures of one
repetition of each) with their min and max, the target and whether it is met. Usage (from the
repository root, after building both):

    python3 benchmarks/speed.py --iem build/iem --baseline "$(bash benchmarks/baseline.sh f17bd0c)"
    python3 benchmarks/speed.py --iem NEW --baseline OLD [--repeat 5] [--quick] [--weak]
                                [--only force,rk4,verlet,memory,checkpoint,size,nonlinear,damped,
                                        fracture,weak]
                                [--save runs.json]

The cases (1 rank unless said; `block N` is benchmarks/throughput.py's clamped 2:1 block of
about N nodes, plane stress, paper's cell, edge load, at about 0.9 of the stable step):
- RK4 and Verlet blocks of 1e5 nodes (101,025), about 200 and 400 steps; for the force
  also the RK4 block with the bending-corrected cell, and an RK4 block of 1.37e5 grid nodes
  with 8 round holes (radius 0.15 on a 4 x 2 pattern of pitch 0.5 of the 2 x 1 block: 28 %
  of its cells void, a body of 100,475 nodes; the holes end the chunks of the rows they cut),
  and the same body with 8 square holes of the same area and centres (no target: its holes
  cut every row at the same columns, so that a chunk's bottom row is the top row of the chunk
  below, which the round holes' rows are not for a third of their cells);
  and the RK4 block of 1e5 nodes with capped stiffness damping, about 90 steps;
- RK4 and Verlet blocks of 1e6 nodes (1,001,820), about 100 steps (memory, size; fewer
  would weigh a run's fixed costs, such as its first evaluation and its two history samples,
  more at 1e6 than in the longer runs of 1e5);
- checkpoint: the RK4 blocks of 1e5 and 1e6 nodes with one checkpoint half way
  (`checkpoint_interval`), for the memory a checkpoint adds;
- the nonlinear cantilever of benchmarks/nonlinear_cost.py (inputs/cantilever_nonlinear_
  dynamic.nml, 729 nodes) for 0.01 s, and with the nonlinear springs off for 0.04 s (the
  elastic run's rate does not depend on its length; 0.01 s of it would last 0.1 s);
- the concrete cantilever of benchmarks/fracture_cost.py (101,101 nodes), about 200 RK4 or
  130 Verlet steps, with and without fracture = .true. (the script checks that nothing
  failed: /history/energy/fracture = 0), in tension, and with every criterion (tension,
  crushing, shear: fracture_cost.py --every);
- weak: the RK4 block of 2e5 nodes on 2 ranks, with the steps of the 1e5 block; and two
  1-rank runs of the RK4 block of 1e5 nodes started together, each pinned to its own core
  (the machine's own ceiling for weak scaling: two cores reading one shared cache and memory).
--quick halves the work (steps, or t_end) of each run and leaves out memory, checkpoint and
size (the 1e6-node runs); weak runs only with --weak or when --only names it.

Definitions (from iem's end-of-run report: node-steps, the time loop's wall time, the share
of that time in each part, the peak resident memory VmHWM of every rank):
- node-steps/s: iem's node-steps over the time loop's wall time less its share in output
  (the frames at t = 0 and t_end, with the buffered history, and a fracture run's fragment
  counts at its history samples: the two frames weigh twice as much in the 100-step runs of
  1e6 nodes as in the 200-step runs of 1e5);
- force (cells/s of the force alone) = force evaluations in the time loop x cells / time in
  force evaluation (its share of the loop's wall time); RK4 evaluates 4 times a step; cells
  = the body's cells as iem reports them (nx*ny for a block, without the void ones for the
  block with holes); measured on the RK4 blocks of 1e5 nodes, the paper's cell, the
  bending-corrected one, and the paper's cell with holes;
- bytes per node = slope of the peak resident memory (`memory: peak ... MB per rank`, MB =
  2^20 bytes) between the blocks of 1e5 and 1e6 nodes on 1 rank, RK4 and Verlet;
- checkpoint (no target) = the same slope for the RK4 blocks with a checkpoint: the run's bytes
  a node with what a checkpoint adds at its moment (its records' buffer is at most 16 MB, so
  the slope counts it only up to about 2.6e5 nodes);
- size ratio = node-steps/s at 1e6 nodes / node-steps/s at 1e5 (RK4, Verlet);
- nonlinear ratio = elastic node-steps/s / nonlinear node-steps/s, same scene and build;
- damped (no target; the runs of the nonlinear ratio's elastic cantilever, mass-damped): its
  node-steps/s, RK4 and Verlet, so that the damping's own costs, which the undamped blocks
  never run, are seen as well; and the RK4 block of 1e5 nodes with capped stiffness damping
  (3 % at 50 Hz, cap 500 Hz: 6 values a node), about 90 steps;
- fracture idle ratio = elastic node-steps/s / node-steps/s with fracture on (nothing failed),
  in tension and with every criterion;
- weak scaling on 2 ranks = per-rank node-steps/s on 2 ranks with 2x the nodes / node-steps/s
  of the 1e5 block on 1 rank (optional, --weak: it needs 2 idle cores);
- two runs at once (no target) = the mean node-steps/s of the two 1-rank runs of the 1e5 block
  started together / node-steps/s of the 1e5 block run alone: what 2 ranks would reach with
  no halo and no waiting for each other, so that weak scaling can be read against it;
- weak scaling / two runs at once (no target): per repetition, the 2-rank run's per-rank
  node-steps/s over the mean of that repetition's two runs at once: what the halo and the
  ranks' waits for each other take, the shared cache and memory left out.
Targets: force >= 3.5x old, RK4 >= 3x old and <= 130 bytes a node, Verlet >= 2.5x old and
<= 90 bytes a node (the ratios on the median of the paired ratios, the bytes on the new
build's median); size >= 0.80, nonlinear <= 2, fracture idle <= 1.05 (our reading of "no
measurable cost"), weak >= 0.97 for the new build (the old build's verdict is shown beside).
The machine's noise enters every ratio: compare within one run of the script.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import re
import statistics
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fracture_cost  # noqa: E402
import iembench as ib  # noqa: E402
import nonlinear_cost  # noqa: E402
from throughput import block_case, run_nml, run_pair  # noqa: E402

MEASURES = ("force", "rk4", "verlet", "memory", "checkpoint", "size", "nonlinear", "damped",
            "fracture", "weak")
DEFAULT = MEASURES[:-1]
QUICK = ("force", "rk4", "verlet", "nonlinear", "damped", "fracture")
EVALS_PER_STEP = {"rk4": 4, "verlet": 1}


# ---------------------------------------------------------------------------------------------
# figures of one run and of one repetition
# ---------------------------------------------------------------------------------------------

def step_rate(r: dict) -> float:
    """node-steps/s of a run, the time loop's share in output left out."""
    return r["rate"] / (1.0 - r["output"] / 100.0)


def force_rate(r: dict, integrator: str) -> float:
    """cells/s of the force alone: evaluations x cells / time in force evaluation."""
    return EVALS_PER_STEP[integrator] * r["steps"] * r["cells"] / (r["wall"] * r["force"] / 100.0)


def bytes_per_node(small: dict, large: dict) -> float:
    """Slope of the peak memory per rank (MB = 2^20 bytes) between two 1-rank runs."""
    return (large["mem_rank"] - small["mem_rank"]) * 1048576.0 / (large["nodes"] - small["nodes"])


@dataclass(frozen=True)
class Target:
    """A target: `scope` 'ratio' applies to the median of the paired ratios new/old,
    'new' to the new build's median (the old build's verdict shown beside)."""
    scope: str
    op: str
    value: float

    def met(self, x: float) -> bool:
        """Whether x meets the target."""
        return x >= self.value if self.op == ">=" else x <= self.value

    def text(self) -> str:
        """The target as the table shows it."""
        return f"{'new/old ' if self.scope == 'ratio' else ''}{self.op} {self.value:g}"


@dataclass(frozen=True)
class Measure:
    """One row of the table: the cases it needs and its figure from one repetition's runs
    of one build (`get(case)` gives that run's report)."""
    key: str
    label: str
    cases: tuple[str, ...]
    figure: Callable[[Callable[[str], dict]], float]
    fmt: str
    target: Target | None


ROWS = (
    Measure("force", "force: cells/s of the force alone (RK4, block 1e5)", ("rk4_1e5",),
            lambda g: force_rate(g("rk4_1e5"), "rk4"), ".3e", Target("ratio", ">=", 3.5)),
    Measure("force", "force, bending-corrected cell (RK4, block 1e5)", ("rk4_bending_1e5",),
            lambda g: force_rate(g("rk4_bending_1e5"), "rk4"), ".3e", Target("ratio", ">=", 3.5)),
    Measure("force", "force, body of 1e5 nodes with 8 round holes (RK4)", ("rk4_holes_1e5",),
            lambda g: force_rate(g("rk4_holes_1e5"), "rk4"), ".3e", Target("ratio", ">=", 3.5)),
    Measure("force", "force, the same body with 8 square holes (RK4)", ("rk4_squares_1e5",),
            lambda g: force_rate(g("rk4_squares_1e5"), "rk4"), ".3e", None),
    Measure("rk4", "RK4 node-steps/s (block 1e5)", ("rk4_1e5",),
            lambda g: step_rate(g("rk4_1e5")), ".3e", Target("ratio", ">=", 3.0)),
    Measure("verlet", "Verlet node-steps/s (block 1e5)", ("verlet_1e5",),
            lambda g: step_rate(g("verlet_1e5")), ".3e", Target("ratio", ">=", 2.5)),
    Measure("memory", "RK4 bytes per node (1e5 to 1e6)", ("rk4_1e5", "rk4_1e6"),
            lambda g: bytes_per_node(g("rk4_1e5"), g("rk4_1e6")), ".0f", Target("new", "<=", 130)),
    Measure("memory", "Verlet bytes per node (1e5 to 1e6)", ("verlet_1e5", "verlet_1e6"),
            lambda g: bytes_per_node(g("verlet_1e5"), g("verlet_1e6")), ".0f",
            Target("new", "<=", 90)),
    Measure("checkpoint", "RK4 bytes per node with a checkpoint (1e5 to 1e6)",
            ("rk4_ck_1e5", "rk4_ck_1e6"),
            lambda g: bytes_per_node(g("rk4_ck_1e5"), g("rk4_ck_1e6")), ".0f", None),
    Measure("size", "RK4 size ratio: rate 1e6 / rate 1e5", ("rk4_1e5", "rk4_1e6"),
            lambda g: step_rate(g("rk4_1e6")) / step_rate(g("rk4_1e5")), ".3f",
            Target("new", ">=", 0.80)),
    Measure("size", "Verlet size ratio: rate 1e6 / rate 1e5", ("verlet_1e5", "verlet_1e6"),
            lambda g: step_rate(g("verlet_1e6")) / step_rate(g("verlet_1e5")), ".3f",
            Target("new", ">=", 0.80)),
    Measure("nonlinear", "RK4 nonlinear ratio: elastic / nonlinear rate",
            ("nl_rk4_elastic", "nl_rk4_nonlinear"),
            lambda g: step_rate(g("nl_rk4_elastic")) / step_rate(g("nl_rk4_nonlinear")), ".3f",
            Target("new", "<=", 2.0)),
    Measure("nonlinear", "Verlet nonlinear ratio: elastic / nonlinear rate",
            ("nl_verlet_elastic", "nl_verlet_nonlinear"),
            lambda g: step_rate(g("nl_verlet_elastic")) / step_rate(g("nl_verlet_nonlinear")),
            ".3f", Target("new", "<=", 2.0)),
    Measure("damped", "RK4 node-steps/s, damped elastic cantilever (729 nodes)",
            ("nl_rk4_elastic",), lambda g: step_rate(g("nl_rk4_elastic")), ".3e", None),
    Measure("damped", "Verlet node-steps/s, damped elastic cantilever (729 nodes)",
            ("nl_verlet_elastic",), lambda g: step_rate(g("nl_verlet_elastic")), ".3e", None),
    Measure("damped", "RK4 node-steps/s, capped damping (block 1e5)", ("rk4_capped_1e5",),
            lambda g: step_rate(g("rk4_capped_1e5")), ".3e", None),
    Measure("fracture", "RK4 fracture idle ratio: elastic / fracture-on rate",
            ("fr_rk4_elastic", "fr_rk4_fracture"),
            lambda g: step_rate(g("fr_rk4_elastic")) / step_rate(g("fr_rk4_fracture")), ".3f",
            Target("new", "<=", 1.05)),
    Measure("fracture", "Verlet fracture idle ratio: elastic / fracture-on rate",
            ("fr_verlet_elastic", "fr_verlet_fracture"),
            lambda g: step_rate(g("fr_verlet_elastic")) / step_rate(g("fr_verlet_fracture")),
            ".3f", Target("new", "<=", 1.05)),
    Measure("fracture", "RK4 fracture idle ratio, every criterion",
            ("fr_rk4_elastic", "fr_rk4_every"),
            lambda g: step_rate(g("fr_rk4_elastic")) / step_rate(g("fr_rk4_every")), ".3f",
            Target("new", "<=", 1.05)),
    Measure("fracture", "Verlet fracture idle ratio, every criterion",
            ("fr_verlet_elastic", "fr_verlet_every"),
            lambda g: step_rate(g("fr_verlet_elastic")) / step_rate(g("fr_verlet_every")),
            ".3f", Target("new", "<=", 1.05)),
    Measure("weak", "RK4 weak scaling, 2 ranks (1e5 nodes a rank)", ("rk4_1e5", "weak_rk4_2"),
            lambda g: step_rate(g("weak_rk4_2")) / 2.0 / step_rate(g("rk4_1e5")), ".3f",
            Target("new", ">=", 0.97)),
    Measure("weak", "RK4 two 1-rank runs of the 1e5 block at once: rate / alone",
            ("rk4_1e5", "pair_rk4_1e5"),
            lambda g: step_rate(g("pair_rk4_1e5")) / step_rate(g("rk4_1e5")), ".3f", None),
    Measure("weak", "RK4 weak scaling / two runs at once (of one repetition)",
            ("weak_rk4_2", "pair_rk4_1e5"),
            lambda g: step_rate(g("weak_rk4_2")) / 2.0 / step_rate(g("pair_rk4_1e5")), ".3f",
            None),
)


# ---------------------------------------------------------------------------------------------
# summary and table
# ---------------------------------------------------------------------------------------------

def spread(xs: list[float], fmt: str) -> str:
    """median [min, max] of a non-empty list."""
    return f"{statistics.median(xs):{fmt}} [{min(xs):{fmt}}, {max(xs):{fmt}}]"


def table_row(m: Measure, old: list[float], new: list[float]) -> str:
    """The Markdown row of a measure from its per-repetition figures of each build."""
    ratios = [n / o for o, n in zip(old, new)]
    t = m.target
    if t is None:
        return (f"| {m.label} | {spread(old, m.fmt)} | {spread(new, m.fmt)} | "
                f"{spread(ratios, '.3f')} | none | - |")
    if t.scope == "ratio":
        met = "yes" if t.met(statistics.median(ratios)) else "no"
    else:
        verdict = lambda xs: "yes" if t.met(statistics.median(xs)) else "no"  # noqa: E731
        met = f"{verdict(new)} (old: {verdict(old)})"
    return (f"| {m.label} | {spread(old, m.fmt)} | {spread(new, m.fmt)} | "
            f"{spread(ratios, '.3f')} | {t.text()} | {met} |")


def table(rows: list[tuple[Measure, list[float], list[float]]]) -> str:
    """The Markdown table of every measure."""
    head = ("| measure | old: median [min, max] | new: median [min, max] | "
            "new/old: median of paired ratios [min, max] | target | met? |\n"
            "|---|---|---|---|---|---|")
    return "\n".join([head] + [table_row(m, old, new) for m, old, new in rows])


# ---------------------------------------------------------------------------------------------
# cases
# ---------------------------------------------------------------------------------------------

def with_holes(text: str) -> str:
    """A block case (2 x 1) with 8 round holes of radius 0.15 cut out (void), centred on a
    4 x 2 pattern of pitch 0.5: 28 % of the cells void, the rows' chunks ended at the holes."""
    holes = "".join(f"&shape\n  name = 'hole{4 * j + i + 1}', kind = 'circle', "
                    f"center = {0.25 + 0.5 * i}, {0.25 + 0.5 * j}, radius = 0.15, "
                    "material = 'void'\n/\n" for j in range(2) for i in range(4))
    return text.replace("&bc", holes + "&bc", 1)


def with_square_holes(text: str) -> str:
    """with_holes with square holes of the holes' area and centres (side 0.2658): the rows
    they cut end their chunks at the same columns from one grid row to the next."""
    half = 0.5 * math.sqrt(math.pi) * 0.15
    holes = "".join(f"&shape\n  name = 'hole{4 * j + i + 1}', kind = 'rectangle', "
                    f"box = {0.25 + 0.5 * i - half:.6f}, {0.25 + 0.5 * i + half:.6f}, "
                    f"{0.25 + 0.5 * j - half:.6f}, {0.25 + 0.5 * j + half:.6f}, "
                    "material = 'void'\n/\n" for j in range(2) for i in range(4))
    return text.replace("&bc", holes + "&bc", 1)


def with_checkpoint(text: str, path: Path) -> str:
    """A block case with one checkpoint half way (to path)."""
    t_end = float(re.search(r"t_end = ([0-9.eE+-]+)", text)[1])
    return text.replace("&run\n", f"&run\n  checkpoint_interval = {0.5 * t_end:.6e}, "
                        f"checkpoint_file = '{path}'\n", 1)


def with_capped_damping(text: str) -> str:
    """A block case with capped stiffness damping: 3 % at 50 Hz, faded above 500 Hz."""
    damping = ("&damping\n  kind = 'capped', ratio = 0.03, frequency = 50.0, "
               "cap_frequency = 500.0\n/\n")
    return text.replace("&bc", damping + "&bc", 1)


def write_cases(names: list[str], folder: Path, scale: float) -> dict[str, tuple[Path, int]]:
    """Write the namelist of each case into folder: name -> (namelist, ranks)."""
    out = {}
    nl_scene = nonlinear_cost.SCENE.read_text()
    for name in names:
        nml, ranks = folder / f"{name}.nml", 1
        if name in ("rk4_1e5", "verlet_1e5", "pair_rk4_1e5"):
            integ = "verlet" if name == "verlet_1e5" else "rk4"
            text = block_case(1e5, (4e7 if integ == "rk4" else 8e7) * scale, "paper", integ)[0]
        elif name == "rk4_capped_1e5":
            # capped stiffness damping (6 values a node); about 90 steps, its step being
            # shorter than the undamped block's
            text = with_capped_damping(block_case(1e5, 1.4e7 * scale, "paper", "rk4")[0])
        elif name == "rk4_bending_1e5":
            text = block_case(1e5, 4e7 * scale, "bending", "rk4")[0]
        elif name == "rk4_holes_1e5":
            # a grid of 1.37e5 nodes, so that the body, 72 % of it, has about 1e5 nodes as
            # the other blocks (a smaller body would sit better in the caches)
            text = with_holes(block_case(1.37e5, 4e7 * scale / 0.72, "paper", "rk4")[0])
        elif name == "rk4_squares_1e5":
            text = with_square_holes(block_case(1.37e5, 4e7 * scale / 0.72, "paper", "rk4")[0])
        elif name in ("rk4_ck_1e5", "rk4_ck_1e6"):
            # the RK4 blocks of memory with one checkpoint half way
            n, work = (1e5, 4e7) if name == "rk4_ck_1e5" else (1e6, 2e8)
            text = with_checkpoint(block_case(n, work * scale, "paper", "rk4")[0],
                                   folder / f"{name}.chk")
        elif name in ("rk4_1e6", "verlet_1e6"):
            # 200 nominal steps: about 100 (block_case's step is about half the stable step;
            # the run takes 0.9 of it). Not fewer: a run's fixed costs (its first evaluation,
            # the history samples at both ends, the steps that read the state) took 8% of a
            # 25-step Verlet run's loop here, against under 1% of the 388 steps of the 1e5 block
            text = block_case(1e6, 2e8 * scale, "paper", name.split("_")[0])[0]
        elif name == "weak_rk4_2":
            text, ranks = block_case(2e5, 2 * 4e7 * scale, "paper", "rk4")[0], 2
        elif name.startswith("nl_"):
            _, integ, kind = name.split("_")
            # the elastic variant runs 4 times as long (else its loop lasts 0.1 s); its rate
            # does not depend on the duration
            t_end = (0.01 if kind == "nonlinear" else 0.04) * scale
            text = nonlinear_cost.variant(nl_scene, kind == "nonlinear", integ, t_end)
        elif name.startswith("fr_"):
            _, integ, kind = name.split("_")
            text = fracture_cost.scene(1000, integ, kind != "elastic", folder / f"{name}.h5",
                                       every=kind == "every")
            # about 200 RK4 steps (130 Verlet) instead of the script's 300
            text = re.sub(r"t_end = ([0-9.eE+-]+)",
                          lambda t: f"t_end = {float(t[1]) * 2 / 3 * scale:.6e}", text, count=1)
        else:
            raise ValueError(name)
        nml.write_text(text)
        out[name] = (nml, ranks)
    return out


def both(pair: list[dict]) -> dict:
    """The report of two runs at once as one run's: the first run's, with the mean of their
    node-steps/s (output left out) as its rate, and both reports under 'pair'."""
    return dict(pair[0], rate=statistics.mean(step_rate(p) for p in pair), output=0.0, pair=pair)


def two_cores() -> tuple[int, int]:
    """The first two processors this process may run on."""
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) < 2:
        raise SystemExit("two runs at once need two processors; this process may use one")
    return cpus[0], cpus[1]


def main() -> int:
    """Run the cases interleaved and print the table."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--iem", required=True, help="the new iem executable")
    ap.add_argument("--baseline", required=True, metavar="OLD_IEM", help="the old iem executable")
    ap.add_argument("--repeat", type=int, help="runs of each case and build (5; --quick: 3)")
    ap.add_argument("--quick", action="store_true",
                    help="3 repeats, half the work, without memory and size (1e6 nodes)")
    ap.add_argument("--only", help="comma-separated measures: " + ",".join(MEASURES))
    ap.add_argument("--weak", action="store_true", help="add weak scaling on 2 ranks")
    ap.add_argument("--mpiexec", default="mpirun")
    ap.add_argument("--save", metavar="JSON", help="write every run's report to this file")
    args = ap.parse_args()
    if args.only:
        keys = [k.strip() for k in args.only.split(",") if k.strip()]
        bad = [k for k in keys if k not in MEASURES]
        if bad or not keys:
            ap.error(f"--only: unknown measure(s) {','.join(bad)}; known: {','.join(MEASURES)}")
    else:
        keys = list(QUICK if args.quick else DEFAULT)
    if args.weak and "weak" not in keys:
        keys.append("weak")
    repeat = args.repeat if args.repeat is not None else (3 if args.quick else 5)
    if repeat < 1:
        ap.error("--repeat must be at least 1")
    scale = 0.5 if args.quick else 1.0
    exes = [("old", str(Path(args.baseline).resolve())), ("new", str(Path(args.iem).resolve()))]
    for which, exe in exes:
        if not Path(exe).is_file():
            ap.error(f"{which} executable {exe} not found")
    rows = [m for m in ROWS if m.key in keys]
    names = list(dict.fromkeys(c for m in rows for c in m.cases))

    runs: dict[tuple[str, str], list[dict]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        cases = write_cases(names, Path(tmp), scale)
        for rep in range(repeat):
            for name in names:
                nml, ranks = cases[name]
                for which, exe in exes:
                    if name == "pair_rk4_1e5":
                        r = both(run_pair(exe, nml, args.mpiexec, Path(tmp), two_cores()))
                    else:
                        r = run_nml(exe, nml, ranks, args.mpiexec, Path(tmp))
                    if name.startswith("fr_") and not name.endswith("elastic") and \
                            fracture_cost.dissipated(Path(tmp) / f"{name}.h5") != 0.0:
                        raise SystemExit(f"{name}, {which}: a spring failed; the comparison is "
                                         "not of an idle fracture state")
                    runs.setdefault((name, which), []).append(r)
                    how = "2 runs of 1 rank" if "pair" in r else f"{ranks} ranks"
                    print(f"# {rep + 1}/{repeat} {name} ({r['nodes']:,} nodes, {how}), "
                          f"{which}: {step_rate(r):.3e} node-steps/s, loop {r['wall']:.2f} s",
                          file=sys.stderr, flush=True)

    figures = []
    for m in rows:
        per = {which: [m.figure(lambda c, w=which, i=i: runs[(c, w)][i]) for i in range(repeat)]
               for which, _ in exes}
        figures.append((m, per["old"], per["new"]))
    print(f"Machine: {ib.machine()}. {repeat} interleaved runs of each case and build"
          f"{' (--quick: half the work)' if args.quick else ''}, {', '.join(keys)}.")
    for which, exe in exes:
        print(f"- {which}: {exe} ({ib.build_info(exe)})")
    print()
    print(table(figures))
    if args.save:
        Path(args.save).write_text(json.dumps(
            {"binaries": dict(exes), "repeat": repeat, "quick": args.quick, "measures": keys,
             "runs": {f"{n} {w}": rs for (n, w), rs in runs.items()},
             "figures": {m.label: {"old": o, "new": n} for m, o, n in figures}}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
