"""Rolling and twisting resistance (:mod:`dem.contact.rolling`): analytic stopping
distances, the moments' bookkeeping in the homogenised stresses, files and bad input.

A sphere (disk) rolling without slip on a plane under a constant rolling moment
``M = mu_roll R m g`` decelerates at ``a = M R / (I + m R^2) = mu_roll g / (1 + I /
(m R^2))``: it stops after ``v0^2 / (2 a)``. A sphere spinning about the normal under a
constant twisting moment ``mu_twist R m g`` turns ``I w0^2 / (2 mu_twist R m g)`` before
it stops. The 2D scenes are periodic along the path (far longer than it), so they run
the loop of the periodic RVEs with rolling below; the 3D ones have the plane alone, the
loop of the poured piles with rolling (tests/test_angle_of_repose.py): each loop the
suite compiles costs it half a minute or more.
"""

import math

import numpy as np
import pytest

import dem
from dem import rve

R, RHO, G = 0.01, 2500.0, 9.81
INERTIA = {3: 0.4, 2: 0.5}  # I / (m R^2)


def _on_plane(dim, law, v=None, w=None):
    """One sphere resting on a plane at its static overlap (kn = 1e7 m); in 2D in a box
    periodic along x (1 m long)."""
    up = np.eye(dim)[-1]
    m = RHO * (4.0 / 3.0 * math.pi * R**3 if dim == 3 else math.pi * R**2)
    pos = (R - G * m / law.kn) * up
    b = dem.Bodies.spheres([pos], radius=R, density=RHO,
                           vel=None if v is None else [v])
    if w is not None:
        b.ang_vel[0] = w
    b.add_plane(np.zeros(dim), up)
    box = (dem.Domain(np.full(dim, -0.5), np.full(dim, 0.5), np.eye(dim)[0] > 0)
           if dim == 2 else None)
    return dem.Simulation(b, law, gravity=-G * up, box=box), m


def _law(m, **rolling):
    kn = 1e7 * m
    return dem.LinearSpring(kn=kn, kt=0.4 * kn, mu=0.5, restitution=0.5,
                            rolling=dem.Rolling(**rolling))


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("eta", [0.0, 0.5])
def test_rolling_sphere_stops_at_the_analytic_distance(dim, eta):
    v0, mu_r = 0.2, 0.1
    m = RHO * (4.0 / 3.0 * math.pi * R**3 if dim == 3 else math.pi * R**2)
    w = [0.0, 0.0, -v0 / R] if dim == 2 else [0.0, v0 / R, 0.0]  # rolls towards +x
    sim, _ = _on_plane(dim, _law(m, mu_roll=mu_r, eta_roll=eta), v=np.eye(dim)[0] * v0,
                       w=w[2:] if dim == 2 else w)
    a = mu_r * G / (1.0 + INERTIA[dim])
    t_stop = v0 / a
    sim.run(int(1.3 * t_stop / sim.dt))
    b = sim.bodies
    assert b.pos[0, 0] == pytest.approx(v0**2 / (2.0 * a), rel=1e-3)  # the bar: 1 %
    # held by the rolling spring: at rest with a dashpot, else swinging a little about
    # where it stopped
    assert abs(b.vel[0, 0]) < (1e-6 if eta else 1e-2) * v0
    # without rolling resistance it would still roll at v0
    free, _ = _on_plane(dim, _law(m, mu_roll=0.0), v=np.eye(dim)[0] * v0,
                        w=w[2:] if dim == 2 else w)
    free.run(200)
    assert free.bodies.vel[0, 0] == pytest.approx(v0, rel=1e-4)


def test_spinning_sphere_stops_at_the_analytic_angle():
    """Twisting resistance alone (no rolling) brakes a spin about the normal."""
    w0, mu_w = 20.0, 0.2
    m = RHO * 4.0 / 3.0 * math.pi * R**3
    law = _law(m, mu_roll=0.0, mu_twist=mu_w, eta_roll=0.5)
    track = dem.ParticleTracker([0], every=1)
    sim, _ = _on_plane(3, law, w=[0.0, 0.0, w0])
    sim.observers.append(track)
    moment = mu_w * R * m * G
    inertia = INERTIA[3] * m * R**2
    t_stop = inertia * w0 / moment
    sim.run(int(1.3 * t_stop / sim.dt))
    rec = track.as_arrays()
    angle = np.sum(rec["ang_vel"][:, 0, 2]) * sim.dt
    assert angle == pytest.approx(inertia * w0**2 / (2.0 * moment), rel=1e-2)
    assert abs(sim.bodies.ang_vel[0, 2]) < 1e-6 * w0


@pytest.fixture(scope="module")
def sheared():
    """A small 2D packing with rolling resistance, sheared by 0.2 %: its contacts
    carry rolling moments."""
    law = dem.LinearSpring(kn=1e8, kt=5e7, mu=0.5,
                           rolling=dem.Rolling(mu_roll=0.3, eta_roll=0.3))
    r = rve.generate(2, 40, (0.8e-3, 1.2e-3), law, p0=1e5, friction=0.0, seed=5,
                     damping=0.5)
    deps = np.array([[0.0, 2e-3], [0.0, 0.0]])
    r.apply_strain(deps)
    return r


def test_couple_stress_is_the_contact_sum(sheared):
    """The RVE's stress and couple stress equal the sums over the touching pairs of
    -f (x) l and -m (x) l over the cell's area (f, m: force and moment on j; l the
    branch vector from i to j across the periodic image)."""
    r = sheared
    sim = r.sim
    res = r.response(tangent=False)
    b, nl = sim.bodies, sim.neighbors
    h = sim.image_matrix
    sig = np.zeros((2, 2))
    mu = np.zeros((1, 2))
    n_moment = 0
    for k, (i, j) in enumerate(nl.pairs):
        branch = b.pos[j] - b.pos[i] + h @ nl.img[k]
        if np.linalg.norm(branch) >= b.radius[i] + b.radius[j]:
            continue
        sig -= np.outer(sim.pair_state.fpair[k], branch)
        m = sim.pair_state.hist[k, 7]
        mu -= m * branch[None, :]
        n_moment += abs(m) > 0.0
    sig -= np.einsum("p,pa,pb->ab", b.mass, b.vel, b.vel)
    sig = 0.5 * (sig + sig.T) / r.volume
    np.testing.assert_allclose(res["stress"], sig, rtol=1e-12, atol=1e-9 * abs(sig).max())
    np.testing.assert_allclose(res["couple_stress"], mu / r.volume, rtol=1e-12)
    assert n_moment > 10 and np.abs(res["couple_stress"]).max() > 0.0


def test_relaxed_bodies_balance_their_moments(sheared):
    """At rest every body's torque sums to zero only with the rolling moments counted:
    the moments recorded are the ones the loop applied, with their signs."""
    sim = sheared.sim
    c = sim.contacts()
    n = sim.bodies.n
    lever = np.zeros(n)
    moment = np.zeros(n)
    cross = lambda a, f: a[:, 0] * f[:, 1] - a[:, 1] * f[:, 0]  # noqa: E731
    np.add.at(lever, c["i"], cross(c["arm_i"], -c["force"]))
    np.add.at(lever, c["j"], cross(c["arm_j"], c["force"]))
    np.add.at(moment, c["i"], -c["moment"][:, 0])
    np.add.at(moment, c["j"], c["moment"][:, 0])
    scale = np.abs(moment).max()
    assert scale > 0.0
    assert np.abs(lever + moment).max() < 0.05 * scale
    assert np.abs(lever).max() > 0.5 * scale  # the levers alone do not balance


def test_rolling_state_survives_a_snapshot_and_the_spec(sheared):
    """The longer history rows travel through snapshots bit for bit, and the law's
    plain-data form rebuilds the rolling parameters."""
    r = sheared
    law = r.law
    assert dem.contact.laws.law_from_spec(law.spec()).rolling.spec() == law.rolling.spec()
    assert r.sim.pair_state.hist.shape[1] == 10
    snap = r.snapshot()
    deps = np.array([[0.0, 1e-4], [0.0, 0.0]])
    a = r.apply_strain(deps)
    r.restore(snap)
    b = r.apply_strain(deps)
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("kwargs, key", [({"mu_roll": -0.1}, "mu_roll"),
                                         ({"mu_roll": 0.1, "eta_roll": math.nan}, "eta_roll"),
                                         ({"mu_roll": 0.1, "k_roll": -1.0}, "k_roll"),
                                         ({"mu_roll": 0.1, "mu_twist": -1.0}, "mu_twist")])
def test_bad_rolling_parameters_name_their_key(kwargs, key):
    with pytest.raises(ValueError, match=f"^{key} must be finite and >= 0"):
        dem.Rolling(**kwargs)


def test_rolling_is_refused_on_level_set_shapes():
    b = dem.Bodies.empty(2)
    b.add_shapes(dem.Box([0.01, 0.01]), [[0.0, 0.0], [0.03, 0.0]], density=2500.0)
    law = dem.LinearSpring(kn=1e5, rolling=dem.Rolling(0.1))
    with pytest.raises(ValueError, match="rolling resistance acts between spheres"):
        dem.Simulation(b, law, dt=1e-6)
