"""Dry runs of ``hmm run``, ``hmm rve`` and ``hmm batch``: read and check everything
the real run will read, check that its outputs can be written, print the plan.

A dry run opens every input file the run opens (packings, meshes, a restart's
checkpoint and ``fields.h5``, a batch file it would resume), with the same checks, and
refuses what the real run would refuse about existing outputs. It creates nothing and
opens nothing for writing. What it does not do is generate packings or run DEM: a
generated packing that cannot be consolidated fails the real run (exit status 1, not
an input error).

The plan gives sizes, steps, the memory of the particle state
(:func:`dem.limits.memory_estimate`), the work that sets the run time (RVE calls for
``hmm run``: each a DEM relaxation, at least one per Gauss point, load step and Newton
iteration; particle-increments for ``hmm rve`` and ``hmm batch``) and the time the
cost model :mod:`dem.cost` gives for that work on one core.
"""

from pathlib import Path

import numpy as np

from dem.cost import fe2_seconds, rve_test_seconds, time_line
from dem.io.plan import check_new_files, check_writable_dir
from dem.io.schema import SceneError
from dem.limits import memory_estimate

__all__ = ["plan_batch", "plan_rve", "plan_run", "strain_increment"]


def plan_run(problem, directory, overwrite=False, restart=False, stop_after=None):
    """Check a validated problem as :func:`hmm.run.run_problem` would, writing
    nothing; return the plan as one line.

    Raises SceneError, FileExistsError, FileNotFoundError, ValueError or OSError
    (one line each), as the real run does for the same input.
    """
    from .problem_build import build_loads, build_macro, build_porous

    directory = Path(directory)
    macro = build_macro(problem)
    supports, *_ = build_loads(problem, macro)
    porous, schedule = build_porous(problem, macro)
    first = 1
    if restart:
        first = _check_restart(problem, directory, macro, supports, porous, schedule,
                               stop_after) + 1
    else:  # as hmm.io.Output: an existing fields.h5 needs --overwrite
        from .run import _refuse_directories

        _refuse_directories(directory)
        check_new_files([directory / "fields.h5"], overwrite)
    check_writable_dir(directory)
    n_particles = _check_packings(problem, macro)
    n = problem["load"]["steps"]
    last = n if stop_after is None else min(n, stop_after)
    steps = (f"{n} load steps" if first == 1 and last == n
             else f"load steps {first} to {last} of {n}")
    calls = macro.n_gp * (last - first + 1)
    mc = problem["micro"]
    work = ""
    if mc["model"] in ("dem", "adaptive"):
        increment = strain_increment(problem, macro.mesh.p)
        seconds = fe2_seconds(n_particles, macro.dim, macro.n_gp, last - first + 1,
                              mc["max_step_strain"], generated=mc["packing"] is None,
                              shaped=mc["shape"] != "sphere", relax=mc["relax"],
                              predictor=problem["solver"]["predictor"],
                              **({} if increment is None else {"increment": increment}))
        work = (f"; work at least {calls} RVE calls ({macro.n_gp} Gauss points x "
                f"{last - first + 1} load steps, times the Newton iterations); "
                + time_line(seconds, at_most=mc["model"] == "adaptive"))
    memory = ("" if n_particles is None else
              f"; memory {memory_estimate(n_particles * macro.n_gp, macro.n_gp)}")
    mode = (f"restart from step {first - 1}" if restart else
            "replaced" if overwrite and (directory / "fields.h5").exists() else "new")
    return (f"{problem['source']}: valid; {macro.n_elems} elements, {macro.n_gp} Gauss "
            f"points, {steps}; output {directory} ({mode}){memory}{work}")


def strain_increment(problem, points):
    """The macro strain increment of one load step [-] that the cost model gives each
    RVE call: the largest prescribed displacement (``[[dirichlet]] value``) over the
    extent of the mesh ``points`` (d, n) [m] along its component, or the largest entry
    of a prescribed displacement gradient (``[[dirichlet]] gradient``, ``[load]
    gradient``), over the load steps. None when no displacement is prescribed (a run
    driven by forces): the cost model's default then applies.

    >>> import numpy as np
    >>> problem = {"dirichlet": [{"component": "y", "value": -0.02, "gradient": None}],
    ...            "load": {"steps": 200, "gradient": None}}
    >>> strain_increment(problem, np.array([[0.0, 0.05, 0.0], [0.0, 0.0, 0.1]]))
    0.001
    """
    from .problem_schema import COMPONENTS

    extent = np.ptp(np.asarray(points, float), axis=1)
    strains = [abs(float(c["value"])) / extent[COMPONENTS.index(c["component"])]
               for c in problem.get("dirichlet", ()) if c.get("gradient") is None
               and c.get("component") in COMPONENTS and c.get("value")
               and extent[COMPONENTS.index(c["component"])] > 0.0]
    gradients = [c["gradient"] for c in problem.get("dirichlet", ())
                 if c.get("gradient") is not None]
    if problem["load"].get("gradient") is not None:
        gradients.append(problem["load"]["gradient"])
    strains += [float(np.max(np.abs(np.asarray(g, float)))) for g in gradients]
    largest = max(strains, default=0.0)
    return float(largest) / problem["load"]["steps"] if largest > 0.0 else None


def _check_restart(problem, directory, macro, supports, porous, schedule, stop_after):
    """The checkpoint's step, after the checks of a restart (checkpoint, fields.h5,
    the micro states of analytic models); nothing is changed."""
    from .checkpoint import Checkpoint
    from .io import Output
    from .problem_build import build_farm
    from .run import _check_stop, _refuse_directories

    _refuse_directories(directory)
    platens = tuple(dict.fromkeys(c["boundary"] for c in problem["platen"]))
    ck = Checkpoint(directory / "checkpoint.h5", problem)
    try:
        curve = Output.curve_names(supports.boundaries, porous is not None, platens)
        ck.check(macro, curve, porous, schedule)
        _check_stop(ck, stop_after)
        # reads fields.h5 and checks its frames; it changes the file only on a write
        Output(directory, macro, supports.boundaries, problem["output"]["every"],
               restart=(ck.step, ck.curve()), porous=porous, platens=platens).discard()
        if problem["micro"]["model"] not in ("dem", "adaptive"):  # cheap to build
            try:
                build_farm(problem, macro).load(ck.micro_state)
            except (KeyError, TypeError, IndexError) as err:
                raise ValueError(f"{ck.path}: a micro state does not fit the problem "
                                 f"({err})") from None
        return ck.step
    finally:
        ck.close()


def _check_packings(problem, macro):
    """Read the packing files the run reads (``[micro] packing``, and the packing of
    every ``[[imperfection]]`` that holds a Gauss point), with the run's checks;
    return the particles of one RVE (None for analytic models)."""
    from .problem_build import _packing, spot_of

    mc = problem["micro"]
    if mc["model"] not in ("dem", "adaptive"):
        return None
    n = mc["count"]
    if mc["packing"] is not None:
        n = _packing(problem, 0, macro.dim, None).bodies.n
    if problem["imperfection"]:
        held = set(spot_of(problem, macro.gauss_points()).tolist())
        for i, spot in enumerate(problem["imperfection"]):
            if i in held and spot["packing"] is not None:
                _packing(problem, 0, macro.dim, None, spot)
    return n


def plan_rve(cfg, out_dir=None, overwrite=False):
    """Check a validated RVE test as :func:`hmm.experiment.run_experiment` would
    (its packing file read and checked), writing nothing; return the plan."""
    from .experiment import make_packing, output_paths
    from .experiment_config import n_increments

    paths = output_paths(cfg, out_dir)
    check_new_files(paths, overwrite)
    p = cfg["packing"]
    if p["file"] is not None:
        rve = make_packing(cfg)[0]
        n, dim, source = rve.bodies.n, rve.dim, f"read from {p['file']}"
    else:
        n, dim, source = p["count"], p["dim"], "generated"
    incs = n_increments(cfg["test"])
    return (f"{cfg['source']}: valid; {cfg['test']['kind']} test of {n} particles "
            f"({dim}D, {source}), {incs} increments; output {paths[0].parent}; memory "
            f"{memory_estimate(n)}; work {n * incs:.3g} particle-increments; "
            f"{time_line(_test_seconds(cfg, n, dim))}")


def _test_seconds(cfg, n, dim):
    """The cost model's seconds of one RVE test of ``n`` particles."""
    from .experiment_config import n_increments

    t, p = cfg["test"], cfg["packing"]
    return rve_test_seconds(n, dim, n_increments(t), t.get("increment") or 1e-4,
                            t["max_step_strain"],
                            servo=t["kind"] in ("drained", "isotropic", "simple_shear"),
                            generated=p["file"] is None,
                            shaped=p.get("shape", "sphere") != "sphere")


def plan_batch(sweep, out_dir=None, overwrite=False):
    """Check a sweep as :func:`hmm.queue.run_batch` would (the packing files of its
    experiments read, an existing ``batch.h5`` checked for resuming), writing
    nothing; return the plan."""
    from .batch import OUTPUTS, Store
    from .experiment import make_packing
    from .experiment_config import n_increments

    out = Path(sweep.out_dir if out_dir is None else out_dir)
    files = [out / name for name in OUTPUTS]
    check_new_files(files, True)  # a directory in the place of an output
    stored = {}
    if files[0].exists() and not overwrite:
        stored = _stored(Store, files[0], sweep)
    check_writable_dir(out)
    todo = [e for e in sweep.experiments if e.id not in stored]
    counts, work, seconds, read = [], 0, 0.0, {}
    for e in todo:
        p = e.config["packing"]
        if p["file"] is not None:
            if p["file"] not in read:
                read[p["file"]] = make_packing(e.config)[0].bodies.n
            n = read[p["file"]]
        else:
            n = p["count"]
        counts.append(n)
        work += n * n_increments(e.config["test"])
        seconds += _test_seconds(e.config, n, e.config["packing"].get("dim") or 2)
    largest = max(counts, default=0)
    return (f"{sweep.source}: valid; {len(sweep.experiments)} experiments "
            f"({len(todo)} to run, {len(stored)} already in {files[0]}); largest "
            f"packing {largest} particles; memory {memory_estimate(largest)} a rank; "
            f"work {work:.3g} particle-increments; {time_line(seconds)}")


def _stored(store_class, path, sweep):
    """The experiments an existing batch file holds, after the checks of resuming it
    (SceneError if it is not a batch of this sweep); read-only."""
    import h5py

    store = store_class.__new__(store_class)  # the checks only: nothing opened to write
    store.path, store.sweep = Path(path), sweep
    try:
        with h5py.File(path, "r") as f:
            store._check(f, sweep)
            return {name: g.attrs["status"] for name, g in f.items()
                    if "status" in g.attrs}
    except OSError as exc:
        raise SceneError(f"{path}: cannot read the batch file ({exc}); pass "
                         f"--overwrite to start afresh") from None
