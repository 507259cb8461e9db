"""Peridynamic bodies contact through the ordinary contact laws: friction, damping,
history carried across rebuilds, the default spring, bad input."""

import math

import numpy as np
import pytest

import dem
from dem import peridynamics as pd

E, RHO, DX, G = 1e7, 1000.0, 0.01, 9.81


def block_on_floor(law, v0=1.0, **kw):
    """A 6 x 2 block of points resting on the plane y = 0 (its bottom row touching),
    sliding along x at ``v0`` [m/s] under gravity."""
    b = dem.Bodies.empty(2)
    ids = pd.add_points(b, pd.lattice([0, 0], [6 * DX, 2 * DX], DX), DX, RHO,
                        thickness=0.01, vel=[v0, 0.0])
    b.add_plane([0.0, 0.0], [0.0, 1.0])
    sim = pd.PDSimulation(b, pd.PMB(E=E, density=RHO, plane="stress"), ids, 3 * DX,
                          gravity=[0.0, -G], contact=law, threads=1, **kw)
    return sim, ids


def test_a_sliding_block_decelerates_at_mu_g():
    """Coulomb friction of the wall law: while the block slides, the wall's friction is
    mu times its normal reaction, which balances the weight on average, so the block
    slows at mu g: v(t) = v0 - mu g t (the law is damped: the landing bounce dies out
    and leaves the vertical momentum at zero). Every contact slides from its first
    step, so the friction impulse is mu times the normal one to round-off."""
    mu, v0 = 0.3, 1.0
    law = dem.LinearSpring(kn=2e3, kt=1e3, mu=mu, restitution=0.3)
    sim, ids = block_on_floor(law, v0)
    mass = sim.bodies.mass[ids].sum()
    t_end = 0.2  # before it stops (at v0 / (mu g) = 0.34 s)
    sim.run(int(round(t_end / sim.dt)))
    p = sim.momentum()
    v = p[0] / mass
    expect = v0 - mu * G * sim.time
    # the exact balance: friction impulse = mu x (weight impulse + vertical momentum)
    exact = v0 - mu * (G * sim.time + p[1] / mass)
    assert v == pytest.approx(exact, rel=1e-9)  # measured: 1e-15
    assert v == pytest.approx(expect, rel=1e-4)  # measured: 1e-8
    assert abs(p[1]) / mass < 0.01  # it has landed
    assert sim._contact.whist.any()  # the wall contacts carry a tangential spring


def test_without_friction_the_block_keeps_its_speed():
    law = dem.LinearSpring(kn=2e3, restitution=0.3)
    sim, ids = block_on_floor(law, 1.0)
    sim.run(int(round(0.1 / sim.dt)))
    v = sim.momentum()[0] / sim.bodies.mass[ids].sum()
    assert v == pytest.approx(1.0, abs=1e-9)


def test_default_contact_is_the_frictionless_elastic_spring():
    """No law given: a linear spring of E V / (2 dx^2), no friction, no dashpot; the
    contact time step is sqrt(2 m / kn) as before the laws came in."""
    sim, ids = block_on_floor(None, 1.0)
    (law,) = sim.contact.laws["pp"].values()
    vol = DX * DX * 0.01
    assert isinstance(law, dem.LinearSpring)
    assert law.kn == pytest.approx(0.5 * E * vol / DX**2)
    assert law.mu == 0.0 and law.kt == 0.0 and law.zeta == 0.0
    m = float(sim.bodies.mass[ids].min())
    assert sim.critical_time_step() <= math.sqrt(2 * m / law.kn)
    sim2, _ = block_on_floor(None, 1.0, contact_kn=law.kn)
    assert sim2.dt == sim.dt


def test_dashpots_shorten_the_contact_time_step():
    stiff = dict(kn=1e6, kt=0.0)
    sim_e1, _ = block_on_floor(dem.LinearSpring(**stiff, restitution=1.0))
    sim_e, _ = block_on_floor(dem.LinearSpring(**stiff, restitution=0.1))
    z = sim_e.contact.max_damping_ratio(sim_e.bodies, float(sim_e.bodies.mass[:-1].min()))
    assert z > 0.5
    ratio = sim_e.critical_time_step() / sim_e1.critical_time_step()
    assert ratio == pytest.approx(math.sqrt(1 + z * z) - z, rel=1e-9)


def test_fragments_with_friction_carry_history_across_rebuilds():
    """Two blocks, one sliding over the other: their contacts' tangential springs are
    carried by pair key when the contact list is rebuilt, and friction drags the lower
    block along, conserving momentum."""
    b = dem.Bodies.empty(2)
    low = pd.add_points(b, pd.lattice([0, 0], [0.1, 0.02], DX), DX, RHO)
    top = pd.add_points(b, pd.lattice([0.02, 0.02], [0.06, 0.04], DX), DX, RHO,
                        vel=[2.0, -0.5])
    law = dem.LinearSpring(kn=5e4, kt=2e4, mu=0.5, restitution=0.5)
    sim = pd.PDSimulation(b, pd.PMB(E=E, density=RHO), [low, top], 3 * DX, contact=law,
                          threads=1)
    p0 = sim.momentum()
    rebuilds = 0
    carried = False
    for _ in range(40):
        before = sim._contact.cpairs.copy()
        sim.run(25)
        if not np.array_equal(before, sim._contact.cpairs):
            rebuilds += 1
            carried = carried or sim._contact.hist.any()
    assert rebuilds > 0 and carried
    assert b.vel[low, 0].mean() > 0.05  # dragged along by friction
    np.testing.assert_allclose(sim.momentum(), p0, atol=1e-12)


def test_hertz_mindlin_fragments_rebound_with_momentum_conserved():
    b = dem.Bodies.empty(2)
    a = pd.add_points(b, pd.lattice([0, 0], [0.04, 0.04], DX), DX, RHO, vel=[1.0, 0.0])
    c = pd.add_points(b, pd.lattice([0.05, 0], [0.09, 0.04], DX), DX, RHO, vel=[-1.0, 0.0])
    law = dem.HertzMindlin(young=1e7, poisson=0.3, restitution=0.9, mu=0.3)
    sim = pd.PDSimulation(b, pd.PMB(E=E, density=RHO), [a, c], 3 * DX, contact=law,
                          threads=1)
    sim.run(2000)
    assert b.vel[a, 0].mean() < 0.0 < b.vel[c, 0].mean()  # they rebounded
    np.testing.assert_allclose(sim.momentum(), 0.0, atol=1e-12)


def test_bad_contact_input_is_refused():
    law = dem.LinearSpring(kn=1e3)
    with pytest.raises(ValueError, match="not both"):
        block_on_floor(law, contact_kn=1e3)
    with pytest.raises(ValueError, match="contact_kn must be positive"):
        block_on_floor(None, contact_kn=-1.0)
    with pytest.raises(ValueError, match="peridynamic points carry none"):
        block_on_floor(dem.LinearSpring(kn=1e3, rolling=dem.Rolling(mu_roll=0.1)))
    with pytest.raises(TypeError, match="contact must be a contact law"):
        block_on_floor("linear")
