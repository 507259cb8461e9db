"""Contact laws: kernel functions and the parameter objects that feed them.

A law kernel takes one contact's summary (overlap ``ov`` > 0, unit normal ``n`` from
the home body i to the neighbour j), the velocity ``v`` of j relative to i at the contact
point, the contact's effective radius and mass, the parameter table ``p`` with the
materials ``a``, ``b`` of the pair (it reads ``p[a, b, :]``: no array view is made in the
hot loop) and the contact's history row ``hist[k]``, and returns the force on j (i gets
the opposite). The history row holds the tangential spring (elongation vector, 3
components, [m]); it is updated in place and reset by the caller when the contact
opens. Vectors are passed as three scalars: 2D contacts pass ``z = 0``.

Tangential history is a time-dependent state: its rate is the tangential relative
velocity. It is advanced with the relative velocity at mid-step (the velocity Verlet
half-step velocity), i.e. the midpoint rule, second order in ``dt``; before each update
it is projected onto the current tangent plane (the contact frame rotates).

Every law has three kernels: ``force``, ``stiffness`` (normal and tangential tangent
stiffness [N/m], for the critical time step and the tangent operator) and ``energy``
(elastic energy stored in the contact [J]).
"""

import math

import numpy as np

from .._jit import kernel
from .rolling import N_HIST as N_HIST_ROLLING
from .restitution import clipped_damping
from .rolling import as_rolling

N_HIST = 3  # tangential spring vector


# --------------------------------------------------------------------------- tangential
@kernel(inline=True)
def tangential(hist, k, nx, ny, nz, tvx, tvy, tvz, kt, ct, cap, dt):
    """Tangential force of a spring ``kt`` [N/m] and a dashpot ``ct`` [N s/m] in
    parallel, in series with a Coulomb slider of limit ``cap`` [N]; updates the
    spring ``hist[k]`` [m] (rotated into the current tangent plane first).

    Sticking, the pair stretches with the tangential velocity ``tv`` [m/s]:
    ``f = -kt s - ct tv``. Sliding (the trial force above ``cap``), the pair carries
    exactly the capped force, and its own stretch rate is what the dashpot then
    needs: ``kt s_new + ct (s_new - s_old) / dt = -f``, so the spring moves from its
    old length towards ``cap / kt`` along the force, never against it. With no
    dashpot that is the usual reset ``s = -f / kt``. With ``dt`` = 0 (a pass that
    evaluates forces without advancing time) the spring keeps its length, the limit
    of that rule as ``dt`` goes to 0.
    """
    sn = hist[k, 0] * nx + hist[k, 1] * ny + hist[k, 2] * nz
    rx, ry, rz = hist[k, 0] - sn * nx, hist[k, 1] - sn * ny, hist[k, 2] - sn * nz
    sx, sy, sz = rx + tvx * dt, ry + tvy * dt, rz + tvz * dt
    ftx, fty, ftz = -kt * sx - ct * tvx, -kt * sy - ct * tvy, -kt * sz - ct * tvz
    ft2 = ftx * ftx + fty * fty + ftz * ftz
    if ft2 > cap * cap:  # sliding
        scale = cap / math.sqrt(ft2)
        ftx, fty, ftz = ftx * scale, fty * scale, ftz * scale
        # dt = 0 evaluates without advancing (a priming pass): the spring stays
        w = ct / dt if dt > 0.0 else 0.0
        if dt > 0.0 and kt + w > 0.0:
            sx = (w * rx - ftx) / (kt + w)
            sy = (w * ry - fty) / (kt + w)
            sz = (w * rz - ftz) / (kt + w)
    hist[k, 0], hist[k, 1], hist[k, 2] = sx, sy, sz
    return ftx, fty, ftz


# --------------------------------------------------------------------------- linear
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


@kernel
def stiffness_linear(ov, r_eff, p):
    return p[0], p[1]


@kernel
def energy_linear(ov, r_eff, p, hist, k):
    s2 = hist[k, 0] ** 2 + hist[k, 1] ** 2 + hist[k, 2] ** 2
    return 0.5 * p[0] * ov * ov + 0.5 * p[1] * s2


# --------------------------------------------------------------------------- Hertz-Mindlin
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


@kernel
def stiffness_hertz_mindlin(ov, r_eff, p):
    a = math.sqrt(r_eff * max(ov, 0.0))
    return 2.0 * p[0] * a, 8.0 * p[1] * a


@kernel
def energy_hertz_mindlin(ov, r_eff, p, hist, k):
    a = math.sqrt(r_eff * ov)
    s2 = hist[k, 0] ** 2 + hist[k, 1] ** 2 + hist[k, 2] ** 2
    return 8.0 / 15.0 * p[0] * a * ov * ov + 0.5 * 8.0 * p[1] * a * s2


# --------------------------------------------------------------------------- batches (observers)
@kernel(inline=True)
def apply_law(code, ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff, p, a, b, hist, k, dt):
    """Force on j from the law with this ``code`` (a constant: other branches fold away)."""
    if code == 0:
        return law_linear(ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff, p, a, b, hist, k, dt)
    return law_hertz_mindlin(ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff, p, a, b, hist, k, dt)


@kernel(inline=True)
def normal_stiffness(code, ov, r_eff, p, a, b):
    """The law's normal tangent stiffness [N/m] of a contact (a compile-time ``code``)."""
    if code == 0:
        return p[a, b, 0]
    return 2.0 * p[a, b, 0] * math.sqrt(r_eff * ov)


@kernel(inline=True)
def row_size(code):
    """Length of the law's own parameter row: the rolling parameters follow it."""
    return 7 if code == 0 else 5


@kernel
def contact_stiffness(code, ov, r_eff, p, ma, mb, kn_out, kt_out):
    """Tangent stiffnesses [N/m] of many contacts of law ``code`` (observers, not steps)."""
    for c in range(ov.shape[0]):
        if code == 0:
            kn, kt = stiffness_linear(ov[c], r_eff[c], p[ma[c], mb[c]])
        else:
            kn, kt = stiffness_hertz_mindlin(ov[c], r_eff[c], p[ma[c], mb[c]])
        kn_out[c] = kn
        kt_out[c] = kt


@kernel
def contact_energy(code, ov, r_eff, p, ma, mb, hist, rows):
    """Elastic energy [J] of the contacts ``rows`` (with ``ov[c]`` > 0) of law ``code``."""
    e = 0.0
    for c in range(rows.shape[0]):
        k = rows[c]
        if code == 0:
            e += energy_linear(ov[k], r_eff[k], p[ma[k], mb[k]], hist, k)
        else:
            e += energy_hertz_mindlin(ov[k], r_eff[k], p[ma[k], mb[k]], hist, k)
    return e


# --------------------------------------------------------------------------- parameter objects
def _check(name, value, lo=0.0, strict=False):
    value = float(value)
    ok = math.isfinite(value) and (value > lo if strict else value >= lo)
    if not ok:
        rel = ">" if strict else ">="
        raise ValueError(f"{name} must be finite and {rel} {lo}, got {value}")
    return value


class Law:
    """Base of the law parameter objects: names its kernels and its parameter row."""

    code = -1  # selects the force kernel inside the compiled time-step loop
    force = None
    stiffness = None
    energy = None
    #: rolling resistance (:class:`~dem.contact.rolling.Rolling`), or None
    rolling = None

    def _set_rolling(self, rolling):
        self.rolling = as_rolling(rolling)
        if self.rolling is not None:
            self._args["rolling"] = self.rolling.spec()

    @property
    def n_hist(self):
        """Columns of a contact's history row: the tangential spring, and the rolling
        state when the law has rolling resistance."""
        return N_HIST if self.rolling is None else N_HIST_ROLLING

    def row(self):
        """The pair-parameter row the kernels read (float64 array)."""
        raise NotImplementedError

    def full_row(self, rolling):
        """:meth:`row`, followed by the rolling parameters when ``rolling`` (zeros for a
        law without rolling resistance in a scene where others have it)."""
        if not rolling:
            return self.row()
        extra = self.rolling.row() if self.rolling is not None else [0.0] * 5
        return np.concatenate([self.row(), extra])

    def critical_stiffness(self, r_ref):
        """Largest normal stiffness [N/m] a contact of reference radius ``r_ref`` reaches."""
        raise NotImplementedError

    def damping_ratios(self, m_eff, rot):
        """Damping ratios [-] of a contact's normal and tangential modes, ``(zeta_n,
        zeta_t)``.

        ``m_eff`` [kg] is the pair's effective mass, ``rot`` the rotational coupling of
        the tangential mode (``1 + m r^2 / I``): it scales that mode's stiffness and
        dashpot alike, so its ratio by ``sqrt(rot)``.
        """
        raise NotImplementedError

    def damping_ratio(self, m_eff, rot):
        """Largest damping ratio [-] of a contact's normal and tangential modes."""
        return max(self.damping_ratios(m_eff, rot))

    def spec(self):
        """The law as plain data: ``{"law": class name, **constructor arguments}``;
        :func:`law_from_spec` rebuilds it (files store laws this way, never as code)."""
        return {"law": type(self).__name__, **self._args}

    def with_friction(self, mu):
        """A copy of the law with friction coefficient ``mu``."""
        return law_from_spec({**self.spec(), "mu": float(mu)})


def law_from_spec(spec):
    """Rebuild a law from :meth:`Law.spec` data; unknown names or arguments raise."""
    spec = dict(spec)
    name = spec.pop("law", None)
    kinds = {"LinearSpring": LinearSpring, "HertzMindlin": HertzMindlin}
    if name not in kinds:
        raise ValueError(f"unknown contact law {name!r}; known: {', '.join(kinds)}")
    try:
        return kinds[name](**spec)
    except TypeError as err:
        raise ValueError(f"contact law {name}: {err}") from None


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

    code = 0
    force = staticmethod(law_linear)
    stiffness = staticmethod(stiffness_linear)
    energy = staticmethod(energy_linear)

    def __init__(self, kn, kt=0.0, mu=0.0, gamma_n=0.0, gamma_t=0.0, restitution=1.0,
                 rolling=None, limit_damping=False):
        self.kn = _check("kn", kn, strict=True)
        self.kt = _check("kt", kt)
        self.mu = _check("mu", mu)
        self.gamma_n = _check("gamma_n", gamma_n)
        self.gamma_t = _check("gamma_t", gamma_t)
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


def Elastic(kn, kt, mu):
    """The paper's elastic law (eqs 16-18): linear springs, shear history, Coulomb cap."""
    return LinearSpring(kn=kn, kt=kt, mu=mu)


def Viscoelastic(kn, kt, gamma_n, gamma_t, mu):
    """The paper's viscoelastic law (eqs 19-20): the elastic law plus dashpots [N s/m]."""
    return LinearSpring(kn=kn, kt=kt, mu=mu, gamma_n=gamma_n, gamma_t=gamma_t)


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

    code = 1
    force = staticmethod(law_hertz_mindlin)
    stiffness = staticmethod(stiffness_hertz_mindlin)
    energy = staticmethod(energy_hertz_mindlin)

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
        self.mu = _check("mu", mu)
        self.e_star = float(1.0 / ((1 - n1**2) / e1 + (1 - n2**2) / e2))
        self.g_star = float(1.0 / (2 * (2 - n1) * (1 + n1) / e1 + 2 * (2 - n2) * (1 + n2) / e2))
        self.limit_damping = bool(limit_damping)
        self.beta = (-clipped_damping("hertz", e) / math.sqrt(5.0) if self.limit_damping
                     else math.log(e) / math.sqrt(math.log(e) ** 2 + math.pi**2))
        self.overlap_ref = _check("overlap_ref", overlap_ref, strict=True)
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
