"""3D: the edge-pair geometry of the separating-axis contact (:mod:`.sat`).

The overlap along the cross product of two edges (:func:`_edge_axis3`), an edge's ends
on its body (:func:`_edge_ends3`), and the edge pairs met at an end
(:func:`_vertex_edges3`). Everything is read in B's frame, A placed at ``R x + p``
(its pose ``(R row-major, p)``, :mod:`.common`); faces are the shape table's rows
``n . x <= o``, scaled by the row's scale.
"""

import math

from ...._jit import kernel
from .common import cross3, face_row3, place3, turn3, unturn3


@kernel(inline=True)
def _plane_line(ax, ay, az, ao, bx, by, bz, bo):
    """The line where the planes ``a . x = ao`` and ``b . x = bo`` meet: its point
    nearest the origin and its direction ``a x b`` (not normalised, 0 if parallel)."""
    ex, ey, ez = cross3(ax, ay, az, bx, by, bz)
    ee = ex * ex + ey * ey + ez * ez
    if ee == 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    ab = ax * bx + ay * by + az * bz
    aa = ax * ax + ay * ay + az * az
    bb = bx * bx + by * by + bz * bz
    al = (bb * ao - ab * bo) / ee  # x = al a + be b, the Gram determinant is |a x b|^2
    be = (aa * bo - ab * ao) / ee
    return al * ax + be * bx, al * ay + be * by, al * az + be * bz, ex, ey, ez


@kernel(inline=True)
def _closest_params(xax, xay, xaz, eax, eay, eaz, xbx, xby, xbz, ebx, eby, ebz):
    """Parameters ``s``, ``t`` of the closest points of lines ``xa + s ea`` and ``xb + t
    eb``, with ``|ea|^2``, ``|eb|^2`` and ``den = |ea x eb|^2`` (``s``, ``t`` are not
    finite when ``den`` is 0: parallel lines)."""
    wx, wy, wz = xax - xbx, xay - xby, xaz - xbz
    aa = eax * eax + eay * eay + eaz * eaz
    bb = ebx * ebx + eby * eby + ebz * ebz
    ab = eax * ebx + eay * eby + eaz * ebz
    d = eax * wx + eay * wy + eaz * wz
    e = ebx * wx + eby * wy + ebz * wz
    den = aa * bb - ab * ab
    return (ab * e - bb * d) / den, (aa * e - ab * d) / den, aa, bb, den


@kernel(inline=True)
def _line_pair(xax, xay, xaz, eax, eay, eaz, xbx, xby, xbz, ebx, eby, ebz):
    """Midpoint of the closest points of lines ``xa + s ea`` and ``xb + t eb``
    (not parallel)."""
    s, t, _, _, _ = _closest_params(xax, xay, xaz, eax, eay, eaz, xbx, xby, xbz,
                                    ebx, eby, ebz)
    return (0.5 * (xax + s * eax + xbx + t * ebx), 0.5 * (xay + s * eay + xby + t * eby),
            0.5 * (xaz + s * eaz + xbz + t * ebz))


@kernel(inline=True)
def _edge_normal(a1x, a1y, a1z, a2x, a2y, a2z, b1x, b1y, b1z, b2x, b2y, b2z):
    """Unit ``(a1 x a2) x (b1 x b2)`` oriented out of A (``n . (a1 + a2) > 0``), for the
    edge of A between faces with normals a1, a2 and of B between b1, b2; zero when the
    edges are parallel. Also returns the two edge directions."""
    eax, eay, eaz = cross3(a1x, a1y, a1z, a2x, a2y, a2z)
    ebx, eby, ebz = cross3(b1x, b1y, b1z, b2x, b2y, b2z)
    nx, ny, nz = cross3(eax, eay, eaz, ebx, eby, ebz)
    nn = nx * nx + ny * ny + nz * nz
    if not nn > 1e-12 * ((eax * eax + eay * eay + eaz * eaz)
                         * (ebx * ebx + eby * eby + ebz * ebz)):
        return 0.0, 0.0, 0.0, eax, eay, eaz, ebx, eby, ebz
    nrm = math.sqrt(nn)
    if nx * (a1x + a2x) + ny * (a1y + a2y) + nz * (a1z + a2z) < 0.0:
        nrm = -nrm
    return nx / nrm, ny / nrm, nz / nrm, eax, eay, eaz, ebx, eby, ebz


@kernel
def _edge_axis3(sa, sca, sb, scb, pose, vstart, verts, faces, ga, gb, fa, fb):
    """Overlap along the cross product of an edge of A and an edge of B (B's frame).

    A sits in B's frame at ``R x + p``; its edge is where its faces ``ga``, ``gb``
    meet, B's where ``fa``, ``fb`` meet. The axis ``n`` is oriented out of A and into
    B; the overlap is ``max_A n . x - min_B n . y`` (an upper bound of the penetration
    depth, equal to the distance between the two edge lines when the edges are the
    bodies' extreme features along ``n``). Returns ``(overlap, nx, ny, nz, cx, cy,
    cz)`` with ``c`` the midpoint of the lines' closest points, or an infinite overlap
    when the edges are parallel.
    """
    a1x, a1y, a1z, a1o = face_row3(ga, sca, pose, faces)
    a2x, a2y, a2z, a2o = face_row3(gb, sca, pose, faces)
    b1x, b1y, b1z, b1o = faces[fa, 0], faces[fa, 1], faces[fa, 2], scb * faces[fa, 3]
    b2x, b2y, b2z, b2o = faces[fb, 0], faces[fb, 1], faces[fb, 2], scb * faces[fb, 3]
    nx, ny, nz, _, _, _, _, _, _ = _edge_normal(a1x, a1y, a1z, a2x, a2y, a2z,
                                                b1x, b1y, b1z, b2x, b2y, b2z)
    if nx == 0.0 and ny == 0.0 and nz == 0.0:
        return math.inf, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    xax, xay, xaz, eax, eay, eaz = _plane_line(a1x, a1y, a1z, a1o, a2x, a2y, a2z, a2o)
    xbx, xby, xbz, ebx, eby, ebz = _plane_line(b1x, b1y, b1z, b1o, b2x, b2y, b2z, b2o)
    cx, cy, cz = _line_pair(xax, xay, xaz, eax, eay, eaz, xbx, xby, xbz, ebx, eby, ebz)
    # support of A along n (read in A's frame) and of B along -n
    mx, my, mz = unturn3(pose, nx, ny, nz)
    hi = -math.inf
    for v in range(vstart[sa], vstart[sa + 1]):
        hi = max(hi, mx * verts[v, 0] + my * verts[v, 1] + mz * verts[v, 2])
    lo = math.inf
    for v in range(vstart[sb], vstart[sb + 1]):
        lo = min(lo, nx * verts[v, 0] + ny * verts[v, 1] + nz * verts[v, 2])
    ov = sca * hi + nx * pose[9] + ny * pose[10] + nz * pose[11] - scb * lo
    return ov, nx, ny, nz, cx, cy, cz


@kernel
def _edge_ends3(s, sc, g1, g2, fstart, faces, eps):
    """The edge of body ``s`` (own frame) where faces ``g1``, ``g2`` meet.

    Returns a point on its line, the unit direction, the parameters ``lo``, ``hi`` of
    its two ends (``lo > hi``: the line misses the body, the faces do not meet in an
    edge), and for either end a bit mask of the faces through it (bit ``k``: face
    ``fstart[s] + k``, for the first 62 faces).
    """
    f0 = fstart[s]
    xx, xy, xz, ex, ey, ez = _plane_line(faces[g1, 0], faces[g1, 1], faces[g1, 2],
                                         sc * faces[g1, 3], faces[g2, 0], faces[g2, 1],
                                         faces[g2, 2], sc * faces[g2, 3])
    norm = math.sqrt(ex * ex + ey * ey + ez * ez)
    if norm == 0.0:
        return xx, xy, xz, 0.0, 0.0, 0.0, 1.0, -1.0, 0, 0
    ex, ey, ez = ex / norm, ey / norm, ez / norm
    lo, hi, mlo, mhi = -math.inf, math.inf, 0, 0
    for h in range(f0, fstart[s + 1]):
        if h == g1 or h == g2:
            continue
        den = faces[h, 0] * ex + faces[h, 1] * ey + faces[h, 2] * ez
        num = sc * faces[h, 3] - (faces[h, 0] * xx + faces[h, 1] * xy + faces[h, 2] * xz)
        bit = 1 << (h - f0) if h - f0 < 62 else 0
        if den > 1e-12:
            t = num / den
            if t < hi - eps:
                hi, mhi = t, bit
            elif t <= hi + eps:
                hi, mhi = min(hi, t), mhi | bit
        elif den < -1e-12:
            t = num / den
            if t > lo + eps:
                lo, mlo = t, bit
            elif t >= lo - eps:
                lo, mlo = max(lo, t), mlo | bit
        elif num < 0.0:
            return xx, xy, xz, ex, ey, ez, 1.0, -1.0, 0, 0
    both = 0
    if g1 - f0 < 62:
        both |= 1 << (g1 - f0)
    if g2 - f0 < 62:
        both |= 1 << (g2 - f0)
    return xx, xy, xz, ex, ey, ez, lo, hi, mlo | both, mhi | both


@kernel(inline=True)
def _pair_overlap(faces, i, j, is_a, vx, vy, vz, o1x, o1y, o1z, o2x, o2y, o2z,
                  xox, xoy, xoz):
    """Overlap along the axis of an edge at ``v`` between faces ``i``, ``j`` and the
    other body's edge (normals ``o1``, ``o2``, through ``xo``), one frame; infinite
    unless their arcs of normals cross. Also the axis and the two edge directions."""
    if is_a:
        a1x, a1y, a1z = faces[i, 0], faces[i, 1], faces[i, 2]
        a2x, a2y, a2z = faces[j, 0], faces[j, 1], faces[j, 2]
        b1x, b1y, b1z, b2x, b2y, b2z = o1x, o1y, o1z, o2x, o2y, o2z
    else:
        a1x, a1y, a1z, a2x, a2y, a2z = o1x, o1y, o1z, o2x, o2y, o2z
        b1x, b1y, b1z = faces[i, 0], faces[i, 1], faces[i, 2]
        b2x, b2y, b2z = faces[j, 0], faces[j, 1], faces[j, 2]
    # do the arcs a1-a2 and (-b1)-(-b2) of the unit sphere cross?
    ux, uy, uz = cross3(a2x, a2y, a2z, a1x, a1y, a1z)
    qx, qy, qz = cross3(b2x, b2y, b2z, b1x, b1y, b1z)
    cba = -(b1x * ux + b1y * uy + b1z * uz)
    dba = -(b2x * ux + b2y * uy + b2z * uz)
    adc = a1x * qx + a1y * qy + a1z * qz
    bdc = a2x * qx + a2y * qy + a2z * qz
    if not (cba * dba < 0.0 and adc * bdc < 0.0 and cba * bdc > 0.0):
        return math.inf, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    nx, ny, nz, eax, eay, eaz, ebx, eby, ebz = _edge_normal(
        a1x, a1y, a1z, a2x, a2y, a2z, b1x, b1y, b1z, b2x, b2y, b2z)
    if nx == 0.0 and ny == 0.0 and nz == 0.0:
        return math.inf, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    ov = nx * (vx - xox) + ny * (vy - xoy) + nz * (vz - xoz)
    return ov if is_a else -ov, nx, ny, nz, eax, eay, eaz, ebx, eby, ebz


@kernel
def _vertex_edges3(s, sc, vx, vy, vz, mask, is_a, skip1, skip2, pose, fstart, faces, eps,
                   other):
    """The least edge-edge overlap between the edges at vertex ``v`` of body ``s`` and
    one edge of the other body.

    Everything is in the body's own frame, placed in B's at ``pose``; ``is_a`` tells
    whether ``s`` is A, ``mask`` which faces pass through ``v`` (as
    :func:`_edge_ends3`; with more than 62 faces they are tested). The other edge,
    ``other = (o1, o2, xo, eo)`` (twelve scalars), has face normals ``o1``, ``o2`` and
    line ``xo + t eo``. Every pair of faces through
    ``v`` but ``(skip1, skip2)`` is tried (a pair that is no edge lies inside the
    vertex's normal cone, where ``v`` is still the extreme point: its overlap is an
    upper bound too); a pair counts when its arc of normals crosses the other edge's
    (negated for B), i.e. when the two edges are the extreme features along their cross
    product. Returns ``(overlap, nx, ny, nz, cx, cy, cz, i, j)`` in B's frame with
    ``i, j`` the pair's faces, overlap infinite if no pair counts.
    """
    o1x, o1y, o1z, o2x, o2y, o2z, xox, xoy, xoz, eox, eoy, eoz = other
    best, bi, bj = math.inf, -1, -1
    bnx, bny, bnz = 0.0, 0.0, 0.0
    eax, eay, eaz, ebx, eby, ebz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    # the other edge's great circle: a pair crosses its arc only if its two normals
    # (negated for B) lie on either side
    qx, qy, qz = cross3(o1x, o1y, o1z, o2x, o2y, o2z)
    f0, f1 = fstart[s], fstart[s + 1]
    small = f1 - f0 <= 62
    for i in range(f0, f1):
        if small:
            if not (mask >> (i - f0)) & 1:
                continue
        elif abs(faces[i, 0] * vx + faces[i, 1] * vy + faces[i, 2] * vz
                 - sc * faces[i, 3]) > eps:
            continue
        side = faces[i, 0] * qx + faces[i, 1] * qy + faces[i, 2] * qz
        later = mask >> (i + 1 - f0) if small else 0
        for j in range(i + 1, f1):
            if small:
                if later == 0:
                    break
                hit = later & 1
                later >>= 1
                if not hit:
                    continue
            elif abs(faces[j, 0] * vx + faces[j, 1] * vy + faces[j, 2] * vz
                     - sc * faces[j, 3]) > eps:
                continue
            if (i == skip1 and j == skip2) or (i == skip2 and j == skip1):
                continue
            if side * (faces[j, 0] * qx + faces[j, 1] * qy + faces[j, 2] * qz) >= 0.0:
                continue
            ov, nx, ny, nz, ax, ay, az, bx, by, bz = _pair_overlap(
                faces, i, j, is_a, vx, vy, vz, o1x, o1y, o1z, o2x, o2y, o2z, xox, xoy,
                xoz)
            if ov < best:
                best, bi, bj, bnx, bny, bnz = ov, i, j, nx, ny, nz
                eax, eay, eaz, ebx, eby, ebz = ax, ay, az, bx, by, bz
    if bi < 0:
        return math.inf, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1, -1
    if is_a:
        cx, cy, cz = _line_pair(vx, vy, vz, eax, eay, eaz, xox, xoy, xoz, eox, eoy, eoz)
    else:
        cx, cy, cz = _line_pair(xox, xoy, xoz, eox, eoy, eoz, vx, vy, vz, ebx, eby, ebz)
    nx, ny, nz = turn3(pose, bnx, bny, bnz)
    cx, cy, cz = place3(pose, cx, cy, cz)
    return best, nx, ny, nz, cx, cy, cz, bi, bj
