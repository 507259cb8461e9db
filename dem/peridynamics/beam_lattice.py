"""A 3D cantilever as a cubic lattice of rigid bodies joined by beams (paper Fig 11).

Bodies sit on a cubic lattice of spacing ``s`` that fills the bar ``[0, L] x [-w/2,
w/2] x [-h/2, h/2]``: layers ``x = 0, s, ..., L`` along the bar (nodes, as in
:func:`.beams.cantilever`) and, in each layer, an ``n_y x n_z`` grid at the centres of
the ``s x s`` cells of the cross-section. Each body is the rigid cube of bar around it
(half a cube in the two end layers), so the masses add up to ``rho L h w``; the layer
``x = 0`` is clamped. Pairs of bodies are joined by :class:`.beams.BeamBonds`:

- **nearest neighbours** (``radius=None``): a bond along an axis carries the patch of
  material between its bodies, of area ``s^2`` and own second moments ``s^4 / 12``
  (half the patch, ``s^2 / 2``, for bonds across the bar in the two end layers). Since
  the fibres sit at the centroids of their patches, the parallel-axis theorem gives
  ``sum A = h w`` and ``sum (A z^2 + I) = w h^3 / 12`` exactly: the lattice has the
  bar's EA and EI at every resolution. Its bulk is an isotropic solid with Young's
  modulus E, Poisson's ratio 0 and shear modulus E / 2 (:func:`lattice_constants`).
- **every pair within** ``radius``: all bonds carry the same section, ``f`` times that
  of an ``s x s`` square (``A = f s^2``, ``I = f s^4 / 12``), with the factor ``f``
  calibrated, as a peridynamic micromodulus is, so that the bulk lattice in uniaxial
  stress has Young's modulus E.

Lengths in m, E in Pa, density in kg/m^3.
"""

import logging
from typing import NamedTuple

import numpy as np

from .beams import BeamBonds, BeamStructure, rectangle_torsion_constant

log = logging.getLogger(__name__)

_TOL = 1e-9  # relative tolerance of lattice geometry tests


class LatticeConstants(NamedTuple):
    """Linear elastic constants [Pa] of a bulk cubic beam lattice (cubic symmetry)."""

    c11: float
    c12: float
    c44: float
    young: float  # uniaxial stress along a lattice axis
    poisson: float  # lateral contraction in that test


def _offsets(radius_over_spacing):
    """Integer offsets ``(m, 3)`` of the full neighbourhood within the radius."""
    m = int(np.floor(radius_over_spacing * (1.0 + _TOL)))
    g = np.arange(-m, m + 1)
    n = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    norm = np.linalg.norm(n, axis=1)
    return n[(norm > 0) & (norm <= radius_over_spacing * (1.0 + _TOL))]


def lattice_constants(radius_over_spacing=1.0, E=1.0):
    """Elastic constants of the bulk lattice with bonds to every body within
    ``radius_over_spacing`` spacings, each bond of section ``A = s^2``, ``I = s^4/12``
    (section factor 1) and Young's modulus ``E`` [Pa].

    Under a uniform strain ``eps`` the bodies do not turn (every lattice mirror maps
    the strains used here onto themselves and flips a rotation), and a bond along
    the unit vector ``e`` of length ``l`` stores, from its axial stretch and from the
    chord's rotation ``(1 - e e^T) eps e`` against its two ends,
    ``U = E A l (e.eps.e)^2 / 2 + 6 E I / l |(1 - e e^T) eps e|^2``. Half of the bonds
    of one body, per volume ``s^3``, give the energy density and so ``C11``, ``C12``,
    ``C44``; ``s`` cancels. Young's modulus and Poisson's ratio are those of uniaxial
    stress along a lattice axis. Nearest neighbours give ``C11 = E``, ``C12 = 0``,
    ``C44 = E / 2``: isotropic, ``nu = 0``.

    >>> c = lattice_constants(1.0, E=1.0)
    >>> c.c11, c.c12, c.c44, c.poisson
    (1.0, 0.0, 0.5, 0.0)
    """
    n = _offsets(radius_over_spacing).astype(np.float64)
    length = np.linalg.norm(n, axis=1)  # in spacings
    e = n / length[:, None]
    area, moment = 1.0, 1.0 / 12.0  # section factor 1, in units of s^2 and s^4

    def density(eps):
        d = e @ eps  # eps e (eps symmetric)
        axial = np.sum(d * e, axis=1)
        side = d - axial[:, None] * e
        u = (0.5 * E * area * length * axial**2
             + 6.0 * E * moment / length * np.sum(side * side, axis=1))
        return 0.5 * u.sum()  # each bond is shared by two bodies; volume s^3 = 1

    xx, yy = np.diag([1.0, 0.0, 0.0]), np.diag([0.0, 1.0, 0.0])
    xz = np.array([[0.0, 0.0, 0.5], [0.0, 0.0, 0.0], [0.5, 0.0, 0.0]])  # gamma = 1
    c11 = 2.0 * density(xx)
    c12 = density(xx + yy) - c11
    c44 = 2.0 * density(xz)
    young = (c11 - c12) * (c11 + 2.0 * c12) / (c11 + c12)
    return LatticeConstants(float(c11), float(c12), float(c44), float(young),
                            float(c12 / (c11 + c12)))


def section_factor(radius_over_spacing):
    """Section factor ``f`` that gives the bulk lattice with bonds within
    ``radius_over_spacing`` spacings Young's modulus E (1 for nearest neighbours)."""
    return 1.0 / lattice_constants(radius_over_spacing).young


def _grid(n_x, n_y, n_z, length, height, width):
    """Body positions (n, 3) [m], integer lattice indices (n, 3) and spacing [m]."""
    s = length / (n_x - 1)
    if not (np.isclose(height / n_z, s, rtol=_TOL) and np.isclose(width / n_y, s,
                                                                  rtol=_TOL)):
        raise ValueError(
            f"not a cubic lattice: spacings {s:.6g} (x), {width / n_y:.6g} (y), "
            f"{height / n_z:.6g} (z) m; choose n_x - 1 = n_y length / width = "
            f"n_z length / height")
    idx = np.stack(np.meshgrid(np.arange(n_x), np.arange(n_y), np.arange(n_z),
                               indexing="ij"), -1).reshape(-1, 3)
    pos = np.column_stack([idx[:, 0] * s, -0.5 * width + (idx[:, 1] + 0.5) * s,
                           -0.5 * height + (idx[:, 2] + 0.5) * s])
    return pos, idx, s


def _pairs(idx, shape, offsets):
    """Bonds ``(i, j)`` for every lattice offset with a first non-zero component > 0,
    and the offset of each."""
    first = np.array([o[np.flatnonzero(o)[0]] for o in offsets])
    half = offsets[first > 0]
    pairs, steps = [], []
    for o in half:
        other = idx + o
        ok = np.all((other >= 0) & (other < shape), axis=1)
        j = np.ravel_multi_index(other[ok].T, shape)
        pairs.append(np.column_stack([np.flatnonzero(ok), j]))
        steps.append(np.broadcast_to(o, (ok.sum(), 3)))
    return np.concatenate(pairs), np.concatenate(steps)


def lattice_cantilever(n_x, n_y, n_z, length, height, width, E, density, radius=None,
                       poisson=0.3):
    """A bar along +x clamped at x = 0, as a cubic lattice of bodies joined by beams.

    See the module docstring for the layout and the sections. The lattice must be
    cubic: ``length / (n_x - 1) = width / n_y = height / n_z``; ``height`` is along z,
    ``width`` along y. Body ``(i_x, i_y, i_z)`` is row ``(i_x n_y + i_y) n_z + i_z``,
    so the clamped layer is the first ``n_y n_z`` rows and the tip layer the last.

    Parameters
    ----------
    n_x, n_y, n_z : int
        Bodies along the bar (>= 2) and across it (>= 1).
    length, height, width : float
        Bar dimensions [m].
    E : float
        Young's modulus [Pa].
    density : float
        [kg/m^3].
    radius : float, optional
        Bond radius [m]: join every pair closer than it, with the calibrated common
        section (:func:`section_factor`). Default: nearest neighbours with their
        tributary sections.
    poisson : float
        Sets the beams' shear modulus ``G = E / (2 (1 + poisson))`` (torsion only).

    Returns
    -------
    bodies : dem.Bodies
    bonds : BeamBonds
    """
    from ..shapes import Box
    from ..state import Bodies

    if int(n_x) < 2 or int(n_y) < 1 or int(n_z) < 1:
        raise ValueError(f"need n_x >= 2 and n_y, n_z >= 1, got {n_x, n_y, n_z}")
    shape = (int(n_x), int(n_y), int(n_z))
    pos, idx, s = _grid(*shape, length, height, width)
    ends = (idx[:, 0] == 0) | (idx[:, 0] == shape[0] - 1)
    bodies = Bodies.empty(3)
    for rows, piece in ((np.flatnonzero(~ends), s), (np.flatnonzero(ends), 0.5 * s)):
        if rows.size:
            bodies.add_shapes(Box([0.5 * piece, 0.5 * s, 0.5 * s]), pos[rows],
                              density=density)
    order = np.argsort(np.concatenate([np.flatnonzero(~ends), np.flatnonzero(ends)]),
                       kind="stable")
    for name in bodies.ARRAYS:  # back to lattice order
        setattr(bodies, name, np.ascontiguousarray(getattr(bodies, name)[order]))
    bodies.fix(np.flatnonzero(idx[:, 0] == 0))
    G = E / (2.0 * (1.0 + poisson))
    if radius is None:
        pairs, step = _pairs(idx, shape, _offsets(1.0))
        along_x = step[:, 0] != 0
        # across the bar, a bond's patch is s (or s / 2 in an end layer) along x by s
        thick = np.where(along_x | ~ends[pairs[:, 0]], s, 0.5 * s)
        up = np.where(step[:, 2:3] != 0, [1.0, 0.0, 0.0], [0.0, 0.0, 1.0])
        # section axes b = up, c = a x b: x and y bonds have b = z (extent s), c along
        # x (extent ``thick``) or y; z bonds have b = x (extent ``thick``), c = y
        eb = np.where(step[:, 2] != 0, thick, s)
        ec = np.where(step[:, 1] != 0, thick, s)
        area = eb * ec
        moments = np.column_stack([eb * ec**3 / 12.0, ec * eb**3 / 12.0,
                                   [rectangle_torsion_constant(a, b)
                                    for a, b in zip(eb, ec, strict=True)]])
    else:
        ratio = radius / s
        if ratio < 1.0 - _TOL:
            raise ValueError(f"radius {radius:g} m is below the spacing {s:g} m")
        pairs, step = _pairs(idx, shape, _offsets(ratio))
        f = section_factor(ratio)
        area = f * s * s
        moments = f * np.array([s**4 / 12.0, s**4 / 12.0,
                                rectangle_torsion_constant(s, s)])
        up = None
    bonds = BeamBonds(bodies, pairs, E=E, area=area, moments=moments, G=G, up=up)
    return bodies, bonds


def lattice_deflection(n_x, n_y, n_z, length, height, width, E, density, accel,
                       radius=None, damping=0.7, tol=1e-6):
    """Static deflection [m] of :func:`lattice_cantilever` under a body acceleration
    ``accel`` [m/s^2] along -z, by dynamic relaxation with Cundall damping: the mean
    over the tip layer, positive along the load. Returns ``(deflection, structure)``.
    """
    bodies, bonds = lattice_cantilever(n_x, n_y, n_z, length, height, width, E,
                                       density, radius=radius)
    sim = BeamStructure(bodies, bonds, accel=[0.0, 0.0, -accel], damping=damping)
    sim.relax(tol=tol)
    log.info("lattice %dx%dx%d r=%s: %d bonds, %d steps", n_x, n_y, n_z, radius,
             bonds.n_bonds, sim.step)
    tip = slice(bodies.n - n_y * n_z, bodies.n)
    return float(-bodies.pos[tip, 2].mean()), sim
