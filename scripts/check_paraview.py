"""Opens DIR/results.xdmf with ParaView's XDMF reader (run with pvpython) and checks that what
ParaView sees is what rkfem wrote to DIR/results.h5: the number of time steps and their times,
the point and cell counts of every step (each step's mesh is the group its `mesh` attribute names:
a run whose topology changed, e.g. by erosion, has several), every point and cell array, and the
values of the deformed coordinates, displacement and every cell array at the last step (to 1e-12
relative). The stress
must come out as the full symmetric tensor that rkfem's Tensor6 components (xx, xy, xz, yy, yz,
zz) describe; the test that runs this also checks one component against a known state.

Usage: pvpython scripts/check_paraview.py DIR [AXIS] [--min-meshes N]   (exit 0 when everything
matches; AXIS x | y | z: the run is a uniaxial-strain column along AXIS, whose axial stress must
show there; --min-meshes: the run must have changed topology, N meshes at least)
"""
import sys

import h5py
import numpy as np
from paraview import servermanager
from paraview.simple import XDMFReader
from vtk.util.numpy_support import vtk_to_numpy


def main(run_dir, axial=None, min_meshes=1):
    h5 = h5py.File(f"{run_dir}/results.h5", "r")
    steps = sorted(h5["steps"].keys())
    times = [h5["steps"][s].attrs["time"] for s in steps]
    reader = XDMFReader(FileNames=[f"{run_dir}/results.xdmf"])
    reader.UpdatePipelineInformation()
    seen = list(reader.TimestepValues)
    problems = []
    if len(seen) != len(times) or not np.allclose(seen, times, rtol=1e-12, atol=0):
        problems.append(f"time steps: ParaView {seen}, results.h5 {times}")
    def mesh_of(step):
        m = h5["steps"][step].attrs.get("mesh", b"/mesh")
        return (m.decode() if isinstance(m, bytes) else str(m)).strip("\x00")

    meshes = sorted({mesh_of(s) for s in steps})
    for s, time in zip(steps, seen):
        reader.UpdatePipeline(time)
        grid = servermanager.Fetch(reader)
        mesh = h5[mesh_of(s)]
        n_points = mesh["coordinates"].shape[0]
        n_cells = mesh["part"].shape[0]  # elements, then the vertex cells of cloud particles
        if grid.GetNumberOfPoints() != n_points or grid.GetNumberOfCells() != n_cells:
            problems.append(f"step {s} sizes: ParaView {grid.GetNumberOfPoints()} points / "
                            f"{grid.GetNumberOfCells()} cells, results.h5 {mesh_of(s)} {n_points} / {n_cells}")
    reader.UpdatePipeline(seen[-1])
    grid = servermanager.Fetch(reader)
    last = h5["steps"][steps[-1]]
    n_points = h5[mesh_of(steps[-1])]["coordinates"].shape[0]
    n_cells = h5[mesh_of(steps[-1])]["part"].shape[0]

    def compare(name, vtk_array, expected):
        if vtk_array is None:
            problems.append(f"{name}: missing in ParaView")
            return
        got = vtk_to_numpy(vtk_array)
        if got.ndim == 2 and got.shape[1] == 9 and expected.shape[1] == 6:
            # a Tensor6 attribute: ParaView expands (xx, xy, xz, yy, yz, zz) to the full tensor;
            # the expected full tensor, row-major, from the components as rkfem documents them
            xx, xy, xz, yy, yz, zz = expected.T
            expected = np.stack([xx, xy, xz, xy, yy, yz, xz, yz, zz], axis=1)
        got = got.reshape(expected.shape)
        scale = max(np.abs(expected).max(), 1e-300)
        err = np.abs(got - expected).max() / scale
        print(f"  {name:26s} {str(expected.shape):14s} max relative difference {err:.1e}")
        if err > 1e-12:
            problems.append(f"{name}: differs by {err:.2e}")

    compare("coordinates (deformed)", grid.GetPoints().GetData(), last["coordinates"][...])
    for name in ("displacement", "velocity"):
        compare(name, grid.GetPointData().GetArray(name), last[name][...])
    point_names = ("coordinates", "displacement", "velocity")
    cell_names = [n for n in last.keys() if last[n].shape[0] == n_cells and n not in point_names]
    for name in sorted(cell_names):
        compare(name, grid.GetCellData().GetArray(name), last[name][...])
    if axial is not None:
        # a uniaxial-strain column along `axial`: ParaView's full tensor must carry the largest
        # diagonal stress on that axis where the stress is largest (a component-order check)
        T = vtk_to_numpy(grid.GetCellData().GetArray("stress")).reshape(-1, 3, 3)
        c = int(np.argmax(np.abs(T).reshape(len(T), -1).max(axis=1)))
        diag = np.abs(np.diagonal(T[c]))
        k = "xyz".index(axial)
        print(f"  cell {c}: ParaView stress diagonal {np.diagonal(T[c])}, off-diagonal max "
              f"{np.abs(T[c] - np.diag(np.diagonal(T[c]))).max():.3e}")
        if int(np.argmax(diag)) != k:
            problems.append(f"axial stress not on {axial}{axial}: diagonal {np.diagonal(T[c])}")
    if len(meshes) < min_meshes:
        problems.append(f"{len(meshes)} mesh(es), expected at least {min_meshes}")
    print(f"ParaView read {len(seen)} time steps on {len(meshes)} mesh(es) ({', '.join(meshes)}); "
          f"the last: {n_points} points, {n_cells} cells")
    for p in problems:
        print("MISMATCH:", p)
    return 1 if problems else 0


if __name__ == "__main__":
    args = sys.argv[1:]
    min_meshes = 1
    if "--min-meshes" in args:
        k = args.index("--min-meshes")
        min_meshes = int(args[k + 1])
        del args[k:k + 2]
    sys.exit(main(args[0], args[1] if len(args) > 1 else None, min_meshes))
