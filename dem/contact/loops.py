"""The compiled time-step loop for sphere scenes: one loop per (dimension, laws).

``stepper(dim, law_pp, law_pw)`` returns a kernel that advances the scene by up to
``n_steps`` velocity Verlet steps inside one call. The dimension and the two contact
laws (sphere-sphere, sphere-wall) are compile-time constants of the returned kernel, so
a 2D scene runs 2D code and a scene runs only the laws it uses. Kernels are memoised.

One step, in this order (the ``Simulation.run`` contract):

1. half kick and drift of free bodies (``v += dt/2 F/m``, ``x += dt v``, angle or
   quaternion update); fixed bodies drift at their prescribed velocity;
2. if a body is now more than ``skin_inner / 2`` from where the inner list was made
   (less any radius growth), refresh the inner list (the Verlet pairs closer than
   ``r_i + r_j + skin_inner``, the only ones evaluated every step); if the Verlet list
   itself no longer holds (a body more than ``skin / 2`` from where it was built):
   stop with status ``REBUILD``; Python rebuilds the list and calls again with
   ``resume=True``, which finishes this step from 3;
3. sphere-sphere contacts: overlap, relative velocity at the contact point, law;
4. sphere-wall contacts, likewise;
5. per body: sum of contact forces, gravity, local damping, second half kick.

Summation order is fixed, so results do not depend on the number of threads. Bodies
fall into ``N_BLOCKS`` blocks of consecutive rows (a fixed number, whatever the thread
count); a contact inside one block is *internal*, others are *cross*. Every body sums
its internal contacts in pair order, then its cross contacts in pair order, then its
walls. On one thread, 3 and 4 add each contact to its bodies as they go, in that order.
On several threads, the internal contacts run in parallel over blocks, each block adding
into its own bodies; the cross contacts run in parallel over pairs and write their two
contributions to rows laid out body by body in pair order; 5 adds each body's rows and
walls in parallel. The sums are the same, bit for bit. With bodies in spatial order
(``Bodies.sort_spatially``) few contacts cross a block boundary. ``touch[k]`` marks the
pairs in contact at the last force evaluation.
"""

import math
from typing import NamedTuple

import numba
import numpy as np

from .._jit import kernel
from ..status import NONFINITE, OK, OVERLAP, REBUILD
from .laws import law_hertz_mindlin, law_linear

_STEPPERS = {}


@kernel(inline=True)
def _apply_law(code, ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff, p, a, b, hist, k, dt):
    """Force on j from the law with this ``code`` (a constant: other branches fold away)."""
    if code == 0:
        return law_linear(ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff, p, a, b, hist, k, dt)
    return law_hertz_mindlin(ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff, p, a, b, hist, k, dt)


@kernel(inline=True)
def add_strain_rate(dim, rate, lx, ly, lz, vx, vy, vz):
    """``v + D l`` with ``D`` the symmetric part of ``rate``: the affine field's
    velocity difference across a branch vector ``l`` felt by a contact. The spin
    turns the pair as a whole, and the bodies with it (:func:`cell_spin`, which gives
    the ``rate`` to use then), so it does not slide the contact. For a symmetric
    ``rate`` (``L`` without spin) this is ``v + L l``, summed as it always was."""
    d01 = 0.5 * (rate[0, 1] + rate[1, 0])
    vx += rate[0, 0] * lx + d01 * ly
    vy += d01 * lx + rate[1, 1] * ly
    if dim == 3:
        d02 = 0.5 * (rate[0, 2] + rate[2, 0])
        d12 = 0.5 * (rate[1, 2] + rate[2, 1])
        vx += d02 * lz
        vy += d12 * lz
        vz += d02 * lx + d12 * ly + rate[2, 2] * lz
    return vx, vy, vz


@kernel(inline=True)
def cell_spin(dim, on, lgrad, dt, spin, quat, rate):
    """The rotation of one step's cell map ``M = I + dt L`` when ``L`` has a spin.

    In a deforming cell (``on``) whose velocity gradient is not symmetric: ``spin``
    (d, d) gets the rotation ``R`` of ``M = R U`` (its polar factor: the material's
    rotation over the step, exactly ``M`` for a rigid turn), ``quat`` (4,) its
    quaternion (w, x, y, z) in 3D or its angle ``quat[0]`` in 2D, and ``rate`` (d, d)
    the stretching the contacts feel, ``(V - I) / dt`` with ``V = M R^T`` the left
    stretch (zero for a rigid turn of any angle); returns True. Otherwise returns
    False and leaves the three alone. Bodies' angular velocities are then
    fluctuations about this spin, as their velocities are about the affine field:
    each step turns every orientation and every contact's tangential spring by ``R``
    (:func:`turn_spring`, :func:`turn_orientation`).
    """
    if not on:
        return False
    turns = lgrad[0, 1] != lgrad[1, 0]
    if dim == 3:
        turns = turns or lgrad[0, 2] != lgrad[2, 0] or lgrad[1, 2] != lgrad[2, 1]
    if not turns:
        return False
    m = np.eye(dim) + dt * lgrad
    if dim == 2:
        ang = math.atan2(m[1, 0] - m[0, 1], m[0, 0] + m[1, 1])
        c, s = math.cos(ang), math.sin(ang)
        spin[0, 0], spin[0, 1], spin[1, 0], spin[1, 1] = c, -s, s, c
        quat[0] = ang
    else:
        r = m.copy()
        for _ in range(30):  # Newton's iteration for the polar factor: R <- (R + R^-T)/2
            nxt = 0.5 * (r + np.linalg.inv(r).T)
            change = np.abs(nxt - r).max()
            r = nxt
            if change <= 1e-16:
                break
        spin[:, :] = r
        _quaternion(r, quat)
    v = np.zeros((dim, dim))  # V = M R^T
    for a in range(dim):
        for c in range(dim):
            for e in range(dim):
                v[a, c] += m[a, e] * spin[c, e]
    for a in range(dim):
        for c in range(dim):  # V is symmetric: keep it so to the bit
            rate[a, c] = (0.5 * (v[a, c] + v[c, a]) - (1.0 if a == c else 0.0)) / dt
    return True


@kernel(inline=True)
def _quaternion(r, q):
    """The unit quaternion (w, x, y, z) of the rotation matrix ``r`` (Shepperd's
    method: the largest of w, x, y, z first)."""
    tr = r[0, 0] + r[1, 1] + r[2, 2]
    if tr >= max(r[0, 0], r[1, 1], r[2, 2]):
        w = 0.5 * math.sqrt(1.0 + tr)
        q[0], q[1], q[2], q[3] = (w, (r[2, 1] - r[1, 2]) / (4.0 * w),
                                  (r[0, 2] - r[2, 0]) / (4.0 * w),
                                  (r[1, 0] - r[0, 1]) / (4.0 * w))
    elif r[0, 0] >= r[1, 1] and r[0, 0] >= r[2, 2]:
        x = 0.5 * math.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
        q[0], q[1], q[2], q[3] = ((r[2, 1] - r[1, 2]) / (4.0 * x), x,
                                  (r[0, 1] + r[1, 0]) / (4.0 * x),
                                  (r[0, 2] + r[2, 0]) / (4.0 * x))
    elif r[1, 1] >= r[2, 2]:
        y = 0.5 * math.sqrt(1.0 - r[0, 0] + r[1, 1] - r[2, 2])
        q[0], q[1], q[2], q[3] = ((r[0, 2] - r[2, 0]) / (4.0 * y),
                                  (r[0, 1] + r[1, 0]) / (4.0 * y), y,
                                  (r[1, 2] + r[2, 1]) / (4.0 * y))
    else:
        z = 0.5 * math.sqrt(1.0 - r[0, 0] - r[1, 1] + r[2, 2])
        q[0], q[1], q[2], q[3] = ((r[1, 0] - r[0, 1]) / (4.0 * z),
                                  (r[0, 2] + r[2, 0]) / (4.0 * z),
                                  (r[1, 2] + r[2, 1]) / (4.0 * z), z)


@kernel(inline=True)
def turn_vector(dim, spin, rows, k):
    """Turn the vector ``rows[k, :dim]`` by the step's spin (:func:`cell_spin`)."""
    h0, h1 = rows[k, 0], rows[k, 1]
    if dim == 2:
        rows[k, 0] = spin[0, 0] * h0 + spin[0, 1] * h1
        rows[k, 1] = spin[1, 0] * h0 + spin[1, 1] * h1
        return
    h2 = rows[k, 2]
    for a in range(3):
        rows[k, a] = spin[a, 0] * h0 + spin[a, 1] * h1 + spin[a, 2] * h2


@kernel(inline=True)
def turn_spring(dim, spin, hist, k):
    """Turn contact k's tangential spring (history columns 0-2) by the step's spin."""
    turn_vector(dim, spin, hist, k)


@kernel(inline=True)
def turn_orientation(dim, quat, rot, b):
    """Turn body b's orientation by the step's spin ``quat`` (:func:`cell_spin`; 2D:
    add the angle; 3D: ``q <- q_R q``)."""
    if dim == 2:
        rot[b, 0] += quat[0]
        return
    rw, rx, ry, rz = quat[0], quat[1], quat[2], quat[3]
    qw, qx, qy, qz = rot[b, 0], rot[b, 1], rot[b, 2], rot[b, 3]
    rot[b, 0] = rw * qw - rx * qx - ry * qy - rz * qz
    rot[b, 1] = rw * qx + rx * qw + ry * qz - rz * qy
    rot[b, 2] = rw * qy - rx * qz + ry * qw + rz * qx
    rot[b, 3] = rw * qz + rx * qy - ry * qx + rz * qw


@kernel(inline=True)
def _sphere_pair(k, dim, code, periodic, deform, pos, vel, ang_vel, radius, inv_mass,
                 mat_id, hmat, rate, turns, spin, pairs, img, touch, hist, params, dt,
                 overlap_limit, status_out):
    """Contact k of the sphere-sphere list.

    Returns ``(touching, fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz)``: the force on j
    (i gets the opposite) and the torques on i and j (2D: the z components only).
    In a deforming cell (``deform``) velocities are fluctuations and the relative
    velocity gains ``D l``, ``l`` the branch vector, ``D`` the symmetric part of
    ``rate`` (:func:`add_strain_rate`: ``L``, or with ``turns`` the stretching of
    :func:`cell_spin`, the spring then first turning with the cell). Resets the
    history of a contact that opened; flags an excessive overlap.
    """
    i = pairs[k, 0]
    j = pairs[k, 1]
    dx = pos[j, 0] - pos[i, 0]
    dy = pos[j, 1] - pos[i, 1]
    dz = pos[j, 2] - pos[i, 2] if dim == 3 else 0.0
    if periodic and (img[k, 0] != 0 or img[k, 1] != 0 or (dim == 3 and img[k, dim - 1] != 0)):
        dx += hmat[0, 0] * img[k, 0] + hmat[0, 1] * img[k, 1]
        dy += hmat[1, 0] * img[k, 0] + hmat[1, 1] * img[k, 1]
        if dim == 3:
            dx += hmat[0, 2] * img[k, 2]
            dy += hmat[1, 2] * img[k, 2]
            dz += hmat[2, 0] * img[k, 0] + hmat[2, 1] * img[k, 1] + hmat[2, 2] * img[k, 2]
    ri = radius[i]
    rj = radius[j]
    dist2 = dx * dx + dy * dy + dz * dz
    cut = ri + rj
    if dist2 >= cut * cut:
        if touch[k]:  # the contact opened: its history ends
            touch[k] = 0
            hist[k, 0] = 0.0
            hist[k, 1] = 0.0
            hist[k, 2] = 0.0
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    touch[k] = 1
    dist = math.sqrt(dist2)
    inv = 1.0 / dist
    nx, ny, nz = dx * inv, dy * inv, dz * inv
    ov = cut - dist
    if ov > overlap_limit * min(ri, rj):
        status_out[0] = OVERLAP
        status_out[1] = i
        status_out[2] = j
    li = ri - 0.5 * ov  # lever arms from each centre to the contact point
    lj = rj - 0.5 * ov
    # velocity of j relative to i at the contact point:
    # w_j x (-lj n) - w_i x (li n) = -(lj w_j + li w_i) x n
    if dim == 2:
        s = lj * ang_vel[j, 0] + li * ang_vel[i, 0]
        vx = vel[j, 0] - vel[i, 0] + s * ny
        vy = vel[j, 1] - vel[i, 1] - s * nx
        vz = 0.0
    else:
        sx = lj * ang_vel[j, 0] + li * ang_vel[i, 0]
        sy = lj * ang_vel[j, 1] + li * ang_vel[i, 1]
        sz = lj * ang_vel[j, 2] + li * ang_vel[i, 2]
        vx = vel[j, 0] - vel[i, 0] - (sy * nz - sz * ny)
        vy = vel[j, 1] - vel[i, 1] - (sz * nx - sx * nz)
        vz = vel[j, 2] - vel[i, 2] - (sx * ny - sy * nx)
    if deform:  # the affine field's velocity difference across the branch vector
        vx, vy, vz = add_strain_rate(dim, rate, dx, dy, dz, vx, vy, vz)
        if turns:
            turn_spring(dim, spin, hist, k)
    r_eff = ri * rj / (ri + rj)
    m_eff = 1.0 / (inv_mass[i] + inv_mass[j])
    fx, fy, fz = _apply_law(code, ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff, params,
                            mat_id[i], mat_id[j], hist, k, dt)
    # torques: tau_i = li n x (-f), tau_j = -lj n x f
    tx = ny * fz - nz * fy
    ty = nz * fx - nx * fz
    tz = nx * fy - ny * fx
    if dim == 2:
        return True, fx, fy, 0.0, -li * tz, 0.0, 0.0, -lj * tz, 0.0, 0.0
    return True, fx, fy, fz, -li * tx, -li * ty, -li * tz, -lj * tx, -lj * ty, -lj * tz


@kernel(inline=True)
def _sphere_wall(k, dim, code, pos, vel, ang_vel, radius, inv_mass, mat_id, normal,
                 wpairs, whist, params, dt, overlap_limit, status_out):
    """Contact k of the sphere-wall list (home body: the sphere; n points into the wall).

    Returns ``(touching, fx, fy, fz, tx, ty, tz, power)``: force and torque on the
    sphere, and the power of the wall's force on it [W].
    """
    i = wpairs[k, 0]
    w = wpairs[k, 1]
    nx = -normal[w, 0]
    ny = -normal[w, 1]
    nz = -normal[w, 2] if dim == 3 else 0.0
    gap = (pos[i, 0] - pos[w, 0]) * normal[w, 0] + (pos[i, 1] - pos[w, 1]) * normal[w, 1]
    if dim == 3:
        gap += (pos[i, 2] - pos[w, 2]) * normal[w, 2]
    ri = radius[i]
    ov = ri - gap
    if ov <= 0.0:
        whist[k, 0] = 0.0
        whist[k, 1] = 0.0
        whist[k, 2] = 0.0
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if ov > overlap_limit * ri:
        status_out[0] = OVERLAP
        status_out[1] = i
        status_out[2] = w
    li = ri - 0.5 * ov
    vwx = vel[w, 0]
    vwy = vel[w, 1]
    vwz = vel[w, 2] if dim == 3 else 0.0
    if dim == 2:
        s = li * ang_vel[i, 0]
        vx = vwx - vel[i, 0] + s * ny
        vy = vwy - vel[i, 1] - s * nx
        vz = 0.0
    else:
        sx, sy, sz = li * ang_vel[i, 0], li * ang_vel[i, 1], li * ang_vel[i, 2]
        vx = vwx - vel[i, 0] - (sy * nz - sz * ny)
        vy = vwy - vel[i, 1] - (sz * nx - sx * nz)
        vz = vwz - vel[i, 2] - (sx * ny - sy * nx)
    fx, fy, fz = _apply_law(code, ov, nx, ny, nz, vx, vy, vz, ri, 1.0 / inv_mass[i], params,
                            mat_id[i], mat_id[w], whist, k, dt)
    # the sphere gets -f; torque li n x (-f)
    tx = -li * (ny * fz - nz * fy)
    ty = -li * (nz * fx - nx * fz)
    tz = -li * (nx * fy - ny * fx)
    power = -(fx * vwx + fy * vwy + fz * vwz)
    if dim == 2:
        return True, -fx, -fy, 0.0, tz, 0.0, 0.0, power
    return True, -fx, -fy, -fz, tx, ty, tz, power


@kernel(inline=True)
def _affine(dim, deform, lgrad, pos, b, dt):
    """The step's affine displacement ``dt L x`` of body b in a deforming cell."""
    if not deform:
        return 0.0, 0.0, 0.0
    x, y = pos[b, 0], pos[b, 1]
    if dim == 2:
        return dt * (lgrad[0, 0] * x + lgrad[0, 1] * y), \
            dt * (lgrad[1, 0] * x + lgrad[1, 1] * y), 0.0
    z = pos[b, 2]
    return (dt * (lgrad[0, 0] * x + lgrad[0, 1] * y + lgrad[0, 2] * z),
            dt * (lgrad[1, 0] * x + lgrad[1, 1] * y + lgrad[1, 2] * z),
            dt * (lgrad[2, 0] * x + lgrad[2, 1] * y + lgrad[2, 2] * z))


@kernel(inline=True)
def moved2(dim, deform, pos, ref, b, fmap):
    """Squared displacement [m^2] of body b since ``ref``; in a deforming cell the
    displacement beyond the affine map ``fmap`` (= H H_ref^-1) of the reference."""
    s2 = 0.0
    for a in range(dim):
        if deform:
            dx = pos[b, a]
            for c in range(dim):
                dx -= fmap[a, c] * ref[b, c]
        else:
            dx = pos[b, a] - ref[b, a]
        s2 += dx * dx
    return s2


@kernel(inline=True)
def _drift_centre(b, dim, deform, lgrad, dt, half, pos, vel, force, torque, inv_mass,
                  is_fixed, turns, spin):
    """The translational half kick and drift of body b (fixed bodies: drift at their
    velocity; its torque zeroed too), carried by the cell's affine field ``dt L x``
    when ``deform``, its fluctuation velocity turned with the cell when ``turns``
    (:func:`cell_spin`); zeroes its force."""
    ax, ay, az = _affine(dim, deform, lgrad, pos, b, dt)
    if is_fixed[b]:
        for a in range(dim):
            pos[b, a] += dt * vel[b, a]
            force[b, a] = 0.0
        for a in range(torque.shape[1]):
            torque[b, a] = 0.0
    else:
        for a in range(dim):
            vel[b, a] += half * force[b, a] * inv_mass[b]
        if turns:
            turn_vector(dim, spin, vel, b)
        for a in range(dim):
            pos[b, a] += dt * vel[b, a]
            force[b, a] = 0.0
    if deform:
        pos[b, 0] += ax
        pos[b, 1] += ay
        if dim == 3:
            pos[b, 2] += az


@kernel(inline=True)
def _drift_body(b, dim, deform, dt, half, pos, vel, rot, ang_vel, force, torque,
                inv_mass, inv_inertia, is_fixed, pos_inner, lgrad, fmap, turns, spin, quat):
    """Half kick and drift of body b (fixed bodies: drift at their velocity), carried
    by the cell's affine field when ``deform`` (and turned with the cell when
    ``turns``: :func:`cell_spin`).

    Zeroes b's force and torque: the contact loops add into them. Returns the squared
    displacement [m^2] since the inner list was made (beyond the affine map ``fmap``).
    """
    _drift_centre(b, dim, deform, lgrad, dt, half, pos, vel, force, torque, inv_mass,
                  is_fixed, turns, spin)
    s2 = moved2(dim, deform, pos, pos_inner, b, fmap)
    if is_fixed[b]:
        return s2
    if dim == 2:
        ang_vel[b, 0] += half * torque[b, 0] * inv_inertia[b, 0]
        rot[b, 0] += dt * ang_vel[b, 0]
        torque[b, 0] = 0.0
    else:
        wx = ang_vel[b, 0] + half * torque[b, 0] * inv_inertia[b, 0]
        wy = ang_vel[b, 1] + half * torque[b, 1] * inv_inertia[b, 1]
        wz = ang_vel[b, 2] + half * torque[b, 2] * inv_inertia[b, 2]
        ang_vel[b, 0], ang_vel[b, 1], ang_vel[b, 2] = wx, wy, wz
        torque[b, 0] = 0.0
        torque[b, 1] = 0.0
        torque[b, 2] = 0.0
        # rotation by |w| dt about w: r = (1 - |h|^2/2, h), h = w dt/2, is the
        # exponential map to O(|h|^3) and a unit quaternion to O(|h|^4) without a
        # square root; quaternions are renormalised at every neighbour rebuild
        hx, hy, hz = half * wx, half * wy, half * wz
        rw = 1.0 - 0.5 * (hx * hx + hy * hy + hz * hz)
        qw, qx, qy, qz = rot[b, 0], rot[b, 1], rot[b, 2], rot[b, 3]
        rot[b, 0] = rw * qw - hx * qx - hy * qy - hz * qz
        rot[b, 1] = rw * qx + hx * qw + hy * qz - hz * qy
        rot[b, 2] = rw * qy - hx * qz + hy * qw + hz * qx
        rot[b, 3] = rw * qz + hx * qy - hy * qx + hz * qw
    if turns:  # the orientation, and a 3D spin fluctuation, turn with the cell
        turn_orientation(dim, quat, rot, b)
        if dim == 3:
            turn_vector(3, spin, ang_vel, b)
    return s2


@kernel(inline=True)
def body_force(b, dim, fx, fy, fz, tx, ty, tz, gravity, damping, mass, is_fixed, vel,
               ang_vel, force, torque, status_out):
    """Add gravity and local damping to body b's contact force and torque and store them.

    A fixed body keeps the bare contact force. Flags a non-finite result. Returns the
    stored ``(fx, fy, fz, tx, ty, tz)``.
    """
    if not is_fixed[b]:
        mb = mass[b]
        fx += mb * gravity[0]
        fy += mb * gravity[1]
        if dim == 3:
            fz += mb * gravity[2]
        if damping > 0.0:  # Cundall local damping: oppose the velocity's sign
            fx -= damping * abs(fx) * np.sign(vel[b, 0])
            fy -= damping * abs(fy) * np.sign(vel[b, 1])
            tx -= damping * abs(tx) * np.sign(ang_vel[b, 0])
            if dim == 3:
                fz -= damping * abs(fz) * np.sign(vel[b, 2])
                ty -= damping * abs(ty) * np.sign(ang_vel[b, 1])
                tz -= damping * abs(tz) * np.sign(ang_vel[b, 2])
        if not (math.isfinite(fx) and math.isfinite(fy) and math.isfinite(fz)
                and math.isfinite(tx) and math.isfinite(ty) and math.isfinite(tz)):
            status_out[0] = NONFINITE
            status_out[1] = b
    force[b, 0] = fx
    force[b, 1] = fy
    torque[b, 0] = tx
    if dim == 3:
        force[b, 2] = fz
        torque[b, 1] = ty
        torque[b, 2] = tz
    return fx, fy, fz, tx, ty, tz


@kernel(inline=True)
def _finish_body(b, dim, fx, fy, fz, tx, ty, tz, kick, half, gravity, damping, mass,
                 inv_mass, inv_inertia, is_fixed, vel, ang_vel, force, torque, status_out):
    """:func:`body_force`, then the second half kick (spheres: isotropic inertia)."""
    fx, fy, fz, tx, ty, tz = body_force(b, dim, fx, fy, fz, tx, ty, tz, gravity, damping,
                                        mass, is_fixed, vel, ang_vel, force, torque,
                                        status_out)
    if kick and not is_fixed[b]:
        vel[b, 0] += half * fx * inv_mass[b]
        vel[b, 1] += half * fy * inv_mass[b]
        ang_vel[b, 0] += half * tx * inv_inertia[b, 0]
        if dim == 3:
            vel[b, 2] += half * fz * inv_mass[b]
            ang_vel[b, 1] += half * ty * inv_inertia[b, 1]
            ang_vel[b, 2] += half * tz * inv_inertia[b, 2]


#: bodies are split into this many blocks of consecutive rows; a pair within one block
#: is "internal", others "cross". Fixed, so that the summation order (and so every bit
#: of the result) does not depend on the thread count.
N_BLOCKS = 8


@kernel(inline=True)
def _near(k, dim, periodic, pos, radius, hmat, pairs, img, touch, hist, skin_inner):
    """Is Verlet pair k closer than ``r_i + r_j + skin_inner``? Resets the history of a
    pair left out that was touching (it has opened)."""
    i = pairs[k, 0]
    j = pairs[k, 1]
    r2 = 0.0
    for a in range(dim):
        dx = pos[j, a] - pos[i, a]
        if periodic:
            for c in range(dim):
                dx += hmat[a, c] * img[k, c]
        r2 += dx * dx
    cut = radius[i] + radius[j] + skin_inner
    if r2 < cut * cut:
        return 1
    if touch[k]:
        touch[k] = 0
        hist[k, 0] = 0.0
        hist[k, 1] = 0.0
        hist[k, 2] = 0.0
    return 0


@kernel
def _compact_inner(pairs, near, n_bodies, inner_out, n_inner_out, blk_start_out,
                   inc_start_out, slot_out):
    """The inner list from the flags ``near`` (m,): internal pairs (both bodies in one
    block) in ascending order, then cross pairs in ascending order; ``n_inner_out``
    (2,) gets the total and internal counts. Then :func:`inner_index`. ``near`` may be
    a column of ``slot_out``: it is read before ``slot_out`` is written."""
    n_int = 0
    n_cross = 0
    for k in range(pairs.shape[0]):
        if near[k]:
            if (pairs[k, 0] * N_BLOCKS) // n_bodies == (pairs[k, 1] * N_BLOCKS) // n_bodies:
                n_int += 1
            else:
                n_cross += 1
    q_int = 0
    q_cross = n_int
    for k in range(pairs.shape[0]):
        if near[k]:
            if (pairs[k, 0] * N_BLOCKS) // n_bodies == (pairs[k, 1] * N_BLOCKS) // n_bodies:
                inner_out[q_int] = k
                q_int += 1
            else:
                inner_out[q_cross] = k
                q_cross += 1
    n_inner_out[0] = n_int + n_cross
    n_inner_out[1] = n_int
    inner_index(pairs, inner_out, n_inner_out, blk_start_out, inc_start_out, slot_out)


@kernel
def inner_index(pairs, inner, n_inner, blk_start_out, inc_start_out, slot_out):
    """Where each block's internal pairs start, and the cross pairs' incidence rows.

    ``blk_start_out`` (N_BLOCKS + 1,) delimits block b's internal pairs in ``inner``.
    ``inc_start_out`` (n + 1,) delimits body b's rows of the per-incidence buffer for
    cross pairs, in ascending pair order; ``slot_out[k]`` gives the rows of cross pair
    k's two incidences (as i, as j).
    """
    n = inc_start_out.shape[0] - 1
    n_tot, n_int = n_inner[0], n_inner[1]
    blk_start_out[:] = n_int
    for q in range(n_int - 1, -1, -1):  # internal pairs come grouped by block
        blk_start_out[(pairs[inner[q], 0] * N_BLOCKS) // n] = q
    for b in range(N_BLOCKS - 1, -1, -1):  # empty blocks start where the next one does
        blk_start_out[b] = min(blk_start_out[b], blk_start_out[b + 1])
    inc_start_out[:] = 0
    for u in range(n_int, n_tot):
        k = inner[u]
        inc_start_out[pairs[k, 0] + 1] += 1
        inc_start_out[pairs[k, 1] + 1] += 1
    for b in range(n):
        inc_start_out[b + 1] += inc_start_out[b]
    for u in range(n_int, n_tot):  # inc_start_out[b]: b's fill pointer, restored below
        k = inner[u]
        i = pairs[k, 0]
        j = pairs[k, 1]
        slot_out[k, 0] = inc_start_out[i]
        inc_start_out[i] += 1
        slot_out[k, 1] = inc_start_out[j]
        inc_start_out[j] += 1
    for b in range(n, 0, -1):
        inc_start_out[b] = inc_start_out[b - 1]
    inc_start_out[0] = 0


@kernel(inline=True)
def _scatter_pair(k, dim, i, j, fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz, fpair, force,
                  torque):
    """Add pair k's force (on j; i gets the opposite) and torques to its two bodies."""
    fpair[k, 0] = fx
    fpair[k, 1] = fy
    force[i, 0] -= fx
    force[i, 1] -= fy
    force[j, 0] += fx
    force[j, 1] += fy
    torque[i, 0] += tix
    torque[j, 0] += tjx
    if dim == 3:
        fpair[k, 2] = fz
        force[i, 2] -= fz
        force[j, 2] += fz
        torque[i, 1] += tiy
        torque[i, 2] += tiz
        torque[j, 1] += tjy
        torque[j, 2] += tjz


@kernel(inline=True)
def _deform_cell(hmat, lgrad, dt):
    """One step of the cell matrix: H <- (I + dt L) H, the map the bodies follow."""
    d = hmat.shape[0]
    for c in range(d):
        h0 = hmat[0, c]
        h1 = hmat[1, c]
        h2 = hmat[2, c] if d == 3 else 0.0
        for a in range(d):
            inc = lgrad[a, 0] * h0 + lgrad[a, 1] * h1
            if d == 3:
                inc += lgrad[a, 2] * h2
            hmat[a, c] += dt * inc


@kernel(inline=True)
def _cell_map(hmat, href_inv, fmap_out):
    """fmap = H H_ref^-1, the affine map from a reference state of the cell to now."""
    d = hmat.shape[0]
    for a in range(d):
        for c in range(d):
            v = 0.0
            for e in range(d):
                v += hmat[a, e] * href_inv[e, c]
            fmap_out[a, c] = v


@kernel(inline=True)
def _cell_start(deform, radius, hmat, href_inv, fmap):
    """At the start of a call in a deforming cell: ``fmap = H H_ref^-1`` and the
    largest radius (a pair's distance changes by its strain times at most 2 r_max +
    skin beyond the bodies' own motion); else leaves ``fmap`` and returns 0."""
    rmax = 0.0
    if deform:
        for b in range(radius.shape[0]):
            rmax = max(rmax, radius[b])
        _cell_map(hmat, href_inv, fmap)
    return rmax


@kernel(inline=True)
def _strain_norm(fmap):
    """Frobenius norm of fmap - I: bounds the relative length change of any vector."""
    d = fmap.shape[0]
    s = 0.0
    for a in range(d):
        for c in range(d):
            v = fmap[a, c] - (1.0 if a == c else 0.0)
            s += v * v
    return math.sqrt(s)


class InnerIndex(NamedTuple):
    """The sphere loop's index of its inner contact list (made by the loop itself when
    ``n_inner[0]`` is -1): per-body contribution rows ``contrib`` (2 m, d + r) and each
    pair's two rows ``slot`` (m, 2); each body's first row ``inc_start`` (n + 1,); the
    blocks' first internal pairs ``blk_start`` (N_BLOCKS + 1,); the list ``inner`` (m,)
    and its (total, internal) lengths ``n_inner`` (2,); the positions it was made at
    ``pos_inner`` (n, d) [m]; each body's first wall pair ``wstart`` (n + 1,)."""

    contrib: np.ndarray
    slot: np.ndarray
    inc_start: np.ndarray
    blk_start: np.ndarray
    inner: np.ndarray
    n_inner: np.ndarray
    pos_inner: np.ndarray
    wstart: np.ndarray


def stepper(dim, law_pp, law_pw, periodic=False, deform=False):
    """The compiled multi-step kernel for ``dim`` (2 or 3) and two law codes.

    ``law_pp``/``law_pw`` are law codes (a law class's ``code``: 0 linear, 1
    Hertz-Mindlin); ``periodic`` (or ``deform``) compiles in the periodic-image shifts
    and the deforming cell (:mod:`dem.boundary`), one kernel for both: with
    ``is_cell`` true at run time, ``hmat`` is advanced by ``lgrad`` every step, bodies
    are carried by the affine field and ``cellref`` (2, d, d) holds H^-1 at the
    Verlet build and at the inner list's making; an orthogonal periodic box passes
    ``is_cell`` false and a zero ``lgrad``, and every affine term adds an exact zero.
    Only integers are captured, so the kernel caches on disk; the branches not taken
    fold away at compile time.
    """
    key = (int(dim), int(law_pp), int(law_pw), bool(periodic or deform))
    if key in _STEPPERS:
        return _STEPPERS[key]
    DIM, PP, PW, PERIODIC = key
    DEFORM = PERIODIC

    @kernel(parallel=True)
    def run_steps(n_steps, prime, resume, serial, settings, body, cell, nbr, pstate,
                  wstate, index, params_pp, params_pw, status_out, work_out):
        """Advance ``n_steps``; returns the number of completed steps.

        The arrays come in bundles (:mod:`dem.state`): ``settings``
        (:class:`~dem.state.StepSettings`), ``body`` (:class:`~dem.state.BodyArrays`),
        ``cell`` (:class:`~dem.state.CellArrays`), ``nbr``
        (:class:`~dem.state.NeighborArrays`), the contact state ``pstate``
        (:class:`~dem.state.PairState`) and ``wstate`` (:class:`~dem.state.WallState`),
        and the loop's own index of the inner list (:class:`InnerIndex`).

        ``prime`` = True computes forces at the current state without moving anything
        (tangential springs are not advanced). ``resume`` = True finishes a step whose
        drift was done by the previous call (which stopped with ``REBUILD``).
        ``serial`` = True takes the one-thread path (the caller knows the thread
        count; asking numba from here would make the kernel uncacheable).
        ``status_out`` (4,) int64 receives (code, i, j, inner-list refreshes); ``work_out`` (1,)
        accumulates the work of walls on bodies [J].
        """
        dt, gravity, damping, skin, overlap_limit, skin_inner, grow = settings
        (pos, vel, rot, ang_vel, force, torque, radius, mass, inv_mass, inv_inertia,
         is_fixed, normal, mat_id) = body
        hmat, lgrad, cellref, is_cell = cell
        pairs, img, wpairs, pos_ref = nbr
        hist, touch, fpair = pstate
        whist, wforce, wtorque = wstate
        contrib, slot, inc_start, blk_start, inner, n_inner, pos_inner, wstart = index
        n = pos.shape[0]
        mw = wpairs.shape[0]
        status_out[0] = OK
        status_out[3] = 0
        done = 0
        half = 0.5 * dt
        hdt = 0.0 if prime else dt
        kick = not prime
        n_iter = 1 if prime else n_steps
        # a deforming cell: fmap = H H_inner^-1 maps the positions of the inner
        # list's making affinely to now
        fmap = np.eye(DIM)
        rmax = _cell_start(DEFORM and is_cell, radius, hmat, cellref[1], fmap)
        # a cell whose velocity gradient has a spin turns springs and orientations;
        # its contacts then feel the stretching rate ``rate``, not L's symmetric part
        spin, quat, rate = np.eye(DIM), np.zeros(4), lgrad.copy()
        turns = cell_spin(DIM, DEFORM and is_cell and not prime, lgrad, dt, spin, quat,
                          rate)
        for it in range(n_iter):
            if not prime and not (resume and it == 0):
                if DEFORM and is_cell:  # the cell follows the affine field: H += dt L H
                    _deform_cell(hmat, lgrad, dt)
                    _cell_map(hmat, cellref[1], fmap)
                # ---- 1. half kick + drift
                maxd2 = 0.0
                n_bad = 0
                for b in numba.prange(n):
                    s2 = _drift_body(b, DIM, DEFORM, dt, half, pos, vel, rot, ang_vel,
                                     force, torque, inv_mass, inv_inertia, is_fixed,
                                     pos_inner, lgrad, fmap, turns, spin, quat)
                    if not math.isfinite(s2):
                        n_bad += 1
                    maxd2 = max(maxd2, s2)
                # ---- 2. the contact candidates must hold for the new positions (and
                # radii: ``grow`` is the largest radius growth since the build)
                if n_bad > 0 or not math.isfinite(maxd2):
                    status_out[0] = NONFINITE
                    status_out[1] = -1
                    return done
                strain = _strain_norm(fmap) if DEFORM else 0.0
                if 2.0 * (math.sqrt(maxd2) + grow) + strain * (2.0 * rmax + skin_inner) \
                        > skin_inner:
                    n_inner[0] = -1
            if n_inner[0] < 0:
                # refresh the inner list from the Verlet list, which must still hold
                if DEFORM and is_cell:
                    _cell_map(hmat, cellref[0], fmap)
                maxd2 = 0.0
                for b in numba.prange(n):
                    maxd2 = max(maxd2, moved2(DIM, DEFORM, pos, pos_ref, b, fmap))
                strain = _strain_norm(fmap) if DEFORM else 0.0
                if 2.0 * (math.sqrt(maxd2) + grow) + strain * (2.0 * rmax + skin) > skin:
                    status_out[0] = REBUILD
                    return done
                if DEFORM and is_cell:
                    cellref[1, :, :] = np.linalg.inv(hmat)
                    fmap[:, :] = np.eye(DIM)
                status_out[3] += 1  # inner refreshes, counted by the caller
                # the inner list: which Verlet pairs are near (in parallel), then
                # their list in order (one pass over flags)
                near = slot[:, 1]
                for k in numba.prange(pairs.shape[0]):
                    near[k] = _near(k, DIM, PERIODIC, pos, radius, hmat, pairs, img,
                                    touch, hist, skin_inner)
                _compact_inner(pairs, near, n, inner, n_inner, blk_start, inc_start, slot)
                pos_inner[:, :] = pos
            if prime or (resume and it == 0):  # else the drift zeroed them
                force[:, :] = 0.0
                torque[:, :] = 0.0
            n_tot = n_inner[0]
            n_int = n_inner[1]
            work = 0.0
            if serial:
                # ---- 3-5 on one thread: add each contact to its bodies as it comes,
                # internal pairs first, then cross pairs (the order the threads use)
                for q in range(n_tot):
                    k = inner[q]
                    (on, fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz) = _sphere_pair(
                        k, DIM, PP, PERIODIC, DEFORM, pos, vel, ang_vel, radius, inv_mass,
                        mat_id, hmat, rate, turns, spin, pairs, img, touch, hist,
                        params_pp, hdt, overlap_limit, status_out)
                    if on:
                        _scatter_pair(k, DIM, pairs[k, 0], pairs[k, 1], fx, fy, fz, tix,
                                      tiy, tiz, tjx, tjy, tjz, fpair, force, torque)
                for k in range(mw):
                    (on, fx, fy, fz, tx, ty, tz, power) = _sphere_wall(
                        k, DIM, PW, pos, vel, ang_vel, radius, inv_mass, mat_id, normal,
                        wpairs, whist, params_pw, hdt, overlap_limit, status_out)
                    if not on:
                        for a in range(DIM):  # wall reactions sum every wall pair
                            wforce[k, a] = 0.0
                        continue
                    i = wpairs[k, 0]
                    wforce[k, 0] = fx
                    wforce[k, 1] = fy
                    force[i, 0] += fx
                    force[i, 1] += fy
                    torque[i, 0] += tx
                    if DIM == 3:
                        wforce[k, 2] = fz
                        force[i, 2] += fz
                        torque[i, 1] += ty
                        torque[i, 2] += tz
                    work += power
                for b in range(n):
                    fz = force[b, 2] if DIM == 3 else 0.0
                    ty = torque[b, 1] if DIM == 3 else 0.0
                    tz = torque[b, 2] if DIM == 3 else 0.0
                    _finish_body(b, DIM, force[b, 0], force[b, 1], fz, torque[b, 0], ty,
                                 tz, kick, half, gravity, damping, mass, inv_mass,
                                 inv_inertia, is_fixed, vel, ang_vel, force, torque,
                                 status_out)
            else:
                # ---- 3a. internal pairs, parallel over blocks: both bodies of a pair
                # belong to the block, so each block adds into its own bodies
                for blk in numba.prange(N_BLOCKS):
                    for q in range(blk_start[blk], blk_start[blk + 1]):
                        k = inner[q]
                        (on, fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz) = _sphere_pair(
                            k, DIM, PP, PERIODIC, DEFORM, pos, vel, ang_vel, radius,
                            inv_mass, mat_id, hmat, rate, turns, spin, pairs, img, touch,
                            hist, params_pp, hdt, overlap_limit, status_out)
                        if on:
                            _scatter_pair(k, DIM, pairs[k, 0], pairs[k, 1], fx, fy, fz,
                                          tix, tiy, tiz, tjx, tjy, tjz, fpair, force,
                                          torque)
                # ---- 3b. cross pairs, parallel over pairs: each writes its two
                # contributions to rows laid out body by body, in pair order
                for q in numba.prange(n_int, n_tot):
                    k = inner[q]
                    (on, fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz) = _sphere_pair(
                        k, DIM, PP, PERIODIC, DEFORM, pos, vel, ang_vel, radius, inv_mass,
                        mat_id, hmat, rate, turns, spin, pairs, img, touch, hist,
                        params_pp, hdt, overlap_limit, status_out)
                    si = slot[k, 0]
                    sj = slot[k, 1]
                    if not on:
                        for a in range(contrib.shape[1]):
                            contrib[si, a] = 0.0
                            contrib[sj, a] = 0.0
                        continue
                    fpair[k, 0] = fx
                    fpair[k, 1] = fy
                    # -f added is f subtracted, bit for bit: the one-thread order
                    contrib[si, 0] = -fx
                    contrib[si, 1] = -fy
                    contrib[sj, 0] = fx
                    contrib[sj, 1] = fy
                    if DIM == 2:
                        contrib[si, 2] = tix
                        contrib[sj, 2] = tjx
                    else:
                        fpair[k, 2] = fz
                        contrib[si, 2] = -fz
                        contrib[sj, 2] = fz
                        contrib[si, 3] = tix
                        contrib[si, 4] = tiy
                        contrib[si, 5] = tiz
                        contrib[sj, 3] = tjx
                        contrib[sj, 4] = tjy
                        contrib[sj, 5] = tjz
                # ---- 4. sphere-wall contacts, parallel over pairs
                for k in numba.prange(mw):
                    (on, fx, fy, fz, tx, ty, tz, power) = _sphere_wall(
                        k, DIM, PW, pos, vel, ang_vel, radius, inv_mass, mat_id, normal,
                        wpairs, whist, params_pw, hdt, overlap_limit, status_out)
                    # written even when not touching (zeros): the gather reads every row
                    wforce[k, 0] = fx
                    wforce[k, 1] = fy
                    wtorque[k, 0] = tx
                    if DIM == 3:
                        wforce[k, 2] = fz
                        wtorque[k, 1] = ty
                        wtorque[k, 2] = tz
                    work += power
                # ---- 5. per body: internal sum, then cross rows and walls in order,
                # gravity, damping, second half kick
                for b in numba.prange(n):
                    fx = force[b, 0]
                    fy = force[b, 1]
                    tx = torque[b, 0]
                    fz = force[b, 2] if DIM == 3 else 0.0
                    ty = torque[b, 1] if DIM == 3 else 0.0
                    tz = torque[b, 2] if DIM == 3 else 0.0
                    for q in range(inc_start[b], inc_start[b + 1]):
                        fx += contrib[q, 0]
                        fy += contrib[q, 1]
                        if DIM == 2:
                            tx += contrib[q, 2]
                        else:
                            fz += contrib[q, 2]
                            tx += contrib[q, 3]
                            ty += contrib[q, 4]
                            tz += contrib[q, 5]
                    for k in range(wstart[b], wstart[b + 1]):
                        fx += wforce[k, 0]
                        fy += wforce[k, 1]
                        tx += wtorque[k, 0]
                        if DIM == 3:
                            fz += wforce[k, 2]
                            ty += wtorque[k, 1]
                            tz += wtorque[k, 2]
                    _finish_body(b, DIM, fx, fy, fz, tx, ty, tz, kick, half, gravity,
                                 damping, mass, inv_mass, inv_inertia, is_fixed, vel,
                                 ang_vel, force, torque, status_out)
            if not prime:
                work_out[0] += work * dt
            if status_out[0] != OK:
                return done
            if not prime:
                done += 1
        return done

    _STEPPERS[key] = run_steps
    return run_steps
