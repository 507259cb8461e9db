"""Closed-form solutions of linear poroelasticity (Biot), to verify a u-p solver.

* :class:`BiotMaterial` -- the drained moduli, Biot's coefficient and modulus, the
  mobility, and the derived undrained constants and consolidation coefficients;
* Terzaghi's one-dimensional consolidation: :func:`terzaghi_initial_pressure`,
  :func:`terzaghi_pressure`, :func:`terzaghi_degree`, :func:`terzaghi_settlement`;
* Mandel's problem (plane strain): :func:`mandel_roots`,
  :func:`mandel_initial_pressure`, :func:`mandel_pressure`,
  :func:`mandel_displacement_top`, :func:`mandel_cryer_peak`.

Conventions: SI units (Pa, m, s, N/m); stresses are positive in tension, the pore
pressure ``p`` is positive in compression, so the effective stress is
``sigma' = sigma + alpha p I``. Plane strain is the three-dimensional problem with
zero out-of-plane strain: every modulus here is the three-dimensional one.

References: E. Detournay and A. H.-D. Cheng, "Fundamentals of poroelasticity" (1993),
in Comprehensive Rock Engineering, vol. 2, pp. 113-171; Y. Abousleiman et al.,
"Mandel's problem revisited", Geotechnique 46 (1996) 187-195.
"""

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, minimize_scalar
from scipy.special import erfc

# Below this time factor the Terzaghi series of images (error functions) is used,
# above it the Fourier series; both are exact to round-off on their side.
_TV_IMAGES = 0.1


@dataclass(frozen=True, kw_only=True)
class BiotMaterial:
    """An isotropic Biot material (all keyword arguments).

    Parameters
    ----------
    bulk : float
        Drained bulk modulus ``K`` (Pa).
    shear : float
        Shear modulus ``G`` (Pa).
    biot : float
        Biot's coefficient ``alpha`` in ``(0, 1]`` (-).
    storage_modulus : float
        Biot's modulus ``M`` (Pa), ``1/M = n/K_f + (alpha - n)/K_s``; ``inf`` for
        incompressible constituents.
    mobility : float
        ``kappa = k / mu``, intrinsic permeability over fluid viscosity (m^2/(Pa s)).

    Examples
    --------
    >>> m = BiotMaterial(bulk=1e8, shear=6e7, storage_modulus=1e9, mobility=1e-10)
    >>> round(m.poisson, 12), round(m.skempton, 12)
    (0.25, 0.909090909091)
    """

    bulk: float
    shear: float
    biot: float = 1.0
    storage_modulus: float = math.inf
    mobility: float

    def __post_init__(self):
        if not (self.bulk > 0 and self.shear > 0 and self.mobility > 0):
            raise ValueError("bulk, shear and mobility must be positive")
        if not (0 < self.biot <= 1 and self.storage_modulus > 0):
            raise ValueError("need 0 < biot <= 1 and storage_modulus > 0")

    @classmethod
    def from_young(cls, young, poisson, **kwargs):
        """The material of drained Young's modulus ``young`` (Pa) and ``poisson``.

        Other fields (``biot``, ``storage_modulus``, ``mobility``) by keyword.
        """
        return cls(bulk=young / (3 * (1 - 2 * poisson)),
                   shear=young / (2 * (1 + poisson)), **kwargs)

    @property
    def poisson(self):
        """Drained Poisson's ratio ``nu`` (-)."""
        return _poisson(self.bulk, self.shear)

    @property
    def undrained_bulk(self):
        """Undrained bulk modulus ``K_u = K + alpha^2 M`` (Pa); ``inf`` if ``M`` is."""
        return self.bulk + self.biot**2 * self.storage_modulus

    @property
    def undrained_poisson(self):
        """Undrained Poisson's ratio ``nu_u`` (-); 1/2 if ``M = inf``."""
        if math.isinf(self.undrained_bulk):
            return 0.5
        return _poisson(self.undrained_bulk, self.shear)

    @property
    def skempton(self):
        """Skempton's coefficient ``B = alpha M / K_u`` (-); ``1/alpha`` if ``M = inf``.
        """
        if math.isinf(self.storage_modulus):
            return 1.0 / self.biot
        return self.biot * self.storage_modulus / self.undrained_bulk

    @property
    def constrained(self):
        """Drained constrained (oedometric) modulus ``K + 4G/3`` (Pa)."""
        return self.bulk + 4.0 * self.shear / 3.0

    @property
    def consolidation_coefficient_1d(self):
        """Oedometric ``c_v = kappa / (1/M + alpha^2 / (K + 4G/3))`` (m^2/s)."""
        return self.mobility / (1.0 / self.storage_modulus
                                + self.biot**2 / self.constrained)

    @property
    def consolidation_coefficient_mandel(self):
        """Detournay and Cheng's ``c`` (m^2/s).

        ``c = 2 kappa B^2 G (1 - nu)(1 + nu_u)^2 / (9 (1 - nu_u)(nu_u - nu))``, which is
        algebraically equal to :attr:`consolidation_coefficient_1d`.
        """
        nu, nu_u, b = self.poisson, self.undrained_poisson, self.skempton
        return (2 * self.mobility * b**2 * self.shear * (1 - nu) * (1 + nu_u)**2
                / (9 * (1 - nu_u) * (nu_u - nu)))


def _poisson(bulk, shear):
    return (3 * bulk - 2 * shear) / (2 * (3 * bulk + shear))


def _check_time(t):
    t = np.asarray(t, dtype=np.float64)
    if np.any(t < 0):
        raise ValueError("time must be >= 0 (the load is applied at t = 0+)")
    return t


# ------------------------------------------------------------------------- Terzaghi
def terzaghi_initial_pressure(material, q):
    """Undrained pressure ``p0`` (Pa) just after the load ``q`` (Pa, compressive).

    ``p0 = alpha M q / (K + 4G/3 + alpha^2 M)``, which is ``q / alpha`` for ``M = inf``.

    Examples
    --------
    >>> m = BiotMaterial(bulk=1e8, shear=6e7, biot=0.8, mobility=1e-10)
    >>> float(terzaghi_initial_pressure(m, 1e5))
    125000.0
    """
    m = material
    if math.isinf(m.storage_modulus):
        return q / m.biot
    alpha_m = m.biot * m.storage_modulus
    return alpha_m * q / (m.constrained + m.biot * alpha_m)


def _terzaghi_fourier(zeta, tv, terms):
    """``p / p0`` at ``zeta = z / H``, Fourier series (good for ``Tv >~ 1e-4``)."""
    k = 2 * np.arange(terms) + 1.0
    amp = 4 / (k * np.pi) * np.exp(-k**2 * np.pi**2 * tv / 4)
    return np.sin(np.multiply.outer(zeta, k) * np.pi / 2) @ amp


def _terzaghi_images(zeta, tv, images=8):
    """``p / p0`` at ``zeta = z / H`` by the series of images (good for ``Tv <~ 1``)."""
    s = 2 * np.sqrt(tv)
    w = sum((-1)**j * (erfc((2 * j + zeta) / s) + erfc((2 * j + 2 - zeta) / s))
            for j in range(images))
    return 1.0 - w


def terzaghi_pressure(z, t, height, material, q, terms=200):
    """Pore pressure (Pa) of Terzaghi's consolidation at depth ``z`` and time ``t``.

    A column of height ``height`` (m) on a rigid impermeable base, loaded at
    ``t = 0+`` by ``q`` (Pa, compressive) on its top, drained (``p = 0``) there:
    ``p = sum_m 4 p0 / (m' pi) sin(m' pi z / (2H)) exp(-m'^2 pi^2 Tv / 4)``,
    ``m' = 2m + 1``, ``Tv = c_v t / H^2``.

    Parameters
    ----------
    z : array_like
        Depth below the drained top (m), in ``[0, height]``.
    t : float
        Time (s) since the load; at ``t = 0`` the value is ``p0`` for ``z > 0``.
    height : float
        Column height ``H`` (m).
    material : BiotMaterial
    q : float
        Applied compressive load (Pa).
    terms : int
        Fourier terms, used for ``Tv >= 0.1``; earlier times use the equivalent
        series of images (error functions), which converges in a few terms there.

    Returns
    -------
    ndarray
        ``p`` (Pa), the shape of ``z``.
    """
    zeta = np.asarray(z, dtype=np.float64) / height
    tv = float(_check_time(t)) * material.consolidation_coefficient_1d / height**2
    p0 = terzaghi_initial_pressure(material, q)
    if tv == 0:
        return np.where(zeta > 0, p0, 0.0)
    if tv < _TV_IMAGES:
        return p0 * _terzaghi_images(zeta, tv)
    return p0 * _terzaghi_fourier(zeta, tv, terms)


def _ierfc(x):
    """``int_x^inf erfc(s) ds``."""
    return np.exp(-x * x) / np.sqrt(np.pi) - x * erfc(x)


def terzaghi_degree(t, height, material, terms=200):
    """Degree of consolidation ``U(t)`` (-), 0 at ``t = 0`` and 1 when drained.

    ``U = 1 - sum_m 8 / (m'^2 pi^2) exp(-m'^2 pi^2 Tv / 4)``, ``m' = 2m + 1``,
    ``Tv = c_v t / H^2``; for ``Tv < 0.1`` the equivalent short-time series
    ``U = 2 sqrt(Tv / pi) + 4 sqrt(Tv) sum_j (-1)^j ierfc(j / sqrt(Tv))``.

    Examples
    --------
    >>> m = BiotMaterial(bulk=1e8, shear=6e7, mobility=1e-10)
    >>> t50 = 0.19674 / m.consolidation_coefficient_1d  # H = 1 m
    >>> round(float(terzaghi_degree(t50, 1.0, m)), 4)
    0.5
    """
    tv = _check_time(t) * material.consolidation_coefficient_1d / height**2
    k = 2 * np.arange(terms) + 1.0
    fourier = 1 - np.exp(-np.multiply.outer(tv, k**2) * np.pi**2 / 4) @ (
        8 / (k**2 * np.pi**2))
    r = np.sqrt(np.minimum(tv, _TV_IMAGES))
    j = np.arange(1, 9)
    with np.errstate(divide="ignore", invalid="ignore"):  # t = 0: inf * 0 -> 0
        tail = _ierfc(np.multiply.outer(1 / r, j)) * (-1.0)**j
    short = 2 * r / np.sqrt(np.pi) + 4 * r * np.nan_to_num(tail).sum(axis=-1)
    return np.where(tv < _TV_IMAGES, short, fourier)


def terzaghi_settlement(t, height, material, q, terms=200):
    """Settlement of the loaded top (m, positive downwards).

    ``s = s0 + (s_inf - s0) U(t)`` with the drained ``s_inf = q H / (K + 4G/3)`` and
    the undrained ``s0 = q H / (K + 4G/3 + alpha^2 M)`` (0 for ``M = inf``).
    """
    m = material
    s_inf = q * height / m.constrained
    s0 = q * height / (m.constrained + m.biot**2 * m.storage_modulus)
    return s0 + (s_inf - s0) * terzaghi_degree(t, height, m, terms)


# --------------------------------------------------------------------------- Mandel
def _mandel_slope(material):
    """``(1 - nu) / (nu_u - nu)``, the slope in ``tan(x) = slope * x``."""
    nu, nu_u = material.poisson, material.undrained_poisson
    return (1 - nu) / (nu_u - nu)


def mandel_roots(material, n):
    """The first ``n`` positive roots of ``tan(x) = (1 - nu)/(nu_u - nu) x``.

    The ``i``-th root (``i = 1..n``) lies in ``((i - 1) pi, (i - 1/2) pi)``; each is
    bracketed there and found by Brent's method on ``sin(x)/x - slope cos(x)``,
    which has no pole.

    Examples
    --------
    >>> m = BiotMaterial(bulk=1e8, shear=6e7, storage_modulus=1e9, mobility=1e-10)
    >>> r = mandel_roots(m, 3)
    >>> bool(np.all((r > np.pi * np.arange(3)) & (r < np.pi * (np.arange(3) + 0.5))))
    True
    """
    slope = _mandel_slope(material)

    def f(x):
        return (math.sin(x) / x if x else 1.0) - slope * math.cos(x)

    eps = 4 * np.finfo(float).eps
    return np.array([brentq(f, (i - 1) * math.pi, (i - 0.5) * math.pi,
                            xtol=1e-300, rtol=eps, maxiter=200)
                     for i in range(1, n + 1)])


def mandel_initial_pressure(a, force, material):
    """Uniform undrained pressure ``p0 = F B (1 + nu_u) / (3 a)`` (Pa) at ``t = 0+``.

    ``force`` is ``F`` (N/m): half the total load ``2F`` per unit out-of-plane length
    on each plate, so the mean vertical stress is ``-F / a``; ``a`` is the half width
    (m).
    """
    m = material
    return force * m.skempton * (1 + m.undrained_poisson) / (3 * a)


def _mandel_time_factor(t, a, material):
    return _check_time(t) * material.consolidation_coefficient_mandel / a**2


def mandel_pressure(x, t, a, force, material, terms=200):
    """Pore pressure (Pa) of Mandel's problem at abscissa ``x`` and time ``t``.

    The specimen ``|x| <= a``, ``|y| <= b`` is squeezed from ``t = 0+`` between
    rigid, frictionless, impermeable plates at ``y = +-b`` carrying a constant total
    load ``2F`` (N/m) each; its faces ``x = +-a`` are traction-free and drained.
    With ``p0`` of :func:`mandel_initial_pressure` and the roots ``a_n`` of
    :func:`mandel_roots`,
    ``p = 2 p0 sum_n sin a_n / (a_n - sin a_n cos a_n) (cos(a_n x/a) - cos a_n)
    exp(-a_n^2 c t / a^2)`` (Detournay and Cheng 1993), ``c`` the
    :attr:`~BiotMaterial.consolidation_coefficient_mandel`.

    Parameters
    ----------
    x : array_like
        Abscissa (m), ``|x| <= a``.
    t : float
        Time (s); at ``t = 0`` the value is ``p0`` for ``|x| < a``.
    a : float
        Half width (m).
    force : float
        ``F`` (N/m): each plate carries ``2F`` per unit out-of-plane length.
    material : BiotMaterial
    terms : int
        Terms of the series; the truncation error is about
        ``exp(-(terms pi)^2 c t / a^2)``: round-off for ``c t / a^2 >= 1e-4`` with
        the default 200 terms, more are needed earlier.

    Returns
    -------
    ndarray
        ``p`` (Pa), the shape of ``x``.
    """
    xi = np.asarray(x, dtype=np.float64) / a
    tf = float(_mandel_time_factor(t, a, material))
    p0 = mandel_initial_pressure(a, force, material)
    if tf == 0:
        return np.where(np.abs(xi) < 1, p0, 0.0)
    r = mandel_roots(material, terms)
    amp = 2 * np.sin(r) / (r - np.sin(r) * np.cos(r)) * np.exp(-r**2 * tf)
    return p0 * ((np.cos(np.multiply.outer(xi, r)) - np.cos(r)) @ amp)


def mandel_displacement_top(t, a, b, force, material, terms=200):
    """Vertical displacement (m) of the top plate, ``u_y(y = b, t)``; negative.

    ``u_y = b F / (G a) [-(1 - nu)/2 + (1 - nu_u) sum_n w_n exp(-a_n^2 c t / a^2)]``,
    ``w_n = sin a_n cos a_n / (a_n - sin a_n cos a_n)`` (Abousleiman et al. 1996),
    ``F`` as in :func:`mandel_pressure`. From the root equation
    ``sum_n w_n = (nu_u - nu) / (2 (1 - nu_u))`` exactly, which is used at ``t = 0``:
    the limits are the plane-strain elastic ones under the mean stress ``-F / a``
    with free sides, ``u_y = -b (F/a)(1 - nu_u) / (2G)`` undrained at ``t = 0+`` and
    ``-b (F/a)(1 - nu) / (2G)`` drained. The same follows from equilibrium with the
    pressure of :func:`mandel_pressure` (``sigma_xx = 0`` throughout):
    ``u_y / b = -F (1 - nu)/(2 G a) + alpha (1 - 2 nu)/(2 G a) int_0^a p dx``.

    Parameters
    ----------
    t : array_like
        Times (s).
    a, b : float
        Half width and half height (m).
    force : float
        ``F`` (N/m).
    material : BiotMaterial
    terms : int
        Terms of the series (see :func:`mandel_pressure` for its accuracy).

    Returns
    -------
    ndarray
        ``u_y(b, t)`` (m), the shape of ``t``.
    """
    m = material
    nu, nu_u = m.poisson, m.undrained_poisson
    tf = _mandel_time_factor(t, a, m)
    r = mandel_roots(m, terms)
    sc = np.sin(r) * np.cos(r)
    series = np.exp(-np.multiply.outer(tf, r**2)) @ (sc / (r - sc))
    series = np.where(tf == 0, (nu_u - nu) / (2 * (1 - nu_u)), series)
    return b * force / (m.shear * a) * (-(1 - nu) / 2 + (1 - nu_u) * series)


def mandel_cryer_peak(a, force, material, terms=200):
    """The Mandel-Cryer overshoot ``max_t p(0, t) / p0`` (-), larger than 1.

    Found on a logarithmic grid of ``c t / a^2`` from the earliest time the
    ``terms``-term series resolves to 10, then refined by a bounded search.
    The ratio depends on ``nu`` and ``nu_u`` only; ``a`` and ``force`` are taken
    for a signature like the other Mandel functions and do not change it.
    """
    r = mandel_roots(material, terms)
    amp = 2 * np.sin(r) / (r - np.sin(r) * np.cos(r)) * (1 - np.cos(r))

    def ratio(log_tf):
        return float(np.exp(-r**2 * 10.0**log_tf) @ amp)

    grid = np.linspace(np.log10(40 / r[-1]**2), 1.0, 241)
    values = [ratio(s) for s in grid]
    i = int(np.clip(np.argmax(values), 1, len(grid) - 2))
    best = minimize_scalar(lambda s: -ratio(s), bounds=(grid[i - 1], grid[i + 1]),
                           method="bounded", options={"xatol": 1e-10})
    return max(-best.fun, max(values))
