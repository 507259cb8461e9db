r"""Peridynamic materials: the linear peridynamic solid and the bond-based PMB.

Notation (per bond of point ``i`` to ``j``): reference bond ``xi``, its length
``|xi|``, deformed bond ``Y = y_j - y_i``, extension ``e = |Y| - |xi|``, stretch
``s = e / |xi|``, neighbour volume ``V_j``; ``d`` is the dimension.

**Linear peridynamic solid** (state-based, Silling et al. 2007), influence
``w = exp(-|xi|^2 / delta^2)``:

.. math::

    m_i = \sum_j w |\xi|^2 V_j, \qquad
    \theta_i = \frac{d}{m_i} \sum_j w |\xi| e V_j, \qquad
    t_{ij} = \frac{d\,\kappa_d\,\theta_i}{m_i} w |\xi|
             + \frac{\alpha}{m_i} w \Big(e - \frac{\theta_i |\xi|}{d}\Big),

with ``alpha = 15 mu`` in 3D and ``8 mu`` in 2D, and the bulk modulus ``kappa_d`` of the
dimension: ``kappa`` in 3D, ``lambda + mu = E / (2 (1 + nu)(1 - 2 nu))`` in plane
strain, ``E / (2 (1 - nu))`` in plane stress. Both follow from requiring the energy
density ``W_i = kappa_d theta_i^2 / 2 + alpha / (2 m_i) sum_j w (e^d)^2 V_j`` to equal the
classical one under any homogeneous deformation of an isotropic family. The force on
point ``i`` is ``sum_j (t_ij + t_ji) V_i V_j Y / |Y|``.

**Prototype microelastic brittle** (bond-based, Silling and Askari 2005): the pair
force is ``c s V_i V_j Y / |Y|``; Poisson's ratio is fixed at 1/4 (3D, plane strain)
or 1/3 (plane stress). The micromodulus ``c = 2 d^2 kappa_d / S`` is calibrated on the
lattice itself, ``S = sum_j |xi| V_j`` over a full (bulk) family, so a uniform
stretch of the bulk has exactly the classical energy density. With
``surface_correction``, each bond's ``c`` is scaled by the mean of its two points'
``S_bulk / S_i``, stiffening points near a free surface back to the bulk value.

Bonds break irreversibly once their stretch exceeds the critical stretch ``s0``, given
or computed from the fracture energy ``G0`` [J/m^2] with the bond-based calibrations:
``sqrt(5 G0 / (9 kappa delta))`` in 3D, ``sqrt(4 pi G0 / (9 E delta))`` in plane
stress, ``sqrt(5 pi G0 / (12 E delta))`` in plane strain (for the LPS, the same values:
an approximation, as in most codes).
"""

import math

import numpy as np

#: model codes the kernels branch on
LPS_CODE, PMB_CODE = 0, 1
#: layout of the parameter vector handed to the kernels (``P_CORR``: 1 when the LPS
#: dilation is surface-corrected, else 0)
P_MODEL, P_KAPPA, P_ALPHA, P_C, P_SCRIT, P_CORR, P_NPARAMS = 0, 1, 2, 3, 4, 5, 6

PLANES = ("strain", "stress")


class _Material:
    code = -1
    surface_correction = False

    def __init__(self, E, nu, density, plane, s_crit, G0):
        for name, v in (("E", E), ("density", density)):
            if not (v > 0.0 and math.isfinite(v)):
                raise ValueError(f"{name} must be positive and finite, got {v}")
        if not -1.0 < nu < 0.5:
            raise ValueError(f"nu must be in (-1, 0.5), got {nu}")
        if plane not in PLANES:
            raise ValueError(f"plane must be 'strain' or 'stress', got {plane!r}")
        if s_crit is not None and G0 is not None:
            raise ValueError("give s_crit or G0, not both")
        for name, v in (("s_crit", s_crit), ("G0", G0)):
            if v is not None and not (v > 0.0 and math.isfinite(v)):
                raise ValueError(f"{name} must be positive and finite, got {v}")
        self.E, self.nu, self.density = float(E), float(nu), float(density)
        self.plane = plane
        self.s_crit = None if s_crit is None else float(s_crit)
        self.G0 = None if G0 is None else float(G0)

    @property
    def mu(self):
        """Shear modulus [Pa]."""
        return self.E / (2.0 * (1.0 + self.nu))

    def kappa(self, dim):
        """Bulk modulus of dimension ``dim`` [Pa] (plane strain or stress in 2D)."""
        E, nu = self.E, self.nu
        if dim == 3:
            return E / (3.0 * (1.0 - 2.0 * nu))
        if self.plane == "strain":
            return E / (2.0 * (1.0 + nu) * (1.0 - 2.0 * nu))
        return E / (2.0 * (1.0 - nu))

    def critical_stretch(self, dim, horizon):
        """``s0``: given, from ``G0``, or infinite (no breaking)."""
        if self.s_crit is not None:
            return self.s_crit
        if self.G0 is None:
            return math.inf
        G0, E, d = self.G0, self.E, horizon
        if dim == 3:
            return math.sqrt(5.0 * G0 / (9.0 * self.kappa(3) * d))
        if self.plane == "stress":
            return math.sqrt(4.0 * math.pi * G0 / (9.0 * E * d))
        return math.sqrt(5.0 * math.pi * G0 / (12.0 * E * d))

    def wave_speed(self, dim):
        """Longitudinal (P) wave speed of the continuum [m/s], for time-step estimates."""
        return math.sqrt((self.kappa(dim) + 2.0 * (dim - 1) / dim * self.mu) / self.density)

    def params(self, dim, horizon, s_bulk):
        p = np.zeros(P_NPARAMS)
        p[P_MODEL] = self.code
        p[P_KAPPA] = self.kappa(dim)
        p[P_ALPHA] = (15.0 if dim == 3 else 8.0) * self.mu
        p[P_C] = 2.0 * dim**2 * self.kappa(dim) / s_bulk if s_bulk > 0.0 else 0.0
        p[P_SCRIT] = self.critical_stretch(dim, horizon)
        p[P_CORR] = 1.0 if self.surface_correction else 0.0
        return p

    def influence(self, length, horizon):
        return np.ones_like(length)

    def __repr__(self):
        brk = (f", s_crit={self.s_crit:g}" if self.s_crit else
               f", G0={self.G0:g}" if self.G0 else "")
        return (f"{type(self).__name__}(E={self.E:g}, nu={self.nu:g}, "
                f"density={self.density:g}, plane={self.plane!r}{brk})")


class LPS(_Material):
    """Linear peridynamic solid (state-based): any Poisson's ratio.

    Parameters
    ----------
    E : float [Pa]
    nu : float, in (-1, 0.5)
    density : float [kg/m^3]
    plane : {"strain", "stress"}
        The 2D form (ignored in 3D).
    s_crit, G0 : float, optional
        Critical stretch, or fracture energy [J/m^2] it is computed from; neither: no
        bond breaks.
    surface_correction : bool
        Compute each point's dilation with weights that make it exact for every
        homogeneous strain of its own (surface-cut) family (see
        :meth:`~dem.peridynamics.Family.dilation_weights`).

    Examples
    --------
    >>> m = LPS(E=1e9, nu=0.3, density=1000.0, plane="stress")
    >>> round(m.kappa(2) / 1e9, 4), round(m.kappa(3) / 1e9, 4)
    (0.7143, 0.8333)
    """

    code = LPS_CODE

    def __init__(self, E, nu, density, plane="strain", s_crit=None, G0=None,
                 surface_correction=False):
        super().__init__(E, nu, density, plane, s_crit, G0)
        self.surface_correction = bool(surface_correction)

    def influence(self, length, horizon):
        return np.exp(-(length / horizon) ** 2)


class PMB(_Material):
    """Prototype microelastic brittle material (bond-based): Poisson's ratio 1/4 in 3D
    and plane strain, 1/3 in plane stress.

    Parameters
    ----------
    E : float [Pa]
    density : float [kg/m^3]
    plane : {"strain", "stress"}
    s_crit, G0 : float, optional
        As for :class:`LPS`.
    surface_correction : bool
        Scale each bond's micromodulus so points near a free surface are as stiff as
        the bulk.
    """

    code = PMB_CODE

    def __init__(self, E, density, plane="strain", s_crit=None, G0=None,
                 surface_correction=False):
        nu = 1.0 / 3.0 if plane == "stress" else 0.25
        super().__init__(E, nu, density, plane, s_crit, G0)
        self.surface_correction = bool(surface_correction)

    def kappa(self, dim):
        nu = 0.25 if dim == 3 else self.nu
        E = self.E
        if dim == 3:
            return E / (3.0 * (1.0 - 2.0 * nu))
        if self.plane == "strain":
            return E / (2.0 * (1.0 + nu) * (1.0 - 2.0 * nu))
        return E / (2.0 * (1.0 - nu))
