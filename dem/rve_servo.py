"""The chunked drive of an RVE: stress and mixed control by a servo on the cell.

:meth:`dem.rve.RVE.load` with stress targets (a drained biaxial or triaxial test, a
consolidation) or with a ``progress`` callback steps in chunks of ``check_every``
steps. After each chunk it measures the packing (:meth:`dem.rve.RVE.response`), sets
the velocity gradient of each stress-controlled component from its error and the
contact tangent (a proportional servo, time constant ``4 check_every dt``), and ends
when every servo is on target and the unbalanced-force ratio is below ``tol``. A
servo that stalls while the packing is at rest, once half the step cap is spent, has
its gain doubled (:attr:`dem.rve.RVE.STALL_CHECKS`). Strain control without a
callback runs in compiled loops instead (:meth:`dem.rve.RVE.apply_strain`), to the
same state.
"""

import math

import numpy as np

from .boundary import cell_map


def servo(rve, r, target, mask, gain, lgrad):
    """Set ``lgrad`` [1/s] on the stress-controlled components from their errors in the
    response ``r`` (zero elsewhere). Returns ``(on_target, worst, sign)``: whether every
    servo is within its tolerance, the largest error in units of its tolerance, and
    that error's sign."""
    d, dt = rve.dim, rve.sim.dt
    rate_max = rve.max_step_strain / dt
    tau = 4.0 * rve.check_every * dt  # servo time constant
    on_target = True
    worst, worst_sign = 0.0, 0.0
    lgrad[:] = 0.0
    c = r["tangent"]
    # a shear target of zero is judged against the mean stress
    scale = max(np.abs(np.diag(target)).max(), abs(np.trace(r["stress"])) / d, 1e-300)
    for a, b in zip(*np.nonzero(np.triu(mask)), strict=True):
        err = target[a, b] - r["stress"][a, b]
        if a == b and target[a, b] != 0.0:
            allowed = rve.stress_tol * abs(target[a, b])
        else:  # shear (or a zero target): SHEAR_TOL of the mean stress
            allowed = rve.SHEAR_TOL * scale
        on_target = on_target and abs(err) <= allowed
        if abs(err) > worst * allowed:
            worst, worst_sign = abs(err) / allowed, math.copysign(1.0, err)
        # d sigma_ab = C_abab d eps_ab (+ C_abba d eps_ba off the diagonal)
        m = c[a, b, a, b] * (1.0 if a == b else 2.0)
        rate = gain * err / (m * tau) if m > 0.0 else math.copysign(rate_max, err)
        lgrad[a, b] = lgrad[b, a] = max(-rate_max, min(rate_max, rate))
    return on_target, worst, worst_sign


class StallWatch:
    """The gain of a servo that stalls at rest (:attr:`dem.rve.RVE.STALL_CHECKS`):
    doubled after that many checks without a 10 % gain on the best error, halved
    (to at least 1) on an overshoot."""

    def __init__(self, checks):
        self.checks = checks
        self.gain, self.best, self.stalled, self.last_sign = 1.0, math.inf, 0, 0.0

    def watch(self, worst, worst_sign):
        """One check of a servo at rest and off target; True when the gain doubled."""
        boosted = False
        if self.gain > 1.0 and worst_sign == -self.last_sign:
            self.gain = max(1.0, 0.5 * self.gain)  # overshot
        if worst < 0.9 * self.best:
            self.best, self.stalled = worst, 0
        else:
            self.stalled += 1
        if self.stalled >= self.checks:
            self.gain, self.best, self.stalled = 2.0 * self.gain, worst, 0
            boosted = True
        self.last_sign = worst_sign
        return boosted


def drive(rve, deps, target, mask, progress, relax=True):
    """Drive ``rve`` (:meth:`dem.rve.RVE.load`'s arguments, validated); returns its
    stress (d, d) [Pa] at the end, and keeps the last response in ``rve._last``."""
    sim, cell, d = rve.sim, rve.cell, rve.dim
    n_load, l_load = rve._load_gradient(deps)
    servoed = bool(mask.any())
    start = sim.step
    done_load = 0
    apart = 0
    stall = StallWatch(rve.STALL_CHECKS)
    lgrad = np.zeros((d, d))
    r = rve.response(tangent=servoed)
    while True:
        servo_ok = True
        lgrad[:] = 0.0
        if servoed:
            servo_ok, worst, worst_sign = servo(rve, r, target, mask, stall.gain, lgrad)
            late = sim.step - start - n_load >= rve.max_relax_steps // 2
            if late and not servo_ok and r["unbalanced"] < rve.tol:
                # at rest, off target, half the cap spent: still closing in?
                rve.servo_boosts += stall.watch(worst, worst_sign)
        n_chunk = rve.check_every
        if done_load < n_load:
            n_chunk = min(n_chunk, n_load - done_load)
            lgrad += l_load
        elif servo_ok and (r["unbalanced"] < rve.tol or not relax):
            break
        if done_load >= n_load and not servoed \
                and r["coordination"] < rve.APART_COORDINATION:
            apart += 1
            if apart >= rve.APART_CHECKS:
                cell.lgrad[:] = 0.0
                raise rve._apart(r, apart)
        else:
            apart = 0
        if sim.step - start - n_load >= rve.max_relax_steps:
            cell.lgrad[:] = 0.0
            raise rve._not_relaxed(r, target, mask)
        cell.lgrad[:] = lgrad
        sim.run(n_chunk, progress=False)
        rve.steps_run += n_chunk
        rve.deformation = cell_map(lgrad, sim.dt, n_chunk) @ rve.deformation
        cell.lgrad[:] = 0.0
        if done_load < n_load:
            done_load += n_chunk
        r = rve.response(tangent=servoed)
        if progress is not None:
            progress(sim.step - start)
    rve.last_relax_steps = sim.step - start
    rve._last = r
    return r["stress"]
