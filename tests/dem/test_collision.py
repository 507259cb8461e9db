"""Binary collisions against the analytic linear spring-dashpot oscillator.

A head-on contact under a linear law is a damped harmonic oscillator in the overlap,
``m_eff ov'' + c ov' + kn ov = 0``, released when the overlap returns to zero:

- contact duration ``pi / omega_d`` with ``omega_d = sqrt(kn / m_eff) sqrt(1 - zeta^2)``
  (``pi sqrt(m_eff / kn)`` when undamped);
- restitution ``e = exp(-pi zeta / sqrt(1 - zeta^2))``, with the damping ratio
  ``zeta = c / (2 sqrt(kn m_eff))``.

``m_eff = m / 2`` for two equal spheres (disks in 2D) and ``m`` for a sphere on a wall.
"""

import math

import numpy as np
import pytest

import dem

R, RHO, KN = 0.01, 2500.0, 1.0e5
SPEED = 0.2  # approach speed [m/s]
STEPS_PER_CONTACT = 1000  # the restitution error is ~ 1/steps (phase of contact entry)


def mass(dim):
    return RHO * (4.0 / 3.0 * math.pi * R**3 if dim == 3 else math.pi * R**2)


def m_eff(dim, partner):
    return 0.5 * mass(dim) if partner == "sphere" else mass(dim)


def collide(dim, partner, law):
    """Head-on collision along the last axis.

    Returns ``(duration [s], restitution, dt, sim)``. The duration counts the steps
    that end in contact; ``dt`` is the undamped contact time / STEPS_PER_CONTACT.
    """
    axis = np.eye(dim)[-1]
    gap = 0.1 * R
    t_c = math.pi * math.sqrt(m_eff(dim, partner) / law.kn)
    dt = t_c / STEPS_PER_CONTACT
    if partner == "sphere":
        pos = [-(R + 0.5 * gap) * axis, (R + 0.5 * gap) * axis]
        vel = [0.5 * SPEED * axis, -0.5 * SPEED * axis]
        bodies = dem.Bodies.spheres(pos, radius=R, density=RHO, vel=vel)

        def overlap(sim):
            return 2 * R - np.linalg.norm(sim.bodies.pos[1] - sim.bodies.pos[0])

        def approach(b):  # normal velocity of 1 relative to 0, along 0 -> 1
            return (b.vel[1] - b.vel[0]) @ axis
    else:
        bodies = dem.Bodies.spheres(
            [(R + gap) * axis], radius=R, density=RHO, vel=[-SPEED * axis]
        )
        bodies.add_plane(np.zeros(dim), axis)

        def overlap(sim):
            return R - sim.bodies.pos[0] @ axis

        def approach(b):  # normal velocity of the sphere, away from the wall
            return b.vel[0] @ axis

    v_before = approach(bodies)
    rec = dem.Record(overlap, every=1)
    sim = dem.Simulation(bodies, law, dt=dt, observers=[rec])
    n_steps = int(gap / SPEED / dt) + int(1.3 * STEPS_PER_CONTACT) + 20
    sim.run(n_steps)
    ov = np.array(rec.values)
    assert ov[-1] < 0.0, "the bodies must have separated"
    duration = np.count_nonzero(ov > 0.0) * dt
    return duration, -approach(sim.bodies) / v_before, dt, sim


def _elastic(kind):
    if kind == "LinearSpring":
        return dem.LinearSpring(KN, kt=0.0, mu=0.0)
    return dem.Elastic(KN, kt=0.0, mu=0.0)


PARTNERS = ["sphere", "plane"]


@pytest.mark.parametrize("kind", ["LinearSpring", "Elastic"])
@pytest.mark.parametrize("partner", PARTNERS)
@pytest.mark.parametrize("dim", [2, 3])
def test_elastic_collision_duration_and_restitution(dim, partner, kind):
    duration, e, dt, sim = collide(dim, partner, _elastic(kind))
    t_c = math.pi * math.sqrt(m_eff(dim, partner) / KN)
    assert abs(duration - t_c) <= 2 * dt
    assert e == pytest.approx(1.0, abs=1e-3)
    if partner == "sphere":  # equal and opposite forces: the centre of mass stays put
        np.testing.assert_allclose(sim.bodies.vel.sum(axis=0), 0.0, atol=1e-15)


@pytest.mark.parametrize("zeta", [0.05, 0.2, 0.5])
@pytest.mark.parametrize("partner", PARTNERS)
@pytest.mark.parametrize("dim", [2, 3])
def test_viscoelastic_restitution_from_gamma_n(dim, partner, zeta):
    gamma_n = 2.0 * zeta * math.sqrt(KN * m_eff(dim, partner))
    law = dem.Viscoelastic(KN, kt=0.0, gamma_n=gamma_n, gamma_t=0.0, mu=0.0)
    duration, e, dt, _ = collide(dim, partner, law)
    assert e == pytest.approx(
        math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2)), rel=0.01
    )
    omega_d = math.sqrt(KN / m_eff(dim, partner)) * math.sqrt(1 - zeta**2)
    assert abs(duration - math.pi / omega_d) <= 2 * dt


@pytest.mark.parametrize("restitution", [0.2, 0.5, 0.9])
@pytest.mark.parametrize("partner", PARTNERS)
@pytest.mark.parametrize("dim", [2, 3])
def test_rebound_equals_requested_restitution(dim, partner, restitution):
    law = dem.LinearSpring(KN, kt=0.0, mu=0.0, restitution=restitution)
    _, e, _, _ = collide(dim, partner, law)
    assert e == pytest.approx(restitution, rel=0.01)


def test_restitution_is_independent_of_the_masses():
    """``restitution=e`` sets a damping ratio, not a dashpot: any masses give e."""
    law = dem.LinearSpring(KN, restitution=0.4)
    axis = np.array([1.0, 0.0, 0.0])
    radii = np.array([R, 2.5 * R])
    pos = [-(radii[0] + 1e-4) * axis, (radii[1] + 1e-4) * axis]
    bodies = dem.Bodies.spheres(
        pos, radius=radii, density=RHO, vel=[0.3 * axis, -0.1 * axis]
    )
    p_before = bodies.mass @ bodies.vel
    m_eff = 1.0 / (1.0 / bodies.mass[0] + 1.0 / bodies.mass[1])
    t_c = math.pi * math.sqrt(m_eff / KN)
    sim = dem.Simulation(bodies, law, dt=t_c / STEPS_PER_CONTACT)
    sim.run(3 * STEPS_PER_CONTACT)  # 0.5 t_c to touch, then the contact, then apart
    rel = (sim.bodies.vel[1] - sim.bodies.vel[0]) @ axis
    assert rel / 0.4 == pytest.approx(0.4, rel=0.01)
    np.testing.assert_allclose(sim.bodies.mass @ sim.bodies.vel, p_before, atol=1e-15)
