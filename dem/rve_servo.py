"""The drive of an RVE under stress or mixed control, and with progress reports.

:meth:`dem.rve.RVE.load` with stress targets (a drained biaxial or triaxial test, a
consolidation) or with a ``progress`` callback imposes its increment and relaxes with a
check every ``check_every`` steps: :func:`dem.contact.servo.drive_check` measures the
packing, sets the velocity gradient of each stress-controlled component from its error
and the contact tangent, and ends the drive when every servo is on target and the
unbalanced-force ratio is below ``tol`` (see :mod:`dem.contact.servo`). For spheres and
disks the sphere loop makes the checks itself: the drive is one compiled loop, which
returns to Python only to rebuild the neighbour list, and, with a ``progress``
callback, every :data:`PROGRESS_CHECKS` checks. The loop of level-set shapes runs from
check to check, the same check called between its chunks. The cell's deformation is
composed afterwards from the drive's log of chunks, as a chunk-by-chunk drive composes
it. Strain control without a callback runs in :meth:`dem.rve.RVE.apply_strain`'s own
compiled loops instead, to the same state.
"""

import math

import numpy as np

from .boundary import cell_map
from .contact.relaxation import OUT_NEXT
from .contact.servo import (N_SETTINGS, N_STATE, SET_MAX_RELAX, SET_N_LOAD, SET_RATE_MAX,
                            SET_RELAX, SET_SERVOED, SET_SHEAR_TOL, SET_STALL_CHECKS,
                            SET_STRESS_TOL, SET_TAU, ST_BEST, ST_BOOSTS, ST_CHUNKS, ST_GAIN,
                            drive_check)
from .state import RelaxCheck, ServoDrive
from .status import CAME_APART, NOT_RELAXED, OK, RELAXED

#: with a ``progress`` callback, a drive of spheres reports after this many checks
PROGRESS_CHECKS = 20


def drive_arrays(rve, n_load, l_load, target, mask, relax):
    """The :class:`~dem.state.RelaxCheck` of a drive of ``rve``: its settings, a fresh
    servo (gain 1), room in the log for every chunk the step cap allows."""
    sim, d, every = rve.sim, rve.dim, rve.check_every
    settings = np.zeros(N_SETTINGS)
    settings[SET_STRESS_TOL] = rve.stress_tol
    settings[SET_SHEAR_TOL] = rve.SHEAR_TOL
    settings[SET_RATE_MAX] = rve.max_step_strain / sim.dt
    settings[SET_TAU] = 4.0 * every * sim.dt  # the servo's time constant
    settings[SET_RELAX] = float(relax)
    settings[SET_MAX_RELAX] = rve.max_relax_steps
    settings[SET_N_LOAD] = n_load
    settings[SET_STALL_CHECKS] = rve.STALL_CHECKS
    settings[SET_SERVOED] = float(mask.any())
    state = np.zeros(N_STATE)
    state[ST_GAIN], state[ST_BEST] = 1.0, math.inf
    chunks = -(-n_load // every) + -(-rve.max_relax_steps // every) + 2
    n = sim.bodies.n
    servo = ServoDrive(np.ascontiguousarray(target, np.float64),
                       np.ascontiguousarray(mask, np.bool_),
                       np.ascontiguousarray(l_load, np.float64), settings, state,
                       np.zeros((chunks, d, d)), np.zeros(chunks, np.int64),
                       np.zeros(n, np.int64), np.zeros((d, d)), np.zeros((d, d, d, d)),
                       np.zeros((d, d)))
    return RelaxCheck(every, float(rve.tol), float(rve.APART_COORDINATION),
                      int(rve.APART_CHECKS), np.zeros((n, d)), np.zeros(5), servo)


def _check(rve, check):
    """One drive check from Python (the first, and those between a shape loop's
    chunks)."""
    sim = rve.sim
    sim.prime()
    b, nl = sim.bodies, sim.neighbors
    pgeom = sim.shape_state.pgeom if sim.shaped else np.zeros((0, 7))
    return drive_check(sim.model.kind("pp").code, b.pos, b.vel, b.mass, b.radius, b.mat_id,
                       nl.pairs, nl.img, sim.image_matrix, sim.cell.lgrad,
                       sim.pair_state.fpair, sim.shaped, pgeom, sim.parameter_table("pp"),
                       check)


def _run(rve, check, progress, start, chunked):
    """Step the drive of ``check`` from its first check on; returns the status of the
    check that ended it."""
    sim = rve.sim
    code = _check(rve, check)
    if chunked:  # a call per chunk, the check between them (the shape loop's way)
        while code == OK:
            sim.run(int(check.out[OUT_NEXT]), progress=False)
            code = _check(rve, check)
            if progress is not None:
                progress(sim.step - start)
        return code
    most = int(check.servo.settings[SET_N_LOAD] + check.servo.settings[SET_MAX_RELAX]
               + 2 * check.every)  # the checks end the drive before this
    piece = most if progress is None else PROGRESS_CHECKS * check.every
    while code == OK and sim.step - start < most:
        code = sim.run_checked(check, piece, progress=False)
        if progress is not None:
            progress(sim.step - start)
    return code


def drive(rve, deps, target, mask, progress, relax=True, chunked=False):
    """Drive ``rve`` (:meth:`dem.rve.RVE.load`'s arguments, validated); returns its
    stress (d, d) [Pa] at the end, and keeps the last response in ``rve._last``.
    ``chunked`` steps spheres as shapes are stepped, a call of the loop per chunk with
    the check made from Python between them: the same state, bit for bit (the tests'
    reference for the checks the loop makes)."""
    sim, cell = rve.sim, rve.cell
    n_load, l_load = rve._load_gradient(deps)
    check = drive_arrays(rve, n_load, l_load, target, mask, relax)
    start = sim.step
    try:
        code = _run(rve, check, progress, start, chunked or sim.shaped)
    finally:
        cell.lgrad[:] = 0.0
    servo = check.servo
    rve.steps_run += sim.step - start
    for k in range(int(servo.state[ST_CHUNKS])):  # the chunks ran whole, in this order
        rve.deformation = cell_map(servo.log[k], sim.dt, int(servo.log_n[k])) \
            @ rve.deformation
    rve.servo_boosts += int(servo.state[ST_BOOSTS])
    r = rve.response(tangent=bool(mask.any()))
    if code == CAME_APART:
        raise rve._apart(r, rve.APART_CHECKS)
    if code == NOT_RELAXED:
        raise rve._not_relaxed(r, target, mask)
    if code != RELAXED:
        raise RuntimeError(f"the drive ended with status {code} at step {sim.step}")
    rve.last_relax_steps = sim.step - start
    rve._last = r
    return r["stress"]
