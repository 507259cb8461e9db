"""Triangle-mesh walls: closest points against dense sampling, one contact per shared
edge or vertex (coplanar, ridge, fan) and two in a valley, an exact box distance and an
infinite plane as references, the broad phase against brute force, closed meshes,
rigid motion, files in and out, every bad input's one-line message, and the kernels run
as plain Python giving the same numbers."""

import json
import os
import subprocess
import sys
from pathlib import Path

import meshio
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dem import MeshWall
from dem.meshwall import CUBE_FACES, CUBE_VERTICES
from dem.meshwall_kernels import EDGE, FACE, VERTEX, closest_on_triangle
from dem.shapes.plane import sdf_plane

SQUARE = (np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]),
          np.array([[0, 1, 2], [0, 2, 3]]))                  # diagonal edge (0, 2)


def roof(height):
    """Two planes meeting along the y axis, each a quad of two triangles wound upward:
    a convex ridge for ``height < 0`` (eaves below), a concave valley for > 0."""
    v = np.array([[0.0, -1, 0], [0, 1, 0], [-1, -1, height], [-1, 1, height],
                  [1, -1, height], [1, 1, height]])
    f = np.array([[0, 1, 3], [0, 3, 2], [0, 4, 5], [0, 5, 1]])
    return MeshWall(v, f)


def fan(n=6):
    """``n`` triangles in z = 0 around the origin (vertex 0), wound upward."""
    angle = 2 * np.pi * np.arange(n) / n
    v = np.vstack([[0.0, 0, 0], np.column_stack([np.cos(angle), np.sin(angle),
                                                 np.zeros(n)])])
    f = np.array([[0, 1 + k, 1 + (k + 1) % n] for k in range(n)])
    return MeshWall(v, f)


def weighted_normal(c):
    """The sum of overlap-weighted normals: what a linear spring would push with."""
    return (c.overlap[:, None] * c.normal).sum(axis=0)


# ------------------------------------------------------------------ closest point
def test_closest_point_matches_dense_sampling():
    rng = np.random.default_rng(7)
    tri = rng.normal(size=(3, 3))
    n = 300                                   # barycentric grid of the triangle
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    keep = i + j <= n
    w = np.column_stack([i[keep], j[keep], n - i[keep] - j[keep]]) / n
    samples = w @ tri
    spacing = max(np.linalg.norm(tri[a] - tri[b]) for a, b in ((0, 1), (1, 2), (2, 0))) / n
    features = set()
    for p in tri.mean(axis=0) + 1.5 * rng.normal(size=(400, 3)):
        wa, wb, wc = closest_on_triangle(*p, *tri[0], *tri[1], *tri[2])
        assert min(wa, wb, wc) >= 0.0 and abs(wa + wb + wc - 1.0) < 1e-12
        q = wa * tri[0] + wb * tri[1] + wc * tri[2]
        d = np.linalg.norm(p - q)
        d_brute = np.linalg.norm(samples - p, axis=1).min()
        assert d <= d_brute + 1e-12               # never worse than any sample
        assert d_brute - d <= spacing             # and as good as the sampling can tell
        zeros = [x == 0.0 for x in (wa, wb, wc)]
        features.add(sum(zeros))
    assert features == {0, 1, 2}, "the points did not reach every region"


# ------------------------------------------------------------------ shared features
def test_coplanar_shared_edge_one_contact_and_no_jump():
    wall = MeshWall(*SQUARE)
    r, h = 0.2, 0.1
    path = np.linspace([0.3, 0.7, h], [0.7, 0.3, h], 201)     # across the diagonal
    pushes, on_edge = [], 0
    for c in path:
        got = wall.contacts(c, r)
        assert len(got.overlap) == 1, c
        np.testing.assert_allclose(got.overlap, r - h, rtol=1e-12)
        np.testing.assert_allclose(got.normal[0], [0, 0, 1], atol=1e-12)
        on_edge += int(EDGE <= got.feature[0] < VERTEX)
        pushes.append(weighted_normal(got))
    assert on_edge == 1                       # the midpoint lies on the diagonal
    assert np.abs(np.diff(pushes, axis=0)).max() < 1e-12


def test_convex_ridge_one_edge_contact_continuous_across():
    wall = roof(-0.5)
    got = wall.contacts([0.0, 0.0, 0.1], 0.2)
    assert len(got.overlap) == 1 and EDGE <= got.feature[0] < VERTEX
    np.testing.assert_allclose(got.overlap, 0.1, rtol=1e-12)
    np.testing.assert_allclose(got.normal[0], [0, 0, 1], atol=1e-12)
    xs = np.linspace(-0.2, 0.2, 401)
    pushes = []
    for x in xs:
        got = wall.contacts([x, 0.3, 0.1], 0.2)
        assert len(got.overlap) == 1, x
        pushes.append(weighted_normal(got))
    step = np.linalg.norm(np.diff(pushes, axis=0), axis=1)
    assert step.max() < 3 * (xs[1] - xs[0])     # Lipschitz: no jump at either face


def test_concave_valley_two_face_contacts():
    wall = roof(0.5)
    got = wall.contacts([0.0, 0.2, 0.15], 0.2)
    assert sorted(got.feature.tolist()) == [FACE, FACE]
    n = np.array([0.5, 0.0, 1.0]) / np.sqrt(1.25)             # the right face's normal
    d = 0.15 * n[2]
    np.testing.assert_allclose(got.overlap, [0.2 - d, 0.2 - d], rtol=1e-12)
    np.testing.assert_allclose(np.sort(got.normal[:, 0]), [-n[0], n[0]], atol=1e-12)


def test_fan_vertex_one_contact():
    wall = fan(6)
    got = wall.contacts([0.0, 0.0, 0.1], 0.2)
    assert got.feature.tolist() == [VERTEX + 0] and got.face.tolist() == [0]
    np.testing.assert_allclose(got.overlap, 0.1, rtol=1e-12)
    rng = np.random.default_rng(3)
    for xy in np.vstack([rng.uniform(-0.3, 0.3, size=(50, 2)),
                         0.2 * np.column_stack([np.cos(np.arange(6) * np.pi / 3),
                                                np.sin(np.arange(6) * np.pi / 3)])]):
        got = wall.contacts([*xy, 0.1], 0.2)
        assert len(got.overlap) == 1, xy
        np.testing.assert_allclose(got.overlap, 0.1, rtol=1e-12)


@pytest.mark.parametrize("seed", [0, 1])
def test_cube_one_contact_outside_with_the_exact_box_distance(seed):
    """Outside a convex mesh the closest point is unique: one contact, at the box's
    exact distance, at face, edge and corner points, on symmetric planes included."""
    wall = MeshWall(CUBE_VERTICES, CUBE_FACES)
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-0.15, 1.15, size=(400, 3))
    snap = rng.random(pts.shape) < 0.3          # land on 0, 1/2, 1 exactly, often
    pts[snap] = rng.choice([0.0, 0.5, 1.0], size=snap.sum())
    r = 0.12
    n_contacts = 0
    for p in pts:
        out = p - np.clip(p, 0.0, 1.0)            # from the box's closest point
        d = np.linalg.norm(out)
        if d == 0.0:
            continue                               # inside: several faces, by design
        got = wall.contacts(p, r)
        assert len(got.overlap) == (1 if d < r else 0), p
        if d < r:
            n_contacts += 1
            np.testing.assert_allclose(got.overlap[0], r - d, rtol=0, atol=1e-14)
            np.testing.assert_allclose(got.normal[0], out / d, atol=1e-12)
    assert n_contacts > 50


def wavy(n, amplitude=0.1):
    """A height field over the unit square, 2 n^2 triangles wound upward."""
    x, y = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1), indexing="ij")
    z = amplitude * np.sin(6 * x) * np.cos(5 * y)
    v = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    k = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    f = np.vstack([np.column_stack([k, k + n + 1, k + n + 2]),
                   np.column_stack([k, k + n + 2, k + 1])])
    return MeshWall(v, f)


def test_the_deepest_point_is_never_dropped_nor_counted_twice():
    """Against every face's closest point (naive): the deepest contact is reported, and
    no two contacts share a point, over a bumpy surface at vertices, edges and faces."""
    wall = wavy(6, amplitude=0.15)
    tri = wall.vertices[wall.faces]
    rng = np.random.default_rng(9)
    centres = np.vstack([wall.vertices + [0, 0, 0.05],              # over vertices
                         tri[:, :2].mean(axis=1) + [0, 0, 0.05],     # over edges
                         rng.uniform([0, 0, -0.1], [1, 1, 0.2], (100, 3))])
    r = 0.12
    for c in centres:
        weights = [closest_on_triangle(*c, *t[0], *t[1], *t[2]) for t in tri]
        near = np.einsum("fk,fkj->fj", np.array(weights), tri)
        d_min = np.linalg.norm(near - c, axis=1).min()
        got = wall.contacts(c, r)
        if d_min >= r:
            assert len(got.overlap) == 0
            continue
        assert got.overlap.max() == pytest.approx(r - d_min, rel=0, abs=1e-14)
        gaps = np.linalg.norm(got.point[:, None] - got.point[None, :], axis=2)
        assert np.all(gaps[~np.eye(len(gaps), dtype=bool)] > 1e-9), c


def test_two_triangles_act_as_an_infinite_plane():
    rng = np.random.default_rng(11)
    rot = Rotation.random(random_state=rng)
    origin = np.array([0.3, -1.0, 2.0])
    v = np.array([[-10.0, -10, 0], [10, -10, 0], [10, 10, 0], [-10, 10, 0]])
    wall = MeshWall(rot.apply(v) + origin, SQUARE[1])
    normal = rot.apply([0.0, 0.0, 1.0])
    local = np.column_stack([rng.uniform(-5, 5, (100, 2)), rng.uniform(0.01, 0.2, 100)])
    local[:10, 1] = local[:10, 0]                   # above the shared diagonal
    for c in rot.apply(local) + origin:
        got = wall.contacts(c, 0.25)
        assert len(got.overlap) == 1
        np.testing.assert_allclose(got.overlap[0], 0.25 - sdf_plane(c - origin, normal),
                                   rtol=0, atol=1e-13)
        np.testing.assert_allclose(got.normal[0], normal, atol=1e-12)


def test_broad_phase_matches_brute_force():
    rng = np.random.default_rng(5)
    wall = wavy(30)
    v, f = wall.vertices, wall.faces
    pos = rng.uniform([-0.1, -0.1, -0.2], [1.1, 1.1, 0.2], size=(300, 3))
    radius = rng.uniform(0.005, 0.05, 300)
    margin = 0.01
    ptr, faces = wall.faces_near(pos, radius, margin)
    tri = v[f]
    lo, hi = tri.min(axis=1) - margin, tri.max(axis=1) + margin
    for i in range(len(pos)):
        hit = np.all((pos[i] + radius[i] >= lo) & (pos[i] - radius[i] <= hi), axis=1)
        assert faces[ptr[i]:ptr[i + 1]].tolist() == np.nonzero(hit)[0].tolist()
    assert ptr[-1] > 300


# ------------------------------------------------------------------ closed meshes, motion
def test_cube_is_watertight_with_unit_volume_and_outward_normals():
    cube = MeshWall(CUBE_VERTICES, CUBE_FACES)
    assert cube.is_watertight() and cube.volume() == pytest.approx(1.0, rel=1e-14)
    assert cube.area == pytest.approx(6.0, rel=1e-14)
    centroids = CUBE_VERTICES[CUBE_FACES].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", centroids - 0.5, cube.face_normal) > 0.0)
    assert cube.edges.shape == (18, 2)
    assert np.all(np.diff(cube.edge_face_ptr) == 2)
    open_box = MeshWall(CUBE_VERTICES, CUBE_FACES[1:])
    assert not open_box.is_watertight() and open_box.open_edges() == 3
    with pytest.raises(ValueError, match="not watertight"):
        open_box.volume()
    flipped = CUBE_FACES.copy()
    flipped[0] = flipped[0, ::-1]                  # one face wound the other way
    assert not MeshWall(CUBE_VERTICES, flipped).is_watertight()


def test_rigid_motion_keeps_the_shape_and_moves_exactly():
    cube = MeshWall(CUBE_VERTICES, CUBE_FACES, velocity=[1.0, 0, 0],
                    angular_velocity=[0, 0, np.pi / 2])
    np.testing.assert_allclose(cube.center, [0.5, 0.5, 0.5])
    moved = cube.moved(1.0)                         # a quarter turn about z, then +x
    expected = (CUBE_VERTICES - 0.5) @ np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1]]) \
        + 0.5 + [1.0, 0, 0]
    np.testing.assert_allclose(moved.vertices, expected, atol=1e-14)
    np.testing.assert_allclose(moved.center, [1.5, 0.5, 0.5])
    assert moved.volume() == pytest.approx(1.0, rel=1e-13)
    half = cube.moved(0.5).moved(0.5)               # exact rotation: steps compose
    np.testing.assert_allclose(half.vertices, expected, atol=1e-14)
    q = Rotation.from_rotvec([0.3, -0.2, 0.5])
    a = cube.rotated(q.as_matrix(), about=[1, 2, 3])
    b = cube.rotated(np.roll(q.as_quat(), 1), about=[1, 2, 3])   # (w, x, y, z)
    np.testing.assert_allclose(a.vertices, b.vertices, atol=1e-14)
    np.testing.assert_allclose(a.face_normal, q.apply(cube.face_normal), atol=1e-14)
    shifted = cube.translated([0, 0, 2])
    assert shifted.bounds[0, 2] == 2.0 and cube.bounds[0, 2] == 0.0
    with pytest.raises(ValueError, match="rotation"):
        cube.rotated(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="velocity"):
        MeshWall(CUBE_VERTICES, CUBE_FACES, velocity=[1.0, np.inf, 0.0])
    with pytest.raises(ValueError, match="radius"):
        cube.contacts([0.5, 0.5, 1.1], -0.1)


# ------------------------------------------------------------------ files
def canonical(wall):
    """The triangles as coordinate triples, each turned to start at its smallest
    corner (keeps the winding), sorted."""
    out = []
    for t in wall.vertices[wall.faces].tolist():
        k = min(range(3), key=lambda i: t[i])
        out.append(tuple(map(tuple, t[k:] + t[:k])))
    return sorted(out)


@pytest.mark.parametrize("binary", [False, True])
def test_stl_round_trip_shares_vertices(tmp_path, binary):
    cube = MeshWall(CUBE_VERTICES * 0.1 + [0.3, 0.2, 0.1], CUBE_FACES)
    path = tmp_path / "cube.stl"
    meshio.write(path, cube.to_meshio(), binary=binary)
    back = MeshWall.from_file(path, require_watertight=True)
    assert back.vertices.shape == (8, 3) and back.is_watertight()
    if binary:                                      # binary STL holds float32
        cube = MeshWall(cube.vertices.astype(np.float32), cube.faces)
    np.testing.assert_allclose(canonical(back), canonical(cube), rtol=0, atol=1e-15)


def test_stl_copies_of_a_corner_a_little_apart_are_merged(tmp_path):
    rng = np.random.default_rng(2)
    tri = CUBE_VERTICES[CUBE_FACES]
    tri = tri + 1e-13 * rng.normal(size=tri.shape)       # each copy its own round-off
    lines = ["solid cube"]
    for t in tri:
        lines += ["facet normal 0 0 0", "outer loop"]
        lines += [f"vertex {x:.17g} {y:.17g} {z:.17g}" for x, y, z in t]
        lines += ["endloop", "endfacet"]
    (tmp_path / "cube.stl").write_text("\n".join(lines + ["endsolid cube", ""]))
    wall = MeshWall.from_file(tmp_path / "cube.stl")
    assert wall.vertices.shape == (8, 3) and wall.is_watertight()


@pytest.mark.parametrize("suffix", [".vtu", ".xdmf"])
def test_write_opens_in_meshio(tmp_path, suffix):
    wall = roof(-0.5)
    wall.write(tmp_path / f"roof{suffix}")
    back = meshio.read(tmp_path / f"roof{suffix}")
    np.testing.assert_array_equal(back.points, wall.vertices)
    np.testing.assert_array_equal(back.cells_dict["triangle"], wall.faces)
    np.testing.assert_allclose(back.cell_data["normal"][0], wall.face_normal)


def test_bad_files_are_one_line_naming_the_file(tmp_path):
    def message(path, **kw):
        with pytest.raises(ValueError) as err:
            MeshWall.from_file(path, **kw)
        text = str(err.value)
        assert "\n" not in text and str(path) in text
        return text

    assert "does not exist" in message(tmp_path / "missing.stl")
    (tmp_path / "notes.stl").write_text("these are my notes, not a mesh\n")
    assert "cannot read mesh file" in message(tmp_path / "notes.stl")
    (tmp_path / "notes.txt").write_text("these are my notes, not a mesh\n")
    assert "cannot read mesh file" in message(tmp_path / "notes.txt")
    lines = meshio.Mesh(CUBE_VERTICES, [("line", np.array([[0, 1], [1, 2]]))])
    meshio.write(tmp_path / "lines.vtu", lines)
    assert "no triangles (cells: line)" in message(tmp_path / "lines.vtu")
    flat = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]])
    with np.errstate(invalid="ignore"):             # meshio's STL normal of it
        meshio.write(tmp_path / "flat.stl",
                     meshio.Mesh(flat, [("triangle", np.array([[0, 1, 2], [0, 1, 3]]))]))
    assert "face 1 is degenerate" in message(tmp_path / "flat.stl")
    meshio.write(tmp_path / "open.stl", MeshWall(CUBE_VERTICES, CUBE_FACES[1:]).to_meshio())
    assert "not watertight: 3 open edges" in message(tmp_path / "open.stl",
                                                      require_watertight=True)


@pytest.mark.parametrize("vertices, faces, cause", [
    ([[0.0, 0, 0], [1, 0, 0], [0, np.nan, 0]], [[0, 1, 2]], "vertex 2 is not finite"),
    ([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 3]], "face 0 has a vertex index out"),
    ([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2], [0, 1, 1]], "face 1 repeats a vertex"),
    ([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], [[0, 1, 2], [0, 3, 1]],
     "face 1 is degenerate"),
    ([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2], [1, 2, 0]], "face 1 repeats face 0"),
    (np.zeros((0, 3)), np.zeros((0, 3), dtype=int), "empty"),
    ([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0.0, 1, 2]], "integer"),
])
def test_bad_arrays_are_one_line(vertices, faces, cause):
    with pytest.raises(ValueError, match=cause) as err:
        MeshWall(vertices, faces)
    assert "\n" not in str(err.value)


INTERPRETED = """
import json, sys
import numpy as np
sys.path.insert(0, {root!r})
from dem.meshwall import CUBE_FACES, CUBE_VERTICES, MeshWall
wall = MeshWall(CUBE_VERTICES, CUBE_FACES).rotated([0.9, 0.1, -0.3, 0.2])
rng = np.random.default_rng(4)
out = []
for c in rng.uniform(-0.3, 1.3, (40, 3)):
    got = wall.contacts(c, 0.3)
    out.append([a.tolist() for a in got])
ptr, faces = wall.faces_near(rng.uniform(-0.3, 1.3, (40, 3)), 0.2, margin=0.05)
print(json.dumps([out, ptr.tolist(), faces.tolist()]))
"""


def test_kernels_run_as_plain_python_with_the_same_numbers():
    root = str(Path(__file__).resolve().parents[2])
    runs = []
    for disable in ("0", "1"):
        env = dict(os.environ, NUMBA_DISABLE_JIT=disable)
        r = subprocess.run([sys.executable, "-c", INTERPRETED.format(root=root)], env=env,
                           capture_output=True, text=True, check=True, timeout=300)
        runs.append(json.loads(r.stdout))
    assert runs[0] == runs[1]
    assert sum(len(c[0]) for c in runs[0][0]) > 10
