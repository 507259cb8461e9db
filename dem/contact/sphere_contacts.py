"""The contacts of the sphere loop (:mod:`dem.contact.loops`): one sphere-sphere or
sphere-wall contact evaluated, a pair's force added to its bodies, and the loop's inner
contact list.

The inner list holds the Verlet pairs closer than ``r_i + r_j + skin_inner``, the only
ones evaluated every step. Bodies fall into :data:`N_BLOCKS` blocks of consecutive rows;
the list holds a block's internal pairs block by block, then the cross pairs, and
:class:`InnerIndex` lays out the rows in which the cross pairs write their
contributions body by body, so that every sum runs in a fixed order (see
:mod:`dem.contact.loops`).
"""

import math
from typing import NamedTuple

import numpy as np

from .._jit import kernel
from ..status import OVERLAP
from .kinematics import add_strain_rate, turn_spring
from .laws import apply_law, normal_stiffness, row_size
from .rolling import pair_inertia, rolling_moment, turn_rolling


@kernel(inline=True)
def _forget(hist, k):
    """Contact k opened: its history ends."""
    for c in range(hist.shape[1]):
        hist[k, c] = 0.0


@kernel(inline=True)
def _sphere_pair(k, dim, code, roll, periodic, deform, pos, vel, ang_vel, radius, inv_mass,
                 inv_inertia, mat_id, hmat, rate, turns, spin, pairs, img, touch, hist,
                 params, dt, overlap_limit, status_out):
    """Contact k of the sphere-sphere list (``roll``: with rolling resistance,
    :mod:`dem.contact.rolling`).

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
            _forget(hist, k)
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
            if roll and dim == 3:
                turn_rolling(spin, hist, k)
    r_eff = ri * rj / (ri + rj)
    m_eff = 1.0 / (inv_mass[i] + inv_mass[j])
    a = mat_id[i]
    b = mat_id[j]
    fx, fy, fz = apply_law(code, ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff, params, a, b,
                           hist, k, dt)
    # torques: tau_i = li n x (-f), tau_j = -lj n x f
    tx = ny * fz - nz * fy
    ty = nz * fx - nx * fz
    tz = nx * fy - ny * fx
    mx, my, mz = 0.0, 0.0, 0.0
    if roll:  # the moment on j; i gets the opposite
        i_r, i_w = pair_inertia(inv_mass[j], inv_inertia[j, 0], rj, inv_mass[i],
                                inv_inertia[i, 0], ri)
        if dim == 2:
            wx, wy, wz = 0.0, 0.0, ang_vel[j, 0] - ang_vel[i, 0]
        else:
            wx = ang_vel[j, 0] - ang_vel[i, 0]
            wy = ang_vel[j, 1] - ang_vel[i, 1]
            wz = ang_vel[j, 2] - ang_vel[i, 2]
        mx, my, mz = rolling_moment(
            dim, hist, k, nx, ny, nz, wx, wy, wz,
            normal_stiffness(code, ov, r_eff, params, a, b), fx * nx + fy * ny + fz * nz,
            r_eff, i_r, i_w, params, a, b, row_size(code), dt)
    if dim == 2:
        return True, fx, fy, 0.0, -li * tz - mz, 0.0, 0.0, -lj * tz + mz, 0.0, 0.0
    return (True, fx, fy, fz, -li * tx - mx, -li * ty - my, -li * tz - mz, -lj * tx + mx,
            -lj * ty + my, -lj * tz + mz)


@kernel(inline=True)
def _sphere_wall(k, dim, code, roll, pos, vel, ang_vel, radius, inv_mass, inv_inertia,
                 mat_id, normal, wpairs, whist, params, dt, overlap_limit, status_out):
    """Contact k of the sphere-wall list (home body: the sphere; n points into the wall;
    ``roll``: with rolling resistance, :mod:`dem.contact.rolling`; walls do not turn).

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
        _forget(whist, k)
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
    a = mat_id[i]
    b = mat_id[w]
    fx, fy, fz = apply_law(code, ov, nx, ny, nz, vx, vy, vz, ri, 1.0 / inv_mass[i], params,
                           a, b, whist, k, dt)
    # the sphere gets -f; torque li n x (-f)
    tx = -li * (ny * fz - nz * fy)
    ty = -li * (nz * fx - nx * fz)
    tz = -li * (nx * fy - ny * fx)
    if roll:  # the rolling moment on the sphere (home body), against its own spin
        i_r, i_w = pair_inertia(inv_mass[i], inv_inertia[i, 0], ri, 0.0, 0.0, 0.0)
        if dim == 2:
            wx, wy, wz = 0.0, 0.0, ang_vel[i, 0]
        else:
            wx, wy, wz = ang_vel[i, 0], ang_vel[i, 1], ang_vel[i, 2]
        mx, my, mz = rolling_moment(
            dim, whist, k, nx, ny, nz, wx, wy, wz, normal_stiffness(code, ov, ri, params, a, b),
            fx * nx + fy * ny + fz * nz, ri, i_r, i_w, params, a, b, row_size(code), dt)
        tx, ty, tz = tx + mx, ty + my, tz + mz  # 2D: mx = my = 0
    power = -(fx * vwx + fy * vwy + fz * vwz)
    if dim == 2:
        return True, -fx, -fy, 0.0, tz, 0.0, 0.0, power
    return True, -fx, -fy, -fz, tx, ty, tz, power


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
        _forget(hist, k)
    return 0


@kernel(inline=True)
def _body_blocks(n_bodies):
    """(n,) each body's block: ``(body * N_BLOCKS) // n_bodies``, without a division
    per body (block ``b`` starts at ``ceil(b n / N_BLOCKS)``)."""
    blk = np.empty(n_bodies, np.int64)
    for b in range(N_BLOCKS):
        lo = (b * n_bodies + N_BLOCKS - 1) // N_BLOCKS
        hi = ((b + 1) * n_bodies + N_BLOCKS - 1) // N_BLOCKS
        blk[lo:hi] = b
    return blk


@kernel
def _compact_inner(pairs, near, n_bodies, inner_out, n_inner_out, blk_start_out,
                   inc_start_out, slot_out):
    """The inner list from the flags ``near`` (m,): internal pairs (both bodies in one
    block) in ascending order, then cross pairs in ascending order; ``n_inner_out``
    (2,) gets the total and internal counts. Then :func:`inner_index`.

    ``near`` may be ``slot_out[:, 1]``; ``slot_out[:, 0]`` holds the cross pairs
    meanwhile, and both are read before :func:`inner_index` writes ``slot_out``. The
    pass has no branch: every pair is written to the next free row of its kind, which
    a near pair keeps (a row index never passes the pair's own, so stays in bounds)."""
    blk = _body_blocks(n_bodies)
    cross = slot_out[:, 0]
    n_int = 0
    n_cross = 0
    for k in range(pairs.shape[0]):
        f = near[k] != 0
        same = blk[pairs[k, 0]] == blk[pairs[k, 1]]
        inner_out[n_int] = k
        cross[n_cross] = k
        n_int += f and same
        n_cross += f and not same
    for u in range(n_cross):
        inner_out[n_int + u] = cross[u]
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
    blk = _body_blocks(n)
    for q in range(n_int - 1, -1, -1):  # internal pairs come grouped by block
        blk_start_out[blk[pairs[inner[q], 0]]] = q
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
