"""Saturated porous media: Biot's u-p equations, monolithic, over the micro models.

The unknowns are the displacement ``u`` on the quadratic element of the dry solver
and the pore pressure ``p`` [Pa] (compression positive) on the linear element of the
same mesh and order of geometry (:data:`PAIRS`): Taylor-Hood pairs, stable in the
inf-sup sense, so the pressure does not oscillate when a load comes on at once and
the mixture answers undrained. Equal-order pairs are refused. Per unit volume, under
small kinematics::

    div(sigma' - alpha p I) + b = 0                              (equilibrium)
    alpha d(tr eps)/dt + (1/M) dp/dt + div w = 0,  w = -kappa grad p   (mass, Darcy)

``sigma'`` is the effective stress of the micro models (tension positive; the total
stress is ``sigma' - alpha p I``), ``alpha`` Biot's coefficient, ``1/M = n/K_f +
(alpha - n)/K_s`` the storage (porosity ``n``, fluid and grain bulk moduli), and
``kappa = k / mu`` the mobility (intrinsic permeability over the fluid's viscosity,
a scalar or a tensor). Backward Euler over a time step ``dt`` gives, with test
functions ``v`` and ``q``::

    R_u = int sigma' : eps(v) - int alpha p div v - f_ext(v)
    R_p = -int q alpha div du - int q (p - p_n) / M - dt int grad q . kappa grad p
          + dt int_boundary q qbar

(``du`` the step's displacement, ``qbar`` a prescribed inflow [m/s]). Newton on
``(du, p)`` uses the symmetric matrix ``[[K, -Q], [-Q^T, -(S + dt H)]]``, ``K`` from
the micro models' tangents: one iteration with a linear micro model, and with a DEM
RVE the same iterations as a dry step. Boundaries are impermeable unless drained
(a prescribed pore pressure) or given a flux.

Under finite kinematics (updated Lagrangian, :mod:`hmm.macro`) every integral is on
the configuration of the trial displacement: the internal force is ``int (sigma' -
alpha p I) : grad_x v dv``, the fluid's volume term the change of the mixture's
volume over the step, ``int q alpha (J - J_n) dV`` (exact for any size of step), the
storage and the flow per unit current volume with ``grad_x``; the Newton matrix adds
the geometric stiffness of the total stress and the load stiffness of follower loads
to ``K``, and ``Q`` of the trial configuration is both off-diagonal blocks (the
derivative of the volume term is ``Q^T``). The change of ``S`` and ``H`` with the
configuration is left out of the matrix (their terms are small beside ``Q``'s):
Newton converges on the same residual.

:class:`~hmm.porous_field.PorousMacro` assembles the fluid's matrices;
:class:`BiotSolver` runs the time steps on :class:`TimeSchedule`, cutting a step that
does not converge exactly as the dry :class:`~hmm.coupling.Solver` does.
"""

import logging
import math
from dataclasses import dataclass

import numpy as np
from scipy import sparse

from .coupling import Solver, SolverError, _NotConverged, free_part, linear_solve, tie_map
from .farm import MicroFailure
from .porous_field import PAIRS, PERMEABILITY_LAWS, Fluid, PorousMacro

__all__ = ["COUPLINGS", "PAIRS", "PERMEABILITY_LAWS", "PRESSURE_BOUND", "BiotSolver",
           "Fluid", "PorousMacro", "TimeSchedule"]

log = logging.getLogger(__name__)

#: a pore pressure beyond this multiple of the problem's pressure scale
#: (:attr:`BiotSolver.pressure_bound`) is a diverging solution: the step is cut
PRESSURE_BOUND = 1e3

#: how the two fields are solved in each iteration (:class:`BiotSolver`)
COUPLINGS = ("monolithic", "fixed_stress")


@dataclass(frozen=True)
class TimeSchedule:
    """Time steps [s] and the load factor through them.

    ``steps`` steps reach ``end``: equal ones, or (``first`` given) growing
    geometrically from ``first``, as consolidation wants (fast at first, slow
    later). The load factor rises linearly from 0 to 1 over ``ramp`` seconds, or
    (``ramp`` = 0) is 1 from the first step on: a load applied at once, which the
    mixture first carries undrained.
    """

    end: float
    steps: int
    first: float = None
    ramp: float = 0.0

    def __post_init__(self):
        if not (self.end > 0.0 and math.isfinite(self.end)):
            raise ValueError(f"end must be positive, got {self.end}")
        if int(self.steps) < 1:
            raise ValueError("steps must be >= 1")
        if self.first is not None and not 0.0 < self.first <= self.end / self.steps:
            raise ValueError(f"first must be in (0, end / steps] = (0, "
                             f"{self.end / self.steps:.6g}], got {self.first}")
        if not self.ramp >= 0.0:
            raise ValueError(f"ramp must be >= 0, got {self.ramp}")

    def times(self):
        """The end of every step (steps,) [s]."""
        n = int(self.steps)
        if self.first is None or self.first * n >= self.end * (1.0 - 1e-12):
            return self.end * np.arange(1, n + 1) / n
        # first (r^n - 1) / (r - 1) = end: the ratio r > 1 by bisection
        lo, hi = 1.0, 2.0
        while self.first * (hi ** n - 1.0) / (hi - 1.0) < self.end:
            hi *= 2.0
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if self.first * (mid ** n - 1.0) / (mid - 1.0) < self.end:
                lo = mid
            else:
                hi = mid
        t = self.first * np.cumsum(hi ** np.arange(n))
        t[-1] = self.end
        return t

    def load_factor(self, t):
        """The load factor at time ``t`` [s]."""
        if self.ramp == 0.0:
            return 1.0 if t > 0.0 else 0.0
        return min(t / self.ramp, 1.0)


class BiotSolver(Solver):
    """Monolithic u-p Newton over a farm of micro models (effective stresses), in time.

    As :class:`~hmm.coupling.Solver`, with the clock ``t`` in seconds: prescribed
    displacements and external forces follow ``schedule.load_factor(t)``.
    :attr:`p` is the committed pore pressure (``porous.n_p``,) [Pa].
    """

    def __init__(self, porous, farm, supports, schedule, f_const=None, f_ramp=None,
                 settings=None, coupling="monolithic", loads=()):
        if supports.tie_values:
            raise ValueError("a saturated problem takes no periodic boundaries")
        super().__init__(porous.macro, farm, supports, f_const, f_ramp, settings, loads)
        if coupling not in COUPLINGS:
            raise ValueError(f"coupling must be \"monolithic\" or \"fixed_stress\", got "
                             f"{coupling!r}")
        #: "monolithic" (Newton on both fields) or "fixed_stress" (the flow, then the
        #: mechanics, in every iteration)
        self.coupling = coupling
        self.porous = porous
        self.schedule = schedule
        self.p = np.full(porous.n_p, float(porous.fluid.initial_pressure))
        n_u = self.macro.n_dofs
        self._fixed = np.concatenate([supports.dofs, n_u + porous.p_dofs])
        self._free_p = np.setdiff1d(np.arange(porous.n_p), porous.p_dofs)
        self._tie_up = tie_map(n_u + porous.n_p, supports.ties, self._fixed) \
            if supports.ties else None
        #: [Pa] a trial pore pressure beyond it cuts the step: PRESSURE_BOUND x the
        #: largest of the initial and drained pressures, the micro models' initial
        #: stresses, the largest external nodal force over h^(d-1) and the largest
        #: prescribed displacement over h times the stiffest tangent (h the shortest
        #: element edge): far above any pressure the loads can make
        h = porous.shortest_edge()
        forces = max(np.abs(self.f_const).max(initial=0.0),
                     np.abs(self.f_ramp).max(initial=0.0))
        moved = np.abs(supports.values).max(initial=0.0) \
            if supports.path is None else 0.0
        scale = max(abs(porous.fluid.initial_pressure),
                    np.abs(porous.p_values).max(initial=0.0),
                    np.abs(self.sigma).max(initial=0.0),
                    forces / h ** (self.macro.dim - 1),
                    moved / h * np.abs(self.tangent).max(initial=0.0), 1.0)
        self.pressure_bound = PRESSURE_BOUND * scale

    def advance(self, dt, on_iteration=None):
        """Take the clock from ``t`` to ``t + dt`` [s], cutting as needed; with a
        drained boundary, a first step below :meth:`PorousMacro.oscillation_bound` is
        announced (a warning)."""
        if self.t == 0.0 and self.porous.p_dofs.size:
            bound = self.porous.oscillation_bound(self.tangent)
            if dt < bound:
                log.warning("the first time step, %.3g s, is below Vermeer and "
                            "Verruijt's bound h^2 / (6 c_v) = %.3g s: pore pressures "
                            "may oscillate next to drained boundaries", dt, bound)
        return super().advance(dt, on_iteration)

    def f_ext(self, t, u=None):
        """External nodal forces [N] at time ``t`` [s] (on the configuration of ``u``
        for configuration-dependent loads)."""
        lam = self.schedule.load_factor(t)
        f = self.f_const + lam * self.f_ramp
        for load in self.loads:
            f = f + load.force(self.macro, self.u if u is None else u, lam)
        return f

    def _total(self, sig, p):
        """``sigma' - alpha p I`` at the Gauss points for the pressures ``p``."""
        pg = self.porous.gauss_pressure(p)
        return sig - self.porous.fluid.biot * pg[:, None, None] * np.eye(self.macro.dim)

    def total_stress(self):
        """The committed total stress ``sigma' - alpha p I`` at the Gauss points
        (n_gp, d, d) [Pa]."""
        return self._total(self.sigma, self.p)

    def _unbalanced(self):
        """As :meth:`Solver._unbalanced`, from the total stress: the reactions."""
        return self.macro.internal_force(self.sigma, self.u) \
            - self.porous.coupling_matrix(self.u) @ self.p - self.f_ext(self.t)

    def _fields(self, u1):
        """The fluid's matrices on the configuration of ``u1``: ``(Q, S, H)``."""
        por = self.porous
        return por.coupling_matrix(u1), por.storage_matrix(u1), por.flow_matrix(u1)

    def _mechanics(self, tangent, sig, p, u1, t1):
        """The stiffness of the displacements on the configuration of ``u1``: the
        micro models' (small), or with the geometric stiffness of the total stress
        and the load stiffness of configuration-dependent loads (finite)."""
        if not self.macro.finite:
            return self.macro.stiffness(tangent)
        return self.stiffness(tangent, self._total(sig, p), u1,
                              self.schedule.load_factor(t1))

    def _residual(self, sig, du, p, dt, t1, fields):
        """``(R_u, R_p)`` and the reference norms of their terms (``fields``: the
        fluid's matrices ``(Q, S, H)`` of the trial configuration)."""
        por = self.porous
        q, s, flow = fields
        u1 = self.u + du
        f_int = self.macro.internal_force(sig, u1)
        f_ext = self.f_ext(t1, u1)
        r_u = f_int - q @ p - f_ext
        mass = (por.volume_change(self.u, du), s @ (p - self.p), dt * (flow @ p),
                dt * por.f_q)
        r_p = -(mass[0] + mass[1] + mass[2] - mass[3])
        ref_u = max(float(np.linalg.norm(f_int)), float(np.linalg.norm(f_ext)),
                    float(np.linalg.norm(q @ p)), 1e-300)
        # the mass balance's scale: its terms, and the gross volume change the step
        # makes, |Q|^T |du|: in an undrained sample of incompressible constituents
        # every term vanishes at the solution (the volume change is the constraint)
        gross = abs(q).T @ np.abs(du)
        ref_p = max(max(float(np.linalg.norm(m)) for m in mass),
                    float(np.linalg.norm(gross)), 1e-300)
        return r_u, r_p, ref_u, ref_p

    @staticmethod
    def _matrix(k, dt, fields):
        """The whole Newton matrix from the stiffness ``k`` and the fluid's
        matrices ``(Q, S, H)``."""
        q, s, flow = fields
        return sparse.bmat([[k, -q], [-q.T, -(s + dt * flow)]], format="csr")

    def _correction(self, k, r, tangent, dt, fields):
        """The correction of ``(du, p)`` for the residual ``r`` (``k``: the stiffness
        of ``tangent``): Newton on the whole matrix (monolithic), or the fixed-stress
        split: the flow first, its volume change estimated from the pressure change
        at a fixed mean total stress (``alpha^2 / K_dr dp``), then the mechanics at
        the new pressure."""
        if self.coupling == "monolithic":
            return linear_solve(self._matrix(k, dt, fields), -r, self._fixed,
                                tie=self._tie_up)
        por, n_u = self.porous, self.macro.n_dofs
        q, s, flow = fields
        r_u, r_p = r[:n_u], r[n_u:]
        a_p = s + por.fixed_stress_mass(tangent) + dt * flow
        dp = linear_solve(a_p, r_p, por.p_dofs)
        du = linear_solve(k, -(r_u - q @ dp), self.supports.dofs, tie=self._tie)
        return np.concatenate([du, dp])

    def _check_pressure(self, p):
        """Cut the step if a trial pore pressure is not finite or beyond
        :attr:`pressure_bound`."""
        worst = float(np.abs(p).max(initial=0.0))
        if not math.isfinite(worst):
            raise _NotConverged("the pore pressure is not finite")
        if worst > self.pressure_bound:
            raise _NotConverged(
                f"pore pressure {worst:.4g} Pa is beyond {self.pressure_bound:.4g} Pa "
                f"({PRESSURE_BOUND:g} x the problem's pressure scale): the coupled "
                f"solution diverges")

    def _attempt(self, h, nominal, on_iteration):
        macro, farm, st, por = self.macro, self.farm, self.settings, self.porous
        sup = self.supports
        n_u = macro.n_dofs
        t1 = self.t + h
        lam0 = self.schedule.load_factor(self.t)
        z = np.zeros(n_u + por.n_p)
        z[sup.dofs] = sup.increment(lam0, self.schedule.load_factor(t1) - lam0)
        z[n_u:] = self.p
        z[n_u + por.p_dofs] = por.p_values
        # predictor from the committed tangents: the residual at z, linearised about
        # the committed state z0, and one correction
        fields = self._fields(self.u)
        r_u, r_p, _, _ = self._residual(self.sigma, np.zeros(n_u), self.p, h, t1, fields)
        k = self._mechanics(self.tangent, self.sigma, self.p, self.u, t1)
        z0 = np.concatenate([np.zeros(n_u), self.p])
        r = np.concatenate([r_u, r_p]) + self._matrix(k, h, fields) @ (z - z0)
        z = z + self._correction(k, r, self.tangent, h, fields)
        growth, last = 0, math.inf
        prev, omega = None, 1.0
        for it in range(1, st.max_iterations + 1):
            du, p = z[:n_u], z[n_u:]
            self._check_pressure(p)
            inverted = self._inverted(du)
            if inverted is not None:
                raise _NotConverged(inverted)
            grad = macro.increment_gradient(self.u, du)
            try:
                sig, c = farm.trial(grad)
            except MicroFailure as err:
                if not err.recoverable:
                    farm.rollback()
                    raise SolverError(f"time step at t = {self.t:.6g} s stopped: "
                                      f"{err}") from err
                raise _NotConverged(str(err)) from err
            fields = self._fields(self.u + du)
            r_u, r_p, ref_u, ref_p = self._residual(sig, du, p, h, t1, fields)
            ru = float(np.linalg.norm(free_part(r_u, self.free, self._tie)))
            rp = float(np.linalg.norm(r_p[self._free_p]))
            rel = max(ru / ref_u, rp / ref_p)
            if not math.isfinite(rel):
                raise _NotConverged("non-finite residual")
            k = self._mechanics(c, sig, p, self.u + du, t1)
            dz = self._correction(k, np.concatenate([r_u, r_p]), c, h, fields)
            dn = float(np.linalg.norm(dz[:n_u]))
            pn = float(np.linalg.norm(dz[n_u:]))
            if st.check_residual:
                un = float(np.linalg.norm(self.u + du))
            else:
                un = float(np.linalg.norm(du)) * (nominal / h)
            un = max(un, self._u_floor)
            p_scale = max(float(np.linalg.norm(p)), float(np.linalg.norm(p - self.p)),
                          1e-300)
            drel = max(dn / un, pn / p_scale if pn > 0.0 else 0.0)
            if on_iteration is not None:
                on_iteration(it, rel, drel)
            small_r = rel <= st.tol_residual
            small_d = drel <= st.tol_displacement
            if (small_r and small_d) if st.check_residual else (small_d or small_r):
                self.u += du
                self.p = p.copy()
                self.t = t1
                self.sigma, self.tangent = sig, c
                self.increment = grad
                farm.commit()
                return it
            watched = rel if st.check_residual else drel
            growth = growth + 1 if watched > last else 0
            if growth >= 3:
                raise _NotConverged(f"residual grew three times (|r|/|f| = {rel:.3g})")
            last = watched
            if st.aitken and prev is not None:
                diff = dz - prev
                den = float(diff @ diff)
                if den > 0.0:
                    omega = min(max(-omega * float(prev @ diff) / den, 0.5), 8.0)
            prev = dz
            z = z + omega * dz
        raise _NotConverged(f"no convergence in {st.max_iterations} iterations "
                            f"(|r|/|f| = {rel:.3g}, |dz|/|z| = {drel:.3g})")
