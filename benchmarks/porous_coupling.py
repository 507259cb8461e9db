"""Monolithic Newton against the fixed-stress split on saturated problems.

Two problems, each solved with ``[solver] coupling = "monolithic"`` and
``"fixed_stress"`` (the split of YADE FEMxDEM's msFEMup), with the same tolerances and
Aitken relaxation for both:

* **terzaghi**: the column of ``examples/consolidation.toml`` (16 quad8 cells,
  linear-elastic micro models) to Tv = 1 in 40 steps, tolerances 1e-3; the error is
  the largest nodal pressure error against the series, relative to the load, at the
  end;
* **dem**: a 2 x 4 cm sample of 2 x 2 quad8 elements (16 Gauss points), 40-disk
  periodic RVEs consolidated to 100 kPa, drained at the top, confined at 100 kPa on
  the right, shortened by 0.4 % in 8 steps over 80 s, with the demo's tolerances
  (1e-2 on the residual, which the RVEs' relaxation noise floors, 5e-3 on the
  correction).

For both, the deviation is the largest difference of the pore pressures of the two
couplings over the run, relative to the largest pressure.

Per problem and coupling: Newton iterations (micro model calls) per step, the wall
time of the solve (median of REPEATS runs), the error or deviation. Keys:
``iterations_per_step``, ``wall_seconds``, ``speedup_monolithic`` (split wall over
monolithic wall), ``max_rel_pressure_error`` / ``max_rel_pressure_deviation``. Writes
benchmarks/results/porous_coupling.json. Run it alone on the machine (2 cores: the
DEM problem runs in a worker process with one numba thread).

environment: REPEATS (3).
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "porous_coupling.json"
COUPLINGS = ("monolithic", "fixed_stress")

DEM = {
    "mesh": {"dim": 2, "element": "quad8", "size": [0.02, 0.04], "cells": [2, 2]},
    "dirichlet": [{"boundary": "bottom", "component": "y"},
                  {"boundary": "left", "component": "x"},
                  {"boundary": "top", "component": "y", "value": -1.6e-4}],
    "pressure": [{"boundary": "right", "value": 1e5}],
    "load": {"steps": 8},
    "fluid": {"permeability": 1e-13},
    "drainage": [{"boundary": "top", "pressure": 0.0}],
    "time": {"end": 80.0},
    "micro": {"model": "dem", "count": 40, "seed": 3, "p0": 1e5},
    "solver": {"tol_residual": 1e-2, "tol_displacement": 5e-3, "max_iterations": 40},
}


def worker(args):
    import copy
    import time

    import numpy as np

    from hmm import poroelastic_solutions as exact
    from hmm.problem import load_problem, validate_problem
    from hmm.run import run_problem

    case, coupling = args[0], args[1]
    if case == "terzaghi":
        problem = load_problem(C.REPO / "examples" / "consolidation.toml")
        problem["load"]["steps"] = 40
    else:
        problem = validate_problem(copy.deepcopy(DEM), source="porous_coupling")
    problem["solver"]["coupling"] = coupling
    problem["solver"]["max_iterations"] = 40
    problem["output"]["every"] = 1
    out_dir = C.WORK / "porous_coupling" / f"{case}_{coupling}"
    t0 = time.perf_counter()
    res = run_problem(problem, out_dir, overwrite=True, progress=False)
    wall = time.perf_counter() - t0
    import h5py

    with h5py.File(out_dir / "fields.h5", "r") as f:
        y = f["mesh/points"][:, 1]
        frames = [f["steps"][k]["pore_pressure"][()] for k in sorted(f["steps"])]
    row = {"wall_seconds": wall, "solve_seconds": res["solve_time"],
           "iterations": res["iterations"], "cuts": res["cuts"],
           "pressures": [p.tolist() for p in frames]}
    if case == "terzaghi":
        mat = exact.BiotMaterial.from_young(1e7, 0.25, mobility=8.333e-8,
                                            storage_modulus=2.2e9 / 0.4)
        series = exact.terzaghi_pressure(1.0 - y, res["time"], 1.0, mat, 1e4)
        row["max_rel_pressure_error"] = float(np.abs(frames[-1] - series).max() / 1e4)
    C.emit_result(row)


def main():
    repeats = C.env_int("REPEATS", 3)
    import numpy as np

    res = {"benchmark": "porous_coupling", "date": C.now(), "machine": C.machine_info(),
           "versions": C.our_versions(), "repeats": repeats, "cases": {}}
    for case in ("terzaghi", "dem"):
        rows = {}
        for coupling in COUPLINGS:
            runs = [C.run_worker(__file__, [case, coupling], threads=1)
                    for _ in range(repeats)]
            bad = [r for r in runs if not r.get("ok", True)]
            if bad:
                raise SystemExit(f"{case} {coupling}: {bad[0]}")
            first = runs[0]
            rows[coupling] = {
                "wall_seconds": C.median([r["solve_seconds"] for r in runs]),
                "iterations_per_step": float(np.mean(first["iterations"])),
                "iterations": first["iterations"], "cuts": first["cuts"]}
            if "max_rel_pressure_error" in first:
                rows[coupling]["max_rel_pressure_error"] = first["max_rel_pressure_error"]
            rows[coupling]["_p"] = first["pressures"]
        mono, split = (np.array(rows[k].pop("_p")) for k in COUPLINGS)
        entry = {"couplings": rows,
                 "speedup_monolithic": rows["fixed_stress"]["wall_seconds"]
                 / rows["monolithic"]["wall_seconds"],
                 "max_rel_pressure_deviation": float(np.abs(mono - split).max()
                                                     / np.abs(mono).max())}
        res["cases"][case] = entry
        print(f"{case}: " + "; ".join(
            f"{k} {v['iterations_per_step']:.2f} iterations/step, "
            f"{v['wall_seconds']:.2f} s" for k, v in rows.items())
            + f"; monolithic {entry['speedup_monolithic']:.2f}x faster, pressures "
            f"differ by {entry['max_rel_pressure_deviation']:.2e}", flush=True)
    res["loadavg_end"] = C.loadavg()
    C.write_json(OUT, res)
    print(f"wrote {C.display_path(OUT)}")


if __name__ == "__main__":
    C.entry(main, worker)
