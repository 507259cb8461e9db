"""H5Writer and its XDMF file with level-set shapes: boxes, polygons, polyhedra, custom.

The surfaces written are checked against world vertices computed here from the shape
objects themselves (not from the shape table), and each body's triangles must close
around the body's own area (2D) or volume (3D) with outward orientation.
"""

import math
import os
import xml.etree.ElementTree as ET

import h5py
import numba
import numpy as np
import pytest

import dem
from dem.io import H5Writer, read_frame
from dem.io.xdmf import xdmf_files
from dem.shapes import Shape
from dem.shapes.box import Box
from dem.shapes.custom import CustomShape
from dem.shapes.polygon import ConvexPolygon
from dem.shapes.polyhedron import ConvexPolyhedron

CONTACT_KEYS = ("i", "j", "normal", "overlap", "x1", "x2", "branch", "force", "arm_i",
                "arm_j", "kn", "kt", "is_wall")


class StandIn:
    """The part of a Simulation the writer reads: bodies, clock and contacts()."""

    def __init__(self, bodies, step=0, dt=1e-5):
        self.bodies, self.step, self.dt = bodies, step, dt

    @property
    def time(self):
        return self.step * self.dt

    def contacts(self):
        d = self.bodies.dim
        out = {k: np.zeros((0, d)) for k in CONTACT_KEYS}
        out |= {"i": np.zeros(0, np.int32), "j": np.zeros(0, np.int32),
                "overlap": np.zeros(0), "kn": np.zeros(0), "kt": np.zeros(0),
                "is_wall": np.zeros(0, bool)}
        return out


@numba.njit
def _ellipse(x, y, z, p):  # an approximate SDF is enough for a glyph-only body
    return math.sqrt((x / p[0]) ** 2 + (y / p[1]) ** 2) * min(p[0], p[1]) - min(p[0], p[1])


def rotate(rot, v):
    """Rotate points ``v`` (m, d) by an angle (2D) or a quaternion (3D), padded to 3."""
    v = np.column_stack([v, np.zeros((len(v), 3 - v.shape[1]))])
    if np.size(rot) == 1:
        c, s = np.cos(rot), np.sin(rot)
        return np.column_stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1],
                                v[:, 2]])
    q = np.asarray(rot, np.float64) / np.linalg.norm(rot)
    w, u = q[0], q[1:]
    t = 2.0 * np.cross(u, v)  # v' = v + w t + u x t
    return v + w * t + np.cross(u, t)


def unrotate(rot, v):
    """The inverse of :func:`rotate`."""
    return rotate(-rot if np.size(rot) == 1 else rot * [1, -1, -1, -1], v)


def pad(x):
    """A point (d,) as (3,), z = 0 in 2D."""
    return np.append(x, np.zeros(3 - len(x)))


def random_quats(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def scene(dim, seed=0):
    """Shapes at random positions and orientations, two spheres and a floor.

    Returns the bodies and, per shaped body, ``(body id, shape object, pos, rot)`` as
    given to ``add_shapes``.
    """
    rng = np.random.default_rng(seed)
    if dim == 2:
        shapes = [Box([0.02, 0.01]), ConvexPolygon.regular(5, 0.015),
                  ConvexPolygon(rng.uniform(-0.02, 0.02, (9, 2)))]
    else:
        shapes = [Box([0.02, 0.01, 0.015]),
                  ConvexPolyhedron.from_vertices(rng.uniform(-0.02, 0.02, (14, 3))),
                  ConvexPolyhedron.extrude(ConvexPolygon.regular(6, 0.01), 0.03)]
    b = dem.Bodies.spheres(rng.uniform(0.0, 0.5, (2, dim)), radius=0.01, density=2500.0)
    placed = []
    for shape in shapes:
        pos = rng.uniform(0.0, 0.5, (2, dim))
        rot = rng.uniform(-np.pi, np.pi, 2) if dim == 2 else random_quats(rng, 2)
        ids = b.add_shapes(shape, pos, density=2500.0, rot=rot,
                           vel=rng.normal(0.0, 0.1, (2, dim)))
        placed += list(zip(ids.tolist(), [shape] * 2, pos, rot, strict=True))
    b.add_plane(np.zeros(dim), np.eye(dim)[-1])
    if dim == 2:  # no vertices: a particle (glyph), not a surface
        b.add_shapes(CustomShape(_ellipse, 0.02, dim=2, params=[0.02, 0.01],
                                 resolution=32), [[0.25, 0.25]], density=2500.0)
    return b, placed


def vertices(shape):
    return shape.corners() if isinstance(shape, Box) else shape.vertices


def n_triangles(shape):
    if shape.dim == 2:
        return len(vertices(shape)) - 2
    return 12 if isinstance(shape, Box) else len(shape.triangles)


def enclosed(points, dim):
    """Area (2D, from z) or volume (3D) enclosed by triangles ``points`` (t, 3, 3)."""
    a, b, c = points[:, 0], points[:, 1], points[:, 2]
    if dim == 2:
        return 0.5 * np.cross(b - a, c - a)[:, 2].sum()
    return np.einsum("ti,ti->t", a, np.cross(b, c)).sum() / 6.0


@pytest.fixture(scope="module", params=[2, 3], ids=["2d", "3d"])
def written(request, tmp_path_factory):
    """Two frames of a shape scene; before the second, bodies move and one grows."""
    dim = request.param
    b, placed = scene(dim)
    path = tmp_path_factory.mktemp(f"shapes_{dim}d") / "run.h5"
    sim = StandIn(b)
    with H5Writer(path, contacts=True) as out:
        out(sim)
        first = b.copy()
        b.pos[:] += 0.1
        b.rot[:] = b.rot[::-1] if dim == 2 else random_quats(np.random.default_rng(1), b.n)
        b.table.scale[0] = 1.5  # e.g. a state object growing the boxes
        sim.step = 10
        out(sim)
    return {"dim": dim, "path": path, "out": out, "placed": placed,
            "states": [first, b]}


def test_frames_hold_every_particle(written):
    for index, b in enumerate(written["states"]):
        frame = read_frame(written["path"], index)
        par = np.flatnonzero(b.kind != Shape.PLANE)
        assert np.array_equal(frame["id"], par)
        assert np.array_equal(frame["kind"], b.kind[par])
        for k in ("pos", "vel", "rot", "ang_vel", "radius", "force"):
            assert np.array_equal(frame[k], getattr(b, k)[par]), k
        assert frame["n_particles"] == par.size
        assert frame["n_spheres"] == 2 and frame["n_walls"] == 1
        assert frame["n_contacts"] == 0
        assert frame["n_surface_cells"] == frame["surface"]["cells"].shape[0]


def test_surfaces_are_the_world_shapes(written):
    dim = written["dim"]
    for index, b in enumerate(written["states"]):
        surf = read_frame(written["path"], index)["surface"]
        points, cells, body = surf["points"], surf["cells"], surf["body"]
        assert points.shape[1] == 3 and cells.shape[1] == 3
        assert cells.dtype == np.int32 and body.dtype == np.int32
        assert cells.min() == 0 and cells.max() == len(points) - 1
        assert len(cells) == sum(n_triangles(shape) for _, shape, _, _ in
                                 written["placed"])
        if dim == 2:
            assert np.all(points[:, 2] == 0.0)
        for i, shape, pos, rot in written["placed"]:
            mine = cells[body == i]
            assert len(mine) == n_triangles(shape)
            got = points[np.unique(mine)]
            scale = 1.5 if index == 1 and b.shape[i] == 0 else 1.0
            # frame 0: where add_shapes put the shape's own frame
            want = pad(pos) + rotate(rot, vertices(shape))
            if index == 1:  # moved, turned and grown about its centre of mass
                start = written["states"][0]
                local = unrotate(start.rot[i], want - pad(start.pos[i]))
                want = pad(b.pos[i]) + rotate(b.rot[i], scale * local)
            assert len(got) == len(want)
            dist = np.linalg.norm(got[:, None] - want[None], axis=2)
            assert dist.min(axis=1).max() < 1e-12 and dist.min(axis=0).max() < 1e-12
            vol = shape.volume() * scale**dim
            inner = points[mine] - pad(b.pos[i])  # about the centre: no cancellation
            assert enclosed(inner, dim) == pytest.approx(vol, rel=1e-9)
        vel = np.zeros((len(body), 3))
        vel[:, :dim] = b.vel[body]
        assert np.array_equal(surf["vel"], vel)


def test_custom_shapes_are_particles_only(written):
    b = written["states"][0]
    frame = read_frame(written["path"], 0)
    custom = np.flatnonzero(b.kind == Shape.CUSTOM)
    assert custom.size == (1 if written["dim"] == 2 else 0)
    assert np.all(np.isin(custom, frame["id"]))
    assert not np.any(np.isin(custom, frame["surface"]["body"]))


def check_hdf_items(root, xdmf_path, h5_path):
    """Every HDF DataItem names a dataset of ``h5_path`` with its Dimensions."""
    n_refs = 0
    with h5py.File(h5_path, "r") as f:
        for item in root.iter("DataItem"):
            if item.get("Format") != "HDF":
                continue
            fname, dset = item.text.strip().split(":")
            here = os.path.dirname(xdmf_path)
            assert os.path.join(here, fname) == str(h5_path)
            assert dset in f, dset
            shape = tuple(int(s) for s in item.get("Dimensions").split())
            assert f[dset].shape == shape, dset
            dtype = f[dset].dtype
            want = ("Int", "4") if dtype == np.int32 else ("Float", "8")
            assert (item.get("NumberType"), item.get("Precision")) == want, dset
            n_refs += 1
    return n_refs


def test_xdmf_has_a_shapes_file(written):
    out, dim = written["out"], written["dim"]
    files = xdmf_files(out.xdmf_path)
    assert out.xdmf_paths == [files["particles"], files["shapes"], files["walls"]]
    series = []
    for path in out.xdmf_paths:
        root = ET.parse(path).getroot()
        assert root.get("Version") == "3.0"
        assert check_hdf_items(root, path, written["path"]) > 0
        (s,) = root.findall("Domain/Grid")
        assert s.get("CollectionType") == "Temporal"
        series.append(s)
    assert [s.get("Name") for s in series] == ["particles", "shapes", "walls"]
    particles, shapes = (s.findall("Grid") for s in series[:2])
    assert len(particles) == len(shapes) == 2
    for index, (pg, sg) in enumerate(zip(particles, shapes, strict=True)):
        frame = read_frame(written["path"], index)
        assert float(sg.find("Time").get("Value")) == frame["time"]
        assert float(pg.find("Time").get("Value")) == frame["time"]
        names = {a.get("Name"): a for a in pg.findall("Attribute")}
        assert set(names) == {"position", "id", "kind", "radius", "vel", "force",
                              "ang_vel", "quat"} \
            | ({"angle"} if dim == 2 else set())
        assert names["vel"].find("DataItem").get("Dimensions").split()[-1] == "3"
        topo = sg.find("Topology")
        assert topo.get("TopologyType") == "Triangle"
        assert int(topo.get("NumberOfElements")) == frame["surface"]["cells"].shape[0]
        assert sg.find("Geometry").get("GeometryType") == "XYZ"
        cell = {a.get("Name"): a.get("AttributeType") for a in sg.findall("Attribute")
                if a.get("Center") == "Cell"}
        assert cell == {"body": "Scalar", "vel": "Vector"}
    assert pg.find("Geometry").get("GeometryType") == "XYZ"


@pytest.mark.parametrize("dim", [2, 3])
def test_sphere_only_layout_is_unchanged(tmp_path, dim):
    b = dem.Bodies.spheres(np.random.default_rng(2).uniform(0, 1, (5, dim)),
                           radius=0.01, density=2500.0)
    b.add_plane(np.zeros(dim), np.eye(dim)[-1])
    path = tmp_path / "spheres.h5"
    with H5Writer(path, contacts=False) as out:
        out(StandIn(b))
    with h5py.File(path, "r") as f:
        g = f["frames/000000"]
        assert set(g) == {"id", "kind", "pos", "vel", "rot", "ang_vel", "radius",
                          "force", "walls", "xdmf"}
        assert g.attrs["n_spheres"] == g.attrs["n_particles"] == 5
        assert g.attrs["n_surface_cells"] == 0
    assert out.xdmf_paths == [out.xdmf_path, xdmf_files(out.xdmf_path)["walls"]]
    root = ET.parse(out.xdmf_path).getroot()
    series = root.findall("Domain/Grid")
    assert [s.get("Name") for s in series] == ["particles"]
    grid = series[0].find("Grid")
    assert grid.find("Topology").get("TopologyType") == "Polyvertex"
    assert {a.get("Name") for a in grid.findall("Attribute")} == {
        "position", "id", "kind", "radius", "vel", "force", "ang_vel", "quat"} | (
        {"angle"} if dim == 2 else set())
    assert check_hdf_items(root, out.xdmf_path, path) > 0
