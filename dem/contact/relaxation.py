"""The unbalanced-force ratio, and the relaxation check of the sphere loop (kernel module).

A quasi-static run is at rest when the forces on every body nearly cancel. The measure
used throughout (an RVE's relaxation, :meth:`dem.Simulation.relax`, YADE's
``unbalancedForce``) is the ratio of the mean norm of the net contact force on a body
to the mean norm of the contact forces, over the touching body-body pairs: walls and
mesh walls are not counted. A pair touches when ``r_i + r_j - |l| > 0``, ``l`` its
branch vector across its periodic image; its force is that of the last force
evaluation (``fpair``, the force on j).

:func:`unbalanced_ratio` computes it in the order of
:func:`dem.rve_measure.measure_periodic`, so the two agree bit for bit; the sphere loop
calls :func:`relax_check` every ``every`` steps when asked, and stops as soon as the
ratio is below its tolerance (or the packing has come apart), instead of returning to
Python after every check.
"""

import math

from .._jit import kernel
from ..status import CAME_APART, OK, RELAXED

#: the entry of ``RelaxCheck.out`` (:class:`dem.state.RelaxCheck`) that holds the steps
#: to the next check
OUT_NEXT = 4


@kernel(inline=True)
def branch(k, d, pos, pairs, img, hmat, br):
    """Branch vector of pair ``k`` into ``br`` (j's centre across its image minus i's)
    and its length [m]."""
    i = pairs[k, 0]
    j = pairs[k, 1]
    dist2 = 0.0
    for a in range(d):
        la = pos[j, a] - pos[i, a]
        for c in range(d):
            la += hmat[a, c] * img[k, c]
        br[a] = la
        dist2 += la * la
    return math.sqrt(dist2)


@kernel(inline=True)
def add_pair_force(k, i, j, d, fpair, net):
    """Add pair ``k``'s force (on j; i gets the opposite) to the rows of ``net``;
    returns its norm [N]."""
    f2 = 0.0
    for a in range(d):
        fa = fpair[k, a]
        f2 += fa * fa
        net[i, a] -= fa
        net[j, a] += fa
    return math.sqrt(f2)


@kernel(inline=True)
def force_ratio(net, n_c, fsum):
    """The mean norm of the rows of ``net`` (n, d) [N] over the mean contact force,
    ``fsum / n_c`` (``n_c`` > 0); ``inf`` without force."""
    n, d = net.shape
    total = 0.0
    for p_ in range(n):
        s = 0.0
        for a in range(d):
            s += net[p_, a] * net[p_, a]
        total += math.sqrt(s)
    fmean = fsum / n_c
    if not fmean > 0.0:
        return math.inf
    return (total / n) / fmean


@kernel
def unbalanced_ratio(pos, radius, pairs, img, hmat, fpair, net):
    """``(n_contacts, ratio)`` of spheres or disks: the touching pairs and the mean
    net contact force norm on a body over the mean contact force norm (infinite
    without contacts or forces). ``net`` (n, d) is scratch, left holding each body's
    net contact force [N]."""
    d = pos.shape[1]
    net[:, :] = 0.0
    n_c = 0
    fsum = 0.0
    br = [0.0, 0.0, 0.0]
    for k in range(pairs.shape[0]):
        dist = branch(k, d, pos, pairs, img, hmat, br)
        i = pairs[k, 0]
        j = pairs[k, 1]
        if not radius[i] + radius[j] - dist > 0.0:
            continue
        n_c += 1
        fsum += add_pair_force(k, i, j, d, fpair, net)
    if n_c == 0:
        return 0, math.inf
    return n_c, force_ratio(net, n_c, fsum)


@kernel
def relax_check(pos, radius, pairs, img, hmat, fpair, check):
    """One check of a relaxation (:class:`dem.state.RelaxCheck`): ``RELAXED`` when the
    ratio is below ``check.tol``; ``CAME_APART`` when the coordination number (2 contacts
    per body) was below ``check.min_coordination`` at ``check.apart_checks`` checks in a
    row; else ``OK``. ``check.out`` gets the ratio, the contacts, the low checks in a
    row, one more check, and the steps to the next (``check.every``)."""
    n_c, ratio = unbalanced_ratio(pos, radius, pairs, img, hmat, fpair, check.net)
    out = check.out
    out[0] = ratio
    out[1] = n_c
    out[3] += 1.0
    out[OUT_NEXT] = check.every
    if ratio < check.tol:
        return RELAXED
    if 2.0 * n_c / pos.shape[0] < check.min_coordination:
        out[2] += 1.0
        if check.apart_checks > 0 and out[2] >= check.apart_checks:
            return CAME_APART
    else:
        out[2] = 0.0
    return OK
