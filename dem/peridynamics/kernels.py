"""Compiled peridynamic kernels: bond pass, force pass, and the time stepper (the contact
pass is :mod:`.contact`'s).

Every kernel is dimension-generic (``d`` is read from the arrays) and serves both
materials (a scalar branch on the model code), so one compilation serves every scene.
Forces are gathered per point from its own bonds (each bond is stored in both
directions), so the bond passes run in parallel over points without races, and their
sums, in family order, do not depend on the number of threads.
"""

import math
from typing import NamedTuple

import numpy as np
from numba import prange

from .._jit import kernel
from ..status import NONFINITE, OK, REBUILD
from .contact import contact_pass
from .materials import P_ALPHA, P_C, P_CORR, P_KAPPA, P_MODEL, P_SCRIT, PMB_CODE


class Bonds(NamedTuple):
    """The bonds of a peridynamic scene, what the bond and force passes read: the
    families (``start`` (n + 1,), ``nbr``, ``twin`` (nb,) int64 and reference
    ``length`` (nb,) [m], each bond stored in both directions), the influence ``omega``
    (nb,), the points' volumes ``vol`` (n,) [m^3], the dilation weights ``qw`` (nb,),
    the inverse weighted volume of each bond's owner ``pw`` (nb,), the surface
    corrections ``corr`` (n,), the dilation ``theta`` and the weighted deviatoric
    extension ``sdev`` (n,) of the current state (written by the bond pass), the
    material row ``params`` and the broken flags ``broken`` (nb,) uint8."""

    start: np.ndarray
    nbr: np.ndarray
    twin: np.ndarray
    length: np.ndarray
    omega: np.ndarray
    vol: np.ndarray
    qw: np.ndarray
    pw: np.ndarray
    corr: np.ndarray
    theta: np.ndarray
    sdev: np.ndarray
    params: np.ndarray
    broken: np.ndarray


class Loads(NamedTuple):
    """The loads of a peridynamic scene: body force ``bforce`` (n, d) [N] scaled by the
    profile ``(prof_t, prof_v)`` (times [s] and factors; empty: 1), and ``gravity``
    (d,) [m/s^2]."""

    bforce: np.ndarray
    prof_t: np.ndarray
    prof_v: np.ndarray
    gravity: np.ndarray


@kernel(inline=True)
def distance(pos, i, j):
    """``|x_j - x_i|``."""
    r2 = 0.0
    for k in range(pos.shape[1]):
        y = pos[j, k] - pos[i, k]
        r2 += y * y
    return math.sqrt(r2)


@kernel
def weighted_volume(start, nbr, length, omega, vol, m_out):
    """``m_i = sum_j w |xi|^2 V_j`` over every bond (broken or not)."""
    for i in range(start.size - 1):
        s = 0.0
        for b in range(start[i], start[i + 1]):
            s += omega[b] * length[b] * length[b] * vol[nbr[b]]
        m_out[i] = s


@kernel(parallel=True)
def bond_pass(pos, start, nbr, length, omega, vol, qw, pw, params, broken, theta_out,
              sdev_out):
    """Break over-stretched bonds, then each point's dilation and deviatoric moment (LPS).

    ``theta_i = sum_j w |xi| e V_j q_j`` and ``S_i = sum_j w e^d |xi| V_j``, with the
    per-bond weights ``q = d / m_i`` (or its surface-corrected value) and ``p = 1 / m_i``.
    Without the correction ``S_i`` is zero wherever every bond of the point is intact
    (``m_i`` sums the whole family): it is set to 0 there without a second pass over
    the bonds, and summed only for points with a broken bond or corrected weights. Both
    directions of a bond see the same stretch bit for bit, so they break in the same
    pass. Modified in place: ``broken``, ``theta_out``, ``sdev_out``.
    """
    n, d = pos.shape
    s_crit = params[P_SCRIT]
    lps = params[P_MODEL] != PMB_CODE
    for i in prange(n):
        th = 0.0
        for b in range(start[i], start[i + 1]):
            if broken[b]:
                continue
            j = nbr[b]
            e = distance(pos, i, j) - length[b]
            if e > s_crit * length[b]:
                broken[b] = 1
                continue
            if lps:
                th += omega[b] * length[b] * e * vol[j] * qw[b]
        theta_out[i] = th
    if not lps:
        return
    corrected = params[P_CORR] != 0.0
    for i in prange(n):
        whole = not corrected
        if whole:
            for b in range(start[i], start[i + 1]):
                if broken[b]:
                    whole = False
                    break
        if whole:
            sdev_out[i] = 0.0
            continue
        sd = 0.0
        for b in range(start[i], start[i + 1]):
            if broken[b]:
                continue
            j = nbr[b]
            e = distance(pos, i, j) - length[b]
            sd += omega[b] * (e - theta_out[i] * length[b] / d) * length[b] * vol[j]
        sdev_out[i] = sd


@kernel
def _lps_t(kap, alpha, d, theta, sdev, p, w, L, q, e):
    """LPS scalar force state of one bond direction (see :mod:`.materials`)."""
    a = alpha * p
    return kap * theta * w * L * q + a * w * (e - theta * L / d) - a / d * sdev * w * L * q


@kernel(parallel=True)
def force_pass(pos, start, nbr, twin, length, omega, vol, qw, pw, corr, theta, sdev, params,
               broken, force_out):
    """Peridynamic force [N] on every point, added to ``force_out``."""
    n, d = pos.shape
    lps = params[P_MODEL] != PMB_CODE
    kap, alpha, c = params[P_KAPPA], params[P_ALPHA], params[P_C]
    for i in prange(n):
        for b in range(start[i], start[i + 1]):
            if broken[b]:
                continue
            j = nbr[b]
            r = distance(pos, i, j)
            L = length[b]
            e = r - L
            if lps:
                w = omega[b]
                bt = twin[b]
                t = (_lps_t(kap, alpha, d, theta[i], sdev[i], pw[b], w, L, qw[b], e)
                     + _lps_t(kap, alpha, d, theta[j], sdev[j], pw[bt], w, L, qw[bt], e))
            else:
                t = c * 0.5 * (corr[i] + corr[j]) * e / L
            f = t * vol[i] * vol[j] / r
            for k in range(d):
                force_out[i, k] += f * (pos[j, k] - pos[i, k])


@kernel
def energy_density(pos, start, nbr, length, omega, vol, pw, corr, theta, params, broken,
                   w_out):
    """Strain-energy density [J/m^3] of every point (``sum_i W_i V_i`` is the energy)."""
    n, d = pos.shape
    lps = params[P_MODEL] != PMB_CODE
    kap, alpha, c = params[P_KAPPA], params[P_ALPHA], params[P_C]
    for i in range(n):
        w_i = 0.5 * kap * theta[i] * theta[i] if lps else 0.0
        for b in range(start[i], start[i + 1]):
            if broken[b]:
                continue
            j = nbr[b]
            L = length[b]
            e = distance(pos, i, j) - L
            if lps:
                ed = e - theta[i] * L / d
                w_i += 0.5 * alpha * pw[b] * omega[b] * ed * ed * vol[j]
            else:
                w_i += 0.25 * c * 0.5 * (corr[i] + corr[j]) * e * e / L * vol[j]
        w_out[i] = w_i


@kernel
def forces(pos, vel, radius, mass, fixed, bonds, contacts, loads, scale, dt, force_out):
    """Every force of the current state into ``force_out`` (zeroed first): the body
    force of ``loads`` times ``scale``, gravity, then the bonds (:class:`Bonds`; their
    dilations are written into ``bonds.theta`` and ``bonds.sdev``) and the contacts
    (:class:`~dem.peridynamics.contact.Contacts`, whose laws advance their history by
    ``dt``; 0 leaves it). The bundles are unpacked here, outside the parallel passes."""
    (start, nbr, twin, length, omega, vol, qw, pw, corr, theta, sdev, params,
     broken) = bonds
    bforce, gravity = loads.bforce, loads.gravity
    n, d = pos.shape
    for i in range(n):
        for k in range(d):
            force_out[i, k] = scale * bforce[i, k]
            if not fixed[i]:
                force_out[i, k] += mass[i] * gravity[k]
    bond_pass(pos, start, nbr, length, omega, vol, qw, pw, params, broken, theta, sdev)
    force_pass(pos, start, nbr, twin, length, omega, vol, qw, pw, corr, theta, sdev, params,
               broken, force_out)
    contact_pass(pos, vel, mass, radius, start, nbr, broken, contacts, dt, force_out)


@kernel
def _damped(f, v, damping):
    """Cundall's local damping: the force less ``damping |f|`` against the velocity."""
    if damping > 0.0 and v != 0.0:
        return f - damping * abs(f) * (1.0 if v > 0.0 else -1.0)
    return f


@kernel
def step_chunk(n_steps, t0, dt, damping, pos, vel, radius, mass, fixed, bonds, contacts,
               loads, pos_ref, half_skin, force, status):
    """Up to ``n_steps`` velocity-Verlet steps; returns the number done.

    Per step: half kick with the force of the last step, drift (fixed bodies move with
    their prescribed velocity), forces at the new positions (bond breaking, dilation,
    bond forces, contact, body force times its profile at the new time, gravity), second
    half kick; with ``damping``, both kicks use Cundall's local damping. A step after
    which a body has moved more than ``half_skin`` since the contact list was built
    ends the chunk with ``REBUILD`` (the step itself is complete); a non-finite state,
    or a body that moves more than its radius in one step (a run blowing up), ends it
    with ``NONFINITE``.
    """
    prof_t, prof_v = loads.prof_t, loads.prof_v
    n, d = pos.shape
    status[0] = OK
    status[1] = -1
    for s in range(n_steps):
        h = 0.5 * dt
        for i in range(n):
            if fixed[i]:
                for k in range(d):
                    pos[i, k] += dt * vel[i, k]
            else:
                for k in range(d):
                    vel[i, k] += h * _damped(force[i, k], vel[i, k], damping) / mass[i]
                    pos[i, k] += dt * vel[i, k]
        t = t0 + (s + 1) * dt
        scale = np.interp(t, prof_t, prof_v) if prof_t.size else 1.0
        forces(pos, vel, radius, mass, fixed, bonds, contacts, loads, scale, dt, force)
        far = 0.0
        for i in range(n):
            if fixed[i]:
                continue
            m2 = 0.0
            v2 = 0.0
            for k in range(d):
                vel[i, k] += h * _damped(force[i, k], vel[i, k], damping) / mass[i]
                u = pos[i, k] - pos_ref[i, k]
                m2 += u * u
                v2 += vel[i, k] * vel[i, k]
            if not (m2 < 1e300 and v2 * dt * dt <= radius[i] * radius[i]):
                status[0] = NONFINITE
                status[1] = i
                return s + 1
            far = max(far, m2)
        if far > half_skin * half_skin:
            status[0] = REBUILD
            return s + 1
    return n_steps
