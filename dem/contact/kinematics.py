"""The motion of bodies and of the periodic cell in the compiled step loops.

Inline kernels that the sphere loop (:mod:`dem.contact.loops`) and the shape loop
(:mod:`dem.contact.shape_loop`) compose: the half kick and drift of a body and its second
half kick with gravity and local damping; the deforming cell (``H += dt L H``, the map
``H H_ref^-1`` of the positions since a list was made, its strain, how far a body has
moved against a list); a cell spin, which turns tangential springs, velocities and
orientations with the cell, and the stretching rate its contacts feel.
"""

import math

import numpy as np

from .._jit import kernel
from ..status import NONFINITE


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
def body_force(b, dim, fx, fy, fz, tx, ty, tz, gravity, damping, body, force, torque,
               status_out):
    """Add gravity and local damping to body b's contact force and torque and store them
    in ``force`` and ``torque`` (reading the masses, fixed flags and velocities from
    ``body``, :class:`~dem.state.BodyArrays`).

    A fixed body keeps the bare contact force. Flags a non-finite result. Returns the
    stored ``(fx, fy, fz, tx, ty, tz)``.
    """
    if not body.is_fixed[b]:
        mb = body.mass[b]
        fx += mb * gravity[0]
        fy += mb * gravity[1]
        if dim == 3:
            fz += mb * gravity[2]
        if damping > 0.0:  # Cundall local damping: oppose the velocity's sign
            vel = body.vel
            ang_vel = body.ang_vel
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
def _finish_body(b, dim, fx, fy, fz, tx, ty, tz, kick, half, gravity, damping, body, vel,
                 ang_vel, force, torque, status_out):
    """:func:`body_force`, then the second half kick (spheres: isotropic inertia) into
    ``vel`` and ``ang_vel`` (``body``'s own, named because they are written)."""
    fx, fy, fz, tx, ty, tz = body_force(b, dim, fx, fy, fz, tx, ty, tz, gravity, damping,
                                        body, force, torque, status_out)
    if kick and not body.is_fixed[b]:
        inv_mass = body.inv_mass
        inv_inertia = body.inv_inertia
        vel[b, 0] += half * fx * inv_mass[b]
        vel[b, 1] += half * fy * inv_mass[b]
        ang_vel[b, 0] += half * tx * inv_inertia[b, 0]
        if dim == 3:
            vel[b, 2] += half * fz * inv_mass[b]
            ang_vel[b, 1] += half * ty * inv_inertia[b, 1]
            ang_vel[b, 2] += half * tz * inv_inertia[b, 2]


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
