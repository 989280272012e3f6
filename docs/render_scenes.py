#!/usr/bin/env python3
"""Renders the surgical scenes' embedded surfaces at three moments, for the README.

Needs Debian's python3-vtk9 (run with /usr/bin/python3; under xvfb-run on a machine without a
display, as Debian's VTK renders offscreen through X):
    xvfb-run -a /usr/bin/python3 docs/render_scenes.py fat_grasp|vessel_twist|liver_cage|liver_cut|sheet_tear DIR OUT.png

DIR is the example's --out directory from a default run (a frame every 10 steps of 10 ms:
frame k is t = k / 10 s). Each panel draws the smooth embedded surface (DIR/SCENE_surface_NNNN.vtu,
shaded with the normals the example wrote), coloured by the magnitude of its displacement in
mm, one colour scale for the three panels; the simulation mesh is drawn as a faint wireframe
where it helps to see the motion (the vessel's mesh, the liver's cage).
"""
import sys

import vtk

# Per scene: the three moments (frame, label), the camera (direction from the focal point,
# view up), whether to draw the mesh's wireframe, the panels' size, and how close the camera
# is (1: the bounds' diagonal fills the view).
SCENES = {
    "fat_grasp": {
        "frames": [(0, "rest"), (15, "lifted 15 mm, t = 1.5 s"), (30, "released, relaxed: t = 3 s")],
        "camera": ((0.2, -1.0, 0.55), (0, 0, 1)),
        "wireframe": False,
        "size": (520, 330),
        "zoom": 0.75,
    },
    "vessel_twist": {
        "frames": [(0, "rest"), (15, "twisted 90 degrees, t = 1.5 s"), (30, "released: t = 3 s")],
        "camera": ((0.35, -1.0, 0.45), (0, 0, 1)),
        "wireframe": True,
        "size": (520, 300),
        "zoom": 0.8,
    },
    "liver_cage": {
        "frames": [(0, "rest"), (20, "left lobe lifted 25 mm, t = 2 s"),
                   (35, "released: t = 3.5 s")],
        "camera": ((0.15, -1.0, 0.35), (0, 0, 1)),
        "wireframe": True,
        "size": (560, 380),
        "zoom": 0.8,
    },
    "liver_cut": {
        "frames": [(0, "rest"), (13, "the blade half-way: t = 1.3 s"), (25, "the lobe cut off: t = 2.5 s")],
        "camera": ((0.0, -0.8, 1.0), (0, 0, 1)),
        "wireframe": False,
        "size": (520, 380),
        "zoom": 0.75,
    },
    "sheet_tear": {
        "frames": [(0, "rest, nicked at the left"), (6, "tearing: t = 0.6 s"), (15, "torn through: t = 1.5 s")],
        "camera": ((0.0, -0.25, 1.0), (0, 1, 0)),
        "wireframe": False,
        "size": (420, 400),
        "zoom": 0.95,
    },
}


def read(path):
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(path)
    r.Update()
    return r.GetOutput()


def surface_of(grid):
    """The grid's triangles as polydata, with the written normals as the shading normals and
    |displacement| in mm as the scalars."""
    geometry = vtk.vtkGeometryFilter()
    geometry.SetInputData(grid)
    geometry.Update()
    poly = geometry.GetOutput()
    pd = poly.GetPointData()
    pd.SetNormals(pd.GetArray("normal"))
    disp = pd.GetArray("displacement")
    mag = vtk.vtkDoubleArray()
    mag.SetName("mm")
    for i in range(disp.GetNumberOfTuples()):
        x, y, z = disp.GetTuple3(i)
        mag.InsertNextValue(1e3 * (x * x + y * y + z * z) ** 0.5)
    pd.SetScalars(mag)
    return poly


def wireframe_of(grid):
    """The volume mesh's outer edges, deformed (the VTU's points are already moved)."""
    outline = vtk.vtkDataSetSurfaceFilter()
    outline.SetInputData(grid)
    edges = vtk.vtkExtractEdges()
    edges.SetInputConnection(outline.GetOutputPort())
    edges.Update()
    return edges.GetOutput()


def main():
    scene, directory, out = sys.argv[1:4]
    spec = SCENES[scene]
    panels = []
    vmax = 0.0
    for frame, label in spec["frames"]:
        surface = surface_of(read("%s/%s_surface_%04d.vtu" % (directory, scene, frame)))
        vmax = max(vmax, surface.GetPointData().GetScalars().GetRange()[1])
        mesh = read("%s/%s_%04d.vtu" % (directory, scene, frame)) if spec["wireframe"] else None
        panels.append((label, surface, mesh))
    lut = vtk.vtkLookupTable()
    lut.SetHueRange(0.667, 0.0)
    lut.SetTableRange(0, vmax)
    lut.Build()

    # One camera for all panels, fitted to the union of their bounds.
    bounds = [1e30, -1e30] * 3
    for _, surface, _ in panels:
        b = surface.GetBounds()
        for a in range(3):
            bounds[2 * a] = min(bounds[2 * a], b[2 * a])
            bounds[2 * a + 1] = max(bounds[2 * a + 1], b[2 * a + 1])
    width, height = spec["size"]
    window = vtk.vtkRenderWindow()
    window.SetOffScreenRendering(1)
    strip = 110  # the colour bar's own strip on the right, clear of the panels
    total = width * len(panels) + strip
    window.SetSize(total, height)
    camera = vtk.vtkCamera()
    direction, up = spec["camera"]
    centre = [(bounds[2 * a] + bounds[2 * a + 1]) / 2 for a in range(3)]
    camera.SetFocalPoint(*centre)
    camera.SetPosition(*[centre[a] + direction[a] for a in range(3)])
    camera.SetViewUp(*up)
    camera.SetViewAngle(20)
    for k, (label, surface, mesh) in enumerate(panels):
        renderer = vtk.vtkRenderer()
        renderer.SetBackground(1, 1, 1)
        renderer.SetViewport(k * width / total, 0, (k + 1) * width / total, 1)
        renderer.SetActiveCamera(camera)
        mapper = vtk.vtkPolyDataMapper()
        mapper.SetInputData(surface)
        mapper.SetLookupTable(lut)
        mapper.SetScalarRange(0, vmax if vmax > 0 else 1)
        actor = vtk.vtkActor()
        actor.SetMapper(mapper)
        actor.GetProperty().SetInterpolationToPhong()
        actor.GetProperty().SetSpecular(0.25)
        actor.GetProperty().SetSpecularPower(30)
        renderer.AddActor(actor)
        if mesh is not None:
            edges = vtk.vtkPolyDataMapper()
            edges.SetInputData(wireframe_of(mesh))
            edges.ScalarVisibilityOff()
            wire = vtk.vtkActor()
            wire.SetMapper(edges)
            wire.GetProperty().SetColor(0.2, 0.2, 0.2)
            wire.GetProperty().SetOpacity(0.25)
            renderer.AddActor(wire)
        text = vtk.vtkTextActor()
        text.SetInput(label)
        text.GetTextProperty().SetColor(0, 0, 0)
        text.GetTextProperty().SetFontSize(18)
        text.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
        text.SetPosition(0.03, 0.9)
        renderer.AddActor2D(text)
        window.AddRenderer(renderer)
    legend = vtk.vtkRenderer()
    legend.SetBackground(1, 1, 1)
    legend.SetViewport(len(panels) * width / total, 0, 1, 1)
    bar = vtk.vtkScalarBarActor()
    bar.SetLookupTable(lut)
    bar.SetTitle("|u| mm")
    bar.SetNumberOfLabels(3)
    bar.SetLabelFormat("%.0f")
    bar.SetWidth(0.45)
    bar.SetHeight(0.6)
    bar.SetPosition(0.15, 0.18)
    bar.UnconstrainedFontSizeOn()
    bar.GetTitleTextProperty().SetColor(0, 0, 0)
    bar.GetTitleTextProperty().SetFontSize(16)
    bar.GetLabelTextProperty().SetColor(0, 0, 0)
    bar.GetLabelTextProperty().SetFontSize(14)
    legend.AddActor2D(bar)
    window.AddRenderer(legend)
    # Frame the union of the bounds: a distance at which its diagonal fills the view.
    diagonal = sum((bounds[2 * a + 1] - bounds[2 * a]) ** 2 for a in range(3)) ** 0.5
    norm = sum(d * d for d in direction) ** 0.5
    distance = 0.5 * diagonal / 0.176 * spec["zoom"]  # tan(10 degrees): half the view angle
    camera.SetPosition(*[centre[a] + direction[a] / norm * distance for a in range(3)])
    window.Render()
    grab = vtk.vtkWindowToImageFilter()
    grab.SetInput(window)
    writer = vtk.vtkPNGWriter()
    writer.SetFileName(out)
    writer.SetInputConnection(grab.GetOutputPort())
    writer.Write()


if __name__ == "__main__":
    main()
