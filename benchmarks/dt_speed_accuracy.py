"""Time step: speed against accuracy, for choosing the engine's default ``DT_FACTOR``.

Accuracy: a head-on binary collision of two equal spheres (the benchmark's linear law:
kn = 1e6 N/m, kt = 2/7 kn, mu = 0.3, R = 0.025 m, 1000 kg/m^3) at dt = f x dt_crit, with
``dt_crit = sim.dt_crit`` the engine's critical step and f on a log grid from 0.01 to 1:

- contact duration (elastic law) against ``pi sqrt(m_eff / kn)``;
- energy (elastic law): ``|KE_after / KE_before - 1|``;
- restitution (viscoelastic law, e = 0.5) against ``exp(-pi zeta / sqrt(1 - zeta^2))``.

Entry and exit times are where the straight free-flight paths before and after the
contact cross zero gap, so the duration is not rounded to whole steps. A discrete
collision depends on where within a step the spheres first touch: each error is the
largest over 32 entry phases (0, 1/32, ..., 31/32 of a step); the phase-averaged
signed error (the bias left in a large assembly, where contacts start at random phases)
is reported too.

Speed: the benchmark's "static" scene (16,250 spheres, 1 thread, fresh process per
point) at f = 0.05, 0.1, 0.15, 0.25, 0.4: wall seconds per simulated second.

The recommended factor is the largest f for which every (worst-phase) error is below 1%
at f and at every smaller f tried; the same criterion on the phase-averaged errors is
reported alongside.

usage::

    python benchmarks/dt_speed_accuracy.py             # run: results/dt_speed_accuracy.{json,png}
    python benchmarks/dt_speed_accuracy.py --markdown  # print the docs table from the JSON

environment: DT_NSTEPS (300 timed steps), DT_NPRE (100 untimed), DT_REPS (1),
DT_COST_FACTORS ("0.05 0.1 0.15 0.25 0.4"), DEM_BENCH_SCENE (scene directory).
"""

import argparse
import json
import math
import os
import sys
import textwrap
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

os.environ.setdefault("NUMBA_NUM_THREADS", "1")  # the collisions: two bodies, one thread
os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
os.environ.setdefault("MPLBACKEND", "Agg")

OUT = C.RESULTS / "dt_speed_accuracy.json"
PNG = C.RESULTS / "dt_speed_accuracy.png"
TOL = 0.01
GRID = [0.01 * 100.0 ** (k / 14) for k in range(15)]  # 0.01 .. 1, 15 points, log spaced
PHASES = tuple(k / 32 for k in range(32))  # where within a step the spheres touch

# the benchmark scene's material (../shared/bench/dem_throughput/params.py)
R, RHO = 0.025, 1000.0
KN, KT, MU = 1.0e6, 2.0 / 7.0 * 1.0e6, 0.3
V0 = 1.0  # closing speed [m/s]: peak overlap v0 sqrt(m_eff/kn) = 0.18 mm = 0.7% of R


# --------------------------------------------------------------------------- accuracy
def collide(factor, restitution=1.0, phase=0.0):
    """One head-on collision at dt = factor x dt_crit.

    Returns the effective contact duration [s], the restitution (separation speed over
    approach speed) and KE_after / KE_before, plus the analytic references.
    """
    import dem
    import numpy as np

    law = dem.LinearSpring(kn=KN, kt=KT, mu=MU, restitution=restitution)
    model = dem.ContactModel(law)
    probe = dem.Bodies.spheres([[0.0, 0.0, 0.0], [3.0 * R, 0.0, 0.0]], radius=R, density=RHO)
    dt_crit = dem.critical_time_step(probe, model)[0]
    dt = factor * dt_crit
    gap0 = V0 * dt * (2.0 + phase)  # touch between steps 2 and 3, at ``phase`` of a step
    b = dem.Bodies.spheres([[0.0, 0.0, 0.0], [2.0 * R + gap0, 0.0, 0.0]], radius=R,
                           density=RHO, vel=[[0.5 * V0, 0.0, 0.0], [-0.5 * V0, 0.0, 0.0]])
    sim = dem.Simulation(b, model, dt=dt, allow_unstable_dt=True)  # factors up to 1.0
    ke0 = sum(dem.kinetic_energy(b))

    def gap():
        return float(np.linalg.norm(b.pos[1] - b.pos[0]) - 2.0 * R)

    g_prev, touched, step = gap(), False, 0
    t_in = None
    max_steps = int(50.0 / factor) + 100
    while step < max_steps:
        sim.run(1)
        step += 1
        g = gap()
        if g < 0.0 and not touched:
            touched = True
            t_in = (step - 1) * dt + g_prev / V0  # approach path crosses zero gap
        elif g >= 0.0 and touched:
            break
        g_prev = g
    else:
        raise RuntimeError(f"no separation within {max_steps} steps at dt/dt_crit = {factor}")
    v_out = float(b.vel[1, 0] - b.vel[0, 0])  # separation speed, constant from here on
    t_out = step * dt - g / v_out  # departure path crosses zero gap
    m_eff = 0.5 * float(b.mass[0])
    omega = math.sqrt(KN / m_eff)
    zeta = law.zeta
    return {"duration": t_out - t_in, "restitution": v_out / V0,
            "energy_ratio": sum(dem.kinetic_energy(b)) / ke0,
            "duration_ref": math.pi / (omega * math.sqrt(1.0 - zeta**2)),
            "restitution_ref": math.exp(-math.pi * zeta / math.sqrt(1.0 - zeta**2)),
            "dt": dt, "dt_crit": dt_crit, "steps_in_contact": (t_out - t_in) / dt}


def accuracy(factor):
    """Errors at one factor: worst over the entry phases, and the phase-averaged bias.

    ``err_*`` is the largest |relative error| over :data:`PHASES` (one collision's
    error); ``bias_*`` is |mean signed relative error| over the phases (what remains in a
    large assembly, where contacts start at random phases).
    """
    el = [collide(factor, 1.0, ph) for ph in PHASES]
    ve = [collide(factor, 0.5, ph) for ph in PHASES]
    signed = {"duration": [c["duration"] / c["duration_ref"] - 1.0 for c in el],
              "energy": [c["energy_ratio"] - 1.0 for c in el],
              "restitution": [c["restitution"] / c["restitution_ref"] - 1.0 for c in ve]}
    out = {"dt_factor": factor, "dt": el[0]["dt"], "dt_crit": el[0]["dt_crit"],
           "steps_per_contact": el[0]["duration_ref"] / el[0]["dt"]}
    for k, v in signed.items():
        out[f"err_{k}"] = max(abs(x) for x in v)
        out[f"bias_{k}"] = abs(sum(v) / len(v))
    out["err_max"] = max(out["err_duration"], out["err_energy"], out["err_restitution"])
    out["bias_max"] = max(out["bias_duration"], out["bias_energy"], out["bias_restitution"])
    out["phases"] = list(PHASES)
    out["signed_errors_per_phase"] = signed
    return out


def recommend(rows, key="err_max", tol=TOL):
    """Largest factor whose errors, and those of every smaller factor, are below ``tol``."""
    best = None
    for r in sorted(rows, key=lambda r: r["dt_factor"]):
        if r[key] >= tol:
            break
        best = r["dt_factor"]
    return best


# --------------------------------------------------------------------------- speed
def worker(factor):
    """Time the static scene at dt = factor x dt_crit in this (fresh) process."""
    import numba

    sdir, why = C.scene_dir()
    if sdir is None:
        raise SystemExit(why)
    nsteps, npre = C.env_int("DT_NSTEPS", 300), C.env_int("DT_NPRE", 100)
    sim, info = C.build_scene(sdir, "static", dt_factor=factor)
    sim.prime()
    sim.run(npre)
    w0, c0 = time.perf_counter(), time.process_time()
    sim.run(nsteps)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    C.emit_result({**info, **C.scene_state(sim), "dt_factor": factor, "nsteps": nsteps,
                   "npre": npre, "wall_s": wall, "cpu_s": cpu,
                   "threads": getattr(sim, "threads", numba.get_num_threads()),
                   "pps": info["N"] * nsteps / wall,
                   "wall_per_sim_s": wall / (nsteps * info["dt"]),
                   "cpu_per_sim_s": cpu / (nsteps * info["dt"])})


def cost(factors, reps):
    rows = []
    for f in factors:
        runs = []
        for _ in range(reps):
            load = C.loadavg()
            r = C.run_worker(Path(__file__), [repr(f)], threads=1)
            r["loadavg_before"] = load
            runs.append(r)
            if r.get("ok"):
                print(f"  dt/dt_crit = {f:<5g} {r['wall_per_sim_s']:8.1f} wall s "
                      f"({r['cpu_per_sim_s']:.1f} CPU s) per simulated s"
                      f"  ({r['pps']:.3g} particle-steps/s, "
                      f"CPU {100 * r['cpu_s'] / r['wall_s']:.0f}%,"
                      f" KE {r['ke']:.3g} J, Z {r['Z']:.3f})", flush=True)
            else:
                print(f"  dt/dt_crit = {f:<5g} FAILED: {r['error']}", flush=True)
        ok = [r for r in runs if r.get("ok")]
        rows.append({"dt_factor": f, "wall_per_sim_s": C.median(r["wall_per_sim_s"] for r in ok),
                     "cpu_per_sim_s": C.median(r["cpu_per_sim_s"] for r in ok),
                     "pps": C.median(r["pps"] for r in ok),
                     "dt": ok[0]["dt"] if ok else None, "runs": runs})
    return rows


# --------------------------------------------------------------------------- figure
def plot(data, path):
    import matplotlib

    matplotlib.use(os.environ.get("MPLBACKEND", "Agg"))
    import matplotlib.pyplot as plt

    grid = [r for r in data["accuracy"] if r["on_grid"]]
    f = [r["dt_factor"] for r in grid]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.3), constrained_layout=True)
    floor = 1e-12  # exact zeros cannot sit on a log axis
    for (key, label, mk), col in zip((("duration", "contact duration (elastic)", "o"),
                                      ("restitution", "restitution (e = 0.5)", "s"),
                                      ("energy", "energy (elastic)", "^")),
                                     ("tab:blue", "tab:orange", "tab:green"),
                                     strict=True):
        ax1.loglog(f, [max(r[f"err_{key}"], floor) for r in grid], marker=mk, color=col,
                   label=label + ", worst phase")
        ax1.loglog(f, [max(r[f"bias_{key}"], floor) for r in grid], ls=":", color=col,
                   lw=1.0, label=label + ", phase mean")
    ax1.axhline(data["tolerance"], color="k", lw=0.8, ls="--", label="1%")
    ax1.axvline(data["dt_factor_default"], color="tab:red", lw=0.8, ls=":",
                label=f"DT_FACTOR = {data['dt_factor_default']:g}")
    if data["recommended_dt_factor"]:
        ax1.axvline(data["recommended_dt_factor"], color="tab:purple", lw=0.8, ls="-.",
                    label=f"all < 1%, worst phase: {data['recommended_dt_factor']:.3g}")
    if data["recommended_dt_factor_phase_mean"]:
        ax1.axvline(data["recommended_dt_factor_phase_mean"], color="tab:brown", lw=0.8,
                    ls="-.", label="all < 1%, phase mean: "
                    f"{data['recommended_dt_factor_phase_mean']:.3g}")
    ax1.set_xlabel("dt / dt_crit")
    ax1.set_ylabel("relative error")
    ax1.set_title("Binary collision, linear spring(-dashpot)")
    ax1.set_ylim(1e-7, 1e1)
    ax1.legend(fontsize=7, loc="lower right")
    ax1.grid(True, which="both", alpha=0.3)

    cost_rows = [r for r in data["cost"] if r["wall_per_sim_s"]]
    if cost_rows:
        ax2.loglog([r["dt_factor"] for r in cost_rows], [r["wall_per_sim_s"] for r in cost_rows],
                   "o-", color="tab:blue", label="cost (16,250 spheres, 1 thread)")
        for r in cost_rows:
            ax2.annotate(f"{r['wall_per_sim_s']:.0f}", (r["dt_factor"], r["wall_per_sim_s"]),
                         textcoords="offset points", xytext=(4, 4), fontsize=8)
    else:
        why = textwrap.fill(data.get("cost_skipped", ""), 45)
        ax2.text(0.5, 0.5, "cost not measured:\n" + why,
                 ha="center", va="center", transform=ax2.transAxes, fontsize=9)
        ax2.set_xscale("log")
        ax2.set_yscale("log")
    ax2.set_xlabel("dt / dt_crit")
    ax2.set_ylabel("wall s per simulated s", color="tab:blue")
    ax2.set_title("Cost (benchmark scene) and largest error")
    ax2.grid(True, which="both", alpha=0.3)
    tw = ax2.twinx()
    acc = sorted(data["accuracy"], key=lambda r: r["dt_factor"])
    tw.loglog([r["dt_factor"] for r in acc], [max(r["err_max"], floor) for r in acc],
              "s--", color="tab:orange", ms=3, label="largest error, worst phase")
    tw.loglog([r["dt_factor"] for r in acc], [max(r["bias_max"], floor) for r in acc],
              ":", color="tab:orange", label="largest error, phase mean")
    tw.axhline(data["tolerance"], color="k", lw=0.8, ls="--")
    tw.set_ylabel("largest relative error", color="tab:orange")
    lines = ax2.get_legend_handles_labels()[0] + tw.get_legend_handles_labels()[0]
    if lines:
        ax2.legend(lines, [ln.get_label() for ln in lines], fontsize=8, loc="upper center")
    fig.savefig(path, dpi=120)
    plt.close(fig)


# --------------------------------------------------------------------------- driver
def _g(x):
    return "none" if x is None else format(x, ".3g")



def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worker", metavar="FACTOR", type=float, help=argparse.SUPPRESS)
    ap.add_argument("--markdown", nargs="?", const=str(OUT), metavar="JSON",
                    help="print the results table of JSON (default results/dt_speed_accuracy.json)")
    args = ap.parse_args(argv)
    if args.worker is not None:
        worker(args.worker)
        return 0
    if args.markdown:
        print(C.dt_markdown(json.loads(Path(args.markdown).read_text())))
        return 0

    import dem

    cost_factors = [float(x) for x in C.env_list("DT_COST_FACTORS", "0.05 0.1 0.15 0.25 0.4")]
    reps = C.env_int("DT_REPS", 1)
    extra = sorted(set(cost_factors + [dem.DT_FACTOR]) - set(GRID))
    print(f"binary collisions at {len(GRID)} + {len(extra)} time steps ...", flush=True)
    rows = []
    for f in sorted(GRID + extra):
        r = accuracy(f)
        r["on_grid"] = f in GRID
        rows.append(r)
        print(f"  dt/dt_crit = {f:<7.4g} ({r['steps_per_contact']:6.1f} steps per contact)  "
              f"worst phase: duration {r['err_duration']:.2e}  restitution "
              f"{r['err_restitution']:.2e}  energy {r['err_energy']:.2e}   phase mean: "
              f"{r['bias_duration']:.1e} {r['bias_restitution']:.1e} {r['bias_energy']:.1e}",
              flush=True)
    rec = recommend(rows, "err_max")
    rec_bias = recommend(rows, "bias_max")
    per_error = {f"{kind}_{k}": recommend(rows, f"{kind}_{k}")
                 for kind in ("err", "bias") for k in ("duration", "restitution", "energy")}
    at_default = next(r for r in rows if r["dt_factor"] == dem.DT_FACTOR)
    supported = at_default["err_max"] < TOL and rec is not None and rec >= dem.DT_FACTOR
    supported_bias = (at_default["bias_max"] < TOL and rec_bias is not None
                      and rec_bias >= dem.DT_FACTOR)

    sdir, why = C.scene_dir()
    data = {"benchmark": "dt_speed_accuracy", "status": "ok", "date": C.now(),
            "tolerance": TOL, "recommended_dt_factor": rec,
            "recommended_dt_factor_phase_mean": rec_bias,
            "dt_factor_default": dem.DT_FACTOR, "default_supported": bool(supported),
            "default_supported_phase_mean": bool(supported_bias),
            "recommended_dt_factor_per_error": per_error,
            "errors_at_default": {k: at_default[k] for k in (
                "err_duration", "err_restitution", "err_energy",
                "bias_duration", "bias_restitution", "bias_energy")},
            "collision": {"R": R, "density": RHO, "kn": KN, "kt": KT, "mu": MU,
                          "closing_speed": V0, "restitution": 0.5, "phases": list(PHASES),
                          "head_on": True},
            "accuracy": rows, "cost": [], "skipped": [],
            "machine": C.machine_info(), "versions": {"ours": C.our_versions()}}
    if sdir is None:
        print(f"cost: skipped: {why}")
        data["skipped"].append({"what": "cost", "reason": why})
        data["cost_skipped"] = why
    else:
        nsteps, npre = C.env_int("DT_NSTEPS", 300), C.env_int("DT_NPRE", 100)
        print(f"cost on the static scene ({nsteps} timed steps after {npre}, 1 thread) ...",
              flush=True)
        data["scene_dir"] = C.display_path(sdir)
        data["cost_config"] = {"scene": "static", "nsteps": nsteps, "npre": npre,
                               "reps": reps, "threads": 1}
        data["cost"] = cost(cost_factors, reps)
    C.write_json(OUT, data)
    plot(data, PNG)
    print()
    print(C.dt_markdown(data))
    print()
    e = data["errors_at_default"]
    print(f"recommended default dt factor (every worst-phase error < {TOL:.0%}): "
          f"{'none on the grid' if rec is None else format(rec, '.3g')}; "
          f"(every phase-averaged error < {TOL:.0%}): "
          f"{'none on the grid' if rec_bias is None else format(rec_bias, '.3g')}")
    print(f"engine default DT_FACTOR = {dem.DT_FACTOR}: worst-phase errors there: duration "
          f"{e['err_duration']:.2e}, restitution {e['err_restitution']:.2e}, energy "
          f"{e['err_energy']:.2e}; phase-averaged: {e['bias_duration']:.2e}, "
          f"{e['bias_restitution']:.2e}, {e['bias_energy']:.2e}")
    print("largest factor below 1% per error (worst phase / phase mean): " + ", ".join(
        f"{k} {_g(per_error['err_' + k])} / {_g(per_error['bias_' + k])}"
        for k in ("duration", "restitution", "energy")))
    print(f"the chart {'supports' if supported else 'does NOT support'} DT_FACTOR = "
          f"{dem.DT_FACTOR} on worst-phase errors; it "
          f"{'supports' if supported_bias else 'does NOT support'} it on phase-averaged errors")
    print(f"wrote {C.display_path(OUT)} and {C.display_path(PNG)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
