"""The two halves of an ADMM iteration: the prox of ``t f`` and the projection onto C.

Both evaluate the SDFs (:mod:`.sdf`) and add the linearisations they meet to the
contact's bundles (:mod:`.cuts`).
"""

import numpy as np

from ...._jit import kernel
from .cuts import _add_cut, _cut_range, _keep_cut, _model_prox
from .sdf import _sdf


@kernel(inline=True, cache=False)
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


@kernel(inline=True, cache=False)
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
