"""The drive of an RVE under mixed control, checked inside the compiled step loop
(kernel module).

:meth:`dem.rve.RVE.load` with stress targets (a drained biaxial or triaxial test, a
consolidation) imposes its strain increment and relaxes in chunks of ``check_every``
steps. At every check, :func:`drive_check` measures the packing
(:func:`dem.rve_measure.measure_periodic`), sets the velocity gradient of each
stress-controlled component from its error and the contact tangent (a proportional
servo, time constant ``4 check_every dt``: :func:`servo_rates`), and ends the drive when
every servo is on target and the unbalanced-force ratio is below ``tol``. A servo that
stalls while the packing is at rest, once half the step cap is spent, has its gain
doubled (:func:`stall_watch`, :attr:`dem.rve.RVE.STALL_CHECKS`), and halved again at
any check where its worst error changed sign (:func:`overshoot_watch`). The sphere loop calls
it at its checks (:mod:`dem.contact.loops`), so a drive of spheres or disks is one
compiled loop; the loop of level-set shapes runs chunk by chunk with the same check
called between chunks (:func:`dem.rve_servo.drive`).

The entries of the drive's ``settings`` and ``state`` arrays (:class:`dem.state.ServoDrive`)
are the ``SET_*`` and ``ST_*`` indices below. Each chunk's velocity gradient and steps
go to the drive's log, from which the RVE composes its deformation.
"""

import math

import numpy as np

from .._jit import kernel
from ..rve_measure import measure_periodic
from ..status import CAME_APART, NOT_RELAXED, OK, RELAXED
from .relaxation import OUT_NEXT

#: settings: stress tolerance (relative), shear tolerance (of the stress scale), the
#: largest strain rate [1/s], the servo time constant [s], relax (1) or stop once the
#: increment is imposed (0), the relaxation's step cap, the increment's steps, the
#: checks without progress of a stalled servo, and whether any component is servoed
(SET_STRESS_TOL, SET_SHEAR_TOL, SET_RATE_MAX, SET_TAU, SET_RELAX, SET_MAX_RELAX, SET_N_LOAD,
 SET_STALL_CHECKS, SET_SERVOED, N_SETTINGS) = range(10)
#: state: the servo's gain, its best error (in tolerances) and the checks since it
#: last improved by 10 %, the sign of its last worst error, the gain doublings, the
#: steps since the drive began (the increment's come first), and the chunks logged
(ST_GAIN, ST_BEST, ST_STALLED, ST_LAST_SIGN, ST_BOOSTS, ST_STEPS, ST_CHUNKS,
 N_STATE) = range(8)


@kernel
def servo_rates(d, stress, tangent, target, mask, gain, settings, lgrad):
    """Set ``lgrad`` [1/s] on the stress-controlled components of ``mask`` from their
    errors (zero elsewhere). Returns ``(on_target, worst, sign)``: whether every servo
    is within its tolerance, the largest error in units of its tolerance, and that
    error's sign.

    Component ``ab`` is driven at ``gain err / (C_abab tau)`` (twice ``C_abab`` off the
    diagonal, where ``d sigma_ab = C_abab d eps_ab + C_abba d eps_ba``), capped at the
    largest strain rate. A shear target, or a target of zero, is judged against the
    mean stress (the shear tolerance of the larger of it and the largest target).
    """
    rate_max = settings[SET_RATE_MAX]
    tau = settings[SET_TAU]
    on_target = True
    worst, worst_sign = 0.0, 0.0
    lgrad[:, :] = 0.0
    trace = 0.0
    biggest = 0.0
    for a in range(d):
        trace += stress[a, a]
        biggest = max(biggest, abs(target[a, a]))
    scale = max(biggest, abs(trace) / d, 1e-300)
    for a in range(d):
        for b in range(a, d):
            if not mask[a, b]:
                continue
            err = target[a, b] - stress[a, b]
            if a == b and target[a, b] != 0.0:
                allowed = settings[SET_STRESS_TOL] * abs(target[a, b])
            else:
                allowed = settings[SET_SHEAR_TOL] * scale
            on_target = on_target and abs(err) <= allowed
            if abs(err) > worst * allowed:
                worst, worst_sign = abs(err) / allowed, math.copysign(1.0, err)
            m = tangent[a, b, a, b] * (1.0 if a == b else 2.0)
            rate = gain * err / (m * tau) if m > 0.0 else math.copysign(rate_max, err)
            rate = max(-rate_max, min(rate_max, rate))
            lgrad[a, b] = rate
            lgrad[b, a] = rate
    return on_target, worst, worst_sign


@kernel
def overshoot_watch(state, worst_sign):
    """Every check of a servo: a doubled gain is halved (to at least 1) when the worst
    error changed sign since the last check (an overshoot), moving or at rest. A gain
    doubled for a packing at rest would otherwise stay when the packing moves again,
    and a packing that comes apart then swings at the largest strain rate for good:
    jammed past the target at one check, loose at the next."""
    if state[ST_GAIN] > 1.0 and worst_sign == -state[ST_LAST_SIGN]:
        state[ST_GAIN] = max(1.0, 0.5 * state[ST_GAIN])
    state[ST_LAST_SIGN] = worst_sign


@kernel
def stall_watch(state, worst, checks):
    """One check of a servo at rest and off target: its gain doubled after ``checks``
    checks without a 10 % gain on its best error (an overshoot halves it again:
    :func:`overshoot_watch`). Returns 1 when the gain doubled, else 0."""
    boosted = 0
    if worst < 0.9 * state[ST_BEST]:
        state[ST_BEST] = worst
        state[ST_STALLED] = 0.0
    else:
        state[ST_STALLED] += 1.0
    if state[ST_STALLED] >= checks:
        state[ST_GAIN] = 2.0 * state[ST_GAIN]
        state[ST_BEST] = worst
        state[ST_STALLED] = 0.0
        boosted = 1
    return boosted


@kernel
def drive_check(code, pos, vel, mass, radius, mat_id, pairs, img, hmat, lgrad, fpair,
                shaped, pgeom, params, check):
    """One check of a drive (:class:`dem.state.RelaxCheck` with its ``servo``): measure
    the packing, then either end the drive or set the cell's velocity gradient
    ``lgrad`` [1/s] for the next chunk, log that chunk and set the steps to the next
    check (``check.out[OUT_NEXT]``).

    ``code`` is the pair law's code; ``shaped``, ``pgeom`` and ``params`` as
    :func:`dem.rve_measure.measure_periodic`. Returns ``OK`` (go on), ``RELAXED`` (on
    target and at rest, or the increment imposed when not relaxing), ``CAME_APART``
    (a strain-controlled packing with too few contacts for ``check.apart_checks``
    checks in a row) or ``NOT_RELAXED`` (the step cap spent); the velocity gradient is
    zero once the drive ends.
    """
    s = check.servo
    se, st, out = s.settings, s.state, check.out
    n, d = pos.shape
    servoed = se[SET_SERVOED] > 0.0
    n_c, unbalanced = measure_periodic(
        code, pos, vel, mass, radius, mat_id, pairs, img, hmat, fpair, shaped, pgeom, params,
        np.linalg.det(hmat), servoed, check.net, s.degree, s.stress, s.tangent, s.fabric)
    out[0] = unbalanced
    out[1] = n_c
    out[3] += 1.0
    n_load = int(se[SET_N_LOAD])
    steps = int(st[ST_STEPS])
    done_load = min(steps, n_load)  # the increment's chunks run first
    lgrad[:, :] = 0.0
    servo_ok = True
    if servoed:
        servo_ok, worst, sign = servo_rates(d, s.stress, s.tangent, s.target, s.mask,
                                            st[ST_GAIN], se, lgrad)
        overshoot_watch(st, sign)
        late = steps - n_load >= int(se[SET_MAX_RELAX]) // 2
        if late and not servo_ok and unbalanced < check.tol:
            # at rest, off target, half the cap spent: still closing in?
            st[ST_BOOSTS] += stall_watch(st, worst, se[SET_STALL_CHECKS])
    n_chunk = check.every
    if done_load < n_load:
        n_chunk = min(n_chunk, n_load - done_load)
        for a in range(d):
            for b in range(d):
                lgrad[a, b] += s.l_load[a, b]
    elif servo_ok and (unbalanced < check.tol or se[SET_RELAX] == 0.0):
        lgrad[:, :] = 0.0
        return RELAXED
    if done_load >= n_load and not servoed and 2.0 * n_c / n < check.min_coordination:
        out[2] += 1.0
        if check.apart_checks > 0 and out[2] >= check.apart_checks:
            lgrad[:, :] = 0.0
            return CAME_APART
    else:
        out[2] = 0.0
    k = int(st[ST_CHUNKS])
    if steps - n_load >= int(se[SET_MAX_RELAX]) or k >= s.log_n.shape[0]:
        lgrad[:, :] = 0.0
        return NOT_RELAXED
    s.log[k, :, :] = lgrad
    s.log_n[k] = n_chunk
    st[ST_CHUNKS] = k + 1
    st[ST_STEPS] = steps + n_chunk
    out[OUT_NEXT] = n_chunk
    return OK
