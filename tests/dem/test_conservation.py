"""Conservation laws of the time integrator with contact forces.

- Contact forces come in equal and opposite pairs applied at a common point, so the
  total linear momentum and the total angular momentum about the origin (orbital plus
  spin ``I omega``) are conserved by each velocity Verlet step, whatever the dashpots
  and friction: they change only by round-off.
- Without dashpots or friction the linear spring is conservative: over 10^5 steps at a
  small time step the total energy (kinetic + elastic) does not drift.
"""

import naive
import numpy as np
import pytest

import dem
from dem.neighbors import Box

R, RHO = 0.01, 2500.0
DISSIPATIVE = dem.LinearSpring(kn=1e5, kt=4e4, mu=0.3, gamma_t=0.5, restitution=0.6)
# One thread: results do not depend on the thread count (test_kernels checks that
# bit for bit), and on shared cores a parallel region can cost 100x its serial time.
SERIAL = 1


def gas(n, spacing, seed, spin=0.0, dim=3):
    """``n`` spheres on a jittered lattice, random radii, velocities ~ N(0, 1)."""
    rng = np.random.default_rng(seed)
    pos = naive.lattice_spheres(rng, n, dim, spacing, jitter=0.03)
    radius = R * rng.uniform(0.9, 1.0, n)
    bodies = dem.Bodies.spheres(pos, radius=radius, density=RHO)
    bodies.vel[:] = rng.normal(0.0, 1.0, size=bodies.vel.shape)
    bodies.ang_vel[:] = rng.normal(0.0, spin, size=bodies.ang_vel.shape)
    return bodies


def set_speed(sim, per_step):
    """Scale velocities so bodies move ``per_step * R`` per step (rms per axis)."""
    sim.bodies.vel *= per_step * R / sim.dt


def test_linear_momentum_conserved_in_periodic_gas():
    side = 10
    spacing = 2.3 * R
    bodies = gas(side**3, spacing, seed=1)
    box = Box(
        -0.5 * spacing * np.ones(3), (side - 0.5) * spacing * np.ones(3), [True] * 3
    )
    sim = dem.Simulation(bodies, DISSIPATIVE, box=box, threads=SERIAL)
    set_speed(sim, 0.01)
    b = sim.bodies
    p0, _ = naive.momenta(b.pos, b.vel, b.ang_vel, b.mass, b.inertia)
    scale = np.sum(b.mass * np.linalg.norm(b.vel, axis=1))
    ke0 = sum(dem.kinetic_energy(b))
    sim.run(300)
    p1, _ = naive.momenta(b.pos, b.vel, b.ang_vel, b.mass, b.inertia)
    assert sum(dem.kinetic_energy(b)) < 0.9 * ke0  # many dissipative collisions
    assert np.linalg.norm(p1 - p0) < 1e-12 * scale


def test_linear_and_angular_momentum_conserved_in_free_gas():
    n = 1000
    bodies = gas(n, 2.3 * R, seed=2, spin=30.0)
    bodies.pos += [0.3, -0.2, 0.1]  # away from the origin: large orbital momentum
    sim = dem.Simulation(bodies, DISSIPATIVE, threads=SERIAL)
    set_speed(sim, 0.01)
    b = sim.bodies
    p0, l0 = naive.momenta(b.pos, b.vel, b.ang_vel, b.mass, b.inertia)
    spin0 = np.sum(b.inertia * b.ang_vel, axis=0)
    p_scale = np.sum(b.mass * np.linalg.norm(b.vel, axis=1))
    l_scale = np.sum(b.mass * np.linalg.norm(np.cross(b.pos, b.vel), axis=1)) + np.sum(
        np.linalg.norm(b.inertia * b.ang_vel, axis=1)
    )
    ke0 = sum(dem.kinetic_energy(b))
    sim.run(300)
    p1, l1 = naive.momenta(b.pos, b.vel, b.ang_vel, b.mass, b.inertia)
    spin1 = np.sum(b.inertia * b.ang_vel, axis=0)
    assert sum(dem.kinetic_energy(b)) < 0.9 * ke0  # many dissipative collisions
    # friction moved angular momentum between spin and orbit, far above round-off
    assert np.linalg.norm(spin1 - spin0) > 1e-6 * l_scale
    assert np.linalg.norm(p1 - p0) < 1e-12 * p_scale
    assert np.linalg.norm(l1 - l0) < 1e-12 * l_scale


@pytest.mark.parametrize("dim", [2, 3])
def test_energy_does_not_drift_in_elastic_gas(dim):
    side = 4 if dim == 3 else 8  # 64 bodies
    spacing = (2.76 if dim == 3 else 3.96) * R  # packing fraction about 0.2
    bodies = gas(side**dim, spacing, seed=5, dim=dim)
    lo = -0.5 * spacing * np.ones(dim)
    box = Box(lo, lo + side * spacing, [True] * dim)
    law = dem.LinearSpring(kn=1e5)  # no dashpot, no friction
    energy = dem.EnergyTracker(every=1000)
    dt = 0.02 * dem.Simulation(bodies.copy(), law, box=box).dt_crit
    sim = dem.Simulation(bodies, law, dt=dt, box=box, observers=[energy])
    set_speed(sim, 0.002)  # peak overlaps of a few % of R
    sim.run(100_000)
    e = energy.as_arrays()
    total = e["kinetic"] + e["rotational"] + e["elastic"] + e["potential"]
    # collisions were under way when sampled
    assert e["elastic"].max() > 1e-3 * total[0]
    assert np.abs(total - total[0]).max() < 1e-3 * total[0]
    assert np.abs(e["dissipated"]).max() < 1e-3 * total[0]
