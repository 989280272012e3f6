#!/usr/bin/env python3
"""Renders plastifem VTU frames side by side, for the README's plasticity figures.

Needs Debian's python3-vtk9 (run with /usr/bin/python3; under xvfb-run on a machine without a
display):
    /usr/bin/python3 docs/render_plastic.py OUT.png [--view side|end] [--field NAME] [--exaggerate S] \
        --column "TITLE" "LABEL=frame.vtu" "LABEL=frame.vtu" ... [--column "TITLE" ...]

Each column is one viewport; its frames are stacked from top to bottom (the first on top),
drawn as surfaces with their mesh edges, coloured by the magnitude of the point field NAME
(default material_displacement: how far the material mesh moved, i.e. the plastic
deformation), one colour scale for the whole figure; --exaggerate S draws the points at
X + S (x - X), x - X being the field (1: as written). --view side looks at the bar from -y
(x to the right, z up); --view end looks along the bar's axis from +x (the cross-section).
"""
import sys

import vtk


def parse(argv):
    out, view, field, columns, scale = argv[0], "side", "material_displacement", [], 1.0
    i = 1
    while i < len(argv):
        a = argv[i]
        if a == "--view":
            view, i = argv[i + 1], i + 2
        elif a == "--field":
            field, i = argv[i + 1], i + 2
        elif a == "--exaggerate":
            scale, i = float(argv[i + 1]), i + 2
        elif a == "--column":
            columns.append((argv[i + 1], []))
            i += 2
        else:
            label, path = a.split("=", 1)
            columns[-1][1].append((label, path))
            i += 1
    return out, view, field, columns, scale


def magnitude(reader, field):
    grid = reader.GetOutput()
    calc = vtk.vtkArrayCalculator()
    calc.SetInputData(grid)
    calc.SetAttributeTypeToPointData()
    calc.AddVectorArrayName(field)
    calc.SetFunction("mag(%s)" % field)
    calc.SetResultArrayName("magnitude")
    calc.Update()
    return calc


def main():
    out, view, field, columns, scale = parse(sys.argv[1:])
    readers = []
    vmax = 0.0
    for _, frames in columns:
        rs = []
        for label, path in frames:
            r = vtk.vtkXMLUnstructuredGridReader()
            r.SetFileName(path)
            r.Update()
            calc = magnitude(r, field)
            vmax = max(vmax, calc.GetOutput().GetPointData().GetArray("magnitude").GetRange()[1])
            rs.append((label, calc))
        readers.append(rs)
    lut = vtk.vtkLookupTable()
    lut.SetHueRange(0.667, 0.0)
    lut.Build()
    window = vtk.vtkRenderWindow()
    window.SetOffScreenRendering(1)
    width = 560 if view == "side" else 300
    rows = max(len(f) for _, f in columns)
    height = (140 if view == "side" else 300) * rows + 70
    window.SetSize(width * len(columns), height)
    for c, ((title, frames), rs) in enumerate(zip(columns, readers)):
        renderer = vtk.vtkRenderer()
        renderer.SetBackground(1, 1, 1)
        renderer.SetViewport(c / len(columns), 0, (c + 1) / len(columns), 1)
        bounds = None
        for k, (label, calc) in enumerate(rs):
            grid = calc.GetOutput()
            b = grid.GetBounds()
            # Stack the frames: each one shifted down by its row.
            transform = vtk.vtkTransform()
            if view == "side":
                transform.Translate(0, 0, -6.0 * k)
            else:
                transform.Translate(0, 0, -6.0 * k)
            warp = vtk.vtkWarpVector()
            warp.SetInputData(grid)
            warp.SetInputArrayToProcess(0, 0, 0, vtk.vtkDataObject.FIELD_ASSOCIATION_POINTS, field)
            warp.SetScaleFactor(scale - 1.0)
            tf = vtk.vtkTransformFilter()
            tf.SetInputConnection(warp.GetOutputPort())
            tf.SetTransform(transform)
            surface = vtk.vtkDataSetSurfaceFilter()
            surface.SetInputConnection(tf.GetOutputPort())
            mapper = vtk.vtkDataSetMapper()
            mapper.SetInputConnection(surface.GetOutputPort())
            mapper.SetScalarModeToUsePointFieldData()
            mapper.SelectColorArray("magnitude")
            mapper.SetLookupTable(lut)
            mapper.SetScalarRange(0, vmax if vmax > 0 else 1)
            actor = vtk.vtkActor()
            actor.SetMapper(mapper)
            actor.GetProperty().EdgeVisibilityOn()
            actor.GetProperty().SetEdgeColor(0.15, 0.15, 0.15)
            renderer.AddActor(actor)
            tf.Update()
            bb = tf.GetOutput().GetBounds()
            text = vtk.vtkTextActor()
            text.SetInput(label)
            text.GetTextProperty().SetColor(0, 0, 0)
            text.GetTextProperty().SetFontSize(14)
            text.GetPositionCoordinate().SetCoordinateSystemToWorld()
            if view == "side":
                text.GetPositionCoordinate().SetValue(bb[0], 0, bb[5] + 0.3)
            else:
                text.GetPositionCoordinate().SetValue(0, bb[2], bb[5] + 0.3)
            renderer.AddActor2D(text)
        title_actor = vtk.vtkTextActor()
        title_actor.SetInput(title)
        title_actor.GetTextProperty().SetColor(0, 0, 0)
        title_actor.GetTextProperty().SetFontSize(16)
        title_actor.GetTextProperty().BoldOn()
        title_actor.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
        title_actor.SetPosition(0.02, 0.96)
        renderer.AddActor2D(title_actor)
        camera = renderer.GetActiveCamera()
        if view == "side":
            camera.SetPosition(0, -1, 0)
            camera.SetViewUp(0, 0, 1)
        else:
            camera.SetPosition(1, 0, 0)
            camera.SetViewUp(0, 0, 1)
        camera.SetFocalPoint(0, 0, 0)
        camera.ParallelProjectionOn()
        renderer.ResetCamera()
        camera.Zoom(0.92)
        if c == len(columns) - 1:
            bar = vtk.vtkScalarBarActor()
            bar.SetLookupTable(lut)
            bar.SetTitle(field.replace("_", "\n"))  # its magnitude, one word per line: it fits the margin
            bar.SetNumberOfLabels(3)
            bar.SetWidth(0.12)
            bar.SetHeight(0.5)
            bar.SetPosition(0.84, 0.25)
            # Fixed font sizes: scaled to the bar's width, the title came out unreadably small.
            bar.UnconstrainedFontSizeOn()
            bar.GetTitleTextProperty().SetFontSize(14)
            bar.GetLabelTextProperty().SetFontSize(13)
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
