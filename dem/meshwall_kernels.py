"""Compiled geometry of triangle-mesh walls: closest points, sphere contacts, broad phase.

Kernel module (only ``@kernel`` functions and the bundles they take); the checked API
is :class:`dem.MeshWall` in :mod:`dem.meshwall`.

Contact rule
------------
Every face within a sphere's radius has one closest point to the sphere's centre, in
its interior, on one of its edges or at one of its vertices. A point in a face's
interior is a contact. A point on an edge or a vertex is shared with the faces around
that feature: the contact is kept only if every face around the feature has its own
closest point on that same feature (otherwise one of them is strictly closer and
reports the contact itself), and then only by the lowest face index among them. So a
sphere over the edge of two coplanar triangles, over a convex ridge or over a vertex of
a fan has one contact, and a sphere in a concave valley two (one per face). The rule is
combinatorial, not a comparison of distances with a tolerance: no two faces can both
claim one point.

Feature codes (``feature_out``): :data:`FACE` for the interior, ``EDGE + k`` for edge
``k`` of the face (from its vertex ``k`` to vertex ``(k + 1) % 3``), ``VERTEX + k``
for its vertex ``k``.
"""

import math
from typing import NamedTuple

import numpy as np

from ._jit import kernel

#: feature code of a closest point in a face's interior
FACE = 0
#: feature code of edge 0 of a face (edges 1 and 2 follow)
EDGE = 1
#: feature code of vertex 0 of a face (vertices 1 and 2 follow)
VERTEX = 4
#: barycentric weights at or below this count as zero when a closest point is
#: labelled with its feature, so that round-off puts a point on an edge or a vertex
#: in that feature for every face around it
SNAP = 1e-12


class MeshArrays(NamedTuple):
    """The arrays of one triangle mesh that the kernels read (all C-contiguous).

    ``vertices`` (nv, 3) f8 [m]; ``faces`` (nf, 3) i8 vertex rows; ``face_normal``
    (nf, 3) f8 unit normals (counter-clockwise winding); ``face_edges`` (nf, 3) i8, the
    edge row of edge ``k`` of each face; ``edge_face_ptr`` (ne + 1,) and
    ``edge_face_idx`` i8, the faces of each edge (compressed rows); ``vertex_face_ptr``
    (nv + 1,) and ``vertex_face_idx`` i8, the faces around each vertex.
    """

    vertices: np.ndarray
    faces: np.ndarray
    face_normal: np.ndarray
    face_edges: np.ndarray
    edge_face_ptr: np.ndarray
    edge_face_idx: np.ndarray
    vertex_face_ptr: np.ndarray
    vertex_face_idx: np.ndarray


class FaceGrid(NamedTuple):
    """A uniform grid over the faces' bounding boxes, grown by ``margin`` [m].

    ``lo`` (3,) f8 [m] the grid's corner, ``cell`` [m] the cell width, ``dims`` (3,) i8
    cells per axis, ``cell_ptr`` (n_cells + 1,) and ``cell_faces`` i8 the faces whose
    grown box meets each cell (compressed rows), ``face_lo``/``face_hi`` (nf, 3) f8 [m]
    the faces' grown boxes, ``mark`` (nf,) i8 scratch for de-duplication.
    """

    lo: np.ndarray
    cell: float
    dims: np.ndarray
    cell_ptr: np.ndarray
    cell_faces: np.ndarray
    face_lo: np.ndarray
    face_hi: np.ndarray
    mark: np.ndarray


@kernel(inline=True)
def closest_on_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Closest point of the triangle (a, b, c) to the point p, by the regions of the
    triangle's vertices, edges and interior (Ericson, Real-Time Collision Detection,
    section 5.1.5).

    Returns the barycentric weights ``(wa, wb, wc)`` of the closest point (they sum to
    one; a zero weight puts the point on the opposite edge, two on a vertex).
    """
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    # p against vertex a: both edges from a point away from p
    sa_b = abx * (px - ax) + aby * (py - ay) + abz * (pz - az)
    sa_c = acx * (px - ax) + acy * (py - ay) + acz * (pz - az)
    if sa_b <= 0.0 and sa_c <= 0.0:
        return 1.0, 0.0, 0.0
    sb_b = abx * (px - bx) + aby * (py - by) + abz * (pz - bz)
    sb_c = acx * (px - bx) + acy * (py - by) + acz * (pz - bz)
    if sb_b >= 0.0 and sb_c <= sb_b:
        return 0.0, 1.0, 0.0
    # edge ab: p projects between a and b, and lies outside the triangle across ab
    area_c = sa_b * sb_c - sb_b * sa_c
    if area_c <= 0.0 and sa_b >= 0.0 and sb_b <= 0.0:
        t = sa_b / (sa_b - sb_b)
        return 1.0 - t, t, 0.0
    sc_b = abx * (px - cx) + aby * (py - cy) + abz * (pz - cz)
    sc_c = acx * (px - cx) + acy * (py - cy) + acz * (pz - cz)
    if sc_c >= 0.0 and sc_b <= sc_c:
        return 0.0, 0.0, 1.0
    area_b = sc_b * sa_c - sa_b * sc_c
    if area_b <= 0.0 and sa_c >= 0.0 and sc_c <= 0.0:
        t = sa_c / (sa_c - sc_c)
        return 1.0 - t, 0.0, t
    area_a = sb_b * sc_c - sc_b * sb_c
    if area_a <= 0.0 and sb_c - sb_b >= 0.0 and sc_b - sc_c >= 0.0:
        t = (sb_c - sb_b) / ((sb_c - sb_b) + (sc_b - sc_c))
        return 0.0, 1.0 - t, t
    inv = 1.0 / (area_a + area_b + area_c)
    wb = area_b * inv
    wc = area_c * inv
    return 1.0 - wb - wc, wb, wc


@kernel(inline=True)
def feature_of(wa, wb, wc):
    """Feature code (:data:`FACE`, ``EDGE + k``, ``VERTEX + k``) of barycentric weights,
    a weight at or below :data:`SNAP` counting as zero."""
    za = wa <= SNAP
    zb = wb <= SNAP
    zc = wc <= SNAP
    n_zero = int(za) + int(zb) + int(zc)
    if n_zero == 0:
        return FACE
    if n_zero == 1:
        if zc:
            return EDGE + 0
        if za:
            return EDGE + 1
        return EDGE + 2
    if not za:
        return VERTEX + 0
    if not zb:
        return VERTEX + 1
    return VERTEX + 2


@kernel(inline=True)
def _face_closest(f, px, py, pz, mesh):
    """Closest point of face ``f`` to p: ``(qx, qy, qz, feature)``."""
    v = mesh.vertices
    i0, i1, i2 = mesh.faces[f, 0], mesh.faces[f, 1], mesh.faces[f, 2]
    wa, wb, wc = closest_on_triangle(px, py, pz, v[i0, 0], v[i0, 1], v[i0, 2],
                                     v[i1, 0], v[i1, 1], v[i1, 2],
                                     v[i2, 0], v[i2, 1], v[i2, 2])
    qx = wa * v[i0, 0] + wb * v[i1, 0] + wc * v[i2, 0]
    qy = wa * v[i0, 1] + wb * v[i1, 1] + wc * v[i2, 1]
    qz = wa * v[i0, 2] + wb * v[i1, 2] + wc * v[i2, 2]
    return qx, qy, qz, feature_of(wa, wb, wc)


@kernel(inline=True)
def _same_feature(g, feature_g, f, feature_f, mesh):
    """Do face g's feature and face f's feature (edge or vertex codes) name the same
    edge or vertex of the mesh?"""
    if feature_f >= VERTEX:
        return (feature_g >= VERTEX and
                mesh.faces[g, feature_g - VERTEX] == mesh.faces[f, feature_f - VERTEX])
    return (EDGE <= feature_g < VERTEX and
            mesh.face_edges[g, feature_g - EDGE] == mesh.face_edges[f, feature_f - EDGE])


@kernel(inline=True)
def _owns(f, feature, px, py, pz, mesh):
    """Does face f report its closest point on ``feature`` (an edge or a vertex)? Only
    if every face around the feature has its closest point there too, and f is the
    lowest of them."""
    if feature >= VERTEX:
        v = mesh.faces[f, feature - VERTEX]
        lo, hi = mesh.vertex_face_ptr[v], mesh.vertex_face_ptr[v + 1]
        around = mesh.vertex_face_idx
    else:
        e = mesh.face_edges[f, feature - EDGE]
        lo, hi = mesh.edge_face_ptr[e], mesh.edge_face_ptr[e + 1]
        around = mesh.edge_face_idx
    for k in range(lo, hi):
        g = around[k]
        if g == f:
            continue
        feature_g = _face_closest(g, px, py, pz, mesh)[3]
        if not _same_feature(g, feature_g, f, feature, mesh) or g < f:
            return False
    return True


@kernel
def sphere_mesh_contacts(center, radius, mesh, candidates, overlap_out, normal_out,
                         point_out, face_out, feature_out):
    """Every contact of one sphere with a triangle mesh, by the rule of the module.

    Parameters
    ----------
    center : (3,) float64 [m]
    radius : float [m]
    mesh : MeshArrays
    candidates : (nc,) int64
        The faces to test (a broad phase's answer, or every face).
    overlap_out : (m,) float64 [m]
        Modified in place: ``radius - distance`` (> 0) of each contact.
    normal_out : (m, 3) float64
        Unit normal from the contact point towards the centre (the face's normal when
        the centre lies on the face).
    point_out : (m, 3) float64 [m]
        The contact point, the closest point of the mesh to the centre.
    face_out, feature_out : (m,) int64
        The face reporting the contact and the feature code of the point on it.

    Returns
    -------
    n : int
        The number of contacts; only the first ``m`` are written if ``n > m`` (the
        caller regrows the outputs and calls again).
    """
    px, py, pz = center[0], center[1], center[2]
    r2 = radius * radius
    n = 0
    for k in range(candidates.shape[0]):
        f = candidates[k]
        qx, qy, qz, feature = _face_closest(f, px, py, pz, mesh)
        dx, dy, dz = px - qx, py - qy, pz - qz
        d2 = dx * dx + dy * dy + dz * dz
        if d2 >= r2:
            continue
        if feature != FACE and not _owns(f, feature, px, py, pz, mesh):
            continue
        if n < overlap_out.shape[0]:
            d = math.sqrt(d2)
            if d > 0.0:
                nx, ny, nz = dx / d, dy / d, dz / d
            else:
                nx, ny, nz = (mesh.face_normal[f, 0], mesh.face_normal[f, 1],
                              mesh.face_normal[f, 2])
            overlap_out[n] = radius - d
            normal_out[n, 0], normal_out[n, 1], normal_out[n, 2] = nx, ny, nz
            point_out[n, 0], point_out[n, 1], point_out[n, 2] = qx, qy, qz
            face_out[n] = f
            feature_out[n] = feature
        n += 1
    return n


# ------------------------------------------------------------------------ broad phase
@kernel(inline=True)
def _cell_range(lo, hi, grid_lo, cell, dims, a):
    """Cells ``[first, last]`` along axis ``a`` met by the interval ``[lo, hi]``
    (``first > last`` if none; an end on the grid's far side is in its last cell)."""
    if hi < grid_lo[a] or lo > grid_lo[a] + dims[a] * cell:
        return 1, 0
    first = int(math.floor((lo - grid_lo[a]) / cell))
    last = int(math.floor((hi - grid_lo[a]) / cell))
    return min(max(first, 0), dims[a] - 1), max(min(last, dims[a] - 1), 0)


@kernel
def fill_face_grid(grid_lo, cell, dims, face_lo, face_hi, cell_ptr_out, cell_faces_out):
    """Bin every face's box into the grid's cells (two passes: count, then fill).

    ``cell_ptr_out`` (n_cells + 1,) i8 is modified in place; ``cell_faces_out`` i8 is
    filled if it is long enough. Returns the length ``cell_faces_out`` needs.
    """
    n_cells = dims[0] * dims[1] * dims[2]
    cell_ptr_out[:] = 0
    for f in range(face_lo.shape[0]):
        x0, x1 = _cell_range(face_lo[f, 0], face_hi[f, 0], grid_lo, cell, dims, 0)
        y0, y1 = _cell_range(face_lo[f, 1], face_hi[f, 1], grid_lo, cell, dims, 1)
        z0, z1 = _cell_range(face_lo[f, 2], face_hi[f, 2], grid_lo, cell, dims, 2)
        for ix in range(x0, x1 + 1):
            for iy in range(y0, y1 + 1):
                for iz in range(z0, z1 + 1):
                    cell_ptr_out[(ix * dims[1] + iy) * dims[2] + iz + 1] += 1
    for c in range(n_cells):
        cell_ptr_out[c + 1] += cell_ptr_out[c]
    total = cell_ptr_out[n_cells]
    if total > cell_faces_out.shape[0]:
        return total
    fill = cell_ptr_out[:n_cells].copy()
    for f in range(face_lo.shape[0]):
        x0, x1 = _cell_range(face_lo[f, 0], face_hi[f, 0], grid_lo, cell, dims, 0)
        y0, y1 = _cell_range(face_lo[f, 1], face_hi[f, 1], grid_lo, cell, dims, 1)
        z0, z1 = _cell_range(face_lo[f, 2], face_hi[f, 2], grid_lo, cell, dims, 2)
        for ix in range(x0, x1 + 1):
            for iy in range(y0, y1 + 1):
                for iz in range(z0, z1 + 1):
                    c = (ix * dims[1] + iy) * dims[2] + iz
                    cell_faces_out[fill[c]] = f
                    fill[c] += 1
    return total


@kernel
def faces_near_spheres(pos, radius, grid, ptr_out, faces_out):
    """The faces whose grown boxes meet each sphere's box (compressed rows).

    ``pos`` (n, 3) f8 [m] and ``radius`` (n,) f8 [m]; ``ptr_out`` (n + 1,) i8 is
    modified in place; the faces of sphere ``i`` (ascending) are written to
    ``faces_out[ptr_out[i]:ptr_out[i + 1]]`` while ``faces_out`` (i8) is long enough.
    Returns the length it needs. Cost: per sphere, the cells its box meets plus the
    faces listed in them; ``grid.mark`` (reset here) keeps a face seen in several
    cells from being listed twice.
    """
    mark = grid.mark
    mark[:] = -1
    n = 0
    ptr_out[0] = 0
    for i in range(pos.shape[0]):
        start = n
        r = radius[i]
        x0, x1 = _cell_range(pos[i, 0] - r, pos[i, 0] + r, grid.lo, grid.cell, grid.dims, 0)
        y0, y1 = _cell_range(pos[i, 1] - r, pos[i, 1] + r, grid.lo, grid.cell, grid.dims, 1)
        z0, z1 = _cell_range(pos[i, 2] - r, pos[i, 2] + r, grid.lo, grid.cell, grid.dims, 2)
        for ix in range(x0, x1 + 1):
            for iy in range(y0, y1 + 1):
                for iz in range(z0, z1 + 1):
                    c = (ix * grid.dims[1] + iy) * grid.dims[2] + iz
                    for k in range(grid.cell_ptr[c], grid.cell_ptr[c + 1]):
                        f = grid.cell_faces[k]
                        if mark[f] == i:
                            continue
                        mark[f] = i
                        hit = True
                        for a in range(3):
                            if (pos[i, a] + r < grid.face_lo[f, a] or
                                    pos[i, a] - r > grid.face_hi[f, a]):
                                hit = False
                        if hit:
                            if n < faces_out.shape[0]:
                                faces_out[n] = f
                            n += 1
        if n <= faces_out.shape[0]:
            faces_out[start:n].sort()
        ptr_out[i + 1] = n
    return n
