"""A multiscale run from a validated problem: build, solve step by step, write.

:func:`run_problem` is what ``hmm run`` and ``hmm demo`` call. :data:`DEMO` is the
embedded demonstration problem: a 2D drained biaxial compression of a dense granular
sample (4 x 8 cm, 2 x 4 bilinear elements, 32 Gauss points each running a periodic
RVE of 60 disks), confined at 100 kPa and shortened by 1 % in 8 load steps.
"""

import logging
import time
from pathlib import Path

import numpy as np

from dem.progress import progress_bar
from dem.io.files import OutputError

from .checkpoint import Checkpoint
from .checkpoint import save as save_checkpoint
from .coupling import Solver, SolverError, SolverSettings
from .porous import BiotSolver
from .farm import mpi_world
from .signals import Interrupted, held
from .io import Output
from .problem import validate_problem
from .problem_build import build_farm, build_loads, build_macro, build_porous

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
    "solver": {"tol_residual": 1e-2, "tol_displacement": 5e-3, "max_iterations": 10},
    "output": {"dir": "output/demo"},
}


def run_problem(problem, directory, overwrite=False, progress=None, echo=None,
                restart=False, stop_after=None):
    """Solve a validated problem, writing into ``directory``.

    Under ``mpiexec`` with several ranks every rank calls this: rank 0 solves and
    writes, the others run their share of the Gauss points and return None.
    ``echo(line)`` receives a few lines of narrative (set-up, timing).
    ``restart`` continues from ``directory/checkpoint.h5`` (see
    :mod:`hmm.checkpoint`); ``stop_after`` ends the run after that load step (a
    checkpoint is written there), to split a long run into jobs. Returns (on rank 0)
    a dict summary: steps, iterations, cuts, wall time, final load factor, the farm's
    ``work`` (``rve_calls``, ``rve_seconds`` summed over the points, ``dem_steps``),
    reactions (per support, ``(d,)`` [N/m in 2D, N in 3D]) and the components each
    support holds (``held``), output files.
    """
    _, comm = mpi_world()
    rank = 0 if comm is None else comm.Get_rank()
    say = (echo if rank == 0 else None) or (lambda line: None)
    t0 = time.perf_counter()
    macro = build_macro(problem)
    supports, f_const, f_ramp, loads = build_loads(problem, macro)
    porous, schedule = build_porous(problem, macro)
    platens = tuple(dict.fromkeys(c["boundary"] for c in problem["platen"]))
    say(f"mesh: {macro.n_elems} {macro.element} elements, {macro.n_dofs} dofs"
        + (f" + {porous.n_p} pore pressures ({porous.p_element})" if porous else "")
        + f", {macro.n_gp} Gauss points"
        + (f", {comm.Get_size()} MPI ranks" if comm else ""))
    driven = driven_components(problem, macro.dim)
    ck = None
    out, refused = None, None
    try:  # every rank opens the checkpoint: each reads its own points from it
        _refuse_directories(directory)
        if restart:
            ck = Checkpoint(Path(directory) / "checkpoint.h5", problem)
            ck.check(macro, Output.curve_names(supports.boundaries, porous is not None,
                                               platens), porous, schedule)
            _check_stop(ck, stop_after)
        if rank == 0:
            out = Output(directory, macro, supports.boundaries, problem["output"]["every"],
                         overwrite=overwrite, driven=driven,
                         restart=(ck.step, ck.curve()) if ck is not None else None,
                         porous=porous, platens=platens, config=problem)
    except (OSError, ValueError) as err:  # an existing output, a file in the path
        refused = err
    if comm is not None:
        refused = comm.allgather(refused)
        refused = next((e for e in refused if e is not None), None)
    if refused is not None:
        if ck is not None:
            ck.close()
        raise refused
    try:
        farm = build_farm(problem, macro)
        if ck is not None:
            try:
                farm.load(ck.micro_state)
            except (KeyError, TypeError, IndexError) as err:
                raise ValueError(f"{ck.path}: a micro state does not fit the problem "
                                 f"({err})") from None
    except BaseException:
        if out is not None:  # the run never started: leave no output
            out.discard()
        raise
    finally:
        if ck is not None and rank != 0:
            ck.close()
    if rank != 0:
        farm.serve()
        return None
    return _solve_and_close((problem, macro, farm, supports, (f_const, f_ramp, loads),
                             out, progress, say, t0, ck, stop_after, (porous, schedule)),
                            comm)


def driven_components(problem, dim):
    """``[(boundary, component)]`` that a ``[[dirichlet]]`` moves (a non-zero value,
    or a gradient with a non-zero row): the curves of ``load_displacement.png``."""
    from .conditions import gradient_tensor

    out = []
    for c in problem["dirichlet"]:
        if c["boundary"] is None:
            continue
        comps = range(dim) if c["component"] is None else ["xyz".index(c["component"])]
        if c["gradient"] is None:
            moved = [k for k in comps if c["value"] != 0.0]
        else:
            g = gradient_tensor(c["gradient"], dim)
            moved = [k for k in comps if np.any(g[k] != 0.0)]
        out += [(c["boundary"], k) for k in moved if (c["boundary"], k) not in out]
    return out


#: the files a run writes into its directory
OUTPUT_FILES = ("fields.h5", "fields.xdmf", "checkpoint.h5", "load_displacement.png",
                "deviatoric_strain.png", "pore_pressure.png")


def _check_stop(ck, stop_after):
    """ValueError if a restart from ``ck`` would stop before it ran a step."""
    if stop_after is not None and stop_after <= ck.step:
        raise ValueError(f"--stop-after {stop_after}: the checkpoint {ck.path} is at "
                         f"load step {ck.step} already; give a later step")


def _refuse_directories(directory):
    """FileExistsError if one of :data:`OUTPUT_FILES` is a directory (``--overwrite``
    cannot replace it)."""
    for name in OUTPUT_FILES:
        path = Path(directory) / name
        if path.is_dir():
            raise FileExistsError(f"{path} is a directory, not an output file: remove "
                                  f"it or choose another directory with --output")


def _solve_and_close(args, comm):
    """:func:`_solve` on ``args``, then the farm, the output and the checkpoint closed;
    after an interrupt without the figures (the user asked to stop now, and drawing
    takes seconds)."""
    farm, out, ck = args[2], args[5], args[9]
    plots, failed = True, None
    try:
        return _solve(*args)
    except (Interrupted, KeyboardInterrupt):
        plots = False
        raise
    except OutputError as err:  # the disk refused a file: no figures, and that error
        plots, failed = False, err
        raise
    finally:
        if comm is not None:
            farm.close()
        try:
            out.close(plots=plots)
        except OutputError:
            if failed is None:
                raise
        if ck is not None:
            ck.close()


def _solve(problem, macro, farm, supports, loading, out, progress, say, t0,
           ck, stop_after, saturated=(None, None)):
    say(f"micro models ready ({problem['micro']['model']}) in "
        f"{time.perf_counter() - t0:.1f} s")
    st = problem["solver"]
    settings = SolverSettings.from_section(st)
    f_const, f_ramp, loads = loading
    porous, schedule = saturated
    n = problem["load"]["steps"]
    if porous is None:
        solver = Solver(macro, farm, supports, f_const, f_ramp, settings, loads)
        ends = np.arange(1, n + 1) / n  # the load factor at the end of each step
    else:
        solver = BiotSolver(porous, farm, supports, schedule, f_const, f_ramp, settings,
                            st["coupling"], loads)
        ends = schedule.times()  # [s]
    first = 1
    if ck is None:
        out.write(0, solver, farm.measures(), 0, force_frame=True)
    else:
        ck.restore_solver(solver)
        first = ck.step + 1
        say(f"restarted from the checkpoint of step {ck.step}")
    every_ck = problem["output"]["checkpoint_every"]
    last = n if stop_after is None else min(n, int(stop_after))
    bar = progress_bar(last - first + 1, progress, min_steps=1, unit="load step")
    t1 = time.perf_counter()
    try:
        for k in range(first, last + 1):

            def show(it, r, d):
                if bar is not None:
                    bar.set_postfix_str(f"Newton {it}: |r|/|f| = {r:.1e}")

            try:
                its = solver.advance(ends[k - 1] - solver.t, on_iteration=show)
            except SolverError as err:
                # cut sub-steps of step k may have converged before the stop
                begin = ends[k - 2] if k > 1 else 0.0
                partial = solver.t > begin + 1e-12 * ends[-1] / n
                done = solver.iterations[-1] if solver.iterations else 0
                out.stopped(k if partial else k - 1, solver, farm.measures(), done,
                            str(err), partial=partial)
                clock = "load factor" if porous is None else "time [s]"
                raise SolverError(f"load step {k} of {n}: {err}; that state ({clock} "
                                  f"{solver.t:.6g}) is the last frame of "
                                  f"{out.path}") from err
            out.write(k, solver, farm.measures(), its, force_frame=(k == n))
            log.info("load step %d of %d done: clock %.6g, %d Newton iterations, "
                     "%d cuts so far, %.1f s", k, n, solver.t, its, solver.cuts,
                     time.perf_counter() - t1)
            if (every_ck and k % every_ck == 0) or k == last < n:
                state = farm.export()
                with held():  # HDF5 must not be left mid-write (hmm.signals.held)
                    save_checkpoint(out.dir / "checkpoint.h5", problem, k, solver,
                                    out.curve, state)
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    solve_time = time.perf_counter() - t1
    m = farm.measures()
    return {"steps": last, "iterations": list(solver.iterations), "cuts": solver.cuts,
            "trials": farm.n_trials, "solve_time": solve_time,
            "total_time": time.perf_counter() - t0,
            "load_factor": solver.t if porous is None else schedule.load_factor(solver.t),
            "dem_points": int(np.sum(m["ran_dem"] > 0)), "gauss_points": macro.n_gp,
            "reactions": {k: v.tolist() for k, v in solver.reactions().items()},
            "held": solver.held_components(), "dim": macro.dim,
            "u": solver.u.copy(), "sigma": solver.sigma.copy(),
            "migrated": getattr(farm, "n_migrated", 0),
            "work": dict(zip(("rve_calls", "rve_seconds", "dem_steps"),
                             m["work"].tolist(), strict=True)),
            "files": [str(out.dir / f) for f in ("fields.h5", "fields.xdmf",
                                                 "load_displacement.png",
                                                 "deviatoric_strain.png")]
                      + ([str(out.dir / "pore_pressure.png")] if porous else []),
            **({} if porous is None else {"time": solver.t, "p": solver.p.copy()})}


def demo_problem():
    """The validated :data:`DEMO` problem."""
    return validate_problem(DEMO, source="<demo>")
