"""Load stepping and Newton-Raphson over a farm of micro models, with step cutting.

One load step from the committed state (displacement ``u``, load factor ``t``)
to ``t + dt``, in this order (``macro.kinematics`` decides what "strain", "internal
force" and "stiffness" mean: :mod:`hmm.macro`):

1. **Predictor.** The prescribed displacements move by their share of the step;
   the free ones come from the committed tangents (``K_c du = f_ext(t + dt) -
   f_int(sigma_c)``), so the first trial already sees a sensible strain field; or,
   with ``predictor = "extrapolated"``, from the last converged step's increment
   scaled to this step (under a steady load nearly the answer, where the contact
   tangent of DEM RVEs, stiffer than they are, undershoots it).
2. **Iterations.** ``farm.trial(G(du))`` gives stresses and tangents from the
   committed micro states (``G``: the strain increment, or under finite kinematics
   the displacement-gradient increment on the converged configuration, after a
   check that no element inverts); the residual ``r = f_int - f_ext`` on the free
   degrees of freedom (both on the trial configuration under finite kinematics) and
   the correction ``K dd = -r`` follow; ``du += dd``.
3. **Convergence** needs both ``|r_free| <= tol_residual * |f_int|`` (or ``|f_ext|``,
   or, for a state with no stress such as a prescribed rigid rotation, a floor of
   :data:`ROUNDOFF` times the largest tangent stiffness times ``|u|``) and
   ``|dd| <= tol_displacement * |u + du|`` (the total displacement: a micro model
   that relaxes to a tolerance answers with noise that a cut step must not have to
   beat); with ``check_residual`` false the correction alone, relative to the
   step's displacement (YADE FEMxDEM's criterion, for micro models whose noise keeps
   the residual above any useful tolerance; a cut step's displacement is scaled up
   to the nominal step's, since the noise in a correction does not shrink with the
   step), or a residual already within ``tol_residual``; then ``farm.commit()`` and
   the step is done. A step that has not converged in ``max_iterations``, whose
   residual (or, without the residual check, correction) grows three times in a
   row, in which an element would invert (``det F <= 0``, or below
   :data:`MIN_JACOBIAN`, at a Gauss point), or in
   which a micro model's physics fails (an RVE that cannot relax), is **cut**: ``farm.rollback()`` and the step is retried at half its size, down to
   ``min_step`` times the nominal step, after which :class:`SolverError` stops the
   run; the solver keeps the last converged state (:func:`hmm.run.run_problem`
   writes its frame and marks ``fields.h5`` as stopped). Any other exception of a
   micro model (a bug, bad input) stops the run at once, naming the Gauss point.
"""

import logging
import math
from dataclasses import dataclass, fields

import numpy as np
from scipy import sparse
from skfem import condense, solve

from .farm import MicroFailure
from .problem_schema import PREDICTORS

log = logging.getLogger(__name__)


#: a Gauss point whose volume ratio det F falls to this is inverted (or flattened to
#: round-off): the step is cut
MIN_JACOBIAN = 1e-8
#: the residual's reference never falls below this times the largest diagonal entry of
#: the tangent times |u| [N]: what round-off leaves of the internal force where the
#: solution carries no stress (a prescribed rigid rotation), so that it converges
ROUNDOFF = 1e-8


class SolverError(RuntimeError):
    """The load step could not be completed even at the smallest step size."""


@dataclass
class SolverSettings:
    """Newton and step-cutting settings (see the module docstring)."""

    tol_residual: float = 1e-3
    tol_displacement: float = 1e-3
    max_iterations: int = 10
    min_step: float = 1.0 / 64.0
    check_residual: bool = True
    #: Aitken relaxation of successive corrections: steadies Newton with a DEM
    #: micro model's approximate tangent; off, an exact tangent converges
    #: quadratically
    aitken: bool = True
    #: the first guess of a step: "tangent" (a linear solve with the committed
    #: tangents) or "extrapolated" (the last converged step's displacements, scaled
    #: to this step; the tangent's for the first step)
    predictor: str = "tangent"

    @classmethod
    def from_section(cls, section):
        """The settings of a validated ``[solver]`` section (a dict)."""
        return cls(**{f.name: section[f.name] for f in fields(cls) if f.name in section})

    def __post_init__(self):
        for name in ("tol_residual", "tol_displacement", "min_step"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be positive and finite, got {v}")
        if int(self.max_iterations) < 1:
            raise ValueError("max_iterations must be >= 1")
        if self.predictor not in PREDICTORS:
            raise ValueError(f"predictor must be one of {', '.join(PREDICTORS)}, got "
                             f"{self.predictor!r}")


@dataclass
class Supports:
    """Prescribed displacements: ``dofs`` and their values at the end of the schedule
    (load factor 1), ramped linearly with the load factor, or given along the
    schedule by ``path(t) -> values`` (e.g. a rigid rotation).

    A support's reaction is the sum of the unbalanced nodal force over the degrees
    of freedom it holds, and only those: ``held`` names them (``{name: {component:
    dofs}}``; :meth:`from_conditions` builds it). Without ``held``, each of the
    ``boundaries`` holds the components in which all its degrees of freedom are
    prescribed, less the corners a boundary listed before it holds.
    """

    dofs: np.ndarray
    values: np.ndarray
    #: boundaries whose reaction forces make the load-displacement curve
    boundaries: tuple = ()
    #: optional ``path(t)``: the prescribed values at load factor ``t``
    path: object = None
    #: groups of degrees of freedom that move as one (each a rigid, frictionless
    #: platen in one component, pushed by the loads on it): no reaction, one unknown
    ties: tuple = ()
    #: optional ``{name: {component: dofs}}``: the degrees of freedom whose
    #: reaction each support reports (each prescribed dof in one support at most)
    held: dict = None
    #: per group of ``ties`` (or empty: none), each member's prescribed offset [m]
    #: from the group's first at load factor 1, ramped like ``values``: the jumps
    #: ``G L`` of periodic boundaries (:mod:`hmm.periodic`); zero for a platen
    tie_values: tuple = ()

    @classmethod
    def from_conditions(cls, conditions, boundaries=None, ties=()):
        """Supports from ``(name, component, dofs, value)`` conditions, in order.

        ``value`` [m] is a number or one per dof (at load factor 1). A dof named by
        two conditions (the corner of two supported edges) takes the value of the
        first and belongs to its support alone, so that the reactions of all the
        supports sum to the whole force on the prescribed dofs; ``name`` None: no
        reaction reported. ``boundaries`` (default: every name) make the
        load-displacement curve.
        """
        dofs, values, owner = [], [], []
        for i, (_, _, k, v) in enumerate(conditions):
            k = np.asarray(k, dtype=np.int64).ravel()
            dofs.append(k)
            values.append(np.broadcast_to(np.asarray(v, dtype=np.float64), k.shape))
            owner.append(np.full(k.size, i))
        if not dofs:
            return cls(np.zeros(0, np.int64), np.zeros(0), (), ties=tuple(ties), held={})
        dofs, first = np.unique(np.concatenate(dofs), return_index=True)
        owner = np.concatenate(owner)[first]
        held = {}
        for i, (name, comp, _, _) in enumerate(conditions):
            if name is None:
                continue
            mine = held.setdefault(name, {})
            mine[comp] = np.union1d(mine.get(comp, np.zeros(0, np.int64)),
                                    dofs[owner == i])
        if boundaries is None:
            boundaries = tuple(held)
        return cls(dofs, np.concatenate(values)[first], tuple(boundaries),
                   ties=tuple(ties), held=held)

    def owned(self, macro):
        """``{name: {component: dofs}}``: the degrees of freedom whose reaction each
        support reports (:attr:`held`, or, per boundary of :attr:`boundaries`, the
        components in which it is wholly prescribed, less the dofs of a boundary
        before it)."""
        if self.held is not None:
            return self.held
        taken = np.zeros(0, np.int64)
        out = {}
        for name in self.boundaries:
            out[name] = {}
            for c in range(macro.dim):
                k = macro.dofs(name, c)
                if not np.all(np.isin(k, self.dofs)):  # only some (corners): not held
                    continue
                out[name][c] = np.setdiff1d(k, taken)
                taken = np.union1d(taken, k)
        return out

    def increment(self, t, h):
        """The change of the prescribed values from load factor ``t`` to ``t + h``."""
        if self.path is None:
            return h * self.values
        return (np.asarray(self.path(t + h), dtype=np.float64)
                - np.asarray(self.path(t), dtype=np.float64))

    def prescribe(self, du, t, h):
        """Write into ``du`` (n_dofs,) the change from load factor ``t`` to ``t + h``
        of the prescribed values and of the tied offsets (periodic jumps): the
        prescribed part of a step's first guess."""
        du[self.dofs] = self.increment(t, h)
        for group, offset in zip(self.ties if self.tie_values else (), self.tie_values,
                                 strict=True):
            du[group[1:]] = h * np.asarray(offset)[1:]
        return du


def tie_map(n, groups, fixed):
    """``(T, keep)`` for degrees of freedom ``groups`` that move as one: ``u = T
    u_r``, ``T`` (n, m) sparse, ``keep`` (m,) the full index of each reduced one
    (the first of a group stands for it). Only the first of a group may be one of the
    ``fixed`` dofs (then the whole group follows it)."""
    groups = [np.asarray(list(dict.fromkeys(np.asarray(g, dtype=np.int64).tolist())),
                         dtype=np.int64) for g in groups]
    slaves = np.concatenate([g[1:] for g in groups]) if groups else np.zeros(0, int)
    if np.intersect1d(slaves, fixed).size:
        raise ValueError("a tied (platen) boundary also has a prescribed displacement "
                         "in the same component")
    if np.unique(slaves).size != slaves.size or np.intersect1d(
            slaves, [g[0] for g in groups]).size:
        raise ValueError("two platens share a degree of freedom")
    keep = np.setdiff1d(np.arange(n), slaves)
    pos = np.full(n, -1)
    pos[keep] = np.arange(keep.size)
    rows, cols = keep, np.arange(keep.size)
    for g in groups:
        rows = np.concatenate([rows, g[1:]])
        cols = np.concatenate([cols, np.full(g.size - 1, pos[g[0]])])
    t = sparse.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n, keep.size))
    return t, keep


def linear_solve(k, rhs, fixed, x=None, tie=None):
    """Solve ``k du = rhs`` with ``du`` = ``x`` on the ``fixed`` dofs (zero without
    ``x``), through the reduced system ``T^T k T`` of a :func:`tie_map`: ``du = T
    du_r + s``, ``s`` the offsets of the tied dofs from their group's first, read
    from ``x`` (the jumps of periodic boundaries; zero without ``x``)."""
    if tie is None:
        return solve(*condense(k, rhs, x=x, D=fixed))
    t, keep = tie
    pos = np.full(k.shape[0], -1)
    pos[keep] = np.arange(keep.size)
    kr = (t.T @ k @ t).tocsr()
    if x is None:
        return t @ solve(*condense(kr, t.T @ rhs, D=pos[fixed]))
    s = np.array(x, dtype=np.float64)
    s[keep] = 0.0
    return t @ solve(*condense(kr, t.T @ (rhs - k @ s), x=x[keep], D=pos[fixed])) + s


def free_part(r, free, tie=None):
    """The residual ``r`` on the ``free`` dofs, summed over each tie's group (the
    force on a platen)."""
    if tie is None:
        return r[free]
    t, keep = tie
    on = np.zeros(r.size, bool)
    on[free] = True
    return (t.T @ r)[on[keep]]


class Solver:
    """Quasi-static multiscale solver: a :class:`~hmm.macro.Macro` and a farm.

    Parameters
    ----------
    macro : Macro
    farm : SerialFarm or a farm with the same calls
    supports : Supports
    f_const : (n_dofs,) array
        External forces present from the start [N] (e.g. a confining pressure that
        the micro models' initial stress already balances).
    f_ramp : (n_dofs,) array
        External forces at load factor 1 on top of ``f_const``, ramped linearly.
    settings : SolverSettings
    loads : sequence, optional
        Loads that depend on the configuration (finite kinematics: follower
        pressures, loads per unit current area or volume, :mod:`hmm.loads`).
    """

    def __init__(self, macro, farm, supports, f_const=None, f_ramp=None, settings=None,
                 loads=()):
        self.macro = macro
        self.farm = farm
        self.supports = supports
        n = macro.n_dofs
        self.f_const = np.zeros(n) if f_const is None else np.asarray(f_const, float)
        self.f_ramp = np.zeros(n) if f_ramp is None else np.asarray(f_ramp, float)
        self.loads = tuple(loads)
        if self.loads and not macro.finite:
            raise ValueError("configuration-dependent loads need finite kinematics")
        self.settings = settings or SolverSettings()
        if farm.n != macro.n_gp:
            raise ValueError(f"the farm has {farm.n} micro models for {macro.n_gp} "
                             f"Gauss points")
        models = getattr(farm, "models", ())  # this rank's (an MPI farm: a dict)
        models = models.values() if isinstance(models, dict) else models
        small_only = sorted({type(m).__name__ for m in models
                             if not getattr(m, "objective", False)})
        if macro.finite and small_only:
            raise ValueError(f"finite kinematics needs objective micro models; "
                             f"{', '.join(small_only)} is a small-strain law")
        self.u = np.zeros(n)
        self.t = 0.0
        self.sigma = farm.stress()
        # committed tangents: the micro models' response to a zero increment
        _, self.tangent = farm.trial(np.zeros((farm.n, macro.dim, macro.dim)))
        farm.rollback()
        self.free = np.setdiff1d(np.arange(n), supports.dofs)
        self._tie = tie_map(n, supports.ties, supports.dofs) if supports.ties else None
        self._held = supports.owned(macro)
        # displacements below round-off of the mesh size count as zero
        self._u_floor = 1e-12 * float(np.ptp(macro.mesh.p, axis=1).max())
        self.iterations = []  # Newton iterations of each converged step
        self.cuts = 0
        #: what the micro models got in the last converged step (n_gp, d, d): the
        #: strain increment, or the displacement-gradient increment (finite)
        self.increment = np.zeros((farm.n, macro.dim, macro.dim))
        #: the last converged step: its size in load factor and its displacement
        #: increment (n_dofs,), the extrapolated predictor's source; None before one
        self.last_step = None

    def f_ext(self, t, u=None):
        """External nodal forces [N] at load factor ``t`` (on the configuration of
        the displacement ``u`` for configuration-dependent loads)."""
        f = self.f_const + t * self.f_ramp
        for load in self.loads:
            f = f + load.force(self.macro, self.u if u is None else u, t)
        return f

    def stiffness(self, tangent, sigma, u, t):
        """The Newton matrix at the configuration of ``u``: internal minus the load
        stiffness of configuration-dependent loads."""
        k = self.macro.stiffness(tangent, u, sigma)
        for load in self.loads:
            k = k - load.stiffness(self.macro, u, t)
        return k

    def reactions(self):
        """Force the supports exert on the body, per support, at the committed state
        (``{name: (d,)}``) [N in 3D, N/m in 2D (plane strain, per unit
        thickness)]: the internal force that external loads do not balance (on the
        current configuration under finite kinematics), summed over the degrees of
        freedom the support holds (:meth:`Supports.owned`); a component it does not
        hold is zero. A held degree of freedom that stands for a tied group (a point
        support at a corner of periodic boundaries) carries the group's force."""
        r = self._unbalanced()
        if self._tie is not None:  # each group's force on its first member
            t, keep = self._tie
            full = np.zeros_like(r)
            full[keep] = t.T @ r
            r = full
        out = {}
        for name, held in self._held.items():
            f = np.zeros(self.macro.dim)
            for c, k in held.items():
                f[c] = r[k].sum()
            out[name] = f
        return out

    def held_components(self):
        """``{name: (components,)}``: the displacement components each support
        holds (those of :meth:`reactions` that are not zero by definition)."""
        return {name: tuple(sorted(held)) for name, held in self._held.items()}

    def _unbalanced(self):
        """Internal minus external nodal force at the committed state [N]."""
        return self.macro.internal_force(self.sigma, self.u) - self.f_ext(self.t)

    # ------------------------------------------------------------------ one step
    def advance(self, dt, on_iteration=None):
        """Take the load factor from ``t`` to ``t + dt``, cutting as needed.

        Returns the number of Newton iterations of the last (successful) attempt.
        """
        target = self.t + dt
        nominal = dt
        while self.t < target - 1e-12 * nominal:
            h = min(dt, target - self.t)
            try:
                its = self._attempt(h, nominal, on_iteration)
            except _NotConverged as why:
                self.farm.rollback()
                self.cuts += 1
                dt = 0.5 * h
                log.info("step from t = %.6g with dt = %.3g cut: %s", self.t, h, why)
                if dt < self.settings.min_step * nominal:
                    raise SolverError(
                        f"load step at t = {self.t:.6g} did not converge even at "
                        f"the minimum step {self.settings.min_step:g} x {nominal:.4g} "
                        f"(last try {h:.4g}: {why}); the solver holds the last "
                        f"converged state (t = {self.t:.6g})") from None
                continue
            self.iterations.append(its)
            dt = min(2.0 * dt, nominal)  # grow back after a cut
        return its

    def _inverted(self, du):
        """A message naming the first element that ``u + du`` would invert, or None
        (finite kinematics only: a small-strain mesh never moves)."""
        macro = self.macro
        if not macro.finite:
            return None
        jac = np.linalg.det(macro.deformation(self.u + du))
        bad = np.flatnonzero(~(jac > MIN_JACOBIAN))
        if bad.size == 0:
            return None
        g = int(bad[0])
        return (f"element {g // macro.n_qp} inverts (det F = {jac[g]:.3g} at its Gauss "
                f"point {g}; {bad.size} points in all)")

    def _extrapolated(self, prescribed, h):
        """The last converged step's displacement increment scaled to a step of
        ``h``, with the prescribed values and tied offsets of ``prescribed`` (the
        step's :meth:`Supports.prescribe`): under a steady loading the best first
        guess, which the committed tangents (the contact tangent of DEM RVEs is an
        upper bound of their stiffness) undershoot."""
        h0, du0 = self.last_step
        du = du0 * (h / h0)
        du[self.supports.dofs] = prescribed[self.supports.dofs]
        if self._tie is not None:  # each group as its first, plus its offsets
            t, keep = self._tie
            offsets = prescribed.copy()
            offsets[keep] = 0.0
            du = t @ du[keep] + offsets
        return du

    def _attempt(self, h, nominal, on_iteration):
        macro, farm, st = self.macro, self.farm, self.settings
        sup = self.supports
        t1 = self.t + h
        du = sup.prescribe(np.zeros(macro.n_dofs), self.t, h)
        k_c = self.stiffness(self.tangent, self.sigma, self.u, t1)
        if st.predictor == "extrapolated" and self.last_step is not None:
            du = self._extrapolated(du, h)
        else:  # predictor from the committed tangents, on the committed configuration
            r_c = macro.internal_force(self.sigma, self.u) - self.f_ext(t1)
            du = linear_solve(k_c, -r_c, sup.dofs, du, self._tie)
        k_max = float(np.abs(k_c.diagonal()).max()) if k_c.shape[0] else 0.0
        growth = 0
        last = math.inf
        prev, omega = None, 1.0
        for it in range(1, st.max_iterations + 1):
            inverted = self._inverted(du)
            if inverted is not None:
                raise _NotConverged(inverted)
            u1 = self.u + du
            grad = macro.increment_gradient(self.u, du)
            try:
                sig, c = farm.trial(grad)
            except MicroFailure as err:
                if not err.recoverable:  # a bug or bad input: cutting cannot help
                    farm.rollback()
                    raise SolverError(f"load step at t = {self.t:.6g} stopped: {err}") \
                        from err
                raise _NotConverged(str(err)) from err
            f_int = macro.internal_force(sig, u1)
            f_ext = self.f_ext(t1, u1)
            r = f_int - f_ext
            rn = float(np.linalg.norm(free_part(r, self.free, self._tie)))
            # a stress-free solution (a prescribed rigid rotation) has no force to
            # compare with: the floor is what round-off leaves of k |u|
            ref = max(float(np.linalg.norm(f_int)), float(np.linalg.norm(f_ext)),
                      ROUNDOFF * k_max * float(np.linalg.norm(u1)), 1e-300)
            if not math.isfinite(rn):
                raise _NotConverged("non-finite residual")
            dd = linear_solve(self.stiffness(c, sig, u1, t1), -r, sup.dofs,
                              tie=self._tie)
            dn = float(np.linalg.norm(dd))
            # the correction against the total displacement; without the residual
            # check against the step's own, FEMxDEM's (|du| of a late step is far
            # below the total, which would let any correction pass), at the size of
            # the nominal step: the micro models' noise in the correction does not
            # shrink with a cut step, so a tolerance that did would make every cut
            # harder to pass than the step it replaces
            if st.check_residual:
                un = float(np.linalg.norm(self.u + du))
            else:
                un = float(np.linalg.norm(du)) * (nominal / h)
            un = max(un, self._u_floor)
            if on_iteration is not None:
                on_iteration(it, rn / ref, dn / un)
            small_r = rn <= st.tol_residual * ref
            small_d = dn <= st.tol_displacement * un
            # without the residual check, a residual already within its tolerance
            # ends the step too: the correction of a small cut step is the micro
            # models' noise over a tiny displacement, which no iteration removes
            if (small_r and small_d) if st.check_residual else (small_d or small_r):
                self.u += du
                self.last_step = (h, du.copy())
                self.t = t1
                self.sigma, self.tangent = sig, c
                self.increment = grad
                farm.commit()
                return it
            watched = rn if st.check_residual else dn
            growth = growth + 1 if watched > last else 0
            if growth >= 3:
                what = "residual" if st.check_residual else "correction"
                raise _NotConverged(f"{what} grew three times (|r|/|f| = {rn / ref:.3g}, "
                                    f"|du|/|u| = {dn / un:.3g})")
            last = watched
            if st.aitken and prev is not None:  # Aitken relaxation of the corrections
                diff = dd - prev
                den = float(diff @ diff)
                if den > 0.0:
                    omega = min(max(-omega * float(prev @ diff) / den, 0.5), 8.0)
            prev = dd
            du += omega * dd
        raise _NotConverged(f"no convergence in {st.max_iterations} iterations "
                            f"(|r|/|f| = {rn / ref:.3g}, |du|/|u| = {dn / un:.3g})")


class _NotConverged(Exception):
    pass
