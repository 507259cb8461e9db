"""The undrained biaxial test of ``examples/biaxial_undrained.toml`` on a dense and a
loose packing: effective stress paths and excess pore pressures.

The example is YADE FEMxDEM's ``undrain.py`` in this project's terms: a sealed 5 x 10
cm plane-strain sample, 100 kPa of pore pressure at the start, 200 kPa of total
confinement, every Gauss point a DEM RVE consolidated to 100 kPa of effective stress,
shortened by 5 %. Two packings of the same disks: consolidated frictionless (dense,
``[micro] consolidation_friction = 0``) and with friction 0.3 (loose). Undrained, a
dense packing first contracts a little, then dilates: its pore pressure rises, then
falls below its start (suction) while the effective stress grows; a loose one
contracts: its pore pressure rises until the effective stress, and with it the
deviator, collapse (static liquefaction).

Each packing runs under the venv's ``mpiexec`` on ``PROCS`` ranks (one numba thread
each). Per step: the Gauss-point means of the mean effective stress ``p' = -(s'_xx +
s'_yy) / 2``, the deviator ``q = s'_xx - s'_yy`` and the excess pore pressure ``p -
p_0``, and of the volumetric strain, which a sealed sample keeps at the water's
compression. ``CELLS`` ("2x4") and ``COUNT`` (the example's 100 disks) set the size:
the reference's is ``CELLS=8x16 COUNT=400``.

usage::

    python benchmarks/undrained_biaxial.py   # writes benchmarks/results/undrained_biaxial.json
                                             # and docs/figures/undrained_biaxial.png

environment: CELLS ("2x4"), COUNT (100), STEPS (100), PROCS (2), PACKINGS ("dense loose"),
LOOSE_FRICTION (0.3).
"""

import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "undrained_biaxial.json"
FIGURE = C.REPO / "docs" / "figures" / "undrained_biaxial.png"
SCRATCH = C.WORK / "undrained_biaxial"
EXAMPLE = C.REPO / "examples" / "biaxial_undrained.toml"
VENV_BIN = Path(sys.executable).parent
#: packing -> [micro] consolidation_friction (LOOSE_FRICTION: the loose one's)
PACKINGS = {"dense": 0.0, "loose": float(os.environ.get("LOOSE_FRICTION", "0.3"))}


def problem(packing, cells, count, steps, out_dir):
    """The example's problem with its packing, mesh, RVE size and steps replaced."""
    from hmm.problem import load_problem

    prob = load_problem(EXAMPLE)
    prob["micro"]["consolidation_friction"] = PACKINGS[packing]
    prob["micro"]["count"] = int(count)
    prob["mesh"]["cells"] = list(cells)
    prob["load"]["steps"] = int(steps)
    prob["output"]["dir"] = str(out_dir)
    return prob


def run_one(packing, cells, count, steps):
    """One run (every rank calls this); rank 0 returns the mean path per step."""
    import h5py
    import numpy as np

    from hmm.coupling import SolverError
    from hmm.run import run_problem

    out_dir = SCRATCH / packing
    prob = problem(packing, cells, count, steps, out_dir)
    stopped = None
    try:
        s = run_problem(prob, out_dir, overwrite=True, progress=False)
    except SolverError as err:  # a liquefied point: its packing came apart
        s, stopped = {}, str(err)
    if s is None:
        return None
    p0 = prob["fluid"]["initial_pressure"]
    shortening = abs(next(d["value"] for d in prob["dirichlet"] if d["boundary"] == "top"))
    path = {"axial_strain": [], "p_eff": [], "q": [], "excess_pore_pressure": [],
            "volumetric_strain": []}
    with h5py.File(out_dir / "fields.h5", "r") as f:
        w = f["gauss/weights"][()]
        w = w / w.sum()
        height = float(np.ptp(f["mesh/points"][()][:, 1]))
        for k in sorted(f["steps"]):
            g = f["steps"][k]
            sig, eps = g["gauss/stress"][()], g["gauss/strain"][()]
            path["axial_strain"].append(float(g.attrs["load_factor"]) * shortening / height)
            path["p_eff"].append(float(w @ -(sig[:, 0, 0] + sig[:, 1, 1]) / 2.0))
            path["q"].append(float(w @ (sig[:, 0, 0] - sig[:, 1, 1])))
            path["excess_pore_pressure"].append(float(w @ g["gauss/pore_pressure"][()])
                                                - p0)
            path["volumetric_strain"].append(float(w @ np.trace(eps, axis1=1, axis2=2)))
    return {"stopped": stopped, "steps": len(path["q"]) - 1,
            **{k: s.get(k) for k in ("cuts", "iterations", "solve_time", "total_time")},
            **path}


def visualize(data):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11.0, 3.8), layout="constrained")
    FigureCanvasAgg(fig)
    ax_s, ax_q, ax_u = fig.subplots(1, 3)
    for name, style in (("dense", "ko-"), ("loose", "rs--")):
        r = data["runs"].get(name)
        if r is None:
            continue
        ea = [100.0 * e for e in r["axial_strain"]]
        kpa = 1e-3
        ax_s.plot([kpa * x for x in r["p_eff"]], [kpa * x for x in r["q"]], style, ms=4,
                  mfc="none", label=name)
        ax_q.plot(ea, [kpa * x for x in r["q"]], style, ms=4, mfc="none", label=name)
        ax_u.plot(ea, [kpa * x for x in r["excess_pore_pressure"]], style, ms=4,
                  mfc="none", label=name)
    ax_s.set(xlabel="mean effective stress p' [kPa]", ylabel="deviator q [kPa]",
             title="effective stress path")
    ax_q.set(xlabel="axial strain [%]", ylabel="deviator q [kPa]", title="deviator")
    ax_u.set(xlabel="axial strain [%]", ylabel="excess pore pressure [kPa]",
             title="pore pressure (sealed sample)")
    ax_u.axhline(0.0, color="0.6", lw=0.8)
    for ax in (ax_s, ax_q, ax_u):
        ax.legend(fontsize=8)
    s = data["settings"]
    fig.suptitle(f"undrained biaxial, {s['cells'][0]} x {s['cells'][1]} quad8, "
                 f"{s['count']}-disk RVEs (Gauss-point means)", fontsize=10)
    return fig


def main():
    cells = [int(c) for c in C.env_list("CELLS", "2x4")[0].split("x")]
    count, steps, procs = C.env_int("COUNT", 100), C.env_int("STEPS", 100), \
        C.env_int("PROCS", 2)
    data = {"benchmark": OUT.stem, "date": C.now(), "machine": C.machine_info(),
            "versions": C.our_versions(),
            "settings": {"example": C.display_path(EXAMPLE), "cells": cells,
                         "count": count, "steps": steps, "processes": procs,
                         "consolidation_friction": PACKINGS},
            "runs": {}}
    t0 = time.perf_counter()
    for packing in C.env_list("PACKINGS", "dense loose"):
        cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", packing,
               "x".join(map(str, cells)), str(count), str(steps)]
        if procs > 1:
            cmd = [str(VENV_BIN / "mpiexec"), "-n", str(procs), sys.executable, "-m",
                   "mpi4py"] + cmd[1:]
        load = C.loadavg()
        r = C.run_result(cmd, C.worker_env(1), C.REPO, timeout=4 * 3600)
        if not r.get("ok"):
            raise RuntimeError(f"{packing} failed: {r['error']}")
        r.pop("ok")
        data["runs"][packing] = dict(r, loadavg=load)
        q = max(r["q"])
        if r["stopped"]:
            print(f"{packing} stopped after {r['steps']} steps: {r['stopped']}")
        print(f"{packing}: {r['steps']} steps, peak q "
              f"{q / 1e3:.1f} kPa, excess pore pressure "
              f"{max(r['excess_pore_pressure']) / 1e3:.1f} to "
              f"{r['excess_pore_pressure'][-1] / 1e3:.1f} kPa at the end", flush=True)
    data["wall_time"] = time.perf_counter() - t0
    C.write_json(OUT, data)
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    visualize(data).savefig(FIGURE, dpi=120)
    print(f"wrote {C.display_path(OUT)}, {C.display_path(FIGURE)}")


def worker(args):
    cells = [int(c) for c in args[1].split("x")]
    r = run_one(args[0], cells, int(args[2]), int(args[3]))
    if r is not None:
        C.emit_result(r)


if __name__ == "__main__":
    C.entry(main, worker)
