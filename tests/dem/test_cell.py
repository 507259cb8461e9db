"""The deformable periodic cell: affine motion, images through the cell matrix,
unlimited shear, the affine velocity inside contacts, threads and restart; spheres and
level-set shapes (boxes, polygons, polyhedra) alike."""

import naive
import numba
import numpy as np
import pytest

import dem
from dem.boundary import PeriodicCell
from dem.io import load_checkpoint, save_checkpoint


def _grid(dim, side, spacing):
    g = (np.arange(side) + 0.5) * spacing
    return np.stack(np.meshgrid(*[g] * dim, indexing="ij"), -1).reshape(-1, dim)


def _lattice_residual(h, x):
    """Largest distance, in fractional terms, of x (n, d) from the lattice of h."""
    k = np.linalg.solve(h, x.T).T
    return float(np.abs(k - np.rint(k)).max())


def test_cell_rejects_degenerate_or_misshapen_matrices():
    with pytest.raises(ValueError, match="positive determinant"):
        PeriodicCell([[1.0, 0.0], [0.0, -1.0]])
    with pytest.raises(ValueError, match=r"\(2, 2\) or \(3, 3\)"):
        PeriodicCell(np.eye(4))
    with pytest.raises(ValueError, match="finite"):
        PeriodicCell([1.0, np.nan])


def _boxes(dim, pos, rng):
    """Boxes at ``pos`` in random orientations."""
    if dim == 2:
        rot = rng.uniform(0.0, np.pi, len(pos))
    else:
        rot = rng.normal(size=(len(pos), 4))
        rot /= np.linalg.norm(rot, axis=1, keepdims=True)
    bodies = dem.Bodies.empty(dim)
    bodies.add_shapes(dem.Box([0.15, 0.075, 0.1][:dim]), pos, density=1000.0, rot=rot)
    return bodies


@pytest.mark.parametrize("kind", ["spheres", "boxes"])
@pytest.mark.parametrize("dim", [2, 3])
def test_free_bodies_keep_their_place_in_the_deforming_lattice(dim, kind):
    """Bodies that do not touch follow x -> F x exactly; the cell is F H0 (up to a
    change of lattice basis), whatever stretch, shear and spin L has. Orientations
    turn with the field's spin: each step by the rotation of its map I + dt L."""
    side = 4
    cell = PeriodicCell(np.full(dim, side * 1.0))
    pos0 = _grid(dim, side, 1.0)
    rng = np.random.default_rng(7)
    lgrad = rng.uniform(-0.4, 0.4, (dim, dim))
    lgrad[0, 1] = 1.5  # enough shear for at least one change of basis
    bodies = (dem.Bodies.spheres(pos0.copy(), radius=0.2, density=1000.0)
              if kind == "spheres" else _boxes(dim, pos0.copy(), rng))
    rot0 = bodies.rot.copy()
    sim = dem.Simulation(bodies, dem.LinearSpring(kn=1e4), box=cell, dt=1e-3)
    cell.lgrad[:] = lgrad
    n = 2000
    sim.run(n)
    fmap = np.linalg.matrix_power(np.eye(dim) + 1e-3 * lgrad, n)
    assert cell.n_reductions >= 1
    assert _lattice_residual(cell.h, bodies.pos - pos0 @ fmap.T) < 1e-11
    assert _lattice_residual(cell.h, (fmap * side).T) < 1e-11  # edges of F H0 (rows)
    assert cell.volume == pytest.approx(np.linalg.det(fmap) * side**dim, rel=1e-12)
    assert np.all(bodies.vel == 0.0)  # the affine field is not in the fluctuations
    assert np.all(bodies.ang_vel == 0.0)
    w, _, vt = np.linalg.svd(np.eye(dim) + 1e-3 * lgrad)
    turn = np.linalg.matrix_power(w @ vt, n)  # the steps' rotations, compounded
    if dim == 2:
        angle = n * np.arctan2((w @ vt)[1, 0], (w @ vt)[0, 0])
        assert np.allclose(bodies.rot[:, 0], rot0[:, 0] + angle, rtol=0.0, atol=1e-11)
    else:
        for q, q0 in zip(bodies.rot, rot0, strict=True):
            np.testing.assert_allclose(_quat_matrix(q), turn @ _quat_matrix(q0),
                                       rtol=0.0, atol=1e-11)


def _quat_matrix(q):
    """The rotation matrix of a unit quaternion (w, x, y, z)."""
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def test_simple_shear_without_limit_keeps_every_contact():
    """Held bodies (affine motion only) sheared to gamma = 4: at every check the
    touching pairs and their distances are the brute-force ones over all images."""
    rng = np.random.default_rng(3)
    cell = PeriodicCell([1.0, 1.0])
    pos = rng.uniform(0.0, 1.0, (60, 2))
    radius = rng.uniform(0.05, 0.08, 60)
    bodies = dem.Bodies.spheres(pos, radius=radius, density=1000.0)
    bodies.is_fixed[:] = True
    sim = dem.Simulation(bodies, dem.LinearSpring(kn=1e3), box=cell, dt=1e-3,
                         overlap_limit=10.0)  # random centres: deep overlaps allowed
    cell.lgrad[0, 1] = 1.0  # gamma-dot = 1 / s
    for _ in range(4):
        sim.run(1000)
        c = sim.contacts()
        got = {(int(i), int(j)): float(np.linalg.norm(br))
               for i, j, br in zip(c["i"], c["j"], c["branch"], strict=True)}
        want = naive.cell_pairs(bodies.pos, radius, cell.h, reach=4)
        assert got.keys() == want.keys()
        assert max(abs(got[k] - want[k]) for k in got) < 1e-12
    assert cell.n_reductions >= 2
    assert cell.h[0, 1] == pytest.approx(4.0 - 4.0 * round(1.0), abs=0.51)


@pytest.mark.parametrize("kind", ["disks", "squares"])
@pytest.mark.parametrize("across", [False, True])
def test_shear_loads_the_tangential_spring_through_the_affine_velocity(across, kind):
    """Two heavy bodies, one above the other (two disks of radius 0.1 m; a square of
    half side 0.05 m on one of 0.1 m), in simple shear ``L = gamma-dot e_x e_y``: the
    bodies turn with its spin, so the relative velocity at the contact is the
    stretching ``D l = gamma-dot |l| / 2 e_x``, and the tangential force grows as
    kt gamma-dot |l| t / 2, while the normal one is kn ov -- the same whether the
    pair sits inside the cell or touches through its boundary."""
    cell = PeriodicCell([1.0, 1.0])
    r, ov = 0.1, 1e-3
    branch = (2.0 if kind == "disks" else 1.5) * r - ov
    y0 = 0.95 if across else 0.4  # across: j is i's image above the top edge
    pos = np.array([[0.5, y0], [0.5, (y0 + branch) % 1.0]])
    # so heavy that the contact force barely moves them in the run
    if kind == "disks":
        bodies = dem.Bodies.spheres(pos, radius=r, density=1e9)
    else:
        bodies = dem.Bodies.empty(2)
        bodies.add_shapes(dem.Box([r, r]), pos[:1], density=1e9)
        bodies.add_shapes(dem.Box([0.5 * r, 0.5 * r]), pos[1:], density=1e9)
    kt, rate, dt, n = 2e3, 1e-2, 1e-4, 500
    sim = dem.Simulation(bodies, dem.LinearSpring(kn=1e4, kt=kt, mu=10.0), box=cell, dt=dt)
    cell.lgrad[0, 1] = rate
    sim.run(n)
    c = sim.contacts()
    assert c["i"].size == 1
    f, n_ = c["force"][0], c["normal"][0]
    f_t = np.linalg.norm(f - (f @ n_) * n_)  # the normal has turned a little too
    assert f_t == pytest.approx(0.5 * kt * rate * branch * n * dt, rel=2e-3)
    assert abs(f @ n_) == pytest.approx(1e4 * ov, rel=2e-3)

def test_thread_count_does_not_change_a_deforming_run():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs NUMBA_NUM_THREADS >= 2 to compare 1 and 2 threads")
    from dem import packings

    out = []
    for threads in (1, 2):
        radii = packings.particle_radii(300, (0.8, 1.2), seed=1)
        cell, pos = packings.loose_cloud(2, radii, 0.5, seed=1)
        bodies = dem.Bodies.spheres(pos, radius=radii, density=1.0)
        sim = dem.Simulation(bodies, dem.LinearSpring(kn=1e3, kt=5e2, mu=0.5), box=cell,
                             damping=0.3, threads=threads)
        cell.lgrad[:] = [[-2e-3, 1e-3], [0.0, -1e-3]]
        sim.run(3000)
        out.append((bodies.pos.copy(), cell.h.copy(), sim.pair_state.fpair.copy()))
    for a, b in zip(out[0], out[1], strict=True):
        assert np.array_equal(a, b)


def test_checkpoint_of_a_deforming_cell_restarts_bit_for_bit(tmp_path):
    from dem import packings

    radii = packings.particle_radii(80, (0.8, 1.2), seed=2)
    cell, pos = packings.loose_cloud(2, radii, 0.5, seed=2)
    law = dem.LinearSpring(kn=1e3, kt=5e2, mu=0.5)
    sim = dem.Simulation(dem.Bodies.spheres(pos, radius=radii, density=1.0), law,
                         box=cell, damping=0.3)
    cell.lgrad[:] = [[-3e-3, 2e-3], [0.0, -1e-3]]
    sim.run(1500)
    save_checkpoint(sim, tmp_path / "c.h5")
    sim.run(1500)
    again = load_checkpoint(tmp_path / "c.h5", law)
    assert again.cell is not None and np.array_equal(again.cell.lgrad, cell.lgrad)
    again.run(1500)
    assert np.array_equal(again.bodies.pos, sim.bodies.pos)
    assert np.array_equal(again.cell.h, cell.h)
    assert np.array_equal(again.pair_state.hist, sim.pair_state.hist)


def test_cell_refuses_what_it_cannot_run():
    cell = PeriodicCell([1.0, 1.0])
    bodies = dem.Bodies.spheres(np.array([[0.5, 0.5]]), radius=0.1, density=1.0)
    sim = dem.Simulation(bodies, dem.LinearSpring(kn=1.0), box=cell, dt=1e-3,
                         neighbor_backend="kdtree")
    with pytest.raises(ValueError, match="orthogonal"):
        sim.run(1)
    small = dem.Bodies.spheres(np.array([[0.5, 0.5]]), radius=0.3, density=1.0)
    sim = dem.Simulation(small, dem.LinearSpring(kn=1.0), box=cell, dt=1e-3)
    with pytest.raises(ValueError, match="less than twice the neighbour cut-off"):
        sim.run(1)
