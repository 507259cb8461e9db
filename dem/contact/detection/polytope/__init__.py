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
  is used, then P1 (3D; in 2D the corners inside decide, :mod:`.contact2`).

What the programmes' answer becomes is told where it is done: the corners inside in 2D
(:mod:`.arcs2`, :mod:`.contact2`); a vertex on a face, an edge across an edge
(:mod:`.contact3`, :mod:`.sat`) and patches (:mod:`.patch3`) in 3D; a polytope on a
wall (:func:`polytope_plane`).

Limitations: in 2D the point of a face-on-face contact is a weighted mean of corners,
not the centroid of the overlap region. In 3D each vertex's depth is its nearest face's
(the 2D arcs have no 3D counterpart), and the overlap and normal of a patch are its
deepest feature's. In 2D, while a short piece's face (divisor below 1) decides a corner's
depth, the push ignores how the divisor changes, so there the force is not quite a
gradient.
Shapes must be convex with outward unit face normals, as the shape table stores them.

Modules
-------
common      tolerances and small helpers shared by 2D and 3D (smooth maximum, cross
            products, rotation matrices)
simplex2    2D: the programme and the separating-axis early exit
arcs2       2D: the corners inside the other polygon, arc by arc, and their depths
contact2    2D: the contact of two polygons from the programmes and the corners
simplex3    3D: the programme and the separating-axis early exit
contact3    3D: the contact of two polyhedra (a vertex on a face, the crease rows)
patch3      3D: the volume and centroid of two polyhedra's intersection (patches)
sat         3D: the separating-axis contact of an edge across an edge
sat_edges   3D: its edge-pair geometry
wall        a polytope against a wall
"""

from ...._jit import kernel
from .common import BLEND, TIE, smooth_max, smooth_min
from .contact2 import DEEPER, _polytope2
from .contact3 import _polytope3
from .patch3 import PATCH_FROM, PATCH_TO, overlap_centroid3
from .wall import polytope_plane

__all__ = ["BLEND", "DEEPER", "PATCH_FROM", "PATCH_TO", "TIE", "overlap_centroid3",
           "polytope_contact", "polytope_plane", "smooth_max", "smooth_min"]


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
