#!/usr/bin/env python3
"""Renders frames of a plastifem PVD/VTU series to one PNG (for the README).

Needs Debian's python3-vtk9 (`apt-get install python3-vtk9`, run with /usr/bin/python3):
    /usr/bin/python3 docs/render.py OUT.png FRAME.vtu [FRAME.vtu ...]
Each frame is drawn as a surface coloured by its `von_mises` cell field, frames overlaid
(so a falling bar shows its motion), camera looking along +y.
"""
import sys

import vtk


def main():
    out, frames = sys.argv[1], sys.argv[2:]
    renderer = vtk.vtkRenderer()
    renderer.SetBackground(1, 1, 1)
    lut = vtk.vtkLookupTable()
    lut.SetHueRange(0.667, 0.0)
    lut.Build()
    vmax = 0.0
    readers = []
    for f in frames:
        r = vtk.vtkXMLUnstructuredGridReader()
        r.SetFileName(f)
        r.Update()
        arr = r.GetOutput().GetCellData().GetArray("von_mises")
        if arr is not None:
            vmax = max(vmax, arr.GetRange()[1])
        readers.append(r)
    for i, r in enumerate(readers):
        surface = vtk.vtkDataSetSurfaceFilter()
        surface.SetInputConnection(r.GetOutputPort())
        mapper = vtk.vtkDataSetMapper()
        mapper.SetInputConnection(surface.GetOutputPort())
        mapper.SetScalarModeToUseCellFieldData()
        mapper.SelectColorArray("von_mises")
        mapper.SetLookupTable(lut)
        mapper.SetScalarRange(0, vmax if vmax > 0 else 1)
        actor = vtk.vtkActor()
        actor.SetMapper(mapper)
        actor.GetProperty().EdgeVisibilityOn()
        actor.GetProperty().SetEdgeColor(0.2, 0.2, 0.2)
        actor.GetProperty().SetOpacity(1.0 if i == len(readers) - 1 else 0.35)
        renderer.AddActor(actor)
    bar = vtk.vtkScalarBarActor()
    bar.SetLookupTable(lut)
    bar.SetTitle("von Mises")
    bar.SetNumberOfLabels(4)
    bar.GetTitleTextProperty().SetColor(0, 0, 0)
    bar.GetLabelTextProperty().SetColor(0, 0, 0)
    renderer.AddActor2D(bar)
    camera = renderer.GetActiveCamera()
    camera.SetPosition(0, -1, 0)
    camera.SetFocalPoint(0, 0, 0)
    camera.SetViewUp(0, 0, 1)
    camera.Azimuth(25)
    camera.Elevation(15)
    renderer.ResetCamera()
    window = vtk.vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.AddRenderer(renderer)
    window.SetSize(1000, 520)
    window.Render()
    grab = vtk.vtkWindowToImageFilter()
    grab.SetInput(window)
    writer = vtk.vtkPNGWriter()
    writer.SetFileName(out)
    writer.SetInputConnection(grab.GetOutputPort())
    writer.Write()


if __name__ == "__main__":
    main()
