"""Rolling and twisting resistance: an elastic-plastic spring-dashpot moment that any
contact law of spheres and disks carries as an add-on.

The model is the EPSD model of Ai, Chen, Rotter and Ooi (2011, "Assessment of rolling
resistance models in discrete element simulations", Powder Technology 206; LIGGGHTS'
``rolling_friction epsd``, YADE's rolling moment of ``CohFrictPhys``). Per contact, with
``w = w_home - w_other`` the relative angular velocity of the body that receives the
moment, ``n`` the contact normal and ``R`` the rolling radius (the contact's effective
radius: ``r_i r_j / (r_i + r_j)``, the sphere's radius on a wall):

* rolling: the spring moment ``M`` (tangent to the contact) grows by
  ``-k_r (w - (w.n) n) dt`` with ``k_r = k_roll k_n R^2`` (``k_n`` the law's current
  normal stiffness; LIGGGHTS' ``k_roll = 2.25 mu_roll^2``, the default). A dashpot
  ``-C_r (w - (w.n) n)`` acts beside it, ``C_r = 2 eta_roll sqrt(I_r k_r)`` with
  ``I_r`` the pair's moment of inertia about the contact point,
  ``1 / (1 / (I_i + m_i r_i^2) + 1 / (I_j + m_j r_j^2))``. The pair is in series with a
  slider: the moment applied, spring plus dashpot, is capped at
  ``mu_roll R max(f_n, 0)``, so a body rolling on (full mobilisation) feels exactly
  that moment. Ai et al.'s model caps the spring alone and switches the dashpot off
  at the cap, which lets a fast-turning contact's dashpot push the moment far past
  the cap in its first steps; the series slider is the scheme of our tangential
  spring (:func:`dem.contact.laws.tangential`);
* twisting (3D, optional): the same about ``n`` with ``k_w = k_twist k_n R^2``, the
  dashpot ``2 eta_roll sqrt(I_w k_w)``, ``I_w = 1 / (1 / I_i + 1 / I_j)``, and the cap
  ``mu_twist R max(f_n, 0)``.

The moments live in the last seven columns of the contact's history row, after the
law's own (however many the law has): the rolling spring (3 components [N m]; 2D uses
the first, about z), the twisting spring [N m], and the moment the contact applied at
the last force evaluation (3 components [N m]; the homogenised couple stress reads it).
A 2D contact has only rolling, about z. The columns are counted from the row's end
(:data:`COL_ROLL` and the others are negative), so the kernels need not know the law.
"""

import math

import numpy as np

from .._jit import kernel

#: history columns rolling resistance adds after the law's own: the rolling spring (3),
#: the twisting spring (1), the moment applied (3)
N_HIST = 7
#: first column of the rolling spring, of the twisting spring, of the applied moment,
#: counted from the end of the history row
COL_ROLL, COL_TWIST, COL_MOMENT = -7, -4, -3
#: rolling parameters per material pair, appended to the law's row:
#: (mu_roll [-], k_roll [-], eta_roll [-], mu_twist [-], k_twist [-])
N_PARAM = 5


@kernel(inline=True)
def _slider(tx, ty, tz, limit):
    """The trial moment ``t`` [N m] of a spring beside a dashpot, in series with a slider
    of limit ``limit`` [N m]: the moment applied, and whether the slider slips."""
    t2 = tx * tx + ty * ty + tz * tz
    if t2 <= limit * limit:
        return tx, ty, tz, False
    f = limit / math.sqrt(t2)
    tx, ty, tz = tx * f, ty * f, tz * f
    return tx, ty, tz, True


@kernel(inline=True)
def _spring_after_slip(m, t, k, c, dt):
    """The spring's moment after a slip: the spring ``k`` [N m/rad] (moment ``m``
    before the step) and its dashpot ``c`` [N m s/rad] carry exactly the capped moment
    ``t``, the pair turning at the rate the dashpot then needs,
    ``M_new + c (M_new - m) / (k dt) = t``: the spring moves from ``m`` towards the cap
    along the moment (as the law's tangential spring, :func:`dem.contact.laws.tangential`).
    """
    if not (k > 0.0 and dt > 0.0):
        return m if dt == 0.0 else 0.0
    u = c / (k * dt)
    return (t + u * m) / (1.0 + u)


@kernel(inline=True)
def rolling_moment(dim, hist, k, nx, ny, nz, wx, wy, wz, kn, fn, r_roll, i_roll, i_twist,
                   p, a, b, off, dt):
    """Rolling (and twisting) moment on the home body of contact ``k`` [N m].

    ``w`` [rad/s] is the home body's angular velocity less the other's (2D: ``wz``
    only), ``kn`` [N/m] the law's normal stiffness at this overlap, ``fn`` [N] the normal
    force (compressive positive), ``r_roll`` [m] the rolling radius, ``i_roll`` and
    ``i_twist`` [kg m^2] the pair's moments of inertia for rolling and twisting,
    ``p[a, b, off:off + 5]`` the rolling parameters. Advances the springs in
    ``hist[k]`` by ``dt`` (0: evaluate only) and records the moment applied.
    """
    mu_r, k_r, eta = p[a, b, off], p[a, b, off + 1], p[a, b, off + 2]
    mu_w, k_w = p[a, b, off + 3], p[a, b, off + 4]
    fcap = max(fn, 0.0) * r_roll
    kr = k_r * kn * r_roll * r_roll
    cr = 2.0 * eta * math.sqrt(i_roll * kr)
    if dim == 2:  # rolling about z; no twisting
        m = hist[k, COL_ROLL]
        s = m - kr * wz * dt
        _, _, t, slip = _slider(0.0, 0.0, s - cr * wz, mu_r * fcap)
        hist[k, COL_ROLL] = _spring_after_slip(m, t, kr, cr, dt) if slip else s
        hist[k, COL_MOMENT] = t
        return 0.0, 0.0, t
    wn = wx * nx + wy * ny + wz * nz
    rx, ry, rz = wx - wn * nx, wy - wn * ny, wz - wn * nz
    # the spring turns with the contact: its normal part is dropped, as the law's is
    mx, my, mz = hist[k, COL_ROLL], hist[k, COL_ROLL + 1], hist[k, COL_ROLL + 2]
    sn = mx * nx + my * ny + mz * nz
    mx, my, mz = mx - sn * nx, my - sn * ny, mz - sn * nz
    sx, sy, sz = mx - kr * rx * dt, my - kr * ry * dt, mz - kr * rz * dt
    tx, ty, tz, slip = _slider(sx - cr * rx, sy - cr * ry, sz - cr * rz, mu_r * fcap)
    if slip:
        sx = _spring_after_slip(mx, tx, kr, cr, dt)
        sy = _spring_after_slip(my, ty, kr, cr, dt)
        sz = _spring_after_slip(mz, tz, kr, cr, dt)
    hist[k, COL_ROLL], hist[k, COL_ROLL + 1], hist[k, COL_ROLL + 2] = sx, sy, sz
    kw = k_w * kn * r_roll * r_roll
    cw = 2.0 * eta * math.sqrt(i_twist * kw)
    m = hist[k, COL_TWIST]
    s = m - kw * wn * dt
    _, _, q, slip = _slider(0.0, 0.0, s - cw * wn, mu_w * fcap)
    hist[k, COL_TWIST] = _spring_after_slip(m, q, kw, cw, dt) if slip else s
    tx, ty, tz = tx + q * nx, ty + q * ny, tz + q * nz
    hist[k, COL_MOMENT], hist[k, COL_MOMENT + 1], hist[k, COL_MOMENT + 2] = tx, ty, tz
    return tx, ty, tz


@kernel(inline=True)
def turn_rolling(spin, hist, k):
    """Turn contact k's 3D rolling spring by a deforming cell's step spin."""
    h0, h1, h2 = hist[k, COL_ROLL], hist[k, COL_ROLL + 1], hist[k, COL_ROLL + 2]
    for a in range(3):
        hist[k, COL_ROLL + a] = spin[a, 0] * h0 + spin[a, 1] * h1 + spin[a, 2] * h2


@kernel(inline=True)
def pair_inertia(inv_mass_i, inv_inertia_i, r_i, inv_mass_j, inv_inertia_j, r_j):
    """The rolling and twisting inertias [kg m^2] of a pair from its bodies' inverse mass
    and inverse moment of inertia (0 for a fixed body: it contributes nothing)."""
    # 1 / (I + m r^2) = (1/I)(1/m) / (1/m + r^2 / I), zero for a fixed body
    ui = inv_inertia_i * inv_mass_i / (inv_mass_i + r_i * r_i * inv_inertia_i) \
        if inv_mass_i > 0.0 else 0.0
    uj = inv_inertia_j * inv_mass_j / (inv_mass_j + r_j * r_j * inv_inertia_j) \
        if inv_mass_j > 0.0 else 0.0
    i_roll = 1.0 / (ui + uj) if ui + uj > 0.0 else 0.0
    s = inv_inertia_i + inv_inertia_j
    i_twist = 1.0 / s if s > 0.0 else 0.0
    return i_roll, i_twist


def rolling_energy(q, hist, kn, r_roll):
    """Elastic energy [J] of the rolling and twisting springs of some contacts: their
    rolling parameters ``q`` (c, 5), history rows ``hist`` (c, law's + N_HIST), normal stiffness
    ``kn`` (c,) [N/m] and rolling radius ``r_roll`` (c,) [m]."""
    base = kn * r_roll**2
    kr, kw = q[:, 1] * base, q[:, 4] * base
    m2 = np.sum(hist[:, COL_ROLL:COL_TWIST] ** 2, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.where(kr > 0.0, 0.5 * m2 / kr, 0.0) + np.where(
            kw > 0.0, 0.5 * hist[:, COL_TWIST] ** 2 / kw, 0.0)
    return float(e.sum())


def _number(name, value):
    value = float(value)
    if not (math.isfinite(value) and value >= 0.0):
        raise ValueError(f"{name} must be finite and >= 0, got {value}")
    return value


class Rolling:
    """Rolling (and twisting) resistance for a contact law: ``law(..., rolling=Rolling(...))``.

    Parameters
    ----------
    mu_roll : float
        Rolling-friction coefficient [-]: the rolling moment is capped at
        ``mu_roll R f_n`` (LIGGGHTS' ``coefficientRollingFriction``, YADE's
        ``etaRoll``).
    eta_roll : float, optional
        Damping ratio [-] of the rolling (and twisting) dashpot while the spring holds
        (LIGGGHTS' ``coefficientRollingViscousDamping``; default 0, the ``epsd2`` model).
    k_roll : float, optional
        Rolling stiffness over ``k_n R^2`` [-] (default ``2.25 mu_roll^2``, Ai et al.'s
        and LIGGGHTS' choice).
    mu_twist : float, optional
        Twisting-friction coefficient [-] (3D; default 0: no twisting resistance).
    k_twist : float, optional
        Twisting stiffness over ``k_n R^2`` [-] (default ``2.25 mu_twist^2``).

    Examples
    --------
    >>> round(Rolling(mu_roll=0.1).k_roll, 12)
    0.0225
    """

    def __init__(self, mu_roll, eta_roll=0.0, k_roll=None, mu_twist=0.0, k_twist=None):
        self.mu_roll = _number("mu_roll", mu_roll)
        self.eta_roll = _number("eta_roll", eta_roll)
        self.k_roll = (2.25 * self.mu_roll**2 if k_roll is None
                       else _number("k_roll", k_roll))
        self.mu_twist = _number("mu_twist", mu_twist)
        self.k_twist = (2.25 * self.mu_twist**2 if k_twist is None
                        else _number("k_twist", k_twist))

    def row(self):
        """The five parameters the kernel reads, appended to the law's row."""
        return [self.mu_roll, self.k_roll, self.eta_roll, self.mu_twist, self.k_twist]

    def spec(self):
        return {"mu_roll": self.mu_roll, "eta_roll": self.eta_roll, "k_roll": self.k_roll,
                "mu_twist": self.mu_twist, "k_twist": self.k_twist}

    def stiffness_factor(self, dim):
        """Largest of ``k_roll``, ``k_twist`` over the rotational inertia factor of a
        sphere (0.4) or a disk (0.5): the rolling mode's stiffness is this times
        ``k_n`` [N/m], for the critical time step."""
        k = max(self.k_roll, self.k_twist if dim == 3 else 0.0)
        return k / (0.4 if dim == 3 else 0.5)

    def __repr__(self):
        args = ", ".join(f"{k}={v:g}" for k, v in self.spec().items())
        return f"Rolling({args})"


def as_rolling(value):
    """``None``, a :class:`Rolling` or its spec (a dict) as a Rolling or None."""
    if value is None or isinstance(value, Rolling):
        return value
    if isinstance(value, dict):
        try:
            return Rolling(**value)
        except TypeError as err:
            raise ValueError(f"rolling: {err}") from None
    raise TypeError(f"rolling must be a dem.Rolling or a dict, got {value!r}")
