"""Compiled kernels against the pure-numpy references of ``tests/naive.py``.

- contact forces and torques of seeded random scenes (2D, 3D, open and periodic boxes,
  two sphere materials, moving tilted walls, gravity) equal the O(n^2) reference;
- the cell-list and k-d tree neighbour lists equal the brute-force list;
- no contact is ever missed by the Verlet list during a run;
- laws are the gradients of their energies;
- results do not depend on the number of numba threads.
"""

import naive
import numba
import numpy as np
import pytest

import dem
from dem.contact.laws import (
    energy_hertz_mindlin,
    energy_linear,
    law_hertz_mindlin,
    law_linear,
)
from dem.neighbors import Box, NeighborList

R = 0.01  # mean radius [m]
RHO = 2500.0  # density [kg/m^3]

# Two sphere materials (0, 1) and one wall material (2). Dashpots are large enough that
# some contacts slide and others stick, so both branches of the Coulomb cap are covered.
LAWS_PP = {
    (0, 0): dem.LinearSpring(kn=1e5, kt=4e4, mu=0.3, gamma_n=3.0, gamma_t=40.0),
    (0, 1): dem.LinearSpring(kn=2e5, kt=5e4, mu=0.5, gamma_t=60.0, restitution=0.6),
    (1, 1): dem.LinearSpring(
        kn=1.5e5, kt=3e4, mu=0.2, gamma_n=1.0, gamma_t=20.0, restitution=0.8
    ),
}
LAWS_PW = {
    (0, 2): dem.LinearSpring(kn=3e5, kt=1e5, mu=0.4, gamma_n=2.0, gamma_t=50.0),
    (1, 2): dem.LinearSpring(kn=2.5e5, kt=8e4, mu=0.6, gamma_t=30.0, restitution=0.5),
}


def law_of(bucket, a, b):
    """The law of a material pair, as the reference reads it (unordered for spheres)."""
    if bucket == "pp":
        return LAWS_PP.get((a, b)) or LAWS_PP[(b, a)]
    return LAWS_PW[(a, b)]


def random_scene(dim, box_kind, seed):
    """Overlapping polydisperse spheres with random velocities and spins.

    ``box_kind``: "open" (a moving floor and a moving tilted wall), "periodic" (all
    axes, and the moving floor) or "mixed" (periodic but the last axis, and the floor).
    """
    rng = np.random.default_rng(seed)
    side = 4 if dim == 3 else 9
    spacing = 1.85 * R
    pos = naive.lattice_spheres(rng, side**dim, dim, spacing, jitter=0.1)
    radius = R * rng.uniform(0.85, 1.15, size=pos.shape[0])
    bodies = dem.Bodies.spheres(
        pos, radius=radius, density=RHO, mat_id=rng.integers(0, 2, size=pos.shape[0])
    )
    bodies.vel[:] = rng.normal(0.0, 1.0, size=bodies.vel.shape)
    bodies.ang_vel[:] = rng.normal(0.0, 100.0, size=bodies.ang_vel.shape)
    walls = {"point": [], "normal": [], "vel": [], "mat_id": []}
    box = None
    lo = -0.5 * spacing * np.ones(dim)
    hi = lo + side * spacing
    if box_kind in ("periodic", "mixed"):
        periodic = np.ones(dim, bool)
        if box_kind == "mixed":
            periodic[-1] = False
        box = Box(lo, hi, periodic)
    floor_n = np.eye(dim)[-1]
    wall_specs = [(pos[:, -1].min() - 0.9 * R, floor_n)]
    if box_kind == "open":
        tilted = np.ones(dim)
        tilted[1:] = [0.3, -0.2][: dim - 1]
        tilted /= np.linalg.norm(tilted)
        wall_specs.append((float(np.min(pos @ tilted)) - 0.9 * R, tilted))
    for offset, normal in wall_specs:
        point = offset * normal
        vel = rng.normal(0.0, 0.5, size=dim)
        bodies.add_plane(point, normal, velocity=vel, mat_id=2)
        walls["point"].append(point), walls["normal"].append(normal)
        walls["vel"].append(vel), walls["mat_id"].append(2)
    walls = {k: np.array(v) for k, v in walls.items()}
    return bodies, walls, box


@pytest.mark.parametrize("box_kind", ["open", "periodic", "mixed"])
@pytest.mark.parametrize("dim", [2, 3])
def test_forces_match_naive_reference(dim, box_kind):
    bodies, walls, box = random_scene(dim, box_kind, seed=10 * dim + len(box_kind))
    gravity = np.array([0.7, -9.81, 2.0][:dim])
    model = dem.ContactModel(LAWS_PP, wall_law=LAWS_PW)
    sim = dem.Simulation(bodies, model, gravity=gravity, box=box, overlap_limit=1.0)
    sim.prime()
    b = sim.bodies
    s = b.ids(dem.Shape.SPHERE)
    lo, hi, per = (None, None, None) if box is None else (box.lo, box.hi, box.periodic)
    force, torque, stats = naive.linear_forces(
        b.pos[s],
        b.vel[s],
        b.ang_vel[s],
        b.radius[s],
        b.mass[s],
        b.mat_id[s],
        law_of,
        walls=walls,
        gravity=gravity,
        lo=lo,
        hi=hi,
        periodic=per,
    )
    # the scene exercises what it claims to: many contacts, sliding and sticking ones
    assert stats["contacts"] > s.size
    assert 0 < stats["sliding"] < stats["contacts"]
    np.testing.assert_allclose(
        b.force[s], force, rtol=1e-10, atol=1e-10 * np.abs(force).max()
    )
    np.testing.assert_allclose(
        b.torque[s], torque, rtol=1e-10, atol=1e-10 * np.abs(torque).max()
    )


def _pair_set(nl):
    return {
        (int(i), int(j), *map(int, im))
        for (i, j), im in zip(nl.pairs, nl.img, strict=True)
    }


@pytest.mark.parametrize("box_kind", ["open", "periodic", "mixed"])
@pytest.mark.parametrize("dim", [2, 3])
def test_neighbor_lists_cell_kdtree_and_naive_agree(dim, box_kind):
    rng = np.random.default_rng(100 + dim)
    n = 400 if dim == 3 else 300
    lo, hi = np.zeros(dim), np.full(dim, 0.15)
    pos = rng.uniform(lo, hi, size=(n, dim))
    pos[: n // 10] += 0.3 * (hi - lo)  # some bodies outside the periodic box: wrapped
    radius = rng.uniform(0.004, 0.012, size=n)
    bodies = dem.Bodies.spheres(pos, radius=radius, density=RHO)
    normals = [np.eye(dim)[-1], -np.ones(dim) / np.sqrt(dim)]
    points = [np.full(dim, 0.01), np.full(dim, 0.14)]
    for p, nw in zip(points, normals, strict=True):
        bodies.add_plane(p, nw)
    box = None
    if box_kind != "open":
        periodic = np.ones(dim, bool)
        periodic[-1] = box_kind == "periodic"
        box = Box(lo, hi, periodic)
    skin = 0.003
    lists = {}
    for backend in ("cell", "kdtree"):
        b = bodies.copy()
        lists[backend] = NeighborList(skin, backend=backend, box=box).build(b)
        wrapped = b.pos
    s = bodies.ids(dem.Shape.SPHERE)
    if box is not None:  # build wraps periodic axes into [lo, hi)
        per = box.periodic
        assert np.all((wrapped[s][:, per] >= lo[per]) & (wrapped[s][:, per] < hi[per]))
    ref = naive.sphere_pairs(
        wrapped[s],
        radius,
        skin,
        *((None,) * 3 if box is None else (lo, hi, box.periodic)),
    )
    cell, kd = _pair_set(lists["cell"]), _pair_set(lists["kdtree"])
    assert len(ref) > n  # a dense enough scene to mean something
    assert cell == ref
    assert kd == ref
    for nl in lists.values():  # sorted half list, as the loops expect
        assert np.all(nl.pairs[:, 0] < nl.pairs[:, 1])
        keys = nl.pairs[:, 0].astype(np.int64) * bodies.n + nl.pairs[:, 1]
        assert np.all(np.diff(keys) > 0)
        ref_w = naive.wall_pairs(
            wrapped[s], radius, np.array(points), np.array(normals), skin
        )
        got_w = {(int(i), int(w) - n) for i, w in nl.wall_pairs}
        assert got_w == ref_w
        assert np.all(np.diff(nl.wall_pairs[:, 0]) >= 0)


def _elastic_gas(dim, n, seed):
    """Frictionless gas on a lattice; velocities ~ ``N(0, 1)`` [m/s], to be rescaled."""
    rng = np.random.default_rng(seed)
    pos = naive.lattice_spheres(rng, n, dim, 2.3 * R, jitter=0.02)
    bodies = dem.Bodies.spheres(pos, radius=R * rng.uniform(0.9, 1.1, n), density=RHO)
    bodies.vel[:] = rng.normal(0.0, 1.0, size=bodies.vel.shape)
    return bodies


@pytest.mark.parametrize("dim", [2, 3])
def test_no_contact_missed_while_list_is_stale(dim):
    """Forces after every step equal the brute-force forces at that step's positions.

    Frictionless, undamped: forces depend on positions only. A thin skin (0.02 R) and
    bodies moving about 0.02 R per step force frequent rebuilds, so a list that is
    checked before the drift (and so misses contacts made during the drift) is caught.
    """
    law = dem.LinearSpring(kn=1e3)
    bodies = _elastic_gas(dim, 27 if dim == 3 else 25, seed=7 + dim)
    dt = 0.1 * dem.Simulation(bodies.copy(), law).dt_crit
    bodies.vel *= 0.02 * R / dt

    def mismatch(sim):
        b = sim.bodies
        f, _, st = naive.linear_forces(
            b.pos, b.vel, b.ang_vel, b.radius, b.mass, b.mat_id, lambda *a: law
        )
        return np.abs(b.force - f).max() / max(np.abs(f).max(), 1e-300), st["contacts"]

    rec = dem.Record(mismatch, every=1)
    sim = dem.Simulation(bodies, law, dt=dt, skin=0.02 * R, observers=[rec])
    sim.run(400)
    err, contacts = np.array(rec.values).T
    assert sim.neighbors.n_builds > 20  # the list was stale often
    assert contacts.sum() > 100  # and bodies touched
    assert err.max() < 1e-12


def test_contact_made_during_drift_is_not_missed():
    """Head-on pair, thin skin: contact starts in a step whose drift voids the list.

    Gap ``skin + eps``, each sphere moving ``0.3 skin`` per step: after two drifts the
    spheres overlap by ``0.2 skin - eps``, both having moved ``0.6 skin > skin / 2``.
    """
    skin, v = 1e-3, 1.0
    dt = 0.3 * skin / v
    eps = 1e-6
    pos = [[-R - 0.5 * (skin + eps), 0.0, 0.0], [R + 0.5 * (skin + eps), 0.0, 0.0]]
    bodies = dem.Bodies.spheres(pos, radius=R, density=RHO, vel=[[v, 0, 0], [-v, 0, 0]])
    law = dem.LinearSpring(kn=1e3)
    track = dem.Record(
        lambda s: (
            2 * R - (s.bodies.pos[1, 0] - s.bodies.pos[0, 0]),
            s.bodies.force[1, 0],
        )
    )
    sim = dem.Simulation(bodies, law, dt=dt, skin=skin, observers=[track])
    sim.run(3)
    ov, f = np.array(track.values).T
    assert ov[0] < 0.0 < ov[1]
    np.testing.assert_allclose(f[1:], law.kn * ov[1:], rtol=1e-12)


def test_prime_with_a_list_gone_stale_rebuilds_it():
    """A scene changed between runs (a law swapped, as RVE.set_friction does, marks it
    unprimed) may have bodies past half the skin from the list's build: priming
    rebuilds the list and finds the new contact instead of stopping."""
    skin = 1e-3
    pos = [[-R - skin, 0.0, 0.0], [R + skin, 0.0, 0.0]]
    bodies = dem.Bodies.spheres(pos, radius=R, density=RHO)
    law = dem.LinearSpring(kn=1e3)
    sim = dem.Simulation(bodies, law, skin=skin)
    sim.run(1)
    builds = sim.neighbors.n_builds
    bodies.pos[:, 0] *= (R - 0.1 * skin) / (R + skin)  # both moved 1.1 skin: touching
    sim._primed = False
    sim.prime()
    assert sim.neighbors.n_builds == builds + 1
    ov = 2 * R - (bodies.pos[1, 0] - bodies.pos[0, 0])
    np.testing.assert_allclose(bodies.force[1, 0], law.kn * ov, rtol=1e-12)


@pytest.mark.parametrize(("dim", "law"), [
    (2, dem.LinearSpring(kn=1e5, kt=4e4, mu=0.3, gamma_t=40.0)),
    (3, dem.LinearSpring(kn=1e5, kt=4e4, mu=0.3, gamma_t=40.0)),
    (3, dem.HertzMindlin(young=7e7, poisson=0.3, restitution=0.5, mu=0.3)),
], ids=["linear_dashpot-2", "linear_dashpot-3", "hertz_damped-3"])
def test_priming_a_sliding_damped_contact_keeps_its_spring(dim, law):
    """A pass that evaluates forces without advancing time (dt = 0: priming) finds a
    contact that slides, its tangential dashpot alone past the Coulomb limit. The
    spring keeps its length (the limit of the sliding rule as dt -> 0); it was once
    divided by dt = 0, and the first step of such a scene blew up. Hertz in 3D only:
    the laws' kernels are the same in 2D, and a 2D Hertz loop would be compiled for
    this test alone."""
    pos = np.zeros((2, dim))
    pos[1, 0] = 1.9 * R
    bodies = dem.Bodies.spheres(pos, radius=R, density=RHO)
    bodies.vel[1, 1] = 50.0  # sliding past body 0: the dashpot alone is past the limit
    sim = dem.Simulation(bodies, law)
    sim.prime()
    hist = sim.pair_state.hist
    assert np.all(hist == 0.0)
    fn = bodies.force[1, 0]
    assert fn > 0.0
    np.testing.assert_allclose(abs(bodies.force[1, 1]), law.mu * fn, rtol=1e-12)
    sim.run(20)
    assert np.all(np.isfinite(bodies.pos)) and np.all(np.isfinite(sim.pair_state.hist))


@pytest.mark.parametrize("name", ["linear", "hertz_mindlin"])
def test_law_force_is_minus_energy_gradient(name):
    """Normal force = dU/d(overlap); tangential spring force = -dU/ds (no sliding)."""
    if name == "linear":
        law, force, energy = (
            dem.LinearSpring(kn=1e5, kt=3e4, mu=0.5),
            law_linear,
            energy_linear,
        )
    else:
        law = dem.HertzMindlin(young=1e8, poisson=0.3, restitution=1.0, mu=0.5)
        force, energy = law_hertz_mindlin, energy_hertz_mindlin
    p = law.row()
    r_eff, m_eff, ov = 0.005, 0.01, 2e-5
    n = np.array([0.6, 0.0, 0.8])
    s = np.array([[-0.8e-6, 0.3e-6, 0.6e-6]])  # in the tangent plane of n

    def u(ov_, s_):
        return energy(ov_, r_eff, p, np.array([s_]), 0)

    # normal part without a tangential spring (Mindlin's stiffness depends on overlap)
    table = p[None, None, :]  # the force kernel reads table[mat_a, mat_b]
    f0 = np.array(
        force(
            ov, *n, 0.0, 0.0, 0.0, r_eff, m_eff, table, 0, 0, np.zeros((1, 3)), 0, 0.0
        )
    )
    h = 1e-9
    dudov = (u(ov + h, np.zeros(3)) - u(ov - h, np.zeros(3))) / (2 * h)
    np.testing.assert_allclose(f0, dudov * n, rtol=1e-6, atol=1e-12)
    f = np.array(
        force(ov, *n, 0.0, 0.0, 0.0, r_eff, m_eff, table, 0, 0, s.copy(), 0, 0.0)
    )
    np.testing.assert_allclose(f @ n, f0 @ n, rtol=1e-14)
    dh = 1e-8
    duds = np.array(
        [(u(ov, s[0] + dh * e) - u(ov, s[0] - dh * e)) / (2 * dh) for e in np.eye(3)]
    )
    duds_t = duds - (duds @ n) * n
    np.testing.assert_allclose(
        f - (f @ n) * n, -duds_t, rtol=1e-6, atol=1e-9 * np.abs(f).max()
    )


def _falling_box(seed):
    """A few hundred spheres with friction dropped into a box with five walls."""
    rng = np.random.default_rng(seed)
    pos = naive.lattice_spheres(rng, 343, 3, 2.0 * R, jitter=0.02) + R
    bodies = dem.Bodies.spheres(pos, radius=R * rng.uniform(0.9, 1.0, 343), density=RHO)
    bodies.vel[:] = rng.normal(0.0, 0.3, size=bodies.vel.shape)
    width = 7 * 2.0 * R + R
    for a in range(3):
        normal = np.eye(3)[a]
        bodies.add_plane(np.zeros(3), normal)
        if a < 2:
            bodies.add_plane(width * normal, -normal)
    return bodies


def test_results_do_not_depend_on_thread_count():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs NUMBA_NUM_THREADS >= 2 to compare 1 and 2 threads")
    law = dem.LinearSpring(kn=1e5, kt=4e4, mu=0.4, restitution=0.5)
    initial = _falling_box(seed=3)
    results, kinds = [], []
    for threads in (1, 2):
        used = dem.Record(lambda s: numba.get_num_threads(), every=100)
        sim = dem.Simulation(
            initial.copy(),
            law,
            gravity=[0.0, 0.0, -9.81],
            threads=threads,
            observers=[used],
        )
        sim.run(300)
        assert set(used.values) == {threads}  # the loops really ran on that many
        kinds.append(sim._loop_args(0, True, False)[0].dem_recipe[3]["serial"])
        results.append((sim.bodies, sim.contacts()))
    assert kinds == [True, False]  # the one-thread loop, then the threaded one
    (b1, c1), (b2, c2) = results
    assert c1["i"].size > 20  # bodies and walls in contact, not all in free flight
    for name in ("pos", "vel", "rot", "ang_vel", "force", "torque"):
        assert np.array_equal(getattr(b1, name), getattr(b2, name)), name
