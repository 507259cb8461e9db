"""Observers: homogenised stress and tangent (paper eqs 24, 29), energy, trackers.

Stress is positive in tension: ``sigma = 1/V sum_c f_c (x) a_c`` over the contacts of
the collection's bodies (force on the body, arm from its centre to the contact point).
"""

import math

import naive
import numpy as np
import pytest

import dem

R, RHO = 0.01, 2500.0


# --------------------------------------------------------------------------- stress
@pytest.mark.parametrize("dim", [2, 3])
def test_stress_of_a_chain_compressed_between_walls(dim):
    """Two spheres squeezed between two walls along x, every contact at overlap delta.

    Each contact carries ``F = kn delta``; the chain spans ``L`` between the contact
    points on the walls (halfway through their overlaps), so ``sigma_xx = -F L / V`` and
    every other component vanishes.
    """
    kn, delta = 1e5, 1e-5
    ex = np.eye(dim)[0]
    wall_gap = 4 * R - 3 * delta
    bodies = dem.Bodies.spheres(
        [(R - delta) * ex, (wall_gap - R + delta) * ex], radius=R, density=RHO
    )
    bodies.add_plane(np.zeros(dim), ex)
    bodies.add_plane(wall_gap * ex, -ex)
    volume = wall_gap * (2 * R) ** (dim - 1)
    tracker = dem.CollectionTracker(volume, every=5)
    sim = dem.Simulation(
        bodies, dem.LinearSpring(kn=kn, kt=0.5 * kn, mu=0.5), observers=[tracker]
    )
    sim.run(10)
    # static: equal overlaps balance every sphere
    np.testing.assert_allclose(sim.bodies.pos[:2], bodies.pos[:2], atol=1e-12 * R)
    force, length = kn * delta, wall_gap + delta
    expected = np.zeros((dim, dim))
    expected[0, 0] = -force * length / volume
    assert len(tracker.stress) == 2
    for sigma in tracker.stress:
        np.testing.assert_allclose(
            sigma, expected, rtol=1e-9, atol=1e-9 * abs(expected[0, 0])
        )
        np.testing.assert_array_equal(sigma, sigma.T)
    # the same chain without its walls in the collection: still -F L / V along x
    sigma, _ = dem.stress_and_tangent(sim, volume, ids=[0, 1])
    np.testing.assert_allclose(sigma[0, 0], expected[0, 0], rtol=1e-9)


def random_packing(dim, seed, n=64):
    """Overlapping polydisperse spheres, randomly displaced from a dense lattice."""
    rng = np.random.default_rng(seed)
    pos = naive.lattice_spheres(rng, n, dim, 1.8 * R, jitter=0.15) + R
    return dem.Bodies.spheres(pos, radius=R * rng.uniform(0.85, 1.15, n), density=RHO)


@pytest.mark.parametrize("dim", [2, 3])
def test_tangent_has_major_symmetry(dim):
    bodies = random_packing(dim, seed=dim)
    bodies.add_plane(np.zeros(dim), np.eye(dim)[-1])
    sim = dem.Simulation(
        bodies, dem.LinearSpring(kn=1e5, kt=3e4, mu=0.4), overlap_limit=1.0
    )
    contacts = sim.contacts()
    assert contacts["i"].size > bodies.n and contacts["is_wall"].any()
    sigma, c = dem.stress_and_tangent(sim, volume=1.0)
    assert c.shape == (dim,) * 4
    assert np.abs(c).max() > 0.0
    np.testing.assert_allclose(
        c, c.transpose(2, 3, 0, 1), rtol=1e-12, atol=1e-14 * np.abs(c).max()
    )
    np.testing.assert_allclose(sigma, sigma.T)
    # a compressed packing: negative pressure
    assert np.trace(sigma) < 0.0


def crystal(dim, n_side, spacing):
    """Triangular (2D) or FCC (3D) lattice, nearest neighbours ``spacing`` apart."""
    if dim == 2:
        i, j = np.meshgrid(np.arange(n_side), np.arange(n_side), indexing="ij")
        return spacing * np.stack(
            [i + 0.5 * (j % 2), j * math.sqrt(3) / 2], -1
        ).reshape(-1, 2)
    cell = spacing * math.sqrt(2)
    basis = np.array([[0, 0, 0], [0, 0.5, 0.5], [0.5, 0, 0.5], [0.5, 0.5, 0]])
    grid = np.stack(np.meshgrid(*[np.arange(n_side)] * 3, indexing="ij"), -1).reshape(
        -1, 1, 3
    )
    return cell * (grid + basis).reshape(-1, 3)


@pytest.mark.parametrize("dim", [2, 3])
def test_tangent_predicts_the_stress_of_an_affine_strain(dim):
    """``d sigma_ij = C_ijkl dG_kl`` for a small affine displacement gradient ``dG``.

    Frictionless and barely overlapping (``delta / l = 1e-5``): the geometric terms of
    the stress change are of relative size ``delta / l``, the rest is the tangent's.
    """
    kn = 1e5
    pos = crystal(dim, 5 if dim == 2 else 3, spacing=2 * R * (1 - 1e-5))
    law = dem.LinearSpring(kn=kn)
    sim0 = dem.Simulation(dem.Bodies.spheres(pos, radius=R, density=RHO), law)
    sim0.prime()
    sigma0, c = dem.stress_and_tangent(sim0, volume=1.0, kinetic=False)
    n_contacts = sim0.contacts()["i"].size
    assert n_contacts >= (3 if dim == 2 else 6) * pos.shape[0] // 2
    dg = 1e-7 * np.random.default_rng(dim).normal(size=(dim, dim))
    moved = pos + (pos - pos.mean(axis=0)) @ dg.T
    sim1 = dem.Simulation(dem.Bodies.spheres(moved, radius=R, density=RHO), law)
    sim1.prime()
    sigma1, _ = dem.stress_and_tangent(sim1, volume=1.0, kinetic=False)
    assert sim1.contacts()["i"].size == n_contacts  # no contact opened
    predicted = np.einsum("ijkl,kl->ij", c, dg)
    np.testing.assert_allclose(
        sigma1 - sigma0, predicted, rtol=1e-3, atol=1e-3 * np.abs(predicted).max()
    )


def test_stress_and_tangent_of_a_fresh_simulation():
    """The public function works before any run, like ``Simulation.contacts``."""
    bodies = dem.Bodies.spheres([[0.0, 0.0], [1.9 * R, 0.0]], radius=R, density=RHO)
    sim = dem.Simulation(bodies, dem.LinearSpring(kn=1e5))
    sigma, _ = dem.stress_and_tangent(sim, volume=1.0)
    assert sigma[0, 0] == pytest.approx(-1e5 * 0.1 * R * 1.9 * R)


# --------------------------------------------------------------------------- energy
def test_energy_tracker_free_fall_and_elastic_bounce():
    """A sphere dropped on a wall: kinetic + potential + elastic stays constant."""
    bodies = dem.Bodies.spheres([[0.0, 0.0, 3 * R]], radius=R, density=RHO)
    bodies.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    energy = dem.EnergyTracker(every=10)
    law = dem.LinearSpring(kn=1e5)
    m = bodies.mass[0]
    dt = math.pi * math.sqrt(m / law.kn) / 100  # 100 steps per contact
    sim = dem.Simulation(
        bodies, law, dt=dt, gravity=[0.0, 0.0, -9.81], observers=[energy]
    )
    sim.run(round(0.15 / dt))  # falls 2 R in 0.064 s, bounces back up
    e = energy.as_arrays()
    total = e["kinetic"] + e["rotational"] + e["elastic"] + e["potential"]
    assert e["elastic"].max() > 0.0  # the bounce was sampled
    assert sim.bodies.vel[0, 2] > 0.0 or sim.bodies.pos[0, 2] > R
    np.testing.assert_allclose(total, total[0], rtol=1e-3)
    np.testing.assert_allclose(e["dissipated"], 0.0, atol=1e-3 * total[0])
    assert e["kinetic"][0] == pytest.approx(
        0.5 * m * (9.81 * e["step"][0] * dt) ** 2, rel=1e-9
    )


def test_energy_tracker_dissipation_and_wall_work():
    """A wall moving at ``u`` hits a resting sphere: the wall does the work the sphere
    gains plus what the dashpot dissipates; the rebound leaves at ``(1 + e) u``."""
    e_rest, u = 0.5, 0.05
    bodies = dem.Bodies.spheres([[0.0, 0.0, 1.2 * R]], radius=R, density=RHO)
    bodies.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], velocity=[0.0, 0.0, u])
    law = dem.LinearSpring(kn=1e5, restitution=e_rest)
    m = bodies.mass[0]
    dt = math.pi * math.sqrt(m / law.kn) / 200
    energy = dem.EnergyTracker(every=50)
    sim = dem.Simulation(bodies, law, dt=dt, observers=[energy])
    sim.run(round((0.2 * R / u) / dt) + 600)
    e = energy.as_arrays()
    v_out = sim.bodies.vel[0, 2]
    assert v_out == pytest.approx((1 + e_rest) * u, rel=0.01)
    assert e["elastic"][-1] == 0.0  # separated
    ke = 0.5 * m * v_out**2
    # in the wall's frame the sphere comes in at u and leaves at e u
    lost = 0.5 * m * u**2 * (1 - e_rest**2)
    assert e["wall_work"][-1] == pytest.approx(ke + lost, rel=0.01)
    assert e["dissipated"][-1] == pytest.approx(lost, rel=0.01)


# --------------------------------------------------------------------------- trackers
def test_particle_tracker_and_record_sample_on_their_steps():
    pos = [[0.0, 0.0], [10 * R, 0.0]]
    bodies = dem.Bodies.spheres(
        pos, radius=R, density=RHO, vel=[[0.1, 0.2], [0.0, -0.3]]
    )
    track = dem.ParticleTracker([1], every=7)
    rec = dem.Record(lambda s: s.bodies.pos[0].copy(), every=dem.Periodic(5, phase=3))
    sim = dem.Simulation(
        bodies, dem.LinearSpring(kn=1e5), gravity=[0.0, -1.0], observers=[track, rec]
    )
    sim.run(30)
    out = track.as_arrays()
    np.testing.assert_array_equal(out["step"], [7, 14, 21, 28])
    np.testing.assert_array_equal(rec.steps, [3, 8, 13, 18, 23, 28])
    t = out["time"]
    np.testing.assert_allclose(t, out["step"] * sim.dt, rtol=1e-12)
    # free flight under gravity: velocity Verlet is exact for constant forces
    np.testing.assert_allclose(out["pos"][:, 0, 1], -0.3 * t - 0.5 * t**2, rtol=1e-12)
    np.testing.assert_allclose(out["vel"][:, 0, 1], -0.3 - t, rtol=1e-12)
    ts = np.array(rec.times)
    np.testing.assert_allclose(np.array(rec.values)[:, 0], 0.1 * ts, rtol=1e-12)
    assert sim.step == 30
