"""The stability map's lines, each crossed by a small scene (docs/stability.md).

- DEM: a step above the critical step is refused unless asked for, and then the run
  blows up with a :class:`dem.SimulationError`. A dense lattice is unstable below the
  two-body limit already (hexagonal disks from ``1/sqrt(3)`` of it, fcc spheres from 1/2
  with normal springs and from ``1/sqrt(40/7)`` where their tangential springs spin
  them); the refusal threshold is 0.9 x a close packing's limit, dashpots and local
  damping included.
- RVE: a relaxation that cannot finish within its step cap raises
  :class:`dem.rve.RelaxationError` saying what to change.
- Macro Newton: a load step too large is cut until it converges; a load past the
  micro law's limit is cut down to ``min_step`` and stops with a
  :class:`hmm.coupling.SolverError` naming the minimum step, the last converged state
  kept and, in a run, written and marked in ``fields.h5``.
- ADMM contact detection with too small an iteration cap stops the run naming the pair.

(Peridynamics' step limit is tested in ``tests/dem/test_peridynamics.py``.)
"""

import math

import h5py
import numpy as np
import pytest

import dem
from dem.neighbors import Box
from dem.rve import RVE, RelaxationError
from hmm.coupling import Solver, SolverError, SolverSettings, Supports
from hmm.farm import SerialFarm
from hmm.macro import Macro, structured_mesh
from hmm.micro import Hyperbolic, lame

R, RHO, KN = 0.01, 2500.0, 1e5


def hex_lattice(side=4, squeeze=0.02, seed=0):
    """Precompressed periodic hexagonal lattice of disks, random velocities (small
    against the overlap: contacts stay closed)."""
    a = 2.0 * R * (1.0 - squeeze)
    pos = np.array([[(i + 0.5 * (j % 2)) * a, j * a * math.sqrt(3.0) / 2.0]
                    for j in range(side) for i in range(side)])
    bodies = dem.Bodies.spheres(pos, radius=R, density=RHO)
    rng = np.random.default_rng(seed)
    omega = math.sqrt(KN / bodies.mass[0])
    bodies.vel[:] = rng.normal(0.0, 0.25 * squeeze * R * omega, bodies.vel.shape)
    lo = -0.5 * a * np.ones(2)
    box = Box(lo, lo + [side * a, side * a * math.sqrt(3.0) / 2.0], [True, True])
    return bodies, box


def lattice_sim(factor, **kw):
    bodies, box = hex_lattice()
    dt_crit = dem.Simulation(bodies.copy(), dem.LinearSpring(kn=KN), box=box).dt_crit
    return dem.Simulation(bodies, dem.LinearSpring(kn=KN), box=box, dt=factor * dt_crit,
                          threads=1, **kw)


def test_dt_above_critical_is_refused_then_blows_up():
    with pytest.raises(ValueError, match="exceeds the stable time step"):
        lattice_sim(1.05)
    sim = lattice_sim(1.05, allow_unstable_dt=True)
    with pytest.raises(dem.SimulationError, match=r"critical step"):
        sim.run(2000)


def test_dense_lattice_sets_the_refusal_threshold():
    """dt_crit = sqrt(2 m / k) is the limit of two bodies on one spring. Six contacts per
    disk stiffen the fastest mode: measured limit 0.5-0.55 dt_crit (2 / omega_max =
    0.577 dt_crit), twelve per sphere 0.5; steps above STABLE_FACTOR = 0.9 x 0.5 dt_crit
    are refused. At 0.4 the energy stays bounded; at 0.7, forced, the lattice blows up."""
    from dem.observers import elastic_energy, kinetic_energy

    sim = lattice_sim(0.4)
    e0, k0 = sum(kinetic_energy(sim.bodies)) + elastic_energy(sim), \
        sum(kinetic_energy(sim.bodies))
    err = 0.0
    for _ in range(10):
        sim.run(25)
        err = max(err, abs(sum(kinetic_energy(sim.bodies)) + elastic_energy(sim) - e0))
    assert err < 0.5 * k0
    assert sim.dt_stable == pytest.approx(0.45 * sim.dt_crit, rel=1e-12)  # 0.9 x 0.5
    with pytest.raises(ValueError, match="exceeds the stable time step"):
        lattice_sim(0.7)
    sim = lattice_sim(0.7, allow_unstable_dt=True)
    with pytest.raises(dem.SimulationError):
        sim.run(2000)


def fcc_lattice(side=2, squeeze=0.02, seed=0):
    """Precompressed periodic fcc spheres (``side`` cubic cells of four per axis), random
    velocities and spins small against the overlap."""
    a = 2.0 * R * (1.0 - squeeze)
    c = a * math.sqrt(2.0)
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]]) * c
    cells = np.stack(np.meshgrid(*[np.arange(side) * c] * 3, indexing="ij"),
                     -1).reshape(-1, 3)
    bodies = dem.Bodies.spheres((cells[:, None] + basis[None]).reshape(-1, 3), radius=R,
                                density=RHO)
    rng = np.random.default_rng(seed)
    omega = math.sqrt(KN / bodies.mass[0])
    bodies.vel[:] = rng.normal(0.0, 0.05 * squeeze * R * omega, bodies.vel.shape)
    bodies.vel -= bodies.vel.mean(axis=0)
    bodies.ang_vel[:] = rng.normal(0.0, 0.05 * squeeze * omega, bodies.ang_vel.shape)
    lo = -0.5 * a * np.ones(3)
    return bodies, Box(lo, lo + side * c, [True] * 3)


def lattice_matrices(dim, kn, kt):
    """Mass and stiffness matrices of a touching periodic lattice (hexagonal disks, 4 x 4
    rows; fcc spheres, 2 x 2 x 2 cells) of unit mass and radius 1/2: normal springs
    ``kn`` and tangential springs ``kt`` at the contact points, spins included."""
    r = 0.5
    if dim == 2:
        pts = np.array([[i + 0.5 * (j % 2), j * math.sqrt(3.0) / 2.0]
                        for j in range(4) for i in range(4)])
        length = np.array([4.0, 2.0 * math.sqrt(3.0)])
        inertia, n_rot = 0.5 * r * r, 1
    else:
        c = math.sqrt(2.0)
        basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]]) * c
        pts = np.array([np.array(ijk) * c + b for ijk in np.ndindex(2, 2, 2)
                        for b in basis])
        length = np.full(3, 2.0 * c)
        inertia, n_rot = 0.4 * r * r, 3
    n_dof = dim + n_rot
    stiff = np.zeros((len(pts) * n_dof,) * 2)

    def spin_arm(v):  # the matrix of theta -> theta x v
        if dim == 2:
            return np.array([[-v[1]], [v[0]]])
        return -np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])

    for i, j in zip(*np.triu_indices(len(pts), 1), strict=True):
        d = pts[j] - pts[i]
        d -= np.round(d / length) * length
        if abs(np.linalg.norm(d) - 2.0 * r) > 1e-9:
            continue
        n = d / np.linalg.norm(d)
        b = np.zeros((dim, stiff.shape[0]))  # contact point slip of j against i
        b[:, j * n_dof:j * n_dof + dim] += np.eye(dim)
        b[:, i * n_dof:i * n_dof + dim] -= np.eye(dim)
        b[:, j * n_dof + dim:(j + 1) * n_dof] += spin_arm(-r * n)
        b[:, i * n_dof + dim:(i + 1) * n_dof] -= spin_arm(r * n)
        nn = np.outer(n, n)
        stiff += b.T @ (kn * nn + kt * (np.eye(dim) - nn)) @ b
    mass = np.tile(np.r_[np.ones(dim), inertia * np.ones(n_rot)], len(pts))
    return mass, stiff


@pytest.mark.parametrize("dim", [2, 3])
def test_packing_ratios_are_the_close_packed_lattices_fastest_modes(dim):
    """The fastest mode of a close packing over the two-body one, for normal springs
    alone (fcc 2, hexagonal sqrt(3), taken as 2) and for tangential springs alone with
    their rotational coupling (fcc sqrt(40/7), hexagonal 2: the bodies all spinning the
    same way)."""
    from dem.timestep import PACKING_RATIOS

    rot = {2: 3.0, 3: 3.5}[dim]
    for family, kn, kt, pair_k in (("normal", 1.0, 0.0, 1.0),
                                   ("tangential", 0.0, 1.0, rot)):
        mass, stiff = lattice_matrices(dim, kn, kt)
        scaled = stiff / np.sqrt(np.outer(mass, mass))
        omega = math.sqrt(np.linalg.eigvalsh(scaled).max())
        ratio = omega / math.sqrt(2.0 * pair_k)  # pair: k / (m / 2)
        expected = {("normal", 2): math.sqrt(3.0)}.get((family, dim),
                                                       PACKING_RATIOS[family][dim])
        assert ratio == pytest.approx(expected, rel=1e-9)
        assert ratio <= PACKING_RATIOS[family][dim] + 1e-12


def test_tangential_springs_of_a_close_packing_set_the_threshold():
    """fcc spheres with sticking tangential springs kt = kn / 2 (their rotation-coupled
    stiffness 1.75 kn sets dt_crit): the spin mode's limit is 1 / sqrt(40/7) = 0.418
    dt_crit, below the 0.45 that normal springs alone allow. At 0.95 x the limit the
    lattice keeps its energy; at 1.05 x (0.439 dt_crit), forced, it blows up; steps
    are refused from 0.9 x the limit."""
    from dem.observers import elastic_energy, kinetic_energy

    law = dem.LinearSpring(kn=KN, kt=0.5 * KN, mu=10.0)
    bodies, box = fcc_lattice()
    probe = dem.Simulation(bodies.copy(), law, box=box)
    limit = 1.0 / math.sqrt(40.0 / 7.0)
    assert probe.dt_stable == pytest.approx(0.9 * limit * probe.dt_crit, rel=1e-12)

    def sim(factor):
        b, bx = fcc_lattice()
        return dem.Simulation(b, law, box=bx, dt=factor * limit * probe.dt_crit,
                              threads=1, allow_unstable_dt=True)

    def energy(s):
        return sum(kinetic_energy(s.bodies)) + elastic_energy(s)

    stable = sim(0.95)
    e0 = energy(stable)
    stable.run(2000)
    assert abs(energy(stable) - e0) < 0.2 * e0
    with pytest.raises(dem.SimulationError):
        sim(1.05).run(2000)
    with pytest.raises(ValueError, match="exceeds the stable time step"):
        dem.Simulation(bodies.copy(), law, box=box, dt=1.01 * probe.dt_stable)


def test_dashpots_lower_the_stable_step_as_predicted():
    """Explicit dashpots are stable for omega dt < 2 (sqrt(1 + z^2) - z). The hexagonal
    lattice's fastest mode has sqrt(3) times the two-body frequency and damping ratio,
    so with two-body ratio zeta = 0.6 its limit falls from 0.577 to 0.233 dt_crit: at
    0.9 x that the lattice rings down to round-off, at 1.1 x its fastest mode grows
    until contacts open and keeps ringing at the size of the initial motion (the same
    step without dashpots is stable), and the refusal threshold lies below it."""
    bodies, box = hex_lattice()
    zeta = 0.6
    gamma_n = 2.0 * zeta * math.sqrt(KN * 0.5 * bodies.mass[0])
    law = dem.LinearSpring(kn=KN, gamma_n=gamma_n)
    probe = dem.Simulation(bodies.copy(), law, box=box)
    assert probe.damping_ratio == pytest.approx(zeta, rel=1e-12)
    z = math.sqrt(3.0) * zeta
    limit = (math.sqrt(1.0 + z * z) - z) / math.sqrt(3.0)  # in dt_crit
    assert probe.dt_stable < limit * probe.dt_crit

    def run(factor, model):
        b, bx = hex_lattice()
        sim = dem.Simulation(b, model, box=bx, dt=factor * probe.dt_crit, threads=1,
                             allow_unstable_dt=True)
        sim.run(3000)
        v = sim.bodies.vel - sim.bodies.vel.mean(axis=0)  # the lattice's own motion
        return float(np.abs(v).max())

    v0 = float(np.abs(bodies.vel - bodies.vel.mean(axis=0)).max())
    assert run(0.9 * limit, law) < 1e-9 * v0  # rung down
    assert run(1.1 * limit, law) > 0.1 * v0  # unstable: grows, bounded by opening
    assert run(1.1 * limit, dem.LinearSpring(kn=KN)) < 10.0 * v0  # undamped: stable
    with pytest.raises(ValueError, match="damping ratio 0.6"):
        dem.Simulation(bodies.copy(), law, box=box, dt=1.01 * probe.dt_stable)
    # dashpots heavy enough to push the accurate default step past the stable one:
    # the default falls to half the largest step accepted
    heavy = dem.LinearSpring(kn=KN, gamma_n=10.0 * gamma_n)
    sim = dem.Simulation(bodies.copy(), heavy, box=box)
    assert sim.dt == 0.5 * sim.dt_stable < dem.DT_FACTOR * sim.dt_crit


# --------------------------------------------------------------------------- RVE
def test_relaxation_that_cannot_finish_says_what_to_change():
    """Nine disks of a precompressed square lattice, jostled out of equilibrium:
    undamped, they cannot relax in 200 steps; damped, they do."""
    r, d0 = 1e-3, 1e-6
    a = 2.0 * r - d0
    axes = [(np.arange(3) + 0.5) * a] * 2
    pos = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 2)
    pos += np.random.default_rng(1).normal(0.0, 0.2 * d0, pos.shape)

    def rve(damping, cap):
        bodies = dem.Bodies.spheres(pos, radius=r, density=2650.0)
        return RVE(bodies, dem.LinearSpring(kn=1e8), dem.boundary.PeriodicCell([3 * a] * 2),
                   damping=damping, max_relax_steps=cap)

    deps = np.diag([-1e-4, 0.0])
    with pytest.raises(RelaxationError, match=r"did not relax within 200 steps.*"
                       r"lower the strain increment, raise damping or max_relax_steps"):
        rve(0.0, 200).apply_strain(deps)
    done = rve(0.5, 20_000)
    done.apply_strain(deps)
    assert done.last_relax_steps < 20_000


# --------------------------------------------------------------------------- Newton
E, NU, GAMMA_REF = 1e6, 0.3, 1e-3
Q_LIM = 2.0 * lame(E, NU)[1] * GAMMA_REF  # uniaxial limit of the hyperbolic law


def pressed_block(level, min_step=1.0 / 16.0):
    """A block on rollers under a top pressure ``level x Q_LIM``, ramped."""
    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [1, 1]), "quad1")
    farm = SerialFarm([Hyperbolic(E, NU, GAMMA_REF) for _ in range(macro.n_gp)])
    dofs = np.unique(np.concatenate([macro.dofs("left", 0), macro.dofs("bottom", 1)]))
    return Solver(macro, farm, Supports(dofs, np.zeros(dofs.size)),
                  f_ramp=macro.pressure_force("top", level * Q_LIM),
                  settings=SolverSettings(min_step=min_step))


def test_newton_cuts_a_large_step_and_converges():
    solver = pressed_block(0.9)
    solver.advance(1.0)
    assert solver.t == pytest.approx(1.0) and solver.cuts >= 1


@pytest.mark.filterwarnings("ignore:Matrix is exactly singular")
def test_newton_past_the_limit_load_stops_at_the_minimum_step():
    solver = pressed_block(1.05)
    with pytest.raises(SolverError, match=r"minimum step 0\.0625 x 1 .*holds the last "
                                          r"converged state"):
        solver.advance(1.0)
    # stopped just short of the limit, t_lim = 1 / 1.05, in a consistent state
    assert 0.85 < solver.t < 1.0 / 1.05
    assert np.all(np.isfinite(solver.u)) and solver.cuts >= 4
    np.testing.assert_allclose(solver.sigma, solver.farm.stress(), rtol=1e-12)


@pytest.mark.filterwarnings("ignore:Matrix is exactly singular")
def test_a_stopped_run_writes_and_marks_its_last_converged_state(tmp_path):
    from hmm.problem import validate_problem
    from hmm.run import run_problem

    problem = validate_problem({
        "mesh": {"dim": 2, "element": "quad1", "size": [1.0, 1.0], "cells": [1, 1]},
        "dirichlet": [{"boundary": "bottom", "component": "y", "value": 0.0},
                      {"boundary": "left", "component": "x", "value": 0.0}],
        "pressure": [{"boundary": "top", "value": 1.05 * Q_LIM, "ramp": True}],
        "load": {"steps": 4},
        "micro": {"model": "hyperbolic", "young": E, "poisson": NU,
                  "gamma_ref": GAMMA_REF},
        "solver": {"min_step": 1.0 / 16.0},
        "output": {"every": 3},
    }, source="<test>")
    with pytest.raises(SolverError, match=r"last frame of .*fields\.h5"):
        run_problem(problem, tmp_path / "out")
    with h5py.File(tmp_path / "out" / "fields.h5") as f:
        t = f.attrs["last_converged_load_factor"]
        assert 0.75 < t < 1.0 / 1.05  # step 4 was partly done when it stopped
        assert "minimum step" in f.attrs["stopped"]
        last = f[f"steps/{f.attrs['last_converged_step']:05d}"]
        assert last.attrs["load_factor"] == t
        assert f["curve/load_factor"][-1] == t


# --------------------------------------------------------------------------- ADMM
def test_admm_with_too_small_a_cap_names_the_pair():
    """Two pentagons under ADMM detection (the loop of the polygon checkpoint test):
    one iteration cannot reach 1e-8, warm or cold; the default cap can."""
    law = dem.LinearSpring(kn=1e5, kt=5e4, mu=0.4, restitution=0.5)

    def pair(cap):
        b = dem.Bodies.empty(2)
        b.add_shapes(dem.ConvexPolygon.regular(5, 0.01), [[0.0, 0.0], [0.0195, 0.004]],
                     2500.0, rot=[0.3, 1.1], vel=[[0.1, 0.0], [-0.1, 0.0]])
        return dem.Simulation(b, law, detection="admm", admm_max_iter=cap, threads=1)

    with pytest.raises(dem.SimulationError,
                       match=r"between bodies 0 and 1 did not converge in 1 ADMM "
                             r"iterations, warm or cold.*raise admm_max_iter"):
        pair(1).run(100)
    sim = pair(200)
    sim.run(100)
    assert sim.shape_state.iters.max() > 1
