"""Insertion of particles over time in a region, as LIGGGHTS users pour.

An :class:`Inserter` is a controller of a :class:`dem.Simulation`: every ``every``
steps it adds the spheres (disks in 2D) that are due at ``rate`` particles per second,
at random positions in the box ``lo``..``hi`` where they overlap neither each other nor
any body already there, until ``count`` have been inserted. Particles that find no
room wait for the next insertion. Radii are drawn uniformly in ``radius`` (a number,
or ``(min, max)``); the time step of the simulation was chosen for its first bodies, so
the inserted ones must be no lighter than the lightest of those (refused otherwise).
It is what the ``[insert]`` section of a scene file does (``dem run``).
"""

import numpy as np

from .observers import Periodic
from .shapes import Shape

__all__ = ["Inserter"]

#: random positions tried for each particle due at an insertion
TRIES = 50


class Inserter:
    """Insert ``count`` spheres at ``rate`` [1/s] in the box ``lo``..``hi`` [m].

    Parameters
    ----------
    lo, hi : (d,) array_like
        The region [m]; a particle lies wholly inside it.
    count : int
        Particles to insert in all.
    rate : float
        Particles per second [1/s].
    radius : float or (float, float)
        Radius [m], or the range of uniformly distributed radii.
    density : float
        [kg/m^3] (per unit thickness in 2D).
    velocity : (d,) array_like, optional
        Initial velocity [m/s] (default 0).
    every : int
        Steps between insertions (default 100).
    seed : int
    mat_id : int
        Material row of the inserted particles (default 0).

    Attributes: ``inserted`` (the particles inserted so far), ``ids`` (their body
    indices).
    """

    def __init__(self, lo, hi, count, rate, radius, density, velocity=None, every=100,
                 seed=0, mat_id=0):
        self.lo, self.hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
        r = np.atleast_1d(np.asarray(radius, np.float64))
        self.r_min, self.r_max = float(r.min()), float(r.max())
        if not (self.r_min > 0.0 and np.all(self.hi - self.lo > 2.0 * self.r_max)):
            raise ValueError("the insertion region must be wider than a particle's "
                             "diameter along every axis, and radii positive")
        if not (int(count) >= 0 and rate > 0.0 and density > 0.0):
            raise ValueError("count must be >= 0, rate and density positive")
        self.count, self.rate, self.density = int(count), float(rate), float(density)
        d = self.lo.size
        self.velocity = np.zeros(d) if velocity is None else np.asarray(velocity,
                                                                         np.float64)
        self.trigger = Periodic(every)
        self.rng = np.random.default_rng(seed)
        self.mat_id = int(mat_id)
        self.inserted = 0
        self.ids = np.zeros(0, np.int64)
        self._checked = False

    def check_mass(self, sim):
        """The lightest inserted particle is no lighter than the lightest free body
        the time step was chosen for."""
        b = sim.bodies
        d = self.lo.size
        vol = (4.0 / 3.0 * np.pi * self.r_min**3 if d == 3 else np.pi * self.r_min**2)
        free = ~b.is_fixed & (b.kind != Shape.PLANE)
        if free.any() and self.density * vol < b.mass[free].min() * (1.0 - 1e-12):
            raise ValueError(
                f"inserted particles of radius {self.r_min:g} m and density "
                f"{self.density:g} kg/m^3 (mass {self.density * vol:.4g} kg) are lighter "
                f"than the lightest body the time step was chosen for "
                f"({b.mass[free].min():.4g} kg): the step would be unstable")
        self._checked = True

    def __call__(self, sim):
        """Insert the particles due at ``sim.time`` that find room."""
        if not self._checked:
            self.check_mass(sim)
        due = min(self.count, int(np.floor(self.rate * (sim.time + sim.dt)))) \
            - self.inserted
        if due <= 0:
            return
        pos, radius = self._place(sim, due)
        if len(radius):
            new = sim.bodies.add_spheres(pos, radius, self.density, vel=self.velocity,
                                           mat_id=self.mat_id)
            self.ids = np.concatenate([self.ids, np.asarray(new, np.int64)])
            self.inserted += len(radius)
            sim.invalidate()

    def state(self):
        """What a restart needs to insert as the uninterrupted run would: the count
        inserted, their body indices and the random generator's state (JSON-ready)."""
        return {"inserted": self.inserted, "ids": self.ids.tolist(),
                "checked": self._checked, "rng": self.rng.bit_generator.state}

    def restore(self, state):
        """Take back a :meth:`state`."""
        self.inserted = int(state["inserted"])
        self.ids = np.asarray(state["ids"], np.int64)
        self._checked = bool(state["checked"])
        self.rng.bit_generator.state = state["rng"]

    def _place(self, sim, due):
        """Up to ``due`` non-overlapping positions in the region; (pos, radius)."""
        b = sim.bodies
        d = self.lo.size
        near = np.flatnonzero((b.kind != Shape.PLANE)
                              & np.all(b.pos + b.radius[:, None] > self.lo, axis=1)
                              & np.all(b.pos - b.radius[:, None] < self.hi, axis=1))
        occupied, occ_r = list(b.pos[near]), list(b.radius[near])
        pos, radius = [], []
        for _ in range(due):
            r = self.rng.uniform(self.r_min, self.r_max)
            for _ in range(TRIES):
                x = self.lo + r + self.rng.uniform(0.0, 1.0, d) * (self.hi - self.lo
                                                                   - 2.0 * r)
                if not occupied or np.all(np.linalg.norm(np.asarray(occupied) - x, axis=1)
                                          >= np.asarray(occ_r) + r):
                    occupied.append(x)
                    occ_r.append(r)
                    pos.append(x)
                    radius.append(r)
                    break
        return np.reshape(pos, (-1, d)), np.asarray(radius)
