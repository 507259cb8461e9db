"""Hertz-Mindlin with simplified JKR cohesion (``law = "hertz_sjkr"``): LIGGGHTS'
``cohesion sjkr`` on its Hertz model.

While two bodies overlap, an attraction ``k A`` pulls them together, ``k`` the
cohesion energy density [J/m^3] and ``A`` the area of their contact. ``A`` is the
disc where the two undeformed spheres intersect, ``pi (2 R* delta)`` to first order in
``delta / R*`` (LIGGGHTS takes the exact intersection, smaller by ``delta / (8 R*)``
for two equal spheres and ``delta / (2 R*)`` for a sphere on a plane: 0.5 % at an
overlap of 1 % of ``R*``). The
attraction is conservative: it stores ``-pi R* k delta^2``, so an undamped collision
rebounds with its approach speed, and a body at rest in contact settles where the Hertz
force balances it, ``delta* = 9 pi^2 k^2 R* / (4 E*^2)``. Friction is capped by the
Hertz part of the normal force alone (``mu max(f_n, 0)``, as the law without
cohesion); rolling resistance scales with the Hertz stiffness. The attraction acts only
in contact: bodies that touch nowhere do not attract (no pull-off hysteresis). In 2D,
disks take these sphere formulas unchanged, the force read per unit thickness
(docs/theory.md, Hertz laws in 2D).
"""

import math

import numpy as np

from ..._jit import kernel
from .base import check_number, register
from .hertz_mindlin import (HertzMindlin, energy_hertz_mindlin, law_hertz_mindlin,
                            normal_stiffness_hertz_mindlin, stiffness_hertz_mindlin)

#: the parameter row: Hertz-Mindlin's five, then the cohesion energy density [J/m^3]
COL_COHESION = 5


@kernel
def law_hertz_sjkr(ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff, p, a, b, hist, k, dt):
    """Hertz-Mindlin's force on j, then the attraction ``2 pi R* k delta`` towards i.

    Called from the loops, not inlined (:mod:`.dispatch`): the loops of the other laws
    compile as fast as before this law, and its own scenes pay a call per contact."""
    fx, fy, fz = law_hertz_mindlin(ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff, p, a, b,
                                   hist, k, dt)
    fc = 2.0 * math.pi * r_eff * p[a, b, COL_COHESION] * ov
    return fx - fc * nx, fy - fc * ny, fz - fc * nz


@kernel
def stiffness_hertz_sjkr(ov, r_eff, p):
    """The tangent: Hertz's normal stiffness less the attraction's ``2 pi R* k``
    (negative below 4/9 of the rest overlap), Mindlin's tangential one."""
    kn, kt = stiffness_hertz_mindlin(ov, r_eff, p)
    return kn - 2.0 * math.pi * r_eff * p[COL_COHESION], kt


@kernel
def energy_hertz_sjkr(ov, r_eff, p, hist, k):
    return (energy_hertz_mindlin(ov, r_eff, p, hist, k)
            - math.pi * r_eff * p[COL_COHESION] * ov * ov)


@register
class HertzSJKR(HertzMindlin):
    """Hertz-Mindlin with simplified JKR cohesion, one material pair.

    Parameters
    ----------
    young, poisson, restitution, mu, overlap_ref, rolling, limit_damping
        As :class:`~dem.HertzMindlin`.
    cohesion : float
        Cohesion energy density ``k`` [J/m^3] (LIGGGHTS' ``cohesionEnergyDensity``):
        the attraction is ``k`` times the contact area ``2 pi R* delta``. 0 gives
        Hertz-Mindlin.

    Examples
    --------
    A 1 mm grain at rest on a rigid plane, no gravity, settles at
    ``delta* = 9 pi^2 k^2 R / (4 E*^2)``:

    >>> law = HertzSJKR(young=(1e7, math.inf), poisson=0.0, restitution=0.5, mu=0.3,
    ...                 cohesion=6.7e4)
    >>> round(law.rest_overlap(1e-3) / 1e-3, 4)
    0.001
    """

    name = "hertz_sjkr"
    code = 2
    n_params = 6
    force = staticmethod(law_hertz_sjkr)
    stiffness = staticmethod(stiffness_hertz_sjkr)
    energy = staticmethod(energy_hertz_sjkr)
    normal_stiffness = staticmethod(normal_stiffness_hertz_mindlin)

    def __init__(self, young, poisson, restitution, mu, cohesion, overlap_ref=0.05,
                 rolling=None, limit_damping=False):
        self.cohesion = check_number("cohesion", cohesion)
        super().__init__(young, poisson, restitution, mu, overlap_ref=overlap_ref,
                         rolling=rolling, limit_damping=limit_damping)
        self._args["cohesion"] = self.cohesion

    def row(self):
        return np.append(super().row(), self.cohesion)

    def rest_overlap(self, r_eff):
        """The overlap [m] at which the attraction balances Hertz's force, for a
        contact of effective radius ``r_eff`` [m] (no other load)."""
        return 9.0 * math.pi**2 * self.cohesion**2 * r_eff / (4.0 * self.e_star**2)

    # ------------------------------------------------------------------ files
    @classmethod
    def keys(cls):
        from ...io.schema import NONNEGATIVE, REQUIRED, Key

        return {**super().keys(),
                "cohesion": Key("float", "J/m^3", default=REQUIRED, range=NONNEGATIVE,
                                doc="Cohesion energy density: the attraction is it times "
                                    "the contact area 2 pi R* overlap.")}

    @classmethod
    def wall_keys(cls):
        from ...io.schema import NONNEGATIVE, Key

        return {**super().wall_keys(),
                "cohesion": Key("float", "J/m^3", range=NONNEGATIVE,
                                doc="the cohesion energy density between the wall and "
                                    "particles.")}

    @classmethod
    def arguments(cls, table, wall):
        """Hertz-Mindlin's, and the wall's ``cohesion`` or the table's."""
        return {**super().arguments(table, wall),
                "cohesion": wall.get("cohesion", table["cohesion"])}
