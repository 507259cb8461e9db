"""Choosing an RVE: its size against the scatter of the answer, and the strain cap per
step against the stress error, each against the time it costs.

Two charts, the data a user needs to pick the smallest RVE that answers the question.

**Size.** For each RVE size (disks, 2D: ``SIZES``, default 100 ... 4,000) and each of
``SEEDS`` packings (seeds 0 ... SEEDS-1): a packing is generated (radii uniform in
0.8-1.2 mm, linear springs kn = 1e8 N/m, kt = 5e7 N/m, consolidated frictionless to
100 kPa, then friction 0.5) and run through the drained biaxial test of ``hmm rve``
(constant lateral stress 100 kPa, axial strain to ``AXIAL`` = 3 % in increments of
1e-3, each relaxed to an unbalanced-force ratio of 1e-3). Reported per size: the peak
friction angle over the seeds (mean, standard deviation, range) and the median wall
time of one increment (one Gauss-point-sized call under mixed control). The scatter
of the peak angle over seeds is the RVE's own sampling error: a Gauss point cannot
be more certain than it. A packing that cannot be made (its consolidation does not
relax within the step cap) is listed with its error in ``size_failed`` and left out of
the summary.

**Strain cap.** On the 400-disk packing (seed 1) at three states of a drained biaxial
path (axial strain 0, 0.5 %, 1 %), a Gauss-point call -- a strain increment of
``(+3e-4, -1e-3)`` (lateral, axial) under full strain control, relaxed -- is made with
the largest strain per time step ``max_step_strain`` from 1e-4 down to 2e-7 and the
relaxation tolerance ``tol`` 1e-3 and 1e-4. The error is ``|sigma - sigma_ref| /
|sigma_ref|`` (Frobenius), the reference the same call at 1e-7 and tol 1e-5; the
time is the call's wall time (median of ``REPS``). The same calls at caps 1e-5 and
1e-6 are repeated with the time step at 0.07 and 0.15 of the critical step (the RVE's
default is 0.3; triangles). It shows which knob sets the error: the loading rate per
unit of the packing's response time (cap over time step), not the relaxation
tolerance.

**3D** (``DIM=3``): the size chart alone, for spheres (250 ... 4,000 by default; the
contact law of ``examples/triaxial_3d.toml``, kn = 1e5 N/m, kt = 5e4 N/m) through the
drained triaxial test of ``hmm rve`` (lateral stresses 100 kPa), into
``results/rve_size_accuracy_3d.{json,png}``. Each size also reports the time of a
Gauss-point call as that example makes it (``call_time``): an axial strain increment
of 1e-3 from the consolidated packing, not relaxed, with the contact tangent (median
of five, the state restored before each).

usage::

    python benchmarks/rve_size_accuracy.py   # results/rve_size_accuracy.{json,png}
    DIM=3 python benchmarks/rve_size_accuracy.py   # results/rve_size_accuracy_3d.*

environment: DIM (2 or 3), SIZES ("100 200 400 1000 2000 4000"; 3D "250 500 1000 2000
4000"), SEEDS (5), AXIAL (0.03), CAPS ("1e-4 1e-5 3e-6 1e-6 5e-7 2e-7"), REPS (3), JOBS
(2: worker processes at once, one thread each), PART ("all", "size" or "cap"; one part
keeps the other's entries; 3D: "size").
"""

import json
import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

DIM = C.env_int("DIM", 2)
_SUFFIX = "" if DIM == 2 else "_3d"
OUT = C.RESULTS / f"rve_size_accuracy{_SUFFIX}.json"
FIGURE = C.RESULTS / f"rve_size_accuracy{_SUFFIX}.png"
#: what the RVE holds, for the labels
PARTICLES = "disks" if DIM == 2 else "spheres"

P0 = 1.0e5
RADIUS = (0.8e-3, 1.2e-3)
LAW = {"kn": 1e8, "kt": 5e7, "mu": 0.5} if DIM == 2 else {"kn": 1e5, "kt": 5e4, "mu": 0.5}
INCREMENT = 1e-3
CALL_STRAIN = (3e-4, -1e-3)  # lateral, axial: a dilating biaxial increment
CALL_STATES = (0.0, 0.005, 0.01)  # axial strains of the states the calls start from
TOLS = (1e-3, 1e-4)
REFERENCE = {"max_step_strain": 1e-7, "tol": 1e-5}
#: time steps compared (fractions of the critical step; the RVE's default is 0.3)
DT_FACTORS = (0.07, 0.15, 0.3)
DT_CAPS = (1e-5, 1e-6)


def _config(n, seed, axial):
    from hmm.experiment import validate_config

    return validate_config({
        "packing": {"dim": DIM, "count": n, "radius": list(RADIUS), "p0": P0,
                    "seed": seed, "consolidation_friction": 0.0},
        "contact": {"law": "linear", **LAW},
        "test": {"axial_strain": axial, "increment": INCREMENT}}, "rve_size.toml")


def size_run(n, seed, axial):
    """One packing through the drained biaxial test: peak angle and increment times."""
    from hmm.experiment import compress, make_packing

    cfg = _config(n, seed, axial)
    t0 = time.perf_counter()
    packing = make_packing(cfg)
    t_gen = time.perf_counter() - t0
    times = []
    last = [time.perf_counter()]

    def tick(k):
        now = time.perf_counter()
        if k > 0:
            times.append(now - last[0])
        last[0] = now

    call = _call_time(packing[0]) if DIM == 3 else None
    res = compress(cfg, on_increment=tick, packing=packing)
    s = res.summary
    return {"n": n, "seed": seed, "generation_time": t_gen, "call_time": call,
            "peak_friction_angle": s["peak_friction_angle"],
            "peak_axial_strain": s["peak_axial_strain"],
            "initial_void_ratio": s["initial_void_ratio"],
            "increment_time": C.median(times), "increment_times": times,
            "relax_steps": res.curves["relax_steps"][1:].tolist()}


def _call_time(rve, reps=5):
    """Median time [s] of the 3D example's Gauss-point call from ``rve``'s state: 1e-3
    of axial strain, not relaxed, stress and contact tangent; the state restored."""
    import numpy as np

    deps = np.zeros((DIM, DIM))
    deps[1, 1] = -INCREMENT
    return C.median(C.time_rve_calls(rve, rve.snapshot(), deps, reps, relax=False)[0])


def cap_run(reps):
    """Gauss-point calls at every cap and tolerance from three states of one packing."""
    import numpy as np

    from hmm.experiment import _curves, make_packing

    cfg = _config(400, 1, INCREMENT)
    rve, confining, _ = make_packing(cfg)
    rve.consolidate(confining)
    deps = np.diag(CALL_STRAIN)
    states = []
    done = 0.0
    for target in CALL_STATES:  # walk the drained path to each state, snapshot it
        if target > done:
            _curves(rve, confining, np.arange(done + INCREMENT, target + 1e-12, INCREMENT),
                    None)
            done = target
        states.append(rve.snapshot())
    default = (rve.max_step_strain, rve.tol)

    dt_default = rve.sim.dt

    def call(snap, cap, tol, dt=None):
        rve.restore(snap)
        rve.sim.dt = dt_default if dt is None else dt
        rve.max_step_strain, rve.tol = cap, tol
        s0 = rve.sim.step
        t0 = time.perf_counter()
        sig = rve.apply_strain(deps)
        rve.tangent()
        return sig, time.perf_counter() - t0, rve.sim.step - s0

    caps = [float(x) for x in C.env_list("CAPS", "1e-4 1e-5 3e-6 1e-6 5e-7 2e-7")]
    rows, dt_rows = [], []
    for k, snap in enumerate(states):
        ref, t_ref, steps_ref = call(snap, REFERENCE["max_step_strain"], REFERENCE["tol"])
        for tol in TOLS:
            for cap in caps:
                runs = [call(snap, cap, tol) for _ in range(reps)]
                sig = runs[0][0]
                if any(not np.array_equal(r[0], sig) for r in runs):
                    raise RuntimeError("repeated calls from one state differ")
                rows.append({"state": k, "axial_strain": CALL_STATES[k], "cap": cap,
                             "tol": tol, "time": C.median([r[1] for r in runs]),
                             "steps": runs[0][2],
                             "error": float(np.linalg.norm(sig - ref)
                                            / np.linalg.norm(ref)),
                             "stress": sig.tolist()})
        rows.append({"state": k, "axial_strain": CALL_STATES[k], "reference": True,
                     **REFERENCE, "time": t_ref, "steps": steps_ref,
                     "stress": ref.tolist()})
        for factor in DT_FACTORS:  # the time step: same calls, default tolerance
            for cap in DT_CAPS:
                sig, t, steps = call(snap, cap, default[1], factor * rve.sim.dt_crit)
                dt_rows.append({"state": k, "dt_factor": factor, "cap": cap, "time": t,
                                "steps": steps,
                                "error": float(np.linalg.norm(sig - ref)
                                               / np.linalg.norm(ref))})
    rve.max_step_strain, rve.tol = default
    rve.sim.dt = dt_default
    return {"rows": rows, "dt_rows": dt_rows,
            "dt_factor_default": dt_default / rve.sim.dt_crit}


def summarize_sizes(runs):
    import numpy as np

    out = []
    for n in sorted({r["n"] for r in runs}):
        mine = [r for r in runs if r["n"] == n]
        phi = np.array([r["peak_friction_angle"] for r in mine])
        out.append({"n": n, "seeds": len(mine), "seeds_used": [r["seed"] for r in mine],
                    "peak_friction_angle_mean": phi.mean(),
                    "peak_friction_angle_std": phi.std(ddof=1) if phi.size > 1 else 0.0,
                    "peak_friction_angle_range": [phi.min(), phi.max()],
                    "increment_time": C.median([r["increment_time"] for r in mine]),
                    "call_time": C.median([r["call_time"] for r in mine])
                    if mine[0].get("call_time") is not None else None,
                    "generation_time": C.median([r["generation_time"] for r in mine])})
    return out


def summarize_caps(rows):
    """Per (cap, tol): the largest error over the states and the median time."""
    out = []
    keys = sorted({(r["cap"], r["tol"]) for r in rows if not r.get("reference")})
    for cap, tol in keys:
        mine = [r for r in rows if r.get("cap") == cap and r.get("tol") == tol
                and not r.get("reference")]
        out.append({"cap": cap, "tol": tol, "max_error": max(r["error"] for r in mine),
                    "median_error": C.median([r["error"] for r in mine]),
                    "time": C.median([r["time"] for r in mine]),
                    "steps": C.median([r["steps"] for r in mine])})
    return out


def summarize_dt(rows):
    """Per (dt factor, cap): the largest error over the states, the median steps."""
    out = []
    for factor, cap in sorted({(r["dt_factor"], r["cap"]) for r in rows}):
        mine = [r for r in rows if r["dt_factor"] == factor and r["cap"] == cap]
        out.append({"dt_factor": factor, "cap": cap,
                    "max_error": max(r["error"] for r in mine),
                    "steps": C.median([r["steps"] for r in mine]),
                    "time": C.median([r["time"] for r in mine])})
    return out


def visualize(data):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import NullFormatter

    caps = data.get("cap_summary") or []
    fig = Figure(figsize=(13.0 if caps else 9.0, 3.8), layout="constrained")
    FigureCanvasAgg(fig)
    ax1, ax2, *ax3 = fig.subplots(1, 3 if caps else 2)
    sizes = data.get("size_summary") or []
    if sizes:
        n = [s["n"] for s in sizes]
        for r in data["size_runs"]:
            ax1.plot(r["n"], r["peak_friction_angle"], "o", color="0.7", ms=4)
        ax1.errorbar(n, [s["peak_friction_angle_mean"] for s in sizes],
                     yerr=[s["peak_friction_angle_std"] for s in sizes], fmt="k-s",
                     capsize=3, label="mean ± std over seeds")
        ax1.set(xscale="log", xlabel=f"{PARTICLES} in the RVE",
                ylabel="peak friction angle [deg]",
                title="size: scatter of the answer")
        ax1.legend(loc="upper right")
        ax2.loglog(n, [s["increment_time"] for s in sizes], "k-o",
                   label="relaxed 1e-3 increment, servo")
        if sizes[0].get("call_time") is not None:
            ax2.loglog(n, [s["call_time"] for s in sizes], "b-s",
                       label="Gauss-point call (unrelaxed 1e-3)")
            ax2.legend(loc="upper left", fontsize=8)
        for s in sizes:
            ax2.annotate(f"±{s['peak_friction_angle_std']:.2f}°",
                         (s["n"], s["increment_time"]), textcoords="offset points",
                         xytext=(4, -10), fontsize=8)
        ax2.set(xlabel=f"{PARTICLES} in the RVE", ylabel="time per 1e-3 increment [s]",
                title="size: cost (labels: std of peak angle)")
    for ax in (ax1, ax2):  # the sizes themselves as ticks (log minor labels overlap)
        if sizes:
            ax.set_xticks(n, [f"{x:,}" for x in n])
            ax.xaxis.set_minor_formatter(NullFormatter())
    if not caps:
        return fig
    ax3 = ax3[0]
    for tol, style in zip(TOLS, ("k-o", "r--s"), strict=True):
        mine = [c for c in caps if c["tol"] == tol]
        if not mine:
            continue
        ax3.loglog([c["time"] for c in mine], [c["max_error"] for c in mine], style,
                   label=f"tol = {tol:g}")
        for c in mine:
            ax3.annotate(f"{c['cap']:.0e}", (c["time"], c["max_error"]), fontsize=7,
                         textcoords="offset points", xytext=(3, 3))
    for c in data.get("dt_summary") or []:
        if c["dt_factor"] == data.get("dt_factor_default"):
            continue
        ax3.plot(c["time"], c["max_error"], "b^", ms=5)
        ax3.annotate(f"{c['cap']:.0e}, dt {c['dt_factor']:g}", (c["time"], c["max_error"]),
                     fontsize=6, color="b", textcoords="offset points", xytext=(3, -8))
    ax3.set(xlabel="time per Gauss-point call [s]",
            ylabel="stress error (max over 3 states)",
            title="400 disks: strain cap per step (labels)")
    ax3.legend(loc="upper right")
    return fig


def main():
    part = os.environ.get("PART", "all" if DIM == 2 else "size")
    if part not in (("all", "size", "cap") if DIM == 2 else ("size",)):
        raise SystemExit(f"PART must be all, size or cap (3D: size), got {part!r}")
    sizes = [int(x) for x in C.env_list(
        "SIZES", "100 200 400 1000 2000 4000" if DIM == 2 else "250 500 1000 2000 4000")]
    seeds = C.env_int("SEEDS", 5)
    axial = float(os.environ.get("AXIAL", "0.03"))
    reps, jobs = C.env_int("REPS", 3), C.env_int("JOBS", 2)
    data = json.loads(OUT.read_text()) if part != "all" and OUT.exists() else {}
    stamp = {"date": C.now(), "revision": C.git_revision(), "loadavg": C.loadavg(),
             "jobs": jobs}
    data.update({"benchmark": "rve_size_accuracy" + _SUFFIX, "dim": DIM, "date": stamp["date"],
                 "machine": C.machine_info(), "versions": C.our_versions(),
                 "revision": stamp["revision"]})
    data.setdefault("settings", {}).update(
        {"p0": P0, "radius": list(RADIUS), "law": LAW, "increment": INCREMENT,
         "call_strain": list(CALL_STRAIN), "call_states": list(CALL_STATES),
         "tols": list(TOLS), "reference": REFERENCE})
    if part in ("all", "cap"):
        res = C.run_worker(__file__, ["cap", reps], threads=1, timeout=7200)
        if not res.get("ok"):
            raise RuntimeError("strain-cap worker failed: " + res["error"])
        data["cap_rows"] = res["rows"]
        data["cap_summary"] = summarize_caps(res["rows"])
        data["dt_rows"] = res["dt_rows"]
        data["dt_summary"] = summarize_dt(res["dt_rows"])
        data["dt_factor_default"] = res["dt_factor_default"]
        data["measured_cap"] = stamp
        for c in data["cap_summary"]:
            print(f"cap {c['cap']:.0e} tol {c['tol']:.0e}: error {c['max_error']:.2e}, "
                  f"{1e3 * c['time']:.1f} ms ({c['steps']:.0f} steps)", flush=True)
        for c in data["dt_summary"]:
            print(f"dt {c['dt_factor']:.2f} dt_crit, cap {c['cap']:.0e}: error "
                  f"{c['max_error']:.2e}, {c['steps']:.0f} steps", flush=True)
    if part in ("all", "size"):
        data["settings"].update(sizes=sizes, seeds=seeds, axial_strain=axial)
        tasks = [(n, s) for n in sorted(sizes, reverse=True) for s in range(seeds)]

        def one(task):
            n, s = task
            r = C.run_worker(__file__, ["size", n, s, axial], threads=1, timeout=14400)
            call = f", call {1e3 * r['call_time']:.1f} ms" if r.get("call_time") else ""
            print(f"size {n} seed {s}: " + (f"peak {r['peak_friction_angle']:.2f} deg, "
                  f"{r['increment_time']:.3f} s per increment{call}" if r.get("ok")
                  else r["error"]), flush=True)
            return r

        with ThreadPoolExecutor(max_workers=jobs) as pool:
            runs = list(pool.map(one, tasks))
        # a packing that cannot be made (its consolidation did not relax within the
        # step cap) is a result too: kept with its error, left out of the summary
        failed = [{"n": n, "seed": s, "error": r["error"]}
                  for (n, s), r in zip(tasks, runs, strict=True) if not r.get("ok")]
        runs = [r for r in runs if r.get("ok")]
        if not runs:
            raise RuntimeError("every size run failed: " + failed[0]["error"])
        data["size_runs"] = sorted(runs, key=lambda r: (r["n"], r["seed"]))
        data["size_failed"] = failed
        data["size_summary"] = summarize_sizes(runs)
        data["measured_size"] = stamp
    C.write_json(OUT, data)
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    visualize(data).savefig(FIGURE, dpi=120)
    for f in data.get("size_failed") or []:
        print(f"{f['n']:5d} {PARTICLES}, seed {f['seed']}: no packing: "
              f"{f['error'].split(' | ')[-1]}")
    for s in data.get("size_summary") or []:
        call = f", call {1e3 * s['call_time']:.1f} ms" if s.get("call_time") else ""
        print(f"{s['n']:5d} {PARTICLES}: peak phi {s['peak_friction_angle_mean']:.2f} ± "
              f"{s['peak_friction_angle_std']:.2f} deg, {s['increment_time']:.3f} s per "
              f"increment{call}")


def worker(args):
    if args[0] == "size":
        C.emit_result(size_run(int(args[1]), int(args[2]), float(args[3])))
    elif args[0] == "cap":
        C.emit_result(cap_run(int(args[1])))


if __name__ == "__main__":
    C.entry(main, worker)
