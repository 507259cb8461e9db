"""Exact contact of two convex polytopes, and of a polytope with a wall.

Polygons (2D), polyhedra (3D) and boxes (whose table rows carry vertices and faces
too) are polytopes. Inside a polytope ``B`` with faces ``n_f . x <= o_f`` the signed
distance is exactly ``phi_B(x) = max_f (n_f . x - o_f)``, so problem P1 of
:mod:`dem.contact.detection` (A's point deepest in B) is the linear programme

    minimise t  subject to  n_f . x - t <= o_f  (B's faces),  a_g . x <= c_g  (A's faces)

in the ``d + 1`` unknowns ``(x, t)``, and P2 is the same with the bodies' roles
swapped. When the optimum ``t*`` is negative the point lies inside ``B``, where the max
of the face functions *is* the signed distance, so ``d1 = -t*`` exactly; when ``t* >=
0`` the bodies do not overlap (the max of the face functions is a lower bound of the
distance outside) and the pair is reported separated.

Solver
------
A primal simplex (active-set) method on the vertices of the feasible region, written
out for 3 (2D) and 4 (3D) unknowns with the basis held in scalars:

* it starts at a corner of the searched body: the vertex ``v`` where the other body's
  face function is least, its ``d`` faces and the other body's face attaining the max
  there. A corner pressed into a face is therefore optimal at once (no pivot);
* at a basis of ``d + 1`` active rows ``g_j`` the edge directions are the generalised
  cross products of the other rows (``-C_j / (g_j . C_j)``), the vertex is
  ``sum_j h_j C_j / (g_j . C_j)`` (Cramer: recomputed from the basis, so it does not
  drift), and the multiplier of row ``j`` is the ``t`` component of its edge direction;
* pivots pick the most negative multiplier; after a degenerate pivot (zero step, common
  when faces of both bodies meet at one point) Bland's smallest-index rule is used,
  which rules out cycling. The ratio test prefers, among ties, the row most across the
  edge (the best conditioned basis).

Before either programme, the cheap half of the separating-axis test (each body's faces
against the other's vertices) returns separated pairs early; in 2D it is the whole test.

Ties
----
Ties are decided within ``TIE`` times the larger body size (bounding radius times
scale):

* when several vertices of the searched body are optimal (a face or an edge lying flat
  in the other body), the normal is read at their average, which is optimal too (the
  optimal set is convex);
* the normal is the normalised sum of the outward normals of the faces attaining the
  max at the point (the subgradient of the SDF where two faces are equally deep);
* when ``d1`` and ``d2`` tie (a face on a face), the problem with more optimal vertices
  is used, then P1 (3D; in 2D see the corners below).

Corners inside (2D)
-------------------
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
whole) falls back to each corner's nearest face.

Each body's corners inside the other give one term:

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
(:func:`smooth_max`: the maximum, blended quadratically where they are within ``BLEND``
of their mean), and the force is the gradient of ``k S^2 / 2``: the two terms' forces,
weighted by ``dS/dd``, summed into one on its line of action (in the plane a force pair
always has one). The reported overlap is ``S`` times the length of that sum, so a linear
spring gives exactly that force; at a tie of two parallel faces it is ``(1 + BLEND /
4)^2 = 1.13`` times the depth. Picking the deeper term outright instead makes the point,
the normal and the torque jump by a whole face as a body rocks through the tie, and a
pile of polygons then never comes to rest (it rattles at 1e-4 m/s; see
``tests/dem/test_shape_dynamics.py::test_polygon_pile_comes_to_rest``).

The programme still decides what the corners cannot see. Without any corner inside (two
long bodies crossing deeply) the deeper of P1 and P2 gives the overlap, the normal and
the point; and where its depth exceeds the deepest corner's (a corner pushed past the
middle of a thin body, where its nearest face and so its normal turn over) its answer
is blended in as the ratio goes from 1 to ``DEEPER`` = 1.1, so the overlap keeps
growing and the body keeps being pushed back instead of falling through (a 5,000-polygon
pour did, before). For a corner in a face the two depths are equal and the blend is
idle.

Contact point of a vertex on a face (3D)
----------------------------------------
When the deeper optimum is a vertex, the point lies ``ov / 2`` in front of the mean of
the searched body's vertices that lie inside the other, each weighted by its depth
there (``-phi``, free from the programme's first scan), moved along the normal to the
deepest vertex's level. One vertex inside: that vertex, the contract's point. Several (a
face or an edge lying nearly flat on a face): the point, and so the torque, moves
continuously as the face tilts.

Patches (3D)
------------
Faces lying on faces and edges lying on faces make *patches*, where many features are
nearly equally deep: both bodies' corners, and edges crossing edges whose separating
axes all lie within the faces' small angle of their normal. The rules above then jump
the point across the patch as the deepest feature changes (a face tilting through
parallel, two twisted squares' edge crossings trading places as the least separating
axis), with the normal and the overlap nearly unchanged: a torque that flips each step,
and a packing of cubes that never came to rest (unbalanced-force ratio 0.04 after
60,000 steps, each contact's point jumping by the cube's size every other step). So the
point is moved, within the contact plane (its level along the normal kept), towards the
centroid of the bodies' intersection (:func:`overlap_centroid3`: each body's boundary
triangles clipped by the other's faces, summed by the divergence theorem), with the
weight going smoothly from 0 to 1 as ``q = sqrt(V / ov^3)`` goes from ``PATCH_FROM`` =
3 to ``PATCH_TO`` = 6 (an edge on a face at an overlap of 1 % of its length, q = 10, is a
patch). ``q`` is about 1 for a cube's corner or a cube's edge across an
edge, 1 to 10 for the blunter vertices of random polyhedra, ``sqrt(L / ov)`` for an edge
of length ``L`` lying on a face and ``L / ov`` for faces on faces (a few hundred in a
packing), and the intersection's volume and centroid are continuous in the pose. Where
the weight is 0 the point is the rule's, so the force stays the gradient of ``kn ov^2 /
2`` there; on a patch the torque comes from the centroid instead (a face pressed on a
face has none to speak of). The cost is the clipping, only of triangles in the contact's
slab: from 1.1 to 3.0 µs per box pair (docs/performance.md, Figure 3).

Edge across edge (3D)
---------------------
When the deeper problem's optimum (after the ties above) is *not a vertex* of the
searched body it lies on a crease of the other body, where its SDF has no gradient and
the contract's answer is not the gradient of any function of the pose. Such pairs get
the separating-axis contact of :mod:`dem.contact.detection.sat` (the penetration depth,
along an edge pair's cross product or a face normal), started from the edge pairs of
both programmes' final bases (:func:`_crease_rows`): the limit of P1/P2 there, and
conservative. When a face wins, the point is placed as for a vertex on a face.

Limitations: in 2D the point of a face-on-face contact is a weighted mean of corners,
not the centroid of the overlap region. In 3D each vertex's depth is its nearest face's
(the 2D arcs have no 3D counterpart), and the overlap and normal of a patch are its
deepest feature's. In 2D, while a short piece's face (divisor below 1) decides a corner's
depth, the push ignores how the divisor changes, so there the force is not quite a
gradient.
Shapes must be convex with outward unit face normals, as the shape table stores them.
"""

import math

import numpy as np

from ..._jit import kernel
from ...rotation import to_body, to_world
from .sat import cross3, face_row3, sat_contact3

#: relative tolerance of ties (equal depths, equally deep faces or vertices)
TIE = 1e-12
#: a pivot row must cross the edge direction by more than this (relative to |d|)
_CROSS = 1e-12
_MAX_PIVOTS = 100
#: width of the smooth maximum of two bodies' corner depths, relative to their mean
BLEND = 0.25
#: the programme's depth takes over from the corners' as its ratio to the deepest
#: corner's goes from 1 to this
DEEPER = 1.1
#: 3D: the point moves to the intersection's centroid as ``sqrt(V / ov^3)`` goes from
#: PATCH_FROM to PATCH_TO (a cube's corner in a face: about 1; faces on faces: hundreds)
PATCH_FROM = 3.0
PATCH_TO = 6.0


@kernel(inline=True)
def _matrix3(rot, b):
    """Body ``b``'s rotation matrix (body to world), row-major, from its quaternion."""
    r00, r10, r20 = to_world(3, rot, b, 1.0, 0.0, 0.0)
    r01, r11, r21 = to_world(3, rot, b, 0.0, 1.0, 0.0)
    r02, r12, r22 = to_world(3, rot, b, 0.0, 0.0, 1.0)
    return r00, r01, r02, r10, r11, r12, r20, r21, r22


@kernel(inline=True)
def _cross4(a0, a1, a2, a3, b0, b1, b2, b3, c0, c1, c2, c3):
    """The vector ``e`` with ``e . u = det[u; a; b; c]``: orthogonal to a, b and c."""
    m01 = b0 * c1 - b1 * c0
    m02 = b0 * c2 - b2 * c0
    m03 = b0 * c3 - b3 * c0
    m12 = b1 * c2 - b2 * c1
    m13 = b1 * c3 - b3 * c1
    m23 = b2 * c3 - b3 * c2
    return (a1 * m23 - a2 * m13 + a3 * m12, -(a0 * m23 - a2 * m03 + a3 * m02),
            a0 * m13 - a1 * m03 + a3 * m01, -(a0 * m12 - a1 * m02 + a2 * m01))


# --------------------------------------------------------------------------- 2D
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
    vi0, nvi = vstart[si], vstart[si + 1] - vstart[si]
    # start: the inner corner where the outer face function is least; lo1 <= lo2 are
    # the two least values over all vertices (for the ties below)
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
        # ratio test; inner rows are read in the inner frame
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
            r = max(sl, 0.0) / gd
            if r < rmin - tol:
                rmin, kin, gbest = r, k, gd
            elif r <= rmin + tol and not bland and gd > gbest:
                rmin, kin, gbest = min(r, rmin), k, gd
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
        count = 0
        sx, sy = 0.0, 0.0
        for v in range(vi0, vi0 + nvi):
            lx, ly = sci * verts[v, 0], sci * verts[v, 1]
            wx, wy = c * lx - s * ly + px, s * lx + c * ly + py
            fv = -math.inf
            for f in range(fo0, fo0 + nfo):
                fv = max(fv, faces[f, 0] * wx + faces[f, 1] * wy - sco * faces[f, 3])
            if fv <= zt + tol:
                sx += wx
                sy += wy
                count += 1
        if count > 0:
            zx, zy = sx / count, sy / count
    nx, ny = 0.0, 0.0
    for f in range(fo0, fo0 + nfo):
        if faces[f, 0] * zx + faces[f, 1] * zy - sco * faces[f, 3] >= zt - tol:
            nx += faces[f, 0]
            ny += faces[f, 1]
    norm = math.sqrt(nx * nx + ny * ny)
    if norm < 1e-6:  # opposite faces tied (the point on a medial axis): the first
        best = -math.inf
        for f in range(fo0, fo0 + nfo):
            val = faces[f, 0] * zx + faces[f, 1] * zy - sco * faces[f, 3]
            if val > best:
                best, nx, ny = val, faces[f, 0], faces[f, 1]
        norm = 1.0
    return zt, zx, zy, nx / norm, ny / norm, count, it, sw, swx, swy, sgx, sgy, dv


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
    oc, ncx, ncy, cx, cy = _corners2(ca, sna, cb, snb, sx, sy, pos, a, b, s1, s1x, s1y,
                                     g1x, g1y, v1, s2, s2x, s2y, g2x, g2y, v2)
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

    The gradient is the depth-weighted mean of the corners' (:func:`_corner2`); the
    point the depth-weighted mean of the corners moved out along them by their depths,
    then in by half the deepest's. Both move continuously as corners come in and as
    the deepest changes."""
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
def _corners2(ca, sna, cb, snb, sx, sy, pos, a, b, s1, s1x, s1y, g1x, g1y, v1,
              s2, s2x, s2y, g2x, g2y, v2):
    """The contact from the corners inside: A's in B (depth ``v1``, sums in B's frame)
    and B's in A. One side only: its term. Both: the gradient of the elastic energy of
    the smooth maximum ``S`` of the two depths, as one force: ``(ov, nx, ny, cx, cy)``."""
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


@kernel(inline=True)
def smooth_max(d1, d2):
    """``(S, dS/dd1, dS/dd2)``: a C1 maximum of two depths.

    ``S = max`` where ``|d1 - d2| >= h``, ``h = BLEND (d1 + d2) / 2``; within, the
    quadratic blend ``m + h / 4 + (d1 - d2)^2 / (4 h)`` (``m`` the mean), at most
    ``BLEND / 4`` of the depth above the maximum (at a tie, where the gradient's
    components sum to ``1 + BLEND / 4``). Homogeneous of degree one, so it is a
    function of the depths alone and its gradient a force field.
    """
    m = 0.5 * (d1 + d2)
    h = BLEND * m
    x = d1 - d2
    if h <= 0.0 or x >= h:
        return d1, 1.0, 0.0
    if -x >= h:
        return d2, 0.0, 1.0
    q = BLEND * x * x / (8.0 * h * h)
    return (m + 0.25 * h + x * x / (4.0 * h), 0.5 + BLEND / 8.0 + x / (2.0 * h) - q,
            0.5 + BLEND / 8.0 - x / (2.0 * h) - q)


@kernel(inline=True)
def smooth_min(d1, d2):
    """``(S, dS/dd1, dS/dd2)``: the C1 minimum of two depths matching :func:`smooth_max`
    (``S = d1 + d2 - smooth_max``), the minimum itself, exactly, where they are further
    apart than ``h``."""
    h = BLEND * 0.5 * (d1 + d2)
    if h <= 0.0 or d2 - d1 >= h:
        return d1, 1.0, 0.0
    if d1 - d2 >= h:
        return d2, 0.0, 1.0
    s, w1, w2 = smooth_max(d1, d2)
    return d1 + d2 - s, 1.0 - w1, 1.0 - w2


# --------------------------------------------------------------------------- 3D
@kernel
def _separation3(so, sco, si, sci, r00, r01, r02, r10, r11, r12, r20, r21, r22,
                 px, py, pz, vstart, verts, fstart, faces):
    """Gap (> 0) between a face plane of the outer polyhedron and all inner vertices.

    The inner body sits in the outer frame at ``R x + p``.
    """
    best = -math.inf
    for f in range(fstart[so], fstart[so + 1]):
        nx, ny, nz = faces[f, 0], faces[f, 1], faces[f, 2]
        mx = r00 * nx + r10 * ny + r20 * nz  # R^T n: the normal in the inner frame
        my = r01 * nx + r11 * ny + r21 * nz
        mz = r02 * nx + r12 * ny + r22 * nz
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
def _row3(k, nfo, fo0, fi0, faces, sco, sci, r00, r01, r02, r10, r11, r12, r20, r21, r22,
          px, py, pz):
    """Constraint row ``k`` (gx, gy, gz, gt, h) in the outer frame (outer faces first)."""
    if k < nfo:
        f = fo0 + k
        return faces[f, 0], faces[f, 1], faces[f, 2], -1.0, sco * faces[f, 3]
    ax, ay, az, h = face_row3(fi0 + k - nfo, sci, r00, r01, r02, r10, r11, r12, r20, r21,
                              r22, px, py, pz, faces)
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
def _deepest3(so, sco, si, sci, r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz,
              vstart, verts, fstart, faces, brad, tol):
    """Minimise the outer polyhedron's face function over the inner one (outer frame).

    Returns ``(t, x, y, z, nx, ny, nz, count, pivots, k0, k1, k2, k3, sw, swx, swy,
    swz)`` as :func:`_deepest2`, with the rows of the final basis (outer faces ``0 ..
    nfo - 1``, then inner faces).
    """
    fo0, nfo = fstart[so], fstart[so + 1] - fstart[so]
    fi0, nfi = fstart[si], fstart[si + 1] - fstart[si]
    vi0, nvi = vstart[si], vstart[si + 1] - vstart[si]
    # start: the inner vertex where the outer face function is least
    fmin, lo2, vb = math.inf, math.inf, vi0  # the two least values, the first's vertex
    sw, swx, swy, swz = 0.0, 0.0, 0.0, 0.0  # the inner vertices inside, weighted by depth
    for v in range(vi0, vi0 + nvi):
        lx, ly, lz = sci * verts[v, 0], sci * verts[v, 1], sci * verts[v, 2]
        wx = r00 * lx + r01 * ly + r02 * lz + px
        wy = r10 * lx + r11 * ly + r12 * lz + py
        wz = r20 * lx + r21 * ly + r22 * lz + pz
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
    eps = 1e-9 * brad[si]
    ga, gb, gc, dt3 = _corner3(si, vb, fstart, faces, verts, eps)
    if dt3 < 1e-6:  # not a corner (a vertex on an edge or a face): take the first corner
        for v in range(vi0, vi0 + nvi):
            ga, gb, gc, dt3 = _corner3(si, v, fstart, faces, verts, eps)
            if dt3 >= 1e-6:
                vb = v
                break
    lx, ly, lz = sci * verts[vb, 0], sci * verts[vb, 1], sci * verts[vb, 2]
    wx = r00 * lx + r01 * ly + r02 * lz + px
    wy = r10 * lx + r11 * ly + r12 * lz + py
    wz = r20 * lx + r21 * ly + r22 * lz + pz
    fv, fb = -math.inf, 0
    for k in range(nfo):
        f = fo0 + k
        val = faces[f, 0] * wx + faces[f, 1] * wy + faces[f, 2] * wz - sco * faces[f, 3]
        if val > fv:
            fv, fb = val, k
    k0, k1, k2, k3 = nfo + ga - fi0, nfo + gb - fi0, nfo + gc - fi0, fb
    g0x, g0y, g0z, g0t, h0 = _row3(k0, nfo, fo0, fi0, faces, sco, sci, r00, r01, r02, r10,
                                   r11, r12, r20, r21, r22, px, py, pz)
    g1x, g1y, g1z, g1t, h1 = _row3(k1, nfo, fo0, fi0, faces, sco, sci, r00, r01, r02, r10,
                                   r11, r12, r20, r21, r22, px, py, pz)
    g2x, g2y, g2z, g2t, h2 = _row3(k2, nfo, fo0, fi0, faces, sco, sci, r00, r01, r02, r10,
                                   r11, r12, r20, r21, r22, px, py, pz)
    g3x, g3y, g3z, g3t, h3 = _row3(k3, nfo, fo0, fi0, faces, sco, sci, r00, r01, r02, r10,
                                   r11, r12, r20, r21, r22, px, py, pz)
    zx, zy, zz, zt = wx, wy, wz, fv
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
        # ratio test; inner rows are read in the inner frame (R^T)
        ux, uy, uz = zx - px, zy - py, zz - pz
        xin = r00 * ux + r10 * uy + r20 * uz
        yin = r01 * ux + r11 * uy + r21 * uz
        zin = r02 * ux + r12 * uy + r22 * uz
        dxin = r00 * dx + r10 * dy + r20 * dz
        dyin = r01 * dx + r11 * dy + r21 * dz
        dzin = r02 * dx + r12 * dy + r22 * dz
        eps = _CROSS * (abs(dx) + abs(dy) + abs(dz) + abs(dt))
        rmin, kin, gbest = math.inf, -1, 0.0
        for k in range(nfo + nfi):
            if k == k0 or k == k1 or k == k2 or k == k3:
                continue
            if k < nfo:
                f = fo0 + k
                gd = faces[f, 0] * dx + faces[f, 1] * dy + faces[f, 2] * dz - dt
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
            r = max(sl, 0.0) / gd
            if r < rmin - tol:
                rmin, kin, gbest = r, k, gd
            elif r <= rmin + tol and not bland and gd > gbest:
                rmin, kin, gbest = min(r, rmin), k, gd
        if kin < 0:
            break  # unbounded in round-off: keep the vertex
        bland = rmin * (abs(dx) + abs(dy) + abs(dz)) <= tol
        gx, gy, gz, gt, h = _row3(kin, nfo, fo0, fi0, faces, sco, sci, r00, r01, r02, r10,
                                  r11, r12, r20, r21, r22, px, py, pz)
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
        count = 0
        sx, sy, sz = 0.0, 0.0, 0.0
        for v in range(vi0, vi0 + nvi):
            lx, ly, lz = sci * verts[v, 0], sci * verts[v, 1], sci * verts[v, 2]
            wx = r00 * lx + r01 * ly + r02 * lz + px
            wy = r10 * lx + r11 * ly + r12 * lz + py
            wz = r20 * lx + r21 * ly + r22 * lz + pz
            fv = -math.inf
            for f in range(fo0, fo0 + nfo):
                fv = max(fv, faces[f, 0] * wx + faces[f, 1] * wy + faces[f, 2] * wz
                         - sco * faces[f, 3])
            if fv <= zt + tol:
                sx += wx
                sy += wy
                sz += wz
                count += 1
        if count > 0:
            zx, zy, zz = sx / count, sy / count, sz / count
    nx, ny, nz = 0.0, 0.0, 0.0
    for f in range(fo0, fo0 + nfo):
        if (faces[f, 0] * zx + faces[f, 1] * zy + faces[f, 2] * zz - sco * faces[f, 3]
                >= zt - tol):
            nx += faces[f, 0]
            ny += faces[f, 1]
            nz += faces[f, 2]
    norm = math.sqrt(nx * nx + ny * ny + nz * nz)
    if norm < 1e-6:  # opposite faces tied (the point on a medial axis): the first
        best = -math.inf
        for f in range(fo0, fo0 + nfo):
            val = (faces[f, 0] * zx + faces[f, 1] * zy + faces[f, 2] * zz
                   - sco * faces[f, 3])
            if val > best:
                best, nx, ny, nz = val, faces[f, 0], faces[f, 1], faces[f, 2]
        norm = 1.0
    return (zt, zx, zy, zz, nx / norm, ny / norm, nz / norm, count, it,
            k0, k1, k2, k3, sw, swx, swy, swz)


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
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = _matrix3(rot, a)
    b00, b01, b02, b10, b11, b12, b20, b21, b22 = _matrix3(rot, b)
    vol, ex, ey, ez = overlap_centroid3(
        sa, scale[sa], a00, a01, a02, a10, a11, a12, a20, a21, a22, pos[a, 0] - cx,
        pos[a, 1] - cy, pos[a, 2] - cz, sb, scale[sb], b00, b01, b02, b10, b11, b12, b20,
        b21, b22, pos[b, 0] + sx - cx, pos[b, 1] + sy - cy, pos[b, 2] + sz - cz, nx, ny,
        nz, ov, geo)  # within ov / 2 of the point along n (twice that, for safety)
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
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = _matrix3(rot, a)
    b00, b01, b02, b10, b11, b12, b20, b21, b22 = _matrix3(rot, b)
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
    sep = max(_separation3(sb, scb, sa, sca, r00, r01, r02, r10, r11, r12, r20, r21, r22,
                           px, py, pz, vstart, verts, fstart, faces),
              _separation3(sa, sca, sb, scb, r00, r10, r20, r01, r11, r21, r02, r12, r22,
                           qx, qy, qz, vstart, verts, fstart, faces))
    if sep > 0.0:
        return -sep, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0
    (t1, x1, y1, z1, m1x, m1y, m1z, n1, i1, k10, k11, k12, k13, s1, s1x, s1y,
     s1z) = _deepest3(
        sb, scb, sa, sca, r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz,
        vstart, verts, fstart, faces, brad, tol)
    if t1 >= 0.0:
        return -t1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, i1
    (t2, x2, y2, z2, m2x, m2y, m2z, n2, i2, k20, k21, k22, k23, s2, s2x, s2y,
     s2z) = _deepest3(
        sa, sca, sb, scb, r00, r10, r20, r01, r11, r21, r02, r12, r22, qx, qy, qz,
        vstart, verts, fstart, faces, brad, tol)
    d1, d2 = -t1, -t2
    use1 = d1 > d2 + tol or (d1 >= d2 - tol and n1 >= n2)
    if (n1 if use1 else n2) == 0:  # not a vertex: the separating-axis test decides
        fa0, nfa = fstart[sa], fstart[sa + 1] - fstart[sa]
        fb0, nfb = fstart[sb], fstart[sb + 1] - fstart[sb]
        ga1, ga2, fb1, fb2 = _crease_rows(k10, k11, k12, k13, nfb, fb0, fa0)
        fb3, fb4, ga3, ga4 = _crease_rows(k20, k21, k22, k23, nfa, fa0, fb0)
        kind, ov, mx, my, mz, cx, cy, cz = sat_contact3(
            sa, sca, sb, scb, r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz,
            qx, qy, qz, vstart, verts, fstart, faces, brad, ga1, ga2, fb1, fb2, ga3, ga4,
            fb3, fb4)
        if kind == 2:  # an edge on an edge
            nx = b00 * mx + b01 * my + b02 * mz
            ny = b10 * mx + b11 * my + b12 * mz
            nz = b20 * mx + b21 * my + b22 * mz
            wx = b00 * cx + b01 * cy + b02 * cz + pos[b, 0] + sx
            wy = b10 * cx + b11 * cy + b12 * cz + pos[b, 1] + sy
            wz = b20 * cx + b21 * cy + b22 * cz + pos[b, 2] + sz
            return ov, nx, ny, nz, wx, wy, wz, i1 + i2
        use1 = kind == 0  # a vertex on a face: as below, from that face
        if use1:
            d1, x1, y1, z1, m1x, m1y, m1z = ov, cx, cy, cz, mx, my, mz
        else:
            d2, x2, y2, z2, m2x, m2y, m2z = ov, cx, cy, cz, mx, my, mz
    if use1:
        return _vertex_term3(d1, m1x, m1y, m1z, x1, y1, z1, s1, s1x, s1y, s1z, b00, b01,
                             b02, b10, b11, b12, b20, b21, b22, pos[b, 0] + sx,
                             pos[b, 1] + sy, pos[b, 2] + sz, -1.0, i1 + i2)
    return _vertex_term3(d2, m2x, m2y, m2z, x2, y2, z2, s2, s2x, s2y, s2z, a00, a01, a02,
                         a10, a11, a12, a20, a21, a22, pos[a, 0], pos[a, 1], pos[a, 2], 1.0,
                         i1 + i2)


@kernel
def _clipped3(s_in, sc_in, q00, q01, q02, q10, q11, q12, q20, q21, q22, qx, qy, qz,
              s_cl, sc_cl, u00, u01, u02, u10, u11, u12, u20, u21, u22, ux, uy, uz,
              wx, wy, wz, slab, buf, placed, vstart, verts, fstart, faces, tstart, tris):
    """The part of polyhedron ``s_in``'s boundary inside polyhedron ``s_cl`` (placed
    at ``Q x + q`` and ``U x + u``): its contribution ``(V, Mx, My, Mz)`` to the volume
    of their intersection and to its first moment (divergence theorem: a fan of
    tetrahedra from the origin over each triangle clipped by the other's faces,
    Sutherland-Hodgman, in ``buf`` (2, m, 3), m >= 3 + faces of ``s_cl``; the
    vertices placed in ``placed`` (n, 4), n >= vertices of ``s_in``). The
    intersection lies in the slab ``|w . x| <= slab``: triangles wholly outside it are
    skipped unclipped."""
    vol, mx, my, mz = 0.0, 0.0, 0.0, 0.0
    v0 = vstart[s_in]
    f0, f1 = fstart[s_cl], fstart[s_cl + 1]
    for v in range(v0, vstart[s_in + 1]):  # placed once, with their slab coordinate
        lx, ly, lz = sc_in * verts[v, 0], sc_in * verts[v, 1], sc_in * verts[v, 2]
        x = q00 * lx + q01 * ly + q02 * lz + qx
        y = q10 * lx + q11 * ly + q12 * lz + qy
        z = q20 * lx + q21 * ly + q22 * lz + qz
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
            nx = u00 * faces[f, 0] + u01 * faces[f, 1] + u02 * faces[f, 2]
            ny = u10 * faces[f, 0] + u11 * faces[f, 1] + u12 * faces[f, 2]
            nz = u20 * faces[f, 0] + u21 * faces[f, 1] + u22 * faces[f, 2]
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
def overlap_centroid3(sa, sca, a00, a01, a02, a10, a11, a12, a20, a21, a22, pax, pay, paz,
                      sb, scb, b00, b01, b02, b10, b11, b12, b20, b21, b22, pbx, pby, pbz,
                      wx, wy, wz, slab, geo):
    """Volume and centroid of the intersection of polyhedra A (at ``Ra x + pa``) and B
    (at ``Rb x + pb``), placed about a point near it (round-off), which lies in the slab
    ``|w . x| <= slab`` (``slab = inf``: anywhere): ``(V, cx, cy, cz)``, ``V = 0`` (and
    ``c = 0``) when they do not overlap."""
    vstart, verts, fstart, faces, tstart, tris = (geo[2], geo[3], geo[4], geo[5], geo[6],
                                                  geo[7])
    m = 3 + max(fstart[sa + 1] - fstart[sa], fstart[sb + 1] - fstart[sb])
    buf = np.empty((2, m, 3))
    placed = np.empty((max(vstart[sa + 1] - vstart[sa], vstart[sb + 1] - vstart[sb]), 4))
    va, ma, mb, mc = _clipped3(sa, sca, a00, a01, a02, a10, a11, a12, a20, a21, a22, pax,
                               pay, paz, sb, scb, b00, b01, b02, b10, b11, b12, b20, b21,
                               b22, pbx, pby, pbz, wx, wy, wz, slab, buf, placed, vstart,
                               verts, fstart, faces, tstart, tris)
    vb, na, nb, nc = _clipped3(sb, scb, b00, b01, b02, b10, b11, b12, b20, b21, b22, pbx,
                               pby, pbz, sa, sca, a00, a01, a02, a10, a11, a12, a20, a21,
                               a22, pax, pay, paz, wx, wy, wz, slab, buf, placed, vstart,
                               verts, fstart, faces, tstart, tris)
    vol = va + vb
    if not vol > 0.0:
        return 0.0, 0.0, 0.0, 0.0
    return vol, (ma + na) / vol, (mb + nb) / vol, (mc + nc) / vol


@kernel(inline=True)
def _vertex_term3(d, mx, my, mz, x, y, z, sw, swx, swy, swz, q00, q01, q02, q10, q11,
                  q12, q20, q21, q22, ox, oy, oz, sign, pivots):
    """One body's vertices in the other (the outer, frame ``Q`` at ``o``), deepest
    ``d`` at ``x`` where the outer normal is ``m``: the contact ``(d, n, point,
    pivots)`` in the world, ``n = sign Q m`` (from A into B).

    The point lies ``d / 2`` out of the deepest point's level along ``m``, over the
    depth-weighted mean of the vertices inside (weights ``sw``, sums ``sw x``), so it
    moves continuously as a face tilts through flat on a face; none inside (a face won
    the separating-axis test with a vertex outside): over ``x``."""
    mwx = q00 * mx + q01 * my + q02 * mz
    mwy = q10 * mx + q11 * my + q12 * mz
    mwz = q20 * mx + q21 * my + q22 * mz
    wx = q00 * x + q01 * y + q02 * z + ox
    wy = q10 * x + q11 * y + q12 * z + oy
    wz = q20 * x + q21 * y + q22 * z + oz
    if sw > 0.0:
        ex = (q00 * swx + q01 * swy + q02 * swz) / sw + ox - wx
        ey = (q10 * swx + q11 * swy + q12 * swz) / sw + oy - wy
        ez = (q20 * swx + q21 * swy + q22 * swz) / sw + oz - wz
        e = ex * mwx + ey * mwy + ez * mwz
        wx, wy, wz = wx + ex - e * mwx, wy + ey - e * mwy, wz + ez - e * mwz
    h = 0.5 * d
    return (d, sign * mwx, sign * mwy, sign * mwz, wx + h * mwx, wy + h * mwy,
            wz + h * mwz, pivots)


# --------------------------------------------------------------------------- public
@kernel(inline=True)
def polytope_contact(dim, sa, a, sb, b, sx, sy, sz, pos, rot, geo):
    """Contact of polytope body ``a`` (shape row ``sa``) with polytope ``b`` (row ``sb``).

    Parameters
    ----------
    dim : int
        2 or 3 (a compile-time constant in callers).
    sa, a, sb, b : int
        Shape rows and body indices of A and B. Rows may be boxes, polygons or
        polyhedra: only their vertices and faces are read.
    sx, sy, sz : float
        Shift [m] added to B's position (a periodic image); ``sz`` unused in 2D.
    pos : (n, dim) float64
        Body positions [m].
    rot : (n, 1) or (n, 4) float64
        Angle [rad] (2D) or unit quaternion (w, x, y, z), body to world (3D).
    geo : tuple
        :meth:`dem.shapes.table.ShapeTable.arrays`.

    Returns
    -------
    (ov, nx, ny, nz, cx, cy, cz, pivots)
        Overlap [m] (``<= 0``: separated; the other fields are then zero), unit normal
        from A to B, contact point [m] (the midpoint of the two surface points) and the
        simplex pivots taken, as :mod:`dem.contact.detection` defines them.
    """
    if dim == 2:
        return _polytope2(sa, a, sb, b, sx, sy, pos, rot, geo)
    return _polytope3(sa, a, sb, b, sx, sy, sz, pos, rot, geo)


@kernel(inline=True)
def polytope_plane(dim, sa, a, w, pos, rot, normal, geo):
    """Contact of polytope body ``a`` (shape row ``sa``) with the wall body ``w``.

    The wall passes through ``pos[w]`` with unit free-side normal ``normal[w]``; its
    solid lies behind. The overlap is the depth of A's deepest vertex, ``ov = -min_v
    normal[w] . (v - pos[w])``, and the normal from A to the wall is ``-normal[w]``. The
    contact point lies ``ov / 2`` in front of the depth-weighted mean of the vertices
    behind the wall (weights: their depths): the deepest vertex alone when only one has
    gone through, the middle of a face lying flat. The point, and so the torque, moves
    continuously as a face tilts, where jumping from corner to corner would make a box
    resting flat chatter on the wall at the time step's scale. (A distributed support:
    with two or more vertices through, the force is not the gradient of a potential.)

    Returns ``(ov, nx, ny, nz, cx, cy, cz, 0)``; ``pos``, ``rot`` as in
    :func:`polytope_contact`, ``normal`` (n, dim) float64.
    """
    scale, vstart, verts = geo[1], geo[2], geo[3]
    sc = scale[sa]
    wx, wy = normal[w, 0], normal[w, 1]
    wz = normal[w, 2] if dim == 3 else 0.0
    mx, my, mz = to_body(dim, rot, a, wx, wy, wz)  # the wall normal in A's frame
    base = wx * (pos[a, 0] - pos[w, 0]) + wy * (pos[a, 1] - pos[w, 1])
    if dim == 3:
        base += wz * (pos[a, 2] - pos[w, 2])
    v0, v1 = vstart[sa], vstart[sa + 1]
    lo = math.inf
    for v in range(v0, v1):
        lo = min(lo, mx * verts[v, 0] + my * verts[v, 1] + mz * verts[v, 2])
    ov = -(base + sc * lo)
    if ov <= 0.0:
        return ov, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0
    ax, ay, az, wsum = 0.0, 0.0, 0.0, 0.0
    for v in range(v0, v1):
        depth = -(base + sc * (mx * verts[v, 0] + my * verts[v, 1] + mz * verts[v, 2]))
        if depth > 0.0:
            ax += depth * verts[v, 0]
            ay += depth * verts[v, 1]
            az += depth * verts[v, 2]
            wsum += depth
    k = sc / wsum
    xx, xy, xz = to_world(dim, rot, a, k * ax, k * ay, k * az)
    # the weighted point lies at depth sum(d^2)/sum(d) <= ov: put c at ov/2 in front
    # of the deepest level, on the line through the weighted point along the normal
    dw = -(base + wx * xx + wy * xy + wz * xz)
    h = dw - 0.5 * ov
    cx = pos[a, 0] + xx + h * wx
    cy = pos[a, 1] + xy + h * wy
    cz = pos[a, 2] + xz + h * wz if dim == 3 else 0.0
    return ov, -wx, -wy, -wz, cx, cy, cz, 0
