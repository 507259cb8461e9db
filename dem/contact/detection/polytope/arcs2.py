"""2D: the corners of one polygon inside another, and how deep each one is.

In 2D the answer is read from the corners that lie inside the other body (every
overlap of shallow depth has one). Walking a body's boundary, each run of corners inside
the other lies on an *arc* that enters the other body through one face and leaves
through the same or another (:func:`_arcs2`; edge crossings by Cyrus-Beck). A corner's
depth is its distance to the faces of the other body's boundary across its arc (from
where the arc leaves back to where it entered):

* one face (a corner pressed into a face, a face lying on a face): the distance to that
  face, along its normal, exactly as a nearest-face rule gives it;
* several (the arc passes the other body's corner): the smooth minimum (:func:`smooth_min`)
  of the two least distances, each divided by its face's piece of the boundary, squared,
  relative to the longest piece, so a face comes in continuously as the arc reaches it;
  the push is their normals weighted by the smooth minimum's gradient. Faces off the
  arc never count: two equal boxes stacked with their sides in line (or offset by less
  than the overlap) get their top and bottom faces' normal, where the corners' nearest
  faces are the sides;
* faces ahead, within 60 degrees of head-on along the arc's normal (its faces' normals
  weighted by their pieces' lengths to the fourth), cap it, so the depth falls to zero
  as a corner reaches the far side of a thin body.

A corner on the other body's boundary counts as inside (so exactly aligned sides take
the limit of nearly aligned ones); a body with no corner outside the other (swallowed
whole) falls back to each corner's nearest face. How the corners of both bodies make
one contact: :mod:`.contact2`.
"""

import math

from ...._jit import kernel
from .common import smooth_min


@kernel(inline=True)
def _inner2(v, sci, c, s, px, py, verts):
    """Inner vertex ``v`` in the outer frame."""
    lx, ly = sci * verts[v, 0], sci * verts[v, 1]
    return c * lx - s * ly + px, s * lx + c * ly + py


@kernel(inline=True)
def _phi2(x, y, fo0, nfo, faces, sco):
    """The outer polygon's face function ``max_f (n_f . x - o_f)`` at ``(x, y)``."""
    fv = -math.inf
    for k in range(fo0, fo0 + nfo):
        fv = max(fv, faces[k, 0] * x + faces[k, 1] * y - sco * faces[k, 3])
    return fv


@kernel(inline=True)
def _crossing2(ax, ay, bx, by, fo0, nfo, faces, sco, entering):
    """Where the inner edge ``a -> b`` crosses the outer boundary, and the face it
    crosses: entering (``a`` outside, ``b`` inside) the last face it passes into,
    leaving the first face it passes out of (Cyrus-Beck)."""
    dx, dy = bx - ax, by - ay
    best, fb = (-math.inf if entering else math.inf), 0
    for k in range(nfo):
        nx, ny = faces[fo0 + k, 0], faces[fo0 + k, 1]
        den = nx * dx + ny * dy
        if (den < 0.0) if entering else (den > 0.0):
            t = (sco * faces[fo0 + k, 3] - nx * ax - ny * ay) / den
            if (t > best) if entering else (t < best):
                best, fb = t, k
    t = min(1.0, max(0.0, best))
    return ax + t * dx, ay + t * dy, fb


@kernel(inline=True)
def _piece2(k, ef, ex, ey, vo0, nfo, sco, verts):
    """Where face ``k``'s piece of an arc's outer boundary ends: its end vertex, or the
    entry ``e`` on face ``ef``; and the next face."""
    j = k + 1 if k + 1 < nfo else 0
    if k == ef:
        return ex, ey, j
    return sco * verts[vo0 + j, 0], sco * verts[vo0 + j, 1], j


@kernel
def _support2(so, sco, ex, ey, ef, xx, xy, xf, vstart, verts, fstart, faces):
    """The outer boundary from an arc's exit ``x`` (on face ``xf``) counter-clockwise
    back to its entry ``e`` (face ``ef``): its outward normal ``g`` (its faces' normals
    weighted by their pieces' lengths to the fourth), which says which faces lie ahead
    of its corners, and the largest length to the fourth (0 for one face, whose normal
    it returns exactly)."""
    fo0, nfo, vo0 = fstart[so], fstart[so + 1] - fstart[so], vstart[so]
    if xf == ef and (faces[fo0 + ef, 0] * (ey - xy) - faces[fo0 + ef, 1] * (ex - xx)
                     >= 0.0):
        return faces[fo0 + ef, 0], faces[fo0 + ef, 1], 0.0
    gx, gy, l4max = 0.0, 0.0, 0.0
    ax, ay, k = xx, xy, xf
    for _ in range(nfo + 1):
        bx, by, j = _piece2(k, ef, ex, ey, vo0, nfo, sco, verts)
        l2 = (bx - ax) ** 2 + (by - ay) ** 2
        gx += l2 * l2 * faces[fo0 + k, 0]
        gy += l2 * l2 * faces[fo0 + k, 1]
        l4max = max(l4max, l2 * l2)
        if k == ef:
            break
        ax, ay, k = bx, by, j
    norm = math.sqrt(gx * gx + gy * gy)
    if norm < 1e-300:  # a zero-length arc (a corner just touching): its face
        return faces[fo0 + ef, 0], faces[fo0 + ef, 1], 0.0
    return gx / norm, gy / norm, l4max


@kernel(inline=True)
def _least2(e, vx, vy, e1, v1x, v1y, e2, v2x, v2y):
    """Keep the two least candidates ``e1 <= e2`` (with their vectors)."""
    if e < e1:
        return e, vx, vy, e1, v1x, v1y
    if e < e2:
        return e1, v1x, v1y, e, vx, vy
    return e1, v1x, v1y, e2, v2x, v2y


@kernel
def _corner2(cx, cy, gx, gy, so, sco, ex, ey, ef, xx, xy, xf, l4max, vstart, verts,
             fstart, faces):
    """A corner inside the outer polygon: ``(d, Gx, Gy)``, its depth and the direction
    that pushes it out (module notes).

    Its distances to the faces of its arc's outer boundary, each divided by its
    piece's length squared relative to the longest (a face comes in as the arc reaches
    it): ``d`` is the smooth minimum of the two least, ``G`` the sum of their normals
    weighted by the smooth minimum's gradient (the depth's gradient where the divisors
    are 1; never longer than 1). One face:
    its distance and its normal, exactly. Then the faces ahead (within 60 degrees of
    head-on along ``-g``, the distance divided by how nearly head-on) cap it, so the
    depth falls to zero as the corner reaches the far side of a thin body: there ``G``
    is that face's normal, as the nearest-face rule has it."""
    fo0, nfo, vo0 = fstart[so], fstart[so + 1] - fstart[so], vstart[so]
    e1, v1x, v1y, e2, v2x, v2y = math.inf, 0.0, 0.0, math.inf, 0.0, 0.0
    if l4max > 0.0:
        ax, ay, k = xx, xy, xf
        for _ in range(nfo + 1):
            bx, by, j = _piece2(k, ef, ex, ey, vo0, nfo, sco, verts)
            l2 = (bx - ax) ** 2 + (by - ay) ** 2
            if l2 > 0.0:
                f, lam = fo0 + k, l2 / math.sqrt(l4max)
                e = (sco * faces[f, 3] - (faces[f, 0] * cx + faces[f, 1] * cy)) / lam
                e1, v1x, v1y, e2, v2x, v2y = _least2(e, faces[f, 0], faces[f, 1], e1,
                                                     v1x, v1y, e2, v2x, v2y)
            if k == ef:
                break
            ax, ay, k = bx, by, j
    else:  # one face: its row, the same distance as the nearest-face rule's
        e1 = sco * faces[fo0 + ef, 3] - (faces[fo0 + ef, 0] * cx + faces[fo0 + ef, 1] * cy)
        v1x, v1y = faces[fo0 + ef, 0], faces[fo0 + ef, 1]
    d, s1, s2 = e1, 1.0, 0.0
    if e2 < math.inf:
        d, s1, s2 = smooth_min(e1, e2)
    hx, hy = s1 * v1x + s2 * v2x, s1 * v1y + s2 * v2y
    for f in range(fo0, fo0 + nfo):  # the faces ahead: the plain minimum
        head = -1.0 - 2.0 * (faces[f, 0] * gx + faces[f, 1] * gy)
        if head > 0.0:
            e = (sco * faces[f, 3] - (faces[f, 0] * cx + faces[f, 1] * cy)) / head
            if e < d:
                d, hx, hy = e, faces[f, 0], faces[f, 1]
    return d, hx, hy


@kernel
def _arcs2(so, sco, si, sci, c, s, px, py, vout, inside, vstart, verts, fstart, faces):
    """The inner polygon's corners inside the outer, arc by arc (module notes):
    ``(sw, swx, swy, sgx, sgy, dv)``, the sums of their weights ``w``, of ``w`` times
    their projections onto their arc's supporting line and of ``w`` times its outward
    normal, and the largest weight (the term's depth). ``vout`` is an inner vertex
    outside; bit ``v`` of ``inside`` says vertex ``v`` (< 63) is not."""
    fo0, nfo = fstart[so], fstart[so + 1] - fstart[so]
    vi0, nvi = vstart[si], vstart[si + 1] - vstart[si]
    sw, swx, swy, sgx, sgy, dv = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    inarc, first, ex, ey, ef = False, 0, 0.0, 0.0, 0
    v = vout
    x0, y0 = _inner2(vi0 + v, sci, c, s, px, py, verts)
    for _ in range(nvi):
        q = v + 1 if v + 1 < nvi else 0
        x1, y1 = _inner2(vi0 + q, sci, c, s, px, py, verts)
        if q < 63:
            qin = (inside >> q) & 1 == 1
        else:
            qin = _phi2(x1, y1, fo0, nfo, faces, sco) <= 0.0
        if not inarc and qin:
            ex, ey, ef = _crossing2(x0, y0, x1, y1, fo0, nfo, faces, sco, True)
            inarc, first = True, q
        elif inarc and not qin:
            xx, xy, xf = _crossing2(x0, y0, x1, y1, fo0, nfo, faces, sco, False)
            gx, gy, l4max = _support2(so, sco, ex, ey, ef, xx, xy, xf, vstart, verts,
                                      fstart, faces)
            k = first
            for _ in range(nvi):  # the arc's corners, first .. v
                cx, cy = _inner2(vi0 + k, sci, c, s, px, py, verts)
                d, hx, hy = _corner2(cx, cy, gx, gy, so, sco, ex, ey, ef, xx, xy, xf,
                                     l4max, vstart, verts, fstart, faces)
                w = max(0.0, d)
                sw += w
                swx += w * (cx + w * hx)
                swy += w * (cy + w * hy)
                sgx += w * hx
                sgy += w * hy
                dv = max(dv, w)
                if k == v:
                    break
                k = k + 1 if k + 1 < nvi else 0
            inarc = False
        v, x0, y0 = q, x1, y1
    return sw, swx, swy, sgx, sgy, dv
