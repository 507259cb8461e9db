"""The damping that makes a binary collision rebound with a given restitution when the
normal force is clipped at zero (``limit_damping``: the dashpot never pulls).

Without the clip the linear spring-dashpot rebounds with ``e = exp(-pi zeta / sqrt(1 -
zeta^2))`` exactly. With it the contact ends where the force ``k x + c x'`` first falls to
zero, before the overlap does, and the rebound is faster: the damping ratio for a
target ``e`` is larger. Both laws reduce to one dimensionless equation of the overlap
``x`` (``x(0) = 0``, ``x'(0) = 1``):

* linear: ``x'' = -(x + 2 zeta x')``;
* Hertz-Mindlin with the LIGGGHTS/YADE dashpot: ``x'' = -(x^(3/2) + C x^(1/4) x')`` with
  ``C = -sqrt(5) beta`` (the overlap in units of ``(v^2 / k)^(2/5)``, ``k = 4/3 E*
  sqrt(R*) / m*``), so that ``e`` depends on ``beta`` alone, at every impact speed;

each clipped: once the force reaches zero on the way out it stays zero (the overlap
falls at a constant speed, the force with it) and the rebound speed is ``-x'`` there.
:func:`clipped_damping` inverts ``e`` by Brent's method on a tightly integrated rebound.
"""

import functools
import math


def _force(kind, damping, x, v):
    if kind == "linear":
        return x + 2.0 * damping * v
    x = max(x, 0.0)
    return x**1.5 + damping * x**0.25 * v


def clipped_rebound(kind, damping):
    """The restitution [-] of the clipped dimensionless collision: ``kind`` "linear"
    (``damping`` the ratio zeta) or "hertz" (``damping`` = C = -sqrt(5) beta)."""
    if damping == 0.0:
        return 1.0
    from scipy.integrate import solve_ivp  # here: scipy.integrate costs 0.8 s to import

    def rhs(t, y):
        return [y[1], -_force(kind, damping, y[0], y[1])]

    def released(t, y):  # the force falls to zero on the way out, or the overlap does
        return _force(kind, damping, y[0], y[1]) if y[1] < 0.0 else 1.0

    released.terminal = True
    released.direction = -1
    sol = solve_ivp(rhs, (0.0, 100.0), [1e-12, 1.0], events=released, rtol=1e-11,
                    atol=1e-13, max_step=0.01)
    if not sol.t_events[0].size:
        raise RuntimeError(f"no rebound for {kind} damping {damping}")
    return float(-sol.y_events[0][0][1])


@functools.lru_cache(maxsize=256)
def clipped_damping(kind, e):
    """The damping of the clipped collision that rebounds with restitution ``e`` in (0,
    1]: the ratio zeta ("linear") or C ("hertz"; ``beta = -C / sqrt(5)``)."""
    e = float(e)
    if not 0.0 < e <= 1.0:
        raise ValueError(f"restitution must be in (0, 1], got {e}")
    if e == 1.0:
        return 0.0
    hi = 0.1
    while clipped_rebound(kind, hi) > e:
        hi *= 2.0
        if hi > 1e6:
            raise ValueError(f"restitution {e} is below what a clipped dashpot can give")
    from scipy.optimize import brentq

    return brentq(lambda c: clipped_rebound(kind, c) - e, 0.0, hi, xtol=1e-13, rtol=1e-12)


def unclipped_ratio(e):
    """The linear dashpot's damping ratio for restitution ``e`` without the clip."""
    return -math.log(e) / math.sqrt(math.pi**2 + math.log(e) ** 2)


__all__ = ["clipped_damping", "clipped_rebound", "unclipped_ratio"]
