"""The compiled time-step loop for scenes with non-spherical bodies (level-set shapes).

Same step and the same contract as :mod:`dem.contact.loops` (velocity Verlet; forces
summed in a fixed order, so results do not depend on the thread count), with two
differences:

* **Contacts are bucketed** by the pair of shape kinds and detected by the method made
  for that pair: closed forms for sphere-sphere, sphere-plane and sphere-polytope, the
  exact polytope solver for box/polygon/polyhedron pairs and walls, ADMM for anything
  involving a user-defined shape (or everything, on request). Each bucket's method is
  fixed when the pair list is made, not tested per contact; ADMM is compiled only into
  the loops of scenes that use it (:func:`shape_stepper`), and sphere-only scenes run
  the loop of :mod:`dem.contact.loops`, which has no shape code at all.
* **Detection works on parts.** A body is one part; a compound
  (:class:`~dem.shapes.Compound`) one per convex piece, whose world pose follows its
  body's at the start of every force pass. The pair lists hold a row per pair of
  parts, so each touching pair of parts is a contact of its own (history, warm start,
  point); the law and the torques use the bodies' centres and velocities and the
  parts' radii. Without compounds the part arrays are the body arrays.
* **Rigid bodies rotate with anisotropic inertia.** In 3D the angular momentum is kicked
  in the body frame and the free rotation over a step is the symmetric splitting of the
  free rigid body into rotations about the three principal axes (1, 2, 3, 2, 1 with
  half, half, full, half, half steps). Each sub-rotation is exact, the whole is
  symplectic and time-reversible, keeps the angular momentum exactly (absent torque)
  and the kinetic energy without drift. ``ang_vel`` stays the world-frame angular
  velocity the contact kinematics need.

Per step: (1) half kick and drift; (2) Verlet-list check (stop with ``REBUILD``); (3)
every pair of every bucket, in parallel over pairs, writes its force and two torques
into its own row; (4) every wall pair likewise; (5) per body, in parallel: its pair rows
and wall rows in a fixed order (pair order, then wall order), gravity, damping, the
second half kick.
"""

import math
from typing import NamedTuple

import numba
import numpy as np

from .._jit import kernel, specialise
from ..rotation import to_body, to_world
from ..shapes.table import (
    BOX,
    CUSTOM,
    PLANE,
    POLYGON,
    POLYHEDRON,
    SPHERE,
)
from ..status import NOCONVERGE, NONFINITE, OK, OVERLAP, REBUILD
from .detection.admm import admm_contact, make_admm
from .detection.analytic import sphere_box, sphere_polytope
from .detection.polytope import polytope_contact, polytope_plane
from .kinematics import (_cell_map, _cell_start, _deform_cell, _drift_centre, _strain_norm,
                         add_strain_rate, body_force, cell_spin, moved2, turn_orientation,
                         turn_spring)
from .laws import apply_law

#: detection methods
M_SPHERES, M_SPHERE_BOX, M_SPHERE_POLY, M_POLY, M_ADMM = 0, 1, 2, 3, 4
#: wall methods
W_SPHERE, W_POLY, W_ADMM = 0, 1, 2
_STEPPERS = {}


def method_for(ka, kb, force_admm=False):
    """Detection method for a pair of shape kinds ``ka <= kb`` (walls apart)."""
    poly = (BOX, POLYGON, POLYHEDRON)
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


# --------------------------------------------------------------------------- rigid motion
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


class Detection(NamedTuple):
    """Contact detection settings of the shape loop: the shape table's arrays
    (:meth:`dem.shapes.table.ShapeTable.arrays`), the ADMM tolerance (relative to the
    smaller bounding radius) and its iteration cap."""

    geo: tuple
    tol: float
    max_iter: int


class PartArrays(NamedTuple):
    """The parts detection works on (one per body, one per convex part of a compound):
    ``has_parts`` (a compound is present), each part's body ``ebody``, body-frame
    offset ``eoff`` and orientation ``eq``, own radius ``eprad`` (-1: the body's);
    and the part arrays the loop reads: kind, shape row, position, orientation,
    radius and wall normal (the body arrays themselves when ``has_parts`` is False)."""

    has_parts: bool
    ebody: np.ndarray
    eoff: np.ndarray
    eq: np.ndarray
    eprad: np.ndarray
    ekind: np.ndarray
    eshape: np.ndarray
    epos: np.ndarray
    erot: np.ndarray
    erad: np.ndarray
    enormal: np.ndarray


class BucketIndex(NamedTuple):
    """Pairs (or wall pairs) grouped by bucket: each row's parts ``parts`` (m, 2), the
    rows in bucket order ``order`` with each bucket's first ``bstart``, each bucket's
    detection method ``methods``, and each body's rows ``inc_start``/``inc_list``."""

    parts: np.ndarray
    order: np.ndarray
    bstart: np.ndarray
    methods: np.ndarray
    inc_start: np.ndarray
    inc_list: np.ndarray


def shape_stepper(dim, methods, wall_methods, law_pp, law_pw, periodic=False,
                  custom_sdf=None):
    """The compiled multi-step kernel for one scene's combination of buckets.

    ``methods``/``wall_methods`` are the detection methods of the pair buckets and the
    wall buckets present (``method_for``); the closed forms and the polytope solver are
    always compiled in, ADMM only when a bucket uses it (so one cached loop per
    dimension and laws serves every scene without ADMM). ``custom_sdf`` is the user's SDF
    of a scene with a custom shape (such loops are compiled for the function and not
    cached on disk).
    """
    # the closed forms and the polytope solver are always compiled in (one loop per
    # dimension serves every scene without custom shapes); ADMM only where used
    use_admm = M_ADMM in tuple(methods) or W_ADMM in tuple(wall_methods)
    key = (int(dim), bool(use_admm), int(law_pp), int(law_pw), bool(periodic), custom_sdf)
    if key in _STEPPERS:
        return _STEPPERS[key]
    DIM, PP, PW, PERIODIC = int(dim), int(law_pp), int(law_pw), bool(periodic)
    DEFORM = PERIODIC  # a periodic loop serves orthogonal boxes and deforming cells
    U_ADMM = int(use_admm)
    W_ADM = int(use_admm)

    def run_shape_steps(n_steps, prime, resume, settings, body, cell, nbr, pstate, wstate,
                        sstate, swstate, detection, part_arrays, pindex, windex, params_pp,
                        params_pw, status_out, work_out):
        """Advance ``n_steps``; returns the number of completed steps (see
        :func:`dem.contact.loops.stepper` for ``prime``/``resume``/status and for the
        deforming cell: ``hmat`` advanced by ``lgrad``, ``cellref[0]`` = H^-1 at the
        Verlet build, ``is_cell``).

        Detection works on parts (``e*`` arrays, indexed by ``parts``/``wparts``): a
        body is one part, a compound one per convex part. With ``has_parts`` each part's
        world pose follows its body's every step (``ebody``, body-frame offset ``eoff``
        and orientation ``eq``, radius ``eprad``, or the body's where negative);
        without, the part arrays are the body arrays themselves.

        The arrays come in bundles: those of :func:`dem.contact.loops.stepper`, the
        shape contact state ``sstate`` (:class:`~dem.state.ShapePairState`) and
        ``swstate`` (:class:`~dem.state.ShapeWallState`), ``detection``
        (:class:`Detection`), ``part_arrays`` (:class:`PartArrays`), and the buckets of
        the pairs ``pindex`` and of the wall pairs ``windex`` (:class:`BucketIndex`)."""
        dt, gravity, damping, skin, overlap_limit, _, grow = settings
        (pos, vel, rot, ang_vel, force, torque, radius, mass, inv_mass, inv_inertia,
         is_fixed, normal, mat_id) = body
        hmat, lgrad, cellref, is_cell = cell
        pairs, img, wpairs, pos_ref = nbr
        hist, touch, fpair = pstate
        whist, wforce, wtorque = wstate
        warm, iters, pgeom, tpair = sstate
        wwarm, witers, wgeom = swstate
        geo, tol, max_iter = detection
        (has_parts, ebody, eoff, eq, eprad, ekind, eshape, epos, erot, erad,
         enormal) = part_arrays
        parts, order, bstart, bmethod, inc_start, inc_list = pindex
        wparts, worder, wbstart, wbmethod, winc_start, winc_list = windex
        n = pos.shape[0]
        status_out[0] = OK
        status_out[3] = 0
        done = 0
        half = 0.5 * dt
        hdt = 0.0 if prime else dt
        kick = not prime
        n_iter = 1 if prime else n_steps
        # a deforming cell: fmap = H H_build^-1 maps the positions of the Verlet build
        # affinely to now
        fmap = np.eye(DIM)
        rmax = _cell_start(DEFORM and is_cell, radius, hmat, cellref[0], fmap)
        # a cell whose velocity gradient has a spin turns springs and orientations;
        # its contacts then feel the stretching rate ``rate``, not L's symmetric part
        spin, quat, rate = np.eye(DIM), np.zeros(4), lgrad.copy()
        turns = cell_spin(DIM, DEFORM and is_cell and not prime, lgrad, dt, spin, quat,
                          rate)
        for it in range(n_iter):
            if not prime and not (resume and it == 0):
                if DEFORM and is_cell:  # the cell follows the affine field: H += dt L H
                    _deform_cell(hmat, lgrad, dt)
                    _cell_map(hmat, cellref[0], fmap)
                for b in numba.prange(n):
                    _drift_rigid(b, DIM, DEFORM, lgrad, dt, half, pos, vel, rot, ang_vel,
                                 force, torque, inv_mass, inv_inertia, is_fixed, turns,
                                 spin, quat)
                maxd2 = 0.0
                n_bad = 0
                for b in numba.prange(n):
                    s2 = moved2(DIM, DEFORM, pos, pos_ref, b, fmap)
                    if not math.isfinite(s2):
                        n_bad += 1
                    maxd2 = max(maxd2, s2)
                if n_bad > 0:
                    status_out[0] = NONFINITE
                    status_out[1] = -1
                    return done
                strain = _strain_norm(fmap) if DEFORM else 0.0
                if 2.0 * (math.sqrt(maxd2) + grow) + strain * (2.0 * rmax + skin) > skin:
                    status_out[0] = REBUILD
                    return done
            else:
                force[:, :] = 0.0
                torque[:, :] = 0.0
            if has_parts:  # the parts follow their bodies
                for e in numba.prange(ebody.shape[0]):
                    _part_pose(e, DIM, ebody, eoff, eq, eprad, pos, rot, radius, normal,
                               epos, erot, erad, enormal)
            # ---- 3. pair buckets: each pair writes its own rows (parts pi, pj of i, j)
            for bi in range(bmethod.shape[0]):
                meth = bmethod[bi]
                for q in numba.prange(bstart[bi], bstart[bi + 1]):
                    k = order[q]
                    i = pairs[k, 0]
                    j = pairs[k, 1]
                    pi = parts[k, 0]
                    pj = parts[k, 1]
                    sx, sy, sz = 0.0, 0.0, 0.0
                    if PERIODIC:
                        sx, sy, sz = _image_shift(DIM, hmat, img, k)
                    # the home body A has the lower kind; the law gives the force on B;
                    # B is j's image, so if A is j the shift goes the other way
                    swap = ekind[pj] < ekind[pi]
                    a = j if swap else i
                    b = i if swap else j
                    pa = pj if swap else pi
                    pb = pi if swap else pj
                    if swap:
                        sx, sy, sz = -sx, -sy, -sz
                    if U_ADMM and meth == M_ADMM:
                        st, ov, nx, ny, nz, cx, cy, cz, nit = _ADMM(
                            DIM, ekind[pa], eshape[pa], pa, ekind[pb], eshape[pb], pb, sx,
                            sy, sz, epos, erot, enormal, geo, warm, k, tol, max_iter)
                        iters[k] = nit
                        if st != OK:
                            status_out[0] = NOCONVERGE
                            status_out[1] = i
                            status_out[2] = j
                    else:
                        ov, nx, ny, nz, cx, cy, cz = pair_exact(
                            DIM, meth, pa, pb, sx, sy, sz, epos, erot, erad, eshape, geo)
                    pair_force(DIM, PP, DEFORM, rate, turns, spin, k, i, j, a, b, swap,
                               sx, sy, sz, ov, nx, ny, nz, cx, cy, cz, pos, vel, ang_vel,
                               erad[pa], erad[pb], inv_mass, mat_id, params_pp, hist,
                               touch, fpair, tpair, pgeom, hdt, overlap_limit, status_out)
            # ---- 4. wall buckets: body i against wall w (home body: i)
            work = 0.0
            for bi in range(wbmethod.shape[0]):
                meth = wbmethod[bi]
                for q in numba.prange(wbstart[bi], wbstart[bi + 1]):
                    k = worder[q]
                    i = wpairs[k, 0]
                    w = wpairs[k, 1]
                    pi = wparts[k, 0]
                    pw = wparts[k, 1]
                    if W_ADM and meth == W_ADMM:
                        st, ov, nx, ny, nz, cx, cy, cz, nit = _ADMM(
                            DIM, ekind[pi], eshape[pi], pi, PLANE, 0, pw, 0.0, 0.0, 0.0,
                            epos, erot, enormal, geo, wwarm, k, tol, max_iter)
                        witers[k] = nit
                        if st != OK:
                            status_out[0] = NOCONVERGE
                            status_out[1] = i
                            status_out[2] = w
                    else:
                        ov, nx, ny, nz, cx, cy, cz = wall_exact(
                            DIM, meth, pi, pw, epos, erot, erad, enormal, eshape, geo)
                    work += wall_force(DIM, PW, k, i, w, ov, nx, ny, nz, cx, cy, cz, pos,
                                       vel, ang_vel, erad[pi], inv_mass, mat_id, params_pw,
                                       whist, wforce, wtorque, wgeom, hdt, overlap_limit,
                                       status_out)
            # ---- 5. per body: pair rows, then wall rows, in order; then the kick
            for b in numba.prange(n):
                fx = 0.0
                fy = 0.0
                fz = 0.0
                tx = 0.0
                ty = 0.0
                tz = 0.0
                for q in range(inc_start[b], inc_start[b + 1]):
                    e = inc_list[q]
                    k = e >> 1
                    if e & 1:  # b is j: + f, torque columns nr..
                        fx += fpair[k, 0]
                        fy += fpair[k, 1]
                        if DIM == 3:
                            fz += fpair[k, 2]
                            tx += tpair[k, 3]
                            ty += tpair[k, 4]
                            tz += tpair[k, 5]
                        else:
                            tx += tpair[k, 1]
                    else:
                        fx -= fpair[k, 0]
                        fy -= fpair[k, 1]
                        if DIM == 3:
                            fz -= fpair[k, 2]
                            tx += tpair[k, 0]
                            ty += tpair[k, 1]
                            tz += tpair[k, 2]
                        else:
                            tx += tpair[k, 0]
                for q in range(winc_start[b], winc_start[b + 1]):
                    k = winc_list[q]
                    fx += wforce[k, 0]
                    fy += wforce[k, 1]
                    tx += wtorque[k, 0]
                    if DIM == 3:
                        fz += wforce[k, 2]
                        ty += wtorque[k, 1]
                        tz += wtorque[k, 2]
                _finish_rigid(b, DIM, fx, fy, fz, tx, ty, tz, kick, half, gravity, damping,
                              mass, inv_mass, inv_inertia, is_fixed, rot, vel, ang_vel,
                              force, torque, status_out)
            if not prime:
                work_out[0] += work * dt
            if status_out[0] != OK:
                return done
            if not prime:
                done += 1
        return done

    # with a custom shape, the same code with ``_ADMM`` bound to the user's SDF (not
    # cached on disk); without, ``_ADMM`` stays the global below and the loop caches
    run = specialise(run_shape_steps, parallel=True, _ADMM=make_admm(custom_sdf))
    _STEPPERS[key] = run
    return run


#: the ADMM kernel of loops without custom shapes (a global, so that loops cache)
_ADMM = admm_contact


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
    else:
        r = polytope_contact(dim, shape[a], a, shape[b], b, sx, sy, sz, pos, rot, geo)
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
            hist[k, 0] = 0.0
            hist[k, 1] = 0.0
            hist[k, 2] = 0.0
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
        whist[k, 0] = 0.0
        whist[k, 1] = 0.0
        whist[k, 2] = 0.0
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
def _finish_rigid(b, dim, fx, fy, fz, tx, ty, tz, kick, half, gravity, damping, mass,
                  inv_mass, inv_inertia, is_fixed, rot, vel, ang_vel, force, torque,
                  status_out):
    """:func:`~dem.contact.kinematics.body_force`, then the second half kick (anisotropic
    rotation in 3D)."""
    fx, fy, fz, tx, ty, tz = body_force(b, dim, fx, fy, fz, tx, ty, tz, gravity, damping,
                                        mass, is_fixed, vel, ang_vel, force, torque,
                                        status_out)
    if kick and not is_fixed[b]:
        vel[b, 0] += half * fx * inv_mass[b]
        vel[b, 1] += half * fy * inv_mass[b]
        if dim == 3:
            vel[b, 2] += half * fz * inv_mass[b]
        _kick_rotation(dim, b, half, rot, ang_vel, torque, inv_inertia)


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
