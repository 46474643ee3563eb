"""Render the last frame of a smoke_jet run with ParaView, headless.

    tetfsi run data/scenes/smoke_jet.json -o OUT --steps 30
    xvfb-run -a pvbatch scripts/pv_smoke_jet.py OUT out.png [--array smoke_density] [--z 0.5]

Opens OUT/fluid.pvd and OUT/paddle.pvd, prints the number of frames and the ranges of the
fluid's arrays at the last one, slices the fluid at height z (default 0.5 m, the jet's axis)
coloured by a cell array (default smoke_density; velocity is shown as its magnitude), draws
the paddle and the outline of the fluid box, and saves a PNG seen from above (+z).
Needs ParaView's pvbatch with its Python modules. On Debian 12 those are `paraview` and
`python3-paraview`, but python3-paraview conflicts with python3-vtk9, which tetfsi's build
needs (scripts/setup.sh), so that installing it removes libvtk9-dev. On a machine that builds
tetfsi, install only `paraview` and `xvfb`, unpack the Python modules beside and point pvbatch
at them:

    apt-get install paraview xvfb
    cd /tmp && apt-get download python3-paraview && dpkg-deb -x python3-paraview_*.deb pvpy
    PYTHONPATH=/tmp/pvpy/usr/lib/python3/dist-packages xvfb-run -a pvbatch \
        scripts/pv_smoke_jet.py OUT out.png
"""

import argparse
import os
import sys

from paraview.simple import (  # noqa: E402 (pvbatch provides the module)
    ColorBy,
    GetActiveViewOrCreate,
    GetColorTransferFunction,
    GetScalarBar,
    Outline,
    PVDReader,
    Render,
    SaveScreenshot,
    Show,
    Slice,
)


def array_ranges(source):
    """Name -> (components, [min, max] per component and of the magnitude) of the cell and
    point arrays of `source` at its current time."""
    out = {}
    info = source.GetDataInformation()
    for kind, arrays in (("cell", info.GetCellDataInformation()),
                         ("point", info.GetPointDataInformation())):
        for i in range(arrays.GetNumberOfArrays()):
            a = arrays.GetArrayInformation(i)
            n = a.GetNumberOfComponents()
            comps = [a.GetComponentRange(c) for c in range(n)]
            mag = a.GetComponentRange(-1) if n > 1 else None
            out[(kind, a.GetName())] = (n, comps, mag)
    return out


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", help="output folder of a smoke_jet run (holds fluid.pvd, paddle.pvd)")
    ap.add_argument("png", help="image to write")
    ap.add_argument("--array", default="smoke_density", help="fluid cell array to colour by")
    ap.add_argument("--z", type=float, default=0.5, help="height of the slice (m)")
    ap.add_argument("--size", default="1600x900", help="image size WxH in pixels")
    args = ap.parse_args(argv)

    fluid_pvd = os.path.join(args.out, "fluid.pvd")
    paddle_pvd = os.path.join(args.out, "paddle.pvd")
    for p in (fluid_pvd, paddle_pvd):
        if not os.path.exists(p):
            sys.exit("error: %s not found (run tetfsi run data/scenes/smoke_jet.json -o %s)"
                     % (p, args.out))

    fluid = PVDReader(FileName=fluid_pvd)
    paddle = PVDReader(FileName=paddle_pvd)
    times = list(fluid.TimestepValues) if fluid.TimestepValues else [0.0]
    paddle_times = list(paddle.TimestepValues) if paddle.TimestepValues else [0.0]
    t = times[-1]
    print("fluid.pvd: %d time steps, t = %g .. %g s" % (len(times), times[0], t))
    print("paddle.pvd: %d time steps" % len(paddle_times))

    view = GetActiveViewOrCreate("RenderView")
    w, h = (int(v) for v in args.size.split("x"))
    view.ViewSize = [w, h]
    view.ViewTime = t
    view.Background = [1.0, 1.0, 1.0]
    try:  # ParaView >= 5.10 draws a gradient/palette background unless told otherwise
        view.UseColorPaletteForBackground = 0
    except AttributeError:
        pass
    view.OrientationAxesVisibility = 0

    fluid.UpdatePipeline(t)
    paddle.UpdatePipeline(t)
    info = fluid.GetDataInformation()
    print("fluid at t = %g s: %d cells, %d points"
          % (t, info.GetNumberOfCells(), info.GetNumberOfPoints()))
    for (kind, name), (n, comps, mag) in sorted(array_ranges(fluid).items()):
        if name.startswith("q_"):
            continue
        text = ", ".join("[%.4g, %.4g]" % tuple(c) for c in comps)
        if mag is not None:
            text += "; |%s| [%.4g, %.4g]" % (name, mag[0], mag[1])
        print("  %-5s %-14s %s" % (kind, name, text))

    sl = Slice(Input=fluid)
    sl.SliceType = "Plane"
    sl.SliceType.Origin = [1.0, 0.5, args.z]
    sl.SliceType.Normal = [0.0, 0.0, 1.0]
    sl.UpdatePipeline(t)
    sl_disp = Show(sl, view)
    sl_disp.Ambient, sl_disp.Diffuse = 1.0, 0.0  # unlit: the colours are the data
    ColorBy(sl_disp, ("CELLS", args.array, "Magnitude"))
    lut = GetColorTransferFunction(args.array)
    if args.array == "smoke_density":
        lut.RescaleTransferFunction(0.0, 1.0)
        lut.ApplyPreset("Grayscale", True)
        lut.InvertTransferFunction()  # smoke dark on a light background
    else:
        sl_disp.RescaleTransferFunctionToDataRange(False, True)
        lut.ApplyPreset("Viridis (matplotlib)", True)
    sl_disp.SetScalarBarVisibility(view, True)
    bar = GetScalarBar(lut, view)
    bar.Title = args.array
    bar.ComponentTitle = ""
    bar.TitleColor = bar.LabelColor = [0.0, 0.0, 0.0]

    outline = Show(Outline(Input=fluid), view)
    outline.DiffuseColor = outline.AmbientColor = [0.0, 0.0, 0.0]
    paddle_disp = Show(paddle, view)
    paddle_disp.ColorArrayName = ["POINTS", ""]  # solid colour
    paddle_disp.DiffuseColor = [0.85, 0.35, 0.1]
    paddle_disp.Opacity = 0.8

    Render(view)  # the first render resets the camera: set it after
    # Seen from above, the fluid box filling the image but for a strip on the right that
    # holds the colour bar.
    b = info.GetBounds()
    cx, cy = 0.5 * (b[0] + b[1]) + 0.07 * (b[1] - b[0]), 0.5 * (b[2] + b[3])
    view.CameraPosition = [cx, cy, b[5] + 10.0 * (b[1] - b[0])]
    view.CameraFocalPoint = [cx, cy, args.z]
    view.CameraViewUp = [0.0, 1.0, 0.0]
    view.CameraParallelProjection = 1
    view.CameraParallelScale = 0.525 * max(b[3] - b[2], 1.2 * (b[1] - b[0]) * h / w)
    Render(view)
    SaveScreenshot(args.png, view, ImageResolution=[w, h])
    print("wrote %s (t = %g s, slice z = %g m, coloured by %s)" % (args.png, t, args.z, args.array))


if __name__ == "__main__":
    main(sys.argv[1:])
