"""Run by ``pvpython`` (ParaView's Python) from tests/walk/walk_paraview.py.

usage: pvpython paraview_check.py OUT_DIR PARTICLES.xdmf CONTACTS.xdmf FIELDS.xdmf
       [--no-render]

Opens each XDMF file with ParaView's default reader (Xdmf3) and its legacy reader,
prints one line per file and reader with the arrays it loaded, and renders two
pictures into OUT_DIR: the force chains of the last particle frame
(``force_chains.png``, contact lines coloured and sized by their normal force over
the particles) and the deformed multiscale mesh of the last step
(``deformed_mesh.png``, coloured by the deviatoric strain).
"""

import sys

from paraview.simple import (
    CellDatatoPointData,
    ColorBy,
    ExtractSurface,
    GetActiveViewOrCreate,
    GetAnimationScene,
    GetColorTransferFunction,
    GetScalarBar,
    Glyph,
    Hide,
    Render,
    ResetCamera,
    SaveScreenshot,
    Show,
    Tube,
    XDMFReader,
    Xdmf3ReaderS,
)


def arrays(source):
    source.UpdatePipeline(max(source.TimestepValues) if source.TimestepValues else 0.0)
    info = source.GetDataInformation()
    point = sorted(source.PointData.keys())
    cell = sorted(source.CellData.keys())
    return info.GetNumberOfPoints(), info.GetNumberOfCells(), point, cell


def report(path):
    for name, reader in (("Xdmf3", Xdmf3ReaderS), ("legacy", XDMFReader)):
        src = reader(FileName=path) if name == "Xdmf3" else reader(FileNames=[path])
        n_pts, n_cells, point, cell = arrays(src)
        print(f"{path.rsplit('/', 1)[-1]} {name}: {n_pts} points, {n_cells} cells; "
              f"point arrays {','.join(point)}; cell arrays {','.join(cell)}")


def last_time(source):
    times = source.TimestepValues
    t = max(times) if times else 0.0
    scene = GetAnimationScene()
    scene.UpdateAnimationUsingDataTimeSteps()
    scene.AnimationTime = t
    return t


def force_chains(particles, contacts, out):
    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = [900, 900]
    view.OrientationAxesVisibility = 0
    view.Background = [1.0, 1.0, 1.0]
    view.UseColorPaletteForBackground = 0
    p = Xdmf3ReaderS(FileName=particles)
    c = Xdmf3ReaderS(FileName=contacts)
    last_time(p)
    balls = Glyph(Input=p, GlyphType="Sphere")
    balls.ScaleArray = ["POINTS", "radius"]
    balls.ScaleFactor = 2.0
    balls.GlyphMode = "All Points"
    shown = Show(balls, view)
    shown.Opacity = 0.15
    ColorBy(shown, None)
    # each contact is a segment of its own two points: on the points, its force
    tubes = Tube(Input=ExtractSurface(Input=CellDatatoPointData(Input=c)))
    tubes.Scalars = ["POINTS", "normal_force"]
    tubes.VaryRadius = "By Scalar"
    tubes.Radius = 2.5e-4
    tubes.RadiusFactor = 8.0
    tubes.NumberofSides = 8
    t = Show(tubes, view)
    ColorBy(t, ("POINTS", "normal_force"))
    lut = GetColorTransferFunction("normal_force")
    lut.ApplyPreset("Inferno (matplotlib)", True)
    t.SetScalarBarVisibility(view, True)
    bar = GetScalarBar(lut, view)
    bar.Title, bar.ComponentTitle = "normal force", "[N]"
    bar.TitleColor = bar.LabelColor = [0.0, 0.0, 0.0]
    view.CameraPosition = [0.04, -0.25, 0.05]
    view.CameraFocalPoint = [0.04, 0.04, 0.03]
    view.CameraViewUp = [0.0, 0.0, 1.0]
    ResetCamera(view)
    Render(view)
    SaveScreenshot(f"{out}/force_chains.png", view, ImageResolution=[900, 900])
    Hide(balls, view)
    Hide(tubes, view)


def deformed_mesh(fields, out):
    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = [700, 900]
    f = Xdmf3ReaderS(FileName=fields)
    last_time(f)
    shown = Show(f, view)
    shown.SetRepresentationType("Surface With Edges")
    name = "deviatoric_strain"
    where = "CELLS" if name in f.CellData.keys() else "POINTS"
    ColorBy(shown, (where, name))
    GetColorTransferFunction(name).ApplyPreset("Viridis (matplotlib)", True)
    shown.SetScalarBarVisibility(view, True)
    bar = GetScalarBar(GetColorTransferFunction(name), view)
    bar.Title, bar.ComponentTitle = "deviatoric strain", "[-]"
    bar.TitleColor = bar.LabelColor = [0.0, 0.0, 0.0]
    view.Background = [1.0, 1.0, 1.0]
    view.UseColorPaletteForBackground = 0
    view.InteractionMode = "2D"
    view.CameraPosition = [0.0, 0.0, 10.0]  # the mesh's plane seen from above
    view.CameraFocalPoint = [0.0, 0.0, 0.0]
    view.CameraViewUp = [0.0, 1.0, 0.0]
    ResetCamera(view)
    Render(view)
    SaveScreenshot(f"{out}/deformed_mesh.png", view, ImageResolution=[700, 900])


def main():
    out, particles, contacts, fields = sys.argv[1:5]
    for path in (particles, contacts, fields):
        report(path)
    if "--no-render" in sys.argv:
        return
    force_chains(particles, contacts, out)
    deformed_mesh(fields, out)
    print("screenshots written")
    print("screenshots written")


if __name__ == "__main__":
    main()
