"""The compiled kernels of bonded beams (:mod:`dem.peridynamics.beams`).

One beam's forces, moments and energy (``bond_beam_2d``, ``bond_beam_3d``: the gradient of
the energy written in :mod:`dem.peridynamics.beams`), every beam's summed into the bodies
(``beam_forces_*``), and the velocity Verlet loop of a beam structure with Cundall local
damping (``integrate_beams_*``; in 3D the orientation turns by the exact rotation of the
angular velocity over a step).
"""

import math

from .._jit import kernel


# ------------------------------------------------------------------ small helpers
@kernel(inline=True)
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@kernel(inline=True)
def _qrot(q, b, s, vx, vy, vz):
    """Rotate (vx, vy, vz) by the unit quaternion ``q[b]``; by its inverse if s = -1."""
    w, ux, uy, uz = q[b, 0], s * q[b, 1], s * q[b, 2], s * q[b, 3]
    tx, ty, tz = _cross(ux, uy, uz, vx, vy, vz)
    tx, ty, tz = 2.0 * tx, 2.0 * ty, 2.0 * tz
    cx, cy, cz = _cross(ux, uy, uz, tx, ty, tz)
    return vx + w * tx + cx, vy + w * ty + cy, vz + w * tz + cz


@kernel(inline=True)
def _damped(f, v, damping):
    """Cundall local damping: reduce ``|f|`` by ``damping |f|`` against the velocity."""
    if v > 0.0:
        return f - damping * abs(f)
    if v < 0.0:
        return f + damping * abs(f)
    return f


# ------------------------------------------------------------------ beam kernels
@kernel(inline=True)
def bond_beam_2d(k, pairs, params, frames, pos, rot):
    """Beam ``k`` in 2D: ``(fx, fy, m_i, m_j, U)``.

    ``(fx, fy)`` [N] is the force on body j (i gets the opposite), ``m_i``, ``m_j``
    [N m] the moments on the two bodies, ``U`` [J] the energy. ``frames[k, e]`` (2,) is
    the beam axis in the frame of end ``e`` (0: body i, 1: body j).
    """
    i, j = pairs[k, 0], pairs[k, 1]
    length0, ea, ei = params[k, 0], params[k, 1], params[k, 3]
    rx, ry = pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1]
    length = math.sqrt(rx * rx + ry * ry)
    ex, ey = rx / length, ry / length
    c, s = math.cos(rot[i, 0]), math.sin(rot[i, 0])
    aix = c * frames[k, 0, 0] - s * frames[k, 0, 1]
    aiy = s * frames[k, 0, 0] + c * frames[k, 0, 1]
    c, s = math.cos(rot[j, 0]), math.sin(rot[j, 0])
    ajx = c * frames[k, 1, 0] - s * frames[k, 1, 1]
    ajy = s * frames[k, 1, 0] + c * frames[k, 1, 1]
    psi_i = ex * aiy - ey * aix
    psi_j = ex * ajy - ey * ajx
    bend = 2.0 * ei / length0
    ci = bend * (2.0 * psi_i + psi_j)  # dU/dpsi_i
    cj = bend * (2.0 * psi_j + psi_i)
    axial = ea / length0 * (length - length0)
    gx = ci * aiy + cj * ajy  # dU/de
    gy = -(ci * aix + cj * ajx)
    ge = gx * ex + gy * ey
    energy = (0.5 * axial * (length - length0)
              + bend * (psi_i * psi_i + psi_i * psi_j + psi_j * psi_j))
    return (-(axial * ex + (gx - ge * ex) / length),
            -(axial * ey + (gy - ge * ey) / length),
            -ci * (ex * aix + ey * aiy), -cj * (ex * ajx + ey * ajy), energy)


@kernel(inline=True)
def bond_beam_3d(k, pairs, params, frames, pos, rot):
    """Beam ``k`` in 3D: ``(fx, fy, fz, mix, miy, miz, mjx, mjy, mjz, U)``.

    The force [N] is on body j (i gets the opposite); ``m_i``, ``m_j`` [N m] are the
    world-frame moments on the two bodies, ``U`` [J] the energy. ``frames[k, e]``
    (3, 3) holds the rows ``a, b, c`` of the beam frame in the frame of end ``e``.
    """
    i, j = pairs[k, 0], pairs[k, 1]
    length0, ea = params[k, 0], params[k, 1]
    by, bz, kt = 2.0 * params[k, 2] / length0, 2.0 * params[k, 3] / length0, \
        params[k, 4] / length0
    rx, ry, rz = pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1], pos[j, 2] - pos[i, 2]
    length = math.sqrt(rx * rx + ry * ry + rz * rz)
    ex, ey, ez = rx / length, ry / length, rz / length
    f = frames[k, 0]
    aix, aiy, aiz = _qrot(rot, i, 1.0, f[0, 0], f[0, 1], f[0, 2])
    bix, biy, biz = _qrot(rot, i, 1.0, f[1, 0], f[1, 1], f[1, 2])
    cix, ciy, ciz = _qrot(rot, i, 1.0, f[2, 0], f[2, 1], f[2, 2])
    f = frames[k, 1]
    ajx, ajy, ajz = _qrot(rot, j, 1.0, f[0, 0], f[0, 1], f[0, 2])
    bjx, bjy, bjz = _qrot(rot, j, 1.0, f[1, 0], f[1, 1], f[1, 2])
    cjx, cjy, cjz = _qrot(rot, j, 1.0, f[2, 0], f[2, 1], f[2, 2])
    pix, piy, piz = _cross(ex, ey, ez, aix, aiy, aiz)  # psi_i = e x a_i
    pjx, pjy, pjz = _cross(ex, ey, ez, ajx, ajy, ajz)
    yi, zi = pix * bix + piy * biy + piz * biz, pix * cix + piy * ciy + piz * ciz
    yj, zj = pjx * bjx + pjy * bjy + pjz * bjz, pjx * cjx + pjy * cjy + pjz * cjz
    tau = 0.5 * (cix * bjx + ciy * bjy + ciz * bjz - bix * cjx - biy * cjy - biz * cjz)
    cyi, cyj = by * (2.0 * yi + yj), by * (2.0 * yj + yi)
    czi, czj = bz * (2.0 * zi + zj), bz * (2.0 * zj + zi)
    t2 = 0.5 * kt * tau
    # G = dU/dpsi; dU/de = a_i x G_i + a_j x G_j; dU/da = G x e
    gix, giy, giz = cyi * bix + czi * cix, cyi * biy + czi * ciy, cyi * biz + czi * ciz
    gjx, gjy, gjz = cyj * bjx + czj * cjx, cyj * bjy + czj * cjy, cyj * bjz + czj * cjz
    ux, uy, uz = _cross(aix, aiy, aiz, gix, giy, giz)
    vx, vy, vz = _cross(ajx, ajy, ajz, gjx, gjy, gjz)
    gx, gy, gz = ux + vx, uy + vy, uz + vz
    ge = gx * ex + gy * ey + gz * ez
    axial = ea / length0 * (length - length0)
    fx = -(axial * ex + (gx - ge * ex) / length)
    fy = -(axial * ey + (gy - ge * ey) / length)
    fz = -(axial * ez + (gz - ge * ez) / length)
    # moment on a body = -sum_v v x dU/dv over its frame vectors v
    hx, hy, hz = _cross(gix, giy, giz, ex, ey, ez)
    m = _cross(aix, aiy, aiz, hx, hy, hz)
    n = _cross(bix, biy, biz, cyi * pix - t2 * cjx, cyi * piy - t2 * cjy,
               cyi * piz - t2 * cjz)
    o = _cross(cix, ciy, ciz, czi * pix + t2 * bjx, czi * piy + t2 * bjy,
               czi * piz + t2 * bjz)
    hx, hy, hz = _cross(gjx, gjy, gjz, ex, ey, ez)
    p = _cross(ajx, ajy, ajz, hx, hy, hz)
    q = _cross(bjx, bjy, bjz, cyj * pjx + t2 * cix, cyj * pjy + t2 * ciy,
               cyj * pjz + t2 * ciz)
    r = _cross(cjx, cjy, cjz, czj * pjx - t2 * bix, czj * pjy - t2 * biy,
               czj * pjz - t2 * biz)
    energy = (0.5 * axial * (length - length0) + by * (yi * yi + yi * yj + yj * yj)
              + bz * (zi * zi + zi * zj + zj * zj) + 0.5 * kt * tau * tau)
    return (fx, fy, fz, -(m[0] + n[0] + o[0]), -(m[1] + n[1] + o[1]),
            -(m[2] + n[2] + o[2]), -(p[0] + q[0] + r[0]), -(p[1] + q[1] + r[1]),
            -(p[2] + q[2] + r[2]), energy)


@kernel
def beam_forces_2d(pairs, params, frames, pos, rot, force_out, torque_out, energy_out):
    """Sum the beam forces [N] and moments [N m] on every body (2D).

    Modified in place: ``force_out`` (n, 2) and ``torque_out`` (n, 1) are overwritten
    with the beam sums; ``energy_out`` (n_bonds,) [J] gets each beam's energy.
    """
    force_out[:, :] = 0.0
    torque_out[:, :] = 0.0
    for k in range(pairs.shape[0]):
        i, j = pairs[k, 0], pairs[k, 1]
        fx, fy, mi, mj, u = bond_beam_2d(k, pairs, params, frames, pos, rot)
        force_out[j, 0] += fx
        force_out[j, 1] += fy
        force_out[i, 0] -= fx
        force_out[i, 1] -= fy
        torque_out[i, 0] += mi
        torque_out[j, 0] += mj
        energy_out[k] = u


@kernel
def beam_forces_3d(pairs, params, frames, pos, rot, force_out, torque_out, energy_out):
    """Sum the beam forces [N] and world-frame moments [N m] on every body (3D).

    Modified in place: ``force_out`` (n, 3) and ``torque_out`` (n, 3) are overwritten;
    ``energy_out`` (n_bonds,) [J] gets each beam's energy.
    """
    force_out[:, :] = 0.0
    torque_out[:, :] = 0.0
    for k in range(pairs.shape[0]):
        i, j = pairs[k, 0], pairs[k, 1]
        out = bond_beam_3d(k, pairs, params, frames, pos, rot)
        for a in range(3):
            force_out[j, a] += out[a]
            force_out[i, a] -= out[a]
            torque_out[i, a] += out[3 + a]
            torque_out[j, a] += out[6 + a]
        energy_out[k] = out[9]


# ------------------------------------------------------------------ integrators
@kernel(inline=True)
def _kick_2d(b, half, damping, vel, ang_vel, force, torque, mass, inertia):
    vel[b, 0] += half * _damped(force[b, 0], vel[b, 0], damping) / mass[b]
    vel[b, 1] += half * _damped(force[b, 1], vel[b, 1], damping) / mass[b]
    m = _damped(torque[b, 0], ang_vel[b, 0], damping)
    ang_vel[b, 0] += half * m / inertia[b, 0]


@kernel(inline=True)
def _kick_3d(b, half, damping, vel, rot, ang_vel, force, torque, mass, inertia):
    """Half kick of body b; the angular one in the body frame: h_b += dt/2 R^T M."""
    for a in range(3):
        vel[b, a] += half * _damped(force[b, a], vel[b, a], damping) / mass[b]
    mx = _damped(torque[b, 0], ang_vel[b, 0], damping)
    my = _damped(torque[b, 1], ang_vel[b, 1], damping)
    mz = _damped(torque[b, 2], ang_vel[b, 2], damping)
    mx, my, mz = _qrot(rot, b, -1.0, mx, my, mz)
    wx, wy, wz = _qrot(rot, b, -1.0, ang_vel[b, 0], ang_vel[b, 1], ang_vel[b, 2])
    wx += half * mx / inertia[b, 0]
    wy += half * my / inertia[b, 1]
    wz += half * mz / inertia[b, 2]
    ang_vel[b, 0], ang_vel[b, 1], ang_vel[b, 2] = _qrot(rot, b, 1.0, wx, wy, wz)


@kernel(inline=True)
def _turn_3d(b, dt, rot, ang_vel, inertia):
    """Turn body b by ``ang_vel dt`` (exact exponential map), keeping its world-frame
    angular momentum ``h = R I R^T w``: the new ``w`` is ``R' I^-1 R'^T h``."""
    wx, wy, wz = ang_vel[b, 0], ang_vel[b, 1], ang_vel[b, 2]
    hx, hy, hz = _qrot(rot, b, -1.0, wx, wy, wz)
    hx, hy, hz = _qrot(rot, b, 1.0, inertia[b, 0] * hx, inertia[b, 1] * hy,
                       inertia[b, 2] * hz)
    w = math.sqrt(wx * wx + wy * wy + wz * wz)
    if w * dt > 0.0:
        s = math.sin(0.5 * w * dt) / w
        rw, rx, ry, rz = math.cos(0.5 * w * dt), s * wx, s * wy, s * wz
        qw, qx, qy, qz = rot[b, 0], rot[b, 1], rot[b, 2], rot[b, 3]
        nw = rw * qw - rx * qx - ry * qy - rz * qz
        nx = rw * qx + rx * qw + ry * qz - rz * qy
        ny = rw * qy - rx * qz + ry * qw + rz * qx
        nz = rw * qz + rx * qy - ry * qx + rz * qw
        norm = math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
        rot[b, 0], rot[b, 1], rot[b, 2], rot[b, 3] = nw / norm, nx / norm, ny / norm, \
            nz / norm
    hx, hy, hz = _qrot(rot, b, -1.0, hx, hy, hz)
    ang_vel[b, 0], ang_vel[b, 1], ang_vel[b, 2] = _qrot(
        rot, b, 1.0, hx / inertia[b, 0], hy / inertia[b, 1], hz / inertia[b, 2])


@kernel
def integrate_beams_2d(n_steps, dt, accel, damping, pairs, params, frames, pos, vel,
                       rot, ang_vel, force, torque, mass, inertia, is_fixed,
                       energy_out):
    """Advance a 2D beam structure ``n_steps`` velocity Verlet steps.

    ``force``/``torque`` hold the undamped totals of the last step (beams plus
    ``mass * accel`` on free bodies; fixed bodies keep their beam reaction) and are
    modified in place, with ``pos``, ``vel``, ``rot``, ``ang_vel`` and ``energy_out``.
    """
    half = 0.5 * dt
    n = pos.shape[0]
    for _ in range(n_steps):
        for b in range(n):
            if not is_fixed[b]:
                _kick_2d(b, half, damping, vel, ang_vel, force, torque, mass, inertia)
                pos[b, 0] += dt * vel[b, 0]
                pos[b, 1] += dt * vel[b, 1]
                rot[b, 0] += dt * ang_vel[b, 0]
        beam_forces_2d(pairs, params, frames, pos, rot, force, torque, energy_out)
        for b in range(n):
            if not is_fixed[b]:
                force[b, 0] += mass[b] * accel[0]
                force[b, 1] += mass[b] * accel[1]
                _kick_2d(b, half, damping, vel, ang_vel, force, torque, mass, inertia)


@kernel
def integrate_beams_3d(n_steps, dt, accel, damping, pairs, params, frames, pos, vel,
                       rot, ang_vel, force, torque, mass, inertia, is_fixed,
                       energy_out):
    """Advance a 3D beam structure ``n_steps`` velocity Verlet steps.

    As :func:`integrate_beams_2d`; rotations kick the angular momentum in the body
    frame (principal ``inertia``) and turn the quaternion by the exact exponential map.
    """
    half = 0.5 * dt
    n = pos.shape[0]
    for _ in range(n_steps):
        for b in range(n):
            if not is_fixed[b]:
                _kick_3d(b, half, damping, vel, rot, ang_vel, force, torque, mass,
                         inertia)
                for a in range(3):
                    pos[b, a] += dt * vel[b, a]
                _turn_3d(b, dt, rot, ang_vel, inertia)
        beam_forces_3d(pairs, params, frames, pos, rot, force, torque, energy_out)
        for b in range(n):
            if not is_fixed[b]:
                for a in range(3):
                    force[b, a] += mass[b] * accel[a]
                _kick_3d(b, half, damping, vel, rot, ang_vel, force, torque, mass,
                         inertia)
