"""Rigid level-set bodies in motion: conservation, collisions, walls, growth.

- A torque-free tumbling box keeps its angular momentum to round-off and its kinetic
  energy to the splitting's O(dt^2) bounded error (no drift), even when it spins about
  its unstable middle axis.
- An undamped, frictionless collision of two polyhedra (and of two polygons) gives back
  the kinetic energy (< 1e-3) and keeps linear and angular momentum to round-off: the
  contact force is applied to both bodies at one point, equal and opposite.
- Two random, spinning polyhedra colliding through edge-on-edge contacts keep kinetic
  plus elastic energy within 1e-4 throughout (2e-6 measured) and momentum to
  round-off: the separating-axis contact is the gradient of ``kn ov^2 / 2`` on each
  piece.
- The normal force stays continuous as a corner slides over a face.
- A box at rest on a wall carries its weight; a growing box (ShapeScale) gains mass as
  s^d; results do not depend on the thread count.
"""

import numpy as np
import pytest

import dem
from dem.observers import angular_momentum, elastic_energy, kinetic_energy
from dem.rotation import matrix_to_quat, quat_to_matrix
from dem.shapes import Box, ConvexPolygon, ConvexPolyhedron
from dem.state_objects import ShapeScale

RHO = 1000.0
ELASTIC = dem.LinearSpring(kn=1e5)


def _quat(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])


def _momenta(b):
    p = (b.mass[:, None] * b.vel)[~b.is_fixed].sum(axis=0)
    return p, angular_momentum(b)


def test_torque_free_box_keeps_angular_momentum_and_energy():
    b = dem.Bodies.empty(3)
    b.add_shapes(Box([0.3, 0.2, 0.1]), [[0.0, 0.0, 0.0]], RHO,
                 rot=_quat([1, 2, 3], 0.7), ang_vel=[[0.1, 4.0, 0.1]])  # near the middle axis
    sim = dem.Simulation(b, ELASTIC, dt=2e-3, threads=1)
    l0 = angular_momentum(b)
    e0 = sum(kinetic_energy(b))
    from dem.observers import body_frame
    energies, spin_y = [], []
    for _ in range(50):
        sim.run(40)
        energies.append(sum(kinetic_energy(b)))
        spin_y.append(body_frame(b.rot, b.ang_vel)[0, 1])
    # round-off only: each step turns L between frames a dozen times (2000 steps)
    assert np.linalg.norm(angular_momentum(b) - l0) < 1e-9 * np.linalg.norm(l0)
    err = np.abs(np.array(energies) - e0) / e0
    assert err.max() < 1e-5  # bounded, O(dt^2): measured 9e-7
    # it really tumbled: the spin about the middle (y) axis of the body reversed
    assert min(spin_y) < -2.0 and spin_y[-1] > 2.0


@pytest.mark.parametrize("dim", [2, 3])
def test_elastic_polytope_collision_conserves(dim):
    if dim == 2:
        shape = ConvexPolygon.regular(5, 0.05)
        rot_a, rot_b = [0.3], [1.1]
        pos = [[0.0, 0.0], [0.12, 0.013]]
        vel = [[1.0, 0.0], [-0.5, 0.1]]
        spin = [[2.0], [-1.0]]
    else:
        # a corner of A (turned so that a body diagonal points along +x) hits a face
        # of B: the contact stays a corner in a face, whose depth is a smooth function
        # of the pose (edges meeting edges: the next test)
        shape = ConvexPolyhedron.from_vertices(np.array(
            [[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * 0.03)
        q1 = _quat([0, 0, 1], np.pi / 4)
        q2 = _quat([0, 1, 0], -np.arctan(1 / np.sqrt(2)))
        from dem.rotation import quat_mul
        rot_a, rot_b = [quat_mul(q2, q1)], [_quat([1, 0, 0], 0.0)]
        pos = [[0.0, 0.0, 0.0], [0.11, 0.004, -0.003]]
        vel = [[1.0, 0.0, 0.0], [-0.5, 0.05, 0.0]]
        spin = [[0.5, 0.0, 0.0], [0.0, 0.0, 0.0]]
    b = dem.Bodies.empty(dim)
    b.add_shapes(shape, pos[:1], RHO, rot=rot_a, vel=vel[:1], ang_vel=spin[:1])
    b.add_shapes(shape, pos[1:], RHO, rot=rot_b, vel=vel[1:], ang_vel=spin[1:])
    sim = dem.Simulation(b, ELASTIC, threads=1)
    sim.dt = 0.01 * sim.dt_crit
    p0, l0 = _momenta(b)
    e0 = sum(kinetic_energy(b))
    touched = 0
    for _ in range(400):
        sim.run(25)
        touched += len(sim.contacts()["i"])
    assert touched > 0, "the bodies never met"
    assert len(sim.contacts()["i"]) == 0, "still in contact at the end"
    p1, l1 = _momenta(b)
    scale = np.sum(b.mass * np.linalg.norm(b.vel, axis=1))
    assert np.linalg.norm(p1 - p0) < 1e-12 * scale
    # round-off of the frame rotations (see the tumbling box)
    assert np.linalg.norm(l1 - l0) < 1e-9 * (np.linalg.norm(l0) + scale * 0.1)
    assert abs(sum(kinetic_energy(b)) - e0) / e0 < 1e-3


def test_elastic_random_polyhedra_collision_conserves_energy():
    """Two random convex polyhedra, spinning, collide edge on edge (linear spring, no
    damping, no friction): kinetic plus elastic energy is kept through the contact.

    The run ends once they have parted (400 steps). Spinning, they graze again some
    3500 steps later, where the axis of least overlap jumps by 36 degrees between two
    facets: the integrator's O(dt) error there is 8e-4 (docs/shapes.md, limits).
    """
    rng = np.random.default_rng(2)
    shapes = [ConvexPolyhedron.from_vertices(0.02 * rng.normal(size=(12, 3)))
              for _ in range(2)]
    q = rng.normal(size=(2, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    b = dem.Bodies.empty(3)
    b.add_shapes(shapes[0], [[0.0, 0.0, 0.0]], RHO, rot=q[:1], vel=[[1.0, 0.0, 0.0]],
                 ang_vel=[[3.0, -2.0, 1.0]])
    # 0.42 mm short of touching along x (they touch at x = 0.04118)
    b.add_shapes(shapes[1], [[0.0416, 0.01, -0.008]], RHO, rot=q[1:],
                 vel=[[-0.5, 0.05, 0.0]], ang_vel=[[-1.0, 2.0, 4.0]])
    sim = dem.Simulation(b, ELASTIC, threads=1)
    sim.dt = 0.02 * sim.dt_crit
    p0 = _momenta(b)[0]
    e0 = sum(kinetic_energy(b))
    err, touched, edge_on_edge = 0.0, 0, 0
    for _ in range(40):
        sim.run(10)
        err = max(err, abs(sum(kinetic_energy(b)) + elastic_energy(sim) - e0) / e0)
        c = sim.contacts()
        if len(c["i"]):
            touched += 1
            # an edge across an edge: the normal is no face normal of either body
            along = max(np.abs(c["normal"][0] @ quat_to_matrix(b.rot[i])
                               @ b.table.shapes[b.shape[i]].normals.T).max()
                        for i in (0, 1))
            edge_on_edge += int(along < 1.0 - 1e-6)
    assert touched > 5 and edge_on_edge > 5, (touched, edge_on_edge)
    assert len(sim.contacts()["i"]) == 0, "still in contact at the end"
    scale = np.sum(b.mass * np.linalg.norm(b.vel, axis=1))
    assert np.linalg.norm(_momenta(b)[0] - p0) < 1e-12 * scale
    assert err < 1e-4


def test_normal_force_continuous_as_corner_slides_over_face():
    """A square's corner pressed into a fixed box's face and dragged along it."""
    b = dem.Bodies.empty(2)
    base = b.add_shapes(Box([1.0, 0.1]), [[0.0, 0.0]], RHO)
    tip = b.add_shapes(Box([0.05, 0.05]), [[-0.5, 0.1 + 0.05 * np.sqrt(2) - 1e-4]], RHO,
                       rot=[np.pi / 4])
    b.fix(base)
    b.fix(tip, velocity=[1.0, 0.0])
    sim = dem.Simulation(b, ELASTIC, dt=1e-3, threads=1)
    forces = []
    for _ in range(100):
        sim.run(10)
        c = sim.contacts()
        assert len(c["i"]) == 1
        forces.append(np.linalg.norm(c["force"][0]))
        assert np.allclose(np.abs(c["normal"][0]), [0.0, 1.0], atol=1e-12)
    forces = np.array(forces)
    assert np.allclose(forces, 1e5 * 1e-4, rtol=1e-9)


def test_box_rests_on_wall_and_carries_its_weight():
    b = dem.Bodies.empty(3)
    box = b.add_shapes(Box([0.05, 0.03, 0.02]), [[0.0, 0.0, 0.025]], RHO,
                       rot=_quat([1, 1, 0], 0.2))
    b.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    law = dem.LinearSpring(kn=1e5, kt=5e4, mu=0.5, restitution=0.3)
    sim = dem.Simulation(b, law, gravity=[0.0, 0.0, -9.81], damping=0.3, threads=1)
    sim.run(40000)
    weight = b.mass[box[0]] * 9.81
    fz = sim.wall_forces()[1][2]
    assert fz == pytest.approx(-weight, rel=1e-3)  # the wall is pushed down by the box
    assert np.linalg.norm(b.vel[box[0]]) < 1e-4
    # it settled flat: the smallest axis (z of the body) is vertical
    assert abs(quat_to_matrix(b.rot[box[0]])[2, 2]) == pytest.approx(1.0, abs=1e-4)


def test_staggered_square_settles_on_a_square():
    """A square dropped onto a fixed one with 0.6 of a side of overlap, under gravity
    with local damping: it comes to rest (velocities at round-off), carried by one
    contact whose force is its weight. Before the two corners' points were blended it
    rocked between them for ever, at 0.1 rad/s."""
    h = 0.01
    b = dem.Bodies.empty(2)
    b.fix(b.add_shapes(Box([h, h]), [[0.0, h]], RHO))
    top = b.add_shapes(Box([h, h]), [[0.6 * h, 3 * h + 1e-5]], RHO)
    law = dem.LinearSpring(kn=1e5, kt=5e4, mu=0.5, restitution=0.3)
    sim = dem.Simulation(b, law, gravity=[0.0, -9.81], damping=0.3, threads=1)
    sim.run(20000)
    assert np.abs(b.vel[top]).max() < 1e-12
    assert np.abs(b.ang_vel[top]).max() < 1e-10
    c = sim.contacts()
    assert len(c["i"]) == 1
    np.testing.assert_allclose(np.abs(c["force"][0]), [0.0, b.mass[top[0]] * 9.81],
                               atol=1e-9 * b.mass[top[0]] * 9.81)


def test_polygon_pile_comes_to_rest():
    """30 regular polygons (4 to 7 sides) dropped into a box settle to rest: velocities
    fall by eight orders of magnitude and the floor carries their weight. Faces resting
    on faces, corners in corners: where the point or the normal jumps between two
    corners as a body rocks, this pile was still moving at 1.5e-4 m/s at the end."""
    rng = np.random.default_rng(3)
    b = dem.Bodies.empty(2)
    r, side = 0.01, 10
    for k in range(30):
        shape = ConvexPolygon.regular(int(rng.integers(4, 8)), r * rng.uniform(0.7, 1.0))
        b.add_shapes(shape, [[(k % side + 0.5) * 2.2 * r, (k // side + 0.5) * 2.2 * r]],
                     RHO, rot=[rng.uniform(0, np.pi)])
    floor = b.add_plane([0.0, 0.0], [0.0, 1.0])
    b.add_plane([0.0, 0.0], [1.0, 0.0])
    b.add_plane([side * 2.2 * r, 0.0], [-1.0, 0.0])
    law = dem.LinearSpring(kn=1e5, kt=5e4, mu=0.5, restitution=0.3)
    sim = dem.Simulation(b, law, gravity=[0.0, -9.81], damping=0.5, threads=1)
    sim.run(33000)  # max |v| falls about 7x every 3000 steps from step 12000 on
    assert len(sim.contacts()["i"]) > 35
    assert np.abs(b.vel).max() < 1e-8
    assert np.abs(b.ang_vel).max() < 1e-6
    weight = b.mass[~b.is_fixed].sum() * 9.81
    assert sim.wall_forces()[floor][1] == pytest.approx(-weight, rel=1e-6)


def test_growing_box_follows_its_scale():
    b = dem.Bodies.empty(2)
    ids = b.add_shapes(Box([0.05, 0.02]), [[0.0, 0.0]], RHO)
    m0, i0, r0 = b.mass[0], b.inertia[0, 0], b.radius[0]
    grow = ShapeScale([b.shape[ids[0]]], lambda s, t: np.full_like(s, 0.5))
    sim = dem.Simulation(b, ELASTIC, dt=1e-3, state_objects=[grow], threads=1)
    sim.run(200)  # ds/dt = 0.5 for 0.2 s: s = 1.1 exactly (RK2 of a constant rate)
    s = 1.1
    assert b.table.scale[0] == pytest.approx(s, rel=1e-12)
    assert b.mass[0] == pytest.approx(m0 * s**2, rel=1e-12)
    assert b.inertia[0, 0] == pytest.approx(i0 * s**4, rel=1e-12)
    assert b.radius[0] == pytest.approx(r0 * s, rel=1e-12)


def _pile(dim, seed):
    """40 shapes on a lattice with small gaps, random velocities: many contacts at once."""
    rng = np.random.default_rng(seed)
    b = dem.Bodies.empty(dim)
    shape = ConvexPolygon.regular(6, 0.01) if dim == 2 else Box([0.01, 0.008, 0.006])
    n = 40
    side = 8 if dim == 2 else 4
    # 2D: hexagons in any orientation; 3D: boxes nearly aligned, 0.2 mm apart
    spacing = (2.0 * shape.bounding_radius if dim == 2 else 2.0 * shape.half_extents) + 0.0002
    k = np.arange(n)
    pos = np.zeros((n, dim))
    pos[:, 0] = spacing[0] * (k % side) if dim == 3 else spacing * (k % side)
    if dim == 2:
        pos[:, 1] = spacing * (0.6 + k // side)
    else:
        pos[:, 1] = spacing[1] * ((k // side) % side)
        pos[:, 2] = spacing[2] * (0.6 + k // side**2)
    rot = rng.uniform(0, np.pi, n) if dim == 2 else np.stack(
        [_quat(rng.normal(size=3), rng.uniform(-0.005, 0.005)) for _ in range(n)])
    b.add_shapes(shape, pos, RHO, rot=rot, vel=rng.normal(0.0, 0.1, size=(n, dim)))
    b.add_plane(np.zeros(dim), np.eye(dim)[-1])
    return b


@pytest.mark.parametrize("dim", [2, 3])
def test_thread_count_does_not_change_a_shape_scene(dim):
    import numba
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs two numba threads")
    law = dem.LinearSpring(kn=1e4, kt=5e3, mu=0.4, restitution=0.5)
    g = -9.81 * np.eye(dim)[-1]
    runs, touching = [], 0
    for threads in (1, 2):
        b = _pile(dim, 7)
        sim = dem.Simulation(b, law, gravity=g, threads=threads)
        for _ in range(6):
            sim.run(100)
            touching += len(sim.contacts()["i"]) if threads == 1 else 0
        runs.append(b)
    assert touching > 10
    assert np.array_equal(runs[0].pos, runs[1].pos)
    assert np.array_equal(runs[0].rot, runs[1].rot)


def test_principal_frame_placement():
    """A box given by rotated, shifted corners lands where its corners say."""
    rng = np.random.default_rng(2)
    r = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    r *= np.sign(np.linalg.det(r))
    h = np.array([0.3, 0.2, 0.1])
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                        for sz in (-1, 1)]) * h
    shift = np.array([0.1, -0.2, 0.05])
    poly = ConvexPolyhedron.from_vertices(corners @ r.T + shift)
    b = dem.Bodies.empty(3)
    b.add_shapes(poly, [[1.0, 2.0, 3.0]], RHO)
    assert np.allclose(b.pos[0], [1.1, 1.8, 3.05], atol=1e-12)
    assert np.allclose(np.sort(b.inertia[0]), np.sort(
        RHO * 8 * h.prod() / 3 * np.array([h[1]**2 + h[2]**2, h[0]**2 + h[2]**2,
                                            h[0]**2 + h[1]**2])), rtol=1e-10)
    assert matrix_to_quat(np.eye(3))[0] == 1.0
