"""State objects are advanced by Heun's RK2 once per step, after the bodies.

Heun's method is exact for a right-hand side linear in ``t``, second order in general:
``dR/dt = 1`` gives ``R0 + t``, ``dR/dt = t`` gives ``R0 + t^2 / 2`` (both to round-off)
and ``dR/dt = -R`` gives ``R0 exp(-t)`` with an error that falls 4x when ``dt`` halves.
"""

import math

import naive
import numpy as np
import pytest

import dem

R0, RHO = 0.01, 2500.0
SOFT = dem.LinearSpring(kn=1e-6)  # no contacts here; keeps dt_crit above the dt used


def grow(rate, dt, n_steps, dim=3):
    """A free sphere with ``dR/dt = rate(R, t)`` after ``n_steps``: the simulation."""
    bodies = dem.Bodies.spheres([np.zeros(dim)], radius=R0, density=RHO)
    so = dem.SphereRadius([0], rate)
    sim = dem.Simulation(bodies, SOFT, dt=dt, state_objects=[so])
    sim.run(n_steps)
    return sim


@pytest.mark.parametrize("dim", [2, 3])
def test_constant_growth_rate_is_integrated_exactly(dim):
    sim = grow(lambda r, t: np.ones_like(r), dt=1e-3, n_steps=250, dim=dim)
    assert sim.time == pytest.approx(0.25, rel=1e-12)
    r = sim.bodies.radius[0]
    assert r == pytest.approx(R0 + sim.time, rel=1e-12)
    # mass and inertia follow the radius at constant density
    vol = 4.0 / 3.0 * math.pi * r**3 if dim == 3 else math.pi * r**2
    assert sim.bodies.mass[0] == pytest.approx(RHO * vol, rel=1e-12)
    k = 0.4 if dim == 3 else 0.5
    np.testing.assert_allclose(sim.bodies.inertia[0], k * RHO * vol * r**2, rtol=1e-12)


def test_time_dependent_rate_sees_the_step_times():
    """``dR/dt = t``: Heun's trapezoid is exact only if it is given the right times."""
    sim = grow(lambda r, t: np.full_like(r, t), dt=1e-2, n_steps=100)
    assert sim.bodies.radius[0] == pytest.approx(R0 + 0.5 * sim.time**2, rel=1e-12)


def test_exponential_decay_is_second_order():
    errors = []
    for dt in (0.1, 0.05, 0.025):
        n = round(1.0 / dt)
        sim = grow(lambda r, t: -r, dt=dt, n_steps=n)
        errors.append(abs(sim.bodies.radius[0] - R0 * math.exp(-sim.time)))
    assert errors[0] < 1e-2 * R0
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    np.testing.assert_allclose(ratios, 4.0, rtol=0.1)


def test_contacts_of_growing_and_moving_spheres_are_not_missed():
    """Growth uses up the Verlet skin just as motion does.

    Two spheres approach each other by 0.4 skin each and grow by 0.24 skin each: each
    alone stays within its own rebuild threshold (skin / 2 of motion, skin / 4 of
    growth), together they close a gap of 1.28 skin. Every force must equal the
    brute-force one at that step's positions and the radii it started with (state
    objects advance after the bodies, so a step's forces see the radii of its start).
    """
    skin, n = 1e-3, 40
    law = dem.LinearSpring(kn=1e3)
    gap = 1.1 * skin
    pos = [[-R0 - 0.5 * gap, 0.0, 0.0], [R0 + 0.5 * gap, 0.0, 0.0]]
    bodies = dem.Bodies.spheres(pos, radius=R0, density=RHO)
    dt = 0.1 * dem.Simulation(bodies.copy(), law).dt_crit
    v = 0.4 * skin / (n * dt)
    bodies.vel[:, 0] = [v, -v]
    so = dem.SphereRadius([0, 1], lambda r, t: np.full_like(r, 0.24 * skin / (n * dt)))

    radius_at_start = [bodies.radius.copy()]

    def check(sim):
        b = sim.bodies
        f, _, st = naive.linear_forces(
            b.pos,
            b.vel,
            b.ang_vel,
            radius_at_start[0],
            b.mass,
            b.mat_id,
            lambda *a: law,
        )
        radius_at_start[0] = b.radius.copy()
        return st["contacts"], np.abs(b.force - f).max(), np.abs(f).max()

    rec = dem.Record(check, every=1)
    sim = dem.Simulation(
        bodies, law, dt=dt, skin=skin, state_objects=[so], observers=[rec]
    )
    sim.run(n)
    contacts, err, scale = np.array(rec.values).T
    assert contacts.sum() > 0  # they touched
    assert np.all(err <= 1e-9 * scale.max())
