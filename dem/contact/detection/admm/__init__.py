"""ADMM (Douglas-Rachford) contact detection on any two signed distance functions.

Each of the contract's problems (:mod:`dem.contact.detection`), say P1 ``min phi_B(x)
s.t. phi_A(x) <= 0``, is split into ``f = phi_B`` and the indicator of A and solved by
scaled ADMM with a dimensionless penalty ``rho`` (prox step ``t = L / rho`` [m], ``L``
the smaller bounding radius x scale of the pair)::

    x <- prox_{t f}(z - u)
    z <- P_A(x + u)          P_A(w) = w - max(phi_A(w), 0) grad phi_A / |grad phi_A|^2
    u <- u + x - z

from SDF evaluations only: gradients are central differences with step ``GRAD_STEP``
x bounding radius x scale, so corners and edges need nothing special.

Prox. For an exact SDF, ``v - t grad f(v)`` is the prox when the step stays on one
characteristic, which holds when ``f`` drops by ``t |grad f|^2`` along it (checked to
``tol``: one extra evaluation). Across a crease of ``f`` (the medial axis of a polytope:
P1's optimum lies on one when B's corner presses into A's face) that step would
overshoot and the iterates would oscillate, so the prox is solved on a cutting-plane
model ``max_i (b_i + g_i . x)`` (the cut at v and at each trial point, up to ``d + 1``)
by a small active-set QP and certified: once ``f(x) <= model(x) + tol t`` the active
cuts touch ``f`` at ``x`` and their combination ``gbar`` is a subgradient there. The
iterates land *on* the crease instead of jumping across it.

Polish. ADMM converges linearly, slowly on LP-like problems (a polytope's corner or
edge, or a face nearly parallel to the other's). Every linearisation met (of either
SDF, unit gradients only, taken near the surfaces) is kept per contact, shared by P1
and P2, where the two bodies swap roles. Once the iterates met a crease, or after four
iterations, the LP ``min tau s.t. cuts of f <= tau, cuts of C <= 0`` is solved by a
primal active-set walk: the cuts under-estimate ``f`` and over-estimate C, so ``tau`` is
a lower bound of the optimum; the LP's point, projected onto C, is accepted when ``f``
there is within ``tol L`` of ``tau`` (a certificate). A polytope's optimum is found
this way as soon as its faces are known; curved shapes never pass and stay with ADMM.
P1 and P2 run in turns, one iteration each, so that each LP knows the faces the other
problem's prox met. A problem stops as not needed once the other converged with a
negative depth (convex bodies apart), or once its LP bound puts it below the other's
converged depth.

Stopping. The primal residual ``r = |x - z|`` and the dual residual ``s = rho |z -
z_prev|`` (and ``|z - z_prev|`` itself when ``rho < 1``) below ``tol L``; or ``r`` is,
the prox is certified and ``gbar`` and the normal-cone vector ``u`` are anti-parallel
to ``tol`` (the KKT conditions hold at ``(x, z)``: a warm start can stop after one
iteration); or the polish certificate. ``rho`` is adapted by residual balancing (x2
when ``r > 10 s``, /2 when ``s > 10 r``, ``u`` rescaled) within ``[RHO_MIN, RHO_MAX]``,
and doubled after an uncertified prox: long steps pass along faces nearly parallel to
the objective's level sets, short ones keep the cut model valid.

Result. The deeper problem gives the contact (the contract). Its normal is ``gbar``,
the subgradient of ``f`` that the optimality conditions single out: where ``f`` is
smooth, its central-difference gradient at the solution; on a crease, the combination
of the faces' normals that C's normal cone balances: the common perpendicular of two
edges in an edge-edge contact, a face's own normal when it lies nearly flat on the
other body's face. (The normalised *sum* of the tied faces' normals, another reading
of the contract on a crease, tilts by up to 45 degrees there.)

Warm start. Row ``warm[k]`` (``N_WARM`` = 16 float64; zeros = cold) holds the final
iterates in the bodies' frames, so that it survives a rigid motion of the pair:

====  ========================================================================
0-2   ``z`` of P1 in A's body frame (relative to A's centre) [m]
3-5   ``u`` of P1 in A's body frame [m]
6-8   ``z`` of P2 in B's body frame (relative to B's centre) [m]
9-11  ``u`` of P2 in B's body frame [m]
12    ``rho`` of P1 [-]
13    ``rho`` of P2 [-]
14    1.0 when valid (both problems converged, or one was not needed), else 0.0
15    flags: 1 (2) = P1's (P2's) iterates met a crease (the polish may start at
      once); 4 (8) = P1 (P2) was not needed and starts cold
====  ========================================================================

Cold start: ``z = P(m)`` with ``m`` the midpoint of the two centres (for a plane: the
foot of the other centre on it), ``u = +-t e`` with ``e`` the unit vector from A's to
B's centre (the multiplier of two spheres), ``rho = RHO0``. A warm solve that does not
converge in ``min(max_iter, WARM_MAX_ITER)`` iterations is retried cold once, with the
whole ``max_iter``; if that fails too the status is ``NOCONVERGE`` (1, see
:mod:`dem.status`) and the row is cleared. (A warm start converges in one or two
iterations or has gone stale: one that stalls, as where a cube slides past the end edge
of a leg of an L, would otherwise spend the whole cap before a cold solve that needs a
handful.)

SDF evaluation. SPHERE, BOX, POLYGON and POLYHEDRON rows through
:func:`dem.shapes.table.sdf_local`; a PLANE body is ``n . (x - p)`` with its world normal
``normal[b]``; a CUSTOM row is the user's ``@numba.njit`` function ``user_sdf(x, y, z,
p)`` at ``R @ (x / scale) + c`` (``R, c`` from ``geo[9]`` row ``s``, ``p = param[s]``),
times ``scale`` (:func:`make_admm`). SDFs must be exact distances outside the body (the
projection is a single step) and convex.

Compilation. The solver's functions are compiled into the two cached kernels
(:func:`admm_contact`, :func:`admm_contact_fn`), not cached themselves
(``kernel(cache=False)``); the hot ones are inlined: a call that passes the shape
table's arrays costs two atomic reference counts per array. A user's SDF reaches
``admm_contact_fn`` as the address of a C wrapper (:mod:`dem._jit`), so that kernel too
is compiled once for all of them.

Modules
-------
sdf      the bodies' SDFs and their central-difference gradients in the pair frame
cuts     the cutting-plane models: the bundles of linearisations, the prox of the
         model, the LP polish
prox     the two halves of an iteration: the prox of ``t f`` and the projection onto C
solver   one problem's iterations, the two problems of a contact, the kernels
custom   the kernel for a user's SDF (:func:`make_admm`)
"""

from .custom import custom_address, make_admm
from .sdf import _sdf, sdf_custom, sdf_pair  # noqa: F401  (_sdf: for nodes.py)
from .solver import (N_CUT, N_POLISH, N_WARM, RHO0, RHO_MAX, RHO_MIN, WARM_MAX_ITER,
                     admm_contact, admm_contact_fn)

__all__ = ["N_CUT", "N_POLISH", "N_WARM", "RHO0", "RHO_MAX", "RHO_MIN", "WARM_MAX_ITER",
           "admm_contact", "admm_contact_fn", "custom_address", "make_admm", "sdf_custom",
           "sdf_pair"]
