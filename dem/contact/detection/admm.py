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
"""

import math

import numba
import numpy as np
from llvmlite import ir as llvm_ir
from numba import carray, cfunc
from numba.core import types
from numba.extending import intrinsic, overload

from ..._jit import kernel
from ...rotation import to_body, to_world
from ...shapes.table import CUSTOM, GRAD_STEP, PLANE, sdf_local
from ...status import NOCONVERGE, OK

# The solver's functions are compiled into the two cached kernels at the bottom
# (admm_contact, admm_contact_fn), not cached themselves; the hot ones are inlined: a
# call that passes the shape table's arrays costs two atomic reference counts per
# array. Options otherwise as dem._jit.kernel.
_generic = numba.njit(cache=False, fastmath=False, error_model="numpy")
_generic_inline = numba.njit(cache=False, fastmath=False, error_model="numpy",
                             inline="always")

N_WARM = 16
RHO0 = 4.0
RHO_MIN = 1.0 / 1024.0
RHO_MAX = 1.0e6
N_CUT = 8  # linearisations of each body's SDF kept per contact (shared by P1 and P2)
N_POLISH = 4  # failed LP polishes before a solve stops trying
WARM_MAX_ITER = 50  # iterations a warm attempt gets before its cold restart


# --------------------------------------------------------------------------- SDFs
@kernel(inline=True)
def _fd_point(dim, i, h, x, y, z):
    """Point ``i`` of the difference stencil at (x, y, z): the centre, then +-h on each
    axis; returns it and the weight of its value in the gradient component."""
    if i == 0:
        return x, y, z, 0.0
    w = 0.5 / h if i % 2 == 1 else -0.5 / h
    off = h if i % 2 == 1 else -h
    if i <= 2:
        return x + off, y, z, w
    if i <= 4:
        return x, y + off, z, w
    return x, y, z + off, w


@kernel(inline=True)
def _plane(dim, body, ox, oy, oz, x, y, z, normal):
    d = normal[body, 0] * (x - ox) + normal[body, 1] * (y - oy)
    if dim == 3:
        d += normal[body, 2] * (z - oz)
    return d


@kernel
def sdf_pair(dim, bd, x, y, z, rot, normal, geo, grad):
    """Signed distance [m] of a pair-frame point to the body described by ``bd`` and,
    if ``grad`` (int), its central-difference gradient: ``(phi, gx, gy, gz)``.

    The pair frame has the world's orientation and its origin at A's centre;
    ``bd = (kind, s, body, ox, oy, oz, h)`` with ``(ox, oy, oz)`` the body's centre in
    that frame and ``h`` [m] the difference step. A plane's gradient is its normal.
    Custom rows give NaN (see :func:`make_admm`).
    """
    kind, s, body, ox, oy, oz, h = bd[0], bd[1], bd[2], bd[3], bd[4], bd[5], bd[6]
    if kind == PLANE:
        f = _plane(dim, body, ox, oy, oz, x, y, z, normal)
        gz = normal[body, 2] if dim == 3 else 0.0
        return f, normal[body, 0], normal[body, 1], gz
    f, gx, gy, gz = 0.0, 0.0, 0.0, 0.0
    for i in range(1 + 2 * dim if grad else 1):  # one evaluation site: less to compile
        px, py, pz, w = _fd_point(dim, i, h, x, y, z)
        lx, ly, lz = to_body(dim, rot, body, px - ox, py - oy, pz - oz)
        v = sdf_local(kind, s, lx, ly, lz, geo)
        if i == 0:
            f = v
        elif i <= 2:
            gx += w * v
        elif i <= 4:
            gy += w * v
        else:
            gz += w * v
    return f, gx, gy, gz


@intrinsic
def _call_address(typingctx, address, x, y, z, p):
    """Call the C function ``double f(double, double, double, double*)`` at ``address``."""
    sig = types.float64(address, x, y, z, p)

    def codegen(context, builder, signature, args):
        double = llvm_ir.DoubleType()
        fnty = llvm_ir.FunctionType(double, [double, double, double, double.as_pointer()])
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        return builder.call(fn, args[1:])

    return sig, codegen


@intrinsic
def _as_pointer(typingctx, address):
    """An integer address as a ``float64*``."""
    sig = types.CPointer(types.float64)(address)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(signature.return_type))

    return sig, codegen


def _user_sdf(fn, x, y, z, geo, s):
    """The custom SDF ``fn`` at a point of the user's frame with row ``s``'s parameters:
    a Python function (interpreted), or the address of its ``cfunc`` wrapper."""
    return fn(x, y, z, geo[0][s])


@overload(_user_sdf, jit_options={"cache": False})
def _user_sdf_impl(fn, x, y, z, geo, s):
    def impl(fn, x, y, z, geo, s):
        return _call_address(fn, x, y, z, _as_pointer(geo[0][s].ctypes.data))
    return impl


@kernel
def sdf_custom(fn, dim, bd, x, y, z, rot, geo, grad):
    """:func:`sdf_pair` for a CUSTOM row, whose SDF is ``fn`` (the address of the user's
    function wrapped by :func:`make_admm`) evaluated in the user's frame at ``R @ x + c``
    (``geo[9]`` row ``s``) with the row's parameters and scale."""
    s, body, ox, oy, oz, h = bd[1], bd[2], bd[3], bd[4], bd[5], bd[6]
    sc = geo[1][s]
    xf = geo[9]
    f, gx, gy, gz = 0.0, 0.0, 0.0, 0.0
    for i in range(1 + 2 * dim if grad else 1):
        px, py, pz, w = _fd_point(dim, i, h, x, y, z)
        lx, ly, lz = to_body(dim, rot, body, px - ox, py - oy, pz - oz)
        lx, ly, lz = lx / sc, ly / sc, lz / sc
        ux = xf[s, 0] * lx + xf[s, 1] * ly + xf[s, 2] * lz + xf[s, 9]
        uy = xf[s, 3] * lx + xf[s, 4] * ly + xf[s, 5] * lz + xf[s, 10]
        uz = xf[s, 6] * lx + xf[s, 7] * ly + xf[s, 8] * lz + xf[s, 11]
        v = sc * _user_sdf(fn, ux, uy, uz, geo, s)
        if i == 0:
            f = v
        elif i <= 2:
            gx += w * v
        elif i <= 4:
            gy += w * v
        else:
            gz += w * v
    return f, gx, gy, gz


@_generic_inline
def _sdf(fn, dim, bd, x, y, z, rot, normal, geo, grad):
    """``(phi, grad phi)`` at a pair-frame point: :func:`sdf_pair`, or for a CUSTOM row
    :func:`sdf_custom` (``fn``: the custom SDF, 0 for none: NaN)."""
    if bd[0] == CUSTOM:
        if fn == 0:
            return math.nan, math.nan, math.nan, math.nan
        return sdf_custom(fn, dim, bd, x, y, z, rot, geo, grad)
    return sdf_pair(dim, bd, x, y, z, rot, normal, geo, grad)


@_generic_inline
def _project(fn, dim, bd, wx, wy, wz, rot, normal, geo, cc, nc, L):
    """Projection onto the body: ``w - max(phi, 0) grad phi / |grad phi|^2``.

    Outside, the linearisation at w (a supporting half-space of the body) joins the
    constraint bundle ``cc``; returns ``(p, phi(w), nc)``. Beyond the range where cuts
    are kept (:func:`_cut_range`) it is taken at the point of w's characteristic a
    quarter of that range out: the same half-space for an exact SDF, and a far point
    (an LP vertex along a face nearly parallel to the objective's level sets) must
    still add the face it reveals, or the LP returns it again and again.
    """
    phi = _sdf(fn, dim, bd, wx, wy, wz, rot, normal, geo, np.int64(0))[0]
    if phi <= 0.0:
        return wx, wy, wz, phi, nc
    phi, gx, gy, gz = _sdf(fn, dim, bd, wx, wy, wz, rot, normal, geo, np.int64(1))
    c = phi / (gx * gx + gy * gy + gz * gz)
    reach = _cut_range(bd, L)
    kx, ky, kz, kphi, hx, hy, hz = wx, wy, wz, phi, gx, gy, gz
    if phi > reach:  # (never for a wall: its range is infinite)
        back = (phi - 0.25 * reach) / phi
        kx, ky, kz = wx - back * c * gx, wy - back * c * gy, wz - back * c * gz
        kphi, hx, hy, hz = _sdf(fn, dim, bd, kx, ky, kz, rot, normal, geo, np.int64(1))
    nc = _keep_cut(cc, nc, hx, hy, hz, kphi - hx * kx - hy * ky - hz * kz, kphi, kx, ky,
                   kz, reach)
    return wx - c * gx, wy - c * gy, wz - c * gz, phi, nc


# --------------------------------------------------------------------------- the model prox
@_generic
def _linsolve(mat, m):
    """Solve the m x m system ``mat[:m, :m] y = mat[:m, m]`` in place; False if singular."""
    for c in range(m):
        p = c
        for r in range(c + 1, m):
            if abs(mat[r, c]) > abs(mat[p, c]):
                p = r
        if abs(mat[p, c]) < 1e-14:
            return False
        if p != c:
            for j in range(c, m + 1):
                mat[c, j], mat[p, j] = mat[p, j], mat[c, j]
        for r in range(c + 1, m):
            f = mat[r, c] / mat[c, c]
            for j in range(c, m + 1):
                mat[r, j] -= f * mat[c, j]
    for c in range(m - 1, -1, -1):
        acc = mat[c, m]
        for j in range(c + 1, m):
            acc -= mat[c, j] * mat[j, m]
        mat[c, m] = acc / mat[c, c]
    return True


@_generic
def _model_prox(cuts, n, vx, vy, vz, t, eps, mat):
    """Prox of the cutting-plane model ``max_i (b_i + g_i . x)`` at v with step t [m].

    The dual is ``max_theta sum theta_i c_i - t/2 |sum theta_i g_i|^2`` over the simplex
    (``c_i`` = cut i at v); active sets are tried smallest first and the first that
    satisfies the KKT conditions is returned: ``(x, gbar, model value at x)``. The cut
    highest at v goes first: for an exact SDF its step alone is the prox unless the step
    crosses a crease.
    """
    best, bi = -math.inf, 0
    for i in range(n):
        c = cuts[i, 3] + cuts[i, 0] * vx + cuts[i, 1] * vy + cuts[i, 2] * vz
        if c > best:
            best, bi = c, i
    gx, gy, gz = cuts[bi, 0], cuts[bi, 1], cuts[bi, 2]
    x, y, z = vx - t * gx, vy - t * gy, vz - t * gz
    mu = cuts[bi, 3] + gx * x + gy * y + gz * z
    feasible = True
    for i in range(n):
        if cuts[i, 3] + cuts[i, 0] * x + cuts[i, 1] * y + cuts[i, 2] * z > mu + eps:
            feasible = False
    if feasible:
        return x, y, z, gx, gy, gz, mu
    for size in range(1, n + 1):
        for mask in range(1, 1 << n):
            cnt = 0
            mm = mask
            while mm:
                cnt += mm & 1
                mm >>= 1
            if cnt != size:
                continue
            r = 0
            for i in range(n):
                if (mask >> i) & 1:
                    q = 0
                    for j in range(n):
                        if (mask >> j) & 1:
                            mat[r, q] = t * (cuts[i, 0] * cuts[j, 0]
                                             + cuts[i, 1] * cuts[j, 1]
                                             + cuts[i, 2] * cuts[j, 2])
                            q += 1
                    mat[r, size] = 1.0
                    mat[r, size + 1] = (cuts[i, 3] + cuts[i, 0] * vx + cuts[i, 1] * vy
                                        + cuts[i, 2] * vz)
                    r += 1
            for q in range(size):
                mat[size, q] = 1.0
            mat[size, size] = 0.0
            mat[size, size + 1] = 1.0
            if not _linsolve(mat, size + 1):
                continue
            gx, gy, gz = 0.0, 0.0, 0.0
            feasible = True
            r = 0
            for i in range(n):
                if (mask >> i) & 1:
                    th = mat[r, size + 1]
                    if th < -1e-12:
                        feasible = False
                    gx += th * cuts[i, 0]
                    gy += th * cuts[i, 1]
                    gz += th * cuts[i, 2]
                    r += 1
            if not feasible:
                continue
            x, y, z = vx - t * gx, vy - t * gy, vz - t * gz
            mu = -math.inf
            for i in range(n):
                if (mask >> i) & 1:
                    mu = max(mu, cuts[i, 3] + cuts[i, 0] * x + cuts[i, 1] * y
                             + cuts[i, 2] * z)
            for i in range(n):
                val = cuts[i, 3] + cuts[i, 0] * x + cuts[i, 1] * y + cuts[i, 2] * z
                if val > mu + eps and not (mask >> i) & 1:
                    feasible = False
            if feasible:
                return x, y, z, gx, gy, gz, mu
    # numerically no active set passed: the step on the cut highest at v
    gx, gy, gz = cuts[bi, 0], cuts[bi, 1], cuts[bi, 2]
    x, y, z = vx - t * gx, vy - t * gy, vz - t * gz
    return x, y, z, gx, gy, gz, cuts[bi, 3] + gx * x + gy * y + gz * z


@kernel(inline=True)
def _cut_range(bd, L):
    """How far from its surface [m] a linearisation of body ``bd`` is kept: 4 of its
    bounding radii (a plane's gradient is exact: everywhere)."""
    return math.inf if bd[0] == PLANE else 4.0 * bd[6] / GRAD_STEP


@_generic
def _keep_cut(cuts, n, gx, gy, gz, b, phi, px, py, pz, lim):
    """Insert a linearisation ``b + g . x`` of a body's SDF, taken at p (``phi`` = the
    SDF at p), into a persistent bundle (rows ``g, b, p inside``); returns the count.

    Only unit gradients taken within ``lim`` [m] of the surface (:func:`_cut_range`) are
    kept: an exact SDF's
    off its creases (the difference quotient across a crease blends the faces' normals
    and need not be a subgradient), and not so far that the quotient's rounding error
    (``phi / h`` times the machine epsilon) tilts the plane noticeably at the contact.
    A cut within 1e-3 of a stored one's normal replaces it, unless the stored one was
    taken inside the body and the new one outside (inside, a polytope's linearisation
    is its face plane, the best cut there is). A full bundle drops an outside cut
    first, the one lowest at p.
    """
    if abs(gx * gx + gy * gy + gz * gz - 1.0) > 1e-6 or abs(phi) > lim:
        return n
    inner = 1.0 if phi < 0.0 else 0.0
    for i in range(n):
        if (abs(cuts[i, 0] - gx) <= 1e-3 and abs(cuts[i, 1] - gy) <= 1e-3
                and abs(cuts[i, 2] - gz) <= 1e-3):
            if inner == 1.0 or cuts[i, 4] == 0.0:
                cuts[i, 0], cuts[i, 1], cuts[i, 2] = gx, gy, gz
                cuts[i, 3], cuts[i, 4] = b, inner
            return n
    j = n
    if n < cuts.shape[0]:
        n += 1
    else:
        j, low = 0, math.inf
        for i in range(n):
            val = cuts[i, 3] + cuts[i, 0] * px + cuts[i, 1] * py + cuts[i, 2] * pz
            val -= 1e300 * (1.0 - cuts[i, 4])  # outside cuts go first
            if val < low:
                j, low = i, val
    cuts[j, 0], cuts[j, 1], cuts[j, 2], cuts[j, 3], cuts[j, 4] = gx, gy, gz, b, inner
    return n


@_generic
def _add_cut(cuts, n, cap, gx, gy, gz, b, px, py, pz, L):
    """Insert the cut ``b + g . x`` (from point p); returns the new count.

    A cut equal to a stored one (same face of a polytope) replaces it; when the bundle
    is full the cut lowest at p goes.
    """
    for i in range(n):
        if (abs(cuts[i, 0] - gx) <= 1e-6 and abs(cuts[i, 1] - gy) <= 1e-6
                and abs(cuts[i, 2] - gz) <= 1e-6 and abs(cuts[i, 3] - b) <= 1e-6 * L):
            j = i
            break
    else:
        if n < cap:
            j = n
            n += 1
        else:
            j, low = 0, math.inf
            for i in range(n):
                val = cuts[i, 3] + cuts[i, 0] * px + cuts[i, 1] * py + cuts[i, 2] * pz
                if val < low:
                    j, low = i, val
    cuts[j, 0], cuts[j, 1], cuts[j, 2], cuts[j, 3] = gx, gy, gz, b
    return n


@_generic_inline
def _prox(fn, dim, bd, rot, normal, geo, cuts, fc, nf, vx, vy, vz, t, L, tol, mat):
    """Prox of ``t f`` at v; returns ``(x, gbar, nf, certified, crossed a crease)``.

    First the step on the gradient at v alone: for an exact SDF it is the prox when
    ``f`` drops by ``t |g|^2`` along it (one characteristic, no crease crossed), to
    ``tol`` relative (above the noise of the differences). Otherwise a bundle ``cuts``
    of cuts at v and at the trial points (null steps) models ``f`` and its prox is
    solved. Every cut also joins the persistent bundle ``fc`` (``nf`` cuts).
    """
    cap = dim + 1
    eps = tol * t
    fv, gx, gy, gz = _sdf(fn, dim, bd, vx, vy, vz, rot, normal, geo, np.int64(1))
    bv = fv - gx * vx - gy * vy - gz * vz
    nf = _keep_cut(fc, nf, gx, gy, gz, bv, fv, vx, vy, vz, _cut_range(bd, L))
    gg = gx * gx + gy * gy + gz * gz
    x, y, z = vx - t * gx, vy - t * gy, vz - t * gz
    f = _sdf(fn, dim, bd, x, y, z, rot, normal, geo, np.int64(0))[0]
    if f <= fv - (1.0 - tol) * t * gg:
        return x, y, z, gx, gy, gz, nf, True, False
    cuts[0, 0], cuts[0, 1], cuts[0, 2], cuts[0, 3] = gx, gy, gz, bv
    n = 1
    for _ in range(cap):
        f, hx, hy, hz = _sdf(fn, dim, bd, x, y, z, rot, normal, geo, np.int64(1))
        b = f - hx * x - hy * y - hz * z
        n = _add_cut(cuts, n, cap, hx, hy, hz, b, x, y, z, L)
        nf = _keep_cut(fc, nf, hx, hy, hz, b, f, x, y, z, _cut_range(bd, L))
        x, y, z, gx, gy, gz, m = _model_prox(cuts, n, vx, vy, vz, t, eps, mat)
        f = _sdf(fn, dim, bd, x, y, z, rot, normal, geo, np.int64(0))[0]
        if f <= m + eps:
            return x, y, z, gx, gy, gz, nf, True, True
    return x, y, z, gx, gy, gz, nf, False, True


@_generic
def _lp_polish(dim, fc, nf, cc, nc, px, py, pz, mat, rows, work_set):
    """Optimum of the cut LP ``min tau`` s.t. ``g_i . x + b_i <= tau`` (f cuts) and
    ``n_j . x + e_j <= 0`` (C cuts), by a primal active-set walk from ``(p, max_i f
    cut at p)`` (feasible: p lies in C and the C cuts are valid).

    The cuts under-estimate f and over-estimate C, so ``tau`` is a lower bound of P's
    optimum. Returns ``(found, x, tau, gbar)``: ``gbar`` the multipliers' combination of
    the active f cuts (the KKT subgradient). Not found: ``tau = -inf`` for an unbounded
    LP, with ``x`` a direction along which it is.
    """
    k = dim + 1
    m = nf + nc
    if nf < 1:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    tau, first = -math.inf, 0  # (x, tau) in columns 0..dim-1 and dim
    for i in range(m):  # row i: a . (x, tau) <= rhs, rhs in column 4
        cut = fc[i] if i < nf else cc[i - nf]
        rows[i, 0], rows[i, 1], rows[i, 2] = cut[0], cut[1], cut[2]
        rows[i, dim] = -1.0 if i < nf else 0.0
        rows[i, 4] = -cut[3]
        if i < nf:
            val = cut[3] + cut[0] * px + cut[1] * py + cut[2] * pz
            if val > tau:
                tau, first = val, i
    ya = mat[5]  # the point (x, tau); mat rows 0-3 hold the small systems, row 4 the step
    ya[0], ya[1], ya[2], ya[3] = px, py, pz if dim == 3 else tau, tau
    nw = 1
    work_set[0] = first
    for _ in range(4 * m + 8):
        # p = -(c - A_W^T mu) with (A_W A_W^T) mu = A_W c, c = e_tau
        for r in range(nw):
            for q in range(nw):
                acc = 0.0
                for c in range(k):
                    acc += rows[work_set[r], c] * rows[work_set[q], c]
                mat[r, q] = acc
            mat[r, nw] = rows[work_set[r], dim]
        if not _linsolve(mat, nw):
            return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        pn = 0.0
        for c in range(k):
            acc = -1.0 if c == dim else 0.0
            for r in range(nw):
                acc += rows[work_set[r], c] * mat[r, nw]
            mat[4, c] = acc  # the direction, kept in the spare row
            pn += acc * acc
        if pn < 1e-20 or nw == k:  # stationary on W (a vertex: no direction left);
            # multipliers lambda = -mu must be >= 0
            j, top = -1, 1e-9
            for r in range(nw):
                if mat[r, nw] > top:
                    j, top = r, mat[r, nw]
            if j < 0:
                gx, gy, gz = 0.0, 0.0, 0.0
                for r in range(nw):
                    i = work_set[r]
                    if i < nf:
                        gx -= mat[r, nw] * fc[i, 0]
                        gy -= mat[r, nw] * fc[i, 1]
                        gz -= mat[r, nw] * fc[i, 2]
                z = ya[2] if dim == 3 else 0.0
                return True, ya[0], ya[1], z, ya[dim], gx, gy, gz
            nw -= 1
            work_set[j] = work_set[nw]
            continue
        # ratio test along the direction
        step, blocking = math.inf, -1
        for i in range(m):
            inw = False
            for r in range(nw):
                if work_set[r] == i:
                    inw = True
            if inw:
                continue
            ap, ay = 0.0, 0.0
            for c in range(k):
                ap += rows[i, c] * mat[4, c]
                ay += rows[i, c] * ya[c]
            if ap > 1e-12 * math.sqrt(pn):
                st = max((rows[i, 4] - ay) / ap, 0.0)
                if st < step:
                    step, blocking = st, i
        if blocking < 0:  # unbounded: the direction's x part, and tau = -inf
            dz = mat[4, 2] if dim == 3 else 0.0
            return False, mat[4, 0], mat[4, 1], dz, -math.inf, 0.0, 0.0, 0.0
        for c in range(k):
            ya[c] += step * mat[4, c]
        work_set[nw] = blocking
        nw += 1
    return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0


# --------------------------------------------------------------------------- one problem
# state row of one problem
Z, U, RHO, G, CREASE, POLISH, TRIED, ITS, DONE, POLISHED, BUDGET, ITS0, DEPTH, BOUND = (
    0, 3, 6, 7, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19)
N_STATE = 20  # DONE: 0 running, 1 converged, 2 not needed; BOUND: of the depth (LP)


@_generic_inline
def _start(fn, dim, bc, st, cold, mx, my, mz, ex, ey, ez, L, rot, normal, geo, cc, nc,
           max_iter):
    """(Re)start a problem: cold, ``z = P_C(m)``, ``u = t e`` (``e`` points from C towards
    f's body), ``rho = RHO0``; warm, the state row already holds z, u, rho."""
    if cold:
        t = L / RHO0
        st[Z], st[Z + 1], st[Z + 2], _, nc = _project(fn, dim, bc, mx, my, mz, rot, normal,
                                                      geo, cc, nc, L)
        st[U], st[U + 1], st[U + 2] = t * ex, t * ey, t * ez
        st[RHO] = RHO0
        st[CREASE] = 0.0
    st[G], st[G + 1], st[G + 2] = 0.0, 0.0, 0.0
    st[POLISH], st[TRIED], st[DONE], st[POLISHED] = N_POLISH, 0.0, 0.0, 0.0
    budget = max_iter if cold else min(max_iter, WARM_MAX_ITER)
    st[ITS0], st[BUDGET], st[BOUND] = st[ITS], st[ITS] + budget, math.inf
    return nc


@_generic_inline
def _step(fn, dim, bc, bf, rot, normal, geo, st, L, tol, fc, nf, cc, nc, cuts, mat, rows,
          iwork):
    """One ADMM iteration of ``min f s.t. x in C`` (f = SDF of body ``bf``, C = body
    ``bc``) on the state row ``st`` (modified in place), then a certified LP polish
    once the iterates met a crease. ``fc`` / ``cc`` hold the linearisations of f and of
    C's SDF gathered so far (shared with the other problem, where they swap roles).
    ``cuts``, ``mat``, ``rows``, ``iwork``: scratch. Returns the new cut counts ``(nf,
    nc)``.
    """
    zx, zy, zz, rho = st[Z], st[Z + 1], st[Z + 2], st[RHO]
    ux, uy, uz = st[U], st[U + 1], st[U + 2]
    lim = tol * L
    t = L / rho
    st[ITS] += 1.0
    x, y, z, gx, gy, gz, nf, exact, crossed = _prox(
        fn, dim, bf, rot, normal, geo, cuts, fc, nf, zx - ux, zy - uy, zz - uz, t, L, tol,
        mat)
    if crossed:
        st[CREASE] = 1.0
    wx, wy, wz = x + ux, y + uy, z + uz
    px, py, pz, phi, nc = _project(fn, dim, bc, wx, wy, wz, rot, normal, geo, cc, nc, L)
    ux, uy, uz = wx - px, wy - py, wz - pz
    r = math.sqrt((x - px) ** 2 + (y - py) ** 2 + (z - pz) ** 2)
    dz = math.sqrt((px - zx) ** 2 + (py - zy) ** 2 + (pz - zz) ** 2)
    s = rho * dz
    zx, zy, zz = px, py, pz
    st[G], st[G + 1], st[G + 2] = gx, gy, gz
    done = False
    if r <= lim:
        if max(s, dz) <= lim:
            done = True
        elif exact and phi > 0.0:  # KKT: gbar + lambda u = 0 for some lambda > 0
            gn = math.sqrt(gx * gx + gy * gy + gz * gz)
            un = math.sqrt(ux * ux + uy * uy + uz * uz)
            if gn > 0.0 and un > 0.0:
                a = math.sqrt((gx / gn + ux / un) ** 2 + (gy / gn + uy / un) ** 2
                              + (gz / gn + uz / un) ** 2)
                done = a <= tol
    version = 0.0  # the LP is tried again only once the cuts changed
    for i in range(nf):
        version += (i + 1.0) * (fc[i, 0] + 2.0 * fc[i, 1] + 3.0 * fc[i, 2] + fc[i, 3])
    for i in range(nc):
        version += (i + 7.0) * (cc[i, 0] + 2.0 * cc[i, 1] + 3.0 * cc[i, 2] + cc[i, 3])
    polish = st[CREASE] == 1.0 or st[ITS] - st[ITS0] >= 4.0  # a crease, or slow
    if not done and polish and st[POLISH] > 0.0 and version != st[TRIED]:
        # a polytope's optimum is a vertex of the cut LP: solve it and certify it
        st[TRIED] = version
        found, qx, qy, qz, tau, hx, hy, hz = _lp_polish(
            dim, fc, nf, cc, nc, zx, zy, zz, mat, rows, iwork)
        size = 4.0 * max(bc[6], bf[6]) / GRAD_STEP  # (inf with a wall)
        if found and (qx - zx) ** 2 + (qy - zy) ** 2 + (qz - zz) ** 2 > size * size:
            found = False  # an ill-conditioned vertex, far from the bodies
        if found:
            st[BOUND] = min(st[BOUND], -tau)
        if found:  # certify: a feasible point within tol of the lower bound tau
            pq = _sdf(fn, dim, bc, qx, qy, qz, rot, normal, geo, np.int64(0))[0]
            if pq > 0.0:
                qx, qy, qz, _, nc = _project(fn, dim, bc, qx, qy, qz, rot, normal, geo, cc,
                                             nc, L)
            fq = _sdf(fn, dim, bf, qx, qy, qz, rot, normal, geo, np.int64(0))[0]
            if abs(fq - tau) <= lim:  # (fq < tau: the cuts are not valid)
                rho = max(rho, 1.0)  # the fixed point of ADMM there, for a warm start
                t = L / rho
                zx, zy, zz, ux, uy, uz = qx, qy, qz, -t * hx, -t * hy, -t * hz
                st[G], st[G + 1], st[G + 2] = hx, hy, hz
                st[POLISHED] = 1.0
                done = True
            else:
                st[POLISH] -= 1.0  # a face is missing: the cut at q joins (Kelley)
                fq, kx, ky, kz = _sdf(fn, dim, bf, qx, qy, qz, rot, normal, geo,
                                      np.int64(1))
                nf = _keep_cut(fc, nf, kx, ky, kz, fq - kx * qx - ky * qy - kz * qz, fq, qx,
                               qy, qz, _cut_range(bf, L))
        elif tau == -math.inf and qx * qx + qy * qy + qz * qz > 0.0:
            # unbounded along q: C's supporting plane that way (from a point two
            # bounding radii out; a wall: the point L along) and f's cut there bound it
            reach = L if bc[0] == PLANE else 2.0 * bc[6] / GRAD_STEP
            dn = reach / math.sqrt(qx * qx + qy * qy + qz * qz)
            ox, oy, oz = (zx, zy, zz) if bc[0] == PLANE else (bc[3], bc[4], bc[5])
            qx, qy, qz, _, nc = _project(fn, dim, bc, ox + dn * qx, oy + dn * qy,
                                         oz + dn * qz, rot, normal, geo, cc, nc, L)
            fq, kx, ky, kz = _sdf(fn, dim, bf, qx, qy, qz, rot, normal, geo, np.int64(1))
            nf = _keep_cut(fc, nf, kx, ky, kz, fq - kx * qx - ky * qy - kz * qz, fq, qx,
                           qy, qz, _cut_range(bf, L))
    if not done:
        # residual balancing; shorter steps too when the prox was not certified
        if (not exact or r > 10.0 * s) and rho < RHO_MAX:
            rho *= 2.0
            ux, uy, uz = 0.5 * ux, 0.5 * uy, 0.5 * uz
        elif s > 10.0 * r and rho > RHO_MIN:
            rho *= 0.5
            ux, uy, uz = 2.0 * ux, 2.0 * uy, 2.0 * uz
    st[Z], st[Z + 1], st[Z + 2], st[RHO] = zx, zy, zz, rho
    st[U], st[U + 1], st[U + 2] = ux, uy, uz
    st[DONE] = 1.0 if done else 0.0
    return nf, nc


@kernel(inline=True)
def _into_body(dim, rot, b, x, y, z):
    return to_body(dim, rot, b, x, y, z)


@kernel(inline=True)
def _into_world(dim, rot, b, x, y, z):
    return to_world(dim, rot, b, x, y, z)


# --------------------------------------------------------------------------- one contact
@_generic
def _admm(fn, dim, ka, sa, a, kb, sb, b, sx, sy, sz, pos, rot, normal, geo, warm, k,
          tol, max_iter):
    """:func:`admm_contact` with ``fn`` the custom SDF's address (0: none)."""
    scale, brad = geo[1], geo[8]
    obx = pos[b, 0] + sx - pos[a, 0]  # B's centre in the pair frame (origin: A's centre)
    oby = pos[b, 1] + sy - pos[a, 1]
    obz = pos[b, 2] + sz - pos[a, 2] if dim == 3 else 0.0
    la = brad[sa] * scale[sa] if ka != PLANE else math.inf
    lb = brad[sb] * scale[sb] if kb != PLANE else math.inf
    L = min(la, lb) if min(la, lb) < math.inf else 1.0
    ba = (np.int64(ka), np.int64(sa), np.int64(a), 0.0, 0.0, 0.0, GRAD_STEP * la)
    bb = (np.int64(kb), np.int64(sb), np.int64(b), obx, oby, obz, GRAD_STEP * lb)
    work = np.empty(22 * N_CUT + 52 + 2 * N_STATE)  # cuts of A and B, scratch, states
    iwork = np.empty(4, np.int64)
    cut_a = work[0:5 * N_CUT].reshape((N_CUT, 5))
    cut_b = work[5 * N_CUT:10 * N_CUT].reshape((N_CUT, 5))
    cuts = work[10 * N_CUT:10 * N_CUT + 16].reshape((4, 4))
    mat = work[10 * N_CUT + 16:10 * N_CUT + 52].reshape((6, 6))
    rows = work[10 * N_CUT + 52:22 * N_CUT + 52].reshape((2 * N_CUT, 6))
    state = work[22 * N_CUT + 52:].reshape((2, N_STATE))
    n_a, n_b = np.int64(0), np.int64(0)

    # centres (a plane's: the foot of the other centre on it) and the cold guess
    cax, cay, caz, cbx, cby, cbz = 0.0, 0.0, 0.0, obx, oby, obz
    if kb == PLANE:
        d = _plane(dim, b, 0.0, 0.0, 0.0, obx, oby, obz, normal)
        cbx, cby, cbz = d * normal[b, 0], d * normal[b, 1], d * normal[b, dim - 1]
    elif ka == PLANE:
        d = _plane(dim, a, 0.0, 0.0, 0.0, obx, oby, obz, normal)
        cax, cay, caz = obx - d * normal[a, 0], oby - d * normal[a, 1], obz
        caz -= d * normal[a, dim - 1]
    if dim == 2:
        caz, cbz = 0.0, 0.0
    mx, my, mz = 0.5 * (cax + cbx), 0.5 * (cay + cby), 0.5 * (caz + cbz)
    ex, ey, ez = cbx - cax, cby - cay, cbz - caz
    en = math.sqrt(ex * ex + ey * ey + ez * ez)
    ex, ey, ez = (ex / en, ey / en, ez / en) if en > 0.0 else (1.0, 0.0, 0.0)

    # P1: C = A, f = phi_B (B's cuts are f's);  P2: C = B, f = phi_A. The two run in
    # turns, one iteration each, so that each LP polish knows the faces the other
    # problem's prox met. A warm start that fails is retried cold once.
    flags = int(warm[k, 15]) if warm[k, 14] == 1.0 else 12
    state[:, :] = 0.0
    state[:, BOUND] = math.inf
    retried = np.int64(flags >> 2)  # bit p: problem p started cold
    for p in range(2):
        st = state[p]
        body, ox, oy, oz = (a, 0.0, 0.0, 0.0) if p == 0 else (b, obx, oby, obz)
        if not (flags >> (p + 2)) & 1:
            st[Z], st[Z + 1], st[Z + 2] = _into_world(
                dim, rot, body, warm[k, 6 * p], warm[k, 6 * p + 1], warm[k, 6 * p + 2])
            st[Z], st[Z + 1], st[Z + 2] = st[Z] + ox, st[Z + 1] + oy, st[Z + 2] + oz
            st[U], st[U + 1], st[U + 2] = _into_world(
                dim, rot, body, warm[k, 6 * p + 3], warm[k, 6 * p + 4], warm[k, 6 * p + 5])
            st[RHO] = warm[k, 12 + p]
            st[CREASE] = 1.0 if (flags >> p) & 1 else 0.0
    while True:
        busy = False
        for p in range(2):
            st = state[p]
            exhausted = st[BUDGET] > 0.0 and st[ITS] >= st[BUDGET]
            if st[DONE] >= 1.0 or (exhausted and (retried >> p) & 1):
                continue
            busy = True
            bc, bf = (ba, bb) if p == 0 else (bb, ba)
            if p == 0:
                fc, nf, cc, nc = cut_b, n_b, cut_a, n_a
            else:
                fc, nf, cc, nc = cut_a, n_a, cut_b, n_b
            if st[BUDGET] == 0.0 or exhausted:  # start, or restart cold
                cold = exhausted or bool((flags >> (p + 2)) & 1) or not st[RHO] > 0.0
                retried |= np.int64(1 << p) if cold else np.int64(0)
                sg = 1.0 if p == 0 else -1.0
                nc = _start(fn, dim, bc, st, np.int64(cold), mx, my, mz, sg * ex, sg * ey,
                            sg * ez, L, rot, normal, geo, cc, nc, max_iter)
            nf, nc = _step(fn, dim, bc, bf, rot, normal, geo, st, L, tol, fc, nf, cc, nc,
                           cuts, mat, rows, iwork)
            if p == 0:
                n_b, n_a = nf, nc
            else:
                n_a, n_b = nf, nc
            other = state[1 - p]
            if st[DONE] == 1.0:
                st[DEPTH] = -_sdf(fn, dim, bf, st[Z], st[Z + 1], st[Z + 2], rot, normal,
                                  geo, np.int64(0))[0]
                if other[DONE] == 0.0 and (st[DEPTH] < -tol * L
                                           or other[BOUND] < st[DEPTH] - tol * L):
                    # the other problem is not needed: no point of one body lies in the
                    # other (convex bodies apart), or its depth is bounded below this
                    other[DONE] = 2.0
            elif other[DONE] == 1.0 and st[BOUND] < other[DEPTH] - tol * L:
                st[DONE] = 2.0
        if not busy:
            break
    all_ok = state[0, DONE] >= 1.0 and state[1, DONE] >= 1.0

    # the deeper side gives the contact: n = -grad phi_B(x1) or grad phi_A(x2)
    d1 = state[0, DEPTH] if state[0, DONE] == 1.0 else -math.inf
    d2 = state[1, DEPTH] if state[1, DONE] == 1.0 else -math.inf
    if not all_ok:  # report the last iterates
        d1 = -_sdf(fn, dim, bb, state[0, Z], state[0, Z + 1], state[0, Z + 2], rot,
                   normal, geo, np.int64(0))[0]
        d2 = -_sdf(fn, dim, ba, state[1, Z], state[1, Z + 1], state[1, Z + 2], rot,
                   normal, geo, np.int64(0))[0]
    p = 0 if d1 >= d2 else 1
    st = state[p]
    sg = -1.0 if p == 0 else 1.0
    ov = d1 if p == 0 else d2
    # the gradient: gbar, the subgradient of f at the point that the optimality
    # conditions single out (on a crease, the combination of the faces that C's normal
    # cone balances: the common perpendicular of two edges, a face's own normal when
    # it lies nearly flat on the other body's face)
    gx, gy, gz = st[G], st[G + 1], st[G + 2]
    gn = math.sqrt(gx * gx + gy * gy + gz * gz)
    if gn > 0.0:
        nx, ny, nz = sg * gx / gn, sg * gy / gn, sg * gz / gn
    else:
        nx, ny, nz = ex, ey, ez
    # c = x1 - ov/2 n  or  x2 + ov/2 n, back to the world frame
    cx = st[Z] + sg * 0.5 * ov * nx + pos[a, 0]
    cy = st[Z + 1] + sg * 0.5 * ov * ny + pos[a, 1]
    cz = st[Z + 2] + sg * 0.5 * ov * nz + pos[a, 2] if dim == 3 else 0.0
    if dim == 2:
        nz = 0.0

    # the warm row for the next call, in the bodies' frames (a problem not needed
    # this time starts cold next time)
    warm[k, :] = 0.0
    if all_ok:
        flags = 0
        for p in range(2):
            st = state[p]
            if st[BUDGET] == 0.0:
                flags |= 4 << p
                continue
            body, ox, oy, oz = (a, 0.0, 0.0, 0.0) if p == 0 else (b, obx, oby, obz)
            warm[k, 6 * p], warm[k, 6 * p + 1], warm[k, 6 * p + 2] = _into_body(
                dim, rot, body, st[Z] - ox, st[Z + 1] - oy, st[Z + 2] - oz)
            warm[k, 6 * p + 3], warm[k, 6 * p + 4], warm[k, 6 * p + 5] = _into_body(
                dim, rot, body, st[U], st[U + 1], st[U + 2])
            warm[k, 12 + p] = st[RHO]
        warm[k, 14] = 1.0
        warm[k, 15] = flags + state[0, CREASE] + 2.0 * state[1, CREASE]
    status = OK if all_ok else NOCONVERGE
    return status, ov, nx, ny, nz, cx, cy, cz, int(max(state[0, ITS], state[1, ITS]))


@kernel
def admm_contact(dim, ka, sa, a, kb, sb, b, sx, sy, sz, pos, rot, normal, geo, warm, k,
                 tol, max_iter):
    """Contact of home body ``a`` and neighbour ``b`` by ADMM on their SDFs.

    Parameters
    ----------
    dim : int
        2 or 3.
    ka, kb : int
        Shape kinds (:mod:`dem.shapes.table` codes) of ``a`` and ``b``; SPHERE, BOX,
        POLYGON, POLYHEDRON rows or PLANE (see :func:`make_admm` for CUSTOM).
    sa, sb : int
        Shape-table rows of ``a`` and ``b`` (ignored for a plane).
    a, b : int
        Body indices.
    sx, sy, sz : float
        Periodic shift [m] added to ``b``'s position (zeros without periodicity).
    pos : (n, d) float64 [m]
    rot : (n, 4) float64 quaternions (3D) or (n, 1) angles [rad] (2D)
    normal : (n, d) float64
        World normals of plane bodies.
    geo : tuple
        :meth:`dem.shapes.table.ShapeTable.arrays`.
    warm : (m, 16) float64
        Warm-start rows (layout in the module docstring); row ``k`` is read and
        rewritten (zeroed when a problem failed). Modified in place.
    k : int
        This contact's row of ``warm``.
    tol : float
        Relative tolerance [-]: residuals below ``tol`` x the smaller bounding radius
        (``GRAD_STEP`` limits the differences' precision: ``tol`` >= about 1e-9).
    max_iter : int
        Iteration cap of each problem's cold attempt; a warm attempt gets at most
        ``WARM_MAX_ITER`` of them before its cold restart.

    Returns
    -------
    status : int
        :mod:`dem.status` code: ``OK`` (0) converged, ``NOCONVERGE`` (1) a problem did
        not converge even from a cold start.
    ov, nx, ny, nz, cx, cy, cz : float
        Overlap [m] (> 0 in contact), unit normal from a to b, contact point [m]
        (world frame; 2D: ``nz = cz = 0``).
    iters : int
        ADMM iterations of the longer of the two problems (they run in turns; a failed
        warm attempt counts).
    """
    return _admm(np.int64(0), dim, ka, sa, a, kb, sb, b, sx, sy, sz, pos, rot, normal, geo,
                 warm, k, tol, max_iter)


@kernel
def admm_contact_fn(fn, dim, ka, sa, a, kb, sb, b, sx, sy, sz, pos, rot, normal, geo, warm,
                    k, tol, max_iter):
    """:func:`admm_contact` with CUSTOM rows evaluated by the C function at address ``fn``
    (``double f(double x, double y, double z, double *p)``, see :func:`make_admm`)."""
    return _admm(fn, dim, ka, sa, a, kb, sb, b, sx, sy, sz, pos, rot, normal, geo, warm, k,
                 tol, max_iter)


CUSTOM_SIGNATURE = types.float64(types.float64, types.float64, types.float64,
                                 types.CPointer(types.float64))
_CUSTOM = {}


def make_admm(custom_sdf=None):
    """The :func:`admm_contact` kernel with CUSTOM rows evaluated by ``custom_sdf``.

    Parameters
    ----------
    custom_sdf : numba dispatcher or None
        A ``@numba.njit`` function ``custom_sdf(x, y, z, p) -> float``: the signed
        distance [m] of the point (x, y, z) of the user's frame, with ``p`` the row's
        four parameters (:attr:`ShapeTable.param`, a (4,) float64 array). It must be
        an exact distance outside the shape. ``None`` gives the built-in kernel.

    Returns
    -------
    The compiled kernel, with :func:`admm_contact`'s signature (memoised per function).
    The solver is compiled (and cached) once for every custom SDF: the user's function
    reaches it as the address of a ``cfunc`` wrapping it.
    """
    if custom_sdf is None:
        return admm_contact
    if custom_sdf not in _CUSTOM:
        if numba.config.DISABLE_JIT:
            address = custom_sdf
        else:
            @cfunc(CUSTOM_SIGNATURE, error_model="numpy")
            def wrapper(x, y, z, p):
                return custom_sdf(x, y, z, carray(p, 4))

            address = np.int64(wrapper.address)

        @_generic
        def admm_contact_custom(dim, ka, sa, a, kb, sb, b, sx, sy, sz, pos, rot, normal,
                                geo, warm, k, tol, max_iter):
            return admm_contact_fn(address, dim, ka, sa, a, kb, sb, b, sx, sy, sz, pos,
                                   rot, normal, geo, warm, k, tol, max_iter)

        # the wrapper must outlive every call through its address
        _CUSTOM[custom_sdf] = (admm_contact_custom, address if numba.config.DISABLE_JIT
                               else wrapper)
    return _CUSTOM[custom_sdf][0]


def custom_address(custom_sdf):
    """The address of ``custom_sdf``'s C wrapper: the ``fn`` argument of the ``*_fn``
    kernels (:func:`admm_contact_fn`,
    :func:`dem.contact.detection.nodes.nodes_contact_fn`). Wraps it once, as
    :func:`make_admm` does."""
    make_admm(custom_sdf)
    wrapper = _CUSTOM[custom_sdf][1]
    return wrapper if numba.config.DISABLE_JIT else np.int64(wrapper.address)
