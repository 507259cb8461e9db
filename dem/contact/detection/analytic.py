"""Closed-form contacts: sphere-sphere, sphere-wall, sphere-box, sphere-polytope, box-wall.

Every kernel returns ``(ov, nx, ny, nz, cx, cy, cz, 0)`` as :mod:`dem.contact.detection`
defines it: overlap [m] (``<= 0`` separated), unit normal from A to B, contact point
[m] halfway between the two surface points. A sphere (a disk in 2D) is its centre
``pos[a]`` and radius ``ra``; a wall ``w`` is its point ``pos[w]`` and unit free-side
normal ``normal[w]``, its solid behind; the neighbour B may be a periodic image, at
``pos[b] + (sx, sy, sz)``.

For a sphere against a convex body B, the sphere's surface point is ``c_a + ra n`` in
each case below, so the contact point is ``c_a + (ra - ov / 2) n``:

* centre outside B: ``q`` is the closest point of B, ``ov = ra - |q - c_a|``, ``n = (q -
  c_a) / |q - c_a|`` (problem P2: B's point deepest in the sphere is ``q``);
* centre inside B (or on its surface): ``ov = ra - phi_B(c_a)``, ``n`` minus the outward
  normal of B's face attaining the max in ``phi_B = max_f (n_f . x - o_f)`` (ties within
  ``TIE`` times B's size: the normalised sum of the tied normals).

The two cases meet continuously when the centre crosses a face.
"""

import math

from ..._jit import kernel
from ...rotation import to_body, to_world
from .polytope import TIE


@kernel(inline=True)
def sphere_sphere(dim, a, ra, b, rb, sx, sy, sz, pos):
    """Two spheres (disks): ``ov = ra + rb - |x_b - x_a|`` along the line of centres.

    Coincident centres get the normal along the last axis.
    """
    dx = pos[b, 0] + sx - pos[a, 0]
    dy = pos[b, 1] + sy - pos[a, 1]
    dz = pos[b, 2] + sz - pos[a, 2] if dim == 3 else 0.0
    dist = math.sqrt(dx * dx + dy * dy + dz * dz)
    if dist > 0.0:
        nx, ny, nz = dx / dist, dy / dist, dz / dist
    elif dim == 3:
        nx, ny, nz = 0.0, 0.0, 1.0
    else:
        nx, ny, nz = 0.0, 1.0, 0.0
    ov = ra + rb - dist
    k = ra - 0.5 * ov
    cz = pos[a, 2] + k * nz if dim == 3 else 0.0
    return ov, nx, ny, nz, pos[a, 0] + k * nx, pos[a, 1] + k * ny, cz, 0


@kernel(inline=True)
def sphere_plane(dim, a, ra, w, pos, normal):
    """Sphere (disk) ``a`` against wall ``w``: ``ov = ra - normal[w] . (x_a - x_w)``."""
    wx, wy = normal[w, 0], normal[w, 1]
    wz = normal[w, 2] if dim == 3 else 0.0
    gap = wx * (pos[a, 0] - pos[w, 0]) + wy * (pos[a, 1] - pos[w, 1])
    if dim == 3:
        gap += wz * (pos[a, 2] - pos[w, 2])
    ov = ra - gap
    k = ra - 0.5 * ov
    cz = pos[a, 2] - k * wz if dim == 3 else 0.0
    return ov, -wx, -wy, -wz, pos[a, 0] - k * wx, pos[a, 1] - k * wy, cz, 0


@kernel(inline=True)
def _sphere_finish(dim, a, ra, b, pos, rot, ov, mx, my, mz):
    """World normal and contact point from B's body-frame unit normal ``m``."""
    nx, ny, nz = to_world(dim, rot, b, mx, my, mz)
    k = ra - 0.5 * ov
    cz = pos[a, 2] + k * nz if dim == 3 else 0.0
    return ov, nx, ny, nz, pos[a, 0] + k * nx, pos[a, 1] + k * ny, cz, 0


@kernel(inline=True)
def _centre_in(dim, a, b, sx, sy, sz, pos, rot, sc):
    """Sphere centre ``pos[a]`` in B's body frame, divided by B's scale."""
    dx = pos[a, 0] - pos[b, 0] - sx
    dy = pos[a, 1] - pos[b, 1] - sy
    dz = pos[a, 2] - pos[b, 2] - sz if dim == 3 else 0.0
    lx, ly, lz = to_body(dim, rot, b, dx, dy, dz)
    return lx / sc, ly / sc, lz / sc


@kernel(inline=True)
def sphere_box(dim, a, ra, sb, b, sx, sy, sz, pos, rot, geo):
    """Sphere (disk) ``a`` of radius ``ra`` [m] against box body ``b`` (shape row ``sb``).

    The closest point is the centre clamped to the half extents in B's frame. Arguments
    as :func:`sphere_polytope`.
    """
    param, scale, brad = geo[0], geo[1], geo[8]
    sc = scale[sb]
    hx, hy, hz = param[sb, 0], param[sb, 1], param[sb, 2]
    lx, ly, lz = _centre_in(dim, a, b, sx, sy, sz, pos, rot, sc)
    qx, qy, qz = min(max(lx, -hx), hx), min(max(ly, -hy), hy), min(max(lz, -hz), hz)
    ex, ey, ez = qx - lx, qy - ly, qz - lz
    e2 = ex * ex + ey * ey + ez * ez
    if e2 > 0.0:  # centre outside
        e = math.sqrt(e2)
        return _sphere_finish(dim, a, ra, b, pos, rot, ra - sc * e, ex / e, ey / e, ez / e)
    # centre inside: the face of least depth, ties summed
    px, py = abs(lx) - hx, abs(ly) - hy
    pz = abs(lz) - hz if dim == 3 else -math.inf
    phi = max(px, max(py, pz))
    cut = phi - TIE * brad[sb]
    mx = (-1.0 if lx >= 0.0 else 1.0) if px >= cut else 0.0
    my = (-1.0 if ly >= 0.0 else 1.0) if py >= cut else 0.0
    mz = (-1.0 if lz >= 0.0 else 1.0) if pz >= cut else 0.0
    m = math.sqrt(mx * mx + my * my + mz * mz)
    return _sphere_finish(dim, a, ra, b, pos, rot, ra - sc * phi, mx / m, my / m, mz / m)


@kernel(inline=True)
def _closest_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Closest point of triangle abc to p (Voronoi regions of the vertices and edges)."""
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return ax, ay, az
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bx, by, bz
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return ax + v * abx, ay + v * aby, az + v * abz
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cx, cy, cz
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return ax + w * acx, ay + w * acy, az + w * acz
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return bx + w * (cx - bx), by + w * (cy - by), bz + w * (cz - bz)
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    return ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w


@kernel(inline=True)
def sphere_polytope(dim, a, ra, sb, b, sx, sy, sz, pos, rot, geo):
    """Sphere (disk) ``a`` of radius ``ra`` [m] against polytope ``b`` (shape row ``sb``).

    Parameters
    ----------
    dim : int
        2 or 3 (a compile-time constant in callers).
    a : int
        The sphere's body index (its centre ``pos[a]``).
    ra : float
        The sphere's radius [m].
    sb, b : int
        B's shape row (a box, polygon or polyhedron: its vertices, faces and, in 3D,
        boundary triangles are read) and body index.
    sx, sy, sz : float
        Shift [m] added to B's position; ``sz`` unused in 2D.
    pos, rot, geo
        As :func:`dem.contact.detection.polytope.polytope_contact`.

    Returns
    -------
    (ov, nx, ny, nz, cx, cy, cz, 0)
        See the module docstring.
    """
    scale, vstart, verts, fstart, faces, tstart, tris, brad = (
        geo[1], geo[2], geo[3], geo[4], geo[5], geo[6], geo[7], geo[8])
    sc = scale[sb]
    lx, ly, lz = _centre_in(dim, a, b, sx, sy, sz, pos, rot, sc)
    phi = -math.inf
    for f in range(fstart[sb], fstart[sb + 1]):
        phi = max(phi, faces[f, 0] * lx + faces[f, 1] * ly + faces[f, 2] * lz - faces[f, 3])
    if phi > 0.0:  # centre outside: the closest boundary point
        best, qx, qy, qz = math.inf, 0.0, 0.0, 0.0
        v0, v1 = vstart[sb], vstart[sb + 1]
        if dim == 2:
            for v in range(v0, v1):
                u = v + 1 if v + 1 < v1 else v0
                ex, ey = verts[u, 0] - verts[v, 0], verts[u, 1] - verts[v, 1]
                wx, wy = lx - verts[v, 0], ly - verts[v, 1]
                s = min(max((wx * ex + wy * ey) / (ex * ex + ey * ey), 0.0), 1.0)
                cx, cy = verts[v, 0] + s * ex, verts[v, 1] + s * ey
                d2 = (cx - lx) * (cx - lx) + (cy - ly) * (cy - ly)
                if d2 < best:
                    best, qx, qy = d2, cx, cy
        else:
            for t in range(tstart[sb], tstart[sb + 1]):
                i, j, k = v0 + tris[t, 0], v0 + tris[t, 1], v0 + tris[t, 2]
                cx, cy, cz = _closest_triangle(lx, ly, lz, verts[i, 0], verts[i, 1],
                                               verts[i, 2], verts[j, 0], verts[j, 1],
                                               verts[j, 2], verts[k, 0], verts[k, 1],
                                               verts[k, 2])
                d2 = (cx - lx) * (cx - lx) + (cy - ly) * (cy - ly) + (cz - lz) * (cz - lz)
                if d2 < best:
                    best, qx, qy, qz = d2, cx, cy, cz
        if best > 0.0:
            e = math.sqrt(best)
            return _sphere_finish(dim, a, ra, b, pos, rot, ra - sc * e, (qx - lx) / e,
                                  (qy - ly) / e, (qz - lz) / e)
    # centre inside (or on the surface): minus the normal of the least deep face(s)
    cut = phi - TIE * brad[sb]
    mx, my, mz = 0.0, 0.0, 0.0
    for f in range(fstart[sb], fstart[sb + 1]):
        if faces[f, 0] * lx + faces[f, 1] * ly + faces[f, 2] * lz - faces[f, 3] >= cut:
            mx -= faces[f, 0]
            my -= faces[f, 1]
            mz -= faces[f, 2]
    m = math.sqrt(mx * mx + my * my + mz * mz)
    return _sphere_finish(dim, a, ra, b, pos, rot, ra - sc * phi, mx / m, my / m, mz / m)


@kernel(inline=True)
def box_plane(dim, sa, a, w, pos, rot, normal, geo):
    """Box body ``a`` (shape row ``sa``) against wall ``w``: the support point.

    The same contact as :func:`dem.contact.detection.polytope.polytope_plane` from the
    half extents alone: the deepest corner is ``-sign(m_i) h_i`` per axis, ``m`` the wall
    normal in the box frame; an axis along which the two corners are within ``TIE``
    times the box size of each other (a face or an edge lying flat) contributes 0, the
    average of the tied corners. Arguments as ``polytope_plane``.
    """
    param, scale, brad = geo[0], geo[1], geo[8]
    sc = scale[sa]
    wx, wy = normal[w, 0], normal[w, 1]
    wz = normal[w, 2] if dim == 3 else 0.0
    mx, my, mz = to_body(dim, rot, a, wx, wy, wz)
    hx, hy, hz = param[sa, 0], param[sa, 1], param[sa, 2]
    tie = 0.5 * TIE * brad[sa]
    vx = 0.0 if abs(mx) * hx <= tie else (-hx if mx > 0.0 else hx)
    vy = 0.0 if abs(my) * hy <= tie else (-hy if my > 0.0 else hy)
    vz = 0.0 if abs(mz) * hz <= tie else (-hz if mz > 0.0 else hz)
    depth = abs(mx) * hx + abs(my) * hy + abs(mz) * hz
    gap = wx * (pos[a, 0] - pos[w, 0]) + wy * (pos[a, 1] - pos[w, 1])
    if dim == 3:
        gap += wz * (pos[a, 2] - pos[w, 2])
    ov = sc * depth - gap
    xx, xy, xz = to_world(dim, rot, a, sc * vx, sc * vy, sc * vz)
    h = 0.5 * ov
    cz = pos[a, 2] + xz + h * wz if dim == 3 else 0.0
    return ov, -wx, -wy, -wz, pos[a, 0] + xx + h * wx, pos[a, 1] + xy + h * wy, cz, 0
