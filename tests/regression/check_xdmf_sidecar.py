#!/usr/bin/env python3
"""The XDMF sidecar against the HDF5 file it describes, on short runs of the shipped inputs
and of tests/data/fracture_bar.nml (frames with damage and a failed_springs group).

listing (needs h5py only): every dataset of every frame group is listed in the frame's grid
(the failed_springs group, a list and no mesh field, is not),
with its centre and shape (a 2D vector through its (n, 3) view <name>_xyz, whose first two
columns are the vector and whose third is 0), every /mesh field of the sidecar's table that
the file holds is listed, and everything listed exists with the listed shape.

reader (needs the `vtk` module; exits 77, CTest's skip, without it): VTK's XDMF reader loads
the sidecar; the point data of the last frame holds a 3-component displacement equal to the
HDF5 data with z = 0, set as the vectors, and vtkWarpVector moves the points by it.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

import h5py
import numpy as np

SKIP = 77

# (input under the source tree, t_end, the cell fields its frames are expected to hold)
CASES = [("inputs/cantilever_elastic.nml", 0.006, set()),
         ("inputs/cantilever_nonlinear_dynamic.nml", 0.0125, {"nonlinearity"}),
         ("tests/data/fracture_bar.nml", 0.001, {"damage"})]
# groups a frame may hold that the sidecar does not list (they are not fields of the mesh)
UNLISTED_GROUPS = {"failed_springs"}


def run_case(args, src, workdir, nml, t_end):
    text = open(os.path.join(src, nml)).read()
    text = re.sub(r"t_end\s*=\s*[0-9.eEdD+-]+", f"t_end = {t_end}", text, count=1)
    text = re.sub(r"output_file\s*=\s*'[^']*'", "output_file = 'run.h5'", text, count=1)
    path = os.path.join(workdir, "run.nml")
    with open(path, "w") as f:
        f.write(text)
    cmd = [args.mpiexec, "-n", "2"] + args.mpiexec_flags.split() + [args.iem, "run.nml"]
    proc = subprocess.run(cmd, cwd=workdir, capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        sys.exit(f"iem failed on {nml} ({proc.returncode}):\n{proc.stderr}")
    return os.path.join(workdir, "run.h5"), os.path.join(workdir, "run.xmf")


def attributes(grid):
    """name -> (center, dims tuple, hdf path) of a grid's attributes."""
    out = {}
    for attr in grid.findall("Attribute"):
        items = attr.findall("DataItem")
        assert len(items) == 1, f"attribute {attr.get('Name')}: one DataItem expected"
        item = items[0]
        assert item.get("Format") == "HDF", attr.get("Name")
        file_name, path = item.text.strip().split(":", 1)
        assert file_name == "run.h5", file_name
        dims = tuple(int(d) for d in item.get("Dimensions").split())
        out[attr.get("Name")] = (attr.get("Center"), attr.get("AttributeType"), dims, path)
    return out


def check_listing(h5_path, xmf_path, cell_fields):
    root = ET.parse(xmf_path).getroot()
    with h5py.File(h5_path, "r") as f:
        n_nodes = f["mesh/coordinates"].shape[0]
        n_cells = f["mesh/cells"].shape[0]
        frames = sorted(k for k in f["frames"] if k.startswith("frame_"))
        assert frames, "no frames"
        grids = {g.get("Name"): g for g in root.iter("Grid") if g.get("GridType") == "Uniform"}
        assert sorted(grids) == frames, (sorted(grids), frames)
        mesh_fields = [k for k in ("material",) if k in f["mesh"]]
        seen_cell_fields = set()
        for frame in frames:
            listed = attributes(grids[frame])
            group = f["frames"][frame]
            for name, dset in group.items():
                if isinstance(dset, h5py.Group):
                    assert name in UNLISTED_GROUPS, f"{frame}/{name}: unexpected group"
                    assert name not in listed, f"{frame}/{name}: a group is listed"
                elif name.endswith("_xyz"):
                    base = name[:-4]
                    assert base in group and group[base].shape == (n_nodes, 2), name
                    assert listed.get(base) == ("Node", "Vector", (n_nodes, 3),
                                                f"/frames/{frame}/{name}"), (frame, name, listed)
                    data = dset[...]
                    assert np.array_equal(data[:, :2], group[base][...]), name
                    assert not data[:, 2].any(), name
                elif dset.shape == (n_nodes, 2):
                    assert f"{name}_xyz" in group, f"{frame}/{name} has no (n, 3) view"
                elif dset.shape == (n_cells,):
                    assert listed.get(name) == ("Cell", "Scalar", (n_cells,),
                                                f"/frames/{frame}/{name}"), (frame, name, listed)
                    seen_cell_fields.add(name)
                else:
                    raise AssertionError(f"{frame}/{name}: unexpected shape {dset.shape}")
            for name in mesh_fields:
                assert listed.get(name) == ("Cell", "Scalar", (n_cells,), f"/mesh/{name}"), name
            for name, (_, _, dims, path) in listed.items():
                assert path.lstrip("/") in f, f"{frame}: {name} lists missing {path}"
                assert f[path].shape == dims, (frame, name, f[path].shape, dims)
        assert seen_cell_fields == cell_fields, ("cell fields listed", seen_cell_fields)
        times = [float(g.find("Time").get("Value")) for g in
                 (grids[k] for k in frames)]
        assert np.allclose(times, f["frames/time"][...], rtol=0, atol=1e-15), "times"
    return len(frames)


def check_reader(h5_path, xmf_path):
    try:
        import vtk
        from vtk.util.numpy_support import vtk_to_numpy
    except ImportError:
        print("vtk is not importable: reader check skipped")
        sys.exit(SKIP)
    names = [n for n in ("vtkXdmf3ReaderS", "vtkXdmf3Reader", "vtkXdmfReader") if hasattr(vtk, n)]
    if not names:
        print("this vtk has no XDMF reader: reader check skipped")
        sys.exit(SKIP)
    with h5py.File(h5_path, "r") as f:
        frames = sorted(k for k in f["frames"] if k.startswith("frame_"))
        last = frames[-1]
        u = f["frames"][last]["displacement"][...]
        t_last = float(f["frames"][last].attrs["time"])
        xy = f["mesh/coordinates"][...]
    assert np.abs(u).max() > 0, "the last frame does not move: the warp check would be void"
    for name in names:
        reader = getattr(vtk, name)()
        reader.SetFileName(os.path.abspath(xmf_path))
        reader.UpdateInformation()
        reader.UpdateTimeStep(t_last) if hasattr(reader, "UpdateTimeStep") else reader.Update()
        out = reader.GetOutputDataObject(0)
        if not out.IsA("vtkDataSet"):
            it = out.NewIterator()
            it.InitTraversal()
            out = it.GetCurrentDataObject()
        pd = out.GetPointData()
        arr = pd.GetArray("displacement")
        assert arr is not None, f"{name}: no displacement"
        assert arr.GetNumberOfComponents() == 3, f"{name}: {arr.GetNumberOfComponents()} components"
        got = vtk_to_numpy(arr)
        assert got.shape == (len(u), 3), (name, got.shape)
        assert np.array_equal(got[:, :2], u) and not got[:, 2].any(), f"{name}: values"
        assert pd.GetVectors() is not None and pd.GetVectors().GetName() == "displacement", name
        warp = vtk.vtkWarpVector()
        warp.SetInputData(out)
        warp.SetInputArrayToProcess(0, 0, 0, vtk.vtkDataObject.FIELD_ASSOCIATION_POINTS,
                                    "displacement")
        warp.SetScaleFactor(1.0)
        warp.Update()
        moved = vtk_to_numpy(warp.GetOutput().GetPoints().GetData())
        assert np.allclose(moved[:, :2], xy + u, rtol=0, atol=1e-12), f"{name}: warp"
        assert np.abs(moved[:, :2] - xy).max() > 0, f"{name}: warp moved nothing"
        print(f"{name} (VTK {vtk.vtkVersion.GetVTKVersion()}): displacement (n, 3), z = 0, "
              f"warped by it at t = {t_last:g} s")


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("mode", choices=["listing", "reader"])
    parser.add_argument("--iem", required=True)
    parser.add_argument("--mpiexec", required=True)
    parser.add_argument("--mpiexec-flags", default="")
    args = parser.parse_args()
    src = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    if args.mode == "reader":
        try:
            import vtk  # noqa: F401
        except ImportError:
            print("vtk is not importable: reader check skipped")
            return SKIP
    for nml, t_end, cell_fields in CASES if args.mode == "listing" else CASES[:1]:
        with tempfile.TemporaryDirectory() as work:
            h5_path, xmf_path = run_case(args, src, work, nml, t_end)
            if args.mode == "listing":
                n = check_listing(h5_path, xmf_path, cell_fields)
                print(f"{nml}: {n} frames, every frame dataset listed")
            else:
                check_reader(h5_path, xmf_path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
