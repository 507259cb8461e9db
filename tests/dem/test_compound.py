"""Non-convex bodies as unions of convex parts (:class:`dem.Compound`).

- Mass properties: exact for polytope parts however they overlap (inclusion-exclusion
  over their intersections), exact for spheres that overlap nothing, and on a grid
  for overlapping spheres, against closed forms and a slice-by-slice integral.
- The SDF is the parts' minimum; a body is placed in its principal frame.
- A compound of one part is that part: the same run, bit for bit.
- Each touching pair of parts is a contact: two dumbbells side by side touch twice, a
  dumbbell on a floor twice, and the contact forces carry the weight.
- An undamped, frictionless collision of two 3D compounds keeps kinetic energy
  (< 1e-3) and momentum (round-off); friction history is carried per part pair across
  neighbour-list rebuilds.
- Surfaces of the parts reach the HDF5 output; a checkpoint of bodies round-trips and a
  crafted part pool is refused.
"""

import math

import h5py
import numpy as np
import pytest
from scipy.integrate import quad

import dem
from dem.io.checkpoint import read_bodies, write_bodies
from dem.io.geometry import shape_surfaces
from dem.observers import angular_momentum, kinetic_energy
from dem.rotation import quat_to_matrix
from dem.shapes import Box, Compound, ConvexPolygon, ConvexPolyhedron, Sphere

RHO = 1000.0


def _quat(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])


# --------------------------------------------------------------------------- mass
def test_overlapping_bars_count_their_intersection_once():
    # a 3D cross of three bars 3 x 1 x 1 through the origin: 7 unit cubes
    bars = [Box(np.where(np.arange(3) == a, 1.5, 0.5)) for a in range(3)]
    cross = Compound([(bar, [0.0, 0.0, 0.0]) for bar in bars])
    m, c, inertia = cross.mass_properties(2.0)
    assert m == pytest.approx(14.0, rel=1e-12)
    assert np.abs(c).max() < 1e-12
    # about each axis: 7 cubes about their own centres, plus the 4 arm cubes off that
    # axis at distance 1 (the 2 on it add nothing)
    cube = 2.0 / 6.0  # a unit cube of mass 2 about its centre
    expected = 7 * cube + 4 * 2.0
    assert np.allclose(inertia, expected * np.eye(3), rtol=1e-12, atol=1e-12)


def test_rotated_polyhedron_part_keeps_its_mass_properties():
    rng = np.random.default_rng(4)
    poly = ConvexPolyhedron.from_vertices(rng.normal(size=(10, 3)))
    q = _quat([1.0, -2.0, 0.5], 0.9)
    one = Compound([(poly, [0.3, -0.2, 1.0], q)])
    m0, c0, i0 = poly.mass_properties(RHO)
    m1, c1, i1 = one.mass_properties(RHO)
    assert m1 == pytest.approx(m0, rel=1e-12)
    # the part's own frame sits at the offset, turned by q: so do its centroid and
    # its inertia
    r = quat_to_matrix(q)
    assert np.allclose(c1, r @ c0 + [0.3, -0.2, 1.0], atol=1e-12)
    assert np.allclose(i1, r @ i0 @ r.T, atol=1e-10 * np.abs(i0).max())


def _two_spheres_reference(r, sep, dim):
    """Volume and the moments about the union's centroid of two equal spheres (disks)
    with centres ``sep`` apart on x: slices perpendicular to x, integrated by quad."""
    def rho(x):  # half-width of the slice at x (centres at 0 and sep)
        return math.sqrt(max(r * r - min(x * x, (x - sep) ** 2), 0.0))

    lo, hi, mid = -r, sep + r, 0.5 * sep
    opts = dict(points=[mid], limit=200, epsabs=0.0, epsrel=1e-13)
    if dim == 3:
        vol = quad(lambda x: math.pi * rho(x) ** 2, lo, hi, **opts)[0]
        ixx = quad(lambda x: math.pi * rho(x) ** 4 / 2, lo, hi, **opts)[0]
        iyy = quad(lambda x: math.pi * rho(x) ** 4 / 4 + (x - mid) ** 2 * math.pi
                   * rho(x) ** 2, lo, hi, **opts)[0]
        return vol, np.array([ixx, iyy, iyy])
    area = quad(lambda x: 2 * rho(x), lo, hi, **opts)[0]
    polar = quad(lambda x: 2 * rho(x) ** 3 / 3 + (x - mid) ** 2 * 2 * rho(x), lo, hi,
                 **opts)[0]
    return area, np.array([polar])


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("sep", [0.3, 1.2])
def test_overlapping_spheres_on_the_grid(dim, sep):
    r = 0.7
    zero = np.zeros(dim)
    shift = np.eye(dim)[0] * sep
    union = Compound([(Sphere(r), zero), (Sphere(r), shift)])
    vol, moments = _two_spheres_reference(r, sep, dim)
    m, c, _ = union.mass_properties(1.0)
    assert c == pytest.approx(0.5 * shift, abs=1e-5 * r)
    # the module's stated bounds
    tol_v, tol_i = (1e-4, 5e-4) if dim == 3 else (1e-6, 1e-5)
    assert abs(m - vol) / vol < tol_v
    got = union.principal(1.0)[0].principal_moments(1.0)
    assert np.abs(np.sort(got) - np.sort(moments)).max() / moments.max() < tol_i


def test_spheres_that_overlap_nothing_are_exact():
    r, d = 0.5, 1.0  # touching: still exact
    pair = Compound([(Sphere(r), [0.0, 0.0, 0.0]), (Sphere(r), [d, 0.0, 0.0]),
                     (Box([0.1, 0.1, 0.1]), [0.5, 2.0, 0.0])])
    m, c, inertia = pair.mass_properties(1.0)
    vs, vb = 4.0 / 3.0 * math.pi * r**3, 0.008
    assert m == pytest.approx(2 * vs + vb, rel=1e-14)
    first = np.array([vs * d + vb * 0.5, vb * 2.0, 0.0])
    assert c == pytest.approx(first / m, rel=1e-12)
    # parallel axes about the centroid: spheres 2/5 m r^2, the box m (b^2 + c^2) / 3
    offsets = np.array([[0.0, 0.0, 0.0], [d, 0.0, 0.0], [0.5, 2.0, 0.0]]) - c
    own = [0.4 * vs * r * r * np.eye(3)] * 2 + [vb * 0.02 / 3.0 * np.eye(3)]
    expected = sum(i0 + mk * (o @ o * np.eye(3) - np.outer(o, o))
                   for i0, mk, o in zip(own, [vs, vs, vb], offsets, strict=True))
    assert np.allclose(inertia, expected, rtol=1e-12, atol=1e-14)


def test_sdf_is_the_minimum_of_the_parts():
    rng = np.random.default_rng(3)
    tri = ConvexPolygon([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    shape = Compound([(Box([0.5, 0.2]), [0.0, 0.0], 0.4), (tri, [0.3, 0.1], -1.0),
                      (Sphere(0.3), [-0.6, 0.0])])
    x = rng.uniform(-2.0, 2.0, size=(400, 2))
    ref = np.full(len(x), np.inf)
    for part, rot, off in shape.parts:
        local = (x - off) @ rot
        d = (np.linalg.norm(local, axis=1) - part.radius if isinstance(part, Sphere)
             else part.sdf(local))
        ref = np.minimum(ref, d)
    assert np.array_equal(shape.sdf(x), ref)
    assert shape.sdf([0.0, 0.0]) < 0.0 and shape.sdf([-0.6, 0.0]) == pytest.approx(-0.3)


def test_body_sits_in_its_principal_frame():
    L = Compound([(Box([0.5, 0.1, 0.2]), [0.0, 0.0, 0.0]),
                  (Box([0.1, 0.5, 0.2]), [-0.4, 0.4, 0.0], _quat([1, 1, 0], 0.3))])
    b = dem.Bodies.empty(3)
    b.add_shapes(L, [[1.0, 2.0, 3.0]], RHO)
    shape, rot, c = L.principal(RHO)
    # the body's centre is the centroid; its inertia is diagonal in the body frame
    assert np.allclose(b.pos[0], np.array([1.0, 2.0, 3.0]) + c, atol=1e-12)
    m, c0, inertia = shape.mass_properties(RHO)
    assert np.abs(c0).max() < 1e-12
    assert np.abs(inertia - np.diag(np.diag(inertia))).max() < 1e-10 * inertia.max()
    assert np.allclose(b.inertia[0], np.diag(inertia))
    # a world point: the body's SDF through its pose equals the compound's in its frame
    rng = np.random.default_rng(0)
    x = rng.uniform(-1.0, 1.0, size=(50, 3))
    world = (x @ rot.T + c) + [1.0, 2.0, 3.0]
    body = (world - b.pos[0]) @ quat_to_matrix(b.rot[0])
    assert np.allclose(shape.sdf(body), L.sdf(x @ rot.T + c), atol=1e-12)


def test_bad_parts_are_refused():
    with pytest.raises(ValueError, match="at least one part"):
        Compound([])
    with pytest.raises(ValueError, match="mix dimensions"):
        Compound([(Box([1.0, 1.0]), [0.0, 0.0]), (Box([1.0, 1.0, 1.0]), [0.0, 0, 0])])
    with pytest.raises(ValueError, match="offset must be 2"):
        Compound([(Box([1.0, 1.0]), [0.0, 0.0, 0.0])])
    with pytest.raises(ValueError, match="cannot hold a compound"):
        Compound([(Compound([(Box([1.0, 1.0]), [0.0, 0.0])]), [0.0, 0.0])])
    with pytest.raises(ValueError, match="proper rotation"):
        Compound([(Box([1.0, 1.0, 1.0]), [0.0, 0.0, 0.0], -np.eye(3))])


# --------------------------------------------------------------------------- dynamics
def _pile(shape_of, dim):
    """Three bodies of ``shape_of(k)`` falling onto a floor and onto each other."""
    b = dem.Bodies.empty(dim)
    if dim == 2:
        places = [[0.0, 0.25], [0.55, 0.3], [0.2, 0.9]]
        rots = [[0.1], [-0.4], [0.9]]
    else:
        places = [[0.0, 0.0, 0.25], [0.55, 0.05, 0.3], [0.2, -0.05, 0.9]]
        rots = [_quat([1, 2, 3], 0.2), _quat([0, 1, 1], -0.5), _quat([3, 0, 1], 1.0)]
    for k in range(3):
        b.add_shapes(shape_of(k), [places[k]], RHO, rot=[rots[k]])
    b.add_plane(np.zeros(dim), np.eye(dim)[-1])
    return b


@pytest.mark.parametrize("dim", [2, 3])
def test_a_compound_of_one_part_is_that_part(dim):
    """A pile of one-part compounds runs bit for bit as the pile of the parts
    themselves: the part poses, the expanded lists and the part radii are exact."""
    if dim == 2:
        shapes = [Box([0.2, 0.1]), ConvexPolygon.regular(5, 0.15), Box([0.1, 0.1])]
    else:
        shapes = [Box([0.2, 0.1, 0.15]), ConvexPolyhedron.extrude(
            ConvexPolygon.regular(5, 0.15), 0.2).principal()[0], Box([0.1, 0.1, 0.1])]
    wrapped = _pile(lambda k: Compound([(shapes[k], np.zeros(dim))]), dim)
    t = wrapped.table
    plain = wrapped.copy()  # the same bodies, each its own part
    for k in range(3):
        first = t.cstart[wrapped.shape[k]]
        assert not t.part_off[first].any() and t.part_rot[first, 0] == (dim == 3)
        plain.kind[k], plain.shape[k] = t.part_kind[first], t.part_row[first]
    law = dem.LinearSpring(kn=1e5, kt=2e4, mu=0.4, restitution=0.5)
    runs = []
    for b in (plain, wrapped):
        sim = dem.Simulation(b, law, dt=2e-4, gravity=-9.81 * np.eye(dim)[-1],
                             threads=1)
        touched = 0
        for _ in range(50):
            sim.run(30)
            touched += len(sim.contacts()["i"])
        assert touched > 20
        runs.append((b.pos.copy(), b.rot.copy(), b.vel.copy(), sim.pair_state.hist.copy(),
                     sim.wall_state.whist.copy()))
    for a, c in zip(*runs, strict=True):
        assert np.array_equal(a, c)


def _dumbbell(dim, r=0.1, half=0.15, ends=Sphere):
    """Two ``ends`` (spheres, or cubes of half side r) joined by a thin bar along x."""
    axis = np.eye(dim)[0] * half
    end = Sphere(r) if ends is Sphere else Box([r] * dim)
    return Compound([(end, -axis), (end, axis),
                     (Box([half, 0.3 * r] + [0.3 * r] * (dim - 2)), np.zeros(dim))])


@pytest.mark.parametrize("dim", [2, 3])
def test_dumbbells_touch_at_two_points_and_carry_their_weight(dim):
    """One dumbbell lies on another (disks on disks in 2D; in 3D, where a sphere on a
    sphere would roll off, cubes on cubes)."""
    law = dem.LinearSpring(kn=2e5, kt=5e4, mu=0.5, restitution=0.2)
    b = dem.Bodies.empty(dim)
    up = np.eye(dim)[-1]
    # two dumbbells side by side (along y in 3D, stacked along the vertical in 2D)
    ends = Sphere if dim == 2 else Box
    b.add_shapes(_dumbbell(dim, ends=ends), [0.105 * up], RHO)
    b.add_shapes(_dumbbell(dim, ends=ends), [0.31 * up], RHO)
    b.add_plane(np.zeros(dim), up)
    sim = dem.Simulation(b, law, gravity=-9.81 * up, damping=0.3, threads=1)
    sim.run(4000)
    c = sim.contacts()
    pair = ~c["is_wall"]
    # each end of the upper body rests on an end of the lower one: two contacts
    # between the one pair of bodies, symmetric about the middle
    assert pair.sum() == 2 and set(c["i"][pair]) == {0} and set(c["j"][pair]) == {1}
    f = c["force"][pair]
    assert np.allclose(f[0], f[1], rtol=1e-6, atol=1e-9 * np.abs(f).max())
    weight = b.mass[0] * 9.81
    assert np.sum(f @ up) == pytest.approx(weight, rel=1e-4)  # the force on j, upwards
    # two wall contacts carry both weights
    assert c["is_wall"].sum() == 2
    assert sim.wall_forces()[2] @ up == pytest.approx(-2 * weight, rel=1e-4)
    # the points lie under the ends' centres, not at the body centre
    x = c["x1"][pair][:, 0]
    assert np.allclose(np.sort(x), [-0.15, 0.15], atol=1e-6)


def test_elastic_collision_of_two_compounds_conserves():
    T = Compound([(Box([0.03, 0.01, 0.01]), [0.0, 0.0, 0.0]),
                  (Box([0.01, 0.03, 0.01]), [0.0, 0.02, 0.0], _quat([0, 0, 1], 0.2)),
                  (Sphere(0.012), [0.03, 0.0, 0.0])])
    b = dem.Bodies.empty(3)
    b.add_shapes(T, [[0.0, 0.0, 0.0]], RHO, rot=[_quat([1, 2, 0], 0.4)],
                 vel=[[1.0, 0.0, 0.0]], ang_vel=[[0.0, 3.0, -2.0]])
    b.add_shapes(T, [[0.075, 0.01, 0.004]], RHO, rot=[_quat([0, 1, 3], -1.1)],
                 vel=[[-0.5, 0.05, 0.0]], ang_vel=[[2.0, 0.0, 1.0]])
    sim = dem.Simulation(b, dem.LinearSpring(kn=1e5), threads=1)
    sim.dt = 0.02 * sim.dt_crit
    p0 = (b.mass[:, None] * b.vel).sum(axis=0)
    l0 = angular_momentum(b)
    e0 = sum(kinetic_energy(b))
    touched = set()
    for _ in range(300):
        sim.run(25)
        c = sim.contacts()
        touched.update(zip(c["i"], c["j"], sim._parts[sim.shape_state.pgeom[:, 0] > 0.0, 0],
                           sim._parts[sim.shape_state.pgeom[:, 0] > 0.0, 1], strict=True))
    assert len(touched) >= 2, f"parts that met: {touched}"
    assert len(sim.contacts()["i"]) == 0, "still in contact at the end"
    scale = np.sum(b.mass * np.linalg.norm(b.vel, axis=1))
    assert np.linalg.norm((b.mass[:, None] * b.vel).sum(axis=0) - p0) < 1e-12 * scale
    drift = np.linalg.norm(angular_momentum(b) - l0)
    assert drift < 1e-9 * (np.linalg.norm(l0) + scale)
    assert abs(sum(kinetic_energy(b)) - e0) / e0 < 1e-3


def test_friction_history_is_carried_per_part_across_rebuilds():
    """A dumbbell pushed along a floor: two frictional wall contacts whose shear springs
    must survive every neighbour-list rebuild. A small skin rebuilds often, a large one
    never; the runs agree."""
    law = dem.LinearSpring(kn=2e5, kt=5e4, mu=0.3)
    runs = []
    for skin in (0.004, 1.0):
        b = dem.Bodies.empty(2)
        b.add_shapes(_dumbbell(2), [[0.0, 0.0995]], RHO, vel=[[0.4, 0.0]])
        b.add_plane([0.0, 0.0], [0.0, 1.0])
        sim = dem.Simulation(b, law, gravity=[0.0, -9.81], skin=skin, threads=1)
        builds = sim.neighbors.n_builds
        sim.run(3000)
        runs.append((b.pos.copy(), b.vel.copy(), sim.neighbors.n_builds - builds))
    assert runs[0][2] > 5 and runs[1][2] <= 1
    assert np.allclose(runs[0][0], runs[1][0], rtol=0, atol=1e-12)
    assert np.allclose(runs[0][1], runs[1][1], rtol=0, atol=1e-10)
    assert runs[0][1][0, 0] < 0.4 - 1e-3  # friction did slow it


# --------------------------------------------------------------------------- output
def test_surfaces_and_bodies_file(tmp_path):
    b = dem.Bodies.empty(3)
    L = Compound([(Box([0.5, 0.1, 0.1]), [0.0, 0.0, 0.0]),
                  (Box([0.1, 0.5, 0.1]), [-0.4, 0.4, 0.0]), (Sphere(0.2), [0.6, 0, 0])])
    b.add_shapes(L, [[0.0, 0.0, 1.0]], RHO, rot=[_quat([1, 1, 1], 0.7)])
    b.add_shapes(Box([0.1, 0.1, 0.1]), [[2.0, 0.0, 0.0]], RHO)
    surf = shape_surfaces(b)
    # two boxes of the compound and the plain box: 3 x 12 triangles
    assert surf["cells"].shape == (36, 3)
    assert surf["body"].tolist() == [0] * 24 + [1] * 12
    # the compound's drawn corners are the corners of its boxes, placed in the world
    pts = surf["points"][:16]
    local = (pts - b.pos[0]) @ quat_to_matrix(b.rot[0])
    shape = b.table.shapes[b.shape[0]]
    for k, (part, rot, off) in enumerate(shape.parts[:2]):
        corners = part.corners() @ rot.T + off
        assert np.allclose(local[8 * k:8 * k + 8], corners, atol=1e-12)
    path = tmp_path / "bodies.h5"
    write_bodies(b, path)
    back = read_bodies(path)
    for name in back.table.ARRAYS:
        assert np.array_equal(getattr(back.table, name), getattr(b.table, name)), name
    with h5py.File(path, "r+") as f:
        f["bodies/shape_table/part_row"][0] = 5  # points past the table
    with pytest.raises(ValueError, match="compound part pool"):
        read_bodies(path)


def test_checkpoint_restart_of_compounds_is_bit_for_bit(tmp_path):
    """A 2D pile of dumbbells and L shapes: save at step 200, run on; the restart
    repeats it exactly (the part pool travels with the table, the part rows of the
    lists are remade from the saved ones)."""
    from dem.io.checkpoint import load_checkpoint, save_checkpoint

    law = dem.LinearSpring(kn=1e5, kt=5e4, mu=0.4, restitution=0.5)
    rng = np.random.default_rng(8)
    b = dem.Bodies.empty(2)
    L = Compound([(Box([0.05, 0.01]), [0.0, 0.0]), (Box([0.01, 0.04]), [-0.04, 0.05])])
    b.add_shapes(_dumbbell(2, r=0.012, half=0.02), [[0.0, 0.04], [0.07, 0.045],
                                                    [0.14, 0.04]], RHO,
                 rot=rng.uniform(0, np.pi, 3))
    b.add_shapes(L, [[-0.05, 0.19], [0.17, 0.19]], RHO, rot=rng.uniform(0, np.pi, 2))
    b.add_plane([0.0, 0.0], [0.0, 1.0])
    sim = dem.Simulation(b, law, gravity=[0.0, -9.81], damping=0.3, threads=1)
    sim.run(200)
    save_checkpoint(sim, tmp_path / "c.h5")
    again = load_checkpoint(tmp_path / "c.h5", law)
    shared = 0  # contacts sharing their pair of bodies with another contact
    for _ in range(15):
        sim.run(100)
        again.run(100)
        c = sim.contacts()
        shared += len(c["i"]) - len(set(zip(c["i"], c["j"], strict=True)))
    assert shared > 5
    for name in ("pos", "vel", "rot", "ang_vel"):
        assert np.array_equal(getattr(sim.bodies, name), getattr(again.bodies, name))


def test_a_compound_cannot_be_grown():
    b = dem.Bodies.empty(2)
    b.add_shapes(_dumbbell(2), [[0.0, 0.5]], RHO)
    for row in (b.shape[0], b.table.part_row[b.table.part_row >= 0][0]):
        sim = dem.Simulation(b.copy(), dem.LinearSpring(kn=1e5), dt=1e-4,
                             state_objects=[dem.ShapeScale([row],
                                                           lambda s, t: 0.1 * s)])
        with pytest.raises(ValueError, match="cannot grow a compound"):
            sim.run(2)
