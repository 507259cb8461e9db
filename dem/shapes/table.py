"""The shape table: every non-sphere shape of a scene in flat arrays, and its SDF kernels.

Spheres and planes need no table row: a sphere is its radius (``Bodies.radius``), a
plane its normal (``Bodies.normal``). Every other body points to a row ``s`` of the
table (``Bodies.shape``); bodies may share a row. The layout (ragged data in pools with
offsets, all in the body frame: centre of mass at the origin, principal axes along the
frame axes; 2D shapes have ``z = 0``):

``kind (ns,) int64``
    :class:`~dem.shapes.Shape` code.
``param (ns, 4) float64``
    Box: half extents ``(hx, hy, hz, 0)`` (``hz = 0`` in 2D); custom: the four user
    parameters handed to its SDF; others: zeros.
``scale (ns,) float64``
    The shape is the stored one scaled by ``scale`` about its centre (1 unless a state
    object grows it): ``sdf(x) = scale * sdf0(x / scale)``.
``vstart (ns + 1,) int64``, ``verts (nv, 3) float64``
    Vertices of row ``s`` are ``verts[vstart[s]:vstart[s + 1]]``; polygons
    counter-clockwise.
``fstart (ns + 1,) int64``, ``faces (nf, 4) float64``
    Faces as half-spaces ``n . x <= o``, rows ``(nx, ny, nz, o)`` with outward unit
    ``n``; for a polygon, face ``e`` is the edge from vertex ``e`` to vertex ``e + 1``.
``tstart (ns + 1,) int64``, ``tris (nt, 3) int64``
    Boundary triangles of polyhedra (and 3D boxes), indices into the shape's own
    vertices, counter-clockwise seen from outside.
``brad (ns,) float64``
    Bounding radius [m] (unscaled).
``xform (ns, 12) float64``
    Custom shapes: the user's SDF is evaluated at ``R @ x + c`` for a principal-frame
    point ``x``; rows hold ``R`` (row-major, 9) and ``c`` (3). Identity otherwise.
``cstart (ns + 1,) int64``, ``part_kind``, ``part_row (np,) int64``, ``part_off (np, 3)``,
``part_rot (np, 4)``, ``part_rad (np,) float64``
    Compounds (:class:`~dem.shapes.Compound`): the parts of row ``s`` are
    ``cstart[s]:cstart[s + 1]`` of the part pool, each with its kind, its own table row
    (-1 for a sphere), its offset [m] and orientation in the compound's frame (a unit
    quaternion (w, x, y, z); in 2D the angle [rad] in column 0) and its bounding radius
    [m] (a sphere's radius). Other rows have no parts.

Kernels take the tuple :meth:`ShapeTable.arrays` as ``geo``; with a constant ``kind``
the dispatch in :func:`sdf_local` folds away at compile time.
"""

import math

import numpy as np

from .._jit import kernel
from ..rotation import to_body
from .kinds import BOX, COMPOUND, POLYGON, POLYHEDRON, SPHERE

#: central-difference step of the SDF gradient, relative to the shape's bounding radius
GRAD_STEP = 1e-7


class ShapeTable:
    """Flat arrays of the non-sphere shapes of one scene (see the module docstring).

    Examples
    --------
    >>> t = ShapeTable()
    >>> rows = dict(kind=BOX, param=np.array([1.0, 0.5, 0.0, 0.0]),
    ...             verts=np.array([[1, .5, 0], [-1, .5, 0], [-1, -.5, 0], [1, -.5, 0.]]),
    ...             faces=np.array([[1, 0, 0, 1], [0, 1, 0, .5], [-1, 0, 0, 1], [0, -1, 0, .5]]),
    ...             tris=np.zeros((0, 3), np.int64), bounding_radius=1.118)
    >>> t.add(rows), t.n
    (0, 1)
    """

    def __init__(self):
        self.kind = np.zeros(0, np.int64)
        self.param = np.zeros((0, 4))
        self.scale = np.zeros(0)
        self.brad = np.zeros(0)
        self.vstart = np.zeros(1, np.int64)
        self.verts = np.zeros((0, 3))
        self.fstart = np.zeros(1, np.int64)
        self.faces = np.zeros((0, 4))
        self.tstart = np.zeros(1, np.int64)
        self.tris = np.zeros((0, 3), np.int64)
        self.xform = np.zeros((0, 12))
        self.cstart = np.zeros(1, np.int64)
        self.part_kind = np.zeros(0, np.int64)
        self.part_row = np.zeros(0, np.int64)
        self.part_off = np.zeros((0, 3))
        self.part_rot = np.zeros((0, 4))
        self.part_rad = np.zeros(0)
        self.shapes = []  # the Python shape objects, row by row

    @property
    def n(self):
        return self.kind.shape[0]

    def add(self, rows, shape=None):
        """Append one shape from its ``rows()`` dict; returns its row index.

        A compound's parts get rows of their own first (spheres excepted), then the
        compound its row and its entries in the part pool."""
        parts = []
        if int(rows["kind"]) == COMPOUND:
            for part, off, q in shape.part_poses():
                sphere = not hasattr(part, "rows")
                row = -1 if sphere else self.add(part.rows(), part)
                q = np.atleast_1d(np.asarray(q, np.float64))
                parts.append((SPHERE if sphere else int(part.code), row, off,
                              np.r_[q, np.zeros(4 - q.size)], part.bounding_radius))
        self.cstart = np.append(self.cstart, self.cstart[-1] + len(parts))
        if parts:
            kinds, prow, off, q, rad = zip(*parts, strict=True)
            self.part_kind = np.append(self.part_kind, np.array(kinds, np.int64))
            self.part_row = np.append(self.part_row, np.array(prow, np.int64))
            self.part_off = np.ascontiguousarray(np.vstack([self.part_off, off]))
            self.part_rot = np.ascontiguousarray(np.vstack([self.part_rot, q]))
            self.part_rad = np.append(self.part_rad, np.array(rad, np.float64))
        verts = np.asarray(rows["verts"], np.float64).reshape(-1, 3)
        faces = np.asarray(rows["faces"], np.float64).reshape(-1, 4)
        tris = np.asarray(rows["tris"], np.int64).reshape(-1, 3)
        self.kind = np.append(self.kind, np.int64(rows["kind"]))
        self.param = np.vstack([self.param, np.asarray(rows["param"], np.float64)[None, :4]])
        # a custom shape may carry its own scale; polytopes have it in their vertices
        self.scale = np.append(self.scale, float(getattr(shape, "scale", 1.0)))
        self.brad = np.append(self.brad, float(rows["bounding_radius"]))
        self.vstart = np.append(self.vstart, self.vstart[-1] + verts.shape[0])
        self.verts = np.ascontiguousarray(np.vstack([self.verts, verts]))
        self.fstart = np.append(self.fstart, self.fstart[-1] + faces.shape[0])
        self.faces = np.ascontiguousarray(np.vstack([self.faces, faces]))
        self.tstart = np.append(self.tstart, self.tstart[-1] + tris.shape[0])
        self.tris = np.ascontiguousarray(np.vstack([self.tris, tris]))
        xf = np.zeros(12)
        xf[[0, 4, 8]] = 1.0
        if shape is not None and getattr(shape, "rotation", None) is not None:
            r = np.eye(3)
            rot = np.asarray(shape.rotation, np.float64)
            r[:rot.shape[0], :rot.shape[1]] = rot
            off = np.zeros(3)
            o = np.asarray(shape.offset, np.float64).ravel()
            off[:o.shape[0]] = o
            xf = np.concatenate([r.ravel(), off])
        self.xform = np.vstack([self.xform, xf[None, :]])
        self.shapes.append(shape)
        return self.n - 1

    def arrays(self):
        """The tuple ``geo`` the kernels take."""
        return (self.param, self.scale, self.vstart, self.verts, self.fstart, self.faces,
                self.tstart, self.tris, self.brad, self.xform)

    #: every array of the table
    ARRAYS = ("kind", "param", "scale", "brad", "vstart", "verts", "fstart", "faces",
              "tstart", "tris", "xform", "cstart", "part_kind", "part_row", "part_off",
              "part_rot", "part_rad")

    def copy(self):
        t = ShapeTable()
        for name in self.ARRAYS:
            setattr(t, name, getattr(self, name).copy())
        t.shapes = list(self.shapes)
        return t


# --------------------------------------------------------------------------- distances
@kernel(inline=True)
def _segment_dist2(px, py, ax, ay, bx, by):
    """Squared distance from (px, py) to the segment a-b."""
    ex, ey = bx - ax, by - ay
    wx, wy = px - ax, py - ay
    ee = ex * ex + ey * ey
    t = (wx * ex + wy * ey) / ee if ee > 0.0 else 0.0
    t = min(max(t, 0.0), 1.0)
    dx, dy = wx - t * ex, wy - t * ey
    return dx * dx + dy * dy


@kernel(inline=True)
def triangle_dist2(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Squared distance from p to the triangle abc (closest-point by Voronoi regions)."""
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return apx * apx + apy * apy + apz * apz
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bpx * bpx + bpy * bpy + bpz * bpz
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        qx, qy, qz = apx - v * abx, apy - v * aby, apz - v * abz
        return qx * qx + qy * qy + qz * qz
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cpx * cpx + cpy * cpy + cpz * cpz
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        qx, qy, qz = apx - w * acx, apy - w * acy, apz - w * acz
        return qx * qx + qy * qy + qz * qz
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        qx, qy, qz = bpx - w * (cx - bx), bpy - w * (cy - by), bpz - w * (cz - bz)
        return qx * qx + qy * qy + qz * qz
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    qx = apx - abx * v - acx * w
    qy = apy - aby * v - acy * w
    qz = apz - abz * v - acz * w
    return qx * qx + qy * qy + qz * qz


# --------------------------------------------------------------------------- SDFs
@kernel(inline=True)
def _sdf_box(x, y, z, hx, hy, hz):
    qx, qy = abs(x) - hx, abs(y) - hy
    if hz > 0.0:
        qz = abs(z) - hz
        inner = min(max(qx, max(qy, qz)), 0.0)
        ox, oy, oz = max(qx, 0.0), max(qy, 0.0), max(qz, 0.0)
        return math.sqrt(ox * ox + oy * oy + oz * oz) + inner
    inner = min(max(qx, qy), 0.0)
    ox, oy = max(qx, 0.0), max(qy, 0.0)
    return math.sqrt(ox * ox + oy * oy) + inner


@kernel(inline=True)
def _sdf_polygon(s, x, y, vstart, verts, fstart, faces):
    f0, f1 = fstart[s], fstart[s + 1]
    inside = -math.inf
    for f in range(f0, f1):
        inside = max(inside, faces[f, 0] * x + faces[f, 1] * y - faces[f, 3])
    if inside <= 0.0:
        return inside
    v0, v1 = vstart[s], vstart[s + 1]
    best = math.inf
    for v in range(v0, v1):
        w = v + 1 if v + 1 < v1 else v0
        best = min(best, _segment_dist2(x, y, verts[v, 0], verts[v, 1], verts[w, 0],
                                        verts[w, 1]))
    return math.sqrt(best)


@kernel(inline=True)
def _sdf_polyhedron(s, x, y, z, vstart, verts, fstart, faces, tstart, tris):
    inside = -math.inf
    for f in range(fstart[s], fstart[s + 1]):
        inside = max(inside, faces[f, 0] * x + faces[f, 1] * y + faces[f, 2] * z - faces[f, 3])
    if inside <= 0.0:
        return inside
    v0 = vstart[s]
    best = math.inf
    for t in range(tstart[s], tstart[s + 1]):
        a, b, c = v0 + tris[t, 0], v0 + tris[t, 1], v0 + tris[t, 2]
        best = min(best, triangle_dist2(x, y, z, verts[a, 0], verts[a, 1], verts[a, 2],
                                        verts[b, 0], verts[b, 1], verts[b, 2],
                                        verts[c, 0], verts[c, 1], verts[c, 2]))
    return math.sqrt(best)


@kernel(inline=True)
def sdf_local(kind, s, x, y, z, geo):
    """Signed distance [m] of body-frame point (x, y, z) to shape row ``s`` of ``kind``.

    Custom shapes are not evaluated here (their SDF is the user's function; see
    :mod:`dem.contact.detection`): this returns NaN for them.
    """
    param, scale, vstart, verts, fstart, faces, tstart, tris = (
        geo[0], geo[1], geo[2], geo[3], geo[4], geo[5], geo[6], geo[7])
    sc = scale[s]
    x, y, z = x / sc, y / sc, z / sc
    if kind == SPHERE:
        d = math.sqrt(x * x + y * y + z * z) - param[s, 0]
    elif kind == BOX:
        d = _sdf_box(x, y, z, param[s, 0], param[s, 1], param[s, 2])
    elif kind == POLYGON:
        d = _sdf_polygon(s, x, y, vstart, verts, fstart, faces)
    elif kind == POLYHEDRON:
        d = _sdf_polyhedron(s, x, y, z, vstart, verts, fstart, faces, tstart, tris)
    else:
        d = math.nan
    return sc * d


@kernel
def sdf_points(kind, s, pts, geo, out):
    """:func:`sdf_local` over body-frame points ``pts`` (m, 3) into ``out`` (m,)."""
    for i in range(pts.shape[0]):
        out[i] = sdf_local(kind, s, pts[i, 0], pts[i, 1], pts[i, 2], geo)


# --------------------------------------------------------------------------- frames
@kernel(inline=True)
def sdf_world(dim, kind, s, b, x, y, z, pos, rot, geo):
    """Signed distance [m] of world point (x, y, z) to body ``b`` (shape ``kind``, row ``s``)."""
    dx = x - pos[b, 0]
    dy = y - pos[b, 1]
    dz = z - pos[b, 2] if dim == 3 else 0.0
    lx, ly, lz = to_body(dim, rot, b, dx, dy, dz)
    return sdf_local(kind, s, lx, ly, lz, geo)
