#!/usr/bin/env python3
"""Render one frame of a run's liquid surface (liquid/liquid_<step>.vtp) and its bodies to a PNG.

Usage: xvfb-run -a python3 scripts/render_liquid.py OUT STEP PNG [--azimuth DEG] [--elevation DEG]

OUT is a run's output folder (tetfsi run ... --out OUT) of a scene with fluid.liquid; STEP the
frame's step (as in the file names). Bodies are drawn from OUT/<body>/<body>_<step>.vtu when
present. Uses VTK's Python module (Debian's python3-vtk9), off screen.
"""
import argparse
import glob
import os
import sys

import vtk


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("step", type=int)
    ap.add_argument("png")
    ap.add_argument("--azimuth", type=float, default=-35.0)
    ap.add_argument("--elevation", type=float, default=25.0)
    a = ap.parse_args()
    path = os.path.join(a.out, "liquid", f"liquid_{a.step:06d}.vtp")
    if not os.path.exists(path):
        sys.exit(f"render_liquid: {path} does not exist: give a step with a frame")
    ren = vtk.vtkRenderer()
    ren.SetBackground(1, 1, 1)
    r = vtk.vtkXMLPolyDataReader()
    r.SetFileName(path)
    r.Update()
    m = vtk.vtkPolyDataMapper()
    m.SetInputConnection(r.GetOutputPort())
    m.ScalarVisibilityOff()
    act = vtk.vtkActor()
    act.SetMapper(m)
    act.GetProperty().SetColor(0.25, 0.5, 0.9)
    act.GetProperty().SetSpecular(0.4)
    ren.AddActor(act)
    for vtu in glob.glob(os.path.join(a.out, "*", f"*_{a.step:06d}.vtu")):
        b = vtk.vtkXMLUnstructuredGridReader()
        b.SetFileName(vtu)
        s = vtk.vtkDataSetSurfaceFilter()
        s.SetInputConnection(b.GetOutputPort())
        bm = vtk.vtkPolyDataMapper()
        bm.SetInputConnection(s.GetOutputPort())
        bm.ScalarVisibilityOff()
        ba = vtk.vtkActor()
        ba.SetMapper(bm)
        ba.GetProperty().SetColor(0.9, 0.55, 0.3)
        ren.AddActor(ba)
    # the fluid box as an outline
    box = vtk.vtkXMLImageDataReader()
    vti = os.path.join(a.out, "fluid", f"fluid_{a.step:06d}.vti")
    if os.path.exists(vti):
        box.SetFileName(vti)
        o = vtk.vtkOutlineFilter()
        o.SetInputConnection(box.GetOutputPort())
        om = vtk.vtkPolyDataMapper()
        om.SetInputConnection(o.GetOutputPort())
        oa = vtk.vtkActor()
        oa.SetMapper(om)
        oa.GetProperty().SetColor(0.2, 0.2, 0.2)
        ren.AddActor(oa)
    cam = ren.GetActiveCamera()
    cam.SetViewUp(0, 0, 1)
    cam.SetPosition(0, -1, 0)
    cam.SetFocalPoint(0, 0, 0)
    ren.ResetCamera()
    cam.Azimuth(a.azimuth)
    cam.Elevation(a.elevation)
    ren.ResetCamera()
    cam.Zoom(1.3)
    w = vtk.vtkRenderWindow()
    w.SetOffScreenRendering(1)
    w.AddRenderer(ren)
    w.SetSize(900, 500)
    w.Render()
    f = vtk.vtkWindowToImageFilter()
    f.SetInput(w)
    f.Update()
    wr = vtk.vtkPNGWriter()
    wr.SetFileName(a.png)
    wr.SetInputConnection(f.GetOutputPort())
    wr.Write()
    print(f"render_liquid: wrote {a.png}")


if __name__ == "__main__":
    main()
