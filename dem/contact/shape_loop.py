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

from .._jit import recipe, specialise
from ..shapes.kinds import PLANE
from ..status import NOCONVERGE, NONFINITE, OK, REBUILD
from .detection.admm import admm_contact, make_admm
from .kinematics import _cell_map, _cell_start, _deform_cell, _strain_norm, cell_spin, moved2
from .rigid import _drift_rigid, _finish_rigid, _part_pose
from .shape_contacts import (M_ADMM, W_ADMM, _image_shift, pair_exact, pair_force, wall_exact,
                             wall_force)


_STEPPERS = {}


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
                        # the plane's kind and row as run-time int64s, typed as the pair
                        # call's: one compile of the solver serves both calls
                        st, ov, nx, ny, nz, cx, cy, cz, nit = _ADMM(
                            DIM, ekind[pi], eshape[pi], pi, np.int64(PLANE), np.int64(0),
                            pw, 0.0, 0.0, 0.0, epos, erot, enormal, geo, wwarm, k, tol,
                            max_iter)
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
                              body, rot, vel, ang_vel, force, torque, status_out)
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
    if custom_sdf is None:  # else compiled for this process only
        recipe(run, shape_stepper, DIM, (M_ADMM,) if use_admm else (), (), PP, PW,
               periodic=PERIODIC)
    _STEPPERS[key] = run
    return run


#: the ADMM kernel of loops without custom shapes (a global, so that loops cache)
_ADMM = admm_contact
