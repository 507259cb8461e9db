"""The two limits of the saturated solver on one element of DEM RVEs.

One quad8 element (0.02 x 0.02 m, 3 x 3 Gauss points), every point a 100-disk RVE
consolidated to 100 kPa, shortened by 0.4 % in 4 steps under 100 kPa of lateral
pressure, small kinematics:

- **undrained**: permeability 1e-20 m^2 and no drainage. The element must follow
  ``hmm rve``'s constant-volume (undrained) test on the same packing: its deviator
  ``q = sqrt((s_xx - s_yy)^2 / 4 + s_xy^2)`` and the excess pore pressure its water
  carries, Gauss-point means, against the test's, at every step;
- **drained**: permeability 1e-8 m^2, drained top and right sides, the load applied
  over 1e4 s. It must follow the dry element (no fluid): its deviator against the dry
  one's, and no pore pressure.

Deviations are in units of the peak deviator of the run compared against (the bar:
5 %). The points' axial strains per step show that the element stays uniform (the
limits are those of a uniform element). ``tests/hmm/test_porous_problem.py`` runs
these functions and asserts the bars.

usage::

    python benchmarks/undrained_element.py   # about a minute;
                                             # writes benchmarks/results/undrained_element.json
"""

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

OUT = C.RESULTS / "undrained_element.json"
#: the packing and its undrained RVE test
RVE = {"packing": {"count": 100, "radius": [0.8e-3, 1.2e-3], "p0": 1e5, "seed": 4},
       "contact": {"law": "linear", "kn": 1e8, "kt": 5e7, "mu": 0.5},
       "test": {"kind": "undrained", "axial_strain": 0.004, "increment": 0.001}}
UNDRAINED = {"fluid": {"permeability": 1e-20}, "time": {"end": 1.0, "ramp": 1.0}}
DRAINED = {"fluid": {"permeability": 1e-8}, "time": {"end": 1e4, "ramp": 1e4},
           "drainage": [{"boundary": "top", "pressure": 0.0},
                        {"boundary": "right", "pressure": 0.0}]}


def rve_test(out):
    """Make the packing by ``hmm rve``'s undrained test in ``out``: (the packing file,
    the test's result with its curves ``q`` and ``excess_pore_pressure``)."""
    from hmm.experiment import run_experiment, validate_config

    cfg = validate_config(RVE, "undrained.toml")
    cfg["output"]["dir"] = str(out)
    return Path(out) / "packing.h5", run_experiment(cfg, progress=False)


def element(workdir, packing_file, name, **saturated):
    """Run the element of RVEs from ``packing_file`` in ``workdir/name`` (``saturated``:
    the problem's [fluid], [time] and [[drainage]], none for the dry element). Returns
    per step the mean deviator q [Pa], the mean pore pressure [Pa] (empty when dry) and
    the points' axial strains (steps, points)."""
    import copy

    import h5py
    import numpy as np

    from hmm.problem import validate_problem
    from hmm.run import run_problem

    data = {
        "mesh": {"dim": 2, "element": "quad8", "size": [0.02, 0.02], "cells": [1, 1],
                 "integration": "full"},
        "dirichlet": [{"boundary": "bottom", "component": "y"},
                      {"boundary": "left", "component": "x"},
                      {"boundary": "top", "component": "y", "value": -8e-5}],
        "pressure": [{"boundary": "right", "value": 1e5}],
        "load": {"steps": 4},
        "micro": {"model": "dem", "packing": str(packing_file)},
        "solver": {"tol_residual": 1e-2, "tol_displacement": 5e-3, "kinematics": "small"},
        **copy.deepcopy(saturated)}
    run_problem(validate_problem(data, source=f"{name}.toml"), Path(workdir) / name,
                progress=False)
    q, p, eyy = [], [], []
    with h5py.File(Path(workdir) / name / "fields.h5", "r") as f:
        for k in sorted(f["steps"]):
            step = f["steps"][k]
            s = -step["gauss/stress"][()]
            q.append(np.mean(np.sqrt(0.25 * (s[:, 0, 0] - s[:, 1, 1]) ** 2 + s[:, 0, 1] ** 2)))
            if "gauss/pore_pressure" in step:
                p.append(step["gauss/pore_pressure"][()].mean())
            eyy.append(-step["gauss/strain"][()][:, 1, 1])
    return np.array(q), np.array(p), np.array(eyy)


def limits(workdir):
    """Both limits, run in ``workdir``: a dict of the deviations (module docstring)."""
    import numpy as np

    packing_file, lab = rve_test(Path(workdir) / "rve")
    q_lab, p_lab = lab.curves["q"], lab.curves["excess_pore_pressure"]
    peak = float(q_lab.max())
    q_u, p_u, e_u = element(workdir, packing_file, "undrained", **UNDRAINED)
    q_dry, _, e_dry = element(workdir, packing_file, "dry")
    q_d, p_d, e_d = element(workdir, packing_file, "drained", **DRAINED)
    peak_dry = float(q_dry.max())
    return {
        "rve_test": {"q": q_lab.tolist(), "excess_pore_pressure": p_lab.tolist(),
                     "peak_q": peak},
        "undrained": {
            "q": q_u.tolist(), "pore_pressure": p_u.tolist(),
            "max_rel_q_deviation": float(np.abs(q_u - q_lab).max() / peak),
            "max_rel_pore_pressure_deviation": float(np.abs(p_u - p_lab).max() / peak),
            "axial_strain_min": e_u.min(axis=1).tolist(),
            "axial_strain_max": e_u.max(axis=1).tolist()},
        "drained": {
            "q": q_d.tolist(), "q_dry": q_dry.tolist(), "peak_q_dry": peak_dry,
            "max_rel_q_deviation": float(np.abs(q_d - q_dry).max() / peak_dry),
            "max_rel_pore_pressure": float(np.abs(p_d).max() / peak_dry),
            "axial_strain_min": e_d.min(axis=1).tolist(),
            "axial_strain_max": e_d.max(axis=1).tolist(),
            "dry_axial_strain_min": e_dry.min(axis=1).tolist(),
            "dry_axial_strain_max": e_dry.max(axis=1).tolist()},
    }


def main():
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as work:
        out = limits(work)
    u, d = out["undrained"], out["drained"]
    print(f"undrained: deviator within {100 * u['max_rel_q_deviation']:.2f} %, pore "
          f"pressure within {100 * u['max_rel_pore_pressure_deviation']:.2f} % of the "
          f"RVE test's peak deviator; points' axial strains at the end "
          f"{100 * u['axial_strain_min'][-1]:.3f} to {100 * u['axial_strain_max'][-1]:.3f} %")
    print(f"drained: deviator within {100 * d['max_rel_q_deviation']:.2f} % of the dry "
          f"element's peak, pore pressure at most {100 * d['max_rel_pore_pressure']:.2g} %")
    C.write_json(OUT, {"date": C.now(), "machine": C.machine_info(),
                       "revision": C.git_revision(), **out,
                       "wall_s": time.perf_counter() - start})


if __name__ == "__main__":
    C.entry(main, None)
