#!/usr/bin/env python3
"""The fracture fields of the frames (docs/output.md, "/frames"), on a bar pulled apart.

bar: tests/data/fracture_bar.nml on each rank count of --ranks. Every frame's `damage` and
`failed_springs` are bitwise the same on every rank count; the list has its documented types
and is sorted by (cell, spring) without duplicates; nothing heals (a frame lists every spring
of the frame before with the same kind and time, and the springs new in a frame failed after
the frame before and not after this one); damage is in [0, 1], at least the share of the
cell's 8 factors its listed springs set to 0 (a failed edge zeroes itself and the shear
springs of its two corners), and 1 exactly where all four edges are listed. The last frame
has failed springs. The checkpoint the run writes at its end holds, for the last frame, the
same failure times for the listed springs and no other failed spring, and each listed edge
has its factor 0: its tension strain history at least the end of its softening,
2 G_f / (f_t h) (h the cell size across the band: lx for bottom and top edges, ly for right and
left ones), or the pre-cut mark.

precut: the same bar with two `&shape ... material = 'crack'` boxes: frame 0 lists the four
edges (springs 0-3) of each cell whose centre a box holds, kind 4 (pre-cut) at time 0, and
nothing else; those cells have damage 1 in every frame; plus every check of `bar`.
"""
import argparse
import os
import re
import struct
import subprocess
import sys
import tempfile

import h5py
import numpy as np

SPRINGS = 8
KINDS = {1: "tension", 2: "crushing", 3: "shear", 4: "pre-cut"}
FIELDS = ("cell", "spring", "kind", "time")
DTYPES = {"cell": np.dtype("<i8"), "spring": np.dtype("<i4"), "kind": np.dtype("<i4"),
          "time": np.dtype("<f8")}
# the pre-cut boxes: a top-row cell on the left and a bottom-row one on the right, so that a
# rank's cells (the bar is cut across its length) do not come in global order
BOXES = [(0.02, 0.025, 0.005, 0.01), (0.08, 0.085, 0.0, 0.005)]

failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)


def run(args, text, workdir, ranks):
    d = os.path.join(workdir, f"np{ranks}")
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "case.nml"), "w") as f:
        f.write(text)
    cmd = [args.mpiexec, "-n", str(ranks)] + args.mpiexec_flags.split() + [args.iem, "case.nml"]
    proc = subprocess.run(cmd, cwd=d, capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        sys.exit(f"iem failed on {ranks} rank(s) ({proc.returncode}):\n{proc.stderr}")
    return os.path.join(d, "bar.h5"), os.path.join(d, "bar.chk")


def frames_of(path):
    """[(time, damage, {field: array})] of every frame, and the mesh."""
    out = []
    with h5py.File(path, "r") as f:
        mesh = {k: f["mesh"][k][...] for k in ("coordinates", "cells")}
        mesh.update({k: float(f["mesh"].attrs[k]) for k in ("lx", "ly")})
        for name in sorted(k for k in f["frames"] if k.startswith("frame_")):
            g = f["frames"][name]
            lists = {k: g["failed_springs"][k] for k in FIELDS}
            for k, d in lists.items():
                check(d.dtype == DTYPES[k] and d.ndim == 1,
                      f"{name}/failed_springs/{k}: {d.dtype} {d.shape}")
            out.append((float(g.attrs["time"]), g["damage"][...],
                        {k: d[...] for k, d in lists.items()}))
    return out, mesh


def same_bytes(a, b):
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def checkpoint_cells(path, n_cells):
    """(time, kappa (n_cells, 12), t_fail (n_cells, 8)) of a checkpoint's cell records."""
    data = open(path, "rb").read()
    ints = struct.unpack("<64q", data[:512])
    t = struct.unpack("<64d", data[512:1024])[0]
    rec_cell, layout_len = ints[21], ints[23]
    layout = data[1024:1024 + layout_len].decode()
    cell_part = layout.split("cell:", 1)[1]
    offset, where = 0, {}
    for name, width, size in re.findall(r"(\w+) (\d+) real\((\d+)\)", cell_part):
        where[name] = (offset, int(width))
        offset += int(width) * int(size)
    rec = (rec_cell + 7) // 8 * 8
    cells = np.frombuffer(data[len(data) - n_cells * rec:], dtype="<f8").reshape(n_cells, rec // 8)

    def field(name):
        o, w = where[name]
        return cells[:, o // 8:o // 8 + w]
    return t, field("fracture_kappa"), field("fracture_time")


def check_frames(frames, mesh, label):
    n_cells = mesh["cells"].shape[0]
    prev = {}
    t_prev = None
    for i, (t, damage, lst) in enumerate(frames):
        what = f"{label} frame {i} (t = {t:.6g})"
        n = len(lst["cell"])
        check(all(len(lst[k]) == n for k in FIELDS), f"{what}: the four datasets of one length")
        key = lst["cell"] * SPRINGS + lst["spring"]
        check(bool(np.all(np.diff(key) > 0)), f"{what}: sorted by (cell, spring), no duplicate")
        check(bool(np.all((lst["cell"] >= 0) & (lst["cell"] < n_cells))
                   and np.all((lst["spring"] >= 0) & (lst["spring"] < SPRINGS))),
              f"{what}: cells and springs in range")
        edge = lst["spring"] < 4
        check(bool(np.all(np.isin(lst["kind"][edge], [1, 2, 4]))
                   and np.all(lst["kind"][~edge] == 3)),
              f"{what}: kinds 1, 2, 4 on edges, 3 on shear springs")
        check(bool(np.all((lst["time"] >= 0) & (lst["time"] <= t))),
              f"{what}: failure times in [0, t]")
        cur = {(int(c), int(s)): (int(k), float(tt)) for c, s, k, tt in
               zip(lst["cell"], lst["spring"], lst["kind"], lst["time"])}
        kept = all(cur.get(e) == v for e, v in prev.items())
        check(kept, f"{what}: every spring of the frame before, same kind and time (no healing)")
        if t_prev is not None:
            new = [v[1] for e, v in cur.items() if e not in prev]
            check(all(tt > t_prev for tt in new),
                  f"{what}: the {len(new)} springs new in this frame failed after the frame before")
        check(damage.dtype == np.dtype("<f8") and damage.shape == (n_cells,),
              f"{what}: damage (n_cells,) float64")
        check(bool(np.all((damage >= 0) & (damage <= 1))), f"{what}: damage in [0, 1]")
        zero = np.zeros((n_cells, SPRINGS), bool)
        zero[lst["cell"], lst["spring"]] = True
        edges = zero[:, :4].copy()
        for q in range(4):  # corner q joins edges q and q-1 (0-based)
            zero[:, 4 + q] |= edges[:, q] | edges[:, (q - 1) % 4]
        bound = zero.sum(axis=1) / SPRINGS
        check(bool(np.all(damage >= bound)),
              f"{what}: damage at least the share of its failed springs' zeroed factors")
        full = edges.all(axis=1)
        check(bool(np.array_equal(damage == 1.0, full)),
              f"{what}: damage 1 exactly in the cells whose four edges failed")
        prev, t_prev = cur, t
    check(len(frames[-1][2]["cell"]) > 0 and frames[-1][1].max() > 0,
          f"{label}: the last frame has failed springs and damage")


def check_checkpoint(chk, frames, mesh, text, label):
    n_cells = mesh["cells"].shape[0]
    t, kappa, t_fail = checkpoint_cells(chk, n_cells)
    match = [i for i, fr in enumerate(frames) if fr[0] == t]
    check(len(match) == 1, f"{label}: the checkpoint (t = {t}) is at a frame's time")
    if not match:
        return
    lst = frames[match[0]][2]
    listed = np.zeros((n_cells, SPRINGS), bool)
    listed[lst["cell"], lst["spring"]] = True
    check(bool(np.array_equal(listed, t_fail < np.finfo(float).max)),
          f"{label}: the frame lists exactly the checkpoint's failed springs")
    check(bool(np.array_equal(t_fail[lst["cell"], lst["spring"]], lst["time"])),
          f"{label}: the listed failure times are the checkpoint's")
    ft = float(re.search(r"tensile_strength\s*=\s*([0-9.eEdD+-]+)", text).group(1))
    gf = float(re.search(r"fracture_energy\s*=\s*([0-9.eEdD+-]+)", text).group(1))
    ok = True
    for c, s, k in zip(lst["cell"], lst["spring"], lst["kind"]):
        if s >= 4:
            continue
        h = mesh["lx"] if s % 2 == 0 else mesh["ly"]
        if k == 4:
            ok &= kappa[c, s] == np.finfo(float).max
        elif k == 1:
            ok &= kappa[c, s] >= 2 * gf / (ft * h)
        else:
            ok = False  # the bar fails in tension only
    check(bool(ok) and len(lst["cell"]) > 0,
          f"{label}: every listed edge has factor 0 in the checkpoint (strain history past "
          f"the end of softening, or pre-cut)")


def check_precut(frames, mesh):
    xy = mesh["coordinates"][mesh["cells"]].mean(axis=1)
    held = np.zeros(len(xy), bool)
    for b in BOXES:
        held |= ((xy[:, 0] >= b[0]) & (xy[:, 0] <= b[1]) & (xy[:, 1] >= b[2]) &
                 (xy[:, 1] <= b[3]))
    inside = np.nonzero(held)[0]
    check(len(inside) == len(BOXES), f"precut: the boxes hold cells {inside.tolist()}")
    lst = frames[0][2]
    want_cell = np.repeat(inside, 4)
    want_spring = np.tile(np.arange(4), len(inside))
    check(np.array_equal(lst["cell"], want_cell) and np.array_equal(lst["spring"], want_spring)
          and bool(np.all(lst["kind"] == 4)) and bool(np.all(lst["time"] == 0.0)),
          "precut: frame 0 lists the four edges of the pre-cut cells, kind 4, time 0, only them")
    check(all(bool(np.all(fr[1][inside] == 1.0)) for fr in frames),
          "precut: the pre-cut cells have damage 1 in every frame")


def main():
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("mode", choices=["bar", "precut"])
    p.add_argument("--iem", required=True)
    p.add_argument("--mpiexec", required=True)
    p.add_argument("--mpiexec-flags", default="")
    p.add_argument("--case", required=True)
    p.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 3])
    args = p.parse_args()
    text = open(args.case).read()
    if args.mode == "precut":
        shapes = "".join("&shape kind = 'rectangle', box = " + ", ".join(str(x) for x in b) +
                         ", material = 'crack' /\n" for b in BOXES)
        text = text.replace("&bc", shapes + "&bc", 1)
    with tempfile.TemporaryDirectory(prefix="iem_fracture_frames_") as work:
        runs = {n: run(args, text, work, n) for n in args.ranks}
        ref_frames, mesh = frames_of(runs[args.ranks[0]][0])
        check_frames(ref_frames, mesh, f"{args.mode} on {args.ranks[0]} rank(s)")
        check_checkpoint(runs[args.ranks[0]][1], ref_frames, mesh, text,
                         f"{args.mode} on {args.ranks[0]} rank(s)")
        if args.mode == "precut":
            check_precut(ref_frames, mesh)
        for n in args.ranks[1:]:
            frames, _ = frames_of(runs[n][0])
            same = len(frames) == len(ref_frames) and all(
                same_bytes(a[1], b[1]) and all(same_bytes(a[2][k], b[2][k]) for k in FIELDS)
                for a, b in zip(frames, ref_frames))
            check(same, f"{args.mode}: damage and failed_springs of every frame bitwise the "
                        f"same on {n} and {args.ranks[0]} rank(s) ({len(frames)} frames)")
            check_checkpoint(runs[n][1], frames, mesh, text, f"{args.mode} on {n} rank(s)")
    if failures:
        sys.exit(f"{len(failures)} check(s) failed")
    print("all checks passed")


if __name__ == "__main__":
    main()
