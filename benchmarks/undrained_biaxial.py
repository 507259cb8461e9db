"""The undrained biaxial test of ``examples/biaxial_undrained.toml`` on a dense and a
loose packing: effective stress paths and excess pore pressures, and the two limits
the solution must reach: the constant-volume RVE test and the drained run.

The example is YADE FEMxDEM's ``undrain.py`` in this project's terms: a sealed 5 x 10
cm plane-strain sample, 100 kPa of pore pressure at the start, 200 kPa of total
confinement, every Gauss point a DEM RVE consolidated to 100 kPa of effective stress,
shortened by 5 %. Two packings of the same disks: consolidated frictionless (dense,
``[micro] consolidation_friction = 0``) and with friction 0.3 (loose). Undrained, a
dense packing first contracts a little, then dilates: its pore pressure rises, then
falls below its start (suction) while the effective stress grows; a loose one
contracts: its pore pressure rises until the effective stress, and with it the
deviator, collapse (static liquefaction).

Each packing is made once, by ``hmm rve``'s undrained (constant-volume) test on it,
which writes the packing every run of it then reads. The sealed sample must follow
that test (the undrained limit). For the dense packing (``LIMITS``), two more runs:
the sample with drained top and right sides and a permeability of 1e-8 m^2, whose
water has time to leave (the drained limit), and the dry sample under 100 kPa; the
two must agree. Deviations are in units of the peak deviator of the run compared
against.

The sample runs under the venv's ``mpiexec`` on ``PROCS`` ranks (one numba thread
each). Per step: the Gauss-point means of the mean effective stress ``p' = -(s'_xx +
s'_yy) / 2``, the deviator ``q = s'_xx - s'_yy`` and the excess pore pressure ``p -
p_0``, and of the volumetric strain, which a sealed sample keeps at the water's
compression. ``CELLS`` ("2x4") and ``COUNT`` (the example's 100 disks) set the size:
the reference's is ``CELLS=8x16 COUNT=400``.

usage::

    python benchmarks/undrained_biaxial.py   # writes benchmarks/results/undrained_biaxial.json
                                             # and docs/figures/undrained_biaxial.png
    CELLS=8x16 COUNT=400 LIMITS= python benchmarks/undrained_biaxial.py   # the reference's
                                             # size: undrained_biaxial_8x16_400.json, .png
    python benchmarks/undrained_biaxial.py --plot      # redraws the figure from the JSON
    python benchmarks/undrained_biaxial.py --collect   # the JSON of an interrupted run

environment: CELLS ("2x4"), COUNT (100), STEPS (100), PROCS (2), PACKINGS ("dense loose"),
LOOSE_FRICTION (0.3), LIMITS ("dense": the packings whose drained limit runs).
"""

import json
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "undrained_biaxial.json"
FIGURE = C.REPO / "docs" / "figures" / "undrained_biaxial.png"
#: the example's size; any other writes undrained_biaxial_<cells>_<count>.json/.png
DEFAULT_SIZE = ([2, 4], 100)
SCRATCH = C.WORK / "undrained_biaxial"
EXAMPLE = C.REPO / "examples" / "biaxial_undrained.toml"
#: packing -> [micro] consolidation_friction (LOOSE_FRICTION: the loose one's)
PACKINGS = {"dense": 0.0, "loose": float(os.environ.get("LOOSE_FRICTION", "0.3"))}
#: the drained limit: a permeability [m^2] whose consolidation time is far below a step
DRAINED_PERMEABILITY = 1e-8
#: the strain [-] to which the limits are also compared: before the samples localise
EARLY_STRAIN = 0.01
#: run kind -> how the example changes: "sealed" as written, "drained" with drained
#: top and right sides, "dry" without water under the effective confinement
KINDS = ("sealed", "drained", "dry")


def scratch(packing, cells, count):
    """The runs' directory of ``packing`` at a size."""
    return SCRATCH / f"{packing}_{cells[0]}x{cells[1]}_{count}"


def raw_example():
    """The example file's tables, before validation."""
    import tomllib

    with open(EXAMPLE, "rb") as f:
        return tomllib.load(f)


def problem(packing, kind, cells, count, steps, out_dir):
    """The example's problem of ``kind`` with its mesh and steps replaced, every
    Gauss point holding the packing the RVE test of ``packing`` wrote."""
    from hmm.problem import validate_problem

    data = raw_example()
    for key in ("count", "radius", "p0", "seed"):  # the packing file has them
        data["micro"].pop(key)
    data["micro"]["packing"] = str(scratch(packing, cells, count) / "rve" / "packing.h5")
    data["mesh"]["cells"] = list(cells)
    data["load"]["steps"] = int(steps)
    data["output"]["dir"] = str(out_dir)
    p0 = data["fluid"]["initial_pressure"]
    if kind == "drained":
        data["fluid"]["permeability"] = DRAINED_PERMEABILITY
        data["drainage"] = [{"boundary": b, "pressure": p0} for b in ("top", "right")]
    elif kind == "dry":
        for key in ("fluid", "time"):
            data.pop(key)
        # a dry problem's default is finite; the saturated runs' is small
        data["solver"].setdefault("kinematics", "small")
        for load in data["pressure"]:
            load["value"] -= p0  # the effective confinement
    return validate_problem(data, source=f"{EXAMPLE.stem}_{kind}.toml")


def rve_test(packing, cells, count, steps):
    """``hmm rve``'s undrained test of the example's RVE (its disks, contacts and
    consolidation, ``count`` of them) to the example's axial strain in ``steps``
    increments. It writes the packing the sample's runs read. The curves in the
    sample's measures."""
    from hmm.experiment import run_experiment, validate_config

    data = raw_example()
    mc = data["micro"]
    extent = abs(next(d["value"] for d in data["dirichlet"] if d["boundary"] == "top"))
    extent /= data["mesh"]["size"][1]
    cfg = validate_config({
        "packing": {"count": int(count), "radius": mc["radius"], "p0": mc["p0"],
                    "seed": mc["seed"], "consolidation_friction": PACKINGS[packing]},
        "contact": {"law": "linear", "kn": mc["kn"], "kt": mc["kt"], "mu": mc["mu"]},
        "test": {"kind": "undrained", "axial_strain": extent,
                 "increment": extent / steps}},
        f"{EXAMPLE.stem}_rve.toml")
    cfg["output"]["dir"] = str(scratch(packing, cells, count) / "rve")
    t0 = time.perf_counter()
    run_experiment(cfg, overwrite=True, progress=False)
    return {"wall_time": time.perf_counter() - t0,
            **rve_curves(scratch(packing, cells, count) / "rve")}


def rve_curves(out_dir):
    """The curves of the RVE test in ``out_dir``, in the sample's measures."""
    import h5py

    with h5py.File(out_dir / "rve_test.h5", "r") as f:
        sig = f["stress"][()]
        strain, excess = f["axial_strain"][()], f["excess_pore_pressure"][()]
    return {"axial_strain": [float(e) for e in strain],
            "p_eff": [float(x) for x in -(sig[:, 0, 0] + sig[:, 1, 1]) / 2.0],
            "q": [float(x) for x in sig[:, 0, 0] - sig[:, 1, 1]],
            "excess_pore_pressure": [float(x) for x in excess]}


def run_one(packing, kind, cells, count, steps):
    """One run of the sample (every rank calls this); rank 0 returns the mean path
    per step."""
    from hmm.coupling import SolverError
    from hmm.run import run_problem

    out_dir = scratch(packing, cells, count) / kind
    prob = problem(packing, kind, cells, count, steps, out_dir)
    stopped = None
    try:
        s = run_problem(prob, out_dir, overwrite=True, progress=False)
    except SolverError as err:  # a liquefied point: its packing came apart
        s, stopped = {}, str(err)
    if s is None:
        return None
    return {"stopped": stopped,
            **{k: s.get(k) for k in ("cuts", "iterations", "solve_time", "total_time")},
            **sample_path(prob, out_dir)}


def sample_path(prob, out_dir):
    """The Gauss-point means per step of the run of ``prob`` in ``out_dir``."""
    import h5py
    import numpy as np

    p0 = prob["fluid"]["initial_pressure"] if prob.get("fluid") else 0.0
    shortening = abs(next(d["value"] for d in prob["dirichlet"] if d["boundary"] == "top"))
    path = {"axial_strain": [], "p_eff": [], "q": [], "excess_pore_pressure": [],
            "volumetric_strain": [], "axial_strain_min": [], "axial_strain_max": []}
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
            pore = g["gauss/pore_pressure"][()] if "gauss/pore_pressure" in g else \
                np.full_like(w, p0)
            path["excess_pore_pressure"].append(float(w @ (pore - p0)))
            path["volumetric_strain"].append(float(w @ np.trace(eps, axis1=1, axis2=2)))
            path["axial_strain_min"].append(float(-eps[:, 1, 1].max()))  # the points'
            path["axial_strain_max"].append(float(-eps[:, 1, 1].min()))  # spread
    return {"steps": len(path["q"]) - 1, **path}


def visualize(data):
    """The effective stress paths, deviators and excess pore pressures of the sealed
    samples beside their RVE tests (thin lines), and the drained limit."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    drained = data["drained_limit"]
    fig = Figure(figsize=(14.5 if drained else 11.0, 3.8), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 4 if drained else 3)
    ax_s, ax_q, ax_u = axes[:3]
    kpa = 1e-3
    for name, style, colour in (("dense", "o-", "k"), ("loose", "s--", "r")):
        r, lab = data["runs"].get(name), data["rve_tests"].get(name)
        if r is None:
            continue
        ea = [100.0 * e for e in r["axial_strain"]]
        ea_lab = [100.0 * e for e in lab["axial_strain"]]
        for ax, x, y, x_lab, y_lab in (
                (ax_s, r["p_eff"], r["q"], lab["p_eff"], lab["q"]),
                (ax_q, None, r["q"], None, lab["q"]),
                (ax_u, None, r["excess_pore_pressure"], None,
                 lab["excess_pore_pressure"])):
            xs = ea if x is None else [kpa * v for v in x]
            xs_lab = ea_lab if x_lab is None else [kpa * v for v in x_lab]
            ax.plot(xs, [kpa * v for v in y], style, color=colour, ms=3, mfc="none",
                    label=f"{name}, sample")
            ax.plot(xs_lab, [kpa * v for v in y_lab], "-", color=colour, lw=0.8,
                    alpha=0.6, label=f"{name}, RVE test")
    for name, lim in drained.items():
        for kind, style in (("drained", "b^-"), ("dry", "k-")):
            r = lim["runs"][kind]
            axes[3].plot([100.0 * e for e in r["axial_strain"]], [kpa * v for v in r["q"]],
                      style, ms=3, mfc="none", lw=0.9, label=f"{name}, {kind}")
    ax_s.set(xlabel="mean effective stress p' [kPa]", ylabel="deviator q [kPa]",
             title="effective stress path")
    ax_q.set(xlabel="axial strain [%]", ylabel="deviator q [kPa]", title="deviator")
    ax_u.set(xlabel="axial strain [%]", ylabel="excess pore pressure [kPa]",
             title="pore pressure (sealed sample)")
    if drained:
        axes[3].set(xlabel="axial strain [%]", ylabel="deviator q [kPa]",
                    title="the drained limit")
    ax_u.axhline(0.0, color="0.6", lw=0.8)
    for ax in axes:
        ax.legend(fontsize=7)
    s = data["settings"]
    fig.suptitle(f"undrained biaxial, {s['cells'][0]} x {s['cells'][1]} quad8, "
                 f"{s['count']}-disk RVEs (Gauss-point means)", fontsize=10)
    return fig


def outputs(cells, count):
    """The result and figure paths: the example's size keeps the plain names."""
    if (list(cells), count) == DEFAULT_SIZE:
        return OUT, FIGURE
    tag = f"_{cells[0]}x{cells[1]}_{count}"
    return (OUT.with_name(OUT.stem + tag + ".json"),
            FIGURE.with_name(FIGURE.stem + tag + ".png"))


def deviation(path, ref, key, scale, upto=None):
    """Largest ``|path[key] - ref[key]|`` over the axial strains both reach (``ref``
    interpolated at ``path``'s), or up to ``upto``, over ``scale``."""
    import numpy as np

    e, e_ref = np.asarray(path["axial_strain"]), np.asarray(ref["axial_strain"])
    inside = e <= min(e_ref[-1], np.inf if upto is None else upto) * (1.0 + 1e-9)
    d = np.asarray(path[key])[inside] - np.interp(e[inside], e_ref, ref[key])
    return float(np.abs(d).max() / scale)


def launch(args, procs, cells, count, steps):
    """Run a worker of ``args`` (on ``procs`` ranks); its result."""
    return C.launch(__file__, [*args, "x".join(map(str, cells)), count, steps], procs,
                    timeout=4 * 3600)


def report(name, r):
    """One line on a sample's run."""
    if r["stopped"]:
        print(f"{name} stopped after {r['steps']} steps: {r['stopped']}")
    print(f"{name}: {r['steps']} steps, peak q {max(r['q']) / 1e3:.1f} kPa, excess pore "
          f"pressure {max(r['excess_pore_pressure']) / 1e3:.1f} to "
          f"{r['excess_pore_pressure'][-1] / 1e3:.1f} kPa at the end", flush=True)


def score_undrained(data, packing):
    """The sealed sample of ``packing`` against its RVE test."""
    r, lab = data["runs"][packing], data["rve_tests"][packing]
    peak = max(abs(v) for v in lab["q"])
    data["undrained_limit"][packing] = {
        **{f"max_rel_{name}_deviation{tag}": deviation(r, lab, key, peak, upto)
           for name, key in (("q", "q"), ("pore_pressure", "excess_pore_pressure"))
           for tag, upto in (("", None), ("_to_1_percent", EARLY_STRAIN))},
        "rve_test_peak_q": peak, "rve_test_steps": len(lab["q"]) - 1}
    print(f"{packing}, against its RVE test: {data['undrained_limit'][packing]}")


def score_drained(data, packing, runs):
    """The drained sample of ``packing`` against the dry one."""
    dry, drained = runs["dry"], runs["drained"]
    peak = max(abs(v) for v in dry["q"])
    data["drained_limit"][packing] = {
        "max_rel_q_deviation": deviation(drained, dry, "q", peak),
        "max_rel_q_deviation_to_1_percent": deviation(drained, dry, "q", peak,
                                                      EARLY_STRAIN),
        "max_rel_pore_pressure": max(abs(v) for v in drained["excess_pore_pressure"])
        / peak, "dry_peak_q": peak, "runs": runs}
    print(f"{packing}, drained against dry: "
          f"{ {k: v for k, v in data['drained_limit'][packing].items() if k != 'runs'} }")


def collected(packing, kind, cells, count, steps):
    """A run of an interrupted benchmark, read back from its directory (``None``
    when it has none): the steps it finished."""
    out_dir = scratch(packing, cells, count) / kind
    if not (out_dir / "fields.h5").is_file():
        return None
    r = sample_path(problem(packing, kind, cells, count, steps, out_dir), out_dir)
    short = f"{r['steps']} of {steps} steps on disk (collected; why it stopped is not " \
        "recorded)"
    return {"stopped": None if r["steps"] == steps else short, "collected": True, **r}


def main():
    """The runs and their comparison. ``--plot`` redraws the figure of the size's
    JSON; ``--collect`` writes the JSON from the runs on disk (an interrupted
    benchmark: the steps each run finished; times and iterations are lost)."""
    cells = [int(c) for c in C.env_list("CELLS", "2x4")[0].split("x")]
    count, steps, procs = C.env_int("COUNT", 100), C.env_int("STEPS", 100), \
        C.env_int("PROCS", 2)
    limits = os.environ.get("LIMITS", "dense").replace(",", " ").split()
    out, figure = outputs(cells, count)
    if "--plot" in sys.argv:
        visualize(json.loads(out.read_text())).savefig(figure, dpi=120)
        return
    collect = "--collect" in sys.argv
    data = {"benchmark": out.stem, "date": C.now(), "machine": C.machine_info(),
            "versions": C.our_versions(),
            "settings": {"example": C.display_path(EXAMPLE), "cells": cells,
                         "count": count, "steps": steps, "processes": procs,
                         "consolidation_friction": PACKINGS,
                         "drained_permeability": DRAINED_PERMEABILITY,
                         "collected": collect},
            "runs": {}, "rve_tests": {}, "undrained_limit": {}, "drained_limit": {}}
    t0 = time.perf_counter()
    size = (cells, count, steps)
    for packing in C.env_list("PACKINGS", "dense loose"):
        if collect:
            if not (scratch(packing, cells, count) / "rve" / "rve_test.h5").is_file():
                continue
            data["rve_tests"][packing] = rve_curves(scratch(packing, cells, count) / "rve")
            r = collected(packing, "sealed", *size)
            if r is None:
                continue
            data["runs"][packing] = r
        else:
            data["rve_tests"][packing] = launch(["rve", packing], 1, *size)
            data["runs"][packing] = launch(["sealed", packing], procs, *size)
        report(packing, data["runs"][packing])
        score_undrained(data, packing)
        if packing not in limits:
            continue
        if collect:
            runs = {kind: collected(packing, kind, *size) for kind in ("drained", "dry")}
            if None in runs.values():
                continue
        else:
            runs = {kind: launch([kind, packing], procs, *size)
                    for kind in ("drained", "dry")}
        score_drained(data, packing, runs)
    if not collect:
        data["wall_time"] = time.perf_counter() - t0
    C.write_json(out, data)
    figure.parent.mkdir(parents=True, exist_ok=True)
    visualize(data).savefig(figure, dpi=120)
    print(f"wrote {C.display_path(out)}, {C.display_path(figure)}")


def worker(args):
    """``kind packing cells count steps``: the RVE test ("rve") or a run of the
    sample."""
    kind, packing = args[0], args[1]
    cells = [int(c) for c in args[2].split("x")]
    count, steps = int(args[3]), int(args[4])
    if kind == "rve":
        r = rve_test(packing, cells, count, steps)
    elif kind not in KINDS:
        raise ValueError(f"unknown run {kind!r}: one of rve, {', '.join(KINDS)}")
    else:
        r = run_one(packing, kind, cells, count, steps)
    if r is not None:
        C.emit_result(r)


if __name__ == "__main__":
    C.entry(main, worker)
