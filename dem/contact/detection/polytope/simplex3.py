"""3D: the programme of a polyhedron's point deepest in another, and the early exit.

:func:`_deepest3` is the simplex method of :mod:`dem.contact.detection.polytope` for
four unknowns ``(x, y, z, t)``, started at a corner of the searched body
(:func:`_corner3`); :func:`_separation3` is the cheap half of the separating-axis test
(each body's faces against the other's vertices).
"""

import math

from ...._jit import kernel
from .common import (_CROSS, _MAX_PIVOTS, _cross4, better_ratio, cross3, face_row3,
                     place3, unturn3)


@kernel
def _separation3(so, sco, si, sci, pose, vstart, verts, fstart, faces):
    """Gap (> 0) between a face plane of the outer polyhedron and all inner vertices.

    The inner body sits in the outer frame at ``R x + p``, ``pose = (R row-major, p)``.
    """
    px, py, pz = pose[9], pose[10], pose[11]
    best = -math.inf
    for f in range(fstart[so], fstart[so + 1]):
        nx, ny, nz = faces[f, 0], faces[f, 1], faces[f, 2]
        mx, my, mz = unturn3(pose, nx, ny, nz)  # the normal in the inner frame
        off = sco * faces[f, 3] - nx * px - ny * py - nz * pz
        lo = math.inf
        for v in range(vstart[si], vstart[si + 1]):
            val = sci * (mx * verts[v, 0] + my * verts[v, 1] + mz * verts[v, 2]) - off
            lo = min(lo, val)
            if lo <= 0.0:
                break
        best = max(best, lo)
        if best > 0.0:
            break
    return best


@kernel(inline=True)
def _row3(k, nfo, fo0, fi0, faces, sco, sci, pose):
    """Constraint row ``k`` (gx, gy, gz, gt, h) in the outer frame (outer faces first)."""
    if k < nfo:
        f = fo0 + k
        return faces[f, 0], faces[f, 1], faces[f, 2], -1.0, sco * faces[f, 3]
    ax, ay, az, h = face_row3(fi0 + k - nfo, sci, pose, faces)
    return ax, ay, az, 0.0, h


@kernel(inline=True)
def _corner3(si, v, fstart, faces, verts, eps):
    """Three faces of polyhedron ``si`` through vertex ``v`` spanning space best, and
    |det| of their normals (near 0: ``v`` is not a corner)."""
    g1, g2, g3 = -1, -1, -1
    x, y, z = verts[v, 0], verts[v, 1], verts[v, 2]
    best2, best3 = -1.0, -1.0
    for g in range(fstart[si], fstart[si + 1]):
        if faces[g, 0] * x + faces[g, 1] * y + faces[g, 2] * z - faces[g, 3] < -eps:
            continue
        if g1 < 0:
            g1 = g
            continue
        cx, cy, cz = cross3(faces[g1, 0], faces[g1, 1], faces[g1, 2],
                            faces[g, 0], faces[g, 1], faces[g, 2])
        w = cx * cx + cy * cy + cz * cz
        if w > best2:
            best2, g2 = w, g
    if g2 < 0:
        return g1, g2, g3, 0.0
    cx, cy, cz = cross3(faces[g1, 0], faces[g1, 1], faces[g1, 2],
                        faces[g2, 0], faces[g2, 1], faces[g2, 2])
    for g in range(fstart[si], fstart[si + 1]):
        if faces[g, 0] * x + faces[g, 1] * y + faces[g, 2] * z - faces[g, 3] < -eps:
            continue
        w = abs(cx * faces[g, 0] + cy * faces[g, 1] + cz * faces[g, 2])
        if w > best3:
            best3, g3 = w, g
    return g1, g2, g3, best3


@kernel
def _deepest3(so, sco, si, sci, pose, vstart, verts, fstart, faces, brad, tol):
    """Minimise the outer polyhedron's face function over the inner one (outer frame;
    the inner body at ``R x + p``, ``pose = (R row-major, p)``).

    Returns ``(t, x, y, z, nx, ny, nz, count, pivots, k0, k1, k2, k3, sw, swx, swy,
    swz)`` as :func:`.simplex2._deepest2`, with the rows of the final basis (outer
    faces ``0 .. nfo - 1``, then inner faces).
    """
    fo0, nfo = fstart[so], fstart[so + 1] - fstart[so]
    fi0, nfi = fstart[si], fstart[si + 1] - fstart[si]
    fmin, lo2, vb, sw, swx, swy, swz = _scan3(so, sco, si, sci, pose, vstart, verts,
                                              fstart, faces)
    k0, k1, k2, k3, zx, zy, zz, zt = _first_basis3(so, sco, si, sci, pose, vb, vstart,
                                                   verts, fstart, faces, brad)
    g0x, g0y, g0z, g0t, h0 = _row3(k0, nfo, fo0, fi0, faces, sco, sci, pose)
    g1x, g1y, g1z, g1t, h1 = _row3(k1, nfo, fo0, fi0, faces, sco, sci, pose)
    g2x, g2y, g2z, g2t, h2 = _row3(k2, nfo, fo0, fi0, faces, sco, sci, pose)
    g3x, g3y, g3z, g3t, h3 = _row3(k3, nfo, fo0, fi0, faces, sco, sci, pose)
    bland = False
    it = 0
    while True:
        c0x, c0y, c0z, c0t = _cross4(g1x, g1y, g1z, g1t, g2x, g2y, g2z, g2t,
                                     g3x, g3y, g3z, g3t)
        c1x, c1y, c1z, c1t = _cross4(g0x, g0y, g0z, g0t, g2x, g2y, g2z, g2t,
                                     g3x, g3y, g3z, g3t)
        c2x, c2y, c2z, c2t = _cross4(g0x, g0y, g0z, g0t, g1x, g1y, g1z, g1t,
                                     g3x, g3y, g3z, g3t)
        c3x, c3y, c3z, c3t = _cross4(g0x, g0y, g0z, g0t, g1x, g1y, g1z, g1t,
                                     g2x, g2y, g2z, g2t)
        e0 = g0x * c0x + g0y * c0y + g0z * c0z + g0t * c0t
        e1 = g1x * c1x + g1y * c1y + g1z * c1z + g1t * c1t
        e2 = g2x * c2x + g2y * c2y + g2z * c2z + g2t * c2t
        e3 = g3x * c3x + g3y * c3y + g3z * c3z + g3t * c3t
        if abs(e0) < 1e-14:
            break  # singular basis: cannot happen with pivots crossing by _CROSS
        w0, w1, w2, w3 = h0 / e0, h1 / e1, h2 / e2, h3 / e3
        zx = c0x * w0 + c1x * w1 + c2x * w2 + c3x * w3
        zy = c0y * w0 + c1y * w1 + c2y * w2 + c3y * w3
        zz = c0z * w0 + c1z * w1 + c2z * w2 + c3z * w3
        zt = c0t * w0 + c1t * w1 + c2t * w2 + c3t * w3
        l0, l1, l2, l3 = -c0t / e0, -c1t / e1, -c2t / e2, -c3t / e3  # multipliers
        # leaving row: most negative multiplier, or the smallest index (Bland)
        j, lj, kj = -1, -1e-12, 1 << 30
        if bland:
            if l0 < lj and k0 < kj:
                j, kj = 0, k0
            if l1 < lj and k1 < kj:
                j, kj = 1, k1
            if l2 < lj and k2 < kj:
                j, kj = 2, k2
            if l3 < lj and k3 < kj:
                j, kj = 3, k3
        else:
            if l0 < lj:
                j, lj = 0, l0
            if l1 < lj:
                j, lj = 1, l1
            if l2 < lj:
                j, lj = 2, l2
            if l3 < lj:
                j, lj = 3, l3
        if j < 0 or it >= _MAX_PIVOTS:
            break  # optimal
        it += 1
        if j == 0:
            dx, dy, dz, dt = -c0x / e0, -c0y / e0, -c0z / e0, -c0t / e0
        elif j == 1:
            dx, dy, dz, dt = -c1x / e1, -c1y / e1, -c1z / e1, -c1t / e1
        elif j == 2:
            dx, dy, dz, dt = -c2x / e2, -c2y / e2, -c2z / e2, -c2t / e2
        else:
            dx, dy, dz, dt = -c3x / e3, -c3y / e3, -c3z / e3, -c3t / e3
        kin, rmin = _entering3((k0, k1, k2, k3), nfo, nfi, fo0, fi0, faces, sco, sci, pose,
                               (zx, zy, zz, zt), (dx, dy, dz, dt), bland, tol)
        if kin < 0:
            break  # unbounded in round-off: keep the vertex
        bland = rmin * (abs(dx) + abs(dy) + abs(dz)) <= tol
        gx, gy, gz, gt, h = _row3(kin, nfo, fo0, fi0, faces, sco, sci, pose)
        if j == 0:
            k0, g0x, g0y, g0z, g0t, h0 = kin, gx, gy, gz, gt, h
        elif j == 1:
            k1, g1x, g1y, g1z, g1t, h1 = kin, gx, gy, gz, gt, h
        elif j == 2:
            k2, g2x, g2y, g2z, g2t, h2 = kin, gx, gy, gz, gt, h
        else:
            k3, g3x, g3y, g3z, g3t, h3 = kin, gx, gy, gz, gt, h
    # ties: the average of the optimal inner vertices, the sum of the maximal faces
    count = 1 if fmin <= zt + tol else 0
    if lo2 <= zt + tol:
        count, sx, sy, sz = _tied_vertices3(so, sco, si, sci, pose, vstart, verts, fstart,
                                            faces, zt + tol)
        if count > 0:
            zx, zy, zz = sx / count, sy / count, sz / count
    nx, ny, nz = _max_face_normal3(fo0, nfo, faces, sco, zx, zy, zz, zt - tol)
    return (zt, zx, zy, zz, nx, ny, nz, count, it, k0, k1, k2, k3, sw, swx, swy, swz)


@kernel(inline=True)
def _scan3(so, sco, si, sci, pose, vstart, verts, fstart, faces):
    """The first scan over the inner vertices, for :func:`_deepest3`: the least outer
    face function over them, the second least, the first's vertex, and the vertices
    inside weighted by their depth (``sw``, ``sw x``)."""
    fo0, nfo = fstart[so], fstart[so + 1] - fstart[so]
    fmin, lo2, vb = math.inf, math.inf, vstart[si]
    sw, swx, swy, swz = 0.0, 0.0, 0.0, 0.0
    for v in range(vstart[si], vstart[si + 1]):
        wx, wy, wz = place3(pose, sci * verts[v, 0], sci * verts[v, 1], sci * verts[v, 2])
        fv = -math.inf
        for f in range(fo0, fo0 + nfo):
            fv = max(fv, faces[f, 0] * wx + faces[f, 1] * wy + faces[f, 2] * wz
                     - sco * faces[f, 3])
        if fv < 0.0:
            sw -= fv
            swx -= fv * wx
            swy -= fv * wy
            swz -= fv * wz
        if fv < fmin:
            fmin, lo2, vb = fv, fmin, v
        elif fv < lo2:
            lo2 = fv
    return fmin, lo2, vb, sw, swx, swy, swz


@kernel(inline=True)
def _first_basis3(so, sco, si, sci, pose, vb, vstart, verts, fstart, faces, brad):
    """The simplex's start at inner vertex ``vb`` (or, if that is no corner, the first
    corner): the rows ``k0 .. k3`` of three inner faces through it and the outer face
    largest there, and the vertex ``(x, y, z, t)``."""
    fo0, nfo = fstart[so], fstart[so + 1] - fstart[so]
    fi0 = fstart[si]
    eps = 1e-9 * brad[si]
    ga, gb, gc, dt3 = _corner3(si, vb, fstart, faces, verts, eps)
    if dt3 < 1e-6:  # not a corner (a vertex on an edge or a face): take the first corner
        for v in range(vstart[si], vstart[si + 1]):
            ga, gb, gc, dt3 = _corner3(si, v, fstart, faces, verts, eps)
            if dt3 >= 1e-6:
                vb = v
                break
    wx, wy, wz = place3(pose, sci * verts[vb, 0], sci * verts[vb, 1], sci * verts[vb, 2])
    fv, fb = -math.inf, 0
    for k in range(nfo):
        f = fo0 + k
        val = faces[f, 0] * wx + faces[f, 1] * wy + faces[f, 2] * wz - sco * faces[f, 3]
        if val > fv:
            fv, fb = val, k
    return nfo + ga - fi0, nfo + gb - fi0, nfo + gc - fi0, fb, wx, wy, wz, fv


@kernel(inline=True)
def _entering3(basis, nfo, nfi, fo0, fi0, faces, sco, sci, pose, z, dz, bland, tol):
    """The ratio test of :func:`_deepest3`: the row that enters the ``basis`` along the
    edge ``dz`` from the vertex ``z`` (both ``(x, y, z, t)`` in the outer frame), and
    its step; ``(-1, inf)`` if none bounds the edge. Inner rows are read in the inner
    frame (``R^T``)."""
    k0, k1, k2, k3 = basis
    zx, zy, zz, zt = z
    dx, dy, dz_, dt = dz
    xin, yin, zin = unturn3(pose, zx - pose[9], zy - pose[10], zz - pose[11])
    dxin, dyin, dzin = unturn3(pose, dx, dy, dz_)
    eps = _CROSS * (abs(dx) + abs(dy) + abs(dz_) + abs(dt))
    rmin, kin, gbest = math.inf, -1, 0.0
    for k in range(nfo + nfi):
        if k == k0 or k == k1 or k == k2 or k == k3:
            continue
        if k < nfo:
            f = fo0 + k
            gd = faces[f, 0] * dx + faces[f, 1] * dy + faces[f, 2] * dz_ - dt
            if gd <= eps:
                continue
            sl = sco * faces[f, 3] - (faces[f, 0] * zx + faces[f, 1] * zy
                                      + faces[f, 2] * zz - zt)
        else:
            g = fi0 + k - nfo
            gd = faces[g, 0] * dxin + faces[g, 1] * dyin + faces[g, 2] * dzin
            if gd <= eps:
                continue
            sl = sci * faces[g, 3] - (faces[g, 0] * xin + faces[g, 1] * yin
                                      + faces[g, 2] * zin)
        rmin, kin, gbest = better_ratio(max(sl, 0.0) / gd, gd, k, rmin, kin, gbest, bland,
                                        tol)
    return kin, rmin


@kernel(inline=True)
def _tied_vertices3(so, sco, si, sci, pose, vstart, verts, fstart, faces, bound):
    """How many inner vertices have an outer face function ``<= bound``, and the sums
    of their coordinates (outer frame)."""
    count, sx, sy, sz = 0, 0.0, 0.0, 0.0
    for v in range(vstart[si], vstart[si + 1]):
        wx, wy, wz = place3(pose, sci * verts[v, 0], sci * verts[v, 1], sci * verts[v, 2])
        fv = -math.inf
        for f in range(fstart[so], fstart[so + 1]):
            fv = max(fv, faces[f, 0] * wx + faces[f, 1] * wy + faces[f, 2] * wz
                     - sco * faces[f, 3])
        if fv <= bound:
            sx += wx
            sy += wy
            sz += wz
            count += 1
    return count, sx, sy, sz


@kernel(inline=True)
def _max_face_normal3(fo0, nfo, faces, sco, zx, zy, zz, bound):
    """The normalised sum of the normals of the faces whose function at the point is
    ``>= bound``; where they cancel (opposite faces tied: the point on a medial axis),
    the normal of the first face of largest value."""
    nx, ny, nz = 0.0, 0.0, 0.0
    for f in range(fo0, fo0 + nfo):
        if (faces[f, 0] * zx + faces[f, 1] * zy + faces[f, 2] * zz - sco * faces[f, 3]
                >= bound):
            nx += faces[f, 0]
            ny += faces[f, 1]
            nz += faces[f, 2]
    norm = math.sqrt(nx * nx + ny * ny + nz * nz)
    if norm < 1e-6:
        best = -math.inf
        for f in range(fo0, fo0 + nfo):
            val = (faces[f, 0] * zx + faces[f, 1] * zy + faces[f, 2] * zz
                   - sco * faces[f, 3])
            if val > best:
                best, nx, ny, nz = val, faces[f, 0], faces[f, 1], faces[f, 2]
        norm = 1.0
    return nx / norm, ny / norm, nz / norm
