"""Triangle-mesh walls in scene files (``[[meshes]]``): the wall a file gives, its own
material, a mesh floor that is a plane floor, and bad input as one line, exit 2."""

import numpy as np
import pytest
from test_cli import assert_one_line_error, base_scene, run_cli, write_scene

import dem
from dem.io.scene import build_simulation, load_scene
from dem.meshwall import CUBE_FACES, CUBE_VERTICES

#: the square [-100, 100]^2 mm at z = 0 as two triangles, normal +z
FLOOR_V = np.array([[-100.0, -100.0, 0.0], [100.0, -100.0, 0.0], [100.0, 100.0, 0.0],
                    [-100.0, 100.0, 0.0]])
FLOOR_F = np.array([[0, 1, 2], [0, 2, 3]])


def _mesh_floor(tmp_path, **keys):
    """base_scene() with its floor plane replaced by the floor of an STL file in mm."""
    dem.MeshWall(FLOOR_V, FLOOR_F).write(tmp_path / "floor.stl")
    scene = base_scene()
    scene["walls"] = []
    scene["meshes"] = [{"file": "floor.stl", "scale": 0.001, **keys}]
    return scene


def _build(tmp_path, scene, name="scene.toml"):
    return build_simulation(load_scene(write_scene(tmp_path, scene, name)))[0]


def test_a_mesh_floor_from_a_file_is_the_plane_floor(tmp_path):
    """Eight spheres settling on the STL floor (in mm, scaled to m) move as on the
    [[walls]] plane, to round-off."""
    mesh = _build(tmp_path, _mesh_floor(tmp_path))
    plane = _build(tmp_path, base_scene(), "plane.toml")
    (wall,) = mesh.mesh_walls
    np.testing.assert_array_equal(wall.bounds, [[-0.1, -0.1, 0.0], [0.1, 0.1, 0.0]])
    assert mesh.dt == plane.dt
    mesh.run(400)
    plane.run(400)
    b, p = mesh.bodies, plane.bodies
    assert p.pos[:8, 2].min() < 0.005  # the lowest press into the floor
    scale = np.abs(p.pos[:8]).max()
    np.testing.assert_allclose(b.pos[:8], p.pos[:8], rtol=0.0, atol=1e-12 * scale)
    np.testing.assert_allclose(b.vel[:8], p.vel[:8], rtol=0.0,
                               atol=1e-10 * np.abs(p.vel[:8]).max())


def test_a_moving_mesh_of_its_own_material(tmp_path):
    """Scale, shift, motion and the wall's own friction reach the MeshWall."""
    dem.MeshWall(CUBE_VERTICES, CUBE_FACES).write(tmp_path / "cube.stl")
    scene = base_scene()
    scene["meshes"] = [{"file": "cube.stl", "scale": 0.01, "shift": [0.1, 0.0, 0.0],
                        "velocity": [0.0, 0.0, -0.1], "angular_velocity": [0.0, 0.0, 2.0],
                        "watertight": True, "mu": 0.1}]
    sim = _build(tmp_path, scene)
    (wall,) = sim.mesh_walls
    np.testing.assert_allclose(wall.bounds, [[0.1, 0.0, 0.0], [0.11, 0.01, 0.01]],
                               rtol=0, atol=1e-15)
    np.testing.assert_allclose(wall.center, [0.105, 0.005, 0.005], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(wall.velocity, [0.0, 0.0, -0.1])
    np.testing.assert_array_equal(wall.angular_velocity, [0.0, 0.0, 2.0])
    assert wall.is_watertight()
    c = scene["contact"]
    own = dem.LinearSpring(kn=c["kn"], kt=c["kt"], mu=0.1, restitution=c["restitution"])
    np.testing.assert_array_equal(sim.parameter_table("pw")[0, wall.mat_id], own.row())
    floor = sim.bodies.mat_id[-1]
    assert floor != wall.mat_id
    shared = dem.LinearSpring(kn=c["kn"], kt=c["kt"], mu=c["mu"], restitution=c["restitution"])
    np.testing.assert_array_equal(sim.parameter_table("pw")[0, floor], shared.row())


def test_dem_run_reports_and_writes_the_mesh_walls(tmp_path, capsys):
    scene = _mesh_floor(tmp_path)
    scene["simulation"]["steps"] = 20
    scene["output"] = {"every": 10, "contacts": False}
    path = write_scene(tmp_path, scene)
    code, out, _ = run_cli(["run", path, "--dry-run"], capsys)
    assert code == 0 and "8 spheres, 0 walls, 1 mesh walls (3D)" in out
    code, out, _ = run_cli(["run", path, "-o", tmp_path / "out"], capsys)
    assert code == 0
    assert (tmp_path / "out" / "scene_meshes.xdmf").exists()


def _cube(tmp_path):
    dem.MeshWall(CUBE_VERTICES, CUBE_FACES).write(tmp_path / "cube.stl")


def _open(tmp_path):
    dem.MeshWall(FLOOR_V, FLOOR_F).write(tmp_path / "cube.stl")


def _flat(tmp_path):
    (tmp_path / "cube.stl").write_text(
        "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
        "vertex 2 0 0\nendloop\nendfacet\nendsolid s\n")


BAD = {
    "missing file": (None, {}, ("[[meshes]] #1", "cube.stl does not exist")),
    "not a mesh": (lambda p: (p / "cube.stl").write_text("no mesh\n"), {},
                   ("[[meshes]] #1", "cannot read mesh file", "cube.stl")),
    "degenerate": (_flat, {}, ("[[meshes]] #1", "face 0 is degenerate")),
    "open": (_open, {"watertight": True},
             ("[[meshes]] #1", "cube.stl is not watertight: 4 open edges")),
    "overlap": (_cube, {"shift": [0.008, -0.5, -0.5]},
                ("[[meshes]] #1", "particle", "overlaps the mesh wall by")),
    "scale": (_cube, {"scale": 0.0}, ("[[meshes]] #1", "scale must be > 0")),
    "wall key": (_cube, {"young": 1e9}, ("[[meshes]] #1", "young is not used with the "
                                         "linear law")),
    "2D": (_cube, {"dim": 2}, ("[[meshes]] #1", "mesh walls need a 3D scene")),
    "periodic": (_cube, {"domain": True}, ("[[meshes]] #1", "periodic [domain]")),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_mesh_walls_exit_2_with_one_line(case, tmp_path, capsys):
    make, keys, fragments = BAD[case]
    if make is not None:
        make(tmp_path)
    scene = base_scene()
    keys = dict(keys)
    if keys.pop("dim", None):
        scene = {**scene, "simulation": {**scene["simulation"], "dim": 2,
                                         "gravity": [0.0, -9.81]}}
        scene["particles"] = {**scene["particles"], "lo": [0.0, 0.0], "hi": [0.03, 0.03],
                              "count": 4}
        scene["walls"] = [{"point": [0.0, 0.0], "normal": [0.0, 1.0]}]
    if keys.pop("domain", None):
        scene["domain"] = {"periodic": ["x"], "lo": [-0.01, -0.01, -0.01],
                           "hi": [0.04, 0.04, 0.04]}
    table = {"file": "cube.stl", "shift": [0.2, 0.0, 0.0], **keys}
    if scene["simulation"].get("dim") == 2:
        del table["shift"]
    scene["meshes"] = [table]
    path = write_scene(tmp_path, scene)
    code, _, err = run_cli(["run", path, "-o", tmp_path / "out"], capsys)
    assert code == 2
    assert_one_line_error(err, *fragments)
    assert not (tmp_path / "out").exists()
