"""The pore-pressure field of a saturated problem and the fluid's matrices.

:class:`Fluid` holds the fluid's and the mixture's hydraulic constants;
:class:`PorousMacro` puts linear pore pressures beside the quadratic displacements of
a :class:`~hmm.macro.Macro` (:data:`PAIRS`) and assembles the matrices of Biot's u-p
equations (:mod:`hmm.porous`): ``Q`` (coupling), ``S`` (storage) and ``H`` (flow),
once on the initial mesh under small kinematics, or on the configuration of a
displacement under finite kinematics, where the mass balance counts the change of
the mixture's volume ``J`` (:meth:`PorousMacro.volume_change`).
"""

import math
from dataclasses import dataclass

import numpy as np
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
from skfem.helpers import div, dot, grad, mul, trace

#: how the permeability follows the porosity (:class:`Fluid`)
PERMEABILITY_LAWS = ("constant", "kozeny_carman")

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


# --------------------------------------------------------------------------- finite
# w.Finv (d, d, ...) and w.J (...) describe the configuration at the quadrature points
# of the initial mesh (hmm.macro): grad_x = F^-T grad_X, div_x v = tr(grad_X v F^-1),
# dv = J dV
def _spatial(g, finv):
    return np.einsum("ji...,j...->i...", finv, g)


@BilinearForm
def _coupling_current(p, v, w):
    return w.alpha * p * trace(mul(v.grad, w.Finv)) * w.J


@BilinearForm
def _storage_current(p, q, w):
    return w.storage * p * q * w.J


@BilinearForm
def _flow_current(p, q, w):
    return dot(_spatial(grad(q), w.Finv), mul(w.kappa, _spatial(grad(p), w.Finv))) * w.J


@LinearForm
def _volume_change(q, w):
    return w.alpha * w.dJ * q


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
        n)^2`` from its value at ``porosity``, ``n = 1 - (1 - n_0) / J`` at each
        Gauss point (the grains keep their volume; ``J = 1 + tr eps`` under small
        kinematics, ``det F`` under finite); the storage keeps ``n_0``.
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
        A quadratic element of :data:`PAIRS`, small or finite kinematics (finite:
        the fluid's forms on the configuration of the displacement, see
        :meth:`coupling_matrix`).
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

    # ------------------------------------------------ the configuration (finite)
    def _current(self, u):
        """``(F^-1, det F)`` at the quadrature points for the displacement ``u``, or
        None: small kinematics (or no ``u``), the initial configuration."""
        if u is None or not self.macro.finite:
            return None
        return self.macro.configuration(u)

    def coupling_matrix(self, u=None):
        """``Q = int alpha p div v``: on the initial mesh (small kinematics), or on
        the configuration of ``u``, ``int alpha p div_x v dv`` (finite). Its
        transpose is the derivative of :meth:`volume_change` with the displacement,
        and it is the pressure's part of the internal force: ``int (sigma' - alpha p
        I) : grad_x v dv = f_int(sigma') - Q p``."""
        cur = self._current(u)
        if cur is None:
            return self.Q
        finv, jac = cur
        return asm(_coupling_current, self.pbasis, self.macro.basis,
                   alpha=self.fluid.biot, Finv=finv, J=jac).tocsr()

    def storage_matrix(self, u=None):
        """``S = int p q / M`` per unit initial (small) or current volume (finite)."""
        cur = self._current(u)
        if cur is None:
            return self.S
        return asm(_storage_current, self.pbasis, storage=self.fluid.storage,
                   J=cur[1]).tocsr()

    def volume_change(self, u, du):
        """The fluid volume the step ``du`` from ``u`` drives out, against each
        pressure test function (n_p,): ``Q^T du`` (small), or ``int q alpha (J(u +
        du) - J(u)) dV`` (finite: the change of the mixture's volume, exact for any
        size of step; its derivative with ``du`` is :meth:`coupling_matrix` of ``u +
        du``, transposed)."""
        if not self.macro.finite:
            return self.Q.T @ du
        _, j1 = self.macro.configuration(u + du)
        _, j0 = self.macro.configuration(u)
        return asm(_volume_change, self.pbasis, alpha=self.fluid.biot, dJ=j1 - j0)

    def jacobian(self, u):
        """The volume ratio ``J`` at the Gauss points (n_gp,): ``det F`` (finite),
        ``1 + tr eps`` (small)."""
        if self.macro.finite:
            return np.linalg.det(self.macro.deformation(u))
        return 1.0 + np.trace(self.macro.strain(u), axis1=1, axis2=2)

    def permeability_ratio(self, u):
        """``k / k_0`` at the Gauss points (n_gp,) for the displacement ``u``: 1, or
        Kozeny-Carman's ``[n^3 / (1 - n)^2] / [n_0^3 / (1 - n_0)^2]``."""
        if self.fluid.permeability_law == "constant" or u is None:
            return np.ones(self.macro.n_gp)
        n0 = self.fluid.porosity
        jac = self.jacobian(u)
        n = np.clip(1.0 - (1.0 - n0) / jac, 1e-6, 1.0 - 1e-6)
        return (n ** 3 / (1.0 - n) ** 2) / (n0 ** 3 / (1.0 - n0) ** 2)

    def flow_matrix(self, u=None):
        """``H = int grad q . kappa grad p`` (sparse) for the displacement ``u`` (the
        assembled one of the initial porosity under a constant permeability and
        small kinematics); under finite kinematics ``int grad_x q . kappa grad_x p
        dv`` on the configuration of ``u``."""
        cur = self._current(u)
        if cur is None and (self.fluid.permeability_law == "constant" or u is None):
            return self.H
        kappa = self.kappa[:, :, None, None]
        if self.fluid.permeability_law != "constant":
            kappa = kappa * self.macro.from_gp(self.permeability_ratio(u))
        if cur is None:
            return asm(_flow, self.pbasis, kappa=kappa).tocsr()
        return asm(_flow_current, self.pbasis, kappa=kappa, Finv=cur[0],
                   J=cur[1]).tocsr()

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
        permeability of the displacement ``u`` under Kozeny-Carman; the gradient on
        its configuration under finite kinematics)."""
        g = self.pbasis.interpolate(p).grad
        cur = self._current(u)
        if cur is not None:
            g = _spatial(g, cur[0])
        g = self.macro.to_gp(g)  # (n_gp, d)
        return -(g @ self.kappa.T) * self.permeability_ratio(u)[:, None]
