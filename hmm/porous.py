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

:class:`PorousMacro` assembles the fluid's matrices once; :class:`BiotSolver` runs the
time steps on :class:`TimeSchedule`, cutting a step that does not converge exactly as
the dry :class:`~hmm.coupling.Solver` does.
"""

import logging
import math
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from skfem import (
    Basis,
    BilinearForm,
    ElementHex1,
    ElementQuad1,
    ElementTetP1,
    ElementTriP1,
    FacetBasis,
    LinearForm,
    asm,
)
from skfem.helpers import div, dot, grad, mul

from .coupling import Solver, SolverError, _NotConverged, free_part, linear_solve, tie_map
from .farm import MicroFailure

log = logging.getLogger(__name__)

#: a pore pressure beyond this multiple of the problem's pressure scale
#: (:attr:`BiotSolver.pressure_bound`) is a diverging solution: the step is cut
PRESSURE_BOUND = 1e3

#: how the permeability follows the porosity (:class:`Fluid`)
PERMEABILITY_LAWS = ("constant", "kozeny_carman")

#: how the two fields are solved in each iteration (:class:`BiotSolver`)
COUPLINGS = ("monolithic", "fixed_stress")

#: displacement element -> (pressure element name, class): quadratic displacement,
#: linear pressure on the same mesh
PAIRS = {
    "quad8": ("quad1", ElementQuad1),
    "quad2": ("quad1", ElementQuad1),
    "tri2": ("tri1", ElementTriP1),
    "hex20": ("hex1", ElementHex1),
    "hex27": ("hex1", ElementHex1),
    "tet10": ("tet1", ElementTetP1),
}


@BilinearForm
def _coupling(p, v, w):
    # alpha p div v: rows displacement tests, columns pressures
    return w.alpha * p * div(v)


@BilinearForm
def _storage(p, q, w):
    return w.storage * p * q


@BilinearForm
def _weighted_mass(p, q, w):
    return w.beta * p * q


@BilinearForm
def _flow(p, q, w):
    return dot(grad(q), mul(w.kappa, grad(p)))


@LinearForm
def _inflow(q, w):
    return w.flux * q


@dataclass(frozen=True)
class Fluid:
    """The pore fluid and the mixture's hydraulic constants (SI units).

    Parameters
    ----------
    permeability : float or (d, d) array
        Intrinsic permeability k [m^2] (isotropic, or a symmetric tensor).
    viscosity : float
        Dynamic viscosity of the fluid mu [Pa s] (water: 1e-3).
    bulk_modulus : float
        Fluid bulk modulus K_f [Pa] (water: 2.2e9; inf: incompressible).
    porosity : float
        Porosity n [-], which weighs the fluid's compressibility in the storage.
    biot : float
        Biot's coefficient alpha (1: incompressible grains).
    solid_bulk_modulus : float
        Bulk modulus of the grains K_s [Pa] (inf: incompressible, alpha = 1).
    initial_pressure : float
        Pore pressure at the start [Pa], uniform.
    permeability_law : str
        ``"constant"``, or ``"kozeny_carman"``: ``k`` scales with ``n^3 / (1 -
        n)^2`` from its value at ``porosity``, ``n = 1 - (1 - n_0) / (1 + tr eps)``
        at each Gauss point (the grains keep their volume); the storage keeps ``n_0``.
    """

    permeability: object
    viscosity: float = 1e-3
    bulk_modulus: float = 2.2e9
    porosity: float = 0.4
    biot: float = 1.0
    solid_bulk_modulus: float = math.inf
    initial_pressure: float = 0.0
    permeability_law: str = "constant"

    def __post_init__(self):
        k = np.asarray(self.permeability, dtype=np.float64)
        if k.ndim == 0:
            ok = math.isfinite(float(k)) and float(k) > 0.0
        else:
            ok = (k.ndim == 2 and k.shape[0] == k.shape[1] and np.allclose(k, k.T)
                  and np.all(np.linalg.eigvalsh(k) > 0.0))
        if not ok:
            raise ValueError("permeability must be positive: a number or a symmetric "
                             "positive definite tensor [m^2]")
        if not (self.viscosity > 0.0 and math.isfinite(self.viscosity)):
            raise ValueError(f"viscosity must be positive, got {self.viscosity}")
        if not self.bulk_modulus > 0.0 or not self.solid_bulk_modulus > 0.0:
            raise ValueError("bulk moduli must be positive (inf: incompressible)")
        if not 0.0 < self.porosity < 1.0:
            raise ValueError(f"porosity must be in (0, 1), got {self.porosity}")
        if not self.porosity <= self.biot <= 1.0:
            raise ValueError(f"biot must be in [porosity, 1], got {self.biot}")
        if self.permeability_law not in PERMEABILITY_LAWS:
            raise ValueError(f"permeability_law must be \"constant\" or "
                             f"\"kozeny_carman\", got {self.permeability_law!r}")

    @property
    def storage(self):
        """``1/M = n/K_f + (alpha - n)/K_s`` [1/Pa] (0: incompressible)."""
        return self.porosity / self.bulk_modulus \
            + (self.biot - self.porosity) / self.solid_bulk_modulus

    def mobility(self, dim):
        """``kappa = k / mu`` as a (dim, dim) tensor [m^2/(Pa s)]."""
        k = np.asarray(self.permeability, dtype=np.float64)
        if k.ndim == 0:
            k = float(k) * np.eye(dim)
        if k.shape != (dim, dim):
            raise ValueError(f"permeability tensor is {k.shape[0]}x{k.shape[1]}, the "
                             f"mesh {dim}D")
        return k / self.viscosity


class PorousMacro:
    """The pressure field beside a :class:`~hmm.macro.Macro`, and the fluid's
    matrices: ``Q`` (coupling), ``S`` (storage) and ``H`` (flow).

    Parameters
    ----------
    macro : Macro
        Small kinematics, a quadratic element of :data:`PAIRS`.
    fluid : Fluid
    drained : dict, optional
        ``{boundary: pore pressure [Pa]}`` held from the first step on.
    inflow : dict, optional
        ``{boundary: flux [m/s]}``, fluid volume entering per unit area and time.
    """

    def __init__(self, macro, fluid, drained=None, inflow=None):
        if macro.element not in PAIRS:
            raise ValueError(
                f"pore pressure needs a quadratic displacement element "
                f"({', '.join(PAIRS)}) to pair with linear pressures; "
                f"\"{macro.element}\" would pair equal orders, whose pressure "
                f"oscillates (no inf-sup stability)")
        if macro.finite:
            raise ValueError("pore pressure runs under small kinematics for now: set "
                             "[solver] kinematics = \"small\"")
        self.macro = macro
        self.fluid = fluid
        self.p_element = PAIRS[macro.element][0]
        # the same quadrature as the displacements: Gauss point data line up
        self.pbasis = Basis(macro.mesh, PAIRS[macro.element][1](), intorder=macro.order)
        self.n_p = self.pbasis.N
        d = macro.dim
        self.Q = asm(_coupling, self.pbasis, macro.basis, alpha=fluid.biot).tocsr()
        self.S = asm(_storage, self.pbasis, storage=fluid.storage).tocsr()
        self.kappa = fluid.mobility(d)
        self.H = asm(_flow, self.pbasis,
                     kappa=self.kappa[:, :, None, None]).tocsr()
        self.drained = dict(drained or {})
        self.inflow = dict(inflow or {})
        for name in (*self.drained, *self.inflow):
            if name not in macro.mesh.boundaries:
                raise KeyError(name)
        dofs = [self.pbasis.get_dofs(b).all() for b in self.drained]
        vals = [np.full(k.size, float(v)) for k, v in
                zip(dofs, self.drained.values(), strict=True)]
        if dofs:
            dofs, first = np.unique(np.concatenate(dofs), return_index=True)
            self.p_dofs, self.p_values = dofs, np.concatenate(vals)[first]
        else:
            self.p_dofs, self.p_values = np.zeros(0, np.int64), np.zeros(0)
        self.f_q = np.zeros(self.n_p)
        for b, flux in self.inflow.items():
            fb = FacetBasis(macro.mesh, self.pbasis.elem,
                            facets=macro.mesh.boundaries[b], intorder=macro.order)
            self.f_q += asm(_inflow, fb, flux=float(flux))

    def consolidation_coefficient(self, tangent):
        """``c_v = kappa / (1/M + alpha^2 / M_c)`` [m^2/s] of the micro models'
        ``tangent`` (n_gp, d, d, d, d): ``kappa`` the mean eigenvalue of the
        mobility, ``M_c`` the constrained modulus ``C_iiii``, averaged over axes
        and Gauss points."""
        d = self.macro.dim
        m_c = float(np.mean([np.mean(tangent[:, i, i, i, i]) for i in range(d)]))
        kappa = float(np.trace(self.kappa)) / d
        alpha = self.fluid.biot
        return kappa / (self.fluid.storage + alpha * alpha / max(m_c, 1e-300))

    def oscillation_bound(self, tangent):
        """Vermeer & Verruijt's lower bound of a first time step [s], ``h^2 / (6
        c_v)`` with ``h`` the shortest element edge: a shorter step after a sudden
        load or a jump of a drained pressure leaves the pressure's boundary layer
        thinner than an element, and the pressure overshoots next to it."""
        h = self.shortest_edge()
        return h * h / (6.0 * self.consolidation_coefficient(tangent))

    def shortest_edge(self):
        """The shortest element edge of the mesh [m]."""
        mesh = self.macro.mesh
        edges = mesh.facets if self.macro.dim == 2 else mesh.edges
        return float(np.min(np.linalg.norm(mesh.p[:, edges[0]] - mesh.p[:, edges[1]],
                                           axis=0)))

    def permeability_ratio(self, u):
        """``k / k_0`` at the Gauss points (n_gp,) for the displacement ``u``: 1, or
        Kozeny-Carman's ``[n^3 / (1 - n)^2] / [n_0^3 / (1 - n_0)^2]``."""
        if self.fluid.permeability_law == "constant" or u is None:
            return np.ones(self.macro.n_gp)
        n0 = self.fluid.porosity
        jac = 1.0 + np.trace(self.macro.strain(u), axis1=1, axis2=2)
        n = np.clip(1.0 - (1.0 - n0) / jac, 1e-6, 1.0 - 1e-6)
        return (n ** 3 / (1.0 - n) ** 2) / (n0 ** 3 / (1.0 - n0) ** 2)

    def flow_matrix(self, u=None):
        """``H = int grad q . kappa grad p`` (sparse) for the displacement ``u`` (the
        assembled one of the initial porosity under a constant permeability)."""
        if self.fluid.permeability_law == "constant" or u is None:
            return self.H
        ratio = self.macro.from_gp(self.permeability_ratio(u))
        return asm(_flow, self.pbasis,
                   kappa=self.kappa[:, :, None, None] * ratio).tocsr()

    def fixed_stress_mass(self, tangent):
        """``int q alpha^2 / K_dr p`` (sparse): the fixed-stress split's estimate of
        the volume change per pressure change, ``K_dr`` each Gauss point's drained
        bulk modulus ``C_iijj / d^2`` from the micro ``tangent`` (n_gp, d, d, d, d)."""
        d = self.macro.dim
        k_dr = np.einsum("giijj->g", tangent) / (d * d)
        beta = self.fluid.biot ** 2 / np.maximum(k_dr, 1e-300)
        return asm(_weighted_mass, self.pbasis, beta=self.macro.from_gp(beta)).tocsr()

    def nodal_pressure(self, p):
        """Pore pressure at the mesh vertices (n_vertices,) [Pa]."""
        return p[self.pbasis.nodal_dofs[0]]

    def gauss_pressure(self, p):
        """Pore pressure at the Gauss points (n_gp,) [Pa]."""
        return self.macro.to_gp(self.pbasis.interpolate(p))

    def darcy_flux(self, p, u=None):
        """Darcy's flux ``w = -kappa grad p`` at the Gauss points (n_gp, d) [m/s] (the
        permeability of the displacement ``u`` under Kozeny-Carman)."""
        g = self.macro.to_gp(self.pbasis.interpolate(p).grad)  # (n_gp, d)
        return -(g @ self.kappa.T) * self.permeability_ratio(u)[:, None]


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
                 settings=None, coupling="monolithic"):
        if supports.tie_values:
            raise ValueError("a saturated problem takes no periodic boundaries")
        super().__init__(porous.macro, farm, supports, f_const, f_ramp, settings)
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
        return self.f_const + self.schedule.load_factor(t) * self.f_ramp

    def total_stress(self):
        """The committed total stress ``sigma' - alpha p I`` at the Gauss points
        (n_gp, d, d) [Pa]."""
        p = self.porous.gauss_pressure(self.p)
        return self.sigma - self.porous.fluid.biot * p[:, None, None] \
            * np.eye(self.macro.dim)

    def _unbalanced(self):
        """As :meth:`Solver._unbalanced`, from the total stress: the reactions."""
        return self.macro.internal_force(self.sigma) - self.porous.Q @ self.p \
            - self.f_ext(self.t)

    def _residual(self, sig, du, p, dt, t1, flow):
        """``(R_u, R_p)`` and the reference norms of their terms (``flow``: the flow
        matrix ``H`` of the trial configuration)."""
        por = self.porous
        f_int = self.macro.internal_force(sig)
        f_ext = self.f_ext(t1)
        r_u = f_int - por.Q @ p - f_ext
        mass = (por.Q.T @ du, por.S @ (p - self.p), dt * (flow @ p), dt * por.f_q)
        r_p = -(mass[0] + mass[1] + mass[2] - mass[3])
        ref_u = max(float(np.linalg.norm(f_int)), float(np.linalg.norm(f_ext)),
                    float(np.linalg.norm(por.Q @ p)), 1e-300)
        ref_p = max(max(float(np.linalg.norm(m)) for m in mass), 1e-300)
        return r_u, r_p, ref_u, ref_p

    def _matrix(self, k, dt, flow):
        """The whole Newton matrix from the stiffness ``k`` and flow matrix."""
        por = self.porous
        return sparse.bmat([[k, -por.Q], [-por.Q.T, -(por.S + dt * flow)]],
                           format="csr")

    def _correction(self, k, r, tangent, dt, flow):
        """The correction of ``(du, p)`` for the residual ``r`` (``k``: the stiffness
        of ``tangent``): Newton on the whole matrix (monolithic), or the fixed-stress
        split: the flow first, its volume change estimated from the pressure change
        at a fixed mean total stress (``alpha^2 / K_dr dp``), then the mechanics at
        the new pressure."""
        if self.coupling == "monolithic":
            return linear_solve(self._matrix(k, dt, flow), -r, self._fixed,
                                tie=self._tie_up)
        por, n_u = self.porous, self.macro.n_dofs
        r_u, r_p = r[:n_u], r[n_u:]
        a_p = por.S + por.fixed_stress_mass(tangent) + dt * flow
        dp = linear_solve(a_p, r_p, por.p_dofs)
        du = linear_solve(k, -(r_u - por.Q @ dp), self.supports.dofs, tie=self._tie)
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
        flow = por.flow_matrix(self.u)
        r_u, r_p, _, _ = self._residual(self.sigma, np.zeros(n_u), self.p, h, t1, flow)
        k = macro.stiffness(self.tangent)
        z0 = np.concatenate([np.zeros(n_u), self.p])
        r = np.concatenate([r_u, r_p]) + self._matrix(k, h, flow) @ (z - z0)
        z = z + self._correction(k, r, self.tangent, h, flow)
        growth, last = 0, math.inf
        prev, omega = None, 1.0
        for it in range(1, st.max_iterations + 1):
            du, p = z[:n_u], z[n_u:]
            self._check_pressure(p)
            grad = macro.increment_gradient(self.u, du)
            try:
                sig, c = farm.trial(grad)
            except MicroFailure as err:
                if not err.recoverable:
                    farm.rollback()
                    raise SolverError(f"time step at t = {self.t:.6g} s stopped: "
                                      f"{err}") from err
                raise _NotConverged(str(err)) from err
            flow = por.flow_matrix(self.u + du)
            r_u, r_p, ref_u, ref_p = self._residual(sig, du, p, h, t1, flow)
            ru = float(np.linalg.norm(free_part(r_u, self.free, self._tie)))
            rp = float(np.linalg.norm(r_p[self._free_p]))
            rel = max(ru / ref_u, rp / ref_p)
            if not math.isfinite(rel):
                raise _NotConverged("non-finite residual")
            dz = self._correction(macro.stiffness(c), np.concatenate([r_u, r_p]), c, h,
                                  flow)
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
