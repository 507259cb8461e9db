"""The SDFs the ADMM solver evaluates, and their gradients, in the pair frame.

A body is described to the solver by ``bd = (kind, s, body, ox, oy, oz, h)``: its shape
kind and table row, its index, its centre in the pair frame (the world's orientation,
origin at A's centre) and the difference step ``h`` [m] of its gradient.
"""

import math

from ...._jit import call_sdf, kernel
from ....rotation import to_body
from ....shapes.kinds import CUSTOM, PLANE
from ....shapes.table import sdf_local


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
    Custom rows give NaN (see :func:`.custom.make_admm`).
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


@kernel
def sdf_custom(fn, dim, bd, x, y, z, rot, geo, grad):
    """:func:`sdf_pair` for a CUSTOM row, whose SDF is ``fn`` (the address of the user's
    function wrapped by :func:`.custom.make_admm`) evaluated in the user's frame at
    ``R @ x + c`` (``geo[9]`` row ``s``) with the row's parameters and scale."""
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
        v = sc * call_sdf(fn, ux, uy, uz, geo[0][s])
        if i == 0:
            f = v
        elif i <= 2:
            gx += w * v
        elif i <= 4:
            gy += w * v
        else:
            gz += w * v
    return f, gx, gy, gz


@kernel(inline=True, cache=False)
def _sdf(fn, dim, bd, x, y, z, rot, normal, geo, grad):
    """``(phi, grad phi)`` at a pair-frame point: :func:`sdf_pair`, or for a CUSTOM row
    :func:`sdf_custom` (``fn``: the custom SDF, 0 for none: NaN)."""
    if bd[0] == CUSTOM:
        if fn == 0:
            return math.nan, math.nan, math.nan, math.nan
        return sdf_custom(fn, dim, bd, x, y, z, rot, geo, grad)
    return sdf_pair(dim, bd, x, y, z, rot, normal, geo, grad)
