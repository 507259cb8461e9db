"""Walls: reaction forces and prescribed motion."""

import numpy as np
import pytest

import dem


@pytest.mark.parametrize("dim", [2, 3])
def test_wall_reaction_balances_and_vanishes_after_rebound(dim):
    """During contact the wall's reaction equals minus the force on the sphere;
    after the rebound it is zero (no stale force of an opened contact)."""
    up = np.eye(dim)[-1]
    bodies = dem.Bodies.spheres([0.0101 * up], radius=0.01, density=2500.0, vel=[-0.2 * up])
    w = bodies.add_plane(np.zeros(dim), up)
    law = dem.LinearSpring(kn=1e5, kt=2e4, mu=0.3, restitution=0.7)
    probe = dem.Record(lambda s: (s.wall_forces()[w] @ up, s.bodies.force[0] @ up), every=1)
    sim = dem.Simulation(bodies, law, observers=[probe], threads=1)
    sim.run(400)
    seen = np.array(probe.values)
    touching = seen[:, 1] != 0.0
    assert touching.any() and not touching[-1], "the sphere must hit and leave the wall"
    np.testing.assert_allclose(seen[touching, 0], -seen[touching, 1], rtol=1e-12)
    assert seen[-1, 0] == 0.0
    assert bodies.vel[0] @ up > 0.0


def test_wall_moves_at_its_prescribed_velocity():
    bodies = dem.Bodies.spheres([[0.0, 0.0, 0.5]], radius=0.01, density=2500.0)
    w = bodies.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], velocity=[0.0, 0.0, 0.1])
    sim = dem.Simulation(bodies, dem.LinearSpring(kn=1e5), dt=1e-4)
    sim.run(1000)
    assert bodies.pos[w, 2] == pytest.approx(0.1 * sim.time, rel=1e-12)
    assert bodies.vel[w, 2] == 0.1
