#!/usr/bin/env python3
"""Partition quality: iem's weighted coordinate bisection against METIS k-way.

iem partitions every body by recursive coordinate bisection (RCB) of its grid nodes, weighted
by the nodes that exist (src/parallel/iem_rcb.f90, rcb_init_weighted; a full rectangle by node
counts alone, rcb_init). This script measures what METIS's refinement would buy: for each
scene and part count P it runs iem on P ranks for a few time steps, reads the body from the
run's output (/mesh/cells, /mesh/coordinates), partitions the same node graph (two nodes
adjacent when they share a cell, as iem's halo is built) with METIS_PartGraphKway (default
options, ncon = 1, no weights) through a small C program compiled on the fly
(`cc -O2 ... -lmetis`), and prints for both partitions
- imbalance: largest / mean owned nodes of a part;
- halo: sum over the parts of the nodes outside the part that share a cell with a node of it
  (the halo nodes every rank receives each exchange).
A second METIS column uses the same call with `METIS_OPTION_OBJTYPE = METIS_OBJTYPE_VOL`
(least total communication volume, which is exactly this halo; the script checks METIS's
reported volume against its own count), the fairer opponent: the default objective is the
edge cut, and on this graph (every node joined to its 8 neighbours) the cut is not the halo.

Our partition's figures come from iem's log line `partition: P ranks, largest/mean owned
nodes X, halo nodes H (F of the nodes)` when the build prints it; the output file does not
record the owner of a node, so the script also recomputes the bisection from the body's nodes
(the same cuts: the low side's node count nearest its share, ties to the lower cut, across the
longer side of the box) and its halo, and checks it against the log line where there is one.
The column `src` says where our figures come from (`log`, or `rcb` for the recomputation;
the recomputation was checked node by node against iem_rcb's owner() for every scene here).

Static scenes are run as dynamic ones (their `&static` group and `analysis` dropped): the
partition does not depend on the analysis. `t_end` is set to about three automatic time steps
(from the cell size and the stiffest material's wave speed), output goes to a temporary
folder. Usage (from the repository root, after building):

    python3 benchmarks/partition_quality.py [--iem build/iem] [--ranks 2 4 8 16]
        [--scenes inputs/plate_hole.nml ...] [--mpiexec mpiexec]

Exit status 1 when iem or METIS fails (the message names the scene and the rank count).
"""
from __future__ import annotations

import argparse
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SCENES = [ROOT / "inputs" / "plate_hole.nml", ROOT / "inputs" / "notched_beam.nml",
          ROOT / "inputs" / "bimaterial_beam.nml", ROOT / "tests" / "data" / "image_body.nml"]
LOG_RE = re.compile(r"partition:\s*(\d+)\s*ranks,\s*largest/mean owned nodes\s*([0-9.eE+-]+),"
                    r"\s*halo nodes\s*(\d+)")

METIS_C = r"""
#include <stdio.h>
#include <stdlib.h>
#include <metis.h>
/* usage: prog graph.bin nparts part.bin cut|vol; graph.bin: int32 n, int32 nnz, xadj[n+1],
   adj[nnz]; prints METIS's objective (edge cut, or total communication volume) */
int main(int argc, char **argv) {
  if (argc != 5) { fprintf(stderr, "usage: %s graph nparts out cut|vol\n", argv[0]); return 2; }
  if (sizeof(idx_t) != 4) { fprintf(stderr, "idx_t is not 32-bit\n"); return 2; }
  FILE *f = fopen(argv[1], "rb");
  if (!f) { perror(argv[1]); return 2; }
  idx_t n, nnz;
  if (fread(&n, 4, 1, f) != 1 || fread(&nnz, 4, 1, f) != 1) {
    fprintf(stderr, "short graph file\n"); return 2;
  }
  idx_t *xadj = malloc(sizeof(idx_t) * (n + 1)), *adj = malloc(sizeof(idx_t) * (nnz + 1));
  idx_t *part = malloc(sizeof(idx_t) * n);
  if (fread(xadj, 4, n + 1, f) != (size_t)(n + 1) || fread(adj, 4, nnz, f) != (size_t)nnz) {
    fprintf(stderr, "short graph file\n"); return 2;
  }
  fclose(f);
  idx_t ncon = 1, nparts = atoi(argv[2]), objval = 0, options[METIS_NOPTIONS];
  METIS_SetDefaultOptions(options);
  if (argv[4][0] == 'v') options[METIS_OPTION_OBJTYPE] = METIS_OBJTYPE_VOL;
  int rc = METIS_PartGraphKway(&n, &ncon, xadj, adj, NULL, NULL, NULL, &nparts, NULL, NULL,
                               options, &objval, part);
  if (rc != METIS_OK) { fprintf(stderr, "METIS_PartGraphKway returned %d\n", rc); return 3; }
  f = fopen(argv[3], "wb");
  if (!f || fwrite(part, 4, n, f) != (size_t)n) { perror(argv[3]); return 2; }
  fclose(f);
  printf("%d\n", (int)objval);
  return 0;
}
"""


def fail(msg: str) -> None:
    print(f"partition_quality: error: {msg}", file=sys.stderr)
    sys.exit(1)


# ---- the scene: a copy that runs a few steps and writes to the temporary folder ----------

def groups(text: str) -> list[tuple[str, str]]:
    """(name, body) of every namelist group, comments removed."""
    clean = "\n".join(line.split("!", 1)[0] for line in text.splitlines())
    return [(m.group(1).lower(), m.group(2))
            for m in re.finditer(r"&(\w+)(.*?)^\s*/\s*$", clean, re.S | re.M)]


def real_of(body: str, key: str) -> float | None:
    m = re.search(rf"(?<![\w]){key}\s*=\s*([-+0-9.eEdD]+)", body)
    return float(m.group(1).replace("d", "e").replace("D", "e")) if m else None


def few_steps_t_end(text: str, nml: Path) -> float:
    """About three automatic time steps: the step is near h / c for the stiffest material
    (RK4 0.9 x 2 sqrt(2) / omega_max, cut to a whole number of steps), so take 3 h / c_max."""
    gs = groups(text)
    geo = next(b for n, b in gs if n == "geometry")
    length, height = real_of(geo, "length"), real_of(geo, "height")
    h = real_of(geo, "cell_size")
    if h is None:
        nx, ny = real_of(geo, "nx"), real_of(geo, "ny")
        if nx is None:   # an image: its width and height (plain or raw PGM/PBM header)
            img = re.search(r"image\s*=\s*['\"]([^'\"]+)['\"]", geo).group(1)
            head = (nml.parent / img).read_bytes()[:4096].decode("latin-1")
            head = "\n".join(line.split("#", 1)[0] for line in head.splitlines())
            nx, ny = (float(v) for v in head.split()[1:3])
        h = min(length / nx, height / ny)
    c = max(math.sqrt(real_of(b, "E") / real_of(b, "density")) for n, b in gs if n == "material")
    return 3.0 * h / c


def scene_copy(nml: Path, out_h5: Path) -> str:
    """The scene's text made dynamic, short and writing out_h5; an image path made absolute."""
    text = nml.read_text()
    try:
        t_end = few_steps_t_end(text, nml)
    except (StopIteration, AttributeError, TypeError, ValueError, ZeroDivisionError, OSError):
        t_end = 1.0e-7   # a scene this cannot read: iem says what is wrong with it
    lines, grp, out = text.splitlines(), None, []
    skip = False
    for line in lines:
        code = line.split("!", 1)[0]
        m = re.match(r"\s*&(\w+)", code)
        if m:
            grp = m.group(1).lower()
            skip = grp == "static"
        if skip:
            if re.match(r"\s*/\s*$", code):
                skip = False
            continue
        if grp == "run":
            if re.match(r"\s*(analysis|t_end|dt|output_interval|history_interval|output_file"
                        r"|overwrite|checkpoint_\w+)\s*=", code, re.I):
                continue
            if re.match(r"\s*/\s*$", code):
                out += [f"  t_end = {t_end:.6e}", f"  output_file = '{out_h5}'",
                        "  overwrite = .true."]
        if grp == "geometry":
            line = re.sub(r"(image\s*=\s*)(['\"])([^'\"]+)\2",
                          lambda m: f"{m.group(1)}'{(nml.parent / m.group(3)).resolve()}'", line)
        if re.match(r"\s*/\s*$", code):
            grp = None
        out.append(line)
    return "\n".join(out) + "\n"


def run_iem(args, nml: Path, ranks: int, work: Path) -> tuple[Path, str]:
    h5 = work / f"{nml.stem}_p{ranks}.h5"
    case = work / f"{nml.stem}_p{ranks}.nml"
    case.write_text(scene_copy(nml, h5))
    cmd = [args.mpiexec, "-n", str(ranks), "--oversubscribe", str(args.iem), str(case)]
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    try:
        p = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True,
                           timeout=args.timeout)
    except subprocess.TimeoutExpired:
        fail(f"iem on {nml.name}, {ranks} ranks: no end after {args.timeout} s ({' '.join(cmd)})")
    log = p.stdout + "\n" + p.stderr
    if p.returncode != 0 or not h5.is_file():
        errors = [line for line in log.splitlines() if line.startswith("iem: error")]
        tail = "\n".join(errors or log.strip().splitlines()[-8:])
        fail(f"iem on {nml.name}, {ranks} ranks, exit status {p.returncode} "
             f"({' '.join(cmd)}):\n{tail}")
    return h5, log


# ---- the body, its graph and the figures of a partition ----------------------------------

def read_body(h5: Path):
    with h5py.File(h5, "r") as f:
        cells = f["mesh/cells"][...].astype(np.int64)
        xy = f["mesh/coordinates"][...]
        a = f["mesh"].attrs
        nx, ny, lx, ly = int(a["nx"]), int(a["ny"]), float(a["lx"]), float(a["ly"])
        text = f.attrs["input_text"]
        text = text.decode() if isinstance(text, bytes) else str(text)
    ij = np.column_stack([np.rint(xy[:, 0] / lx), np.rint(xy[:, 1] / ly)]).astype(np.int64)
    geo = next(b for n, b in groups(text) if n == "geometry")
    uniform = not any(n == "shape" for n, _ in groups(text)) and "image" not in geo
    return cells, ij, nx, ny, uniform


def node_edges(cells: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Both directions (u, v) of every pair of distinct nodes that share a cell, unique."""
    pairs = [(a, b) for a in range(4) for b in range(4) if a != b]
    u = np.concatenate([cells[:, a] for a, _ in pairs])
    v = np.concatenate([cells[:, b] for _, b in pairs])
    key = np.unique(u * n + v)
    return key // n, key % n


def figures(part: np.ndarray, nparts: int, u: np.ndarray, v: np.ndarray):
    """(largest / mean owned nodes, halo nodes summed over the parts)."""
    counts = np.bincount(part, minlength=nparts)
    cross = part[u] != part[v]
    halo = np.unique(part[u[cross]].astype(np.int64) * len(part) + v[cross]).size
    return counts.max() / counts.mean(), int(halo)


def rcb_parts(ij: np.ndarray, ni: int, nj: int, nparts: int, uniform: bool) -> np.ndarray:
    """The owner of every node by iem's bisection (src/parallel/iem_rcb.f90): rcb_init for a
    full rectangle (when every part's box holds at least 2 nodes), else rcb_init_weighted
    with unit weights on the existing nodes."""
    part = np.full(len(ij), -1, dtype=np.int64)
    boxes = {}

    def split_n(i0, i1, j0, j1, p0, np_):
        if np_ == 1:
            boxes[p0] = (i0, i1, j0, j1)
            return
        nl = np_ // 2
        if i1 - i0 >= j1 - j0:   # Fortran nint of a single-precision product: half away from 0
            c = i0 + int(math.floor(float(np.float32(i1 - i0 + 1) * np.float32(nl)
                                          / np.float32(np_)) + 0.5))
            split_n(i0, c - 1, j0, j1, p0, nl)
            split_n(c, i1, j0, j1, p0 + nl, np_ - nl)
        else:
            c = j0 + int(math.floor(float(np.float32(j1 - j0 + 1) * np.float32(nl)
                                          / np.float32(np_)) + 0.5))
            split_n(i0, i1, j0, c - 1, p0, nl)
            split_n(i0, i1, c, j1, p0 + nl, np_ - nl)

    def split_w(i0, i1, j0, j1, p0, np_, idx):
        if np_ == 1:
            boxes[p0] = (i0, i1, j0, j1)
            part[idx] = p0
            return
        nl = np_ // 2
        ax = 0 if i1 - i0 >= j1 - j0 else 1
        lo, hi = (i0, i1) if ax == 0 else (j0, j1)
        if i1 < i0 or j1 < j0:
            c = lo + 1
        else:
            h = np.bincount(ij[idx, ax] - lo, minlength=hi - lo + 1)
            t = int(h.sum())
            c, wl = lo + 1, int(h[0])
            best, d = abs(wl * np_ - t * nl), wl
            for cc in range(lo + 2, hi + 1):
                d += int(h[cc - 1 - lo])
                if abs(d * np_ - t * nl) < best:
                    best, c = abs(d * np_ - t * nl), cc
        low = ij[idx, ax] < c
        if ax == 0:
            split_w(i0, c - 1, j0, j1, p0, nl, idx[low])
            split_w(c, i1, j0, j1, p0 + nl, np_ - nl, idx[~low])
        else:
            split_w(i0, i1, j0, c - 1, p0, nl, idx[low])
            split_w(i0, i1, c, j1, p0 + nl, np_ - nl, idx[~low])

    if uniform:
        split_n(0, ni - 1, 0, nj - 1, 0, nparts)
        if all((b[1] - b[0] + 1) >= 1 and (b[3] - b[2] + 1) >= 1
               and (b[1] - b[0] + 1) * (b[3] - b[2] + 1) >= 2 for b in boxes.values()):
            for p, (i0, i1, j0, j1) in boxes.items():
                inside = ((ij[:, 0] >= i0) & (ij[:, 0] <= i1)
                          & (ij[:, 1] >= j0) & (ij[:, 1] <= j1))
                part[inside] = p
            return part
        boxes.clear()
    split_w(0, ni - 1, 0, nj - 1, 0, nparts, np.arange(len(ij)))
    return part


def metis_parts(exe: Path, work: Path, u: np.ndarray, v: np.ndarray, n: int, nparts: int,
                obj: str = "cut"):
    """METIS_PartGraphKway's part of every node (u, v sorted by u: the CSR graph) and its
    objective value; obj 'cut' (the default options: least edge cut) or 'vol' (least total
    communication volume, which is the halo as counted here)."""
    xadj = np.zeros(n + 1, dtype=np.int32)
    xadj[1:] = np.cumsum(np.bincount(u, minlength=n))
    gfile, pfile = work / "graph.bin", work / "part.bin"
    with open(gfile, "wb") as f:
        np.array([n, len(v)], dtype=np.int32).tofile(f)
        xadj.tofile(f)
        v.astype(np.int32).tofile(f)
    p = subprocess.run([str(exe), str(gfile), str(nparts), str(pfile), obj],
                       capture_output=True, text=True)
    if p.returncode != 0:
        fail(f"METIS on {n} nodes, {nparts} parts: {p.stderr.strip()}")
    return np.fromfile(pfile, dtype=np.int32).astype(np.int64), int(p.stdout.split()[0])


def build_metis(work: Path) -> Path:
    src, exe = work / "metis_kway.c", work / "metis_kway"
    src.write_text(METIS_C)
    p = subprocess.run(["cc", "-O2", str(src), "-o", str(exe), "-lmetis"],
                       capture_output=True, text=True)
    if p.returncode != 0:
        fail(f"cannot compile the METIS driver (cc -O2 ... -lmetis):\n{p.stderr.strip()}")
    return exe


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--iem", type=Path, default=ROOT / "build" / "iem")
    ap.add_argument("--mpiexec", default="mpiexec")
    ap.add_argument("--ranks", type=int, nargs="+", default=[2, 4, 8, 16])
    ap.add_argument("--scenes", type=Path, nargs="+", default=SCENES)
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds allowed per iem run")
    args = ap.parse_args()
    args.iem = args.iem.resolve()
    if not os.access(args.iem, os.X_OK):
        fail(f"no iem executable at {args.iem} (build first, or give --iem)")
    if shutil.which(args.mpiexec) is None:
        fail(f"no {args.mpiexec} on PATH")

    rows, mismatches = [], []
    with tempfile.TemporaryDirectory(prefix="iem_pq_") as tmp:
        work = Path(tmp)
        exe = build_metis(work)
        for nml in args.scenes:
            nml = nml.resolve()
            for ranks in args.ranks:
                h5, log = run_iem(args, nml, ranks, work)
                cells, ij, nx, ny, uniform = read_body(h5)
                n = len(ij)
                u, v = node_edges(cells, n)
                rimb, rhalo = figures(rcb_parts(ij, nx + 1, ny + 1, ranks, uniform), ranks, u, v)
                m = LOG_RE.search(log)
                if m:
                    imb, halo, src = float(m.group(2)), int(m.group(3)), "log"
                    if halo != rhalo or abs(imb - rimb) > 5e-3 * rimb:
                        mismatches.append(f"{nml.name} P={ranks}: log {imb:.3f}/{halo}, "
                                          f"recomputed {rimb:.3f}/{rhalo}")
                else:
                    imb, halo, src = rimb, rhalo, "rcb"
                mimb, mhalo = figures(metis_parts(exe, work, u, v, n, ranks)[0], ranks, u, v)
                vpart, vobj = metis_parts(exe, work, u, v, n, ranks, "vol")
                vimb, vhalo = figures(vpart, ranks, u, v)
                if vhalo != vobj:   # METIS's communication volume is this halo: a self-check
                    mismatches.append(f"{nml.name} P={ranks}: halo of METIS's volume partition "
                                      f"{vhalo}, METIS's own volume {vobj}")
                rows.append((nml.stem, ranks, n, imb, halo, src, mimb, mhalo, vimb, vhalo))
                h5.unlink()
                for side in work.glob(f"{nml.stem}_p{ranks}.*"):
                    side.unlink()

    print("| scene | P | nodes | ours: largest/mean | ours: halo | src | METIS: largest/mean "
          "| METIS: halo | halo ours/METIS | METIS vol: largest/mean | METIS vol: halo "
          "| halo ours/METIS vol |")
    print("|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|")
    for name, ranks, n, imb, halo, src, mimb, mhalo, vimb, vhalo in rows:
        ratio = halo / mhalo if mhalo else float("nan")
        vratio = halo / vhalo if vhalo else float("nan")
        print(f"| {name} | {ranks} | {n} | {imb:.3f} | {halo} | {src} | {mimb:.3f} | {mhalo} "
              f"| {ratio:.2f} | {vimb:.3f} | {vhalo} | {vratio:.2f} |")
    if mismatches:
        print("\nchecks that failed (our log line against the recomputed bisection, the table "
              "showing the log; METIS's volume against this halo):")
        for line in mismatches:
            print("  " + line)


if __name__ == "__main__":
    main()
