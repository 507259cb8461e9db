"""One contact by ADMM: P1 and P2 iterated in turns, warm starts, the kernels."""

import math

import numpy as np

from ...._jit import kernel
from ....rotation import to_body, to_world
from ....shapes.kinds import PLANE
from ....shapes.table import GRAD_STEP
from ....status import NOCONVERGE, OK
from .cuts import _cut_range, _keep_cut, _lp_polish
from .prox import _project, _prox
from .sdf import _plane, _sdf

N_WARM = 16
RHO0 = 4.0
RHO_MIN = 1.0 / 1024.0
RHO_MAX = 1.0e6
N_CUT = 8  # linearisations of each body's SDF kept per contact (shared by P1 and P2)
N_POLISH = 4  # failed LP polishes before a solve stops trying
WARM_MAX_ITER = 50  # iterations a warm attempt gets before its cold restart

# --------------------------------------------------------------------------- one problem
# state row of one problem
Z, U, RHO, G, CREASE, POLISH, TRIED, ITS, DONE, POLISHED, BUDGET, ITS0, DEPTH, BOUND = (
    0, 3, 6, 7, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19)
N_STATE = 20  # DONE: 0 running, 1 converged, 2 not needed; BOUND: of the depth (LP)


@kernel(inline=True, cache=False)
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


@kernel(inline=True, cache=False)
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


@kernel(inline=True, cache=False)
def _load_warm(dim, rot, a, b, obx, oby, obz, warm, k, state):
    """Reset both problems' ``state`` and load pair ``k``'s warm row into the problems
    it did not mark cold; returns the row's flags (12, both cold, without a row)."""
    flags = int(warm[k, 15]) if warm[k, 14] == 1.0 else 12
    state[:, :] = 0.0
    state[:, BOUND] = math.inf
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
    return flags


@kernel(inline=True, cache=False)
def _deeper_side(fn, dim, ba, bb, state, all_ok, rot, normal, geo, pos, a, ex, ey, ez):
    """The contact of the deeper problem: ``(overlap, normal, point)`` in the world
    frame (the last iterates' depths when the solves did not both converge)."""
    # n = -grad phi_B(x1) or grad phi_A(x2)
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
    return ov, nx, ny, nz, cx, cy, cz


@kernel(inline=True, cache=False)
def _store_warm(dim, rot, a, b, obx, oby, obz, state, warm, k):
    """Write pair ``k``'s warm row for its next call, in the bodies' frames (a problem
    not needed this time starts cold next time)."""
    warm[k, :] = 0.0
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


@kernel(cache=False)
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
    flags = _load_warm(dim, rot, a, b, obx, oby, obz, warm, k, state)
    retried = np.int64(flags >> 2)  # bit p: problem p started cold
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

    ov, nx, ny, nz, cx, cy, cz = _deeper_side(fn, dim, ba, bb, state, all_ok, rot, normal,
                                              geo, pos, a, ex, ey, ez)
    if all_ok:
        _store_warm(dim, rot, a, b, obx, oby, obz, state, warm, k)
    else:
        warm[k, :] = 0.0
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
        POLYGON, POLYHEDRON rows or PLANE (see :func:`.custom.make_admm` for CUSTOM).
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
    (``double f(double x, double y, double z, double *p)``, see
    :func:`.custom.make_admm`)."""
    return _admm(fn, dim, ka, sa, a, kb, sb, b, sx, sy, sz, pos, rot, normal, geo, warm, k,
                 tol, max_iter)
