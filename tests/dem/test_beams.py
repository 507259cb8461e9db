"""Bonded Euler-Bernoulli beams: element, objectivity, energy, dynamics, cantilever."""

import itertools
import runpy
from pathlib import Path

import numpy as np
import pytest

import dem
from dem.peridynamics.beams import (
    BeamBonds,
    BeamStructure,
    cantilever,
    cantilever_deflection,
    cantilever_theory,
)
from dem.rotation import matrix_to_quat, quat_mul

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "beams_cantilever.py"

E, G, AREA = 1.0e7, 4.0e6, 1.0e-4
MOMENTS = {2: 1.0e-9, 3: (1.0e-9, 2.0e-9, 1.5e-9)}  # I_z (2D); I_y, I_z, J (3D) [m^4]


def random_rotation(rng):
    q = rng.normal(size=4)
    return q / np.linalg.norm(q) * np.sign(q[0])


def quat_exp(v):
    """Unit quaternion of the rotation vector ``v`` (3,)."""
    angle = np.linalg.norm(v)
    if angle == 0.0:
        return np.array([1.0, 0.0, 0.0, 0.0])
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * v / angle])


def structure(dim, rng, n=5, pairs=None):
    """``n`` box bodies (anisotropic inertia) at random orientations along a bent
    path, joined in a chain plus one cross beam."""
    steps = rng.normal(0.0, 0.03, (n, dim))
    steps[:, 0] += 0.08
    pos = np.cumsum(steps, axis=0)
    rot = (rng.uniform(-np.pi, np.pi, n) if dim == 2
           else np.array([random_rotation(rng) for _ in range(n)]))
    half = [0.02, 0.01] if dim == 2 else [0.02, 0.01, 0.015]
    bodies = dem.Bodies.empty(dim)
    bodies.add_shapes(dem.Box(half), pos, density=1000.0, rot=rot)
    if pairs is None:
        pairs = [[k, k + 1] for k in range(n - 1)] + [[0, 2]]
    bonds = BeamBonds(bodies, pairs, E=E, area=AREA, moments=MOMENTS[dim],
                      G=G if dim == 3 else None)
    return bodies, bonds


def turn(bodies, b, v):
    """Turn body ``b`` by the world rotation vector ``v`` ((1,) in 2D, (3,) in 3D)."""
    if bodies.dim == 2:
        bodies.rot[b, 0] += v[0]
    else:
        bodies.rot[b] = quat_mul(quat_exp(np.asarray(v)), bodies.rot[b])


def generalized_forces(bonds, bodies):
    force, torque, energy = bonds.forces(bodies)
    rows = [np.concatenate([f, t]) for f, t in zip(force, torque, strict=True)]
    return np.concatenate(rows), energy


def perturb(bodies, dof, h):
    """A copy of ``bodies`` with degree of freedom ``dof`` (body-major: d positions,
    then 1 or 3 rotations per body) moved by ``h``."""
    out = bodies.copy()
    d, nr = bodies.dim, bodies.n_rot
    b, c = divmod(dof, d + nr)
    if c < d:
        out.pos[b, c] += h
    else:
        turn(out, b, h * np.eye(nr)[c - d])
    return out


def stiffness(bonds, bodies, h=1e-7):
    """Tangent stiffness ``-dF/du`` by central differences of the beam forces."""
    n_dof = bodies.n * (bodies.dim + bodies.n_rot)
    cols = [(generalized_forces(bonds, perturb(bodies, c, -h))[0]
             - generalized_forces(bonds, perturb(bodies, c, h))[0]) / (2 * h)
            for c in range(n_dof)]
    return np.array(cols).T


def euler_bernoulli(dim, length):
    """Euler-Bernoulli element stiffness along x; dofs (u, theta) of i, then of j."""
    def bend(ei):  # (v_i, theta_i, v_j, theta_j)
        k, c, r4, r2 = 12 * ei / length**3, 6 * ei / length**2, 4 * ei / length, \
            2 * ei / length
        return np.array([[k, c, -k, c], [c, r4, -c, r2],
                         [-k, -c, k, -c], [c, r2, -c, r4]])

    def place(K, idx, block):
        K[np.ix_(idx, idx)] += block

    ea = E * AREA / length
    axial = np.array([[ea, -ea], [-ea, ea]])
    if dim == 2:
        K = np.zeros((6, 6))
        place(K, [0, 3], axial)
        place(K, [1, 2, 4, 5], bend(E * MOMENTS[2]))
        return K
    i_y, i_z, j = MOMENTS[3]
    K = np.zeros((12, 12))
    place(K, [0, 6], axial)
    place(K, [3, 9], G * j / length * np.array([[1, -1], [-1, 1]]))
    place(K, [1, 5, 7, 11], bend(E * i_z))  # v, theta_z
    flip = np.diag([1, -1, 1, -1])  # w, theta_y: theta_y = -dw/dx
    place(K, [2, 4, 8, 10], flip @ bend(E * i_y) @ flip)
    return K


@pytest.mark.parametrize("dim", [2, 3])
def test_linearised_beam_is_the_euler_bernoulli_element(dim):
    pos = np.zeros((2, dim))
    pos[1, 0] = 0.1
    bodies = dem.Bodies.spheres(pos, radius=0.01, density=1000.0)
    bonds = BeamBonds(bodies, [[0, 1]], E=E, area=AREA, moments=MOMENTS[dim],
                      G=G if dim == 3 else None)
    K = stiffness(bonds, bodies)
    ref = euler_bernoulli(dim, 0.1)
    np.testing.assert_allclose(K, ref, atol=1e-6 * np.abs(ref).max())


def single_beam(dim, mode, rng):
    bodies, bonds = structure(dim, rng, n=2, pairs=[[0, 1]])
    axis = bodies.pos[1] - bodies.pos[0]
    axis /= np.linalg.norm(axis)
    if dim == 3:
        side = np.cross(axis, rng.normal(size=3))
    else:
        side = np.array([-axis[1], axis[0]])
    side /= np.linalg.norm(side)
    if mode == "axial":
        bodies.pos[1] += 2e-3 * axis
    elif mode == "bending":
        bodies.pos[1] += 3e-3 * side
        turn(bodies, 0, 0.02 * (np.cross(axis, side) if dim == 3 else np.ones(1)))
    elif mode == "torsion":
        turn(bodies, 1, 0.05 * axis)
    else:
        bodies.pos[1] += rng.normal(0.0, 3e-3, dim)
        for b in (0, 1):
            turn(bodies, b, rng.normal(0.0, 0.03, bodies.n_rot))
    return bodies, bonds


@pytest.mark.parametrize("dim, mode", [(2, "axial"), (2, "bending"), (2, "mixed"),
                                       (3, "axial"), (3, "bending"), (3, "torsion"),
                                       (3, "mixed")])
def test_force_is_minus_energy_gradient(dim, mode):
    bodies, bonds = single_beam(dim, mode, np.random.default_rng(7))
    g, energy = generalized_forces(bonds, bodies)
    assert energy.sum() > 0.0
    h = 1e-7
    def energy_at(c, step):
        return generalized_forces(bonds, perturb(bodies, c, step))[1].sum()

    grad = np.array([(energy_at(c, h) - energy_at(c, -h)) / (2 * h)
                     for c in range(g.size)])
    np.testing.assert_allclose(g, -grad, rtol=0, atol=1e-6 * np.abs(g).max())


@pytest.mark.parametrize("dim", [2, 3])
def test_rigid_motion_gives_no_force_and_rotates_forces(dim):
    rng = np.random.default_rng(3)
    bodies, bonds = structure(dim, rng)
    scale = E * AREA  # force of a unit strain [N]
    if dim == 2:
        angle = 2.3
        Q = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    else:
        Q = dem.rotation.quat_to_matrix(random_rotation(rng))

    def move(b):
        out = b.copy()
        out.pos = np.ascontiguousarray(b.pos @ Q.T + rng.normal(size=dim))
        if dim == 2:
            out.rot += angle
        else:
            out.rot = np.array([quat_mul(matrix_to_quat(Q), q) for q in b.rot])
        return out

    force, torque, energy = bonds.forces(move(bodies))
    assert np.abs(force).max() < 1e-12 * scale
    assert np.abs(torque).max() < 1e-12 * scale * 0.1
    assert np.abs(energy).max() < 1e-20 * scale * 0.1
    bodies.pos += rng.normal(0.0, 1e-3, bodies.pos.shape)  # a deformed state
    for b in range(bodies.n):
        turn(bodies, b, rng.normal(0.0, 0.02, bodies.n_rot))
    f0, t0, e0 = bonds.forces(bodies)
    f1, t1, e1 = bonds.forces(move(bodies))
    assert np.abs(f0).max() > 1e-4 * scale
    np.testing.assert_allclose(f1, f0 @ Q.T, atol=1e-10 * scale)
    np.testing.assert_allclose(t1, t0 if dim == 2 else t0 @ Q.T, atol=1e-11 * scale)
    np.testing.assert_allclose(e1, e0, rtol=1e-9)


@pytest.mark.parametrize("dim", [2, 3])
def test_free_structure_conserves_momentum(dim):
    rng = np.random.default_rng(11)
    bodies, bonds = structure(dim, rng)
    bodies.pos += rng.normal(0.0, 2e-4, bodies.pos.shape)
    for b in range(bodies.n):
        turn(bodies, b, rng.normal(0.0, 0.01, bodies.n_rot))
    bodies.vel[:] = rng.normal(0.0, 0.05, bodies.vel.shape)
    bodies.ang_vel[:] = rng.normal(0.0, 2.0, bodies.ang_vel.shape)
    sim = BeamStructure(bodies, bonds)
    sim = BeamStructure(bodies, bonds, dt=0.1 * sim.dt_crit)
    p0, l0 = sim.momentum()
    e0 = sim.kinetic_energy() + sim.energy.sum()
    sim.run(3000)
    p1, l1 = sim.momentum()
    e1 = sim.kinetic_energy() + sim.energy.sum()
    assert sim.energy.sum() > 0.01 * e0  # it vibrates
    p_scale = np.sum(bodies.mass * np.linalg.norm(bodies.vel, axis=1))
    l_scale = p_scale * np.abs(bodies.pos).max()
    assert np.abs(p1 - p0).max() < 1e-13 * p_scale
    assert np.abs(l1 - l0).max() < 1e-13 * l_scale
    assert abs(e1 - e0) < 1e-2 * e0


def test_time_step_above_critical_is_refused_and_the_limit_is_safe():
    bodies, bonds = cantilever(2, 5, 1.0, 0.05, 1e9, 1000.0)
    sim = BeamStructure(bodies, bonds)
    with pytest.raises(ValueError, match="exceeds the critical time step"):
        BeamStructure(bodies, bonds, dt=1.01 * sim.dt_crit)
    BeamStructure(bodies, bonds, dt=1.01 * sim.dt_crit, allow_unstable_dt=True)
    # the true limit 2 / omega_max of the linearised clamped structure
    free = np.repeat(~bodies.is_fixed, 3)
    mass = np.column_stack([bodies.mass, bodies.mass, bodies.inertia[:, 0]]).ravel()
    K = stiffness(bonds, bodies)[np.ix_(free, free)]
    s = 1.0 / np.sqrt(mass[free])
    omega_max = np.sqrt(np.linalg.eigvalsh(s[:, None] * K * s[None, :]).max())
    assert 0.3 * 2.0 / omega_max < sim.dt_crit <= 2.0 / omega_max


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("young", [1e6, 1e9])
def test_cantilever_tip_deflection(dim, young):
    n, length, height, density = 11, 1.0, 0.05, 1000.0
    width = 0.03 if dim == 3 else None  # 3D: I_y = w h^3 / 12 resists the load along z
    accel = 1e-3 * length / cantilever_theory(length, height, young, density, 1.0)
    w, _ = cantilever_deflection(dim, n, length, height, young, density, accel,
                                 width=width)
    exact = cantilever_theory(length, height, young, density, accel)
    assert w / length == pytest.approx(1e-3, rel=0.02)
    assert w == pytest.approx(exact, rel=0.02)
    # the lumped model's own exact answer, 1 + 1/(3 (n-1)^2) times the beam's
    assert w == pytest.approx(cantilever_theory(length, height, young, density, accel,
                                                n=n), rel=1e-5)


def test_example_converges_with_n(tmp_path):
    ex = runpy.run_path(str(EXAMPLE), run_name="example")
    tables = ex["main"](small=True, out=tmp_path / "beams.png")
    assert (tmp_path / "beams.png").stat().st_size > 0
    for errors in [*tables[2].values(), *tables[3].values()]:
        ns = sorted(errors)
        err = [errors[n] for n in ns]
        assert all(a > b > 0 for a, b in itertools.pairwise(err)), errors
        assert errors[11] < 0.02
        for n in ns:
            assert errors[n] == pytest.approx(1.0 / (3 * (n - 1) ** 2), rel=1e-3)
