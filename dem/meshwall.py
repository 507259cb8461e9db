"""Triangle-mesh walls: a checked surface mesh with its adjacency, rigid motion, files.

A :class:`MeshWall` is a surface of triangles (a hopper, a drum, a footing) read from
any file meshio reads (STL first) or given as arrays. It knows its face normals, which
faces share each edge and each vertex, whether it is closed, its area and (closed) its
volume; it moves rigidly (:meth:`MeshWall.translated`, :meth:`MeshWall.rotated`,
:meth:`MeshWall.moved` by its prescribed velocity and angular velocity); it finds the
faces near spheres (a uniform grid) and every contact of a sphere with it
(:func:`dem.meshwall_kernels.sphere_mesh_contacts`, whose module states the rule for
edges and vertices). Passed to :class:`dem.Simulation` (``walls=[...]``) it is a wall
of the time step (:mod:`dem.mesh_scene`).

>>> cube = MeshWall(CUBE_VERTICES, CUBE_FACES)
>>> cube
MeshWall(8 vertices, 12 faces, watertight)
>>> round(cube.volume(), 12), round(cube.area, 12)
(1.0, 6.0)
"""

import contextlib
import io
import logging
import math
import os
import warnings
from typing import NamedTuple

import numpy as np

from .meshwall_kernels import (FaceGrid, MeshArrays, faces_near_spheres, fill_face_grid,
                               sphere_mesh_contacts)
from .rotation import quat_to_matrix

__all__ = ["CUBE_FACES", "CUBE_VERTICES", "MeshContacts", "MeshWall", "face_grid"]

log = logging.getLogger(__name__)

#: the unit cube [0, 1]^3: 8 corners [m] and 12 triangles wound outward
CUBE_VERTICES = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                          [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=np.float64)
CUBE_FACES = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7],
                       [0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5],
                       [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]], dtype=np.int64)

#: a triangle of area below this times the square of the bounding-box diagonal is
#: degenerate
AREA_TOL = 1e-12
#: vertices of a file closer than this times the bounding-box diagonal are merged
MERGE_TOL = 1e-9


class MeshContacts(NamedTuple):
    """The contacts of one sphere with a mesh, one row each.

    ``overlap`` (n,) [m] > 0; ``normal`` (n, 3) unit, from the contact point towards
    the sphere's centre; ``point`` (n, 3) [m]; ``face`` (n,) the reporting face;
    ``feature`` (n,) its feature code (:data:`dem.meshwall_kernels.FACE`, ``EDGE + k``,
    ``VERTEX + k``).
    """

    overlap: np.ndarray
    normal: np.ndarray
    point: np.ndarray
    face: np.ndarray
    feature: np.ndarray


def _vector3(value, name, default=None):
    if value is None:
        return np.zeros(3) if default is None else default
    v = np.asarray(value, dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"mesh wall {name} must be a finite 3-vector, got {value!r}")
    return v.copy()


def _checked_arrays(vertices, faces):
    """``(vertices (nv, 3) f8, faces (nf, 3) i8)``, or a one-line ValueError."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"mesh vertices must be an (nv, 3) array, got shape {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"mesh faces must be an (nf, 3) array, got shape {f.shape}")
    if v.shape[0] == 0 or f.shape[0] == 0:
        raise ValueError("mesh is empty: it needs at least one triangle")
    if not np.all(np.isfinite(v)):
        row = int(np.nonzero(~np.all(np.isfinite(v), axis=1))[0][0])
        raise ValueError(f"mesh vertex {row} is not finite: {v[row].tolist()}")
    if not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"mesh faces must be integer vertex indices, got {f.dtype}")
    f = f.astype(np.int64)
    bad = np.nonzero(np.any((f < 0) | (f >= v.shape[0]), axis=1))[0]
    if bad.size:
        raise ValueError(f"mesh face {int(bad[0])} has a vertex index out of range "
                         f"0..{v.shape[0] - 1}: {f[bad[0]].tolist()}")
    rep = np.nonzero((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2]))[0]
    if rep.size:
        raise ValueError(f"mesh face {int(rep[0])} repeats a vertex: {f[rep[0]].tolist()}")
    key = np.sort(f, axis=1)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    dup = np.nonzero(first[inverse.reshape(-1)] != np.arange(f.shape[0]))[0]
    if dup.size:
        k = int(dup[0])
        raise ValueError(f"mesh face {k} repeats face {int(first[inverse.reshape(-1)[k]])}")
    return np.ascontiguousarray(v), np.ascontiguousarray(f)


def _normals(v, f):
    """Unit normals (nf, 3) and areas (nf,) [m^2] of the faces, counter-clockwise."""
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    twice = np.linalg.norm(cross, axis=1)
    return np.ascontiguousarray(cross / twice[:, None]), 0.5 * twice


def _compressed(owner, n):
    """``(ptr (n + 1,), idx)``: for ``owner`` (3 nf,), the edge or vertex of each corner
    of each face in turn, the faces of each of the ``n`` owners, ascending."""
    order = np.argsort(owner, kind="stable")
    ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(owner, minlength=n), out=ptr[1:])
    return ptr, np.ascontiguousarray(order // 3)


class MeshWall:
    """A wall made of triangles, moved rigidly by a prescribed velocity.

    Parameters
    ----------
    vertices : (nv, 3) float [m]
    faces : (nf, 3) int
        Rows of ``vertices``; counter-clockwise seen from the side the face normal
        points to (for a closed mesh, outward).
    velocity : (3,) float [m/s], optional
        Prescribed velocity of the wall (zero by default).
    angular_velocity : (3,) float [rad/s], optional
        Prescribed angular velocity about ``center`` (zero by default).
    center : (3,) float [m], optional
        Point the wall turns about, moving with ``velocity``; the centre of the
        bounding box by default.
    mat_id : int, optional
        Material row of the wall in the contact model's ``"pw"`` table (0 by default).

    Raises
    ------
    ValueError
        One line naming the cause: an empty mesh, a non-finite vertex, a vertex index
        out of range, a face repeating a vertex or another face, a degenerate (zero
        area) face (area below ``AREA_TOL`` times the squared bounding-box diagonal).

    Attributes
    ----------
    face_normal : (nf, 3) float64
        Unit normals, by the right-hand rule over each face's vertices.
    face_area : (nf,) float64 [m^2]
    bounds : (2, 3) float64 [m]
        Lowest and highest corner of the bounding box.
    edges : (ne, 2) int64
        Each edge once, as its two vertices (lower first).
    face_edges : (nf, 3) int64
        The row of ``edges`` of edge ``k`` of each face (vertex ``k`` to ``k + 1``).
    edge_face_ptr, edge_face_idx : int64
        The faces of edge ``e`` (one on a boundary, two inside a surface) are
        ``edge_face_idx[edge_face_ptr[e]:edge_face_ptr[e + 1]]``.
    vertex_face_ptr, vertex_face_idx : int64
        The faces around each vertex, the same way.
    """

    def __init__(self, vertices, faces, velocity=None, angular_velocity=None, center=None,
                 mat_id=0):
        v, f = _checked_arrays(vertices, faces)
        self.vertices, self.faces = v, f
        self.bounds = np.array([v.min(axis=0), v.max(axis=0)])
        diag2 = float(np.sum((self.bounds[1] - self.bounds[0]) ** 2))
        with np.errstate(invalid="ignore", divide="ignore"):
            self.face_normal, self.face_area = _normals(v, f)
        small = np.nonzero(~(self.face_area > AREA_TOL * diag2))[0]
        if small.size:
            k = int(small[0])
            raise ValueError(f"mesh face {k} is degenerate: area {self.face_area[k]:.3g} "
                             f"m^2 (vertices {f[k].tolist()})")
        self.velocity = _vector3(velocity, "velocity")
        self.angular_velocity = _vector3(angular_velocity, "angular_velocity")
        self.center = _vector3(center, "center", default=self.bounds.mean(axis=0))
        if isinstance(mat_id, bool) or not isinstance(mat_id, (int, np.integer)) or mat_id < 0:
            raise ValueError(f"mesh wall mat_id must be an integer >= 0, got {mat_id!r}")
        self.mat_id = int(mat_id)
        self._topology()
        self._grids = {}

    def _topology(self):
        """Edges, the faces of each edge and around each vertex (compressed rows)."""
        f = self.faces
        nf = f.shape[0]
        directed = np.stack([f, np.roll(f, -1, axis=1)], axis=2).reshape(-1, 2)
        self.edges, inverse = np.unique(np.sort(directed, axis=1), axis=0,
                                        return_inverse=True)
        inverse = inverse.reshape(-1)
        self.face_edges = np.ascontiguousarray(inverse.reshape(nf, 3))
        self.edge_face_ptr, self.edge_face_idx = _compressed(inverse, self.edges.shape[0])
        self.vertex_face_ptr, self.vertex_face_idx = _compressed(
            f.reshape(-1), self.vertices.shape[0])
        # +1 where a face runs along its edge from the lower vertex to the higher
        sign = np.where(directed[:, 0] < directed[:, 1], 1, -1)
        self._edge_count = np.bincount(inverse, minlength=self.edges.shape[0])
        self._edge_sign = np.bincount(inverse, weights=sign, minlength=self.edges.shape[0])

    # ------------------------------------------------------------------ properties
    def __repr__(self):
        closed = "watertight" if self.is_watertight() else f"{self.open_edges()} open edges"
        return (f"MeshWall({self.vertices.shape[0]} vertices, {self.n_faces} faces, "
                f"{closed})")

    @property
    def n_faces(self):
        """Number of faces."""
        return self.faces.shape[0]

    @property
    def area(self):
        """Total area [m^2]."""
        return float(self.face_area.sum())

    def open_edges(self):
        """Number of edges not shared by exactly two faces of opposite orientation."""
        return int(np.count_nonzero((self._edge_count != 2) | (self._edge_sign != 0)))

    def is_watertight(self):
        """Is every edge shared by exactly two faces, running along it in opposite
        directions (a closed, consistently oriented surface)?"""
        return self.open_edges() == 0

    def volume(self):
        """Enclosed volume [m^3] of a closed mesh, by the divergence theorem: positive
        when the faces are wound outward. A ValueError if the mesh is not watertight."""
        if not self.is_watertight():
            raise ValueError(f"mesh is not watertight ({self.open_edges()} open edges): "
                             "it encloses no volume")
        v, f = self.vertices, self.faces
        origin = self.bounds.mean(axis=0)  # round-off: measure from inside the box
        a, b, c = v[f[:, 0]] - origin, v[f[:, 1]] - origin, v[f[:, 2]] - origin
        return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)

    @property
    def arrays(self):
        """The :class:`~dem.meshwall_kernels.MeshArrays` bundle the kernels read."""
        return MeshArrays(self.vertices, self.faces, self.face_normal, self.face_edges,
                          self.edge_face_ptr, self.edge_face_idx, self.vertex_face_ptr,
                          self.vertex_face_idx)

    # ------------------------------------------------------------------ rigid motion
    def _with_vertices(self, vertices, center):
        """A copy sharing the topology, with new vertex positions (a rigid motion)."""
        out = object.__new__(MeshWall)
        out.__dict__.update(self.__dict__)
        out.vertices = np.ascontiguousarray(vertices)
        out.bounds = np.array([out.vertices.min(axis=0), out.vertices.max(axis=0)])
        out.center = np.asarray(center, dtype=np.float64).copy()
        out.face_normal, _ = _normals(out.vertices, out.faces)
        out._grids = {}
        return out

    def translated(self, d):
        """The wall moved by ``d`` (3,) [m] (its centre too)."""
        d = _vector3(d, "translation")
        return self._with_vertices(self.vertices + d, self.center + d)

    def rotated(self, rotation, about=None):
        """The wall turned by ``rotation`` about the point ``about`` (3,) [m] (its
        centre by default): a rotation matrix (3, 3) or a unit quaternion (w, x, y, z).
        The centre turns with it."""
        r = np.asarray(rotation, dtype=np.float64)
        if r.shape == (4,) and np.all(np.isfinite(r)) and np.linalg.norm(r) > 0.0:
            r = quat_to_matrix(r / np.linalg.norm(r))
        elif r.shape != (3, 3) or not np.all(np.isfinite(r)) or not np.allclose(
                r @ r.T, np.eye(3), atol=1e-9) or np.linalg.det(r) < 0.0:
            raise ValueError("mesh wall rotation must be a rotation matrix (3, 3) or a "
                             f"non-zero quaternion (4,), got {rotation!r}")
        p = self.center if about is None else _vector3(about, "rotation point")
        return self._with_vertices((self.vertices - p) @ r.T + p, (self.center - p) @ r.T + p)

    def moved(self, dt):
        """The wall after ``dt`` [s] of its prescribed motion: turned by
        ``angular_velocity * dt`` about its centre (exactly, by Rodrigues' formula),
        then moved by ``velocity * dt``."""
        dt = float(dt)
        if not np.isfinite(dt):
            raise ValueError(f"mesh wall time step must be finite, got {dt}")
        w = self.angular_velocity
        angle = float(np.linalg.norm(w)) * dt
        out = self
        if angle != 0.0:
            k = w / np.linalg.norm(w)
            kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
            r = np.eye(3) + np.sin(angle) * kx + (1.0 - np.cos(angle)) * (kx @ kx)
            out = out.rotated(r)
        return out.translated(self.velocity * dt) if np.any(self.velocity) else out

    # ------------------------------------------------------------------ detection
    def grid(self, margin=0.0):
        """The broad phase's :class:`~dem.meshwall_kernels.FaceGrid` over the face boxes
        grown by ``margin`` [m] (built once per margin).

        Cells are cubes sized so that there are about as many cells as faces (and no
        smaller than a median grown face box): building costs O(nf) and finding the
        faces near a sphere costs the cells its box meets plus the faces listed there.
        """
        margin = float(margin)
        if margin in self._grids:
            return self._grids[margin]
        if not (np.isfinite(margin) and margin >= 0.0):
            raise ValueError(f"mesh wall margin must be finite and >= 0, got {margin}")
        grid = face_grid(self.vertices, self.faces, margin)
        self._grids[margin] = grid
        return grid

    def faces_near(self, pos, radius, margin=0.0):
        """The faces whose boxes grown by ``margin`` [m] meet each sphere's box.

        ``pos`` (n, 3) [m] and ``radius`` (n,) or scalar [m]. Returns ``(ptr, faces)``:
        the faces of sphere ``i``, ascending, are ``faces[ptr[i]:ptr[i + 1]]``.
        """
        pos = np.ascontiguousarray(np.asarray(pos, dtype=np.float64).reshape(-1, 3))
        radius = np.ascontiguousarray(np.broadcast_to(
            np.asarray(radius, dtype=np.float64), (pos.shape[0],)))
        grid = self.grid(margin)
        ptr = np.zeros(pos.shape[0] + 1, dtype=np.int64)
        faces = np.zeros(max(16, 4 * pos.shape[0]), dtype=np.int64)
        need = faces_near_spheres(pos, radius, grid, ptr, faces)
        if need > faces.shape[0]:
            faces = np.zeros(need, dtype=np.int64)
            faces_near_spheres(pos, radius, grid, ptr, faces)
        return ptr, faces[:need]

    def contacts(self, center, radius):
        """Every contact of the sphere (``center`` (3,) [m], ``radius`` [m]) with the
        wall, as a :class:`MeshContacts` (one row per contact, by the rule of
        :mod:`dem.meshwall_kernels`: an edge or vertex point counts once)."""
        center = _vector3(center, "sphere center")
        radius = float(radius)
        if not (np.isfinite(radius) and radius > 0.0):
            raise ValueError(f"sphere radius must be finite and > 0, got {radius}")
        _, cand = self.faces_near(center[None, :], radius)
        m = 8
        while True:
            out = MeshContacts(np.zeros(m), np.zeros((m, 3)), np.zeros((m, 3)),
                               np.zeros(m, dtype=np.int64), np.zeros(m, dtype=np.int64))
            n = sphere_mesh_contacts(center, radius, self.arrays, cand, *out)
            if n <= m:
                return MeshContacts(*(a[:n] for a in out))
            m = n

    # ------------------------------------------------------------------ files
    def to_meshio(self):
        """The wall as a ``meshio.Mesh`` (its triangles, face normals as cell data)."""
        import meshio

        return meshio.Mesh(self.vertices, [("triangle", self.faces)],
                           cell_data={"normal": [self.face_normal]})

    def write(self, path):
        """Write the wall to ``path`` in the format its suffix names, through meshio:
        ``.xdmf`` (with its ``.h5``) or ``.vtu`` for ParaView, ``.stl``, ... ."""
        import meshio

        try:
            meshio.write(os.fspath(path), self.to_meshio())
        except (meshio.WriteError, KeyError, OSError) as err:
            raise ValueError(f"cannot write mesh file {path}: {err}") from None

    @classmethod
    def from_file(cls, path, require_watertight=False, merge_tol=MERGE_TOL, scale=1.0,
                  shift=None, **kw):
        """The wall of the triangles of a file meshio reads (STL ascii or binary, ...).

        The file's coordinates are multiplied by ``scale`` (e.g. 0.001 for a file in
        millimetres) and then shifted by ``shift`` (3,) [m]. Vertices closer than
        ``merge_tol`` times the bounding-box diagonal are merged, so that triangles
        written with their own copies of each corner (as STL does) share their edges;
        vertices no triangle uses are dropped. ``kw`` go to the constructor
        (``velocity``, ``angular_velocity``, ``center``, ``mat_id``). Every error is one
        ValueError line naming the file: missing, not a mesh, no triangles, a bad
        ``scale``, a degenerate triangle (its index), not watertight (with
        ``require_watertight``, the number of open edges).
        """
        points, tri = _read_triangles(path)
        scale = float(scale)
        if not (math.isfinite(scale) and scale > 0.0):
            raise ValueError(f"mesh file {path}: scale must be finite and > 0, got {scale}")
        points = points * scale + _vector3(shift, "shift")
        points, tri = _merged(points, tri, merge_tol)
        try:
            wall = cls(points, tri, **kw)
        except ValueError as err:
            raise ValueError(f"mesh file {path}: {err}") from None
        if require_watertight and not wall.is_watertight():
            raise ValueError(f"mesh file {path} is not watertight: "
                             f"{wall.open_edges()} open edges")
        return wall


def face_grid(vertices, faces, margin):
    """The :class:`~dem.meshwall_kernels.FaceGrid` of the triangles ``faces`` (nf, 3)
    over ``vertices`` (nv, 3) [m], their boxes grown by ``margin`` [m] (see
    :meth:`MeshWall.grid`)."""
    tri = vertices[faces]
    n_faces = faces.shape[0]
    face_lo = np.ascontiguousarray(tri.min(axis=1) - margin)
    face_hi = np.ascontiguousarray(tri.max(axis=1) + margin)
    lo, hi = face_lo.min(axis=0), face_hi.max(axis=0)
    span = np.maximum(hi - lo, 1e-300)
    typical = float(np.median((face_hi - face_lo).max(axis=1)))
    cell = max(typical, float(np.prod(span) / n_faces) ** (1.0 / 3.0),
               float(span.max()) / 1024.0)
    dims = np.maximum(np.ceil(span / cell).astype(np.int64), 1)
    cell_ptr = np.zeros(int(np.prod(dims)) + 1, dtype=np.int64)
    cell_faces = np.zeros(8 * n_faces, dtype=np.int64)
    need = fill_face_grid(lo, cell, dims, face_lo, face_hi, cell_ptr, cell_faces)
    if need > cell_faces.shape[0]:
        cell_faces = np.zeros(need, dtype=np.int64)
        fill_face_grid(lo, cell, dims, face_lo, face_hi, cell_ptr, cell_faces)
    return FaceGrid(lo, cell, dims, cell_ptr, cell_faces[:need], face_lo, face_hi,
                    np.full(n_faces, -1, dtype=np.int64))


def _read_triangles(path):
    """``(points (n, 3), triangles (m, 3))`` of a mesh file, or a one-line ValueError.

    meshio prints and calls ``sys.exit`` on some files it cannot parse: its output is
    captured and turned into the message.
    """
    import meshio

    if not os.path.exists(path):
        raise ValueError(f"mesh file {path} does not exist")
    if os.path.isdir(path):
        raise ValueError(f"mesh file {path} is a directory")
    said = io.StringIO()
    try:
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said), \
                warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # meshio's format sniffing
            mesh = meshio.read(os.fspath(path))
    except SystemExit:
        reason = " ".join(said.getvalue().split()).removeprefix("Error: ") or \
            "meshio gave up on it"
        raise ValueError(f"cannot read mesh file {path}: {reason}") from None
    except Exception as err:  # noqa: BLE001 - meshio raises many kinds
        reason = " ".join(f"{type(err).__name__}: {err}".split())
        raise ValueError(f"cannot read mesh file {path}: {reason}") from None
    blocks = [c.data for c in mesh.cells if c.type == "triangle"]
    if not blocks or sum(b.shape[0] for b in blocks) == 0:
        kinds = ", ".join(sorted({c.type for c in mesh.cells})) or "none"
        raise ValueError(f"mesh file {path} has no triangles (cells: {kinds})")
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"mesh file {path} has points of shape {points.shape}")
    if points.shape[1] == 2:
        points = np.column_stack([points, np.zeros(points.shape[0])])
    return points, np.concatenate(blocks).astype(np.int64)


def _merged(points, tri, tol):
    """Points within ``tol`` times the diagonal of the used points merged, unused
    points dropped; triangles renumbered."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    used = np.unique(tri)
    if used.size and (used[0] < 0 or used[-1] >= points.shape[0]):
        return points, tri  # the constructor names the bad index
    pts = points[used]
    finite = np.all(np.isfinite(pts))
    diag = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) if finite else 0.0
    n = pts.shape[0]
    pairs = cKDTree(pts).query_pairs(tol * diag, output_type="ndarray") if finite else \
        np.zeros((0, 2), dtype=np.int64)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    # each group keeps the position of its first point, in file order
    first = np.full(label.max() + 1, n, dtype=np.int64)
    np.minimum.at(first, label, np.arange(n))
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    renumber = np.full(points.shape[0], -1, dtype=np.int64)
    renumber[used] = rank[label]
    if len(pairs):
        log.debug("merged %d coincident vertices", n - order.size)
    return pts[first[order]], renumber[tri]
