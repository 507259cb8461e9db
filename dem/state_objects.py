"""Time-dependent state other than the bodies' motion, advanced by RK2 (paper eq 21).

A :class:`StateObject` owns some state ``y`` with a right-hand side ``dy/dt = g(y, t)``
and is advanced every step, after the bodies, by Heun's second-order Runge-Kutta:
``k1 = g(y, t)``, ``k2 = g(y + dt k1, t + dt)``, ``y += dt (k1 + k2) / 2``.
"""

from typing import Protocol

import numpy as np


class StateObject(Protocol):
    """What the simulation needs from a time-dependent state."""

    def advance(self, sim, t, dt):
        """Advance the state from time ``t`` [s] to ``t + dt``."""


class RK2:
    """Mixin: Heun's RK2 over ``get()``/``set(y)`` with ``rhs(y, t)``."""

    def advance(self, sim, t, dt):
        y = self.get(sim)
        k1 = self.rhs(y, t)
        k2 = self.rhs(y + dt * k1, t + dt)
        self.set(sim, y + 0.5 * dt * (k1 + k2))


class SphereRadius(RK2):
    """Radii of chosen spheres driven by ``dR/dt = g(R, t)`` [m/s].

    Mass and inertia follow the radius at constant density.

    Parameters
    ----------
    ids : array_like of int
        Sphere body indices.
    rate : callable
        ``rate(R, t) -> dR/dt``, vectorised over ``R`` (m,) [m], ``t`` [s].

    Examples
    --------
    >>> import dem
    >>> grow = SphereRadius([0], lambda r, t: np.ones_like(r))
    >>> grow.rhs(np.array([0.1]), 0.0).tolist()
    [1.0]
    """

    def __init__(self, ids, rate):
        self.ids = np.atleast_1d(np.asarray(ids, dtype=np.int64))
        self.rate = rate

    def get(self, sim):
        return sim.bodies.radius[self.ids].copy()

    def set(self, sim, y):
        if np.any(y <= 0.0):
            raise ValueError("SphereRadius drove a radius to zero or below")
        sim.bodies.set_radius(self.ids, y)

    def rhs(self, y, t):
        return np.asarray(self.rate(y, t), dtype=np.float64) * np.ones_like(y)
