"""dem: the particle engine (DEM with signed-distance shapes; peridynamics in dem.peridynamics).

A scene in a few lines::

    import dem
    bodies = dem.Bodies.spheres(pos, radius=0.01, density=2500.0)
    bodies.add_plane([0, 0, 0], [0, 0, 1])
    law = dem.LinearSpring(kn=1e5, kt=5e4, mu=0.3, restitution=0.5)
    sim = dem.Simulation(bodies, law, gravity=[0, 0, -9.81])
    sim.run(10000)

Units are SI throughout; stress is positive in tension; overlap is positive in contact;
normals point from the home body to its neighbour.
"""

from .contact.laws import Elastic, HertzMindlin, Law, LinearSpring, Viscoelastic
from .contact.model import ContactModel
from .contact.rolling import Rolling
from .meshwall import MeshWall
from .neighbors import Box as Domain
from .observers import (CollectionTracker, EnergyTracker, ParticleTracker, Periodic,
                        Record, kinetic_energy, stress_and_tangent)
from .shapes import (Box, Compound, ConvexPolygon, ConvexPolyhedron, CustomShape, Plane,
                     Shape, Sphere)
from .simulation import Simulation, SimulationError
from .state import Bodies
from .state_objects import ShapeScale, SphereRadius, StateObject
from .timestep import DT_FACTOR, critical_time_step

__all__ = [
    "Bodies", "Box", "CollectionTracker", "Compound", "ConvexPolygon", "ConvexPolyhedron",
    "CustomShape",
    "ShapeScale", "ContactModel", "DT_FACTOR", "Domain", "Elastic",
    "EnergyTracker", "HertzMindlin", "Law", "LinearSpring", "MeshWall", "ParticleTracker",
    "Periodic", "Plane", "Record", "Rolling", "Shape", "Simulation", "SimulationError",
    "Sphere", "SphereRadius", "StateObject", "Viscoelastic", "critical_time_step",
    "kinetic_energy",
    "stress_and_tangent",
]
