"""What finite kinematics costs and changes on the demonstration problem: the case for
the default.

The problem is ``hmm demo`` (a 4 x 8 cm plane-strain sample, 2 x 4 quad1 elements, 32
Gauss points with relaxed 60-disk periodic RVEs, 100 kPa lateral pressure, the top
pushed down), solved with ``[solver] kinematics`` "small" and "finite" to each axial
strain of ``CASES`` ("0.01:8 0.05:40": axial strain and load steps; the first is the
demo, 1.25e-3 per step), ``REPEATS`` (3) times each in fresh serial processes (one
numba thread), the two kinematics alternating. Per case and kinematics it records the
median wall time of the solve, Newton iterations, step cuts, farm trials (evaluations
of all Gauss points), the top reaction along the way and, where a run stopped (a step
that would not converge at the minimum step), the strain it reached and the message.
Per case: the ratio of the median wall times (finite / small) and the largest
difference of the top reaction at the same displacement, over the range both runs
reached, relative to the small run's largest reaction.

usage::

    python benchmarks/demo_kinematics.py   # writes benchmarks/results/demo_kinematics.json

environment: CASES ("0.01:8 0.05:40"), REPEATS (3).
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "demo_kinematics.json"
SCRATCH = C.WORK / "demo_kinematics"
HEIGHT = 0.08  # [m] the demo sample's height


def worker(args):
    import copy
    import time

    import h5py

    from hmm.coupling import SolverError
    from hmm.problem import validate_problem
    from hmm.run import DEMO, run_problem

    kinematics, strain, steps = args[0], float(args[1]), int(args[2])
    raw = copy.deepcopy(DEMO)
    top = next(d for d in raw["dirichlet"] if d["boundary"] == "top")
    top["value"] = -strain * HEIGHT
    raw["load"] = {"steps": steps}
    raw["solver"]["kinematics"] = kinematics
    out_dir = SCRATCH / f"{kinematics}_{strain}"
    raw["output"] = {"dir": str(out_dir)}
    problem = validate_problem(raw, source="<demo_kinematics>")
    t0 = time.perf_counter()
    stopped = None
    try:
        s = run_problem(problem, out_dir, overwrite=True, progress=False)
    except SolverError as err:  # the converged part is on disk
        s, stopped = {}, str(err)
    wall = time.perf_counter() - t0
    with h5py.File(out_dir / "fields.h5", "r") as f:
        force = f["curve/force/top"][:, 1].tolist()
        disp = f["curve/displacement/top"][:, 1].tolist()
        iterations = int(f["curve/iterations"][()].sum())
    C.emit_result({"kinematics": kinematics, "strain": strain, "steps": steps,
                   "wall": wall, "solve_time": s.get("solve_time", wall),
                   "iterations": iterations, "cuts": s.get("cuts"),
                   "trials": s.get("trials"), "force_top": force,
                   "displacement_top": disp, "stopped": stopped,
                   "reached_strain": -disp[-1] / HEIGHT})


def main():
    import numpy as np

    cases = [(float(a), int(b)) for a, b in
             (c.split(":") for c in C.env_list("CASES", "0.01:8 0.05:40"))]
    repeats = C.env_int("REPEATS", 3)
    data = {"benchmark": "demo_kinematics", "date": C.now(), "machine": C.machine_info(),
            "versions": C.our_versions(), "repeats": repeats, "cases": []}
    for strain, steps in cases:
        runs = {"small": [], "finite": []}
        for _ in range(repeats):
            for kin in ("small", "finite"):
                r = C.run_worker(__file__, [kin, strain, steps], threads=1, timeout=7200)
                if not r.get("ok"):  # a crash, not a stop: SolverError is a result
                    raise SystemExit(f"{kin} to {strain}: {r['error']}")
                runs[kin].append(r)
        case = {"axial_strain": strain, "steps": steps}
        for kin, rs in runs.items():
            case[kin] = {"solve_time_median": C.median(r["solve_time"] for r in rs),
                         "solve_times": [r["solve_time"] for r in rs],
                         **{k: rs[0][k] for k in ("iterations", "cuts", "trials",
                                                  "force_top", "displacement_top",
                                                  "stopped", "reached_strain")}}
        # the load factors of the converged steps differ once a run cuts its steps:
        # compare at the displacements both reached
        ds, fs = (-np.asarray(case["small"][k]) for k in ("displacement_top",
                                                           "force_top"))
        df, ff = (-np.asarray(case["finite"][k]) for k in ("displacement_top",
                                                            "force_top"))
        both = df <= ds[-1] + 1e-15
        diff = np.abs(ff[both] - np.interp(df[both], ds, fs))
        case["time_ratio_finite_small"] = C.ratio(case["finite"]["solve_time_median"],
                                                  case["small"]["solve_time_median"])
        case["max_rel_force_difference"] = float(np.max(diff) / np.max(np.abs(fs)))
        case["common_strain"] = float(min(ds[-1], df[-1]) / HEIGHT)
        data["cases"].append(case)
        stops = "".join(f"; {k} stopped at {100 * case[k]['reached_strain']:.2f} %"
                        for k in ("small", "finite") if case[k]["stopped"])
        print(f"axial strain {strain:.3f} in {steps} steps: small "
              f"{case['small']['solve_time_median']:.2f} s ({case['small']['iterations']} "
              f"iterations, {case['small']['cuts']} cuts), finite "
              f"{case['finite']['solve_time_median']:.2f} s "
              f"({case['finite']['iterations']}, {case['finite']['cuts']} cuts): ratio "
              f"{case['time_ratio_finite_small']:.3f}; top reaction differs by at most "
              f"{100 * case['max_rel_force_difference']:.2f} % of its peak up to "
              f"{100 * case['common_strain']:.2f} %{stops}", flush=True)
        C.write_json(OUT, data)
    data["loadavg_end"] = C.loadavg()
    C.write_json(OUT, data)
    print(f"wrote {C.display_path(OUT)}")


if __name__ == "__main__":
    C.entry(main, worker)
