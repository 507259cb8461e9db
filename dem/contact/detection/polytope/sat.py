"""Separating-axis contact of two convex polyhedra, for an edge across an edge.

:mod:`dem.contact.detection.polytope` solves the contract's programmes P1 and P2 (the
point of each body deepest in the other) exactly. When the deeper optimum is *not a
vertex* of the searched body it lies generically on an edge of that body and on a
crease of the other, where two of the other's faces are equally deep and its SDF has no
gradient. There the contract's answer (depth below the two tied faces, normal their
bisector: ``delta / sqrt(2)`` for two crossed cube edges pressed ``delta`` into each
other) is not the gradient of any function of the pose, and a frictionless collision
through it does not keep its energy. Such pairs get the answer of this module instead.

Method
------
The overlap ``ov`` is the least, over candidate axes ``u``, of ``max_A u . x - min_B u .
y``: the penetration depth, the shortest translation that separates the bodies (the
distance from the origin to the boundary of the Minkowski difference ``A - B``, whose
facets are the bodies' faces and their edge pairs). For an edge pair the axis is ``n =
e_A x e_B / |e_A x e_B|`` oriented from A to B, ``ov`` is the distance between the two
edge lines along ``n`` and ``c`` the midpoint of their closest points; when a face wins
it is a vertex on a face (the caller then places the point as for any vertex on a face).
Candidates:

* every face normal of both bodies (the least overlap along them, with the vertex that
  attains it: :func:`_face_axes3`);
* the edge pairs of the programmes' final bases (an edge of the searched body, two
  rows, on a crease of the other, two rows; P1's and P2's), then the edge pairs at the
  ends of either edge whose arcs of face normals cross (the Minkowski difference's
  facets next to the current one), walking on while the overlap drops (``_MAX_WALK``
  steps at most). An end is skipped when the facet's side there lies so far from the
  foot of the origin that no facet across it can be nearer.

An edge pair is a facet of the Minkowski difference, and so a candidate, only when the
two edges are the extreme features along their cross product: on the unit sphere, the
arc between A's two face normals crosses the arc between B's negated ones.

Why this is the right answer
----------------------------
It is the limit of P1/P2 where the SDF gradient is undefined. Where the deeper optimum
is a vertex with one face attaining the max, that face's normal is an axis along which
the overlap is the vertex's depth, and no translation shorter than the vertex's depth
takes it out of the other body, so the two answers agree; everywhere the penetration
depth is at least ``max(d1, d2)``. It is continuous in the pose, and on each piece (one
face and vertex, or one edge pair) the force ``kn ov n`` at ``c`` is its gradient with
respect to the rigid motions, so an undamped collision keeps its energy up to the
integrator's O(dt) error where the piece changes. The walk is local: for overlaps of a
few per cent of the body size it finds the least overlap (tested against all edge
pairs); deeper it may stop at a larger one, an upper bound of the depth.

Everything is read in B's frame, A placed at ``R x + p`` (``R`` as nine scalars); faces
are the shape table's rows ``n . x <= o`` (outward unit normals), scaled by the row's
scale.
"""

import math

from ...._jit import kernel
from .common import face_row3
from .sat_edges import (_closest_params, _edge_axis3, _edge_ends3, _plane_line,
                        _vertex_edges3)

#: steps of the walk over neighbouring edge pairs
_MAX_WALK = 8


@kernel
def _face_axes3(so, sco, si, sci, r00, r01, r02, r10, r11, r12, r20, r21, r22,
                px, py, pz, vstart, verts, fstart, faces, bound):
    """The least overlap along the outer body's face normals (separating-axis test).

    The inner body sits in the outer frame at ``R x + p``. Along face ``f`` the overlap
    is the depth of the inner body's lowest vertex below the face's plane. Returns
    ``(overlap, f, v)``: the least overlap below ``bound``, its face and that vertex
    (table rows), or ``(bound, -1, -1)``.
    """
    best, fb, vb = bound, -1, -1
    for f in range(fstart[so], fstart[so + 1]):
        nx, ny, nz = faces[f, 0], faces[f, 1], faces[f, 2]
        mx = r00 * nx + r10 * ny + r20 * nz  # R^T n: the normal in the inner frame
        my = r01 * nx + r11 * ny + r21 * nz
        mz = r02 * nx + r12 * ny + r22 * nz
        off = sco * faces[f, 3] - nx * px - ny * py - nz * pz
        cut = (off - best) / sci  # a vertex below this level: no better than best
        lo, vl = math.inf, -1
        for v in range(vstart[si], vstart[si + 1]):
            val = mx * verts[v, 0] + my * verts[v, 1] + mz * verts[v, 2]
            if val < lo:
                lo, vl = val, v
                if lo <= cut:
                    break
        ov = off - sci * lo
        if ov < best:
            best, fb, vb = ov, f, vl
    return best, fb, vb


@kernel
def sat_contact3(sa, sca, sb, scb, r00, r01, r02, r10, r11, r12, r20, r21, r22,
                 px, py, pz, qx, qy, qz, vstart, verts, fstart, faces, brad,
                 ga1, ga2, fb1, fb2, ga3, ga4, fb3, fb4):
    """Contact by the separating-axis test where the deeper optimum is not a vertex.

    A sits in B's frame at ``R x + p``, B in A's at ``R^T y + q``. Candidate axes:
    every face normal of both bodies, the edge-edge axes of the creases the two
    programmes ended on (A's faces ``ga1, ga2`` with B's ``fb1, fb2`` from P1, ``ga3,
    ga4`` with ``fb3, fb4`` from P2; ``-1``: none) and those of the edge pairs met
    walking from them (the module docstring). The least overlap wins. Returns ``(kind,
    ov, nx, ny, nz, cx, cy, cz)``: kind 0, a face of B (its outward normal and A's
    deepest vertex, in B's frame); 1, a face of A (its outward normal and B's deepest
    vertex, in A's frame); 2, an edge on an edge (the normal from A to B and the
    contact point, in B's frame).
    """
    kind, ov, nx, ny, nz, cx, cy, cz = 2, math.inf, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    eps_a = 1e-9 * sca * brad[sa]
    eps_b = 1e-9 * scb * brad[sb]
    for pair in range(2):
        ga, gb, fa, fb = (ga1, ga2, fb1, fb2) if pair == 0 else (ga3, ga4, fb3, fb4)
        if ga < 0 or (pair == 1 and ga1 >= 0 and min(ga, gb) == min(ga1, ga2)
                      and max(ga, gb) == max(ga1, ga2) and min(fa, fb) == min(fb1, fb2)
                      and max(fa, fb) == max(fb1, fb2)):
            continue  # none, or the same crease as P1's
        cur, mx, my, mz, ex, ey, ez = _edge_axis3(
            sa, sca, sb, scb, r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz,
            vstart, verts, faces, ga, gb, fa, fb)
        if cur < ov:
            kind, ov, nx, ny, nz, cx, cy, cz = 2, cur, mx, my, mz, ex, ey, ez
        # walk to the edge pairs at the ends of either edge while the overlap drops
        for _ in range(_MAX_WALK):
            a1x, a1y, a1z, a1o = face_row3(ga, sca, r00, r01, r02, r10, r11, r12, r20,
                                            r21, r22, px, py, pz, faces)
            a2x, a2y, a2z, a2o = face_row3(gb, sca, r00, r01, r02, r10, r11, r12, r20,
                                            r21, r22, px, py, pz, faces)
            b1x, b1y, b1z = faces[fa, 0], faces[fa, 1], faces[fa, 2]
            b2x, b2y, b2z = faces[fb, 0], faces[fb, 1], faces[fb, 2]
            xax, xay, xaz, eax, eay, eaz = _plane_line(a1x, a1y, a1z, a1o,
                                                       a2x, a2y, a2z, a2o)
            xbx, xby, xbz, ebx, eby, ebz = _plane_line(b1x, b1y, b1z, scb * faces[fa, 3],
                                                       b2x, b2y, b2z, scb * faces[fb, 3])
            # the two edges in their own frames; a line that misses its body (two faces
            # that do not meet) is no edge, and the other side cannot be paired with it
            (tax, tay, taz, uax, uay, uaz, loa, hia, mloa,
             mhia) = _edge_ends3(sa, sca, ga, gb, fstart, faces, eps_a)
            (tbx, tby, tbz, ubx, uby, ubz, lob, hib, mlob,
             mhib) = _edge_ends3(sb, scb, fa, fb, fstart, faces, eps_b)
            step, side_to, ng, nh = cur, -1, -1, -1
            # Across the side of the pair's facet (of the Minkowski difference) at an
            # end v of one edge, the next facet is tilted by at most the other edge's
            # dihedral angle theta; at a distance w from the foot of the origin it is
            # no nearer than this one when w >= cur tan(theta / 2): skip that end.
            s, t, aa, bb, den = _closest_params(xax, xay, xaz, eax, eay, eaz,
                                                xbx, xby, xbz, ebx, eby, ebz)
            reach_a, reach_b = math.inf, math.inf  # w below which an end is checked
            tpa, tpb, sin_ab = 0.0, 0.0, 0.0
            if den > 1e-12 * aa * bb:  # s, t: the closest points' parameters
                dx = xax + s * eax - px
                dy = xay + s * eay - py
                dz = xaz + s * eaz - pz
                tpa = ((r00 * dx + r10 * dy + r20 * dz - tax) * uax
                       + (r01 * dx + r11 * dy + r21 * dz - tay) * uay
                       + (r02 * dx + r12 * dy + r22 * dz - taz) * uaz)
                tpb = ((xbx + t * ebx - tbx) * ubx + (xby + t * eby - tby) * uby
                       + (xbz + t * ebz - tbz) * ubz)
                sin_ab = math.sqrt(den / (aa * bb))
                ca = min(max(a1x * a2x + a1y * a2y + a1z * a2z, -1.0), 1.0)
                cb = min(max(b1x * b2x + b1y * b2y + b1z * b2z, -1.0), 1.0)
                if ca > -1.0:
                    reach_b = cur * math.sqrt((1.0 - ca) / (1.0 + ca))
                if cb > -1.0:
                    reach_a = cur * math.sqrt((1.0 - cb) / (1.0 + cb))
            if loa <= hia + eps_a and lob <= hib + eps_b:
                # B's edge in A's frame (R^T), to cross with the edges at A's ends
                o1x = r00 * b1x + r10 * b1y + r20 * b1z
                o1y = r01 * b1x + r11 * b1y + r21 * b1z
                o1z = r02 * b1x + r12 * b1y + r22 * b1z
                o2x = r00 * b2x + r10 * b2y + r20 * b2z
                o2y = r01 * b2x + r11 * b2y + r21 * b2z
                o2z = r02 * b2x + r12 * b2y + r22 * b2z
                dx, dy, dz = xbx - px, xby - py, xbz - pz
                xox = r00 * dx + r10 * dy + r20 * dz
                xoy = r01 * dx + r11 * dy + r21 * dz
                xoz = r02 * dx + r12 * dy + r22 * dz
                eox = r00 * ebx + r10 * eby + r20 * ebz
                eoy = r01 * ebx + r11 * eby + r21 * ebz
                eoz = r02 * ebx + r12 * eby + r22 * ebz
                for k in range(4):
                    if k < 2:  # the edges at A's ends against B's edge
                        t, m = (loa, mloa) if k == 0 else (hia, mhia)
                        if (tpa - t if k == 0 else t - tpa) * sin_ab >= reach_a:
                            continue
                        ov3, mx, my, mz, ex, ey, ez, g, h = _vertex_edges3(
                            sa, sca, tax + t * uax, tay + t * uay, taz + t * uaz, m, True,
                            ga, gb, r00, r01, r02, r10, r11, r12, r20, r21, r22,
                            px, py, pz, fstart, faces, eps_a, o1x, o1y, o1z, o2x, o2y,
                            o2z, xox, xoy, xoz, eox, eoy, eoz)
                    else:  # the edges at B's ends against A's edge
                        t, m = (lob, mlob) if k == 2 else (hib, mhib)
                        if (tpb - t if k == 2 else t - tpb) * sin_ab >= reach_b:
                            continue
                        ov3, mx, my, mz, ex, ey, ez, g, h = _vertex_edges3(
                            sb, scb, tbx + t * ubx, tby + t * uby, tbz + t * ubz, m,
                            False, fa, fb, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0,
                            0.0, 0.0, 0.0, fstart, faces, eps_b, a1x, a1y, a1z, a2x,
                            a2y, a2z, xax, xay, xaz, eax, eay, eaz)
                    if ov3 < step:
                        step, side_to, ng, nh = ov3, k // 2, g, h
                    if ov3 < ov:
                        kind, ov, nx, ny, nz, cx, cy, cz = 2, ov3, mx, my, mz, ex, ey, ez
            if side_to < 0:
                break
            cur = step
            if side_to == 0:
                ga, gb = ng, nh
            else:
                fa, fb = ng, nh
    # the faces of B against A's vertices, then A's against B's (in A's frame)
    ov2, f, v = _face_axes3(sb, scb, sa, sca, r00, r01, r02, r10, r11, r12, r20, r21, r22,
                            px, py, pz, vstart, verts, fstart, faces, ov)
    if f >= 0:
        kind, ov = 0, ov2
        nx, ny, nz = faces[f, 0], faces[f, 1], faces[f, 2]
        lx, ly, lz = sca * verts[v, 0], sca * verts[v, 1], sca * verts[v, 2]
        cx = r00 * lx + r01 * ly + r02 * lz + px
        cy = r10 * lx + r11 * ly + r12 * lz + py
        cz = r20 * lx + r21 * ly + r22 * lz + pz
    ov2, f, v = _face_axes3(sa, sca, sb, scb, r00, r10, r20, r01, r11, r21, r02, r12, r22,
                            qx, qy, qz, vstart, verts, fstart, faces, ov)
    if f >= 0:
        kind, ov = 1, ov2
        nx, ny, nz = faces[f, 0], faces[f, 1], faces[f, 2]
        lx, ly, lz = scb * verts[v, 0], scb * verts[v, 1], scb * verts[v, 2]
        cx = r00 * lx + r10 * ly + r20 * lz + qx
        cy = r01 * lx + r11 * ly + r21 * lz + qy
        cz = r02 * lx + r12 * ly + r22 * lz + qz
    return kind, ov, nx, ny, nz, cx, cy, cz
