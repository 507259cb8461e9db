"""The contacts of spheres with triangle-mesh walls in the sphere loop
(:mod:`dem.contact.loops`, compiled in only for scenes with mesh walls).

Kernel module. Every mesh wall of a scene is one block of a combined mesh
(:class:`~dem.meshwall_kernels.MeshArrays`, vertex and face rows offset wall by wall),
so one kernel serves any number of walls; ``face_wall`` names each face's wall.

Candidates are rows ``(sphere, face)`` (:class:`MeshContactState`), sorted by sphere,
then face: the faces near each sphere, found when the Verlet list is built. Each step
a sphere's rows are evaluated in order by the contact rule of
:mod:`dem.meshwall_kernels` (a point on an edge or a vertex counts once), so that the
work of a sphere is its own and the result does not depend on the thread count.

History hand-over. A contact's history (tangential spring, rolling state) lives in the
row of the face that reports it. When a sphere rolls from one face onto its
neighbour, or onto an edge reported by the lower face, another row starts reporting
the contact on the step the first one stops. A row that starts touching therefore
takes the history of the row of the same sphere and wall that stopped touching on this
step and whose last contact point is nearest to its new one (within the sphere's
radius); the history is moved, not copied. A sphere rolling across a flat seam keeps
its tangential spring, and its force has no jump.

Rigid motion. Each step, after the bodies' drift, a turning wall's vertices and
normals are turned by the rotation ``turn`` (Rodrigues' formula for
``angular_velocity * dt``, made in Python for the chunk) about its centre, then
every moving wall's vertices and centre move by ``velocity * dt``; a wall that does not
turn is only translated, one that does not move is not touched.
"""

import math
from typing import NamedTuple

import numpy as np
import numba

from .._jit import kernel
from ..meshwall_kernels import FACE, _face_closest, _owns
from ..status import OVERLAP
from .laws import apply_law, normal_stiffness, row_size
from .rolling import pair_inertia, rolling_moment


class MeshMotion(NamedTuple):
    """The walls of the combined mesh and their prescribed motion (nw walls).

    ``vert_wall`` (nv,) and ``face_wall`` (nf,) i8, the wall of each vertex and face;
    ``center`` (nw, 3) f8 [m], the points the walls turn about (moving with them);
    ``velocity`` (nw, 3) [m/s] and ``ang_vel`` (nw, 3) [rad/s]; ``turn`` (nw, 3, 3)
    the rotation of one step; ``moving`` (nw,) i8: 0 still, 1 translating, 2 turning;
    ``vert_ref`` (nv, 3) [m], the vertices when the candidates were found;
    ``mat_id`` (nw,) i8, material rows.
    """

    vert_wall: np.ndarray
    face_wall: np.ndarray
    center: np.ndarray
    velocity: np.ndarray
    ang_vel: np.ndarray
    turn: np.ndarray
    moving: np.ndarray
    vert_ref: np.ndarray
    mat_id: np.ndarray


class MeshContactState(NamedTuple):
    """The candidate rows of the sphere-mesh contacts (mr rows) and their state.

    ``mrows`` (mr, 2) i8 (sphere, face), sorted; ``mhist`` (mr, h) f8, law history;
    ``mtouch`` (mr,) u1, 1 while the row reports a contact; ``mpoint`` (mr, 3) [m] its
    contact point (middle of the overlap); ``mforce`` (mr, 3) [N] and ``mtorque``
    (mr, 3) [N m], force and torque on the sphere; ``mpower`` (mr,) [W], the power of
    the wall's force on the sphere.
    """

    mrows: np.ndarray
    mhist: np.ndarray
    mtouch: np.ndarray
    mpoint: np.ndarray
    mforce: np.ndarray
    mtorque: np.ndarray
    mpower: np.ndarray


class MeshLoop(NamedTuple):
    """What the sphere loop takes for mesh walls: the combined ``mesh``
    (:class:`~dem.meshwall_kernels.MeshArrays`, vertices and normals modified in
    place), its ``walls`` (:class:`MeshMotion`), the contact ``state``
    (:class:`MeshContactState`), each sphere's first row ``mstart`` (n + 1,) i8 and
    the scratch flags ``mflag`` (mr,) i8; ``msum`` (n, 6), each sphere's total mesh
    force [N] and torque [N m] (its rows summed in order)."""

    mesh: tuple
    walls: MeshMotion
    state: MeshContactState
    mstart: np.ndarray
    mflag: np.ndarray
    msum: np.ndarray


@kernel
def move_meshes(dt, mesh, walls):
    """Advance every mesh wall by one step of its motion (module docstring).

    Returns the largest squared displacement [m^2] of a vertex from ``vert_ref``.
    """
    v = mesh.vertices
    nrm = mesh.face_normal
    c = walls.center
    rot = walls.turn
    for p in range(v.shape[0]):
        w = walls.vert_wall[p]
        if walls.moving[w] == 2:
            dx, dy, dz = v[p, 0] - c[w, 0], v[p, 1] - c[w, 1], v[p, 2] - c[w, 2]
            for a in range(3):
                v[p, a] = c[w, a] + (rot[w, a, 0] * dx + rot[w, a, 1] * dy + rot[w, a, 2] * dz)
        if walls.moving[w] > 0:
            for a in range(3):
                v[p, a] += dt * walls.velocity[w, a]
    for f in range(nrm.shape[0]):
        w = walls.face_wall[f]
        if walls.moving[w] == 2:
            nx, ny, nz = nrm[f, 0], nrm[f, 1], nrm[f, 2]
            for a in range(3):
                nrm[f, a] = rot[w, a, 0] * nx + rot[w, a, 1] * ny + rot[w, a, 2] * nz
    for w in range(c.shape[0]):
        if walls.moving[w] > 0:
            for a in range(3):
                c[w, a] += dt * walls.velocity[w, a]
    d2max = 0.0
    for p in range(v.shape[0]):
        d2 = 0.0
        for a in range(3):
            d = v[p, a] - walls.vert_ref[p, a]
            d2 += d * d
        d2max = max(d2max, d2)
    return d2max


@kernel(inline=True)
def _touches(i, r, pos, radius, mesh, st):
    """Does row r (of sphere i) report a contact now? Returns ``(on, qx, qy, qz)``,
    the closest point of its face."""
    f = st.mrows[r, 1]
    px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
    qx, qy, qz, feature = _face_closest(f, px, py, pz, mesh)
    dx, dy, dz = px - qx, py - qy, pz - qz
    on = dx * dx + dy * dy + dz * dz < radius[i] * radius[i]
    if on and feature != FACE:
        on = _owns(f, feature, px, py, pz, mesh)
    return on, qx, qy, qz


@kernel(inline=True)
def _hand_over(i, r, lo, hi, qx, qy, qz, radius, walls, st, mflag):
    """Row r of sphere i starts touching at (qx, qy, qz): move to it the history of
    the row of the same wall that stopped touching nearest to it (module docstring)."""
    w = walls.face_wall[st.mrows[r, 1]]
    best = -1
    best2 = radius[i] * radius[i]
    for s in range(lo, hi):
        if st.mtouch[s] == 0 or mflag[s] != 0 or walls.face_wall[st.mrows[s, 1]] != w:
            continue
        dx = st.mpoint[s, 0] - qx
        dy = st.mpoint[s, 1] - qy
        dz = st.mpoint[s, 2] - qz
        d2 = dx * dx + dy * dy + dz * dz
        if d2 < best2:
            best, best2 = s, d2
    if best >= 0:
        for c in range(st.mhist.shape[1]):
            st.mhist[r, c] = st.mhist[best, c]
            st.mhist[best, c] = 0.0
        st.mtouch[best] = 0


@kernel(inline=True)
def _mesh_force(i, r, q, code, roll, pos, vel, ang_vel, radius, inv_mass, inv_inertia,
                mat_id, mesh, walls, st, params, dt, overlap_limit, status_out):
    """The force of row r's contact (closest point ``q`` = (x, y, z)) on sphere i: fills
    the row of ``st``. Inlined only into :func:`_mesh_spheres`, a real call, so it may
    write into the bundle ``st``. The body arrays come one by one: read through the
    bundle in every row, they cost 6 % of a mesh scene's step (docs/performance.md,
    "The force kernels and the bundles")."""
    qx, qy, qz = q
    f = st.mrows[r, 1]
    w = walls.face_wall[f]
    ri = radius[i]
    dx, dy, dz = qx - pos[i, 0], qy - pos[i, 1], qz - pos[i, 2]
    d = math.sqrt(dx * dx + dy * dy + dz * dz)
    if d > 0.0:  # the law's normal points from the sphere into the wall
        nx, ny, nz = dx / d, dy / d, dz / d
    else:
        nx, ny, nz = -mesh.face_normal[f, 0], -mesh.face_normal[f, 1], -mesh.face_normal[f, 2]
    ov = ri - d
    if ov > overlap_limit * ri:
        status_out[0] = OVERLAP
        status_out[1] = i
        status_out[2] = -1 - w
    li = ri - 0.5 * ov
    cx, cy, cz = pos[i, 0] + li * nx, pos[i, 1] + li * ny, pos[i, 2] + li * nz
    # the wall's velocity at the contact point: translation + rotation about its centre
    ox, oy, oz = walls.ang_vel[w, 0], walls.ang_vel[w, 1], walls.ang_vel[w, 2]
    rx, ry, rz = cx - walls.center[w, 0], cy - walls.center[w, 1], cz - walls.center[w, 2]
    vwx = walls.velocity[w, 0] + (oy * rz - oz * ry)
    vwy = walls.velocity[w, 1] + (oz * rx - ox * rz)
    vwz = walls.velocity[w, 2] + (ox * ry - oy * rx)
    sx, sy, sz = li * ang_vel[i, 0], li * ang_vel[i, 1], li * ang_vel[i, 2]
    vx = vwx - vel[i, 0] - (sy * nz - sz * ny)
    vy = vwy - vel[i, 1] - (sz * nx - sx * nz)
    vz = vwz - vel[i, 2] - (sx * ny - sy * nx)
    a = mat_id[i]
    b = walls.mat_id[w]
    fx, fy, fz = apply_law(code, ov, nx, ny, nz, vx, vy, vz, ri, 1.0 / inv_mass[i], params,
                           a, b, st.mhist, r, dt)
    tx = -li * (ny * fz - nz * fy)
    ty = -li * (nz * fx - nx * fz)
    tz = -li * (nx * fy - ny * fx)
    if roll:  # against the sphere's spin relative to the wall's
        i_r, i_w = pair_inertia(inv_mass[i], inv_inertia[i, 0], ri, 0.0, 0.0, 0.0)
        mx, my, mz = rolling_moment(
            3, st.mhist, r, nx, ny, nz, ang_vel[i, 0] - ox, ang_vel[i, 1] - oy,
            ang_vel[i, 2] - oz, normal_stiffness(code, ov, ri, params, a, b),
            fx * nx + fy * ny + fz * nz, ri, i_r, i_w, params, a, b, row_size(code), dt)
        tx, ty, tz = tx + mx, ty + my, tz + mz
    st.mtouch[r] = 1
    st.mpoint[r, 0], st.mpoint[r, 1], st.mpoint[r, 2] = cx, cy, cz
    st.mforce[r, 0], st.mforce[r, 1], st.mforce[r, 2] = -fx, -fy, -fz
    st.mtorque[r, 0], st.mtorque[r, 1], st.mtorque[r, 2] = tx, ty, tz
    st.mpower[r] = -(fx * vwx + fy * vwy + fz * vwz)


@kernel(inline=True)
def mesh_sphere(i, code, roll, pos, vel, ang_vel, radius, inv_mass, inv_inertia, mat_id,
                ml, params, dt, overlap_limit, status_out):
    """Evaluate every mesh row of sphere i: which touch, history hand-over, forces.

    Writes the rows' ``mforce``, ``mtorque`` and ``mpower`` (zeros where not touching)
    and updates their history; ``msum[i]`` gets their sum in row order, which the
    caller adds to the sphere.
    """
    mesh, walls, st, mstart, mflag, msum = ml
    lo, hi = mstart[i], mstart[i + 1]
    for r in range(lo, hi):
        on = _touches(i, r, pos, radius, mesh, st)[0]
        mflag[r] = 1 if on else 0
    for r in range(lo, hi):  # rows that start touching take a history that ended
        if mflag[r] != 0 and st.mtouch[r] == 0:
            on, qx, qy, qz = _touches(i, r, pos, radius, mesh, st)
            _hand_over(i, r, lo, hi, qx, qy, qz, radius, walls, st, mflag)
    for r in range(lo, hi):
        if mflag[r] == 0:
            if st.mtouch[r] != 0:  # the contact opened: its history ends
                st.mtouch[r] = 0
                for c in range(st.mhist.shape[1]):
                    st.mhist[r, c] = 0.0
            for a in range(3):
                st.mforce[r, a] = 0.0
                st.mtorque[r, a] = 0.0
            st.mpower[r] = 0.0
            continue
        on, qx, qy, qz = _touches(i, r, pos, radius, mesh, st)
        _mesh_force(i, r, (qx, qy, qz), code, roll, pos, vel, ang_vel, radius, inv_mass,
                    inv_inertia, mat_id, mesh, walls, st, params, dt, overlap_limit,
                    status_out)
    for a in range(6):
        msum[i, a] = 0.0
    for r in range(lo, hi):
        for a in range(3):
            msum[i, a] += st.mforce[r, a]
            msum[i, 3 + a] += st.mtorque[r, a]


#: spheres per task of :func:`mesh_forces`'s parallel loop
MESH_BLOCK = 64


@kernel
def _mesh_spheres(lo, hi, code, roll, body, mesh, walls, st, mstart, mflag, msum, params,
                  dt, overlap_limit, status_out):
    """:func:`mesh_sphere` for spheres lo to hi - 1 (a real call, from the parallel loop
    of :func:`mesh_forces`, which passes the bundles one by one). The body arrays are
    read from ``body`` here, once per block, and handed to the per-row kernels."""
    ml = (mesh, walls, st, mstart, mflag, msum)
    pos, vel, ang_vel, radius = body.pos, body.vel, body.ang_vel, body.radius
    inv_mass, inv_inertia, mat_id = body.inv_mass, body.inv_inertia, body.mat_id
    for i in range(lo, hi):
        if mstart[i + 1] == mstart[i]:  # no rows: no mesh force
            for a in range(6):
                msum[i, a] = 0.0
            continue
        mesh_sphere(i, code, roll, pos, vel, ang_vel, radius, inv_mass, inv_inertia, mat_id,
                    ml, params, dt, overlap_limit, status_out)


@kernel(parallel=True)
def mesh_forces(code, roll, body, mesh, walls, st, mstart, mflag, msum, params, dt,
                overlap_limit, status_out):
    """:func:`mesh_sphere` for every sphere of ``body`` (:class:`~dem.state.BodyArrays`),
    in parallel over blocks of :data:`MESH_BLOCK` spheres: a sphere writes only its own
    rows and ``msum`` row, so the result does not depend on the thread count. ``code``
    and ``roll`` are the loop's law code and rolling flag; ``mesh`` to ``msum`` are the
    fields of :class:`MeshLoop`.

    The rows are written by a real call (:func:`_mesh_spheres`), not code inlined into
    the parallel loop: numba drops writes into a named tuple's arrays made there
    (``tests/test_architecture.py``, ``bundle_writes``). The bundles come in as
    arguments of their own: numba passes a named tuple into a parallel loop only when
    it can find its class, which it cannot for one unpacked from another inside the
    function (it stops with an ``AttributeError``).
    """
    n = body.pos.shape[0]
    for blk in numba.prange((n + MESH_BLOCK - 1) // MESH_BLOCK):
        _mesh_spheres(blk * MESH_BLOCK, min(n, (blk + 1) * MESH_BLOCK), code, roll, body,
                      mesh, walls, st, mstart, mflag, msum, params, dt, overlap_limit,
                      status_out)


@kernel
def mesh_power(ml):
    """Total power [W] of the mesh walls on the spheres, summed in row order."""
    p = 0.0
    for r in range(ml.state.mpower.shape[0]):
        p += ml.state.mpower[r]
    return p
