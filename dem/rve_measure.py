"""Compiled homogenisation of a periodic packing of spheres/disks or level-set shapes
(kernel module).

One pass over the Verlet pairs of an RVE gives what a relaxation checks every few dozen
steps and what a Gauss point returns: the Love-Weber stress with periodic branch
vectors plus the kinetic part, the unbalanced-force ratio, the contact-stiffness
tangent (paper eq 29), the fabric tensor and each body's contact count. It is the
compiled twin of :func:`dem.observers.contact_summary` followed by the sums of
:meth:`dem.rve.RVE.response`; the tests hold the two equal, and its unbalanced-force
ratio equal bit for bit to the relaxation check the step loop runs
(:mod:`dem.contact.relaxation`).

A pair of spheres touches when ``r_i + r_j - |l| > 0`` with ``l = x_j - x_i + H m`` the
branch vector across the pair's periodic image ``m``; a pair of shapes when the loop's
contact geometry has a positive overlap: the tests of ``contact_summary``, on the forces
of the last force evaluation (``fpair``, the force on j). The branch vector joins the
centres for every shape: with it the Love-Weber sum is the static stress of rigid bodies
of any shape in equilibrium.
"""

import math

from ._jit import kernel
from .contact.laws import law_stiffness
from .contact.relaxation import add_pair_force, branch, force_ratio


@kernel
def measure_periodic(code, pos, vel, mass, radius, mat_id, pairs, img, hmat, fpair,
                     shaped, pgeom, params, volume, use_tangent, net_out, degree_out,
                     stress_out, tangent_out, fabric_out):
    """Stress, tangent, fabric and unbalanced force of the touching pairs.

    Parameters
    ----------
    code : int
        Law code of the sphere-sphere contacts (:data:`dem.contact.laws.LAWS`).
    pos, vel : (n, d) f8
        Positions [m] and fluctuation velocities [m/s].
    mass, radius : (n,) f8
        [kg], [m].
    mat_id : (n,) i8
    pairs, img : (m, 2) i8, (m, d) i8
        Verlet pairs and the periodic image of j.
    hmat : (d, d) f8
        Cell matrix [m] (columns are the cell vectors).
    fpair : (m, d) f8
        Force on j [N] of each pair at the last force evaluation.
    shaped : bool
        Level-set shapes: a pair touches, and has its normal, by the loop's contact
        geometry ``pgeom`` (m, 7) (overlap, normal i->j, point) instead of the radii
        (``radius`` is then the bounding radius, read by Hertz-Mindlin's stiffness).
    params : (n_mat, n_mat, n_p) f8
        The law's pair-parameter table.
    volume : float
        Cell volume [m^3] (area [m^2] in 2D).
    use_tangent : bool
        Compute ``tangent_out`` (eq 29); else it is left as it is.

    Modified in place: ``net_out`` (n, d) net contact force per body [N];
    ``degree_out`` (n,) contacts per body; ``stress_out`` (d, d) [Pa], tension
    positive, symmetrised; ``tangent_out`` (d, d, d, d) [Pa]; ``fabric_out`` (d, d),
    the mean of n (x) n over contacts (zero without contacts).

    Returns ``(n_contacts, unbalanced)``: the touching pairs and the unbalanced-force
    ratio, the mean norm of the net contact force on a body over the mean contact
    force norm (infinite without contacts).
    """
    d = pos.shape[1]
    net_out[:, :] = 0.0
    degree_out[:] = 0
    stress_out[:, :] = 0.0
    fabric_out[:, :] = 0.0
    if use_tangent:
        tangent_out[:, :, :, :] = 0.0
    n_c = 0
    fsum = 0.0
    br = [0.0, 0.0, 0.0]
    nv = [0.0, 0.0, 0.0]
    for k in range(pairs.shape[0]):
        i = pairs[k, 0]
        j = pairs[k, 1]
        dist = branch(k, d, pos, pairs, img, hmat, br)
        if shaped:
            ov = pgeom[k, 0]
            for a in range(d):
                nv[a] = pgeom[k, 1 + a]
        else:
            ov = radius[i] + radius[j] - dist
            for a in range(d):
                nv[a] = br[a] / dist
        if not ov > 0.0:
            continue
        n_c += 1
        degree_out[i] += 1
        degree_out[j] += 1
        fsum += add_pair_force(k, i, j, d, fpair, net_out)
        for a in range(d):
            for b in range(d):
                stress_out[a, b] -= fpair[k, a] * br[b]
        for a in range(d):
            for b in range(d):
                fabric_out[a, b] += nv[a] * nv[b]
        if use_tangent:
            r_eff = radius[i] * radius[j] / (radius[i] + radius[j])
            kn, kt = law_stiffness(code, ov, r_eff, params[mat_id[i], mat_id[j]])
            _add_pair_tangent(d, kn, kt, nv, br, tangent_out)
    _finish_stress(mass, vel, volume, use_tangent, stress_out, tangent_out)
    if n_c == 0:
        return 0, math.inf
    for a in range(d):
        for b in range(d):
            fabric_out[a, b] /= n_c
    return n_c, force_ratio(net_out, n_c, fsum)


@kernel(inline=True)
def _add_pair_tangent(d, kn, kt, nv, br, tangent_out):
    """Add one contact's ``(kn n n + kt (I - n n)) (x) l (x) l`` to the tangent (eq 29)."""
    for a in range(d):
        for b in range(d):
            for c in range(d):
                kron = 1.0 if a == c else 0.0
                sn = kn * nv[a] * nv[c] + kt * (kron - nv[a] * nv[c])
                for e in range(d):
                    tangent_out[a, b, c, e] += sn * br[b] * br[e]


@kernel
def _finish_stress(mass, vel, volume, use_tangent, stress_out, tangent_out):
    """Add the fluctuations' kinetic part, symmetrise and divide by the volume."""
    n, d = vel.shape
    for p in range(n):
        for a in range(d):
            for b in range(d):
                stress_out[a, b] -= mass[p] * vel[p, a] * vel[p, b]
    for a in range(d):
        for b in range(a, d):
            s = 0.5 * (stress_out[a, b] + stress_out[b, a]) / volume
            stress_out[a, b] = s
            stress_out[b, a] = s
    if use_tangent:
        for a in range(d):
            for b in range(d):
                for c in range(d):
                    for e in range(d):
                        tangent_out[a, b, c, e] /= volume
