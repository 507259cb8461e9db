"""2D: the contact of two polygons, from the corners inside and the programmes.

Each body's corners inside the other (:mod:`.arcs2`) give one term:

* its depth ``d``, the deepest corner's (continuous as the deepest changes);
* its gradient, the depth-weighted mean of the corners' pushes, and its point, the
  depth-weighted mean of the corners moved out along them by their depths, then in by
  ``d / 2``. Both move continuously as a corner comes in (its weight starts at zero)
  and as two corners trade places as the deepest (a face tilting through flat on a
  face). One corner inside: that corner's depth and push, and the point where the force
  is the gradient of the elastic energy ``k d^2 / 2`` (the overlap is ``d`` times the
  push's length, at most 1, along it).

With corners of both bodies inside (two staggered faces on each other, or two corners
that have passed each other), the overlap is the smooth maximum ``S`` of the two depths
(:func:`.common.smooth_max`: the maximum, blended quadratically where they are within
``BLEND`` of their mean), and the force is the gradient of ``k S^2 / 2``: the two terms'
forces, weighted by ``dS/dd``, summed into one on its line of action (in the plane a
force pair always has one). The reported overlap is ``S`` times the length of that sum,
so a linear spring gives exactly that force; at a tie of two parallel faces it is ``(1 +
BLEND / 4)^2 = 1.13`` times the depth. Picking the deeper term outright instead makes
the point, the normal and the torque jump by a whole face as a body rocks through the
tie, and a pile of polygons then never comes to rest (it rattles at 1e-4 m/s; see
``tests/dem/test_shape_dynamics.py::test_polygon_pile_comes_to_rest``).

The programme still decides what the corners cannot see. Without any corner inside (two
long bodies crossing deeply) the deeper of P1 and P2 gives the overlap, the normal and
the point; and where its depth exceeds the deepest corner's (a corner pushed past the
middle of a thin body, where its nearest face and so its normal turn over) its answer
is blended in as the ratio goes from 1 to ``DEEPER`` = 1.1, so the overlap keeps
growing and the body keeps being pushed back instead of falling through (a 5,000-polygon
pour did, before). For a corner in a face the two depths are equal and the blend is
idle.
"""

import math

from ...._jit import kernel
from .common import TIE, smooth_max
from .simplex2 import _deepest2, _separation2

#: the programme's depth takes over from the corners' as its ratio to the deepest
#: corner's goes from 1 to this
DEEPER = 1.1


@kernel
def _polytope2(sa, a, sb, b, sx, sy, pos, rot, geo):
    scale, vstart, verts, fstart, faces = geo[1], geo[2], geo[3], geo[4], geo[5]
    brad = geo[8]
    sca, scb = scale[sa], scale[sb]
    tol = TIE * max(sca * brad[sa], scb * brad[sb])
    ca, sna = math.cos(rot[a, 0]), math.sin(rot[a, 0])
    cb, snb = math.cos(rot[b, 0]), math.sin(rot[b, 0])
    c, s = cb * ca + snb * sna, cb * sna - snb * ca  # A's frame in B's: angle a - b
    dx, dy = pos[a, 0] - pos[b, 0] - sx, pos[a, 1] - pos[b, 1] - sy
    px, py = cb * dx + snb * dy, -snb * dx + cb * dy
    qx, qy = -(c * px + s * py), -(-s * px + c * py)  # B's origin in A's frame
    sep = max(_separation2(sb, scb, sa, sca, c, s, px, py, vstart, verts, fstart, faces),
              _separation2(sa, sca, sb, scb, c, -s, qx, qy, vstart, verts, fstart, faces))
    if sep > 0.0:
        return -sep, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0
    t1, x1, y1, m1x, m1y, n1, i1, s1, s1x, s1y, g1x, g1y, v1 = _deepest2(
        sb, scb, sa, sca, c, s, px, py, vstart, verts, fstart, faces, tol)
    if t1 >= 0.0:
        return -t1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, i1
    t2, x2, y2, m2x, m2y, n2, i2, s2, s2x, s2y, g2x, g2y, v2 = _deepest2(
        sa, sca, sb, scb, c, -s, qx, qy, vstart, verts, fstart, faces, tol)
    # the deeper programme's answer
    d1, d2 = -t1, -t2
    if d1 > d2 + tol or (d1 >= d2 - tol and n1 >= n2):
        ov, nx, ny = d1, -(cb * m1x - snb * m1y), -(snb * m1x + cb * m1y)  # -(B's normal)
        wx = cb * x1 - snb * y1 + pos[b, 0] + sx - 0.5 * d1 * nx
        wy = snb * x1 + cb * y1 + pos[b, 1] + sy - 0.5 * d1 * ny
    else:
        ov, nx, ny = d2, ca * m2x - sna * m2y, sna * m2x + ca * m2y  # A's normal
        wx = ca * x2 - sna * y2 + pos[a, 0] + 0.5 * d2 * nx
        wy = sna * x2 + ca * y2 + pos[a, 1] + 0.5 * d2 * ny
    if s1 <= 0.0 and s2 <= 0.0:  # edges across edges, no corner inside
        return ov, nx, ny, 0.0, wx, wy, 0.0, i1 + i2
    oc, ncx, ncy, cx, cy = _corners2(ca, sna, cb, snb, sx, sy, pos, a, b,
                                     (s1, s1x, s1y, g1x, g1y, v1),
                                     (s2, s2x, s2y, g2x, g2y, v2))
    # the corners' answer, unless the bodies overlap deeper than their deepest corner
    # (long bodies crossing, a corner past a thin body's middle): then the programme's,
    # blended in as the ratio of the two depths goes from 1 to DEEPER
    vmax = max(v1, v2)
    u = 0.0 if ov <= vmax else min(1.0, (ov / vmax - 1.0) / (DEEPER - 1.0))
    if u == 0.0:
        return oc, ncx, ncy, 0.0, cx, cy, 0.0, i1 + i2
    mx, my = (1.0 - u) * ncx + u * nx, (1.0 - u) * ncy + u * ny
    norm = math.sqrt(mx * mx + my * my)
    if norm > 1e-9:  # else opposite normals cancel: keep the programme's
        nx, ny = mx / norm, my / norm
    return ((1.0 - u) * oc + u * ov, nx, ny, 0.0, (1.0 - u) * cx + u * wx,
            (1.0 - u) * cy + u * wy, 0.0, i1 + i2)


@kernel(inline=True)
def _corner_term2(sw, swx, swy, sgx, sgy, depth, co, so, ox, oy):
    """One body's corners in the other (the outer, frame ``co, so`` at ``o``): the
    point and the depth's gradient (world; along the outer body's outward normal, of
    length 1 for corners in one face).

    The gradient is the depth-weighted mean of the corners'
    (:func:`.arcs2._corner2`); the point the depth-weighted mean of the corners moved
    out along them by their depths, then in by half the deepest's. Both move
    continuously as corners come in and as the deepest changes."""
    mx, my = (swx - 0.5 * depth * sgx) / sw, (swy - 0.5 * depth * sgy) / sw
    gx, gy = sgx / sw, sgy / sw
    return (co * mx - so * my + ox, so * mx + co * my + oy, co * gx - so * gy,
            so * gx + co * gy)


@kernel(inline=True)
def _along2(depth, gx, gy, px, py):
    """One term's contact: the overlap ``depth |g|`` along ``g / |g|`` (so that a linear
    spring's force is the gradient of its energy)."""
    norm = math.sqrt(gx * gx + gy * gy)
    return depth * norm, gx / norm, gy / norm, px, py


@kernel
def _corners2(ca, sna, cb, snb, sx, sy, pos, a, b, corners1, corners2):
    """The contact from the corners inside: A's in B (``corners1 = (s1, s1x, s1y, g1x,
    g1y, v1)``, the sums of :func:`.simplex2._deepest2` in B's frame, depth ``v1``) and
    B's in A (``corners2``). One side only: its term. Both: the gradient of the elastic
    energy of the smooth maximum ``S`` of the two depths, as one force: ``(ov, nx, ny,
    cx, cy)``."""
    s1, s1x, s1y, g1x, g1y, v1 = corners1
    s2, s2x, s2y, g2x, g2y, v2 = corners2
    p1x, p1y, n1x, n1y, p2x, p2y, n2x, n2y = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if s1 > 0.0:
        p1x, p1y, n1x, n1y = _corner_term2(s1, s1x, s1y, g1x, g1y, v1, cb, snb,
                                           pos[b, 0] + sx, pos[b, 1] + sy)
        n1x, n1y = -n1x, -n1y  # from A into B
    if s2 > 0.0:
        p2x, p2y, n2x, n2y = _corner_term2(s2, s2x, s2y, g2x, g2y, v2, ca, sna,
                                           pos[a, 0], pos[a, 1])
    if s2 <= 0.0:
        return _along2(v1, n1x, n1y, p1x, p1y)
    if s1 <= 0.0:
        return _along2(v2, n2x, n2y, p2x, p2y)
    ov, w1, w2 = smooth_max(v1, v2)
    if w2 == 0.0:
        return _along2(v1, n1x, n1y, p1x, p1y)
    if w1 == 0.0:
        return _along2(v2, n2x, n2y, p2x, p2y)
    # forces w1 n1 at p1 and w2 n2 at p2 (times k S): their resultant, on its line of
    # action through the point nearest their weighted mean
    nx, ny = w1 * n1x + w2 * n2x, w1 * n1y + w2 * n2y
    norm = math.sqrt(nx * nx + ny * ny)
    wt = w1 + w2
    cx, cy = (w1 * p1x + w2 * p2x) / wt, (w1 * p1y + w2 * p2y) / wt
    torque = (w1 * ((p1x - cx) * n1y - (p1y - cy) * n1x)
              + w2 * ((p2x - cx) * n2y - (p2y - cy) * n2x))
    nx, ny = nx / norm, ny / norm
    reach = math.sqrt((p1x - p2x) ** 2 + (p1y - p2y) ** 2)  # never far from the corners
    lam = min(reach, max(-reach, -torque / norm))
    return ov * norm, nx, ny, cx - lam * ny, cy + lam * nx
