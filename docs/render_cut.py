#!/usr/bin/env python3
"""Renders plastifem cut VTU files (io::write_cut_vtu: points already moved, the cut opened)
side by side, one viewport each, for the README's cutting figures.

Needs Debian's python3-vtk9 (run with /usr/bin/python3; under xvfb-run on a machine without a
display):
    /usr/bin/python3 docs/render_cut.py OUT.png [--view DX,DY,DZ] [--up UX,UY,UZ] [--size W,H] [--exaggerate S] \
        "LABEL=file.vtu" "LABEL=file.vtu" ...

--view is the direction the camera looks from (default 0,-1,0: from -y), --up the screen's up
(default 0,0,1), --exaggerate S draws the points at X + S u (1: as written), --sides colours
the cells by their side of a cut (grey: uncut, red: above, blue: below) instead of |u|. Surfaces are drawn with their cell edges, coloured by |displacement| on one
colour scale for the whole figure.
"""
import sys

import vtk


def parse(argv):
    out, view, up, size, frames, scale = argv[0], (0, -1, 0), (0, 0, 1), (360, 420), [], 1.0
    sides = False
    i = 1
    while i < len(argv):
        a = argv[i]
        if a == "--sides":
            sides, i = True, i + 1
        elif a == "--exaggerate":
            scale, i = float(argv[i + 1]), i + 2
        elif a in ("--view", "--up", "--size"):
            v = tuple(float(x) for x in argv[i + 1].split(","))
            if a == "--view":
                view = v
            elif a == "--up":
                up = v
            else:
                size = (int(v[0]), int(v[1]))
            i += 2
        else:
            label, path = a.rsplit("=", 1)
            frames.append((label, path))
            i += 1
    return out, view, up, size, frames, scale, sides


def main():
    out, view, up, size, frames, scale, sides = parse(sys.argv[1:])
    grids, vmax = [], 0.0
    for label, path in frames:
        r = vtk.vtkXMLUnstructuredGridReader()
        r.SetFileName(path)
        r.Update()
        calc = vtk.vtkArrayCalculator()
        calc.SetInputData(r.GetOutput())
        calc.SetAttributeTypeToPointData()
        calc.AddVectorArrayName("displacement")
        calc.SetFunction("mag(displacement)")
        calc.SetResultArrayName("magnitude")
        calc.Update()
        vmax = max(vmax, calc.GetOutput().GetPointData().GetArray("magnitude").GetRange()[1])
        grids.append((label, calc.GetOutput()))
    lut = vtk.vtkLookupTable()
    lut.SetHueRange(0.667, 0.0)
    lut.Build()
    side_lut = vtk.vtkLookupTable()
    side_lut.SetNumberOfTableValues(3)
    for k, rgb in enumerate([(0.85, 0.85, 0.85), (0.9, 0.3, 0.2), (0.2, 0.4, 0.9)]):
        side_lut.SetTableValue(k, *rgb, 1.0)
    side_lut.SetRange(-1, 1)
    window = vtk.vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetSize(size[0] * len(grids), size[1])
    for k, (label, grid) in enumerate(grids):
        renderer = vtk.vtkRenderer()
        renderer.SetBackground(1, 1, 1)
        renderer.SetViewport(k / len(grids), 0, (k + 1) / len(grids), 1)
        warp = vtk.vtkWarpVector()  # the points are x = X + u; drawn at X + S u
        warp.SetInputData(grid)
        warp.SetInputArrayToProcess(0, 0, 0, vtk.vtkDataObject.FIELD_ASSOCIATION_POINTS, "displacement")
        warp.SetScaleFactor(scale - 1.0)
        surface = vtk.vtkDataSetSurfaceFilter()
        surface.SetInputConnection(warp.GetOutputPort())
        mapper = vtk.vtkDataSetMapper()
        mapper.SetInputConnection(surface.GetOutputPort())
        if sides:  # the cell field `side`: -1 standard, 0 above, 1 below a cut
            mapper.SetScalarModeToUseCellFieldData()
            mapper.SelectColorArray("side")
            mapper.SetLookupTable(side_lut)
            mapper.SetScalarRange(-1, 1)
        else:
            mapper.SetScalarModeToUsePointFieldData()
            mapper.SelectColorArray("magnitude")
            mapper.SetLookupTable(lut)
            mapper.SetScalarRange(0, vmax if vmax > 0 else 1)
        actor = vtk.vtkActor()
        actor.SetMapper(mapper)
        actor.GetProperty().EdgeVisibilityOn()
        actor.GetProperty().SetEdgeColor(0.15, 0.15, 0.15)
        renderer.AddActor(actor)
        text = vtk.vtkTextActor()
        text.SetInput(label)
        text.GetTextProperty().SetColor(0, 0, 0)
        text.GetTextProperty().SetFontSize(15)
        text.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
        text.SetPosition(0.03, 0.93)
        renderer.AddActor2D(text)
        camera = renderer.GetActiveCamera()
        camera.SetPosition(*view)
        camera.SetFocalPoint(0, 0, 0)
        camera.SetViewUp(*up)
        camera.ParallelProjectionOn()
        renderer.ResetCamera()
        # ResetCamera fits the bounding sphere vertically; a narrow viewport needs it to fit
        # horizontally too.
        aspect = size[0] / size[1]
        camera.SetParallelScale(camera.GetParallelScale() / min(1.0, aspect))
        camera.Zoom(0.85)
        if k == len(grids) - 1 and not sides:
            bar = vtk.vtkScalarBarActor()
            bar.SetLookupTable(lut)
            bar.SetTitle("|displacement|")
            bar.SetNumberOfLabels(3)
            bar.SetWidth(0.14)
            bar.SetHeight(0.45)
            bar.SetPosition(0.84, 0.08)
            bar.GetTitleTextProperty().SetColor(0, 0, 0)
            bar.GetLabelTextProperty().SetColor(0, 0, 0)
            renderer.AddActor2D(bar)
        window.AddRenderer(renderer)
    window.Render()
    grab = vtk.vtkWindowToImageFilter()
    grab.SetInput(window)
    writer = vtk.vtkPNGWriter()
    writer.SetFileName(out)
    writer.SetInputConnection(grab.GetOutputPort())
    writer.Write()


if __name__ == "__main__":
    main()
