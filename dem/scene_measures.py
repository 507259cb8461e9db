"""What a scene measures of itself, and a run that ends at rest.

:class:`MeasureScene` is a part of :class:`~dem.Simulation` (as
:class:`~dem.shape_scene.ShapeScene` and :class:`~dem.mesh_scene.MeshScene` are): the
touching contacts, the forces on the walls, the unbalanced-force ratio
(:mod:`dem.contact.relaxation`), and :meth:`MeasureScene.relax`, which steps until that
ratio falls below a tolerance with the checks made inside the compiled loop, where a
YADE user would write ``while unbalancedForce() > tol: O.run(100)``.
"""

from typing import NamedTuple

import numpy as np

from .contact.relaxation import relax_check, unbalanced_ratio
from .shapes import Shape
from .state import RelaxCheck, ServoDrive
from .status import CAME_APART, OK, RELAXED


def no_drive(dim):
    """The :class:`~dem.state.ServoDrive` part of a check without a drive: empty
    settings, and arrays of the drive's types."""
    d = dim
    return ServoDrive(np.zeros((d, d)), np.zeros((d, d), np.bool_), np.zeros((d, d)),
                      np.zeros(0), np.zeros(0), np.zeros((0, d, d)), np.zeros(0, np.int64),
                      np.zeros(0, np.int64), np.zeros((d, d)), np.zeros((d, d, d, d)),
                      np.zeros((d, d)))


def never_check(dim):
    """The relaxation check of a plain run: none."""
    return RelaxCheck(0, 0.0, 0.0, 0, np.zeros((0, dim)), np.zeros(5), no_drive(dim))


class Relaxation(NamedTuple):
    """How :meth:`MeasureScene.relax` ended: the steps it ran, the unbalanced-force
    ratio and the touching pairs at its last check, the checks it made (the one before
    the first step included), and ``status``: ``"relaxed"`` (below the tolerance),
    ``"apart"`` (too few contacts for too long) or ``"cap"`` (``max_steps`` ran out)."""

    steps: int
    unbalanced: float
    contacts: int
    checks: int
    status: str


class MeasureScene:
    """Measures of a scene's state, and its relaxation (a :class:`~dem.Simulation`
    part)."""

    def _spheres_only(self, what):
        if self.shaped:
            raise ValueError(f"{what} needs a scene of spheres or disks; for level-set "
                             f"shapes step with run() and measure with dem.observers")

    def unbalanced_force(self):
        """The unbalanced-force ratio now: the mean norm of the net contact force on a
        body over the mean norm of the contact forces, over the touching body-body
        pairs (walls not counted); ``inf`` without contacts. Spheres and disks."""
        self._spheres_only("unbalanced_force()")
        self.prime()
        b, nl = self.bodies, self.neighbors
        return float(unbalanced_ratio(b.pos, b.radius, nl.pairs, nl.img, self._hmat,
                                      self.pair_state.fpair, np.zeros((b.n, self.dim)))[1])

    def relax(self, tol=1e-3, max_steps=200_000, every=50, min_coordination=0.0,
              apart_checks=0, progress=None):
        """Step until the unbalanced-force ratio (:meth:`unbalanced_force`) is below
        ``tol``.

        The ratio is checked before the first step and then every ``every`` steps,
        inside the compiled loop, which stops at the first check below ``tol``: the
        run does not come back to Python between checks. It also stops after
        ``max_steps`` steps, or once the coordination number (2 x contacts / bodies)
        was below ``min_coordination`` at ``apart_checks`` checks in a row (0: never),
        a packing that came apart (a gas never relaxes). Steps are those of
        :meth:`run`, observers, controllers and state objects included, so a
        relaxation and ``run`` of as many steps end in the same state, bit for bit.
        Spheres and disks only.

        Returns a :class:`Relaxation`.
        """
        self._spheres_only("relax()")
        every, max_steps, apart_checks = int(every), int(max_steps), int(apart_checks)
        if every < 1 or max_steps < 0 or apart_checks < 0:
            raise ValueError(f"relax() needs every >= 1, max_steps >= 0 and apart_checks "
                             f">= 0, got {every}, {max_steps}, {apart_checks}")
        if not (tol >= 0.0 and min_coordination >= 0.0):
            raise ValueError(f"tol and min_coordination must be >= 0, got {tol}, "
                             f"{min_coordination}")
        self.prime()
        b, nl = self.bodies, self.neighbors
        check = RelaxCheck(every, float(tol), float(min_coordination), apart_checks,
                           np.zeros((b.n, self.dim)), np.zeros(5), no_drive(self.dim))
        code = relax_check(b.pos, b.radius, nl.pairs, nl.img, self._hmat,
                           self.pair_state.fpair, check)
        start = self.step
        if code == OK and max_steps > 0:
            code = self.run_checked(check, max_steps, progress)
        out = check.out
        status = "relaxed" if code == RELAXED else "apart" if code == CAME_APART else "cap"
        return Relaxation(self.step - start, float(out[0]), int(out[1]), int(out[3]),
                          status)

    def run_checked(self, check, n_steps, progress=None):
        """Step up to ``n_steps`` (as :meth:`run`) with the loop making ``check``'s
        checks (:class:`~dem.state.RelaxCheck`: a relaxation's, or an RVE's drive,
        :mod:`dem.contact.servo`), the first after ``check.out[4]`` steps. Returns the
        status of the check that stopped the run (``RELAXED``, ``CAME_APART``,
        ``NOT_RELAXED``), or ``OK`` when the steps ran out. Spheres and disks."""
        self._spheres_only("run_checked()")
        self._check = check
        try:
            return self._steps(int(n_steps), progress)
        finally:
            self._check = never_check(self.dim)

    def contacts(self):
        """Touching contacts now, as a dict of arrays (see
        :func:`dem.observers.contact_summary`)."""
        from .observers import contact_summary

        self.prime()
        return contact_summary(self)

    def contact_radii(self):
        """Radii [m] of the touching parts: ``(m, 2)`` for the pair rows and ``(mw,)``
        for the wall rows (the bodies' radii, but a compound's part's own)."""
        self.prime()
        b, nl = self.bodies, self.neighbors
        if self.shaped and self._has_parts:
            return self._erad[self._parts], self._erad[self._wparts[:, 0]]
        return b.radius[nl.pairs], b.radius[nl.wall_pairs[:, 0]]

    def wall_forces(self):
        """Total contact force [N] on each wall body: dict ``{body index: (d,) array}``."""
        self.prime()
        walls = self.bodies.ids(Shape.PLANE)
        wp = self.neighbors.wall_pairs
        out = {}
        for w in walls:
            rows = wp[:, 1] == w
            out[int(w)] = -self.wall_state.wforce[rows].sum(axis=0)
        return out

