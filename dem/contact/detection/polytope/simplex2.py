"""2D: the linear programme of a polygon's point deepest in another, and the early exit.

:func:`_deepest2` is the simplex method of :mod:`dem.contact.detection.polytope` for
three unknowns ``(x, y, t)``; its first scan over the searched polygon's corners also
gathers the corners inside the other (:func:`.arcs2._arcs2`). :func:`_separation2` is
the separating-axis test over both polygons' faces, the whole test in 2D.
"""

import math

from ...._jit import kernel
from .arcs2 import _arcs2
from .common import _CROSS, _MAX_PIVOTS, better_ratio


@kernel
def _separation2(so, sco, si, sci, c, s, px, py, vstart, verts, fstart, faces):
    """Gap (> 0) between a face line of the outer polygon and all inner vertices, or <= 0.

    The inner polygon sits in the outer frame at ``R(c, s) x + (px, py)``.
    """
    best = -math.inf
    for f in range(fstart[so], fstart[so + 1]):
        nx, ny = faces[f, 0], faces[f, 1]
        mx, my = c * nx + s * ny, -s * nx + c * ny  # the normal in the inner frame
        off = sco * faces[f, 3] - nx * px - ny * py
        lo = math.inf
        for v in range(vstart[si], vstart[si + 1]):
            lo = min(lo, sci * (mx * verts[v, 0] + my * verts[v, 1]) - off)
            if lo <= 0.0:
                break
        best = max(best, lo)
        if best > 0.0:
            break
    return best


@kernel(inline=True)
def _row2(k, nfo, fo0, fi0, faces, sco, sci, c, s, px, py):
    """Constraint row ``k`` (gx, gy, gt, h) in the outer frame: outer faces, then inner."""
    if k < nfo:
        f = fo0 + k
        return faces[f, 0], faces[f, 1], -1.0, sco * faces[f, 3]
    g = fi0 + k - nfo
    ax = c * faces[g, 0] - s * faces[g, 1]
    ay = s * faces[g, 0] + c * faces[g, 1]
    return ax, ay, 0.0, sci * faces[g, 3] + ax * px + ay * py


@kernel
def _deepest2(so, sco, si, sci, c, s, px, py, vstart, verts, fstart, faces, tol):
    """Minimise the outer polygon's face function over the inner polygon (outer frame).

    Returns ``(t, x, y, nx, ny, count, pivots, sw, swx, swy, sgx, sgy, dv)``: the
    optimum, its point (the average of the optimal inner vertices when several are),
    the normalised sum of the outer normals attaining the max there, how many inner
    vertices are optimal (0: the optimum is not a vertex), and the inner corners inside
    (:func:`_arcs2`): the sums of their weights, of weight times projection and of
    weight times normal, and the deepest one's depth ``dv``.
    """
    fo0, nfo = fstart[so], fstart[so + 1] - fstart[so]
    fi0, nfi = fstart[si], fstart[si + 1] - fstart[si]
    fmin, vb, fb, lo1, lo2, sw, swx, swy, sgx, sgy, dv = _scan2(
        so, sco, si, sci, c, s, px, py, vstart, verts, fstart, faces)
    k0 = nfo + (vb - 1 if vb > 0 else nfi - 1)
    k1 = nfo + vb
    k2 = fb
    g0x, g0y, g0t, h0 = _row2(k0, nfo, fo0, fi0, faces, sco, sci, c, s, px, py)
    g1x, g1y, g1t, h1 = _row2(k1, nfo, fo0, fi0, faces, sco, sci, c, s, px, py)
    g2x, g2y, g2t, h2 = _row2(k2, nfo, fo0, fi0, faces, sco, sci, c, s, px, py)
    zx, zy, zt = 0.0, 0.0, fmin
    bland = False
    it = 0
    while True:
        # edge directions d_j = -C_j / det, C_j orthogonal to the other two rows
        c0x, c0y, c0t = g1y * g2t - g1t * g2y, g1t * g2x - g1x * g2t, g1x * g2y - g1y * g2x
        c1x, c1y, c1t = g2y * g0t - g2t * g0y, g2t * g0x - g2x * g0t, g2x * g0y - g2y * g0x
        c2x, c2y, c2t = g0y * g1t - g0t * g1y, g0t * g1x - g0x * g1t, g0x * g1y - g0y * g1x
        det = g0x * c0x + g0y * c0y + g0t * c0t
        if abs(det) < 1e-14:
            break  # singular basis: cannot happen with pivots crossing by _CROSS
        inv = 1.0 / det
        zx = (c0x * h0 + c1x * h1 + c2x * h2) * inv
        zy = (c0y * h0 + c1y * h1 + c2y * h2) * inv
        zt = (c0t * h0 + c1t * h1 + c2t * h2) * inv
        l0, l1, l2 = -c0t * inv, -c1t * inv, -c2t * inv  # multipliers
        # leaving row: most negative multiplier, or the smallest index (Bland)
        j, lj, kj = -1, -1e-12, 1 << 30
        if bland:
            if l0 < lj and k0 < kj:
                j, kj = 0, k0
            if l1 < lj and k1 < kj:
                j, kj = 1, k1
            if l2 < lj and k2 < kj:
                j, kj = 2, k2
        else:
            if l0 < lj:
                j, lj = 0, l0
            if l1 < lj:
                j, lj = 1, l1
            if l2 < lj:
                j, lj = 2, l2
        if j < 0 or it >= _MAX_PIVOTS:
            break  # optimal
        it += 1
        if j == 0:
            dx, dy, dt = -c0x * inv, -c0y * inv, -c0t * inv
        elif j == 1:
            dx, dy, dt = -c1x * inv, -c1y * inv, -c1t * inv
        else:
            dx, dy, dt = -c2x * inv, -c2y * inv, -c2t * inv
        kin, rmin = _entering2((k0, k1, k2), nfo, nfi, fo0, fi0, faces, sco, sci, c, s,
                               px, py, (zx, zy, zt), (dx, dy, dt), bland, tol)
        if kin < 0:
            break  # unbounded in round-off: keep the vertex
        bland = rmin * (abs(dx) + abs(dy)) <= tol
        gx, gy, gt, h = _row2(kin, nfo, fo0, fi0, faces, sco, sci, c, s, px, py)
        if j == 0:
            k0, g0x, g0y, g0t, h0 = kin, gx, gy, gt, h
        elif j == 1:
            k1, g1x, g1y, g1t, h1 = kin, gx, gy, gt, h
        else:
            k2, g2x, g2y, g2t, h2 = kin, gx, gy, gt, h
    # ties: the average of the optimal inner vertices, the sum of the maximal faces
    count = 1 if lo1 <= zt + tol else 0
    if lo2 <= zt + tol:
        count, sx, sy = _tied_vertices2(so, sco, si, sci, c, s, px, py, vstart, verts,
                                        fstart, faces, zt + tol)
        if count > 0:
            zx, zy = sx / count, sy / count
    nx, ny = _max_face_normal2(fo0, nfo, faces, sco, zx, zy, zt - tol)
    return zt, zx, zy, nx, ny, count, it, sw, swx, swy, sgx, sgy, dv


@kernel(inline=True)
def _scan2(so, sco, si, sci, c, s, px, py, vstart, verts, fstart, faces):
    """The first scan over the inner polygon's corners, for :func:`_deepest2`.

    Returns ``(fmin, vb, fb, lo1, lo2, sw, swx, swy, sgx, sgy, dv)``: the least outer
    face function over the corners, its corner and outer face, the two least values
    ``lo1 <= lo2`` over all vertices (for the ties), and the inner corners inside as
    :func:`_deepest2` returns them.
    """
    fo0, nfo = fstart[so], fstart[so + 1] - fstart[so]
    fi0, nfi = fstart[si], fstart[si + 1] - fstart[si]
    vi0, nvi = vstart[si], vstart[si + 1] - vstart[si]
    # start: the inner corner where the outer face function is least
    fmin, vb, fb = math.inf, 0, 0
    lo1, lo2 = math.inf, math.inf
    # the inner vertices inside, weighted by their depth w: sums of w, of w times their
    # projection onto the outer face nearest, and of w times that face's normal
    sw, swx, swy, sgx, sgy = 0.0, 0.0, 0.0, 0.0, 0.0
    vout = -1  # an inner vertex outside (where the walk over the arcs starts)
    inside = 0  # bit v: vertex v inside or on the outer boundary (v < 63)
    for v in range(nvi):
        lx, ly = sci * verts[vi0 + v, 0], sci * verts[vi0 + v, 1]
        wx, wy = c * lx - s * ly + px, s * lx + c * ly + py
        fv, fa = -math.inf, 0
        for k in range(nfo):
            val = faces[fo0 + k, 0] * wx + faces[fo0 + k, 1] * wy - sco * faces[fo0 + k, 3]
            if val > fv:
                fv, fa = val, k
        if fv > 0.0 and vout < 0:
            vout = v
        if fv <= 0.0 and v < 63:
            inside |= 1 << v
        if fv < 0.0:
            gx, gy = faces[fo0 + fa, 0], faces[fo0 + fa, 1]
            sw -= fv
            swx -= fv * (wx - fv * gx)
            swy -= fv * (wy - fv * gy)
            sgx -= fv * gx
            sgy -= fv * gy
        if fv < lo2:
            lo1, lo2 = min(fv, lo1), max(fv, lo1)
        e = v - 1 if v > 0 else nfi - 1  # the edges into and out of vertex v
        if fv < fmin and abs(faces[fi0 + e, 0] * faces[fi0 + v, 1]
                             - faces[fi0 + e, 1] * faces[fi0 + v, 0]) > 1e-9:
            fmin, vb, fb = fv, v, fa  # a corner, not a straight angle
    dv = -lo1
    if vout >= 0 and (inside != 0 or nvi > 63):  # else wholly inside: nearest faces
        sw, swx, swy, sgx, sgy, dv = _arcs2(so, sco, si, sci, c, s, px, py, vout, inside,
                                            vstart, verts, fstart, faces)
    return fmin, vb, fb, lo1, lo2, sw, swx, swy, sgx, sgy, dv


@kernel(inline=True)
def _entering2(basis, nfo, nfi, fo0, fi0, faces, sco, sci, c, s, px, py, z, dz, bland,
               tol):
    """The ratio test of :func:`_deepest2`: the row that enters the ``basis`` along the
    edge ``dz`` from the vertex ``z`` (both ``(x, y, t)`` in the outer frame), and its
    step; ``(-1, inf)`` if none bounds the edge. Inner rows are read in the inner
    frame."""
    k0, k1, k2 = basis
    zx, zy, zt = z
    dx, dy, dt = dz
    ux, uy = zx - px, zy - py
    xin, yin = c * ux + s * uy, -s * ux + c * uy
    dxin, dyin = c * dx + s * dy, -s * dx + c * dy
    eps = _CROSS * (abs(dx) + abs(dy) + abs(dt))
    rmin, kin, gbest = math.inf, -1, 0.0
    for k in range(nfo + nfi):
        if k == k0 or k == k1 or k == k2:
            continue
        if k < nfo:
            f = fo0 + k
            gd = faces[f, 0] * dx + faces[f, 1] * dy - dt
            if gd <= eps:
                continue
            sl = sco * faces[f, 3] - (faces[f, 0] * zx + faces[f, 1] * zy - zt)
        else:
            g = fi0 + k - nfo
            gd = faces[g, 0] * dxin + faces[g, 1] * dyin
            if gd <= eps:
                continue
            sl = sci * faces[g, 3] - (faces[g, 0] * xin + faces[g, 1] * yin)
        rmin, kin, gbest = better_ratio(max(sl, 0.0) / gd, gd, k, rmin, kin, gbest, bland,
                                        tol)
    return kin, rmin


@kernel(inline=True)
def _tied_vertices2(so, sco, si, sci, c, s, px, py, vstart, verts, fstart, faces, bound):
    """How many inner vertices have an outer face function ``<= bound``, and the sums
    of their coordinates (outer frame)."""
    count, sx, sy = 0, 0.0, 0.0
    for v in range(vstart[si], vstart[si + 1]):
        lx, ly = sci * verts[v, 0], sci * verts[v, 1]
        wx, wy = c * lx - s * ly + px, s * lx + c * ly + py
        fv = -math.inf
        for f in range(fstart[so], fstart[so + 1]):
            fv = max(fv, faces[f, 0] * wx + faces[f, 1] * wy - sco * faces[f, 3])
        if fv <= bound:
            sx += wx
            sy += wy
            count += 1
    return count, sx, sy


@kernel(inline=True)
def _max_face_normal2(fo0, nfo, faces, sco, zx, zy, bound):
    """The normalised sum of the normals of the faces whose function at ``(zx, zy)``
    is ``>= bound``; where they cancel (opposite faces tied: the point on a medial
    axis), the normal of the first face of largest value."""
    nx, ny = 0.0, 0.0
    for f in range(fo0, fo0 + nfo):
        if faces[f, 0] * zx + faces[f, 1] * zy - sco * faces[f, 3] >= bound:
            nx += faces[f, 0]
            ny += faces[f, 1]
    norm = math.sqrt(nx * nx + ny * ny)
    if norm < 1e-6:
        best = -math.inf
        for f in range(fo0, fo0 + nfo):
            val = faces[f, 0] * zx + faces[f, 1] * zy - sco * faces[f, 3]
            if val > best:
                best, nx, ny = val, faces[f, 0], faces[f, 1]
        norm = 1.0
    return nx / norm, ny / norm
