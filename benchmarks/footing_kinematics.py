"""The strip footing under small and finite kinematics: load, peak and wall time
against the number of load steps.

The problem is ``examples/strip_footing.toml`` (half of a 20 cm wide, 10 cm deep
granular layer, 10 x 10 quad8 elements, 400 Gauss points with 100-disk periodic RVEs,
100 kPa surcharge, a rigid smooth footing of width B = 4 cm), pushed to a settlement
of ``S_OVER_B`` x B (0.3: 12 mm). Each run solves it with ``[solver] kinematics`` set
to "small" or "finite" and ``[load] steps`` from ``STEPS``, under the venv's
``mpiexec`` on ``PROCS`` ranks (one numba thread each), and records:

* the load-settlement curve (force per metre of the half footing [N/m] against the
  settlement [m]);
* the peak load, the settlement at the peak, the load at the end;
* the wall time of the solve, Newton iterations, step cuts; where a run stopped (an
  inverted element or a step that would not converge at the minimum step size), its
  last converged settlement and the message.

From the finest pair of runs: the settlement where the two kinematics part, the first
settlement at which their loads differ by more than ``PART`` (5 %) of the small run's
load there. ``MESH`` ("10x10") and ``COUNT`` (100 disks) scale the problem down for a
quick look.

usage::

    python benchmarks/footing_kinematics.py   # writes benchmarks/results/footing_kinematics.json
                                              # and docs/figures/footing_kinematics.png

environment: STEPS ("12 24 48"), KINEMATICS ("small finite"), PROCS (2), S_OVER_B
(0.3), MESH ("10x10"), COUNT (100), PART (0.05).
"""

import json
import os
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "footing_kinematics.json"
FIGURE = C.REPO / "docs" / "figures" / "footing_kinematics.png"
SCRATCH = C.WORK / "footing_kinematics"
EXAMPLE = C.REPO / "examples" / "strip_footing.toml"
WIDTH = 0.04  # [m] B, the whole footing (the model holds half of it)


def problem(kinematics, steps, s_over_b, mesh, count, out_dir):
    """The example's problem, its settlement, steps, kinematics and size replaced."""
    from hmm.problem import load_problem

    prob = load_problem(EXAMPLE)
    prob["solver"]["kinematics"] = kinematics
    prob["load"]["steps"] = int(steps)
    footing = next(d for d in prob["dirichlet"] if d["boundary"] == "footing")
    footing["value"] = -s_over_b * WIDTH
    prob["mesh"]["cells"] = list(mesh)
    prob["micro"]["count"] = int(count)
    prob["output"]["dir"] = str(out_dir)
    return prob


def run_one(kinematics, steps, s_over_b, mesh, count):
    """One solve (every rank calls this); rank 0 returns the curve and the costs."""
    import h5py
    import numpy as np

    from hmm.coupling import SolverError
    from hmm.run import run_problem

    out_dir = SCRATCH / f"{kinematics}_{steps}"
    prob = problem(kinematics, steps, s_over_b, mesh, count, out_dir)
    t0 = time.perf_counter()
    stopped = None
    try:
        s = run_problem(prob, out_dir, overwrite=True, progress=False)
    except SolverError as err:
        s, stopped = {}, str(err)
    wall = time.perf_counter() - t0
    from hmm.farm import mpi_world

    _, comm = mpi_world()
    if comm is not None and comm.Get_rank() != 0:
        return None
    with h5py.File(out_dir / "fields.h5", "r") as f:
        force = -f["curve/force/footing"][:, 1]
        settle = -f["curve/displacement/footing"][:, 1]
        iters = f["curve/iterations"][()].astype(int).tolist()
    k = int(np.argmax(force))
    return {"kinematics": kinematics, "steps": int(steps), "wall": wall,
            "solve_time": s.get("solve_time", wall), "cuts": s.get("cuts"),
            "iterations": iters, "settlement": settle.tolist(), "force": force.tolist(),
            "peak_force": float(force[k]), "peak_settlement": float(settle[k]),
            "end_settlement": float(settle[-1]), "end_force": float(force[-1]),
            "stopped": stopped}


def launch(kinematics, steps, procs, s_over_b, mesh, count):
    cmd = C.worker_command(__file__, [kinematics, steps, s_over_b,
                                      f"{mesh[0]}x{mesh[1]}", count], procs)
    p = subprocess.run(cmd, env=C.worker_env(1), cwd=C.REPO, stdin=subprocess.DEVNULL,
                       capture_output=True, text=True, check=False, timeout=6 * 3600)
    for line in p.stdout.splitlines():
        if line.startswith("RESULT "):
            return dict(json.loads(line[len("RESULT "):]), ok=True)
    tail = (p.stderr or p.stdout or "").strip().splitlines()[-6:]
    return {"ok": False, "kinematics": kinematics, "steps": steps,
            "error": f"rc={p.returncode}: " + " | ".join(tail)}


def parting(small, finite, part):
    """The first settlement [m] at which the finite run's load differs from the small
    run's (interpolated at the same settlement) by more than ``part`` of it."""
    import numpy as np

    s, f = np.asarray(small["settlement"]), np.asarray(small["force"])
    for u, g in zip(finite["settlement"][1:], finite["force"][1:], strict=True):
        if u > s[-1]:
            break
        ref = float(np.interp(u, s, f))
        if abs(g - ref) > part * abs(ref):
            return float(u)
    return None


def visualize(data):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10.5, 4.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax, bx = fig.subplots(1, 2)
    styles = {"small": ("tab:blue", "o"), "finite": ("tab:red", "s")}
    finest = max(r["steps"] for r in data["runs"] if r.get("ok"))
    for r in data["runs"]:
        if not r.get("ok"):
            continue
        color, mark = styles[r["kinematics"]]
        if r["steps"] == finest:
            ax.plot(1e3 * r_(r["settlement"]), 1e-3 * r_(r["force"]), "-", color=color,
                    label=f"{r['kinematics']} ({r['steps']} steps)")
    part = data.get("parting_settlement")
    if part is not None:
        ax.axvline(1e3 * part, color="0.5", lw=0.8, ls=":")
        ax.annotate(f"part by {100 * data['part']:.0f} %\nat s/B = {part / WIDTH:.3f}",
                    (1e3 * part, 0.05), xycoords=("data", "axes fraction"),
                    fontsize=8, ha="left")
    ax.set(xlabel="settlement s [mm]", ylabel="footing load [kN/m] (half footing)",
           title=f"strip footing, B = {1e3 * WIDTH:.0f} mm, to s/B = {data['s_over_b']}")
    ax.legend(fontsize=8, loc="lower right")
    for kin, (color, mark) in styles.items():
        rows = sorted((r for r in data["runs"] if r.get("ok") and r["kinematics"] == kin),
                      key=lambda r: r["steps"])
        if not rows:
            continue
        n = [r["steps"] for r in rows]
        bx.plot(n, [1e-3 * r["peak_force"] for r in rows], mark + "-", color=color,
                label=f"{kin}: peak load")
    counts = sorted({r["steps"] for r in data["runs"] if r.get("ok")})
    bx.set(xlabel="load steps", ylabel="peak load [kN/m]", xscale="log",
           title="peak load and wall time against load steps")
    bx.set_xticks(counts, [str(n) for n in counts])
    bx.minorticks_off()
    tx = bx.twinx()
    for kin, (color, mark) in styles.items():
        rows = sorted((r for r in data["runs"] if r.get("ok") and r["kinematics"] == kin),
                      key=lambda r: r["steps"])
        if rows:
            tx.plot([r["steps"] for r in rows], [r["solve_time"] / 60.0 for r in rows],
                    mark + "--", color=color, mfc="none", label=f"{kin}: wall time")
    tx.set_ylabel(f"wall time [min] ({data['processes']} ranks)")
    h1, l1 = bx.get_legend_handles_labels()
    h2, l2 = tx.get_legend_handles_labels()
    bx.legend(h1 + h2, l1 + l2, fontsize=8, loc="upper left")
    return fig


def r_(x):
    import numpy as np

    return np.asarray(x)


def main():
    steps = [int(s) for s in C.env_list("STEPS", "12 24 48")]
    kinds = C.env_list("KINEMATICS", "small finite")
    procs = C.env_int("PROCS", 2)
    s_over_b = float(os.environ.get("S_OVER_B", "0.3"))
    mesh = tuple(int(v) for v in os.environ.get("MESH", "10x10").split("x"))
    count = C.env_int("COUNT", 100)
    part = float(os.environ.get("PART", "0.05"))
    data = {"benchmark": "footing_kinematics", "date": C.now(),
            "machine": C.machine_info(), "versions": C.our_versions(),
            "s_over_b": s_over_b, "width": WIDTH, "mesh": list(mesh), "rve_disks": count,
            "processes": procs, "part": part, "runs": []}
    t0 = time.perf_counter()
    for n in steps:
        for kin in kinds:
            load = C.loadavg()
            r = launch(kin, n, procs, s_over_b, mesh, count)
            r["loadavg"] = load
            data["runs"].append(r)
            if r.get("ok"):
                print(f"{kin:6s} {n:4d} steps: peak {r['peak_force'] / 1e3:.2f} kN/m at "
                      f"s = {1e3 * r['peak_settlement']:.2f} mm, end s = "
                      f"{1e3 * r['end_settlement']:.2f} mm, {r['solve_time']:.0f} s"
                      + (f", stopped: {r['stopped']}" if r["stopped"] else ""), flush=True)
            else:
                print(f"{kin} {n} steps failed: {r['error']}", flush=True)
            C.write_json(OUT, data)
    ok = {(r["kinematics"], r["steps"]): r for r in data["runs"] if r.get("ok")}
    common = [n for n in steps if ("small", n) in ok and ("finite", n) in ok]
    if common:
        n = max(common)
        data["parting_settlement"] = parting(ok[("small", n)], ok[("finite", n)], part)
        data["parting_s_over_b"] = (None if data["parting_settlement"] is None
                                    else data["parting_settlement"] / WIDTH)
        data["parting_steps"] = n
    data["wall_time"] = time.perf_counter() - t0
    data["loadavg_end"] = C.loadavg()
    C.write_json(OUT, data)
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    visualize(data).savefig(FIGURE, dpi=130)
    print(f"wrote {C.display_path(OUT)}, {C.display_path(FIGURE)}; the kinematics part "
          f"at s/B = {data.get('parting_s_over_b')}")


def worker(args):
    kin, steps, s_over_b, mesh, count = args
    r = run_one(kin, int(steps), float(s_over_b), tuple(int(v) for v in mesh.split("x")),
                int(count))
    if r is not None:
        C.emit_result(r)


if __name__ == "__main__":
    C.entry(main, worker)
