"""The 3D triaxial example measured at mid-size, and the reference's run projected from it.

Runs ``examples/triaxial_3d.toml`` (a 5 x 10 x 5 cm cuboid of 16 hex20 elements, 128
Gauss points of 1,000-sphere periodic RVEs at 100 kPa, rough platens, 40 load steps of
1e-3 axial strain) under ``mpiexec -n RANKS`` (the venv's, one numba thread per rank)
and reads its ``fields.h5``: the wall time, the RVE calls with their mean time and DEM
steps (``curve/work``), the calls per Gauss point and load step, the load curve (the
deviator and its peak), and the peak resident memory of the largest process
(``getrusage`` of the children: one rank). In this process it builds RVEs of the
example's packing and of the demo's packing at 400 disks and counts the bytes of the
numpy arrays each holds of its own (live state, neighbour list, contact history,
committed copy and a call's scratch).

From the measured calls it projects the reference's run, YADE FEMxDEM's
``triaxialRough.py``: 8 x 8 x 16 hex20 (8,192 Gauss points of about 1,000 spheres),
100 load steps of 1e-3 axial strain (its top moves 0.1 mm a step on 10 cm), which its
authors report at about 4.5 days on 16 processes (~1,700 core-hours):

    core-hours = points x steps x calls per point and step x (seconds per call
                 + the run's other core-seconds per call) / 3600

The "other" seconds (the solve's core-seconds besides the RVE calls: the macro solve,
assembly, frames, the ranks waiting for each other) are taken per call from this run,
so they scale with the number of points, as assembly does; the macro solve of 8,192
points (about 15,000 dofs) is a sparse solve of seconds, small beside the RVE calls.
The wall time on P ranks follows from the same figures: each Newton iteration calls
every point once, each rank its ceil(8,192 / P) points, so ``hours = steps x calls
per point and step x ceil(points / P) x (seconds per call + other) / 3600`` (the
measured rebalancing keeps the ranks' shares even).

usage::

    python benchmarks/triaxial_3d.py          # writes benchmarks/results/triaxial_3d.json
    TRIAXIAL_SIZE=small python benchmarks/triaxial_3d.py   # the tests' size, a minute

environment: RANKS (2), TRIAXIAL_SIZE ("mid" or "small": 1 x 2 x 1 hex20, 60 spheres,
2 steps; its JSON goes to ``triaxial_3d_small.json``).
"""

import math
import os
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

SIZE = os.environ.get("TRIAXIAL_SIZE", "mid")
OUT = C.RESULTS / ("triaxial_3d.json" if SIZE == "mid" else "triaxial_3d_small.json")
SCRATCH = C.WORK / "triaxial_3d"
EXAMPLE = C.REPO / "examples" / "triaxial_3d.toml"
#: the reference's run (triaxialRough.py) and its reported cost
REFERENCE = {"gauss_points": 8 * 8 * 16 * 8, "load_steps": 100, "axial_strain_per_step": 1e-3,
             "core_hours": 1700.0, "spheres_per_rve": 1000}
GOAL_CORE_HOURS = 20.0


def problem_file():
    """The example as run: as written, or cut to the tests' size."""
    text = EXAMPLE.read_text()
    if SIZE == "small":
        for old, new in (("cells = [2, 4, 2]", "cells = [1, 2, 1]"),
                         ("count = 1000 ", "count = 60 "), ("steps = 40 ", "steps = 2 "),
                         ("value = -0.004 ", "value = -0.0002 ")):
            assert old in text, old
            text = text.replace(old, new)
    path = SCRATCH / "triaxial_3d.toml"
    path.write_text(text)
    return path


def run(ranks):
    """Run the problem under mpiexec; wall time [s] and peak resident memory [MB]."""
    out = SCRATCH / "out"
    env = C.worker_env(1)
    cmd = [str(C.REPO / ".venv" / "bin" / "mpiexec"), "-n", str(ranks),
           str(C.REPO / ".venv" / "bin" / "hmm"), "run", str(problem_file()), "-o", str(out),
           "--overwrite"]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, env=env, cwd=SCRATCH, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(f"the run failed (exit {done.returncode}):\n{done.stderr[-3000:]}")
    peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
    return out, wall, peak_mb, done.stdout


def read_run(out):
    """What the run's fields.h5 says of its work and its load curve."""
    import h5py
    import numpy as np

    with h5py.File(out / "fields.h5") as f:
        c = {k: f["curve"][k][()] for k in ("load_factor", "iterations")}
        work = {k: f["curve/work"][k][()] for k in ("rve_calls", "rve_seconds", "dem_steps")}
        top = f["curve/force/top"][()]
        uy = f["curve/displacement/top"][()][:, 1]
        n_gp = f["gauss/weights"].shape[0]
        size = np.ptp(f["mesh/points"][()], axis=0)
    area, height = size[0] * size[2], size[1]
    calls, seconds, steps = (float(np.nansum(work[k]))
                             for k in ("rve_calls", "rve_seconds", "dem_steps"))
    n_steps = len(c["load_factor"]) - 1
    # the deviator on the platen: axial stress (its reaction over the initial area)
    # less the 100 kPa on the sides
    q = -top[:, 1] / area - 1e5
    strain = -uy / height
    k = int(np.argmax(q))
    return {"gauss_points": int(n_gp), "load_steps": n_steps,
            "newton_iterations": int(np.sum(c["iterations"])),
            "rve_calls": calls, "rve_seconds": seconds, "dem_steps": steps,
            "seconds_per_call": seconds / calls, "dem_steps_per_call": steps / calls,
            "calls_per_point_step": calls / (n_gp * n_steps),
            "axial_strain": strain.tolist(), "deviator_pa": q.tolist(),
            "peak_deviator_pa": float(q[k]), "peak_axial_strain": float(strain[k]),
            "end_deviator_pa": float(q[-1]), "end_axial_strain": float(strain[-1])}


def _arrays(root, skip=frozenset()):
    """``{id: nbytes}`` of the numpy arrays owning their data that ``root`` reaches
    through attributes, containers and array bases, leaving out the objects in ``skip``
    (ids) and code (modules, classes, functions, compiled kernels)."""
    import gc
    import types

    import numpy as np

    found, seen, todo = {}, set(skip), [root]
    code = (type, types.ModuleType, types.FunctionType, types.BuiltinFunctionType,
            types.MethodType)
    while todo:
        obj = todo.pop()
        if id(obj) in seen or isinstance(obj, code) or \
                type(obj).__module__.startswith("numba"):
            continue
        seen.add(id(obj))
        if isinstance(obj, np.ndarray):
            if obj.base is None:
                found[id(obj)] = obj.nbytes
            else:
                todo.append(obj.base)
            continue
        todo.extend(gc.get_referents(obj))
    return found, seen


def bytes_per_rve(n=4):
    """Bytes an RVE holds: the numpy arrays a model reaches (live state, neighbour
    list, contact history, committed copy, a call's scratch) that the first model of
    the same packing does not share, after a trial and a commit; the mean of ``n``
    models. For the example's 1,000 spheres and the demo's packing at 400 disks (the
    shear-band example's size)."""
    import copy

    import numpy as np

    from hmm.problem import load_problem, validate_problem
    from hmm.problem_build import model_factory
    from hmm.run import DEMO

    out = {}
    disks = copy.deepcopy(DEMO)
    disks["micro"]["count"] = 400
    for name, prob in (("spheres_1000", load_problem(EXAMPLE)),
                       ("disks_400", validate_problem(disks))):
        if SIZE == "small":
            prob["micro"]["count"] = 60
        prob["imperfection"] = []  # every model from the sample's packing
        dim = prob["mesh"]["dim"]
        factory = model_factory(prob, dim)
        models = [factory(g) for g in range(n + 1)]
        for m in models:
            m.trial(np.zeros((dim, dim)))
            m.commit()
        _, shared = _arrays(models[0])  # what every model shares is reached from it
        own = [sum(_arrays(m, shared - {id(m)})[0].values()) for m in models[1:]]
        out[name] = {"bytes": float(np.mean(own)), "particles": prob["micro"]["count"],
                     "models": n}
    return out


def main():
    ranks = C.env_int("RANKS", 2)
    SCRATCH.mkdir(parents=True, exist_ok=True)
    out, wall, peak_mb, stdout = run(ranks)
    r = read_run(out)
    solve = float(re.search(r"solved in ([0-9.]+) s", stdout).group(1))
    # the solve's core-seconds besides the RVE calls (start-up, packings and output are
    # the wall time's rest), per call
    other = (solve * ranks - r["rve_seconds"]) / r["rve_calls"]
    ref = REFERENCE
    calls = ref["gauss_points"] * ref["load_steps"] * r["calls_per_point_step"]
    projected = calls * (r["seconds_per_call"] + other) / 3600.0
    memory = bytes_per_rve()
    # wall time on P ranks: every Newton iteration calls all points, each rank its
    # share, the slowest rank sets the pace (ceil); the other core-seconds divide too
    trials = ref["load_steps"] * r["calls_per_point_step"]
    wall_on = {str(p): trials * math.ceil(ref["gauss_points"] / p)
               * (r["seconds_per_call"] + other) / 3600.0
               for p in (16, 80, 256, 1024, 8192)}
    data = {"benchmark": "triaxial_3d", "date": C.now(), "machine": C.machine_info(),
            "versions": C.our_versions(), "revision": C.git_revision(),
            "loadavg": C.loadavg(), "size": SIZE, "ranks": ranks,
            "command": f"mpiexec -n {ranks} hmm run examples/triaxial_3d.toml",
            "wall_seconds": wall, "solve_seconds": solve,
            "peak_rss_mb_per_rank": peak_mb, **r,
            "other_core_seconds_per_call": other,
            "rve_bytes": memory,
            "gauss_points_fit_per_gib": 2 ** 30 / memory["spheres_1000"]["bytes"],
            "reference_rve_gb": ref["gauss_points"] * memory["spheres_1000"]["bytes"] / 1e9,
            "reference": ref, "projected_calls": calls,
            "projected_core_hours": projected,
            "goal_core_hours": GOAL_CORE_HOURS,
            "ratio_reference_to_projected": ref["core_hours"] / projected,
            "projected_wall_hours_on_ranks": wall_on,
            "stdout": stdout.split("output:")[0].splitlines()}  # not the file paths
    C.write_json(OUT, data)
    print(f"{r['gauss_points']} Gauss points, {r['load_steps']} steps on {ranks} ranks: "
          f"{wall:.0f} s ({solve:.0f} s solving), peak {peak_mb:.0f} MB a rank")
    print(f"RVE calls {r['rve_calls']:.0f}: {1e3 * r['seconds_per_call']:.1f} ms and "
          f"{r['dem_steps_per_call']:.0f} DEM steps each, "
          f"{r['calls_per_point_step']:.2f} per point and step; "
          f"other {1e3 * other:.1f} ms a call")
    print(f"peak deviator {r['peak_deviator_pa'] / 1e3:.1f} kPa at "
          f"{100 * r['peak_axial_strain']:.2f} %; {r['end_deviator_pa'] / 1e3:.1f} kPa at "
          f"{100 * r['end_axial_strain']:.2f} %")
    print(f"bytes per RVE: {memory['spheres_1000']['bytes'] / 1e6:.2f} MB "
          f"({memory['spheres_1000']['particles']} spheres), "
          f"{memory['disks_400']['bytes'] / 1e6:.2f} MB "
          f"({memory['disks_400']['particles']} disks); the reference's 8,192 RVEs: "
          f"{data['reference_rve_gb']:.1f} GB")
    print(f"projected reference run: {projected:.1f} core-hours "
          f"({ref['core_hours'] / projected:.0f}x less than ~{ref['core_hours']:.0f}); "
          f"-> {OUT.relative_to(C.REPO)}")
    print("wall time on P ranks [h]: " + ", ".join(f"{p}: {h:.2f}" for p, h in wall_on.items()))


if __name__ == "__main__":
    C.entry(main, None)
