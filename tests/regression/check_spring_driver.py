#!/usr/bin/env python3
"""Check iem-spring (one nonlinear spring through a strain history, docs/nonlinear.md).

Runs the tool on a history file and checks that
* there is one "strain stress" line per history value, strains echoed exactly;
* the first line is the skeleton value (virgin loading);
* every stress matches a small Python model of the state machine in docs/nonlinear.md;
* -smax_neg < stress < smax_pos;
* committing each change in 7 substeps gives the same stresses at the history points;
* bad input (missing file, malformed number, missing or invalid options) gives a one-line
  message naming the problem and a non-zero exit.
Exits 1 with a message at the first failed check.
"""
import argparse
import os
import subprocess
import sys
import tempfile

EMAX, SMAX_POS, SMAX_NEG = 30e9, 3e6, 30e6
RTOL = 1e-9  # of the larger strength


def fail(msg):
    print(f"spring_driver: FAILED: {msg}")
    sys.exit(1)


def hyperbola(x, emax, smax):
    return emax * x / (1.0 + emax * abs(x) / smax)


def skeleton(e, emax, sp, sn):
    return hyperbola(e, emax, sp if e >= 0 else sn)


class Spring:
    """The state machine of docs/nonlinear.md, written again from the document."""

    def __init__(self, emax, sp, sn, depth=8):
        self.emax, self.sp, self.sn, self.depth = emax, sp, sn, depth
        self.sb = 0.5 * (sp + sn)
        self.e, self.s, self.dir, self.stack = 0.0, 0.0, 0, []

    def mirror(self, e1):
        return -e1 * (self.sn / self.sp) if e1 >= 0 else -e1 * (self.sp / self.sn)

    def level(self, stack, k):
        e0, s0 = stack[k - 1]
        if k >= 2:
            aim = stack[k - 2][0]
            d = 1 if aim > e0 else -1
        else:
            aim = self.mirror(e0)
            d = -1 if e0 > 0 else 1
        return e0, s0, d, aim

    def commit(self, e):
        if e == self.e:
            return self.s
        m = 1 if e > self.e else -1
        stack = list(self.stack)
        if self.dir != 0 and m == -self.dir and len(stack) < self.depth:
            stack.append((self.e, self.s))
        k = len(stack)
        while k > 0:
            e0, _, d, aim = self.level(stack, k)
            if m == d:
                if d * (e - aim) < 0:
                    break
                k = max(k - 2, 0)
            else:
                if d * (e - e0) > 0:
                    break
                k -= 1
        del stack[k:]
        if k == 0:
            s = skeleton(e, self.emax, self.sp, self.sn)
        else:
            e0, s0 = stack[-1]
            s = s0 + 2.0 * hyperbola(0.5 * (e - e0), self.emax, self.sb)
        self.e, self.s, self.dir, self.stack = e, s, m, stack
        return s


def read_history(path):
    values = []
    with open(path) as f:
        for line in f:
            t = line.strip()
            if t and not t.startswith("#"):
                values.append(float(t))
    return values


def run(tool, args):
    return subprocess.run([tool] + args, capture_output=True, text=True, timeout=60)


def parse_output(text):
    rows = []
    for line in text.splitlines():
        parts = line.split()
        if len(parts) != 2:
            fail(f"output line is not 'strain stress': {line!r}")
        rows.append((float(parts[0]), float(parts[1])))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--iem-spring", required=True)
    ap.add_argument("--history", required=True)
    a = ap.parse_args()
    opts = ["--emax", str(EMAX), "--smax-pos", str(SMAX_POS), "--smax-neg", str(SMAX_NEG)]
    tol = RTOL * max(SMAX_POS, SMAX_NEG)

    hist = read_history(a.history)
    r = run(a.iem_spring, [a.history] + opts)
    if r.returncode != 0:
        fail(f"iem-spring exited {r.returncode}: {r.stderr.strip()}")
    rows = parse_output(r.stdout)
    if len(rows) != len(hist):
        fail(f"{len(rows)} output lines for {len(hist)} history values")
    first = skeleton(hist[0], EMAX, SMAX_POS, SMAX_NEG)
    if abs(rows[0][1] - first) > tol:
        fail(f"first stress {rows[0][1]!r} is not the skeleton value {first!r}")
    ref = Spring(EMAX, SMAX_POS, SMAX_NEG)
    for i, ((e, s), h) in enumerate(zip(rows, hist), start=1):
        if abs(e - h) > 1e-15 * max(abs(h), 1e-30):
            fail(f"value {i}: strain {e!r} echoed for {h!r}")
        if not -SMAX_NEG < s < SMAX_POS:
            fail(f"value {i}: stress {s!r} outside (-smax_neg, smax_pos)")
        sr = ref.commit(h)
        if abs(s - sr) > tol:
            fail(f"value {i} (strain {h!r}): stress {s!r}, the model of the doc gives {sr!r}")

    r = run(a.iem_spring, [a.history] + opts + ["--substeps", "7"])
    if r.returncode != 0:
        fail(f"iem-spring --substeps 7 exited {r.returncode}: {r.stderr.strip()}")
    sub = parse_output(r.stdout)
    if len(sub) != 7 * len(hist):
        fail(f"--substeps 7: {len(sub)} lines for {len(hist)} values")
    for i, (e, s) in enumerate(sub[6::7], start=1):
        if abs(s - rows[i - 1][1]) > tol:
            fail(f"--substeps 7 changes the stress at value {i}: {s!r} against {rows[i - 1][1]!r}")

    with tempfile.TemporaryDirectory() as tmp:
        bad = os.path.join(tmp, "bad.txt")
        with open(bad, "w") as f:
            f.write("# header\n1e-4\n\n2e-4\n3e-4x\n")
        empty = os.path.join(tmp, "empty.txt")
        with open(empty, "w") as f:
            f.write("# nothing\n\n")
        cases = [
            ([os.path.join(tmp, "missing.txt")] + opts, "cannot open"),
            ([bad] + opts, "line 5"),
            ([empty] + opts, "no strain values"),
            ([a.history, "--smax-pos", "3e6", "--smax-neg", "3e7"], "--emax is missing"),
            ([a.history, "--emax", "-1", "--smax-pos", "3e6", "--smax-neg", "3e7"],
             "--emax must be > 0"),
            ([a.history, "--emax", "3e10", "--smax-pos", "0", "--smax-neg", "3e7"],
             "--smax-pos must be > 0"),
            ([a.history, "--emax", "3e10", "--smax-pos", "3e6", "--smax-neg", "abc"],
             "--smax-neg needs a number"),
            ([a.history] + opts + ["--substeps", "0"], "--substeps"),
            ([a.history] + opts + ["--bogus"], "unknown option"),
            (opts, "no history file"),
        ]
        for args, expect in cases:
            r = run(a.iem_spring, args)
            err = r.stderr.strip()
            if r.returncode == 0:
                fail(f"iem-spring {' '.join(args)} exited 0")
            if expect not in err or len(err.splitlines()) != 1 or not err.startswith("iem-spring:"):
                fail(f"iem-spring {' '.join(args)}: expected one line with {expect!r}, got {err!r}")
    print(f"spring_driver: OK ({len(hist)} values, {len(cases)} error cases)")


if __name__ == "__main__":
    main()
