"""Renders a run's results (DIR/results.xdmf) to a PNG with ParaView: the deformed shape at the last
frame (or at --time T, in seconds, the frame nearest it), coloured by a cell or point field, seen
from an oblique angle with the z axis up, with a colour legend and the time. Run with pvpython
through scripts/screenshot, which provides a virtual display (Xvfb) when there is none: Debian's
ParaView 5.11 needs an X display, and its --force-offscreen-rendering segfaults without one.

--section X Y Z NX NY NZ cuts the model with the plane through (X, Y, Z) with normal (NX, NY, NZ)
(in metres), keeps the side the normal points away from, and looks at the cut face-on: a crater
seen in section through the shot line, as the seed's Fig. 16 and 20 show one
(`--section 0 0 0 0 1 0` for the P6 cylinder). --frames N draws N frames spread evenly over the
run (the first, the last and those between, nearest each time) side by side in one strip, the
same colour range in each (the range over those frames): a time series in one picture.

Usage: pvpython scripts/screenshot.py DIR OUT.png [--field NAME] [--time T] [--size W H]
           [--section X Y Z NX NY NZ] [--frames N]
"""
import argparse
import os
import tempfile

from paraview.simple import (Clip, ColorBy, CreateView, GetScalarBar, SaveScreenshot, Show, Text,
                             XDMFReader)


def field_range(source, association, field, times):
    """The field's range over the frames drawn (magnitudes of point vectors)."""
    lo, hi = float("inf"), -float("inf")
    for t in times:
        source.UpdatePipeline(t)
        arrays = source.CellData if association == "CELLS" else source.PointData
        r = arrays[field].GetRange(-1 if association == "POINTS" else 0)
        lo, hi = min(lo, r[0]), max(hi, r[1])
    return lo, hi


def render(source, a, t, association, value_range, png, size):
    view = CreateView("RenderView")
    view.ViewSize = size
    view.ViewTime = t
    view.OrientationAxesVisibility = 1
    shown = Show(source, view)
    if association == "CELLS":
        ColorBy(shown, ("CELLS", a.field))
    else:
        ColorBy(shown, ("POINTS", a.field, "Magnitude"))
    if value_range is None:
        shown.RescaleTransferFunctionToDataRange(True, False)
    else:
        shown.LookupTable.RescaleTransferFunction(value_range[0], value_range[1])
    shown.SetScalarBarVisibility(view, True)
    GetScalarBar(shown.LookupTable, view).Title = a.field
    Show(Text(Text=f"t = {t:.6g} s"), view)
    if a.section:
        # face-on: from the side the kept half is not on
        n = a.section[3:]
        view.CameraFocalPoint = [0.0, 0.0, 0.0]
        view.CameraPosition = [n[0], n[1], n[2]]
        view.CameraViewUp = [0.0, 0.0, 1.0] if abs(n[2]) < 0.9 else [0.0, 1.0, 0.0]
    else:
        view.CameraFocalPoint = [0.0, 0.0, 0.0]
        view.CameraPosition = [1.0, -1.6, 0.9]
        view.CameraViewUp = [0.0, 0.0, 1.0]
    view.ResetCamera()
    SaveScreenshot(png, view, ImageResolution=size)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("run_dir")
    p.add_argument("png")
    p.add_argument("--field", default="pressure")
    p.add_argument("--time", type=float, default=None)
    p.add_argument("--size", type=int, nargs=2, default=[1200, 800])
    p.add_argument("--section", type=float, nargs=6, default=None)
    p.add_argument("--frames", type=int, default=0)
    a = p.parse_args()
    reader = XDMFReader(FileNames=[f"{a.run_dir}/results.xdmf"])
    reader.UpdatePipelineInformation()
    times = list(reader.TimestepValues) or [0.0]
    cells = reader.CellData.keys()
    points = reader.PointData.keys()
    if a.field in cells:
        association = "CELLS"
    elif a.field in points:
        association = "POINTS"
    else:
        raise SystemExit(f"screenshot: no field '{a.field}'; cell fields {list(cells)}, point fields {list(points)}")
    source = reader
    if a.section:
        n = a.section[3:]
        if n[0] == 0 and n[1] == 0 and n[2] == 0:
            raise SystemExit("screenshot: --section needs a nonzero normal")
        source = Clip(Input=reader)
        source.ClipType = "Plane"
        source.ClipType.Origin = a.section[:3]
        source.ClipType.Normal = n
        source.Crinkleclip = 0
        source.Invert = 1  # keep the side the normal points away from
    if a.frames <= 1:
        t = times[-1] if a.time is None else min(times, key=lambda s: abs(s - a.time))
        source.UpdatePipeline(t)
        render(source, a, t, association, None, a.png, a.size)
        print(f"screenshot: {a.png} ({a.field} at t = {t:.6g} s" + (", in section)" if a.section else ")"))
        return
    # a strip of frames: the nearest frame to each of N times spread over the run, one range
    wanted = [times[0] + (times[-1] - times[0]) * k / (a.frames - 1) for k in range(a.frames)]
    chosen = []
    for w in wanted:
        t = min(times, key=lambda s: abs(s - w))
        if t not in chosen:
            chosen.append(t)
    value_range = field_range(source, association, a.field, chosen)
    width = max(a.size[0] // len(chosen), 160)
    size = [width, a.size[1]]
    import matplotlib.image as mpimg
    import numpy as np
    tiles = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, t in enumerate(chosen):
            png = os.path.join(tmp, f"frame_{i}.png")
            source.UpdatePipeline(t)
            render(source, a, t, association, value_range, png, size)
            tiles.append(mpimg.imread(png)[:, :, :3])
    strip = np.concatenate(tiles, axis=1)
    mpimg.imsave(a.png, strip)
    print(f"screenshot: {a.png} ({a.field}, {len(chosen)} frames from t = {chosen[0]:.6g} to {chosen[-1]:.6g} s"
          + (", in section)" if a.section else ")"))


if __name__ == "__main__":
    main()
