"""Time-dependent state other than the bodies' motion, advanced by RK2 (paper eq 21).

A :class:`StateObject` owns some state ``y`` with a right-hand side ``dy/dt = g(y, t)``
and is advanced every step, after the bodies, by Heun's second-order Runge-Kutta:
``k1 = g(y, t)``, ``k2 = g(y + dt k1, t + dt)``, ``y += dt (k1 + k2) / 2``.
"""

from typing import Protocol

import numpy as np

from .shapes import Shape


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


class ShapeScale(RK2):
    """Scale factors of level-set shapes driven by ``ds/dt = g(s, t)`` [1/s].

    A growing box, a swelling polygon: the shape-table rows ``rows`` are scaled about
    their centres by ``s`` (1 at the start); every body of those rows follows, with its
    bounding radius ``∝ s``, mass ``∝ s^d`` and inertia ``∝ s^(d+2)`` at constant density.
    Give a body its own row (one :meth:`Bodies.add_shapes` call) to grow it alone.

    Parameters
    ----------
    rows : array_like of int
        Rows of ``bodies.table`` (``bodies.shape`` of the bodies to grow).
    rate : callable
        ``rate(s, t) -> ds/dt``, vectorised over ``s`` (m,) [-], ``t`` [s].
    """

    def __init__(self, rows, rate):
        self.rows = np.atleast_1d(np.asarray(rows, dtype=np.int64))
        self.rate = rate
        self._base = None

    def _bind(self, sim):
        b = sim.bodies
        if (np.any(b.table.kind[self.rows] == Shape.COMPOUND)
                or np.any(np.isin(self.rows, b.table.part_row))):
            raise ValueError("ShapeScale cannot grow a compound (dem.Compound) or its "
                             "parts: scale the parts' shapes before building the bodies")
        ids = np.flatnonzero(np.isin(b.shape, self.rows))
        s = b.table.scale[b.shape[ids]]
        self._base = (ids, b.radius[ids] / s, b.mass[ids] / s ** b.dim,
                      b.inertia[ids] / (s ** (b.dim + 2))[:, None])

    def get(self, sim):
        if self._base is None:
            self._bind(sim)
        return sim.bodies.table.scale[self.rows].copy()

    def set(self, sim, y):
        if np.any(y <= 0.0) or not np.all(np.isfinite(y)):
            raise ValueError("ShapeScale drove a scale factor to zero, below or to NaN")
        b = sim.bodies
        b.table.scale[self.rows] = y
        ids, r0, m0, i0 = self._base
        s = b.table.scale[b.shape[ids]]
        b.radius[ids] = r0 * s
        free = ~b.is_fixed[ids]
        b.mass[ids[free]] = (m0 * s ** b.dim)[free]
        b.inertia[ids[free]] = (i0 * (s ** (b.dim + 2))[:, None])[free]

    def rhs(self, y, t):
        return np.asarray(self.rate(y, t), dtype=np.float64) * np.ones_like(y)
