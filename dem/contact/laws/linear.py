"""The linear spring-dashpot law (``law = "linear"``): the paper's elastic and
viscoelastic laws (eqs 16-20), with LAMMPS/LIGGGHTS restitution damping."""

import math

import numpy as np

from ..._jit import kernel
from ..restitution import clipped_damping
from .base import Law, check_number, register
from .tangential import N_HIST, tangential


@kernel(inline=True)
def law_linear(ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff, p, a, b, hist, k, dt):
    """Linear spring-dashpot normal force, tangential history spring, Coulomb cap.

    ``p[a, b] = (kn [N/m], kt [N/m], gamma_n [N s/m], gamma_t [N s/m], zeta [-], mu [-],
    limit [-])`` for materials ``a``, ``b``; ``limit`` 1 clips the normal force at zero
    (``limit_damping``).
    The normal dashpot is ``gamma_n + 2 zeta sqrt(kn m_eff)``: a fixed coefficient
    (paper eq 19) plus a damping ratio (restitution-based, as in LAMMPS/LIGGGHTS).
    The paper's elastic law (eqs 16-18) is this law with both dashpots zero. The
    tangential spring ``kt`` and dashpot ``gamma_t`` act in parallel, in series with
    a Coulomb slider of limit ``mu max(fn, 0)`` (:func:`tangential`): a contact the
    normal dashpot pulls together carries no friction.
    """
    kn, kt, gn, gt = p[a, b, 0], p[a, b, 1], p[a, b, 2], p[a, b, 3]
    zeta, mu = p[a, b, 4], p[a, b, 5]
    cn = gn + 2.0 * zeta * math.sqrt(kn * m_eff)
    vn = vx * nx + vy * ny + vz * nz
    fn = kn * ov - cn * vn  # approaching (vn < 0) adds repulsion
    if p[a, b, 6] > 0.0 and fn < 0.0:  # limit_damping: the dashpot never pulls
        fn = 0.0
    tvx, tvy, tvz = vx - vn * nx, vy - vn * ny, vz - vn * nz
    # tangential spring: rotate into the current tangent plane, then grow
    ftx, fty, ftz = tangential(hist, k, nx, ny, nz, tvx, tvy, tvz, kt, gt, mu * max(fn, 0.0),
                               dt)
    return fn * nx + ftx, fn * ny + fty, fn * nz + ftz


@kernel(inline=True)
def normal_stiffness_linear(ov, r_eff, p, a, b):
    """Normal tangent stiffness [N/m] of a contact of materials ``a``, ``b``."""
    return p[a, b, 0]


@kernel
def stiffness_linear(ov, r_eff, p):
    return p[0], p[1]


@kernel
def energy_linear(ov, r_eff, p, hist, k):
    s2 = hist[k, 0] ** 2 + hist[k, 1] ** 2 + hist[k, 2] ** 2
    return 0.5 * p[0] * ov * ov + 0.5 * p[1] * s2


@register
class LinearSpring(Law):
    """Linear spring(-dashpot) with tangential history and Coulomb friction.

    Parameters
    ----------
    kn, kt : float
        Normal and tangential spring stiffness [N/m] (>= 0, kn > 0).
    mu : float
        Coulomb friction coefficient [-] (>= 0).
    gamma_n, gamma_t : float, optional
        Normal and tangential dashpot coefficients [N s/m] (paper eqs 19-20).
    restitution : float, optional
        Normal coefficient of restitution in (0, 1]; adds the damping ratio
        ``zeta = -ln e / sqrt(pi^2 + ln^2 e)`` so that a binary collision rebounds
        with ``e`` whatever the masses (LAMMPS/LIGGGHTS convention).
    rolling : Rolling or dict, optional
        Rolling (and twisting) resistance (:class:`~dem.contact.rolling.Rolling`).
    limit_damping : bool, optional
        Clip the normal force at zero, so that the normal dashpot never pulls (LAMMPS'
        ``limit_damping``); the damping ratio is then the one that rebounds with
        ``restitution`` (:mod:`dem.contact.restitution`; a ``gamma_n`` adds to it as
        given).

    Examples
    --------
    >>> law = LinearSpring(kn=1e5, kt=5e4, mu=0.3, restitution=0.5)
    >>> round(law.zeta, 4)
    0.2155
    """

    name = "linear"
    code = 0
    n_params = 7
    n_hist = N_HIST
    force = staticmethod(law_linear)
    stiffness = staticmethod(stiffness_linear)
    energy = staticmethod(energy_linear)
    normal_stiffness = staticmethod(normal_stiffness_linear)

    def __init__(self, kn, kt=0.0, mu=0.0, gamma_n=0.0, gamma_t=0.0, restitution=1.0,
                 rolling=None, limit_damping=False):
        self.kn = check_number("kn", kn, strict=True)
        self.kt = check_number("kt", kt)
        self.mu = check_number("mu", mu)
        self.gamma_n = check_number("gamma_n", gamma_n)
        self.gamma_t = check_number("gamma_t", gamma_t)
        e = float(restitution)
        if not (0.0 < e <= 1.0):
            raise ValueError(f"restitution must be in (0, 1], got {restitution}")
        self.restitution = e
        self.limit_damping = bool(limit_damping)
        self.zeta = (clipped_damping("linear", e) if self.limit_damping
                     else -math.log(e) / math.sqrt(math.pi**2 + math.log(e) ** 2))
        self._args = {"kn": self.kn, "kt": self.kt, "mu": self.mu, "gamma_n": self.gamma_n,
                      "gamma_t": self.gamma_t, "restitution": e}
        if self.limit_damping:
            self._args["limit_damping"] = True
        self._set_rolling(rolling)

    def row(self):
        return np.array([self.kn, self.kt, self.gamma_n, self.gamma_t, self.zeta, self.mu,
                         float(self.limit_damping)])

    def critical_stiffness(self, r_ref):
        return max(self.kn, self.kt)

    def damping_ratios(self, m_eff, rot):
        zeta_n = self.zeta + self.gamma_n / (2.0 * math.sqrt(self.kn * m_eff))
        zeta_t = (self.gamma_t * math.sqrt(rot) / (2.0 * math.sqrt(self.kt * m_eff))
                  if self.kt > 0.0 else 0.0)
        return zeta_n, zeta_t

    # ------------------------------------------------------------------ files
    @classmethod
    def keys(cls):
        from ...io.schema import NONNEGATIVE, POSITIVE, REQUIRED, Key

        return {
            "kn": Key("float", "N/m", default=REQUIRED, range=POSITIVE,
                      doc="Normal stiffness."),
            "kt": Key("float", "N/m", default=0.0, range=NONNEGATIVE,
                      doc="Tangential stiffness."),
            "gamma_n": Key("float", "N s/m", default=0.0, range=NONNEGATIVE,
                           doc="Normal dashpot coefficient."),
            "gamma_t": Key("float", "N s/m", default=0.0, range=NONNEGATIVE,
                           doc="Tangential dashpot coefficient."),
        }

    @classmethod
    def wall_keys(cls):
        from ...io.schema import NONNEGATIVE, POSITIVE, Key

        return {
            "kn": Key("float", "N/m", range=POSITIVE, doc="the wall's normal stiffness."),
            "kt": Key("float", "N/m", range=NONNEGATIVE,
                      doc="the wall's tangential stiffness."),
            "gamma_n": Key("float", "N s/m", range=NONNEGATIVE,
                           doc="the wall's normal dashpot."),
            "gamma_t": Key("float", "N s/m", range=NONNEGATIVE,
                           doc="the wall's tangential dashpot."),
        }

    @classmethod
    def arguments(cls, table, wall):
        """``kn`` and ``mu``, and those of ``kt``, ``gamma_n``, ``gamma_t`` and
        ``restitution`` the table has (a problem file's ``[micro]`` has no dashpots)."""
        c = {**table, **wall}
        return {key: c[key] for key in ("kn", "kt", "mu", "gamma_n", "gamma_t", "restitution")
                if key in c or key in ("kn", "mu")}


def Elastic(kn, kt, mu):
    """The paper's elastic law (eqs 16-18): linear springs, shear history, Coulomb cap."""
    return LinearSpring(kn=kn, kt=kt, mu=mu)


def Viscoelastic(kn, kt, gamma_n, gamma_t, mu):
    """The paper's viscoelastic law (eqs 19-20): the elastic law plus dashpots [N s/m]."""
    return LinearSpring(kn=kn, kt=kt, mu=mu, gamma_n=gamma_n, gamma_t=gamma_t)
