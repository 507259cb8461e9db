"""Saturated problems under finite kinematics: a sealed sample keeps its volume
exactly however far it is squeezed, a rigid turn leaves the pore pressure alone and
turns the effective stress, the small-strain limit, and DEM RVEs answering
undrained on the moving mesh."""

import math

import h5py
import numpy as np
import pytest
from test_finite import _all_nodes, _turn
from test_porous_problem import sealed_dem_sample

from hmm.coupling import SolverError, SolverSettings
from hmm.farm import SerialFarm
from hmm.macro import Macro, structured_mesh
from hmm.micro import Hypoelastic
from hmm.porous import BiotSolver, Fluid, PorousMacro, TimeSchedule
from hmm.problem import validate_problem
from hmm.problem_build import build_farm, build_loads, build_macro, build_porous
from hmm.run import run_problem

E, NU = 1e6, 0.3
MU = E / (2.0 * (1.0 + NU))
TIGHT = SolverSettings(tol_residual=1e-10, tol_displacement=1e-10, max_iterations=20)


def _sealed(kinematics, shortening, confining=0.0, steps=10):
    """A quad8 element of neo-Hookean micro models full of incompressible water,
    sealed, shortened by ``shortening`` of its height (the sides free but for the
    symmetry plane x = 0, a follower ``confining`` pressure on the right)."""
    problem = validate_problem({
        "mesh": {"dim": 2, "element": "quad8", "size": [1.0, 1.0], "cells": [1, 1]},
        "dirichlet": [{"boundary": "bottom", "component": "y"},
                      {"boundary": "left", "component": "x"},
                      {"boundary": "top", "component": "y", "value": -shortening}],
        "pressure": [{"boundary": "right", "value": confining}] if confining else [],
        "load": {"steps": steps},
        "time": {"end": 1.0, "ramp": 1.0},
        "fluid": {"permeability": 1e-15},
        "micro": {"model": "neo_hookean", "young": E, "poisson": NU},
        "solver": {"kinematics": kinematics},
    }, source="sealed.toml")
    return _solve(problem, Fluid(permeability=1e-15, bulk_modulus=math.inf), TIGHT)


def _solve(problem, fluid=None, settings=None):
    """The solver of a validated saturated problem after its last step (``fluid``
    in place of the file's)."""
    macro = build_macro(problem)
    sup, fc, fr, loads = build_loads(problem, macro)
    porous, schedule = build_porous(problem, macro)
    if fluid is not None:
        porous = PorousMacro(macro, fluid)
    settings = settings or SolverSettings.from_section(problem["solver"])
    solver = BiotSolver(porous, build_farm(problem, macro), sup, schedule, fc, fr,
                        settings, problem["solver"]["coupling"], loads)
    for t in schedule.times():
        solver.advance(t - solver.t)
    return solver


@pytest.mark.parametrize("confining", [0.0, 0.2 * MU])
def test_a_sealed_sample_squeezed_by_a_fifth_keeps_its_volume_exactly(confining):
    """Incompressible water, no drainage, 20 % shorter: the mixture's volume cannot
    change, so ``J = 1`` at every Gauss point and the sample widens to 1 / 0.8; the
    neo-Hookean effective stress is ``mu (b - I)`` and the water carries what the
    free (or confined) side leaves: ``p = mu (lambda_x^2 - 1) + confining``, the
    top's total stress ``mu (lambda_y^2 - 1) - p`` over the current width. Small
    kinematics keeps ``tr eps = 0`` instead, which at this size is not a constant
    volume (the area becomes 1.2 x 0.8 = 0.96)."""
    s = _sealed("finite", 0.2, confining)
    jac = np.linalg.det(s.macro.deformation(s.u))
    assert np.abs(jac - 1.0).max() < 1e-10
    f = s.macro.deformation(s.u)
    np.testing.assert_allclose(f, np.broadcast_to(np.diag([1.25, 0.8]), f.shape),
                               atol=1e-10)
    p = s.porous.gauss_pressure(s.p)
    np.testing.assert_allclose(p, MU * (1.25 ** 2 - 1.0) + confining, rtol=1e-9)
    total = s.total_stress()
    np.testing.assert_allclose(total[:, 0, 0], -confining, atol=1e-9 * MU)
    syy = MU * (0.8 ** 2 - 1.0) - p[0]
    np.testing.assert_allclose(total[:, 1, 1], syy, rtol=1e-9)
    assert s.reactions()["top"][1] == pytest.approx(syy * 1.25, rel=1e-9)
    if confining == 0.0:
        small = _sealed("small", 0.2)
        area = np.linalg.det(np.eye(2) + small.macro.strain(small.u))
        np.testing.assert_allclose(area, 0.96, rtol=1e-9)


def test_a_rigid_turn_leaves_the_pore_pressure_and_turns_the_effective_stress():
    """A pre-stressed, sealed element with 500 Pa of pore pressure turned rigidly by
    90 degrees in 20 steps: no volume changes, so the pore pressure stays 500 Pa to
    the round-off of the volume times the water's modulus, and the effective stress
    is the initial one turned, to 1e-10. Under small kinematics the turn reads as a
    volume change (``tr eps = 2 (cos theta - 1)``): within the first degree the
    water's pressure passes a thousand times the problem's pressures, and the step
    cannot be cut small enough."""
    s0 = np.array([[-1e3, 2e2], [2e2, -3e3]])
    p0 = 500.0

    def turned(kin):
        macro = Macro(structured_mesh("quad8", [1.0, 2.0], [1, 1]), "quad8", kin)
        porous = PorousMacro(macro, Fluid(permeability=1e-15, initial_pressure=p0))
        models = [Hypoelastic(E, NU, stress0=s0) for _ in range(macro.n_gp)]
        return BiotSolver(porous, SerialFarm(models),
                          _all_nodes(macro, lambda t: _turn(0.5 * math.pi * t)),
                          TimeSchedule(end=1.0, steps=20, ramp=1.0), settings=TIGHT)

    solver = turned("finite")
    before = solver.sigma.copy()
    for t in TimeSchedule(end=1.0, steps=20).times():
        solver.advance(t - solver.t)
    p = solver.porous.gauss_pressure(solver.p)
    q = _turn(0.5 * math.pi)
    # round-off of the volume, 1e-15 per step, times the water's modulus M
    assert np.abs(p - p0).max() < 20 * 1e-15 / solver.porous.fluid.storage
    np.testing.assert_allclose(solver.sigma, q @ before @ q.T, atol=1e-10 * np.abs(s0).max())
    np.testing.assert_allclose(solver.total_stress(),
                               q @ before @ q.T - p[:, None, None] * np.eye(2),
                               atol=1e-12 * np.abs(s0).max())
    with pytest.raises(SolverError, match="pore pressure .* beyond"):
        turned("small").advance(0.05)


def _column(kinematics, load):
    """Terzaghi's column of neo-Hookean points, ``load`` [Pa] on its drained top."""
    return validate_problem({
        "mesh": {"dim": 2, "element": "quad8", "size": [0.1, 1.0], "cells": [1, 8]},
        "dirichlet": [{"boundary": "bottom", "component": "y"},
                      {"boundary": "left", "component": "x"},
                      {"boundary": "right", "component": "x"}],
        "pressure": [{"boundary": "top", "value": load, "ramp": True}],
        "load": {"steps": 8},
        "time": {"end": 1.0, "first": 0.02},
        "fluid": {"permeability": 1.2e-10},
        "drainage": [{"boundary": "top", "pressure": 0.0}],
        "micro": {"model": "neo_hookean", "young": 1e7, "poisson": 0.25},
        "solver": {"kinematics": kinematics},
    }, source="column.toml")


def test_finite_and_small_consolidation_agree_to_the_order_of_the_strain(tmp_path):
    """A column consolidating under a load of 1e-4 of its stiffness: the pore
    pressures of the two kinematics agree within the strain (1e-4) of the load, at
    every step; the finite run moves its mesh."""
    runs = {}
    for kin in ("small", "finite"):
        run_problem(_column(kin, 1e3), tmp_path / kin, progress=False)
        with h5py.File(tmp_path / kin / "fields.h5", "r") as f:
            frames = [f["steps"][k] for k in sorted(f["steps"])]
            runs[kin] = np.array([g["pore_pressure"][()] for g in frames])
            if kin == "finite":  # the deformed mesh: the top has come down
                top = frames[-1]["points"][()][:, 1].max()
    assert 1.0 - 1e-3 < top < 1.0 - 1e-5
    diff = np.abs(runs["finite"] - runs["small"]).max()
    assert diff < 1e-4 * 1e3  # measured: 2.9e-5 of the load
    assert np.abs(runs["small"]).max() > 0.5e3  # the water carried the load first


def test_dem_rves_undrained_on_the_moving_mesh_keep_the_mixture_volume():
    """A sealed element of 30-disk RVEs shortened under finite kinematics: its
    volume changes only by the water's compression, ``int (J - 1) dV = -int (p -
    p_0) / M dV`` (to the change of ``J`` in the storage's volume), and the squeezed
    water's pressure rises."""
    problem = sealed_dem_sample(kinematics="finite")
    s = _solve(problem)
    jac = np.linalg.det(s.macro.deformation(s.u))
    w = s.macro.weights()
    pg = s.porous.gauss_pressure(s.p)
    assert s.cuts == 0 and np.all(pg > 0.0)
    volume = w @ (jac - 1.0)
    assert volume == pytest.approx(-0.4 / 2.2e9 * (w @ (pg * jac)), rel=1e-3)
    assert abs(volume) < 0.02 * 1e-4 * w.sum()  # a nominal 1e-4 of axial strain
