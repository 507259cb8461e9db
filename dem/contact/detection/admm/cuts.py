"""The solver's cutting-plane models: bundles of linearisations, their prox, the LP.

Each contact keeps the linearisations of both SDFs met so far (``N_CUT`` rows each:
normal, offset, and whether it was taken inside the body); a prox that would cross a
crease is solved on a model of up to ``d + 1`` cuts (:func:`_model_prox`); and the LP
of all the cuts (:func:`_lp_polish`) gives the polish its candidate and lower bound.
"""

import math

from ...._jit import kernel
from ....shapes.kinds import PLANE
from ....shapes.table import GRAD_STEP


@kernel(inline=True)
def _cut_range(bd, L):
    """How far from its surface [m] a linearisation of body ``bd`` is kept: 4 of its
    bounding radii (a plane's gradient is exact: everywhere)."""
    return math.inf if bd[0] == PLANE else 4.0 * bd[6] / GRAD_STEP


@kernel(cache=False)
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


@kernel(cache=False)
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


@kernel(cache=False)
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


@kernel(cache=False)
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


@kernel(cache=False)
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
