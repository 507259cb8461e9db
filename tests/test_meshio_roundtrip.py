"""Every XDMF file the project writes opens in meshio with every array.

Each output kind is written on a tiny case: particle frames of ``dem run`` (3D
spheres, walls, contacts) and of the Python API (2D disks and polygons: shapes and
contacts), and the ``fields.xdmf`` of ``hmm run`` (small and finite kinematics, dry and
saturated). Every file is read back with meshio's ``TimeSeriesReader`` (the points and
cells of its first grid, the time and attributes of every step), and every grid, as a
single-grid file, with ``meshio.read`` (its own points and cells). What is read is
compared with the HDF5 datasets read with h5py: 2D vectors come back with a zero third
component, nothing is left out.
"""

import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import meshio
import numpy as np
import pytest

import dem
from dem.cli import main as dem_main
from dem.shapes import ConvexPolygon
from hmm.problem import validate_problem
from hmm.run import run_problem


def pad(a):
    a = np.asarray(a, dtype=float)
    a = a.reshape(a.shape[0], -1)
    return np.hstack([a, np.zeros((a.shape[0], 3 - a.shape[1]))])


def read_series(path):
    """(points, cells, [(t, point_data, cell_data), ...]) by meshio's TimeSeriesReader;
    cell data of the single cell block."""
    with meshio.xdmf.TimeSeriesReader(path) as r:
        points, cells = r.read_points_cells()
        steps = []
        for k in range(r.num_steps):
            t, pd, cd = r.read_data(k)
            assert all(len(v) == 1 for v in cd.values())
            steps.append((t, pd, {name: v[0] for name, v in cd.items()}))
    return points, cells, steps


def read_grids(path, tmp_path):
    """Each grid of the series ``path`` as a meshio.Mesh read by ``meshio.read`` (a
    single-grid file holding the grid without its Time, next to ``path``)."""
    root = ET.parse(path).getroot()
    meshes = []
    for k, grid in enumerate(root.find("Domain/Grid").findall("Grid")):
        grid.remove(grid.find("Time"))
        one = ET.Element("Xdmf", {"Version": root.get("Version")})
        ET.SubElement(one, "Domain").append(grid)
        single = Path(path).with_name(f"{Path(path).stem}.grid{k}.xdmf")
        ET.ElementTree(one).write(single)
        meshes.append(meshio.read(single))
        single.unlink()
    return meshes


def assert_readers_agree(path, tmp_path, expected, atol=0.0):
    """The XDMF file ``path`` read by both meshio readers equals ``expected``: a list
    (one per step) of dicts with ``time``, ``points`` (to ``atol`` [m]: points derived
    by the writer in another order of operations), ``cell_type``, ``cells``,
    ``point_data`` and ``cell_data`` (every array the step must carry; a point array
    ``position`` must equal the points)."""
    text = Path(path).read_text()
    assert 'Version="3.0"' in text and "Function" not in text and "HyperSlab" not in text
    points, cells, steps = read_series(path)
    meshes = read_grids(path, tmp_path)
    assert len(steps) == len(meshes) == len(expected) > 0
    first = expected[0]
    np.testing.assert_allclose(points, first["points"], rtol=0.0, atol=atol)
    assert [c.type for c in cells] == [first["cell_type"]]
    np.testing.assert_array_equal(cells[0].data, first["cells"])
    for (t, pd, cd), mesh, want in zip(steps, meshes, expected, strict=True):
        assert t == want["time"]
        np.testing.assert_allclose(mesh.points, want["points"], rtol=0.0, atol=atol)
        assert [c.type for c in mesh.cells] == [want["cell_type"]]
        np.testing.assert_array_equal(mesh.cells[0].data, want["cells"])
        for got, name in ((pd, "point_data"), (cd, "cell_data"),
                          (mesh.point_data, "point_data")):
            assert set(got) == set(want[name]), name
            for key, value in want[name].items():
                if key == "position":  # the points of this step, read per step
                    value = want["points"]
                    np.testing.assert_allclose(got[key], value, rtol=0.0, atol=atol)
                    continue
                assert got[key].shape[0] == value.shape[0], key
                np.testing.assert_array_equal(got[key].reshape(value.shape), value,
                                              err_msg=key)


# ------------------------------------------------------------------ particle frames
def particles_expected(f):
    """What ``run.xdmf`` must hold, from the raw datasets of every frame."""
    out = []
    for name in sorted(f["frames"], key=int):
        g = f["frames"][name]
        d = g.attrs["dim"]
        n = g["pos"].shape[0]
        if n == 0:
            continue
        data = {k: g[k][()] for k in ("id", "kind", "radius", "ang_vel")}
        data |= {k: pad(g[k]) for k in ("vel", "force")}
        rot = g["rot"][()]
        if d == 2:
            data["angle"] = rot
            data["quat"] = np.column_stack([np.cos(rot[:, 0] / 2), np.zeros((n, 2)),
                                            np.sin(rot[:, 0] / 2)])
        else:
            data["quat"] = rot
        data |= {k: v[()] for k, v in g.get("fields", {}).items()}
        out.append({"time": g.attrs["time"], "points": pad(g["pos"]),
                    "cell_type": "vertex", "cells": np.arange(n)[:, None],
                    "point_data": data | {"position": None}, "cell_data": {}})
    return out


def contacts_expected(f):
    """``run_contacts.xdmf``: a line per contact from the centre of i to the centre of
    j, or to the contact point (halfway between x1 and x2) for a wall."""
    out = []
    for name in sorted(f["frames"], key=int):
        g = f["frames"][name]
        if g.attrs["n_contacts"] == 0:
            continue
        c = {k: v[()] for k, v in g["contacts"].items() if isinstance(v, h5py.Dataset)}
        centre = dict(zip(g["id"][()], g["pos"][()], strict=True))
        start = np.array([centre[i] for i in c["i"]])
        end = np.array([0.5 * (x1 + x2) if wall else centre[j] for j, x1, x2, wall
                        in zip(c["j"], c["x1"], c["x2"], c["is_wall"], strict=True)])
        fn = np.einsum("kd,kd->k", c["force"], c["normal"])
        ft = c["force"] - fn[:, None] * c["normal"]
        k = c["i"].size
        out.append({"time": g.attrs["time"],
                    "points": pad(np.stack([start, end], axis=1).reshape(2 * k, -1)),
                    "cell_type": "line", "cells": np.arange(2 * k).reshape(k, 2),
                    "point_data": {"position": None},
                    "cell_data": {"normal_force": fn, "tangential_force": pad(ft),
                                  "force": pad(c["force"]), "normal": pad(c["normal"]),
                                  "overlap": c["overlap"], "i": c["i"], "j": c["j"]}})
    return out


def walls_expected(f, walls_file):
    """``run_walls.xdmf``: one patch per plane, lying in the plane and around the
    particles (checked here; the points themselves are taken from the file)."""
    out = []
    grids = read_grids(walls_file, None)
    for mesh, name in zip(grids, sorted(f["frames"], key=int), strict=True):
        g = f["frames"][name]
        w = g["walls"]
        d = g.attrs["dim"]
        k = 4 if d == 3 else 2
        nw = w["id"].shape[0]
        corners = mesh.points.reshape(nw, k, 3)[:, :, :d]
        offset = np.einsum("wkd,wd->wk", corners - w["pos"][()][:, None], w["normal"][()])
        np.testing.assert_allclose(offset, 0.0, atol=1e-12)
        middle = corners.mean(axis=1)
        to_centre = g["pos"][()].mean(axis=0) - middle
        along = to_centre - np.einsum("wd,wd->w", to_centre, w["normal"][()])[:, None] \
            * w["normal"][()]
        np.testing.assert_allclose(along, 0.0, atol=1e-12)
        reach = np.ptp(g["pos"][()], axis=0).max() / 2
        assert np.all(np.linalg.norm(corners - middle[:, None], axis=2) > reach)
        out.append({"time": g.attrs["time"], "points": mesh.points,
                    "cell_type": "quad" if d == 3 else "line",
                    "cells": np.arange(nw * k).reshape(nw, k),
                    "point_data": {"position": None},
                    "cell_data": {"id": w["id"][()], "normal": pad(w["normal"])}})
    return out


def shapes_expected(f):
    out = []
    for name in sorted(f["frames"], key=int):
        g = f["frames"][name]
        if "surface" not in g:
            continue
        s = g["surface"]
        out.append({"time": g.attrs["time"], "points": s["points"][()],
                    "cell_type": "triangle", "cells": s["cells"][()],
                    "point_data": {"position": None},
                    "cell_data": {"body": s["body"][()], "vel": s["vel"][()]}})
    return out


def check_particle_files(h5, tmp_path, kinds):
    files = dem.io.xdmf.xdmf_files(h5.with_suffix(".xdmf"))
    assert {k for k, p in files.items() if Path(p).exists()} == set(kinds)
    with h5py.File(h5, "r") as f:
        assert_readers_agree(files["particles"], tmp_path, particles_expected(f))
        if "contacts" in kinds:
            assert_readers_agree(files["contacts"], tmp_path, contacts_expected(f),
                                 atol=1e-15)
        if "walls" in kinds:
            assert_readers_agree(files["walls"], tmp_path,
                                 walls_expected(f, files["walls"]))
        if "shapes" in kinds:
            assert_readers_agree(files["shapes"], tmp_path, shapes_expected(f))


SCENE = """
[simulation]
steps = 60
gravity = [0.0, 0.0, -9.81]

[particles]
generator = "lattice"
count = 8
lo = [0.0, 0.0, 0.0]
hi = [0.03, 0.03, 0.03]
radius = 0.005
density = 2500.0

[[walls]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]

[[walls]]
point = [0.0, 0.0, 0.0]
normal = [1.0, 0.0, 0.0]

[contact]
law = "linear"
kn = 1.0e4
kt = 5.0e3
mu = 0.5
restitution = 0.5

[output]
every = 20
contacts = true
"""


def test_dem_run_particle_files_open_in_meshio(tmp_path):
    (tmp_path / "drop.toml").write_text(SCENE)
    with pytest.raises(SystemExit) as exc:
        dem_main(["run", str(tmp_path / "drop.toml"), "--output", str(tmp_path / "out"),
                  "--no-progress"])
    assert exc.value.code == 0
    (h5,) = (tmp_path / "out").glob("*.h5")
    with h5py.File(h5, "r") as f:
        assert max(g.attrs["n_contacts"] for g in f["frames"].values()) > 0
    check_particle_files(h5, tmp_path, {"particles", "contacts", "walls"})


def test_2d_shapes_and_contacts_open_in_meshio(tmp_path):
    b = dem.Bodies.spheres([[0.0, 0.0095], [0.021, 0.0098]], radius=0.01, density=20.0,
                           vel=[[0.1, 0.0], [-0.1, 0.0]])
    square = ConvexPolygon([[-0.01, -0.01], [0.01, -0.01], [0.01, 0.01], [-0.01, 0.01]])
    b.add_shapes(square, [[0.06, 0.0099]], density=20.0, rot=[0.3], vel=[[-0.2, 0.0]])
    b.add_plane([0.0, 0.0], [0.0, 1.0])
    sim = dem.Simulation(b, dem.LinearSpring(kn=1e3, kt=3e2, mu=0.3), gravity=[0, -9.81])
    h5 = tmp_path / "mix.h5"
    with dem.io.H5Writer(h5, every=25, contacts=True,
                         fields={"speed": lambda s: np.linalg.norm(s.bodies.vel, axis=1)}
                         ) as out:
        out(sim)
        sim.observers.append(out)
        sim.run(100)
    with h5py.File(h5, "r") as f:
        assert f.attrs["dim"] == 2
        assert max(g.attrs["n_contacts"] for g in f["frames"].values()) > 0
    check_particle_files(h5, tmp_path, {"particles", "contacts", "walls", "shapes"})


# ------------------------------------------------------------------ hmm fields
ELASTIC = {
    "mesh": {"size": [1.0, 2.0], "cells": [2, 1]},
    "dirichlet": [{"boundary": "bottom", "component": "y"},
                  {"boundary": "left", "component": "x"},
                  {"boundary": "top", "component": "y", "value": -0.01}],
    "micro": {"model": "linear_elastic", "young": 1e6, "poisson": 0.3},
    "load": {"steps": 2},
}
SATURATED = {
    "mesh": {"dim": 2, "element": "quad8", "size": [0.1, 1.0], "cells": [1, 2]},
    "dirichlet": [{"boundary": "bottom", "component": "y"},
                  {"boundary": "left", "component": "x"},
                  {"boundary": "right", "component": "x"}],
    "pressure": [{"boundary": "top", "value": 1e4, "ramp": True}],
    "load": {"steps": 3},
    "fluid": {"permeability": 1.2e-10, "bulk_modulus": 2.2e9},
    "drainage": [{"boundary": "top", "pressure": 0.0}],
    "time": {"end": 1.0, "first": 0.1},
    "micro": {"model": "linear_elastic", "young": 1e7, "poisson": 0.25},
}
FINITE_3D = {
    "mesh": {"dim": 3, "element": "hex1", "size": [1.0, 1.0, 1.0], "cells": [1, 1, 1]},
    "dirichlet": [{"boundary": "bottom", "component": "y"},
                  {"boundary": "left", "component": "x"},
                  {"boundary": "front", "component": "z"},
                  {"boundary": "top", "component": "y", "value": -0.05}],
    "micro": {"model": "neo_hookean", "young": 1e6, "poisson": 0.3},
    "solver": {"kinematics": "finite"},
    "load": {"steps": 2},
}


def fields_expected(f):
    """``fields.xdmf``: the mesh (the deformed one per step under finite kinematics),
    displacement and pore pressure on the nodes, every element dataset on the cells."""
    out = []
    for name in sorted(f["steps"]):
        g = f["steps"][name]
        node = {k: g[k][()] for k in ("displacement", "pore_pressure") if k in g}
        cell = {k: v[()] for k, v in g.items() if isinstance(v, h5py.Dataset)
                and k not in node and k != "points"}
        time = g.attrs["time"] if "time" in g.attrs else g.attrs["load_factor"]
        out.append({"time": time,
                    "points": g["points"][()] if "points" in g else f["mesh/points"][()],
                    "cell_type": "hexahedron" if f["mesh/cells"].shape[1] == 8 else "quad",
                    "cells": f["mesh/cells"][()], "point_data": node, "cell_data": cell})
    return out


@pytest.mark.parametrize("problem", [ELASTIC, SATURATED, FINITE_3D],
                         ids=["dry", "saturated", "finite-3d"])
def test_hmm_fields_open_in_meshio(tmp_path, problem):
    run_problem(validate_problem(problem, source="p.toml"), tmp_path / "out",
                progress=False)
    with h5py.File(tmp_path / "out" / "fields.h5", "r") as f:
        expected = fields_expected(f)
        assert len(expected) == len(f["curve/load_factor"])
        if "fluid" in problem:
            assert "pore_pressure" in expected[-1]["point_data"]
            assert "total_stress_yy" in expected[-1]["cell_data"]
    assert_readers_agree(tmp_path / "out" / "fields.xdmf", tmp_path, expected)
