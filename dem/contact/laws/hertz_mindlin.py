"""The Hertz-Mindlin law (``law = "hertz_mindlin"``): Hertz normal force, Mindlin
tangential stiffness, restitution damping as in LIGGGHTS and YADE."""

import math

import numpy as np

from ..._jit import kernel
from ..restitution import clipped_damping
from .base import Law, check_number, register
from .tangential import N_HIST, tangential


@kernel(inline=True)
def law_hertz_mindlin(ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff, p, a, b, hist, k, dt):
    """Hertz normal force, Mindlin (no-slip) tangential stiffness, restitution damping.

    ``p[a, b] = (E* [Pa], G* [Pa], beta [-], mu [-], limit [-])`` with
    ``beta = ln e / sqrt(ln^2 e + pi^2)`` (negative; with ``limit`` 1 the normal force is
    clipped at zero and ``beta`` is the one that rebounds with ``e``). With
    ``a = sqrt(r_eff ov)``: ``Sn = 2 E* a``, ``St = 8 G* a``,
    ``fn = 4/3 E* a ov - 2 sqrt(5/6) beta sqrt(Sn m_eff) vn`` and the tangential spring
    force ``-St s - 2 sqrt(5/6) beta sqrt(St m_eff) vt``, capped by Coulomb at
    ``mu max(fn, 0)`` (the forms used by LIGGGHTS' hertz model and YADE's
    Hertz-Mindlin law; spring and dashpot in series with the slider:
    :func:`tangential`).
    """
    es, gs, beta, mu = p[a, b, 0], p[a, b, 1], p[a, b, 2], p[a, b, 3]
    rad = math.sqrt(r_eff * ov)
    sn_k = 2.0 * es * rad
    st_k = 8.0 * gs * rad
    c = -2.0 * math.sqrt(5.0 / 6.0) * beta
    cn = c * math.sqrt(sn_k * m_eff)
    ct = c * math.sqrt(st_k * m_eff)
    vn = vx * nx + vy * ny + vz * nz
    fn = 4.0 / 3.0 * es * rad * ov - cn * vn
    if p[a, b, 4] > 0.0 and fn < 0.0:  # limit_damping: the dashpot never pulls
        fn = 0.0
    tvx, tvy, tvz = vx - vn * nx, vy - vn * ny, vz - vn * nz
    ftx, fty, ftz = tangential(hist, k, nx, ny, nz, tvx, tvy, tvz, st_k, ct,
                               mu * max(fn, 0.0), dt)
    return fn * nx + ftx, fn * ny + fty, fn * nz + ftz


@kernel(inline=True)
def normal_stiffness_hertz_mindlin(ov, r_eff, p, a, b):
    """Normal tangent stiffness [N/m] of a contact of materials ``a``, ``b``."""
    return 2.0 * p[a, b, 0] * math.sqrt(r_eff * ov)


@kernel
def stiffness_hertz_mindlin(ov, r_eff, p):
    a = math.sqrt(r_eff * max(ov, 0.0))
    return 2.0 * p[0] * a, 8.0 * p[1] * a


@kernel
def energy_hertz_mindlin(ov, r_eff, p, hist, k):
    a = math.sqrt(r_eff * ov)
    s2 = hist[k, 0] ** 2 + hist[k, 1] ** 2 + hist[k, 2] ** 2
    return 8.0 / 15.0 * p[0] * a * ov * ov + 0.5 * 8.0 * p[1] * a * s2


@register
class HertzMindlin(Law):
    """Hertz-Mindlin with restitution-derived damping, one material pair.

    Parameters
    ----------
    young : float or (float, float)
        Young's modulus [Pa] of each side, ``(body, wall)`` for a sphere-wall law: a
        plane may be given its own. ``math.inf`` on one side makes that side rigid
        (its ``1/E`` terms in ``E*`` and ``G*`` vanish); both sides rigid is an error.
    poisson : float or (float, float)
        Poisson's ratio [-] in [0, 0.5) of each side (a rigid side's does not count).
    restitution : float
        Coefficient of restitution in (0, 1].
    mu : float
        Coulomb friction coefficient [-].
    overlap_ref : float
        Overlap, as a fraction of the radius, at which the critical time step takes its
        stiffness (default 0.05).
    rolling : Rolling or dict, optional
        Rolling (and twisting) resistance (:class:`~dem.contact.rolling.Rolling`).
    limit_damping : bool, optional
        Clip the normal force at zero, so that the normal dashpot never pulls (LAMMPS'
        ``limit_damping``); ``beta`` is then the one whose collision rebounds with
        ``restitution`` exactly (:mod:`dem.contact.restitution`), at any speed.

    Examples
    --------
    A steel sphere on a rigid plane: ``E* = E / (1 - nu^2)``.

    >>> law = HertzMindlin(young=(2.1e11, math.inf), poisson=0.3, restitution=1.0, mu=0.0)
    >>> round(law.e_star / (2.1e11 / (1 - 0.3**2)), 12)
    1.0
    """

    name = "hertz_mindlin"
    code = 1
    n_params = 5
    n_hist = N_HIST
    force = staticmethod(law_hertz_mindlin)
    stiffness = staticmethod(stiffness_hertz_mindlin)
    energy = staticmethod(energy_hertz_mindlin)
    normal_stiffness = staticmethod(normal_stiffness_hertz_mindlin)

    def __init__(self, young, poisson, restitution, mu, overlap_ref=0.05, rolling=None,
                 limit_damping=False):
        e1, e2 = np.broadcast_to(np.asarray(young, dtype=float), (2,))
        n1, n2 = np.broadcast_to(np.asarray(poisson, dtype=float), (2,))
        for v in (e1, e2):
            if not v > 0.0:  # NaN fails too; inf is a rigid side
                raise ValueError(f"young must be > 0 (inf: a rigid side), got {v}")
        if math.isinf(e1) and math.isinf(e2):
            raise ValueError("young: at most one side may be rigid (inf), got inf on both")
        for v in (n1, n2):
            if not (0.0 <= v < 0.5):
                raise ValueError(f"poisson must be in [0, 0.5), got {v}")
        e = float(restitution)
        if not (0.0 < e <= 1.0):
            raise ValueError(f"restitution must be in (0, 1], got {restitution}")
        self.mu = check_number("mu", mu)
        self.e_star = float(1.0 / ((1 - n1**2) / e1 + (1 - n2**2) / e2))
        self.g_star = float(1.0 / (2 * (2 - n1) * (1 + n1) / e1 + 2 * (2 - n2) * (1 + n2) / e2))
        self.limit_damping = bool(limit_damping)
        self.beta = (-clipped_damping("hertz", e) / math.sqrt(5.0) if self.limit_damping
                     else math.log(e) / math.sqrt(math.log(e) ** 2 + math.pi**2))
        self.overlap_ref = check_number("overlap_ref", overlap_ref, strict=True)
        self._args = {"young": [float(e1), float(e2)], "poisson": [float(n1), float(n2)],
                      "restitution": e, "mu": self.mu, "overlap_ref": self.overlap_ref}
        if self.limit_damping:
            self._args["limit_damping"] = True
        self._set_rolling(rolling)

    def row(self):
        return np.array([self.e_star, self.g_star, self.beta, self.mu,
                         float(self.limit_damping)])

    def critical_stiffness(self, r_ref):
        a = math.sqrt(r_ref * self.overlap_ref * r_ref)
        return max(2.0 * self.e_star * a, 8.0 * self.g_star * a)

    def damping_ratios(self, m_eff, rot):
        # c sqrt(S m) over 2 sqrt(S m): the same ratio at every overlap
        zeta = -math.sqrt(5.0 / 6.0) * self.beta
        return zeta, zeta * math.sqrt(rot)

    # ------------------------------------------------------------------ files
    @classmethod
    def keys(cls):
        from ...io.schema import POSITIVE, REQUIRED, Key, Range

        return {
            "young": Key("float", "Pa", default=REQUIRED, range=POSITIVE,
                         doc="Young's modulus."),
            "poisson": Key("float", default=REQUIRED, range=Range(0.0, 0.5, hi_closed=False),
                           doc="Poisson's ratio."),
        }

    @classmethod
    def wall_keys(cls):
        from ...io.schema import POSITIVE, Key, Range

        return {
            "young": Key("float", "Pa", range=POSITIVE,
                         doc="the wall's Young's modulus (the particles keep theirs; a "
                             "rigid wall: rigid = true)."),
            "poisson": Key("float", range=Range(0.0, 0.5, hi_closed=False),
                           doc="the wall's Poisson's ratio."),
            "rigid": Key("bool", default=False,
                         doc="true makes the wall rigid (E* and G* from the particles' "
                             "side alone); excludes young."),
        }

    @classmethod
    def arguments(cls, table, wall):
        """The particles keep the table's ``young`` and ``poisson``; a wall's own are
        its side of the pair (``rigid``: an infinite modulus)."""
        c = {**table, **wall}
        wall_young = math.inf if wall.get("rigid") else wall.get("young", table["young"])
        return {"young": [table["young"], wall_young],
                "poisson": [table["poisson"], wall.get("poisson", table["poisson"])],
                "restitution": c["restitution"], "mu": c["mu"]}

