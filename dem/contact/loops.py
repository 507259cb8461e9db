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
4. sphere-wall contacts, likewise, then sphere-mesh contacts (scenes with mesh walls,
   whose vertices moved after the drift of 1: a wall that moved half the skin since
   the Verlet build also stops the chunk with ``REBUILD``);
5. per body: sum of contact forces, gravity, local damping, second half kick.

Summation order is fixed, so results do not depend on the number of threads. Bodies
fall into ``N_BLOCKS`` blocks of consecutive rows (a fixed number, whatever the thread
count); a contact inside one block is *internal*, others are *cross*. Every body sums
its internal contacts in pair order, then its cross contacts in pair order, then its
walls, then its mesh rows in row order. On one thread, 3 and 4 add each contact to its
bodies as they go, in that order (mesh rows: their sum per sphere, last).
On several threads, the internal contacts run in parallel over blocks, each block adding
into its own bodies; the cross contacts run in parallel over pairs and write their two
contributions to rows laid out body by body in pair order; 5 adds each body's rows and
walls in parallel. The sums are the same, bit for bit. With bodies in spatial order
(``Bodies.sort_spatially``) few contacts cross a block boundary. ``touch[k]`` marks the
pairs in contact at the last force evaluation.
"""

import math

import numba
import numpy as np

from .._jit import kernel, recipe
from ..status import NONFINITE, OK, REBUILD
from .kinematics import (_cell_map, _cell_start, _deform_cell, _drift_body, _finish_body,
                         _strain_norm, cell_spin, moved2)
from .mesh_contacts import mesh_forces, mesh_power, move_meshes
from .relaxation import OUT_NEXT, relax_check
from .servo import drive_check
from .sphere_contacts import (N_BLOCKS, _compact_inner, _near, _scatter_pair, _sphere_pair,
                              _sphere_wall)

_STEPPERS = {}


def stepper(dim, law_pp, law_pw, periodic=False, deform=False, rolling=False, mesh=False,
            serial=False):
    """The compiled multi-step kernel for ``dim`` (2 or 3) and two law codes.

    ``law_pp``/``law_pw`` are law codes (a registered law class's ``code``,
    :data:`dem.contact.laws.LAWS`: the loop calls that law's kernels, resolved at
    compile time by :mod:`dem.contact.laws.dispatch`); ``periodic`` (or ``deform``)
    compiles in the periodic-image shifts and the deforming cell (:mod:`dem.boundary`),
    one kernel for both: with ``is_cell`` true at run time, ``hmat`` is advanced by
    ``lgrad`` every step, bodies are carried by the affine field and ``cellref``
    (2, d, d) holds H^-1 at the Verlet build and at the inner list's making; an orthogonal
    periodic box passes ``is_cell`` false and a zero ``lgrad``, and every affine term
    adds an exact zero.
    ``rolling`` compiles in rolling resistance (:mod:`dem.contact.rolling`), whose
    parameters follow the law's in the parameter tables. ``mesh`` compiles in the
    contacts with triangle-mesh walls (:mod:`dem.contact.mesh_contacts`): their motion
    after the drift, their forces after the plane walls' in every body's sum.
    ``serial`` compiles the one-thread loop: each contact is added to its bodies as it
    comes, in the order the threaded sums use, so that the two loops give the same bits;
    the caller takes it for a scene that runs on one thread. It is a kernel of its own,
    not a branch of the threaded one, because numba's parallel passes cost in
    proportion to the whole function: a scene compiles only the kind it runs, and each
    kind compiles without the other's copy of the contact code
    (``benchmarks/loop_compile.py``: the one-thread loop of a 2D periodic RVE in 24 s
    against 92 s for the kernel that held both). The one-thread loop is still compiled
    with ``parallel=True`` (its per-body loops run on the one thread): compiled without,
    the same code ran 11.7x slower in that benchmark.
    Only integers are captured, so the kernel caches on disk; the branches not taken
    fold away at compile time.
    """
    key = (int(dim), int(law_pp), int(law_pw), bool(periodic or deform), bool(rolling),
           bool(mesh), bool(serial))
    if key in _STEPPERS:
        return _STEPPERS[key]
    DIM, PP, PW, PERIODIC, ROLL, MESH, SERIAL = key
    DEFORM = PERIODIC

    @kernel(parallel=True)
    def run_steps(n_steps, prime, resume, settings, body, cell, nbr, pstate,
                  wstate, index, params_pp, params_pw, status_out, work_out, meshes,
                  check):
        """Advance ``n_steps``; returns the number of completed steps.

        The arrays come in bundles (:mod:`dem.state`): ``settings``
        (:class:`~dem.state.StepSettings`), ``body`` (:class:`~dem.state.BodyArrays`),
        ``cell`` (:class:`~dem.state.CellArrays`), ``nbr``
        (:class:`~dem.state.NeighborArrays`), the contact state ``pstate``
        (:class:`~dem.state.PairState`) and ``wstate`` (:class:`~dem.state.WallState`),
        and the loop's own index of the inner list
        (:class:`~dem.contact.sphere_contacts.InnerIndex`).

        ``prime`` = True computes forces at the current state without moving anything
        (tangential springs are not advanced). ``resume`` = True finishes a step whose
        drift was done by the previous call (which stopped with ``REBUILD``).
        ``status_out`` (4,) int64 receives (code, i, j, inner-list refreshes); ``work_out`` (1,)
        accumulates the work of walls on bodies [J]. ``meshes`` is the
        :class:`~dem.contact.mesh_contacts.MeshLoop` (empty arrays unless ``mesh``).
        ``check`` (:class:`~dem.state.RelaxCheck`) asks for relaxation checks, or an
        RVE's drive (:mod:`dem.contact.servo`), whose checks set ``lgrad``: the call ends
        early with the status of the check that stops it (``RELAXED``, ``CAME_APART``,
        ``NOT_RELAXED``).
        """
        dt, gravity, damping, skin, overlap_limit, skin_inner, grow = settings
        (pos, vel, rot, ang_vel, force, torque, radius, mass, inv_mass, inv_inertia,
         is_fixed, normal, mat_id) = body
        hmat, lgrad, cellref, is_cell = cell
        pairs, img, wpairs, pos_ref = nbr
        hist, touch, fpair = pstate
        whist, wforce, wtorque = wstate
        contrib, slot, inc_start, blk_start, inner, n_inner, pos_inner, wstart = index
        msum = meshes.msum  # (n, 6) each sphere's mesh force and torque (``meshes``
        # holds named tuples, which numba does not pass into a parallel loop)
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
        # (made again when a drive's check sets a new L: ``respin``)
        spin, quat, rate = np.eye(DIM), np.zeros(4), np.zeros((DIM, DIM))
        turns = False
        respin = True
        pgeom_none = np.zeros((0, 7))  # spheres have no contact geometry rows
        for it in range(n_iter):
            if respin:
                rate[:, :] = lgrad
                turns = cell_spin(DIM, DEFORM and is_cell and not prime, lgrad, dt, spin,
                                  quat, rate)
                respin = False
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
                if MESH:  # the walls move; their candidates hold while they moved < skin/2
                    dw2 = move_meshes(dt, meshes.mesh, meshes.walls)
                    if 2.0 * math.sqrt(dw2) + skin_inner > skin:
                        status_out[0] = REBUILD
                        return done
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
            if MESH:  # 4b. sphere-mesh rows, by blocks of spheres (their sums added in 5)
                mesh_forces(PW, ROLL, body, meshes.mesh, meshes.walls, meshes.state,
                            meshes.mstart, meshes.mflag, msum, params_pw, hdt, overlap_limit,
                            status_out)
            if SERIAL:
                # ---- 3-5 on one thread: add each contact to its bodies as it comes,
                # internal pairs first, then cross pairs (the order the threads use)
                for q in range(n_tot):
                    k = inner[q]
                    (on, fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz) = _sphere_pair(
                        k, DIM, PP, ROLL, PERIODIC, DEFORM, pos, vel, ang_vel, radius,
                        inv_mass, inv_inertia, mat_id, hmat, rate, turns, spin, pairs, img,
                        touch, hist, params_pp, hdt, overlap_limit, status_out)
                    if on:
                        _scatter_pair(k, DIM, pairs[k, 0], pairs[k, 1], fx, fy, fz, tix,
                                      tiy, tiz, tjx, tjy, tjz, fpair, force, torque)
                for k in range(mw):
                    (on, fx, fy, fz, tx, ty, tz, power) = _sphere_wall(
                        k, DIM, PW, ROLL, pos, vel, ang_vel, radius, inv_mass, inv_inertia,
                        mat_id, normal, wpairs, whist, params_pw, hdt, overlap_limit,
                        status_out)
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
                if MESH:  # mesh walls last, as in the threaded sums
                    for b in range(n):
                        for a in range(3):
                            force[b, a] += msum[b, a]
                            torque[b, a] += msum[b, 3 + a]
                for b in range(n):
                    fz = force[b, 2] if DIM == 3 else 0.0
                    ty = torque[b, 1] if DIM == 3 else 0.0
                    tz = torque[b, 2] if DIM == 3 else 0.0
                    _finish_body(b, DIM, force[b, 0], force[b, 1], fz, torque[b, 0], ty,
                                 tz, kick, half, gravity, damping, body, vel, ang_vel,
                                 force, torque, status_out)
            else:
                # ---- 3a. internal pairs, parallel over blocks: both bodies of a pair
                # belong to the block, so each block adds into its own bodies
                for blk in numba.prange(N_BLOCKS):
                    for q in range(blk_start[blk], blk_start[blk + 1]):
                        k = inner[q]
                        (on, fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz) = _sphere_pair(
                            k, DIM, PP, ROLL, PERIODIC, DEFORM, pos, vel, ang_vel, radius,
                            inv_mass, inv_inertia, mat_id, hmat, rate, turns, spin, pairs,
                            img, touch, hist, params_pp, hdt, overlap_limit, status_out)
                        if on:
                            _scatter_pair(k, DIM, pairs[k, 0], pairs[k, 1], fx, fy, fz,
                                          tix, tiy, tiz, tjx, tjy, tjz, fpair, force,
                                          torque)
                # ---- 3b. cross pairs, parallel over pairs: each writes its two
                # contributions to rows laid out body by body, in pair order
                for q in numba.prange(n_int, n_tot):
                    k = inner[q]
                    (on, fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz) = _sphere_pair(
                        k, DIM, PP, ROLL, PERIODIC, DEFORM, pos, vel, ang_vel, radius,
                        inv_mass, inv_inertia, mat_id, hmat, rate, turns, spin, pairs, img,
                        touch, hist, params_pp, hdt, overlap_limit, status_out)
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
                        k, DIM, PW, ROLL, pos, vel, ang_vel, radius, inv_mass, inv_inertia,
                        mat_id, normal, wpairs, whist, params_pw, hdt, overlap_limit,
                        status_out)
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
                    if MESH:
                        fx += msum[b, 0]
                        fy += msum[b, 1]
                        fz += msum[b, 2]
                        tx += msum[b, 3]
                        ty += msum[b, 4]
                        tz += msum[b, 5]
                    _finish_body(b, DIM, fx, fy, fz, tx, ty, tz, kick, half, gravity,
                                 damping, body, vel, ang_vel, force, torque, status_out)
            if MESH:
                work += mesh_power(meshes)
            if not prime:
                work_out[0] += work * dt
            if status_out[0] != OK:
                return done
            if not prime:
                done += 1
                if check.every > 0:
                    check.out[OUT_NEXT] -= 1.0
                if check.every > 0 and check.out[OUT_NEXT] <= 0.0:
                    code = OK
                    if PERIODIC:
                        if check.servo.settings.shape[0] == 0:
                            code = relax_check(pos, radius, pairs, img, hmat, fpair, check)
                        else:  # an RVE's drive: the check sets the cell's next L
                            # the law code as a run-time int64, as the Python-side
                            # checks pass it: one compile of the check serves both
                            # (a literal code would compile it again per law)
                            code = drive_check(np.int64(PP), pos, vel, mass, radius,
                                               mat_id, pairs, img, hmat, lgrad, fpair,
                                               False, pgeom_none, params_pp, check)
                            respin = True
                    else:
                        code = relax_check(pos, radius, pairs, img, hmat, fpair, check)
                    if code != OK:
                        status_out[0] = code
                        return done
        return done

    _STEPPERS[key] = recipe(run_steps, stepper, DIM, PP, PW, PERIODIC, rolling=ROLL,
                            mesh=MESH, serial=SERIAL)
    return run_steps
