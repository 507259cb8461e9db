"""3D: the contact of two polyhedra.

Contact point of a vertex on a face
-----------------------------------
When the deeper optimum is a vertex, the point lies ``ov / 2`` in front of the mean of
the searched body's vertices that lie inside the other, each weighted by its depth
there (``-phi``, free from the programme's first scan), moved along the normal to the
deepest vertex's level. One vertex inside: that vertex, the contract's point. Several (a
face or an edge lying nearly flat on a face): the point, and so the torque, moves
continuously as the face tilts.

Edge across edge
----------------
When the deeper problem's optimum (after the ties of
:mod:`dem.contact.detection.polytope`) is *not a vertex* of the searched body it lies on
a crease of the other body, where its SDF has no gradient and the contract's answer is
not the gradient of any function of the pose. Such pairs get the separating-axis
contact of :mod:`.sat` (the penetration depth, along an edge pair's cross product or a
face normal), started from the edge pairs of both programmes' final bases
(:func:`_crease_rows`): the limit of P1/P2 there, and conservative. When a face wins,
the point is placed as for a vertex on a face.

Patches
-------
On a patch (faces or an edge lying on a face) the point then moves, within the contact
plane, towards the centroid of the bodies' intersection (:mod:`.patch3`).
"""

import math

from ...._jit import kernel
from .common import TIE, _matrix3, place3, turn3
from .patch3 import PATCH_FROM, PATCH_TO, overlap_centroid3
from .sat import sat_contact3
from .simplex3 import _deepest3, _separation3


@kernel
def _polytope3(sa, a, sb, b, sx, sy, sz, pos, rot, geo):
    """The 3D contact: :func:`_rules3`'s, its point moved onto a patch's centroid
    (module notes, patches)."""
    ov, nx, ny, nz, cx, cy, cz, it = _rules3(sa, a, sb, b, sx, sy, sz, pos, rot, geo)
    if ov <= 0.0:
        return ov, nx, ny, nz, cx, cy, cz, it
    # a patch (faces or an edge on a face): the point moves along the contact plane to
    # the centroid of the bodies' intersection, as its extent against the overlap
    # grows
    scale = geo[1]
    a_pose = _matrix3(rot, a) + (pos[a, 0] - cx, pos[a, 1] - cy, pos[a, 2] - cz)
    b_pose = _matrix3(rot, b) + (pos[b, 0] + sx - cx, pos[b, 1] + sy - cy,
                                 pos[b, 2] + sz - cz)
    vol, ex, ey, ez = overlap_centroid3(
        sa, scale[sa], a_pose, sb, scale[sb], b_pose, (nx, ny, nz), ov,
        geo)  # within ov / 2 of the point along n (twice that, for safety)
    u = (math.sqrt(vol / (ov * ov * ov)) - PATCH_FROM) / (PATCH_TO - PATCH_FROM)
    if u <= 0.0:
        return ov, nx, ny, nz, cx, cy, cz, it
    u = 1.0 if u >= 1.0 else u * u * (3.0 - 2.0 * u)
    e = ex * nx + ey * ny + ez * nz
    return (ov, nx, ny, nz, cx + u * (ex - e * nx), cy + u * (ey - e * ny),
            cz + u * (ez - e * nz), it)


@kernel
def _rules3(sa, a, sb, b, sx, sy, sz, pos, rot, geo):
    """The deeper programme's contact, or the separating axes' where its optimum is no
    vertex, with the point of a vertex on a face (module notes)."""
    scale, vstart, verts, fstart, faces = geo[1], geo[2], geo[3], geo[4], geo[5]
    brad = geo[8]
    sca, scb = scale[sa], scale[sb]
    tol = TIE * max(sca * brad[sa], scb * brad[sb])
    a_rot, b_rot = _matrix3(rot, a), _matrix3(rot, b)
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = a_rot
    b00, b01, b02, b10, b11, b12, b20, b21, b22 = b_rot
    # A's frame in B's: R = Rb^T Ra, p = Rb^T (xa - xb - shift)
    r00 = b00 * a00 + b10 * a10 + b20 * a20
    r01 = b00 * a01 + b10 * a11 + b20 * a21
    r02 = b00 * a02 + b10 * a12 + b20 * a22
    r10 = b01 * a00 + b11 * a10 + b21 * a20
    r11 = b01 * a01 + b11 * a11 + b21 * a21
    r12 = b01 * a02 + b11 * a12 + b21 * a22
    r20 = b02 * a00 + b12 * a10 + b22 * a20
    r21 = b02 * a01 + b12 * a11 + b22 * a21
    r22 = b02 * a02 + b12 * a12 + b22 * a22
    dx = pos[a, 0] - pos[b, 0] - sx
    dy = pos[a, 1] - pos[b, 1] - sy
    dz = pos[a, 2] - pos[b, 2] - sz
    px = b00 * dx + b10 * dy + b20 * dz
    py = b01 * dx + b11 * dy + b21 * dz
    pz = b02 * dx + b12 * dy + b22 * dz
    qx = -(r00 * px + r10 * py + r20 * pz)  # B's origin in A's frame: -R^T p
    qy = -(r01 * px + r11 * py + r21 * pz)
    qz = -(r02 * px + r12 * py + r22 * pz)
    a_in_b = (r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz)
    b_in_a = (r00, r10, r20, r01, r11, r21, r02, r12, r22, qx, qy, qz)
    sep = max(_separation3(sb, scb, sa, sca, a_in_b, vstart, verts, fstart, faces),
              _separation3(sa, sca, sb, scb, b_in_a, vstart, verts, fstart, faces))
    if sep > 0.0:
        return -sep, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0
    (t1, x1, y1, z1, m1x, m1y, m1z, n1, i1, k10, k11, k12, k13, s1, s1x, s1y,
     s1z) = _deepest3(sb, scb, sa, sca, a_in_b, vstart, verts, fstart, faces, brad, tol)
    if t1 >= 0.0:
        return -t1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, i1
    (t2, x2, y2, z2, m2x, m2y, m2z, n2, i2, k20, k21, k22, k23, s2, s2x, s2y,
     s2z) = _deepest3(sa, sca, sb, scb, b_in_a, vstart, verts, fstart, faces, brad, tol)
    d1, d2 = -t1, -t2
    use1 = d1 > d2 + tol or (d1 >= d2 - tol and n1 >= n2)
    if (n1 if use1 else n2) == 0:  # not a vertex: the separating-axis test decides
        fa0, nfa = fstart[sa], fstart[sa + 1] - fstart[sa]
        fb0, nfb = fstart[sb], fstart[sb + 1] - fstart[sb]
        ga1, ga2, fb1, fb2 = _crease_rows(k10, k11, k12, k13, nfb, fb0, fa0)
        fb3, fb4, ga3, ga4 = _crease_rows(k20, k21, k22, k23, nfa, fa0, fb0)
        kind, ov, mx, my, mz, cx, cy, cz = sat_contact3(
            sa, sca, sb, scb, a_in_b, b_in_a, vstart, verts, fstart, faces, brad,
            (ga1, ga2, fb1, fb2), (ga3, ga4, fb3, fb4))
        if kind == 2:  # an edge on an edge
            b_turn = b_rot + (0.0, 0.0, 0.0)
            nx, ny, nz = turn3(b_turn, mx, my, mz)
            wx, wy, wz = turn3(b_turn, cx, cy, cz)
            return (ov, nx, ny, nz, wx + pos[b, 0] + sx, wy + pos[b, 1] + sy,
                    wz + pos[b, 2] + sz, i1 + i2)
        use1 = kind == 0  # a vertex on a face: as below, from that face
        if use1:
            d1, x1, y1, z1, m1x, m1y, m1z = ov, cx, cy, cz, mx, my, mz
        else:
            d2, x2, y2, z2, m2x, m2y, m2z = ov, cx, cy, cz, mx, my, mz
    if use1:
        return _vertex_term3(d1, (m1x, m1y, m1z), (x1, y1, z1), s1, (s1x, s1y, s1z),
                             b_rot + (pos[b, 0] + sx, pos[b, 1] + sy, pos[b, 2] + sz),
                             -1.0, i1 + i2)
    return _vertex_term3(d2, (m2x, m2y, m2z), (x2, y2, z2), s2, (s2x, s2y, s2z),
                         a_rot + (pos[a, 0], pos[a, 1], pos[a, 2]), 1.0, i1 + i2)


@kernel(inline=True)
def _crease_rows(k0, k1, k2, k3, nfo, fo0, fi0):
    """Faces ``(i1, i2, o1, o2)`` of a basis with two inner and two outer rows (an
    inner edge on an outer crease), or ``-1``s."""
    i1, i2, o1, o2, n_out = -1, -1, -1, -1, 0
    for k in (k0, k1, k2, k3):
        if k < nfo:
            n_out += 1
            if o1 < 0:
                o1 = fo0 + k
            else:
                o2 = fo0 + k
        elif i1 < 0:
            i1 = fi0 + k - nfo
        else:
            i2 = fi0 + k - nfo
    if n_out != 2:
        return -1, -1, -1, -1
    return i1, i2, o1, o2


@kernel(inline=True)
def _vertex_term3(d, m, x, sw, swx, pose, sign, pivots):
    """One body's vertices in the other (the outer, placed at ``pose``: ``Q y + o``),
    deepest ``d`` at ``x`` where the outer normal is ``m``: the contact ``(d, n, point,
    pivots)`` in the world, ``n = sign Q m`` (from A into B).

    The point lies ``d / 2`` out of the deepest point's level along ``m``, over the
    depth-weighted mean of the vertices inside (weights ``sw``, sums ``swx = sw x``), so
    it moves continuously as a face tilts through flat on a face; none inside (a face
    won the separating-axis test with a vertex outside): over ``x``."""
    mwx, mwy, mwz = turn3(pose, m[0], m[1], m[2])
    wx, wy, wz = place3(pose, x[0], x[1], x[2])
    if sw > 0.0:
        ex, ey, ez = turn3(pose, swx[0], swx[1], swx[2])
        ex = ex / sw + pose[9] - wx
        ey = ey / sw + pose[10] - wy
        ez = ez / sw + pose[11] - wz
        e = ex * mwx + ey * mwy + ez * mwz
        wx, wy, wz = wx + ex - e * mwx, wy + ey - e * mwy, wz + ez - e * mwz
    h = 0.5 * d
    return (d, sign * mwx, sign * mwy, sign * mwz, wx + h * mwx, wy + h * mwy,
            wz + h * mwz, pivots)
