"""3D: the volume and centroid of the intersection of two polyhedra, for patches.

Faces lying on faces and edges lying on faces make *patches*, where many features are
nearly equally deep: both bodies' corners, and edges crossing edges whose separating
axes all lie within the faces' small angle of their normal. The rules of
:mod:`.contact3` then jump the point across the patch as the deepest feature changes (a
face tilting through parallel, two twisted squares' edge crossings trading places as the
least separating axis), with the normal and the overlap nearly unchanged: a torque that
flips each step, and a packing of cubes that never came to rest (unbalanced-force ratio
0.04 after 60,000 steps, each contact's point jumping by the cube's size every other
step). So the point is moved, within the contact plane (its level along the normal
kept), towards the centroid of the bodies' intersection (:func:`overlap_centroid3`: each
body's boundary triangles clipped by the other's faces, summed by the divergence
theorem), with the weight going smoothly from 0 to 1 as ``q = sqrt(V / ov^3)`` goes from
``PATCH_FROM`` = 3 to ``PATCH_TO`` = 6 (an edge on a face at an overlap of 1 % of its
length, q = 10, is a patch). ``q`` is about 1 for a cube's corner or a cube's edge
across an edge, 1 to 10 for the blunter vertices of random polyhedra, ``sqrt(L / ov)``
for an edge of length ``L`` lying on a face and ``L / ov`` for faces on faces (a few
hundred in a packing), and the intersection's volume and centroid are continuous in the
pose. Where the weight is 0 the point is the rule's, so the force stays the gradient of
``kn ov^2 / 2`` there; on a patch the torque comes from the centroid instead (a face
pressed on a face has none to speak of). The cost is the clipping, only of triangles in
the contact's slab: from 1.1 to 3.0 µs per box pair (docs/performance.md, Figure 3).
"""

import numpy as np

from ...._jit import kernel
from .common import place3, turn3

#: 3D: the point moves to the intersection's centroid as ``sqrt(V / ov^3)`` goes from
#: PATCH_FROM to PATCH_TO (a cube's corner in a face: about 1; faces on faces: hundreds)
PATCH_FROM = 3.0
PATCH_TO = 6.0


@kernel
def _clipped3(s_in, sc_in, q_pose, s_cl, sc_cl, u_pose, w, slab, buf, placed, vstart, verts,
              fstart, faces, tstart, tris):
    """The part of polyhedron ``s_in``'s boundary inside polyhedron ``s_cl`` (placed
    at ``q_pose``, ``Q x + q``, and ``u_pose``, ``U x + u``): its contribution ``(V,
    Mx, My, Mz)`` to the volume of their intersection and to its first moment
    (divergence theorem: a fan of tetrahedra from the origin over each triangle clipped
    by the other's faces, Sutherland-Hodgman, in ``buf`` (2, m, 3), m >= 3 + faces of
    ``s_cl``; the vertices placed in ``placed`` (n, 4), n >= vertices of ``s_in``).
    The intersection lies in the slab ``|w . x| <= slab``: triangles wholly outside it
    are skipped unclipped."""
    vol, mx, my, mz = 0.0, 0.0, 0.0, 0.0
    wx, wy, wz = w
    ux, uy, uz = u_pose[9], u_pose[10], u_pose[11]
    v0 = vstart[s_in]
    f0, f1 = fstart[s_cl], fstart[s_cl + 1]
    for v in range(v0, vstart[s_in + 1]):  # placed once, with their slab coordinate
        x, y, z = place3(q_pose, sc_in * verts[v, 0], sc_in * verts[v, 1],
                         sc_in * verts[v, 2])
        placed[v - v0, 0], placed[v - v0, 1], placed[v - v0, 2] = x, y, z
        placed[v - v0, 3] = wx * x + wy * y + wz * z
    for t in range(tstart[s_in], tstart[s_in + 1]):
        i0, i1, i2 = tris[t, 0], tris[t, 1], tris[t, 2]
        h0, h1, h2 = placed[i0, 3], placed[i1, 3], placed[i2, 3]
        if min(h0, h1, h2) > slab or max(h0, h1, h2) < -slab:
            continue
        for k in range(3):
            i = tris[t, k]
            buf[0, k, 0], buf[0, k, 1], buf[0, k, 2] = (placed[i, 0], placed[i, 1],
                                                        placed[i, 2])
        m, cur = 3, 0
        for f in range(f0, f1):
            nx, ny, nz = turn3(u_pose, faces[f, 0], faces[f, 1], faces[f, 2])
            off = sc_cl * faces[f, 3] + nx * ux + ny * uy + nz * uz
            out = 0
            for k in range(m):
                if nx * buf[cur, k, 0] + ny * buf[cur, k, 1] + nz * buf[cur, k, 2] > off:
                    out += 1
            if out == 0:
                continue  # wholly inside this face
            if out == m:
                m = 0
                break  # wholly outside
            nxt, mo = 1 - cur, 0
            for k in range(m):
                k2 = k + 1 if k + 1 < m else 0
                dp = (nx * buf[cur, k, 0] + ny * buf[cur, k, 1] + nz * buf[cur, k, 2]
                      - off)
                dq = (nx * buf[cur, k2, 0] + ny * buf[cur, k2, 1] + nz * buf[cur, k2, 2]
                      - off)
                if dp <= 0.0:
                    buf[nxt, mo, 0] = buf[cur, k, 0]
                    buf[nxt, mo, 1] = buf[cur, k, 1]
                    buf[nxt, mo, 2] = buf[cur, k, 2]
                    mo += 1
                if (dp <= 0.0) != (dq <= 0.0):
                    w = dp / (dp - dq)
                    for i in range(3):
                        buf[nxt, mo, i] = buf[cur, k, i] + w * (buf[cur, k2, i]
                                                                - buf[cur, k, i])
                    mo += 1
            m, cur = mo, nxt
        if m < 3:
            continue
        ax, ay, az = buf[cur, 0, 0], buf[cur, 0, 1], buf[cur, 0, 2]
        for k in range(1, m - 1):
            bx, by, bz = buf[cur, k, 0], buf[cur, k, 1], buf[cur, k, 2]
            cx, cy, cz = buf[cur, k + 1, 0], buf[cur, k + 1, 1], buf[cur, k + 1, 2]
            v6 = (ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz)
                  + az * (bx * cy - by * cx))
            vol += v6
            mx += v6 * (ax + bx + cx)
            my += v6 * (ay + by + cy)
            mz += v6 * (az + bz + cz)
    return vol / 6.0, mx / 24.0, my / 24.0, mz / 24.0


@kernel
def overlap_centroid3(sa, sca, a_pose, sb, scb, b_pose, w, slab, geo):
    """Volume and centroid of the intersection of polyhedra A (at ``a_pose``, ``Ra x +
    pa``) and B (at ``b_pose``), placed about a point near it (round-off), which lies
    in the slab ``|w . x| <= slab`` (``slab = inf``: anywhere): ``(V, cx, cy, cz)``,
    ``V = 0`` (and ``c = 0``) when they do not overlap. A pose is ``(R row-major,
    p)``."""
    vstart, verts, fstart, faces, tstart, tris = (geo[2], geo[3], geo[4], geo[5], geo[6],
                                                  geo[7])
    m = 3 + max(fstart[sa + 1] - fstart[sa], fstart[sb + 1] - fstart[sb])
    buf = np.empty((2, m, 3))
    placed = np.empty((max(vstart[sa + 1] - vstart[sa], vstart[sb + 1] - vstart[sb]), 4))
    va, ma, mb, mc = _clipped3(sa, sca, a_pose, sb, scb, b_pose, w, slab, buf, placed,
                               vstart, verts, fstart, faces, tstart, tris)
    vb, na, nb, nc = _clipped3(sb, scb, b_pose, sa, sca, a_pose, w, slab, buf, placed,
                               vstart, verts, fstart, faces, tstart, tris)
    vol = va + vb
    if not vol > 0.0:
        return 0.0, 0.0, 0.0, 0.0
    return vol, (ma + na) / vol, (mb + nb) / vol, (mc + nc) / vol
