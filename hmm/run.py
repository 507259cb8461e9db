"""A multiscale run from a validated problem: build, solve step by step, write.

:func:`run_problem` is what ``hmm run`` and ``hmm demo`` call. :data:`DEMO` is the
embedded demonstration problem: a 2D drained biaxial compression of a dense granular
sample (4 x 8 cm, 2 x 4 bilinear elements, 32 Gauss points each running a periodic
RVE of 60 disks), confined at 100 kPa and shortened by 1 % in 8 load steps.
"""

import logging
import time

import numpy as np

from dem.simulation import _progress

from .coupling import Solver, SolverSettings
from .io import Output
from .problem import build_farm, build_loads, build_macro, validate_problem

log = logging.getLogger(__name__)

#: the demonstration problem of ``hmm demo`` (validated like a file)
DEMO = {
    "mesh": {"dim": 2, "element": "quad1", "size": [0.04, 0.08], "cells": [2, 4]},
    "dirichlet": [
        {"boundary": "bottom", "component": "y", "value": 0.0},
        {"boundary": "left", "component": "x", "value": 0.0},
        {"boundary": "top", "component": "y", "value": -0.0008},
    ],
    "pressure": [{"boundary": "right", "value": 1e5}],
    "load": {"steps": 8},
    "micro": {"model": "dem", "count": 60, "radius": [0.8e-3, 1.2e-3], "p0": 1e5,
              "kn": 1e8, "kt": 5e7, "mu": 0.5, "seed": 1, "packings": 1,
              "damping": 0.5, "tol": 1e-3},
    "solver": {"tol_residual": 5e-3, "tol_displacement": 5e-3, "max_iterations": 10},
    "output": {"dir": "output/demo"},
}


def run_problem(problem, directory, overwrite=False, progress=None, echo=None):
    """Solve a validated problem, writing into ``directory``.

    ``echo(line)`` receives a few lines of narrative (set-up, timing). Returns a dict
    summary: steps, iterations, cuts, wall time, final load factor, output files.
    """
    say = echo or (lambda line: None)
    t0 = time.perf_counter()
    macro = build_macro(problem)
    supports, f_const, f_ramp = build_loads(problem, macro)
    say(f"mesh: {macro.n_elems} {macro.element} elements, {macro.n_dofs} dofs, "
        f"{macro.n_gp} Gauss points")
    driven = [(c["boundary"], "xyz".index(c["component"])) for c in problem["dirichlet"]
              if c["value"] != 0.0]
    out = Output(directory, macro, supports.boundaries, problem["output"]["every"],
                 overwrite=overwrite, driven=driven)
    try:
        farm = build_farm(problem, macro)
        say(f"micro models ready ({problem['micro']['model']}) in "
            f"{time.perf_counter() - t0:.1f} s")
        st = problem["solver"]
        settings = SolverSettings(st["tol_residual"], st["tol_displacement"],
                                  st["max_iterations"], st["min_step"])
        solver = Solver(macro, farm, supports, f_const, f_ramp, settings)
        n = problem["load"]["steps"]
        out.write(0, solver, farm.measures(), 0, force_frame=True)
        bar = _progress(n, progress)
        t1 = time.perf_counter()
        try:
            for k in range(1, n + 1):
                state = {}

                def show(it, r, d, state=state):
                    state.update(it=it, r=r)
                    if bar is not None:
                        bar.set_postfix_str(f"Newton {it}: |r|/|f| = {r:.1e}")

                its = solver.advance(1.0 / n, on_iteration=show)
                out.write(k, solver, farm.measures(), its, force_frame=(k == n))
                if bar is not None:
                    bar.update(1)
        finally:
            if bar is not None:
                bar.close()
        solve_time = time.perf_counter() - t1
    finally:
        out.close()
    m = farm.measures()
    summary = {"steps": n, "iterations": list(solver.iterations), "cuts": solver.cuts,
               "trials": farm.n_trials, "solve_time": solve_time,
               "total_time": time.perf_counter() - t0, "load_factor": solver.t,
               "dem_points": int(np.sum(m["ran_dem"] > 0)), "gauss_points": macro.n_gp,
               "reactions": {k: v.tolist() for k, v in solver.reactions().items()},
               "files": [str(out.dir / f) for f in ("fields.h5", "fields.xdmf",
                                                     "load_displacement.png",
                                                     "deviatoric_strain.png")]}
    return summary


def demo_problem():
    """The validated :data:`DEMO` problem."""
    return validate_problem(DEMO, source="<demo>")
