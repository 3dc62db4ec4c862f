"""benchmarks/speed.py on canned end-of-run reports: its figures, paired ratios and table."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import speed  # noqa: E402


def report(**kw) -> dict:
    """A parsed iem report (throughput.run_nml's keys) with the given values."""
    r = {"nodes": 101025, "ranks": 1, "cells": 100352, "steps": 200, "wall": 2.0,
         "rate": 1.0e7, "force": 75.0, "halo": 0.0, "update": 20.0, "output": 5.0,
         "mem_rank": 50.0}
    r.update(kw)
    return r


def test_step_rate_leaves_out_output():
    assert speed.step_rate(report(rate=9.0e6, output=10.0)) == pytest.approx(1.0e7)


def test_force_rate_counts_evaluations_per_step():
    r = report(steps=200, cells=100352, wall=2.0, force=75.0)
    assert speed.force_rate(r, "rk4") == pytest.approx(4 * 200 * 100352 / 1.5)
    assert speed.force_rate(r, "verlet") == pytest.approx(200 * 100352 / 1.5)


def test_bytes_per_node_is_the_slope():
    small = report(nodes=101025, mem_rank=50.0)
    large = report(nodes=1001820, mem_rank=160.0)
    assert speed.bytes_per_node(small, large) == pytest.approx(110.0 * 1048576 / 900795)


def test_row_uses_the_median_of_paired_ratios():
    m = next(m for m in speed.ROWS if m.key == "rk4")
    # paired ratios 4, 2, 2.5: median 2.5 (the ratio of the medians would be 2)
    row = speed.table_row(m, [1.0, 2.0, 4.0], [4.0, 4.0, 10.0])
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[3] == "2.500 [2.000, 4.000]"
    assert cells[4] == "new/old >= 3"
    assert cells[5] == "no"
    assert speed.table_row(m, [1.0, 2.0, 4.0], [4.0, 6.0, 14.0]).endswith("| yes |")


def test_row_of_a_per_build_target_gives_both_verdicts():
    m = next(m for m in speed.ROWS if m.label.startswith("RK4 bytes"))
    row = speed.table_row(m, [200.0, 180.0, 190.0], [120.0, 140.0, 125.0])
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[1] == "190 [180, 200]"
    assert cells[2] == "125 [120, 140]"
    assert cells[4] == "<= 130"
    assert cells[5] == "yes (old: no)"
    m = next(m for m in speed.ROWS if m.key == "weak")
    assert speed.table_row(m, [0.98] * 3, [0.96] * 3).endswith("| no (old: yes) |")


def test_row_without_a_target_gives_no_verdict():
    m = next(m for m in speed.ROWS if m.key == "damped")
    assert m.target is None
    row = speed.table_row(m, [1.0e7, 1.2e7, 0.8e7], [1.2e7, 1.2e7, 1.2e7])
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[3] == "1.200 [1.000, 1.500]"
    assert cells[4:] == ["none", "-"]
    runs = {"nl_rk4_elastic": report(rate=9.0e6, output=10.0)}
    assert m.figure(runs.__getitem__) == pytest.approx(1.0e7)


def test_figures_of_a_repetition_pair_its_runs():
    m = next(m for m in speed.ROWS if m.label.startswith("Verlet size"))
    runs = {"verlet_1e5": report(rate=4.0e7, output=0.0),
            "verlet_1e6": report(rate=3.0e7, output=0.0, nodes=1001820)}
    assert m.figure(runs.__getitem__) == pytest.approx(0.75)
    m = next(m for m in speed.ROWS if m.key == "weak")
    runs = {"rk4_1e5": report(rate=1.0e7, output=0.0),
            "weak_rk4_2": report(rate=1.9e7, output=0.0, ranks=2)}
    assert m.figure(runs.__getitem__) == pytest.approx(0.95)


def test_table_has_a_row_per_measure():
    rows = [(m, [1.0, 1.0], [2.0, 2.0]) for m in speed.ROWS]
    lines = speed.table(rows).splitlines()
    assert len(lines) == 2 + len(speed.ROWS)
    assert all(line.count("|") == 7 for line in lines)


def test_two_runs_at_once_are_read_against_the_run_alone():
    pair = [report(rate=9.0e6, output=10.0), report(rate=6.0e6, output=0.0)]
    r = speed.both(pair)
    # the mean of the two rates with output left out: (1.0e7 + 0.6e7) / 2
    assert speed.step_rate(r) == pytest.approx(8.0e6)
    assert r["pair"] == pair
    m = next(m for m in speed.ROWS if m.label.startswith("RK4 two 1-rank runs"))
    assert m.target is None
    runs = {"rk4_1e5": report(rate=1.0e7, output=0.0), "pair_rk4_1e5": r}
    assert m.figure(runs.__getitem__) == pytest.approx(0.8)


def test_weak_scaling_is_read_against_two_runs_at_once():
    m = next(m for m in speed.ROWS if m.label.startswith("RK4 weak scaling / two runs"))
    assert m.target is None
    pair = speed.both([report(rate=8.0e6, output=0.0), report(rate=1.0e7, output=0.0)])
    runs = {"weak_rk4_2": report(rate=1.44e7, output=0.0, ranks=2), "pair_rk4_1e5": pair}
    # per rank 0.72e7 over the pair's mean 0.9e7
    assert m.figure(runs.__getitem__) == pytest.approx(0.8)
    # the 1-rank run alone does not enter it
    assert "rk4_1e5" not in m.cases


def test_square_holes_have_the_round_holes_area_and_centres():
    block = "&run\n/\n&bc\n  where = 'left'\n/\n"
    text = speed.with_square_holes(block)
    assert text.count("kind = 'rectangle'") == 8
    assert text.index("&shape") < text.index("&bc")
    boxes = [[float(v) for v in line.split("box =", 1)[1].split(",")[:4]]
             for line in text.splitlines() if "box =" in line]
    centres = {(round(0.5 * (b[0] + b[1]), 4), round(0.5 * (b[2] + b[3]), 4)) for b in boxes}
    assert centres == {(0.25 + 0.5 * i, 0.25 + 0.5 * j) for i in range(4) for j in range(2)}
    for x0, x1, y0, y1 in boxes:
        assert (x1 - x0) * (y1 - y0) == pytest.approx(3.141592653589793 * 0.15**2, rel=1e-5)
    # the round holes' case names the same centres
    assert speed.with_holes(block).count("kind = 'circle'") == 8


def test_checkpoint_case_writes_one_half_way():
    block = "&run\n  t_end = 2.0e-04, output_interval = 2.0e-04\n/\n&bc\n/\n"
    text = speed.with_checkpoint(block, speed.Path("/tmp/x.chk"))
    run = text.split("/\n", 1)[0]
    assert "checkpoint_interval = 1.000000e-04" in run
    assert "checkpoint_file = '/tmp/x.chk'" in run
    # the measure reads the slope of the peaks of the two blocks with a checkpoint
    m = next(r for r in speed.ROWS if r.key == "checkpoint")
    assert m.cases == ("rk4_ck_1e5", "rk4_ck_1e6") and m.target is None
