"""The macro level, speed against accuracy: the RVE tangent and the adaptive switch.

The problem is ``hmm demo`` (:data:`hmm.run.DEMO`: a 4 x 8 cm sample, 2 x 4 bilinear
elements, 32 Gauss points with periodic RVEs of 60 disks consolidated to 100 kPa,
100 kPa on the right, the top shortened by 1 % in 8 load steps) with **rough
platens**: the bottom and the top are also held in x. In the demo every Gauss point
sees the same homogeneous strain, so an adaptive model switches all of them in the
same trial and its sweep has nothing to show; with the platens held, the sample
barrels, the strain concentrates at mid-height, away from the platens (the norm of
the final strain spans a factor of four over the points, ``strain_spread`` in the
JSON), and the points leave the elastic range over several load steps. The same
problem serves both panels, so the all-DEM run with the contact tangent is the
reference of both.

1. **Tangent.** The run with ``tangent = "contact"`` (eq 29, from the contact
   stiffnesses) and with ``"perturbation"`` (relaxed probes, one per strain
   component): Newton iterations, wall and CPU time per load step, farm trials, and
   the load-displacement curve (top reaction against top displacement, the curve of
   ``load_displacement.png``). Claim checked: the tangent changes the way to the
   answer, not the answer; the curves differ by less than the solver's tolerance
   allows to accumulate (about 1 % of the peak reaction).
2. **Adaptive.** ``model = "adaptive"`` (:class:`hmm.micro.Adaptive`), one criterion
   swept at a time (the other out of reach): per run, the share of the all-DEM run's
   DEM work saved (point-trials that ran the RVE, and DEM steps), the error of the
   curve (the largest reaction difference relative to the all-DEM run's peak
   reaction, and the difference at the end), and the CPU time as a ratio to the
   all-DEM run. What it shows: a point kept elastic answers with the contact tangent,
   an upper bound that here adds about 1.5 times the load the DEM adds over the
   first step, so every load step spent elastic costs tens of percent of the peak
   reaction; after the switch the RVE takes the strain it is owed and the curve comes
   back to within 1 %. Thresholds low enough for a small error switch every point in
   the first step or two and save nothing (points that switch inside a Newton loop
   even cost iterations), and a threshold that many points cross in the same step
   can stop the run: step cutting does not shrink the strain the RVEs are owed.

Every run is the load-step loop of :func:`hmm.run.run_problem` (the problem built by
:mod:`hmm.problem`, the same :class:`hmm.coupling.Solver`: same iterations and
reactions, bit for bit), without its output files, with the farm wrapped to count
what the points did; the trial of ``Solver.__init__`` is not counted. Times are the
load-step loop only (set-up and packing generation excluded), one numba thread, the
tangent runs the median of ``HMM_REPS`` interleaved repetitions. Cost ratios use CPU
time (``time.process_time``), which other jobs on a shared machine disturb less than
wall time; both are in the JSON. DEM steps are the deterministic measure of cost.

usage::

    python benchmarks/hmm_tangent_adaptive.py   # writes the JSON and the figure:
        # benchmarks/results/hmm_tangent_adaptive.json
        # docs/figures/hmm_tangent_adaptive.png
    python benchmarks/hmm_tangent_adaptive.py --quick     # 1 x 2 elements, 2 steps,
                                                          # 30 disks
    python benchmarks/hmm_tangent_adaptive.py --markdown  # the docs tables (JSON)
    python benchmarks/hmm_tangent_adaptive.py --figure    # redraw the figure (JSON)

environment: HMM_CELLS ("2 4"), HMM_STEPS (8), HMM_COUNT (60 disks per RVE),
HMM_REPS (3, runs of each tangent), HMM_SWEEP_REPS (1, runs of each adaptive case),
HMM_STRAINS ("1e-4 1e-3 1.5e-3 3e-3 6e-3 1.2e-2", the sweep of ``strain_threshold``)
and HMM_RATIOS ("0.3 0.5 0.6 0.7 1", the sweep of ``ratio_threshold``).
"""

import copy
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "hmm_tangent_adaptive.json"
FIGURE = C.REPO / "docs" / "figures" / "hmm_tangent_adaptive.png"
#: a threshold no point reaches in these runs (switches the other criterion off)
OUT_OF_REACH = 1e6


def problem(model="dem", tangent="contact", strain_threshold=None, ratio_threshold=None,
            cells=(2, 4), steps=8, count=60):
    """The demo problem with rough platens, validated."""
    from hmm.problem import validate_problem
    from hmm.run import DEMO

    p = copy.deepcopy(DEMO)
    p["mesh"]["cells"] = [int(c) for c in cells]
    p["load"]["steps"] = int(steps)
    p["dirichlet"] += [{"boundary": "bottom", "component": "x", "value": 0.0},
                       {"boundary": "top", "component": "x", "value": 0.0}]
    p["micro"].update(model=model, tangent=tangent, count=int(count))
    if model == "adaptive":
        p["micro"].update(strain_threshold=float(strain_threshold),
                          ratio_threshold=float(ratio_threshold))
    return validate_problem(p, source="<hmm_tangent_adaptive>")


class CountingFarm:
    """A farm that counts, per trial, the points that ran their RVE and its DEM steps.

    ``hmm.micro.DEMMicroModel.steps`` counts the steps of the strain increment and its
    relaxation, not those of perturbation probes (the RVE restores its step counter
    after each probe): with ``tangent = "perturbation"`` the DEM steps are a lower
    bound, and CPU and wall time are the measures of cost.
    """

    def __init__(self, farm):
        self.farm = farm
        self.reset()

    def reset(self):
        self.trials = self.dem_calls = self.dem_steps = 0

    def trial(self, deps):
        out = self.farm.trial(deps)
        steps = self.farm.steps
        self.trials += 1
        self.dem_calls += int((steps > 0).sum())
        self.dem_steps += int(steps.sum())
        return out

    def counts(self):
        return self.trials, self.dem_calls, self.dem_steps

    def __getattr__(self, name):
        return getattr(self.farm, name)


def solve(prob):
    """Run ``prob`` load step by load step; the curve and the cost of every step."""
    import numpy as np

    from hmm.coupling import Solver, SolverError, SolverSettings
    from hmm.problem import build_farm, build_loads, build_macro

    macro = build_macro(prob)
    supports, f_const, f_ramp, loads = build_loads(prob, macro)
    farm = CountingFarm(build_farm(prob, macro))
    st = prob["solver"]
    solver = Solver(macro, farm, supports, f_const, f_ramp,
                    SolverSettings.from_section(st), loads)
    farm.reset()
    top = macro.dofs("top", 1)
    n = prob["load"]["steps"]

    def state():
        return {"load_factor": solver.t, "displacement": float(solver.u[top].mean()),
                "reaction": float(solver.reactions()["top"][1]),
                "dem_points": int(np.sum(farm.measures()["ran_dem"] > 0))}

    rows = [state() | dict.fromkeys(COUNTS, 0)]
    error, failed = None, None
    for k in range(1, n + 1):
        c0, cuts0 = farm.counts(), solver.cuts
        t0, p0 = time.perf_counter(), time.process_time()
        try:
            its = solver.advance(k / n - solver.t)
        except SolverError as err:
            error = str(err)
        wall, cpu = time.perf_counter() - t0, time.process_time() - p0
        c1 = farm.counts()
        cost = {"wall": wall, "cpu": cpu, "trials": c1[0] - c0[0],
                "dem_calls": c1[1] - c0[1], "dem_steps": c1[2] - c0[2],
                "cuts": solver.cuts - cuts0}
        if error is not None:  # what the failed step cost before the solver gave up
            failed = cost | {"step": k}
            break
        rows.append(state() | cost | {"iterations": its})
    eps = macro.strain(solver.u)
    norm = np.sqrt(np.einsum("gij,gij->g", eps, eps))  # Frobenius norm per point
    return {"steps": rows, "error": error, "failed_step": failed,
            "stopped_at": solver.t if error else None, "gauss_points": macro.n_gp,
            "final_strain_norm": norm.tolist()}


#: the per-step costs of a :func:`solve` result
COUNTS = ("iterations", "wall", "cpu", "trials", "dem_calls", "dem_steps", "cuts")


def totals(run):
    """Sums over the load steps of a :func:`solve` result."""
    return {k: sum(r[k] for r in run["steps"][1:]) for k in COUNTS}


def merge(runs):
    """Repetitions of one problem: the first one's result, with the median wall and
    CPU time of every step and the totals of each repetition."""
    out = runs[0]
    for j, row in enumerate(out["steps"][1:], start=1):
        for key in ("wall", "cpu"):
            row[key] = C.median([r["steps"][j][key] for r in runs])
    out["wall_runs"] = [totals(r)["wall"] for r in runs]
    out["cpu_runs"] = [totals(r)["cpu"] for r in runs]
    curve = [x["reaction"] for x in out["steps"]]
    out["repeatable"] = all([x["reaction"] for x in r["steps"]] == curve for r in runs)
    return out


def deviation(run, ref):
    """Reaction differences over the steps both runs reached: the largest one and the
    one at the end (None if ``run`` stopped early), relative to the peak reaction of
    ``ref`` (``*_peak``) and to the peak of the load ``ref`` adds to its start
    (``*_added``)."""
    r = [x["reaction"] for x in run["steps"]]
    q = [x["reaction"] for x in ref["steps"]]
    diff = [abs(a - b) for a, b in zip(r, q, strict=False)]
    peak = max(abs(x) for x in q)
    added = max(abs(x - q[0]) for x in q)
    end = diff[-1] if len(r) == len(q) else None
    return {"max_peak": max(diff) / peak, "max_added": max(diff) / added,
            "end_peak": None if end is None else end / peak,
            "end_added": None if end is None else end / added,
            "peak_reaction": peak, "peak_added_load": added}


def first_switch(run):
    """How many points began to run the DEM at each load step (``{step: count}``)."""
    pts = [r["dem_points"] for r in run["steps"]]
    return {str(k): pts[k] - pts[k - 1] for k in range(1, len(pts))
            if pts[k] > pts[k - 1]}


def summarise(run, ref):
    """The JSON record of a merged run, its costs as ratios to ``ref``'s."""
    t, tr = totals(run), totals(ref)
    n = len(run["steps"]) - 1
    wall, cpu = C.median(run["wall_runs"]), C.median(run["cpu_runs"])
    return {"completed": run["error"] is None, "error": run["error"],
            "stopped_at_load_factor": run["stopped_at"],
            "failed_step": run["failed_step"], "load_steps": n,
            "iterations": [r["iterations"] for r in run["steps"][1:]],
            "iterations_per_step": t["iterations"] / n if n else None,
            "wall": wall, "wall_runs": run["wall_runs"], "cpu": cpu,
            "cpu_runs": run["cpu_runs"],
            "wall_per_step": wall / n if n else None,
            "cpu_per_step": cpu / n if n else None,
            "wall_ratio": C.ratio(wall, C.median(ref["wall_runs"])),
            "cpu_ratio": C.ratio(cpu, C.median(ref["cpu_runs"])),
            "trials": t["trials"], "point_trials": t["trials"] * run["gauss_points"],
            "dem_calls": t["dem_calls"], "dem_steps": t["dem_steps"], "cuts": t["cuts"],
            "calls_saved": 1.0 - t["dem_calls"] / tr["dem_calls"],
            "steps_saved": 1.0 - t["dem_steps"] / tr["dem_steps"],
            "deviation": deviation(run, ref),
            "dem_points": [r["dem_points"] for r in run["steps"]],
            "switched_at_step": first_switch(run), "repeatable": run["repeatable"],
            "curve": {"load_factor": [r["load_factor"] for r in run["steps"]],
                      "displacement": [r["displacement"] for r in run["steps"]],
                      "reaction": [r["reaction"] for r in run["steps"]]}}


def main(quick=False):
    import numpy as np

    if quick:
        size = {"cells": (1, 2), "steps": 2, "count": 30}
        strains, ratios = ["2e-3"], ["1.0"]
    else:
        size = {"cells": tuple(int(c) for c in C.env_list("HMM_CELLS", "2 4")),
                "steps": C.env_int("HMM_STEPS", 8), "count": C.env_int("HMM_COUNT", 60)}
        strains = C.env_list("HMM_STRAINS", "1e-4 1e-3 1.5e-3 3e-3 6e-3 1.2e-2")
        ratios = C.env_list("HMM_RATIOS", "0.3 0.5 0.6 0.7 1")
    reps = C.env_int("HMM_REPS", 1 if quick else 3)
    sweep_reps = C.env_int("HMM_SWEEP_REPS", 1)
    for model in ("dem", "adaptive"):  # compile (or load) the kernels before timing
        solve(problem(model, "perturbation", 1e-3, OUT_OF_REACH, cells=(1, 1), steps=1,
                      count=30))
    cases = {"dem_contact": (problem("dem", "contact", **size), reps),
             "dem_perturbation": (problem("dem", "perturbation", **size), reps)}
    sweep = [("strain", float(x), OUT_OF_REACH) for x in strains] + [
        ("ratio", OUT_OF_REACH, float(x)) for x in ratios]
    for crit, st, rt in sweep:
        name = f"adaptive_{crit}_{st if crit == 'strain' else rt:g}"
        cases[name] = (problem("adaptive", "contact", st, rt, **size), sweep_reps)
    raw = {name: [] for name in cases}
    for rnd in range(max(reps, sweep_reps)):  # repetitions interleaved
        for name, (prob, n) in cases.items():
            if rnd < n:
                t0 = time.perf_counter()
                raw[name].append(solve(prob))
                print(f"round {rnd + 1}, {name}: {time.perf_counter() - t0:.1f} s",
                      flush=True)
    runs = {name: merge(r) for name, r in raw.items()}
    ref = runs["dem_contact"]
    res = {name: summarise(run, ref) for name, run in runs.items()}
    for (crit, st, rt), name in zip(sweep, list(res)[2:], strict=True):
        res[name].update(criterion=crit, strain_threshold=st, ratio_threshold=rt)
    final = np.array(ref["final_strain_norm"])
    data = {"benchmark": "hmm_tangent_adaptive", "date": C.now(),
            "machine": C.machine_info(), "versions": C.our_versions(),
            "config": {"cells": list(size["cells"]), "load_steps": size["steps"],
                       "disks": size["count"], "gauss_points": ref["gauss_points"],
                       "reps_tangent": reps, "reps_sweep": sweep_reps, "quick": quick,
                       "axial_strain": 0.01, "confinement_pa": 1e5,
                       "platens": "rough (x held at bottom and top)", "threads": 1},
            "strain_spread": {"min": float(final.min()), "max": float(final.max()),
                              "median": float(np.median(final))},
            "tangent": {k: res[k] for k in ("dem_contact", "dem_perturbation")},
            "adaptive": {k: v for k, v in res.items() if k.startswith("adaptive")}}
    C.write_json(OUT, data)
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    visualize(data).savefig(FIGURE, dpi=120)
    print(markdown(data))


def visualize(data):
    """Two panels: the load-displacement curves of the two tangents (Newton
    iterations per step inset), and the adaptive sweep's reaction error against the
    DEM work it saved."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12.0, 4.8))
    tan = data["tangent"]
    styles = {"dem_contact": ("contact (eq 29)", "C0", "o-"),
              "dem_perturbation": ("perturbation", "C3", "s--")}
    for name, (label, color, fmt) in styles.items():
        r = tan[name]
        x = [-1e3 * u for u in r["curve"]["displacement"]]
        y = [-1e-3 * f for f in r["curve"]["reaction"]]
        ax.plot(x, y, fmt, color=color, ms=4, label=(
            f"{label}: {r['iterations_per_step']:.2f} Newton it./step, "
            f"{r['wall_per_step']:.2g} s/step"))
    dev = tan["dem_perturbation"]["deviation"]["max_peak"]
    ax.set_xlabel("top displacement (shortening) [mm]")
    ax.set_ylabel("top reaction [kN/m]")
    ax.set_title(f"(a) RVE tangent; curves differ by at most {100 * dev:.1f} % "
                 f"of the peak", fontsize=10)
    lo, hi = ax.get_ylim()
    ax.set_ylim(lo, hi + 0.2 * (hi - lo))  # room above the curves for the legend
    ax.legend(loc="upper left", fontsize=8)
    ins = ax.inset_axes([0.6, 0.14, 0.36, 0.28])
    for k, (name, (_, color, _)) in enumerate(styles.items()):
        its = tan[name]["iterations"]
        ins.bar([i + 1 + 0.4 * (k - 0.5) for i in range(len(its))], its, width=0.4,
                color=color)
    ins.xaxis.set_major_locator(MaxNLocator(integer=True))
    ins.yaxis.set_major_locator(MaxNLocator(nbins=4, integer=True))
    ins.set_xlabel("load step [-]", fontsize=7)
    ins.set_ylabel("Newton it. [-]", fontsize=7)
    ins.tick_params(labelsize=7)
    _adaptive_panel(bx, data["adaptive"])
    fig.tight_layout()
    return fig


def _adaptive_panel(bx, ada):
    """Panel (b): each criterion's runs as a curve of error against DEM steps saved,
    one label per distinct point (thresholds that land on the same point share it:
    strain labels left of the points, ratio labels right of them unless the point is
    the leftmost), every point inside the axes and the legend below them (with the
    runs that stopped)."""
    import math

    import numpy as np

    stopped = []
    xs = [0.0] + [100 * r["steps_saved"] for r in ada.values() if r["completed"]]
    for crit, color, label, side in (
            ("strain", "C2", "strain_threshold (ratio off)", -1),
            ("ratio", "C1", "ratio_threshold (strain off)", 1)):
        rows = sorted((r for r in ada.values() if r.get("criterion") == crit),
                      key=threshold)
        stopped += [r for r in rows if not r["completed"]]
        rows = [r for r in rows if r["completed"]]
        if not rows:
            continue
        x = [100 * r["steps_saved"] for r in rows]
        y = [100 * r["deviation"]["max_peak"] for r in rows]
        bx.plot(x, y, "o-", color=color, label=f"{label}: largest error")
        bx.plot(x, [100 * r["deviation"]["end_peak"] for r in rows], "o", color=color,
                mfc="none", label="the same runs: error at the end")
        points = {}
        for r, xi, yi in zip(rows, x, y, strict=True):
            points.setdefault((round(xi, 1), round(yi, 2)), []).append(f"{threshold(r):g}")
        for (xi, yi), names in points.items():
            at = -1 if xi <= min(xs) else side
            bx.annotate(", ".join(names), (xi, yi), fontsize=7, color=color,
                        textcoords="offset points", xytext=(7 * at, 0), va="center",
                        ha="left" if at > 0 else "right")
    for r in stopped:  # named in the legend, which has no point of theirs
        bx.plot([], [], " ", label=f"{r['criterion']} threshold {threshold(r):g}: Newton "
                f"failed at load factor {r['stopped_at_load_factor']:.2f} (points switching)")
    # every point inside: room on both sides for the labels, 0 % error above the floor
    lo, hi = min(xs), max(max(xs), 100.0)
    pad = 0.12 * (hi - lo)
    bx.set_xlim(lo - pad, hi + pad)
    bx.set_yscale("symlog", linthresh=0.1)
    top = max((np.max(line.get_ydata()) for line in bx.lines if len(line.get_ydata())),
              default=100.0)
    bx.set_ylim(-0.03, 10 ** (math.log10(max(top, 1.0)) + 0.5))
    bx.set_xlabel("DEM steps saved against the all-DEM run [%]\n"
                  "(negative: more DEM steps than the all-DEM run)")
    bx.set_ylabel("top reaction error [% of the peak reaction]")
    bx.set_title("(b) Adaptive: error against DEM work saved (labels: thresholds)",
                 fontsize=10)
    bx.grid(alpha=0.3)
    bx.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.24), ncol=2)


def threshold(r):
    """The swept threshold of an adaptive record."""
    return r["strain_threshold"] if r["criterion"] == "strain" else r["ratio_threshold"]


def _row(*cells):
    return "| " + " | ".join(str(c) for c in cells) + " |"


def markdown(data):
    """The docs section's tables from the JSON."""
    cfg, sp = data["config"], data["strain_spread"]
    c, p = data["tangent"]["dem_contact"], data["tangent"]["dem_perturbation"]
    pct = "{:.1f} %".format
    intro = (f"{cfg['cells'][0]} x {cfg['cells'][1]} elements, {cfg['gauss_points']} "
             f"Gauss points, {cfg['disks']} disks per RVE, {cfg['load_steps']} load "
             f"steps, rough platens; strain norm at the end "
             f"{1e3 * sp['min']:.1f}e-3 to {1e3 * sp['max']:.1f}e-3 over the points. "
             f"Tangent runs: median of {cfg['reps_tangent']}; sweep: "
             f"{cfg['reps_sweep']} run each.")
    lines = [
        intro, "",
        _row("tangent", "Newton it. per step", "wall (CPU) per step [s]",
             "CPU / contact", "farm trials", "point-trials that ran the DEM", "cuts"),
        "|---" * 7 + "|"]
    for name, r in (("contact (eq 29)", c), ("perturbation", p)):
        its = ", ".join(str(i) for i in r["iterations"])
        lines.append(_row(name, f"{r['iterations_per_step']:.2f} ({its})",
                          f"{r['wall_per_step']:.2f} ({r['cpu_per_step']:.2f})",
                          f"{r['cpu_ratio']:.2f}", r["trials"], r["dem_calls"],
                          r["cuts"]))
    d = p["deviation"]
    gap = (f"Largest difference of the two curves: {pct(100 * d['max_peak'])} of the "
           f"peak reaction ({pct(100 * d['max_added'])} of the peak load added to the "
           f"confinement); at the end {pct(100 * d['end_peak'])}.")
    lines += ["", gap, "",
              _row("criterion", "threshold", "DEM point-trials saved",
                   "DEM steps saved", "largest error", "error at the end",
                   "CPU / all-DEM",
                   "points on DEM at the end (switched at step: count)",
                   "Newton it. per step"),
              "|---" * 9 + "|"]
    for r in data["adaptive"].values():
        th = threshold(r)
        d = r["deviation"]
        if not r["completed"]:
            f = r["failed_step"]
            lines.append(_row(
                r["criterion"], f"{th:g}",
                f"stopped: step {f['step']} failed at load factor "
                f"{r['stopped_at_load_factor']:.3f} after {f['cuts']} cuts, "
                f"{f['dem_steps']:,} DEM steps", "",
                f"{pct(100 * d['max_peak'])} (before the stop)", "",
                f"{C.ratio(r['cpu'] + f['cpu'], c['cpu']):.2f} (to the stop)",
                f"{r['dem_points'][-1]} / {cfg['gauss_points']}", ""))
            continue
        sw = ", ".join(f"{k}: {v}" for k, v in r["switched_at_step"].items()) or "none"
        lines.append(_row(r["criterion"], f"{th:g}", f"{100 * r['calls_saved']:.0f} %",
                          f"{100 * r['steps_saved']:.0f} %", pct(100 * d["max_peak"]),
                          pct(100 * d["end_peak"]), f"{r['cpu_ratio']:.2f}",
                          f"{r['dem_points'][-1]} / {cfg['gauss_points']} ({sw})",
                          f"{r['iterations_per_step']:.2f}"))
    ref = c["deviation"]
    note = ("Errors: the largest difference of the top reaction from the all-DEM "
            "contact run over the load steps, relative to that run's peak reaction "
            f"({1e-3 * ref['peak_reaction']:.1f} kN/m; the load added to the "
            f"confinement peaks at {1e-3 * ref['peak_added_load']:.1f} kN/m).")
    lines += ["", note]
    return "\n".join(lines)


if __name__ == "__main__":
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    os.environ.setdefault("MPLBACKEND", "Agg")
    if "--markdown" in sys.argv or "--figure" in sys.argv:
        import json

        saved = json.loads(OUT.read_text())
        if "--figure" in sys.argv:
            visualize(saved).savefig(FIGURE, dpi=120)
        print(markdown(saved))
    else:
        main(quick="--quick" in sys.argv)
