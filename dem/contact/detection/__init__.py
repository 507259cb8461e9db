"""Contact detection: the contact summary of two bodies from their signed distance functions.

For a home body A and a neighbour B with signed distance functions phi_A, phi_B (negative
inside), detection solves two small convex problems (the paper's eq 14: the boundary
points that minimise the other body's SDF):

    P1:  x1 = argmin phi_B(x)  subject to  phi_A(x) <= 0     (A's point deepest in B)
    P2:  x2 = argmin phi_A(x)  subject to  phi_B(x) <= 0     (B's point deepest in A)

with depths ``d1 = -phi_B(x1)`` and ``d2 = -phi_A(x2)``. The contact is the deeper of the
two. If ``d1 >= d2``: overlap ``ov = d1``, unit normal ``n = -grad phi_B(x1)``; otherwise
``ov = d2``, ``n = grad phi_A(x2)``. The normal points from A to B. The contact point is
the midpoint of the two surface points, ``c = x1 - ov/2 n`` (or ``x2 + ov/2 n``), so A's
surface point is ``c + ov/2 n`` and B's is ``c - ov/2 n``. For spheres both problems give
the familiar ``ov = r_A + r_B - |x_B - x_A|`` along the line of centres. For a corner of
one polygon pressed into a face of another, the corner is the deeper point and the
normal is the face's: a well-defined, continuous contact. Separated bodies give
``ov <= 0``. With several corners inside (a face or an edge lying on a face) the
polytope kernels put ``c`` on the normal through the mean of the deeper side's vertices
inside the other body, each weighted by its depth, so that it moves continuously as the
face tilts.

Where the deeper point sits on a crease of the other body's SDF (in 3D, an edge across
an edge: both optima on creases) the gradient defining ``n`` does not exist. The exact
polytope solver then returns the limit of the definition there, the separating-axis
contact: ``ov`` the penetration depth (the shortest translation separating the bodies),
``n`` its direction (``e_A x e_B`` for two edges), ``c`` the midpoint of the edges'
closest points. The elastic force is then the gradient of ``kn ov^2 / 2`` on each piece,
as for a corner in a face. ADMM solves the definition on the crease itself.

Every detection kernel returns ``(ov, nx, ny, nz, cx, cy, cz, iters)`` (2D: ``nz = cz =
0``), ``iters`` being the iterations an iterative solver took (0 for closed forms).

Modules
-------
analytic    closed forms: sphere-sphere, sphere-plane, sphere-polytope, polytope-plane
polytope    the exact solver for polygon-polygon (2D) and polyhedron-polyhedron (3D), with
            its separating-axis contact for an edge across an edge (3D)
admm        ADMM (Douglas-Rachford) on any two SDFs, warm-started from the last step
nodes       the surface-node method of LS-DEM, the baseline of the speed-accuracy chart
"""
