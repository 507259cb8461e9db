"""The tangential spring every built-in law uses: a spring and a dashpot in parallel,
in series with a Coulomb slider, its elongation in the contact's history columns 0-2.

Tangential history is a time-dependent state: its rate is the tangential relative
velocity. It is advanced with the relative velocity at mid-step (the velocity Verlet
half-step velocity), i.e. the midpoint rule, second order in ``dt``; before each update
it is projected onto the current tangent plane (the contact frame rotates).
"""

import math

from ..._jit import kernel

#: history columns of the tangential spring (its elongation vector [m])
N_HIST = 3


@kernel(inline=True)
def tangential(hist, k, nx, ny, nz, tvx, tvy, tvz, kt, ct, cap, dt):
    """Tangential force of a spring ``kt`` [N/m] and a dashpot ``ct`` [N s/m] in
    parallel, in series with a Coulomb slider of limit ``cap`` [N]; updates the
    spring ``hist[k]`` [m] (rotated into the current tangent plane first).

    Sticking, the pair stretches with the tangential velocity ``tv`` [m/s]:
    ``f = -kt s - ct tv``. Sliding (the trial force above ``cap``), the pair carries
    exactly the capped force, and its own stretch rate is what the dashpot then
    needs: ``kt s_new + ct (s_new - s_old) / dt = -f``, so the spring moves from its
    old length towards ``cap / kt`` along the force, never against it. With no
    dashpot that is the usual reset ``s = -f / kt``. With ``dt`` = 0 (a pass that
    evaluates forces without advancing time) the spring keeps its length, the limit
    of that rule as ``dt`` goes to 0.
    """
    sn = hist[k, 0] * nx + hist[k, 1] * ny + hist[k, 2] * nz
    rx, ry, rz = hist[k, 0] - sn * nx, hist[k, 1] - sn * ny, hist[k, 2] - sn * nz
    sx, sy, sz = rx + tvx * dt, ry + tvy * dt, rz + tvz * dt
    ftx, fty, ftz = -kt * sx - ct * tvx, -kt * sy - ct * tvy, -kt * sz - ct * tvz
    ft2 = ftx * ftx + fty * fty + ftz * ftz
    if ft2 > cap * cap:  # sliding
        scale = cap / math.sqrt(ft2)
        ftx, fty, ftz = ftx * scale, fty * scale, ftz * scale
        # dt = 0 evaluates without advancing (a priming pass): the spring stays
        w = ct / dt if dt > 0.0 else 0.0
        if dt > 0.0 and kt + w > 0.0:
            sx = (w * rx - ftx) / (kt + w)
            sy = (w * ry - fty) / (kt + w)
            sz = (w * rz - ftz) / (kt + w)
    hist[k, 0], hist[k, 1], hist[k, 2] = sx, sy, sz
    return ftx, fty, ftz
