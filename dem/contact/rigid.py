"""The motion of rigid bodies of any shape in the shape loop (:mod:`dem.contact.shape_loop`).

In 3D the angular momentum is kicked in the body frame and the free rotation over a step
is the symmetric splitting of the free rigid body into exact rotations about the three
principal axes (1, 2, 3, 2, 1 with half, half, full, half, half steps): symplectic,
time-reversible, the angular momentum kept exactly (absent torque). A compound's parts
follow their body's pose (:func:`_part_pose`).
"""

import math

from .._jit import kernel
from ..rotation import to_body, to_world
from .kinematics import _drift_centre, body_force, turn_orientation


@kernel(inline=True)
def _qmul_axis(rot, b, axis, theta):
    """rot[b] <- rot[b] * (cos(theta/2), sin(theta/2) e_axis): a body-frame rotation."""
    c, s = math.cos(0.5 * theta), math.sin(0.5 * theta)
    w, x, y, z = rot[b, 0], rot[b, 1], rot[b, 2], rot[b, 3]
    if axis == 0:
        rot[b, 0], rot[b, 1], rot[b, 2], rot[b, 3] = (w * c - x * s, x * c + w * s,
                                                      y * c + z * s, z * c - y * s)
    elif axis == 1:
        rot[b, 0], rot[b, 1], rot[b, 2], rot[b, 3] = (w * c - y * s, x * c - z * s,
                                                      y * c + w * s, z * c + x * s)
    else:
        rot[b, 0], rot[b, 1], rot[b, 2], rot[b, 3] = (w * c - z * s, x * c + y * s,
                                                      y * c - x * s, z * c + w * s)


@kernel(inline=True)
def _free_rotor(rot, b, lx, ly, lz, ix, iy, iz, h):
    """Free rotation of body b over ``h`` by the 1-2-3-2-1 splitting.

    ``(lx, ly, lz)`` is the body-frame angular momentum, ``(ix, iy, iz)`` the inverse
    principal moments. Returns the body-frame angular momentum after the step.
    """
    for sub in range(5):
        axis = 0 if (sub == 0 or sub == 4) else (1 if (sub == 1 or sub == 3) else 2)
        frac = 1.0 if sub == 2 else 0.5
        if axis == 0:
            th = frac * h * lx * ix
            c, s = math.cos(th), math.sin(th)  # L_body turns by -th about e_x
            ly, lz = c * ly + s * lz, -s * ly + c * lz
        elif axis == 1:
            th = frac * h * ly * iy
            c, s = math.cos(th), math.sin(th)
            lz, lx = c * lz + s * lx, -s * lz + c * lx
        else:
            th = frac * h * lz * iz
            c, s = math.cos(th), math.sin(th)
            lx, ly = c * lx + s * ly, -s * lx + c * ly
        _qmul_axis(rot, b, axis, th)
    return lx, ly, lz


@kernel(inline=True)
def _kick_rotation(dim, b, half, rot, ang_vel, torque, inv_inertia):
    """ang_vel[b] += half I^-1 torque, with I the body's principal inertia (world frame).

    Returns the body-frame angular momentum after the kick (3D; zeros in 2D).
    """
    if dim == 2:
        ang_vel[b, 0] += half * torque[b, 0] * inv_inertia[b, 0]
        return 0.0, 0.0, 0.0
    ix, iy, iz = inv_inertia[b, 0], inv_inertia[b, 1], inv_inertia[b, 2]
    wx, wy, wz = to_body(3, rot, b, ang_vel[b, 0], ang_vel[b, 1], ang_vel[b, 2])
    tx, ty, tz = to_body(3, rot, b, torque[b, 0], torque[b, 1], torque[b, 2])
    lx, ly, lz = wx / ix + half * tx, wy / iy + half * ty, wz / iz + half * tz
    ang_vel[b, 0], ang_vel[b, 1], ang_vel[b, 2] = to_world(3, rot, b, lx * ix, ly * iy,
                                                           lz * iz)
    return lx, ly, lz


@kernel(inline=True)
def _drift_rigid(b, dim, deform, lgrad, dt, half, pos, vel, rot, ang_vel, force, torque,
                 inv_mass, inv_inertia, is_fixed, turns, spin, quat):
    """Half kick and drift of body b, carried by the cell's affine field ``dt L x``
    when ``deform``, its orientation turned with the cell's spin when ``turns``
    (:func:`dem.contact.kinematics.cell_spin`: angular velocities are fluctuations about
    it); zeroes its force and torque (the caller checks the displacement against the
    neighbour list)."""
    _drift_centre(b, dim, deform, lgrad, dt, half, pos, vel, force, torque, inv_mass,
                  is_fixed, turns, spin)
    if is_fixed[b]:
        return
    if dim == 2:
        ang_vel[b, 0] += half * torque[b, 0] * inv_inertia[b, 0]
        rot[b, 0] += dt * ang_vel[b, 0]
        torque[b, 0] = 0.0
        if turns:
            turn_orientation(2, quat, rot, b)
        return
    lx, ly, lz = _kick_rotation(3, b, half, rot, ang_vel, torque, inv_inertia)
    ix, iy, iz = inv_inertia[b, 0], inv_inertia[b, 1], inv_inertia[b, 2]
    lx, ly, lz = _free_rotor(rot, b, lx, ly, lz, ix, iy, iz, dt)
    if turns:  # the body-frame momentum stays; the frame turns with the cell
        turn_orientation(3, quat, rot, b)
    ang_vel[b, 0], ang_vel[b, 1], ang_vel[b, 2] = to_world(3, rot, b, lx * ix, ly * iy,
                                                           lz * iz)
    torque[b, 0] = 0.0
    torque[b, 1] = 0.0
    torque[b, 2] = 0.0


@kernel(inline=True)
def _part_pose(e, dim, ebody, eoff, eq, eprad, pos, rot, radius, normal, epos, erot, erad,
               enormal):
    """World pose of part e from its body's: ``pos + R eoff``, ``rot * eq`` (for a body
    that is its own part, offset zero and orientation identity: exactly the body's)."""
    b = ebody[e]
    ox, oy, oz = to_world(dim, rot, b, eoff[e, 0], eoff[e, 1], eoff[e, 2])
    epos[e, 0] = pos[b, 0] + ox
    epos[e, 1] = pos[b, 1] + oy
    enormal[e, 0] = normal[b, 0]
    enormal[e, 1] = normal[b, 1]
    if dim == 2:
        erot[e, 0] = rot[b, 0] + eq[e, 0]
    else:
        epos[e, 2] = pos[b, 2] + oz
        enormal[e, 2] = normal[b, 2]
        w, x, y, z = rot[b, 0], rot[b, 1], rot[b, 2], rot[b, 3]
        qw, qx, qy, qz = eq[e, 0], eq[e, 1], eq[e, 2], eq[e, 3]
        erot[e, 0] = w * qw - x * qx - y * qy - z * qz
        erot[e, 1] = w * qx + x * qw + y * qz - z * qy
        erot[e, 2] = w * qy - x * qz + y * qw + z * qx
        erot[e, 3] = w * qz + x * qy - y * qx + z * qw
    erad[e] = radius[b] if eprad[e] < 0.0 else eprad[e]


@kernel(inline=True)
def _finish_rigid(b, dim, fx, fy, fz, tx, ty, tz, kick, half, gravity, damping, body, rot,
                  vel, ang_vel, force, torque, status_out):
    """:func:`~dem.contact.kinematics.body_force`, then the second half kick (anisotropic
    rotation in 3D) into ``rot``, ``vel`` and ``ang_vel`` (``body``'s own, named because
    they are written)."""
    fx, fy, fz, tx, ty, tz = body_force(b, dim, fx, fy, fz, tx, ty, tz, gravity, damping,
                                        body, force, torque, status_out)
    if kick and not body.is_fixed[b]:
        inv_mass = body.inv_mass
        vel[b, 0] += half * fx * inv_mass[b]
        vel[b, 1] += half * fy * inv_mass[b]
        if dim == 3:
            vel[b, 2] += half * fz * inv_mass[b]
        _kick_rotation(dim, b, half, rot, ang_vel, torque, body.inv_inertia)
