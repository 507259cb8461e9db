"""A sphere (disk in 2D) launched without spin slides on a plane, then rolls.

While it slides, Coulomb friction ``mu m g`` decelerates the centre and spins the body
up: ``v = v0 - mu g t`` and ``omega R = mu g t m R^2 / I``. Angular momentum about the
contact point is conserved, so it rolls from ``t* = v0 / (mu g (1 + m R^2 / I))`` on at
``v = v0 / (1 + I / (m R^2))``: ``5/7 v0`` for a sphere (``I = 2/5 m R^2``) and
``2/3 v0`` for a disk (``I = 1/2 m R^2``), with ``v = omega R``.
"""

import math

import numpy as np
import pytest

import dem

R, RHO, G, MU, V0 = 0.01, 2500.0, 9.81, 0.3, 1.0
# stiffness per unit mass [N/(m kg)]: the same contact frequencies in 2D and 3D, so the
# stick-phase oscillation of the tangential spring, of velocity amplitude about
# mu g sqrt(m / (kt (1 + m R^2 / I))), stays well below 1 % of v0 in both
KN_M, KT_M = 1.0e7, 4.0e6
RATIO = {3: 5.0 / 7.0, 2: 2.0 / 3.0}  # v_roll / v0
INERTIA = {3: 0.4, 2: 0.5}  # I / (m R^2)


@pytest.mark.parametrize("dim", [2, 3])
def test_sliding_sphere_starts_rolling(dim):
    up = np.eye(dim)[-1]
    along = np.eye(dim)[0]
    m = RHO * (4.0 / 3.0 * math.pi * R**3 if dim == 3 else math.pi * R**2)
    # rest at the static overlap, so the sphere does not bounce
    pos = (R - G / KN_M) * up
    bodies = dem.Bodies.spheres([pos], radius=R, density=RHO, vel=[V0 * along])
    bodies.add_plane(np.zeros(dim), up)
    law = dem.LinearSpring(kn=KN_M * m, kt=KT_M * m, mu=MU, restitution=0.5)
    track = dem.ParticleTracker([0], every=10)
    sim = dem.Simulation(bodies, law, gravity=-G * up, observers=[track])
    t_roll = V0 * (1.0 - RATIO[dim]) / (MU * G)
    sim.run(int(2.0 * t_roll / sim.dt))
    rec = track.as_arrays()
    t = rec["time"]
    v = rec["vel"][:, 0] @ along
    w = rec["ang_vel"][:, 0]
    # rim velocity at the contact point: omega x (-R up), along the motion
    spin = -w[:, 0] if dim == 2 else w[:, 1]  # rolling forward spins about -z / +y
    slip = v - R * spin

    sliding = t < 0.9 * t_roll
    assert sliding.sum() > 10
    np.testing.assert_allclose(v[sliding], V0 - MU * G * t[sliding], rtol=0.01)
    np.testing.assert_allclose(
        R * spin[sliding], MU * G * t[sliding] / INERTIA[dim], rtol=0.01, atol=0.01 * V0
    )

    rolling = t > 1.2 * t_roll
    assert rolling.sum() > 10
    np.testing.assert_allclose(v[rolling], RATIO[dim] * V0, rtol=0.01)
    np.testing.assert_allclose(R * spin[rolling], v[rolling], rtol=0.01)
    assert np.abs(slip[rolling]).max() < 0.01 * RATIO[dim] * V0
