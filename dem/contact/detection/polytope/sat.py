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

Everything is read in B's frame, A placed at ``R x + p`` (its pose ``(R row-major,
p)``, :mod:`.common`); faces are the shape table's rows ``n . x <= o`` (outward unit
normals), scaled by the row's scale.
"""

import math

from ...._jit import kernel
from .common import IDENTITY3, face_row3, place3, unturn3
from .sat_edges import (_closest_params, _edge_axis3, _edge_ends3, _plane_line,
                        _vertex_edges3)

#: steps of the walk over neighbouring edge pairs
_MAX_WALK = 8


@kernel
def _face_axes3(so, sco, si, sci, pose, vstart, verts, fstart, faces, bound):
    """The least overlap along the outer body's face normals (separating-axis test).

    The inner body sits in the outer frame at ``pose``. Along face ``f`` the overlap
    is the depth of the inner body's lowest vertex below the face's plane. Returns
    ``(overlap, f, v)``: the least overlap below ``bound``, its face and that vertex
    (table rows), or ``(bound, -1, -1)``.
    """
    px, py, pz = pose[9], pose[10], pose[11]
    best, fb, vb = bound, -1, -1
    for f in range(fstart[so], fstart[so + 1]):
        nx, ny, nz = faces[f, 0], faces[f, 1], faces[f, 2]
        mx, my, mz = unturn3(pose, nx, ny, nz)  # the normal in the inner frame
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
def sat_contact3(sa, sca, sb, scb, a_in_b, b_in_a, vstart, verts, fstart, faces, brad,
                 crease1, crease2):
    """Contact by the separating-axis test where the deeper optimum is not a vertex.

    A sits in B's frame at pose ``a_in_b`` (``R x + p``), B in A's at ``b_in_a``
    (``R^T y + q``). Candidate axes: every face normal of both bodies, the edge-edge
    axes of the creases the two programmes ended on (``crease1 = (ga1, ga2, fb1,
    fb2)``, A's faces with B's, from P1; ``crease2`` from P2; ``-1``: none) and those
    of the edge pairs met walking from them (the module docstring). The least overlap
    wins. Returns ``(kind, ov, nx, ny, nz, cx, cy, cz)``: kind 0, a face of B (its
    outward normal and A's deepest vertex, in B's frame); 1, a face of A (its outward
    normal and B's deepest vertex, in A's frame); 2, an edge on an edge (the normal
    from A to B and the contact point, in B's frame).
    """
    kind, ov, nx, ny, nz, cx, cy, cz = 2, math.inf, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    eps = (1e-9 * sca * brad[sa], 1e-9 * scb * brad[sb])
    ga1, ga2, fb1, fb2 = crease1
    for pair in range(2):
        ga, gb, fa, fb = crease1 if pair == 0 else crease2
        if ga < 0 or (pair == 1 and ga1 >= 0 and min(ga, gb) == min(ga1, ga2)
                      and max(ga, gb) == max(ga1, ga2) and min(fa, fb) == min(fb1, fb2)
                      and max(fa, fb) == max(fb1, fb2)):
            continue  # none, or the same crease as P1's
        cur, mx, my, mz, ex, ey, ez = _edge_axis3(sa, sca, sb, scb, a_in_b, vstart, verts,
                                                  faces, ga, gb, fa, fb)
        if cur < ov:
            kind, ov, nx, ny, nz, cx, cy, cz = 2, cur, mx, my, mz, ex, ey, ez
        # walk to the edge pairs at the ends of either edge while the overlap drops
        for _ in range(_MAX_WALK):
            step, side_to, ng, nh, best = _walk_step3(sa, sca, sb, scb, a_in_b, fstart,
                                                      faces, eps, (ga, gb, fa, fb), cur)
            if best[0] < ov:
                kind = 2
                ov, nx, ny, nz, cx, cy, cz = best
            if side_to < 0:
                break
            cur = step
            if side_to == 0:
                ga, gb = ng, nh
            else:
                fa, fb = ng, nh
    # the faces of B against A's vertices, then A's against B's (in A's frame)
    ov2, f, v = _face_axes3(sb, scb, sa, sca, a_in_b, vstart, verts, fstart, faces, ov)
    if f >= 0:
        kind, ov = 0, ov2
        nx, ny, nz = faces[f, 0], faces[f, 1], faces[f, 2]
        cx, cy, cz = place3(a_in_b, sca * verts[v, 0], sca * verts[v, 1], sca * verts[v, 2])
    ov2, f, v = _face_axes3(sa, sca, sb, scb, b_in_a, vstart, verts, fstart, faces, ov)
    if f >= 0:
        kind, ov = 1, ov2
        nx, ny, nz = faces[f, 0], faces[f, 1], faces[f, 2]
        cx, cy, cz = place3(b_in_a, scb * verts[v, 0], scb * verts[v, 1], scb * verts[v, 2])
    return kind, ov, nx, ny, nz, cx, cy, cz


@kernel
def _walk_step3(sa, sca, sb, scb, pose, fstart, faces, eps, crease, cur):
    """One step of the walk from the edge pair ``crease = (ga, gb, fa, fb)`` (A's faces
    ``ga``, ``gb``; B's ``fa``, ``fb``) of overlap ``cur``: the edge pairs at the ends
    of either edge (A at ``pose`` in B's frame, ``eps`` the two bodies' tolerances).

    Returns ``(step, side, g, h, best)``: the least overlap below ``cur`` and where it
    leads (``side`` 0: A's edge becomes faces ``g``, ``h``; 1: B's; -1: none lower),
    and ``best = (ov, nx, ny, nz, cx, cy, cz)``, the least overlap met (infinite if
    none) with its axis and point in B's frame.
    """
    ga, gb, fa, fb = crease
    eps_a, eps_b = eps
    px, py, pz = pose[9], pose[10], pose[11]
    a1x, a1y, a1z, a1o = face_row3(ga, sca, pose, faces)
    a2x, a2y, a2z, a2o = face_row3(gb, sca, pose, faces)
    b1x, b1y, b1z = faces[fa, 0], faces[fa, 1], faces[fa, 2]
    b2x, b2y, b2z = faces[fb, 0], faces[fb, 1], faces[fb, 2]
    xax, xay, xaz, eax, eay, eaz = _plane_line(a1x, a1y, a1z, a1o, a2x, a2y, a2z, a2o)
    xbx, xby, xbz, ebx, eby, ebz = _plane_line(b1x, b1y, b1z, scb * faces[fa, 3],
                                               b2x, b2y, b2z, scb * faces[fb, 3])
    # the two edges in their own frames; a line that misses its body (two faces that
    # do not meet) is no edge, and the other side cannot be paired with it
    (tax, tay, taz, uax, uay, uaz, loa, hia, mloa,
     mhia) = _edge_ends3(sa, sca, ga, gb, fstart, faces, eps_a)
    (tbx, tby, tbz, ubx, uby, ubz, lob, hib, mlob,
     mhib) = _edge_ends3(sb, scb, fa, fb, fstart, faces, eps_b)
    step, side_to, ng, nh = cur, -1, -1, -1
    best = (math.inf, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    if not (loa <= hia + eps_a and lob <= hib + eps_b):
        return step, side_to, ng, nh, best
    # Across the side of the pair's facet (of the Minkowski difference) at an end v of
    # one edge, the next facet is tilted by at most the other edge's dihedral angle
    # theta; at a distance w from the foot of the origin it is no nearer than this one
    # when w >= cur tan(theta / 2): skip that end.
    s, t, aa, bb, den = _closest_params(xax, xay, xaz, eax, eay, eaz,
                                        xbx, xby, xbz, ebx, eby, ebz)
    reach_a, reach_b = math.inf, math.inf  # w below which an end is checked
    tpa, tpb, sin_ab = 0.0, 0.0, 0.0
    if den > 1e-12 * aa * bb:  # s, t: the closest points' parameters
        qax, qay, qaz = unturn3(pose, xax + s * eax - px, xay + s * eay - py,
                                xaz + s * eaz - pz)
        tpa = (qax - tax) * uax + (qay - tay) * uay + (qaz - taz) * uaz
        tpb = ((xbx + t * ebx - tbx) * ubx + (xby + t * eby - tby) * uby
               + (xbz + t * ebz - tbz) * ubz)
        sin_ab = math.sqrt(den / (aa * bb))
        ca = min(max(a1x * a2x + a1y * a2y + a1z * a2z, -1.0), 1.0)
        cb = min(max(b1x * b2x + b1y * b2y + b1z * b2z, -1.0), 1.0)
        if ca > -1.0:
            reach_b = cur * math.sqrt((1.0 - ca) / (1.0 + ca))
        if cb > -1.0:
            reach_a = cur * math.sqrt((1.0 - cb) / (1.0 + cb))
    # B's edge in A's frame (R^T), to cross with the edges at A's ends
    o1x, o1y, o1z = unturn3(pose, b1x, b1y, b1z)
    o2x, o2y, o2z = unturn3(pose, b2x, b2y, b2z)
    xox, xoy, xoz = unturn3(pose, xbx - px, xby - py, xbz - pz)
    eox, eoy, eoz = unturn3(pose, ebx, eby, ebz)
    for k in range(4):
        if k < 2:  # the edges at A's ends against B's edge
            t, m = (loa, mloa) if k == 0 else (hia, mhia)
            if (tpa - t if k == 0 else t - tpa) * sin_ab >= reach_a:
                continue
            ov3, mx, my, mz, ex, ey, ez, g, h = _vertex_edges3(
                sa, sca, tax + t * uax, tay + t * uay, taz + t * uaz, m, True, ga, gb,
                pose, fstart, faces, eps_a,
                (o1x, o1y, o1z, o2x, o2y, o2z, xox, xoy, xoz, eox, eoy, eoz))
        else:  # the edges at B's ends against A's edge
            t, m = (lob, mlob) if k == 2 else (hib, mhib)
            if (tpb - t if k == 2 else t - tpb) * sin_ab >= reach_b:
                continue
            ov3, mx, my, mz, ex, ey, ez, g, h = _vertex_edges3(
                sb, scb, tbx + t * ubx, tby + t * uby, tbz + t * ubz, m, False, fa, fb,
                IDENTITY3, fstart, faces, eps_b,
                (a1x, a1y, a1z, a2x, a2y, a2z, xax, xay, xaz, eax, eay, eaz))
        if ov3 < step:
            step, side_to, ng, nh = ov3, k // 2, g, h
        if ov3 < best[0]:
            best = (ov3, mx, my, mz, ex, ey, ez)
    return step, side_to, ng, nh, best
