"""Peridynamics on the particle engine: material points, bonds, fracture, bonded beams.

A plate in a few lines::

    import dem
    from dem import peridynamics as pd
    dx = 0.01
    bodies = dem.Bodies.empty(2)
    ids = pd.add_points(bodies, pd.lattice([0, 0], [1, 1], dx), dx, density=1000.0)
    sim = pd.PDSimulation(bodies, pd.LPS(E=1e9, nu=0.3, density=1000.0), ids,
                          horizon=3 * dx)
    sim.run(1000)

Material points are rows of the :class:`dem.Bodies` table; bonds are persistent
interactions in CSR form (:class:`Family`); a pair without an intact bond interacts by
elastic contact. Bonded Euler-Bernoulli beams between rigid bodies are in
:mod:`.beams`. See ``docs/peridynamics.md`` for the equations.
"""

from .beam_lattice import lattice_cantilever, lattice_deflection
from .beams import BeamBonds, BeamStructure, cantilever, cantilever_deflection
from .lattice import Family, crack, lattice
from .materials import LPS, PMB
from .simulation import DT_FACTOR, PDSimulation, add_points

__all__ = ["DT_FACTOR", "LPS", "PMB", "BeamBonds", "BeamStructure", "Family", "PDSimulation",
           "add_points", "cantilever", "cantilever_deflection", "crack", "lattice",
           "lattice_cantilever", "lattice_deflection"]
