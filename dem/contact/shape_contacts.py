"""The contacts of the shape loop (:mod:`dem.contact.shape_loop`): the detection method
of each pair of shape kinds, and one pair or wall contact detected and turned into forces.

A pair's method (:func:`method_for`, :func:`wall_method_for`) is fixed when the pair list
is made: closed forms for sphere-sphere, sphere-box and sphere-polytope, the exact
polytope solver for box/polygon/polyhedron pairs and walls, ADMM for anything involving
a user-defined shape (its call stays in the loop, where it is bound to the user's SDF).
"""

import math

import numpy as np

from .._jit import kernel
from ..shapes.kinds import BOX, CUSTOM, SPHERE
from ..shapes.registry import kinds_with
from ..status import OVERLAP
from .detection.analytic import sphere_box, sphere_polytope
from .detection.polytope import polytope_contact, polytope_plane
from .kinematics import add_strain_rate, turn_spring
from .laws import apply_law

#: detection methods
M_SPHERES, M_SPHERE_BOX, M_SPHERE_POLY, M_POLY, M_ADMM = 0, 1, 2, 3, 4
#: wall methods
W_SPHERE, W_POLY, W_ADMM = 0, 1, 2


def method_for(ka, kb, force_admm=False):
    """Detection method for a pair of shape kinds ``ka <= kb`` (walls apart)."""
    poly = kinds_with("polytope")
    if ka == SPHERE and kb == SPHERE:
        return M_SPHERES
    if force_admm or CUSTOM in (ka, kb):
        return M_ADMM
    if ka == SPHERE and kb == BOX:
        return M_SPHERE_BOX
    if ka == SPHERE and kb in poly:
        return M_SPHERE_POLY
    if ka in poly and kb in poly:
        return M_POLY
    raise ValueError(f"no contact detection for shape kinds {ka} and {kb}")


def wall_method_for(k, force_admm=False):
    if k == SPHERE:
        return W_SPHERE
    if force_admm or k == CUSTOM:
        return W_ADMM
    return W_POLY


# --------------------------------------------------------------------------- one contact
@kernel(inline=True)
def _velocity_at(dim, vel, ang_vel, b, rx, ry, rz):
    """Velocity of body b's material point at arm r from its centre."""
    if dim == 2:
        w = ang_vel[b, 0]
        return vel[b, 0] - w * ry, vel[b, 1] + w * rx, 0.0
    wx, wy, wz = ang_vel[b, 0], ang_vel[b, 1], ang_vel[b, 2]
    return (vel[b, 0] + wy * rz - wz * ry, vel[b, 1] + wz * rx - wx * rz,
            vel[b, 2] + wx * ry - wy * rx)


@kernel(inline=True)
def _sphere_sphere(dim, a, b, sx, sy, sz, pos, radius):
    dx = pos[b, 0] + sx - pos[a, 0]
    dy = pos[b, 1] + sy - pos[a, 1]
    dz = (pos[b, 2] + sz - pos[a, 2]) if dim == 3 else 0.0
    dist = math.sqrt(dx * dx + dy * dy + dz * dz)
    ov = radius[a] + radius[b] - dist
    if ov <= 0.0 or dist == 0.0:
        return ov, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    nx, ny, nz = dx / dist, dy / dist, dz / dist
    t = radius[a] - 0.5 * ov
    return ov, nx, ny, nz, pos[a, 0] + t * nx, pos[a, 1] + t * ny, (
        pos[a, 2] + t * nz if dim == 3 else 0.0)


@kernel(inline=True)
def _image_shift(dim, hmat, img, k):
    """Shift [m] of pair k's periodic image of j: ``H @ img[k]``."""
    sx = hmat[0, 0] * img[k, 0] + hmat[0, 1] * img[k, 1]
    sy = hmat[1, 0] * img[k, 0] + hmat[1, 1] * img[k, 1]
    sz = 0.0
    if dim == 3:
        sx += hmat[0, 2] * img[k, 2]
        sy += hmat[1, 2] * img[k, 2]
        sz = hmat[2, 0] * img[k, 0] + hmat[2, 1] * img[k, 1] + hmat[2, 2] * img[k, 2]
    return sx, sy, sz


@kernel
def pair_exact(dim, meth, a, b, sx, sy, sz, pos, rot, radius, shape, geo):
    """Contact of A = a and B = b (+ shift) by a closed form or the polytope solver.

    Returns ``(ov, nx, ny, nz, cx, cy, cz)``; ``ov <= 0`` when apart (the bounding
    spheres apart: -1 without detection). A real call, not inlined: the time loop stays
    small to compile.
    """
    ox = pos[b, 0] + sx - pos[a, 0]
    oy = pos[b, 1] + sy - pos[a, 1]
    oz = (pos[b, 2] + sz - pos[a, 2]) if dim == 3 else 0.0
    cut = radius[a] + radius[b]
    if ox * ox + oy * oy + oz * oz >= cut * cut:
        return -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if meth == M_SPHERES:
        return _sphere_sphere(dim, a, b, sx, sy, sz, pos, radius)
    if meth == M_SPHERE_BOX:
        r = sphere_box(dim, a, radius[a], shape[b], b, sx, sy, sz, pos, rot, geo)
    elif meth == M_SPHERE_POLY:
        r = sphere_polytope(dim, a, radius[a], shape[b], b, sx, sy, sz, pos, rot, geo)
    else:  # the body indices as int64, as Python passes them: one compile serves both
        r = polytope_contact(dim, shape[a], np.int64(a), shape[b], np.int64(b), sx, sy, sz,
                             pos, rot, geo)
    return r[0], r[1], r[2], r[3], r[4], r[5], r[6]


@kernel
def wall_exact(dim, meth, i, w, pos, rot, radius, normal, shape, geo):
    """Contact of body i with wall w: closed form (sphere) or deepest vertices."""
    gap = 0.0
    for c in range(dim):
        gap += (pos[i, c] - pos[w, c]) * normal[w, c]
    if gap >= radius[i]:
        return -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if meth == W_SPHERE:
        ov = radius[i] - gap
        nx, ny = -normal[w, 0], -normal[w, 1]
        nz = -normal[w, 2] if dim == 3 else 0.0
        t = radius[i] - 0.5 * ov
        cz = pos[i, 2] + t * nz if dim == 3 else 0.0
        return ov, nx, ny, nz, pos[i, 0] + t * nx, pos[i, 1] + t * ny, cz
    r = polytope_plane(dim, shape[i], i, w, pos, rot, normal, geo)
    return r[0], r[1], r[2], r[3], r[4], r[5], r[6]


@kernel
def pair_force(dim, code, deform, rate, turns, spin, k, i, j, a, b, swap, sx, sy, sz, ov,
               nx, ny, nz, cx, cy, cz, pos, vel, ang_vel, ra, rb, inv_mass, mat_id, params,
               hist, touch, fpair, tpair, pgeom, dt, overlap_limit, status_out):
    """Law and rows of pair k (bodies i < j; A = a, B = b + shift; ``ra``, ``rb`` the
    radii of the touching parts): force on j in
    ``fpair[k]``, torques on i and j in ``tpair[k]``, geometry in ``pgeom[k]``. In a
    deforming cell (``deform``) the bodies' velocities are fluctuations about the
    affine field ``L x``, whose stretching ``D l`` across the branch vector is added
    (``rate``: ``L``, or the stretching of :func:`dem.contact.kinematics.cell_spin` when
    ``turns``; the spin turns the pair as a whole, and its spring with it)."""
    nr = tpair.shape[1] // 2
    if ov <= 0.0:
        if touch[k]:  # the contact opened: its history ends
            touch[k] = 0
            for c in range(hist.shape[1]):
                hist[k, c] = 0.0
        for c in range(fpair.shape[1]):
            fpair[k, c] = 0.0
        for c in range(tpair.shape[1]):
            tpair[k, c] = 0.0
        pgeom[k, 0] = 0.0
        return
    touch[k] = 1
    if ov > overlap_limit * min(ra, rb):
        status_out[0] = OVERLAP
        status_out[1] = i
        status_out[2] = j
    # arms from each centre to the contact point
    rax, ray = cx - pos[a, 0], cy - pos[a, 1]
    raz = cz - pos[a, 2] if dim == 3 else 0.0
    rbx, rby = cx - pos[b, 0] - sx, cy - pos[b, 1] - sy
    rbz = cz - pos[b, 2] - sz if dim == 3 else 0.0
    vax, vay, vaz = _velocity_at(dim, vel, ang_vel, a, rax, ray, raz)
    vbx, vby, vbz = _velocity_at(dim, vel, ang_vel, b, rbx, rby, rbz)
    r_eff = ra * rb / (ra + rb)
    im = inv_mass[a] + inv_mass[b]
    m_eff = 1.0 / im if im > 0.0 else 0.0  # two fixed bodies: no dashpot
    rvx, rvy, rvz = vbx - vax, vby - vay, vbz - vaz
    if deform:
        lx = pos[b, 0] + sx - pos[a, 0]
        ly = pos[b, 1] + sy - pos[a, 1]
        lz = pos[b, 2] + sz - pos[a, 2] if dim == 3 else 0.0
        rvx, rvy, rvz = add_strain_rate(dim, rate, lx, ly, lz, rvx, rvy, rvz)
        if turns:
            turn_spring(dim, spin, hist, k)
    fx, fy, fz = apply_law(code, ov, nx, ny, nz, rvx, rvy, rvz, r_eff, m_eff, params,
                           mat_id[a], mat_id[b], hist, k, dt)
    sgn = -1.0 if swap else 1.0  # rows are in (i, j) orientation
    fpair[k, 0] = sgn * fx
    fpair[k, 1] = sgn * fy
    ti = nr if swap else 0  # where A's torque goes
    tj = 0 if swap else nr
    if dim == 2:
        tpair[k, ti] = -(rax * fy - ray * fx)
        tpair[k, tj] = rbx * fy - rby * fx
    else:
        fpair[k, 2] = sgn * fz
        tpair[k, ti] = -(ray * fz - raz * fy)
        tpair[k, ti + 1] = -(raz * fx - rax * fz)
        tpair[k, ti + 2] = -(rax * fy - ray * fx)
        tpair[k, tj] = rby * fz - rbz * fy
        tpair[k, tj + 1] = rbz * fx - rbx * fz
        tpair[k, tj + 2] = rbx * fy - rby * fx
    # contact geometry in (i, j) orientation: overlap, normal i->j, point
    pgeom[k, 0] = ov
    pgeom[k, 1] = sgn * nx
    pgeom[k, 2] = sgn * ny
    pgeom[k, 3] = sgn * nz
    pgeom[k, 4] = cx
    pgeom[k, 5] = cy
    pgeom[k, 6] = cz


@kernel
def wall_force(dim, code, k, i, w, ov, nx, ny, nz, cx, cy, cz, pos, vel, ang_vel, ri,
               inv_mass, mat_id, params, whist, wforce, wtorque, wgeom, dt, overlap_limit,
               status_out):
    """Law and rows of wall pair k (body i, its touching part of radius ``ri``, wall w);
    returns the wall's power on i [W]."""
    if ov <= 0.0:
        for c in range(whist.shape[1]):
            whist[k, c] = 0.0
        for c in range(wforce.shape[1]):
            wforce[k, c] = 0.0
        for c in range(wtorque.shape[1]):
            wtorque[k, c] = 0.0
        wgeom[k, 0] = 0.0
        return 0.0
    if ov > overlap_limit * ri:
        status_out[0] = OVERLAP
        status_out[1] = i
        status_out[2] = w
    rx, ry = cx - pos[i, 0], cy - pos[i, 1]
    rz = cz - pos[i, 2] if dim == 3 else 0.0
    vix, viy, viz = _velocity_at(dim, vel, ang_vel, i, rx, ry, rz)
    vwx, vwy = vel[w, 0], vel[w, 1]
    vwz = vel[w, 2] if dim == 3 else 0.0
    m = 1.0 / inv_mass[i] if inv_mass[i] > 0.0 else 0.0
    fx, fy, fz = apply_law(code, ov, nx, ny, nz, vwx - vix, vwy - viy, vwz - viz,
                           ri, m, params, mat_id[i], mat_id[w], whist, k, dt)
    # the body gets -f at arm r
    wforce[k, 0] = -fx
    wforce[k, 1] = -fy
    if dim == 3:
        wforce[k, 2] = -fz
        wtorque[k, 0] = -(ry * fz - rz * fy)
        wtorque[k, 1] = -(rz * fx - rx * fz)
        wtorque[k, 2] = -(rx * fy - ry * fx)
    else:
        wtorque[k, 0] = -(rx * fy - ry * fx)
    wgeom[k, 0] = ov
    wgeom[k, 1] = nx
    wgeom[k, 2] = ny
    wgeom[k, 3] = nz
    wgeom[k, 4] = cx
    wgeom[k, 5] = cy
    wgeom[k, 6] = cz
    return -(fx * vwx + fy * vwy + fz * vwz)


@kernel
def pair_incidence(pairs, n, start_out, list_out):
    """CSR of each body's pairs, in pair order: entries ``2 k + side`` (side 1: body is j)."""
    start_out[:] = 0
    for k in range(pairs.shape[0]):
        start_out[pairs[k, 0] + 1] += 1
        start_out[pairs[k, 1] + 1] += 1
    for b in range(n):
        start_out[b + 1] += start_out[b]
    fill = start_out[:n].copy()
    for k in range(pairs.shape[0]):
        i = pairs[k, 0]
        j = pairs[k, 1]
        list_out[fill[i]] = 2 * k
        fill[i] += 1
        list_out[fill[j]] = 2 * k + 1
        fill[j] += 1
