"""Farms: everything the macro solver asks of its Gauss points goes through one.

A farm owns the micro models of the Gauss points (flat index ``e * n_qp + q``: element
``e``, quadrature point ``q``) and answers for all of them at once:

``trial(deps)``
    (n, d, d) strain increments in, (n, d, d) stresses and (n, d, d, d, d) tangents
    out, from the committed states;
``commit()`` / ``rollback()``
    after a converged / a failed load step;
``measures()``
    per-point arrays of the committed state (void ratio, coordination, ran_dem) and
    the cost of the last trial (seconds, DEM steps).

:class:`SerialFarm` runs them in this process; an MPI farm with the same calls
distributes them over ranks. A micro model that raises ends the trial with a
:class:`MicroFailure` naming the Gauss point, so the solver can cut the step.
"""

import time

import numpy as np


class MicroFailure(RuntimeError):
    """A micro model failed; ``point`` is its Gauss point index."""

    def __init__(self, point, message):
        super().__init__(f"Gauss point {point}: {message}")
        self.point = int(point)


class SerialFarm:
    """The Gauss points' micro models, run one after the other in this process."""

    def __init__(self, models):
        self.models = list(models)
        if not self.models:
            raise ValueError("a farm needs at least one micro model")
        self.dim = self.models[0].dim
        if any(m.dim != self.dim for m in self.models):
            raise ValueError("every micro model of a farm must have the same dimension")
        n, d = len(self.models), self.dim
        self.n = n
        self.cost = np.zeros(n)  # seconds of each point's last trial
        self.steps = np.zeros(n, np.int64)  # DEM steps of each point's last trial
        self._sig = np.empty((n, d, d))
        self._c = np.empty((n, d, d, d, d))
        self.n_trials = 0

    def trial(self, deps):
        deps = np.asarray(deps, dtype=np.float64)
        if deps.shape != (self.n, self.dim, self.dim):
            raise ValueError(f"strain increments must be ({self.n}, {self.dim}, "
                             f"{self.dim}), got {deps.shape}")
        for k, m in enumerate(self.models):
            t0 = time.perf_counter()
            try:
                self._sig[k], self._c[k] = m.trial(deps[k])
            except Exception as err:  # any failure of a point is reported as its own
                raise MicroFailure(k, f"{type(err).__name__}: {err}") from err
            self.cost[k] = time.perf_counter() - t0
            self.steps[k] = getattr(m, "steps", 0)
        self.n_trials += 1
        return self._sig.copy(), self._c.copy()

    def commit(self):
        for m in self.models:
            m.commit()

    def rollback(self):
        for m in self.models:
            m.rollback()

    def measures(self):
        rows = [m.measures() for m in self.models]
        out = {k: np.array([r[k] for r in rows]) for k in rows[0]}
        out["cost"] = self.cost.copy()
        out["steps"] = self.steps.copy()
        return out

    def stress(self):
        """Committed stresses (n, d, d) [Pa]."""
        return np.array([m.stress for m in self.models])
