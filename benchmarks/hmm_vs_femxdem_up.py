"""The saturated multiscale solver against YADE's FEMxDEM (``msFEMup``) on the same
scaled undrained biaxial test.

FEMxDEM's ``msFEMup.MultiScale`` is Guo & Zhao's hydro-mechanical FEM x DEM: Escript's
quadratic displacements with linear (``ReducedSolution``) pore pressures, a YADE
periodic RVE at every Gauss point giving the effective stress, and the fixed-stress
split (a pressure solve, then a Newton on the displacements, repeated). Its example
``examples/FEMxDEM/undrain.py`` shears an 8 x 16 quad8 sample, sealed, at 200 kPa of
total confinement with a pore pressure of 100 kPa at the start, a fluid bulk
modulus of 2.2 GPa and Kozeny-Carman's permeability ``kappa = d^2 / (180 mu) n^3 /
(1 - n)^2`` (d = 1 mm, mu = 8.9e-4 Pa s). Both solve its scaled version here:

* the 5 x 10 cm plane-strain sample on 2 x 4 quad8 elements (32 Gauss points),
  2 x 2 Gauss points (Escript's ``Rectangle(order=2, integrationOrder=2)``);
* every Gauss point the 400-disk packing of ``benchmarks/hmm_vs_femxdem.py``
  consolidated to 100 kPa (effective) by each engine (its scene and ours, made by
  that benchmark's helpers);
* smooth platens, ``u_x = 0`` on the left side (symmetry), 200 kPa total pressure on
  the right, the top shortened by 1e-3 of the height per time step of 0.1 s, every
  boundary impermeable (FEMxDEM's example has no drained boundary);
* the fluid of the example: pore pressure 100 kPa at the start, ``K_f`` = 2.2 GPa,
  Biot's coefficient 1 and incompressible grains (FEMxDEM's storage is ``n / K_f``),
  Kozeny-Carman's permeability from the porosity ``n`` of the packing (ours:
  ``[fluid] permeability_law = "kozeny_carman"`` from the packing's porosity).

Ours is ``hmm.run.run_problem`` on a validated saturated problem (monolithic Newton,
small kinematics, the saturated default); the peer is a driver script written here
(:data:`DRIVER`, our own text) that builds the Escript domain and the conditions and
calls ``MultiScale.solve`` step by step. Ours runs three times: as it is (RVE calls
relaxed to an unbalanced-force ratio of 1e-3), with FEMxDEM's RVE call (its loading
steps, no relaxation), keys ending in ``_no_relaxation``, and as it is under finite
kinematics (updated Lagrangian, the mesh moving as FEMxDEM's does), keys ending in
``_finite``; ``kinematics_deviation`` compares our two kinematics.

Measured: wall time per time step (the solve, set-up excluded), per Gauss-point
call, Gauss-point evaluations per step, and after every step the mean effective
stress, pore pressure and volumetric strain over the Gauss points. A sealed sample
keeps its volume but for the water's compression, ``tr eps = -n (p - p_0) / K_f``:
each run's ``max_volume_error`` is the largest departure from it, the measure of
how well its coupled iterations converged. ``speedup`` = FEMxDEM's
wall per step / ours over the same steps (our default call; the peer may run fewer,
``PEER_STEPS``), ``speedup_no_relaxation`` the same with FEMxDEM's call. The bars
of the comparison are taken on the two engines running the same algorithm (ours
without relaxation): ``max_rel_pore_pressure_deviation`` = the largest difference
of the mean pore pressure over the run relative to the largest excess pore pressure
(ours, |p - p_0|: the part the loading makes; relative to the pore pressure itself,
``..._of_pressure``, it is smaller), and ``max_rel_stress_deviation`` = the largest
difference of the mean effective axial stress relative to its largest magnitude, as
``hmm_vs_femxdem.py`` defines it (the deviator, a stricter figure, in
``max_rel_deviator_deviation``). The same figures of our default run end in
``_default``.

Where the two set-ups differ:

* **Kinematics.** FEMxDEM moves its mesh (``setX``) after every step and sends the
  RVEs the displacement gradient on it; ours runs small kinematics by default, and
  finite kinematics in ``ours_finite``. At the 2 % of axial strain of this test the
  two kinematics differ by about the strain squared in the stress.
* **Coupling.** FEMxDEM splits (fixed stress, at most 10 outer iterations of at most
  50 Newton iterations, ``rtol`` = 1e-2 on the displacement and 1e-3 on the
  pressure); ours solves both fields in one Newton (``rtol`` = 1e-2 on the
  correction). The converged answers are the same equations'.
* **Storage.** FEMxDEM's ``n / K_f`` follows the packing's porosity from step to
  step; ours keeps the initial porosity (a relative change of the strain's order).

usage::

    python benchmarks/hmm_vs_femxdem_up.py   # writes benchmarks/results/hmm_vs_femxdem_up.json
                                             # and docs/figures/hmm_vs_femxdem_up.png

``python benchmarks/hmm_vs_femxdem_up.py --add ours_finite`` runs one of our variants
into the JSON alone, the others kept.

environment: STEPS (20), PEER_STEPS (3: FEMxDEM's steps take minutes each, see
docs/performance.md), PEER_TIMEOUT (seconds, 14400: past it the peer's finished
steps are compared), PROCS ("2"), YADE (the YADE executable). Without YADE or
Escript the peer is skipped, saying so on stdout and in the JSON, and our side still
runs.
"""

import json
import os
import sys
import time
from pathlib import Path

os.environ["DIM"] = "2"  # msFEMup is 2D: the 2D set-up of hmm_vs_femxdem.py
sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C
import hmm_vs_femxdem as HV

OUT = C.RESULTS / "hmm_vs_femxdem_up.json"
FIGURE = C.REPO / "docs" / "figures" / "hmm_vs_femxdem_up.png"
CELLS = (2, 4)
DT = 0.1  # [s] a time step, as FEMxDEM's example
STRAIN_STEP = HV.STRAIN_STEP  # axial strain per time step
PORE0 = 1e5  # [Pa] pore pressure at the start
CONFINING = HV.P0 + PORE0  # [Pa] total lateral pressure: 100 kPa effective
FLUID_BULK = 2.2e9  # [Pa]
VISCOSITY = 8.9e-4  # [Pa s]
GRAIN = 1e-3  # [m] Kozeny-Carman's grain size in FEMxDEM's example
KC = GRAIN ** 2 / (180.0 * VISCOSITY)  # [m^2/(Pa s)] its kappa / (n^3 / (1 - n)^2)
GLOBAL_ITER, SOLID_ITER = 10, 50  # FEMxDEM's iteration caps (its example's)
#: our runs: as it is, with FEMxDEM's RVE call, and as it is under finite kinematics
VARIANTS = {"ours": (True, "small"), "ours_no_relaxation": (False, "small"),
            "ours_finite": (True, "finite")}


# --------------------------------------------------------------------------- our side
def porosity(prep):
    """The 2D porosity of our consolidated packing, ``e / (1 + e)``."""
    e = prep["void_ratio"]
    return e / (1.0 + e)


def problem(steps, relax, n0, out_dir, kinematics="small"):
    """The validated undrained biaxial problem, the packing's porosity ``n0``."""
    from hmm.problem import validate_problem

    lx, ly = HV.SIZE
    end = steps * DT
    return validate_problem({
        "mesh": {"dim": 2, "element": "quad8", "integration": "reduced",
                 "size": [lx, ly], "cells": list(CELLS)},
        "dirichlet": [{"boundary": "bottom", "component": "y", "value": 0.0},
                      {"boundary": "left", "component": "x", "value": 0.0},
                      {"boundary": "top", "component": "y",
                       "value": -steps * STRAIN_STEP * ly}],
        "pressure": [{"boundary": "right", "value": CONFINING}],
        "load": {"steps": steps},
        "time": {"end": end, "ramp": end},
        "fluid": {"permeability": KC * VISCOSITY * n0 ** 3 / (1.0 - n0) ** 2,
                  "viscosity": VISCOSITY, "bulk_modulus": FLUID_BULK, "porosity": n0,
                  "initial_pressure": PORE0, "permeability_law": "kozeny_carman"},
        "micro": {"model": "dem", "packing": str(HV.PACKING), **HV.MICRO,
                  "relax": bool(relax)},
        "solver": dict(HV.SOLVER, kinematics=kinematics),
        "output": {"dir": str(out_dir)},
    }, source="hmm_vs_femxdem_up")


def prepare():
    """HV's packing, and its void ratio (a worker: numba)."""
    from dem import rve

    out = HV.prepare_ours()
    out["void_ratio"] = rve.RVE.load_file(HV.PACKING).response(tangent=False)["void_ratio"]
    return out


def ours(steps, procs, variant, n0):
    relax, kinematics = VARIANTS[variant]
    cmd = C.worker_command(__file__, ["ours", steps, "relax" if relax else "fixed",
                                      repr(n0), kinematics], procs)
    return C.run_result(cmd, C.worker_env(1), C.REPO)


# --------------------------------------------------------------------------- the peer
#: the msFEMup driver (run by Debian's python3 in HV.PEER_DIR, beside 0.yade.gz),
#: settings from the JSON file named by HVF_CONFIG
DRIVER = r'''
import json, os, time
import numpy as np

cfg = json.load(open(os.environ["HVF_CONFIG"]))
import esys.escript as es
from esys.finley import Rectangle
import msFEMup as ms  # Escript and simDEM (which imports YADE through yadeimport)
''' + HV.DRIVER_POOL + r'''lx, ly = cfg["size"]
nx, ny = cfg["cells"]
dom = Rectangle(l0=lx, l1=ly, n0=nx, n1=ny, order=2, integrationOrder=2)
ng = es.Function(dom).getX().getNumberOfDataPoints()
t0 = time.perf_counter()
prob = ms.MultiScale(domain=dom, pore0=cfg["pore0"], perm=cfg["perm"], kf=cfg["kf"],
                     dt=cfg["dt"], ng=ng, useMPI=False, np=cfg["processes"],
                     rtol=cfg["rtol"])
setup = time.perf_counter() - t0

calls, solids = [], [0]
dem_stage = prob.applyStrain_getStressTangentDEM
solve_solid = prob.solveSolid


def timed_stage(st=es.Data()):
    grad = np.array(st.toListOfTuples()).reshape(-1, 4)
    steps = [int(max(1e5 * np.max(np.abs(g)), 2)) for g in grad]  # as shear2D
    t = time.perf_counter()
    out = dem_stage(st=st)
    calls.append({"wall": time.perf_counter() - t, "steps": steps})
    return out


def counted_solid(*args, **kw):
    solids[0] += 1
    return solve_solid(*args, **kw)


prob.applyStrain_getStressTangentDEM = timed_stage
prob.solveSolid = counted_solid
x = dom.getX()
bx = es.FunctionOnBoundary(dom).getX()
mask = es.whereZero(x[1]) * [0, 1] + es.whereZero(x[1] - ly) * [0, 1] \
    + es.whereZero(x[0]) * [1, 0]
value = es.whereZero(x[1] - ly) * [0, -cfg["strain_step"] * ly]
traction = es.whereZero(bx[0] - lx) * [-cfg["confining"], 0]


def means():
    d = prob.getDomain()
    area = es.integrate(es.Scalar(1.0, es.Function(d)))
    stress = (np.array(es.integrate(prob.getCurrentStress())) / area).tolist()
    pore = es.integrate(es.interpolate(prob.getCurrentPore(), es.Function(d))) / area
    volume = es.integrate(es.trace(prob.getCurrentStrain())) / area
    return stress, float(pore), float(volume)


n0 = prob.getEquivalentPorosity()
porosity = float(es.integrate(n0) / es.integrate(es.Scalar(1.0, es.Function(dom))))
s, p, v = means()
stress, pore, volume, walls, evals, outer = [s], [p], [v], [], [], []
for k in range(cfg["steps"]):
    prob.initialize(f=traction, umsk=mask, uvalue=value)
    n_calls, n_solid = len(calls), solids[0]
    t = time.perf_counter()
    prob.solve(globalIter=cfg["global_iter"], solidIter=cfg["solid_iter"])
    walls.append(time.perf_counter() - t)
    evals.append(len(calls) - n_calls)
    outer.append(solids[0] - n_solid)
    s, p, v = means()
    stress.append(s)
    pore.append(p)
    volume.append(v)
    with open("up_progress.log", "a") as fh:  # for a watcher: a step can take minutes
        fh.write(f"step {k + 1}: {walls[-1]:.1f} s, {evals[-1]} evaluations, "
                 f"{outer[-1]} solid solves, p {p:.0f} Pa, tr eps {v:.3g}\n")
    steps = [s for c in calls for s in c["steps"]]
    result = json.dumps({
        "processes": cfg["processes"], "gauss_points": ng, "steps": k + 1,
        "porosity": porosity, "evaluations_per_step": evals,
        "solid_solves_per_step": outer, "step_wall": walls, "solve_time": sum(walls),
        "setup_time": setup, "stage_wall": sum(c["wall"] for c in calls),
        "calls": len(calls) * ng, "dem_steps_per_call": float(np.mean(steps)),
        "mean_stress": stress, "mean_pore_pressure": pore,
        "mean_volumetric_strain": volume})
    with open(cfg["partial"], "w") as fh:  # the steps so far, should time run out
        fh.write(result)
prob.exitSimulation()
print("RESULT " + result, flush=True)
'''


def peer(paths, steps, procs):
    """FEMxDEM's run of ``steps`` time steps; after ``PEER_TIMEOUT`` seconds (4 h)
    the steps it finished, marked ``partial``."""
    partial = HV.PEER_DIR / "up_partial.json"
    partial.unlink(missing_ok=True)
    cfg = {"size": list(HV.SIZE), "cells": list(CELLS), "steps": steps,
           "processes": procs, "rtol": HV.RTOL, "global_iter": GLOBAL_ITER,
           "solid_iter": SOLID_ITER, "strain_step": STRAIN_STEP, "confining": CONFINING,
           "pore0": PORE0, "perm": KC, "kf": FLUID_BULK, "dt": DT,
           "partial": str(partial)}
    (HV.PEER_DIR / "femxdem_up_driver.py").write_text(DRIVER)
    path = HV.PEER_DIR / f"config_up_{procs}.json"
    path.write_text(json.dumps(cfg))
    env = HV.peer_env(paths, {"HVF_CONFIG": str(path)})
    r = C.run_result([paths["python"], "femxdem_up_driver.py"], env, HV.PEER_DIR,
                   timeout=C.env_int("PEER_TIMEOUT", 4 * 3600))
    if not r.get("ok") and partial.exists():
        r = dict(json.loads(partial.read_text()), ok=True, partial=r["error"])
    return r


# --------------------------------------------------------------------------- comparison
def deviation(a, b):
    """Largest differences of the mean pore pressure, effective axial stress and
    deviator over the common steps of runs ``a`` (ours: the reference scale) and
    ``b``."""
    import numpy as np

    n = min(len(a["mean_stress"]), len(b["mean_stress"]))
    sa, sb = np.array(a["mean_stress"])[:n], np.array(b["mean_stress"])[:n]
    pa, pb = np.array(a["mean_pore_pressure"])[:n], np.array(b["mean_pore_pressure"])[:n]
    excess = max(float(np.abs(pa - PORE0).max()), 1e-300)
    qa, qb = sa[:, 0, 0] - sa[:, 1, 1], sb[:, 0, 0] - sb[:, 1, 1]
    return {
        "max_rel_pore_pressure_deviation": float(np.abs(pa - pb).max() / excess),
        "max_rel_pore_pressure_deviation_of_pressure": float(
            np.abs(pa - pb).max() / np.abs(pa).max()),
        "max_rel_stress_deviation": float(np.abs(sa[:, 1, 1] - sb[:, 1, 1]).max()
                                          / np.abs(sa[:, 1, 1]).max()),
        "max_rel_deviator_deviation": float(np.abs(qa - qb)[1:].max()
                                            / max(np.abs(qa)[1:].max(), 1e-300)),
        "compared_steps": n - 1}


def curves(r):
    s = r["mean_stress"]
    return {"axial_strain": [STRAIN_STEP * k for k in range(len(s))],
            "sigma_xx": [x[0][0] for x in s], "sigma_yy": [x[1][1] for x in s],
            "pore_pressure": r["mean_pore_pressure"],
            "volumetric_strain": r["mean_volumetric_strain"]}


def visualize(data):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10.0, 4.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax_p, ax_s = fig.subplots(1, 2)
    lines = (("ours", "ko-", "hmm"), ("ours_no_relaxation", "b^-.", "hmm, no relaxation"),
             ("ours_finite", "gx:", "hmm, finite kinematics"),
             ("femxdem", "rs--", "FEMxDEM msFEMup"))
    for key, style, name in lines:
        c = data["curves"].get(key)
        if c is None:
            continue
        ea = [100.0 * e for e in c["axial_strain"]]
        ax_p.plot(ea, [(p - PORE0) / 1e3 for p in c["pore_pressure"]], style, ms=5,
                  mfc="none", label=name)
        mean = [-(a + b) / 2e3 for a, b in zip(c["sigma_xx"], c["sigma_yy"], strict=True)]
        q = [(a - b) / 1e3 for a, b in zip(c["sigma_xx"], c["sigma_yy"], strict=True)]
        ax_s.plot(mean, q, style, ms=5, mfc="none", label=name)
    ax_p.set(xlabel="axial strain [%]", ylabel="excess pore pressure p - p0 [kPa]",
             title="pore pressure (mean over the Gauss points)")
    ax_s.set(xlabel="mean effective stress -(σ'xx + σ'yy) / 2 [kPa]",
             ylabel="deviator σ'xx - σ'yy [kPa]", title="effective stress path")
    good = data.get("peer_converged_steps")
    if good is not None:
        dev = data.get("max_rel_pore_pressure_deviation_converged_steps")
        ax_p.set_title(f"pore pressure; FEMxDEM's split converged in {good} of "
                       f"{len(data['runs']['femxdem']['step_wall'])} steps"
                       + (f"\n(there, without relaxation: |Δp| {100 * dev:.1f} % of "
                          f"max |p - p0|)" if dev is not None else ""), fontsize=9)
    for ax in (ax_p, ax_s):
        ax.legend(fontsize=8)
    return fig


#: the per-step series each run keeps in the JSON
SERIES = ("step_wall", "mean_stress", "mean_pore_pressure", "mean_volumetric_strain")


def converged_steps(peer_run):
    """How many of the peer's first steps its split converged in: fewer solid solves
    than its cap (1 + its outer iterations)."""
    n = 0
    for k in peer_run["solid_solves_per_step"]:
        if k > GLOBAL_ITER:
            break
        n += 1
    return n


def compare(data):
    """The figures of ``data["runs"]``: speedups over the peer's steps, deviations
    over them (and over the steps its split converged in, ``_converged_steps``), each
    run's departure from the undrained volume, the curves."""
    runs = data["runs"]
    n0 = data["settings"]["porosity"]
    for r in runs.values():  # how well each keeps the undrained volume
        n = r.get("porosity", n0)
        r["max_volume_error"] = max(
            abs(v + n / FLUID_BULK * (p - PORE0)) for v, p in
            zip(r["mean_volumetric_strain"], r["mean_pore_pressure"], strict=True))
    them = runs.get("femxdem")
    if them is not None:
        n = len(them["step_wall"])  # the peer's steps: the speedups over the same steps
        good = converged_steps(them)
        data["peer_converged_steps"] = good
        for key, suffix in (("ours_no_relaxation", ""), ("ours", "_default"),
                            ("ours_finite", "_finite")):
            if key not in runs:
                continue
            us = runs[key]
            mine = sum(us["step_wall"][:n]) / n
            tag = {"ours": "", "ours_no_relaxation": "_no_relaxation"}.get(key, suffix)
            data["speedup" + tag] = them["wall_per_load_step"] / mine
            data["speedup_rve_call" + tag] = (
                them["wall_per_rve_call"] / us["wall_per_rve_call"])
            for k, v in deviation(us, them).items():
                data[k if k == "compared_steps" else k + suffix] = v
            if good:
                first = {k: v[:good + 1] for k, v in them.items() if k in SERIES}
                for k, v in deviation(us, first).items():
                    if k != "compared_steps":
                        data[k + suffix + "_converged_steps"] = v
    data["max_rel_pore_pressure_deviation_relaxation"] = deviation(
        runs["ours"], runs["ours_no_relaxation"])["max_rel_pore_pressure_deviation"]
    if "ours_finite" in runs:  # the two kinematics over our steps
        data["kinematics_deviation"] = deviation(runs["ours"], runs["ours_finite"])
    data["curves"] = {key: curves(r) for key, r in runs.items()}


def run_ours(data, key, steps, procs, n0):
    """Our run ``key`` of :data:`VARIANTS` into ``data["runs"]``."""
    load = C.loadavg()
    r = ours(steps, procs, key, n0)
    if not r.get("ok"):
        raise RuntimeError(f"{key} failed: {r['error']}")
    data["runs"][key] = dict(HV.per_run(r), loadavg=load, cuts=r["cuts"], date=C.now(),
                             **{k: r[k] for k in SERIES})
    print(f"{key}: {data['runs'][key]['wall_per_load_step']:.2f} s per step, "
          f"evaluations {r['evaluations_per_step']}, p - p0 "
          f"{[round((p - PORE0) / 1e3, 1) for p in r['mean_pore_pressure']]} kPa",
          flush=True)


def main():
    """The runs and their comparison. ``--rescore`` recomputes the figures of the
    JSON's runs (after a change to :func:`compare`) without running anything;
    ``--add NAME`` runs our variant ``NAME`` (of :data:`VARIANTS`) alone into the
    JSON and rescores, the other runs kept (each run carries its date)."""
    if "--rescore" in sys.argv or "--add" in sys.argv:
        data = json.loads(OUT.read_text())
        if "--add" in sys.argv:
            key = sys.argv[sys.argv.index("--add") + 1]
            if key not in VARIANTS:
                raise SystemExit(f"--add: one of {', '.join(VARIANTS)}, not {key!r}")
            s = data["settings"]
            run_ours(data, key, s["steps"], s["processes"], s["porosity"])
        compare(data)
        C.write_json(OUT, data)
        visualize(data).savefig(FIGURE, dpi=120)
        return
    steps = C.env_int("STEPS", 20)
    peer_steps = C.env_int("PEER_STEPS", 3)
    procs = C.env_int("PROCS", 2)
    t0 = time.perf_counter()
    prep = C.run_worker(__file__, ["prepare"], threads=1)
    if not prep.get("ok"):
        raise RuntimeError("preparing the packing failed: " + prep["error"])
    n0 = porosity(prep)
    data = {"benchmark": OUT.stem, "date": C.now(), "machine": C.machine_info(),
            "versions": C.our_versions(),
            "settings": {"sample": list(HV.SIZE), "cells": list(CELLS),
                         "element": "quad8/quad1 (2 x 2 Gauss points)", "dt": DT,
                         "strain_step": STRAIN_STEP, "steps": steps,
                         "peer_steps": peer_steps, "processes": procs,
                         "confining_total": CONFINING, "effective_p0": HV.P0,
                         "pore_pressure_0": PORE0, "fluid_bulk_modulus": FLUID_BULK,
                         "kozeny_carman": KC, "porosity": n0, "rtol": HV.RTOL,
                         "femxdem_iterations": [GLOBAL_ITER, SOLID_ITER],
                         "micro": HV.MICRO, "solver": HV.SOLVER,
                         "kinematics": "small (ours, ours_no_relaxation), updated "
                                       "Lagrangian (ours_finite, FEMxDEM)"},
            "packing": {"ours": {k: prep[k] for k in ("stress", "void_ratio",
                                                      "n_contacts", "particles")}},
            "runs": {}, "curves": {}}
    print(f"packing ready: porosity {n0:.4f}, stress "
          f"{HV._rounded(prep['stress'])} Pa", flush=True)
    paths, reason = HV.peer_paths()
    if paths is not None:
        try:
            data["packing"]["yade"] = HV.prepare_peer(paths)
            data["versions"]["yade"] = data["packing"]["yade"].get("yade_version")
        except (RuntimeError, OSError) as err:
            paths, reason = None, f"YADE could not prepare the RVE scene: {err}"
    for key in VARIANTS:
        run_ours(data, key, steps, procs, n0)
    if paths is None:
        data.update(status="peer_skipped", reason=reason)
        print(f"FEMxDEM skipped: {reason}", flush=True)
    else:
        load = C.loadavg()
        r = peer(paths, peer_steps, procs)
        if not r.get("ok"):
            raise RuntimeError("FEMxDEM failed: " + r["error"])
        data["packing"]["yade"]["porosity"] = r["porosity"]
        if r.get("partial"):
            data["peer_partial"] = f"{r['steps']} of {peer_steps} steps: {r['partial']}"
        data["runs"]["femxdem"] = dict(
            HV.per_run(r, peer=True), loadavg=load, porosity=r["porosity"],
            solid_solves_per_step=r["solid_solves_per_step"], **{k: r[k] for k in SERIES})
        print(f"FEMxDEM: {data['runs']['femxdem']['wall_per_load_step']:.2f} s per step, "
              f"evaluations {r['evaluations_per_step']}, p - p0 "
              f"{[round((p - PORE0) / 1e3, 1) for p in r['mean_pore_pressure']]} kPa",
              flush=True)
        data["status"] = "ok"
    compare(data)
    data["wall_time"] = time.perf_counter() - t0
    data["loadavg_end"] = C.loadavg()
    C.write_json(OUT, data)
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    visualize(data).savefig(FIGURE, dpi=120)
    print(f"speedup {data.get('speedup')}, without relaxation "
          f"{data.get('speedup_no_relaxation')}; max_rel_pore_pressure_deviation "
          f"{data.get('max_rel_pore_pressure_deviation')}, max_rel_stress_deviation "
          f"{data.get('max_rel_stress_deviation')}; wrote {C.display_path(OUT)}, "
          f"{C.display_path(FIGURE)}")


def worker(args):
    if args[0] == "prepare":
        C.emit_result(prepare())
    elif args[0] == "ours":
        steps, relax, n0, kinematics = int(args[1]), args[2] == "relax", float(args[3]), \
            args[4]
        out_dir = HV.SCRATCH / f"ours_up{'' if relax else '_fixed'}_{kinematics}"
        r = HV.run_timed(problem(steps, relax, n0, out_dir, kinematics), out_dir)
        if r is not None:
            C.emit_result(r)


if __name__ == "__main__":
    C.entry(main, worker)
