"""External loads that depend on the configuration (finite kinematics).

Under small kinematics every load is a fixed vector of nodal forces, assembled once
(:func:`hmm.problem_build.build_loads`). Under finite kinematics a pressure follows the
deformed boundary, and a traction or body force may be stated per unit *current*
area or volume: their nodal forces change with the displacement, and so does the
Newton matrix (the load stiffness ``d f / d u``, subtracted from the internal one).
Each term here gives both for a displacement ``u`` and a load factor ``t``; the
force is ``t`` times the term's value when it is ramped, its value otherwise.

Dead loads (pressures on the initial boundary, tractions per unit initial area, body
forces per unit initial volume, e.g. gravity, ``rho_0 g dV``) stay fixed vectors
under either kinematics.
"""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FollowerPressure:
    """A pressure [Pa] (compression positive) normal to the deformed boundary."""

    boundary: str
    value: float
    ramp: bool = False

    def _scale(self, t):
        return t if self.ramp else 1.0

    def force(self, macro, u, t):
        return self._scale(t) * macro.pressure_force(self.boundary, self.value, u)

    def stiffness(self, macro, u, t):
        return self._scale(t) * macro.pressure_stiffness(self.boundary, self.value, u)


@dataclass(frozen=True)
class CurrentTraction:
    """A traction vector (d,) [Pa] per unit current area, ramped."""

    boundary: str
    value: tuple

    def force(self, macro, u, t):
        return t * macro.traction_force(self.boundary, np.asarray(self.value), u)

    def stiffness(self, macro, u, t):
        return t * macro.traction_stiffness(self.boundary, np.asarray(self.value), u)


@dataclass(frozen=True)
class CurrentBodyForce:
    """A body force density (d,) [N/m^3] per unit current volume, ramped."""

    value: tuple

    def force(self, macro, u, t):
        return t * macro.body_force(np.asarray(self.value), u)

    def stiffness(self, macro, u, t):
        return t * macro.body_force_stiffness(np.asarray(self.value), u)
