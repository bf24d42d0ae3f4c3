"""Renders a run's results (DIR/results.xdmf) to a PNG with ParaView: the deformed shape at the last
frame (or at --time T, in seconds, the frame nearest it), coloured by a cell or point field, seen
from an oblique angle with the z axis up, with a colour legend and the time. Run with pvpython
through scripts/screenshot, which provides a virtual display (Xvfb) when there is none: Debian's
ParaView 5.11 needs an X display, and its --force-offscreen-rendering segfaults without one.

Usage: pvpython scripts/screenshot.py DIR OUT.png [--field NAME] [--time T] [--size W H]
"""
import argparse

from paraview.simple import (ColorBy, CreateView, GetScalarBar, SaveScreenshot, Show, Text,
                             XDMFReader)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("run_dir")
    p.add_argument("png")
    p.add_argument("--field", default="pressure")
    p.add_argument("--time", type=float, default=None)
    p.add_argument("--size", type=int, nargs=2, default=[1200, 800])
    a = p.parse_args()
    reader = XDMFReader(FileNames=[f"{a.run_dir}/results.xdmf"])
    reader.UpdatePipelineInformation()
    times = list(reader.TimestepValues) or [0.0]
    t = times[-1] if a.time is None else min(times, key=lambda s: abs(s - a.time))
    reader.UpdatePipeline(t)
    view = CreateView("RenderView")
    view.ViewSize = a.size
    view.ViewTime = t
    view.OrientationAxesVisibility = 1
    shown = Show(reader, view)
    cells = reader.CellData.keys()
    points = reader.PointData.keys()
    if a.field in cells:
        ColorBy(shown, ("CELLS", a.field))
    elif a.field in points:
        ColorBy(shown, ("POINTS", a.field, "Magnitude"))
    else:
        raise SystemExit(f"screenshot: no field '{a.field}'; cell fields {list(cells)}, point fields {list(points)}")
    shown.RescaleTransferFunctionToDataRange(True, False)
    shown.SetScalarBarVisibility(view, True)
    GetScalarBar(shown.LookupTable, view).Title = a.field
    label = Text(Text=f"t = {t:.6g} s")
    Show(label, view)
    view.CameraFocalPoint = [0.0, 0.0, 0.0]
    view.CameraPosition = [1.0, -1.6, 0.9]
    view.CameraViewUp = [0.0, 0.0, 1.0]
    view.ResetCamera()
    SaveScreenshot(a.png, view, ImageResolution=a.size)
    print(f"screenshot: {a.png} ({a.field} at t = {t:.6g} s)")


if __name__ == "__main__":
    main()
