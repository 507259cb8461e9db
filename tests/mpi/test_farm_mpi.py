"""The MPI farm under ``mpiexec -n 2`` (``make test-mpi``): bit-for-bit equality with the
serial farm, restart equality, and a failing Gauss point on rank 1 that ends the run
with its id instead of a hang.

Every rank runs each test; outcomes are broadcast from rank 0 so all ranks pass or fail
together and none is left waiting in a collective.
"""

import copy

import numpy as np
import pytest

MPI = pytest.importorskip("mpi4py.MPI")

from hmm.coupling import Solver, SolverSettings
from hmm.farm import MPIFarm, SerialFarm
from hmm.micro import LinearElastic
from hmm.problem import validate_problem
from hmm.problem_build import build_loads, build_macro, build_porous, model_factory
from hmm.run import DEMO, run_problem

pytestmark = pytest.mark.mpi
COMM = MPI.COMM_WORLD


def _small_demo(steps=3):
    prob = copy.deepcopy(DEMO)
    prob["mesh"]["cells"] = [1, 2]
    prob["micro"]["count"] = 30
    prob["load"]["steps"] = steps
    prob["dirichlet"][2]["value"] = -0.0001 * steps
    prob["solver"]["kinematics"] = "finite"  # the RVEs turn, the mesh moves
    return validate_problem(prob)


class SkewedFarm(MPIFarm):
    """An MPI farm told that later points cost more, so the first rebalancing moves
    points whatever the measured times (which on a loaded machine may be even)."""

    def balance_cost(self):
        return np.arange(1.0, self.n + 1.0) ** 2


def _all_ranks_agree(ok, message=""):
    ok, message = COMM.bcast((ok, message), root=0)
    assert ok, message


def _solve(problem, farm, steps):
    macro = build_macro(problem)
    sup, fc, fr, loads = build_loads(problem, macro)
    solver = Solver(macro, farm, sup, fc, fr, SolverSettings(5e-3, 5e-3, 10), loads)
    for k in range(1, steps + 1):
        solver.advance(k / steps - solver.t)
    return solver


def test_mpi_farm_equals_the_serial_farm_bit_for_bit():
    problem = _small_demo()
    macro = build_macro(problem)
    factory = model_factory(problem, macro.dim)
    farm = SkewedFarm(COMM, macro.n_gp, macro.dim, factory)
    if COMM.rank == 0:
        try:
            par = _solve(problem, farm, 3)
        finally:
            farm.close()
        migrated = farm.n_migrated
        ser = _solve(problem, SerialFarm([factory(g) for g in range(macro.n_gp)]), 3)
        same = (np.array_equal(par.u, ser.u) and np.array_equal(par.sigma, ser.sigma)
                and par.iterations == ser.iterations)
        _all_ranks_agree(same and migrated > 0,
                         f"u equal {np.array_equal(par.u, ser.u)}, migrated {migrated}")
    else:
        farm.serve()
        _all_ranks_agree(None)


def test_restart_on_two_ranks_repeats_the_run(tmp_path_factory):
    base = COMM.bcast(str(tmp_path_factory.mktemp("restart")) if COMM.rank == 0 else None)
    problem = _small_demo(steps=4)
    problem["output"]["checkpoint_every"] = 2
    full = run_problem(problem, f"{base}/full", progress=False)
    run_problem(problem, f"{base}/cut", progress=False, stop_after=1)
    again = run_problem(problem, f"{base}/cut", progress=False, restart=True)
    if COMM.rank == 0:
        _all_ranks_agree(np.array_equal(full["u"], again["u"])
                         and np.array_equal(full["sigma"], again["sigma"]),
                         "restarted run differs")
    else:
        assert full is None and again is None
        _all_ranks_agree(None)


class _FailsOnRankOne(LinearElastic):
    def trial(self, deps):
        raise RuntimeError("injected failure")


def test_a_failing_point_on_rank_one_ends_the_run_with_its_id():
    problem = validate_problem({"mesh": {"size": [1.0, 1.0], "cells": [2, 1]},
                                "dirichlet": [{"boundary": "bottom", "component": "y"},
                                              {"boundary": "left", "component": "x"},
                                              {"boundary": "top", "component": "y",
                                               "value": -0.01}],
                                "micro": {"model": "linear_elastic", "young": 1e6,
                                          "poisson": 0.3}})
    macro = build_macro(problem)
    bad = macro.n_gp - 1  # the last block: rank 1's

    def factory(g):
        return (_FailsOnRankOne if g == bad else LinearElastic)(1e6, 0.3, 2)

    # rank 0 meets the failure twice: in the solver's first trial (its initial
    # tangents) and in a direct trial; either way the point's id comes back
    farm = MPIFarm(COMM, macro.n_gp, macro.dim, factory)
    assert bad not in farm.models or COMM.rank == 1
    if COMM.rank == 0:
        try:
            sup, fc, fr, loads = build_loads(problem, macro)
            try:
                Solver(macro, farm, sup, fc, fr, SolverSettings(min_step=0.25), loads)
                message = "no failure"
            except Exception as err:  # noqa: BLE001 - the message is the test
                message = str(err)
            try:
                farm.trial(np.zeros((macro.n_gp, 2, 2)))
                message2 = "no failure"
            except Exception as err:  # noqa: BLE001
                message2 = f"{type(err).__name__}: {err}"
        finally:
            farm.close()
        _all_ranks_agree(f"Gauss point {bad}: RuntimeError: injected failure" in message2
                         and f"Gauss point {bad}" in message, f"{message} / {message2}")
    else:
        farm.serve()
        _all_ranks_agree(None)


def test_a_saturated_run_on_two_ranks_equals_one_rank_and_restarts(tmp_path_factory):
    """Biot u-p over DEM RVEs farmed on two ranks: the same pressures and
    displacements as on one, and a restart repeats the run."""
    base = COMM.bcast(str(tmp_path_factory.mktemp("biot")) if COMM.rank == 0 else None)
    prob = copy.deepcopy(DEMO)
    prob["mesh"].update(element="quad8", cells=[1, 1])
    prob["micro"]["count"] = 30
    prob["load"]["steps"] = 3
    prob["dirichlet"][2]["value"] = -0.0003
    prob["fluid"] = {"permeability": 1e-12}
    prob["drainage"] = [{"boundary": "top", "pressure": 0.0}]
    prob["time"] = {"end": 30.0, "first": 1.0}
    prob["output"]["checkpoint_every"] = 2
    problem = validate_problem(prob)
    full = run_problem(problem, f"{base}/full", progress=False)
    run_problem(problem, f"{base}/cut", progress=False, stop_after=1)
    again = run_problem(problem, f"{base}/cut", progress=False, restart=True)
    if COMM.rank == 0:
        from hmm.porous import BiotSolver

        macro = build_macro(problem)
        sup, fc, fr, _ = build_loads(problem, macro)
        porous, schedule = build_porous(problem, macro)
        factory = model_factory(problem, macro.dim)
        ser = BiotSolver(porous, SerialFarm([factory(g) for g in range(macro.n_gp)]),
                         sup, schedule, fc, fr, SolverSettings.from_section(
                             problem["solver"]))
        for t in schedule.times():
            ser.advance(t - ser.t)
        same = (np.array_equal(full["u"], ser.u) and np.array_equal(full["p"], ser.p)
                and np.array_equal(full["u"], again["u"])
                and np.array_equal(full["p"], again["p"]) and full["p"].max() > 0.0)
        _all_ranks_agree(same, "saturated run differs between ranks or on restart")
    else:
        assert full is None and again is None
        _all_ranks_agree(None)


def test_a_small_3d_triaxial_on_two_ranks_equals_one_rank_bit_for_bit(tmp_path_factory):
    """examples/triaxial_3d.toml at small size (1 x 2 x 1 hex20, 60-sphere RVEs, two
    steps; tests/hmm/test_triaxial_3d.py) farmed on two ranks: displacements,
    stresses and the gathered measures (the contact fabric, void ratio) equal a
    serial farm's bit for bit, and so do the RVE calls and DEM steps it counts."""
    import h5py

    from hmm.problem_build import build_loads
    from problems import small_triaxial

    base = COMM.bcast(str(tmp_path_factory.mktemp("tri")) if COMM.rank == 0 else None)
    problem = small_triaxial()
    full = run_problem(problem, f"{base}/par", progress=False)
    if COMM.rank == 0:
        macro = build_macro(problem)
        sup, fc, fr, loads = build_loads(problem, macro)
        factory = model_factory(problem, macro.dim, points=macro.gauss_points())
        farm = SerialFarm([factory(g) for g in range(macro.n_gp)])
        ser = Solver(macro, farm, sup, fc, fr,
                     SolverSettings.from_section(problem["solver"]), loads)
        for k in range(1, 3):
            ser.advance(k / 2 - ser.t)
        m = farm.measures()
        with h5py.File(f"{base}/par/fields.h5") as f:
            last = f["steps/00002"]
            same = {"u": np.array_equal(full["u"], ser.u),
                    "sigma": np.array_equal(full["sigma"], ser.sigma),
                    "fabric": np.array_equal(last["gauss/fabric"][()], m["fabric"]),
                    "void": np.array_equal(last["void_ratio"][()], m["void_ratio"].reshape(
                        macro.n_elems, macro.n_qp).mean(axis=1)),
                    "work": (full["work"]["rve_calls"], full["work"]["dem_steps"])
                    == (farm.work[0], farm.work[2])}
        _all_ranks_agree(all(same.values()), f"two ranks against one: {same}")
    else:
        assert full is None
        _all_ranks_agree(None)
