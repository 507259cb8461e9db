"""The passive retaining wall in the reference's geometry: earth pressure against
Rankine's and Coulomb's for the RVE's own friction angles.

``python benchmarks/retaining_wall_reference.py`` first runs the drained biaxial test
(``hmm rve``) of the RVE that ``examples/retaining_wall_reference.toml`` puts at every
Gauss point (its disks, contacts, rolling resistance and consolidation at the
surcharge), which gives the peak and critical-state friction angles and writes the
packing; then the example itself on ``PROCS`` ranks (2), every Gauss point holding that
packing. The wall's earth-pressure coefficient is ``K = F / F_0``: its horizontal force
per metre over the force at rest, where the RVEs' isotropic stress makes ``K_0 = 1``
(``F_0`` is ``q h`` plus the toe's share of its top vertex: ``q (h + l / 6)`` for
quadratic elements, l the length of the toe's facet below that vertex). Rankine's
passive coefficient ``tan^2(45 deg + phi / 2)`` is Coulomb's too for a smooth vertical
wall and a level backfill; the reference's rough base and far side and its toe make the
problem differ from both, which the comparison states, not hides.

Writes ``benchmarks/results/retaining_wall_reference.json`` and
``docs/figures/retaining_wall_reference.png`` (K against the wall's displacement over
its height, with the two coefficients; the deviatoric strain on the deformed mesh at
the end). ``CELLS=40x20`` meshes the reference's 40 x 20 quad8 (3,200 Gauss points,
uniform: the toe's top is a row of vertices) instead of the example's graded 10 x 5, and
writes ``..._40x20`` files; ``COUNT`` (100) disks per RVE; ``--plot`` redraws the
figure from the JSON.
"""

import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common as C

EXAMPLE = C.REPO / "examples" / "retaining_wall_reference.toml"
OUT = C.RESULTS / "retaining_wall_reference.json"
FIGURE = C.REPO / "docs" / "figures" / "retaining_wall_reference.png"
SCRATCH = C.WORK / "retaining_wall_reference"
#: the RVE test: axial strain and increment [-]
RVE_STRAIN, RVE_INCREMENT = 0.1, 1e-3


def tag(cells, count):
    """The runs' and outputs' suffix of a size ("" for the example's)."""
    return ("" if cells is None else f"_{cells[0]}x{cells[1]}") + \
        ("" if count == 100 else f"_{count}")


def raw_example():
    import tomllib

    with open(EXAMPLE, "rb") as f:
        return tomllib.load(f)


def rve_test(count, out_dir):
    """``hmm rve``'s drained biaxial test of the example's RVE (``count`` disks); its
    friction angles, and the packing file it writes."""
    from hmm.experiment import run_experiment, validate_config

    mc = raw_example()["micro"]
    cfg = validate_config({
        "packing": {"dim": 2, "count": int(count), "radius": mc["radius"], "p0": mc["p0"],
                    "seed": mc["seed"], "consolidation_friction": 0.0},
        "contact": {"law": "linear", **{k: mc[k] for k in ("kn", "kt", "mu", "mu_roll",
                                                           "eta_roll")}},
        "test": {"axial_strain": RVE_STRAIN, "increment": RVE_INCREMENT}},
        f"{EXAMPLE.stem}_rve.toml")
    r = run_experiment(cfg, out_dir, overwrite=True, progress=False)
    s = r.summary
    return {"peak_friction_angle": s["peak_friction_angle"],
            "critical_friction_angle": s["critical_friction_angle"],
            "wall_time": s["wall_time"], "packing": str(out_dir / "packing.h5")}


def problem(cells, packing, out_dir):
    """The example with every Gauss point holding ``packing``; on the reference's
    uniform mesh when ``cells`` is given."""
    from hmm.problem import validate_problem

    data = raw_example()
    for key in ("count", "radius", "p0", "seed"):  # the packing file has them
        data["micro"].pop(key)
    data["micro"]["packing"] = packing
    if cells is not None:
        x, y = data["mesh"].pop("x"), data["mesh"].pop("y")
        data["mesh"]["size"] = [x[-1], y[-1]]
        data["mesh"]["cells"] = list(cells)
    data["output"]["dir"] = str(out_dir)
    return validate_problem(data, source=EXAMPLE.name)


def run_sample(cells, packing, out_dir):
    """The example's run (every rank calls this); rank 0 returns its curve."""
    import h5py

    from hmm.farm import mpi_world
    from hmm.run import run_problem

    prob = problem(cells, packing, out_dir)
    t0 = time.perf_counter()
    s = run_problem(prob, out_dir, overwrite=True, progress=False)
    wall = time.perf_counter() - t0
    _, comm = mpi_world()
    if comm is not None and comm.Get_rank() != 0:
        return None
    with h5py.File(out_dir / "fields.h5", "r") as f:
        force = -f["curve/force/wall"][:, 0]
        moved = -f["curve/displacement/wall"][:, 0]
        iters = f["curve/iterations"][()].astype(int).tolist()
        points = f["gauss/points"].shape[0]
    return {"wall_time": wall, "solve_time": s.get("solve_time"), "cuts": s.get("cuts"),
            "iterations": iters, "gauss_points": points, "force": force.tolist(),
            "displacement": moved.tolist()}


def rankine(phi_deg):
    """Rankine's (and, for a smooth vertical wall and a level backfill, Coulomb's)
    passive earth-pressure coefficient."""
    return math.tan(math.radians(45.0 + phi_deg / 2.0)) ** 2


def score(data):
    """K along the run, its peak and end, and the coefficients."""
    run, lab = data["run"], data["rve_test"]
    example = raw_example()
    box = {b["name"]: b for b in example["boundary"]}
    height, toe = (box[n]["hi"][1] - box[n]["lo"][1] for n in ("wall", "toe"))  # [m]
    f0 = run["force"][0]
    k = [f / f0 for f in run["force"]]
    top = max(range(len(k)), key=k.__getitem__)
    q = example["pressure"][0]["value"]
    data["K"] = k
    data["wall_height"], data["toe_height"] = height, toe
    data["wall_displacement_over_height"] = [d / height for d in run["displacement"]]
    # the toe's facet under the wall's lowest vertex, of which that vertex carries a
    # sixth (quadratic elements)
    cells = data["settings"]["cells"]
    if isinstance(cells, list):
        facet = example["mesh"]["y"][-1] / cells[1]
    else:
        facet = toe - max(y for y in example["mesh"]["y"] if y < toe)
    data["toe_facet"] = facet
    data["at_rest_force_over_q_h_plus_toe_facet_sixth"] = f0 / (q * (height + facet / 6.0))
    data["peak_K"], data["peak_at_displacement_over_height"] = k[top], \
        data["wall_displacement_over_height"][top]
    data["end_K"] = k[-1]
    data["rankine_coulomb_K_p"] = {"peak": rankine(lab["peak_friction_angle"]),
                                   "critical": rankine(lab["critical_friction_angle"])}
    data["friction_angle_of_peak_K"] = 2.0 * math.degrees(math.atan(math.sqrt(k[top]))) \
        - 90.0


def visualize(data, fields):
    """K against the wall's displacement, beside the deviatoric strain at the end."""
    import h5py
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11.0, 4.0))
    FigureCanvasAgg(fig)
    ax, bx = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.0, 1.6]})
    x = 100.0 * np.asarray(data["wall_displacement_over_height"])
    ax.plot(x, data["K"], "k.-", ms=3, label="wall, K = F / F$_0$")
    for name, style in (("peak", "--"), ("critical", ":")):
        phi = data["rve_test"][f"{name}_friction_angle"]
        ax.axhline(data["rankine_coulomb_K_p"][name], color="C0", ls=style,
                   label=f"Rankine/Coulomb K$_p$, {name} φ = {phi:.1f}°")
    ax.set_xlabel("wall displacement / wall height [%]")
    ax.set_ylabel("earth-pressure coefficient K [-]")
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(alpha=0.3)
    if fields is not None and Path(fields).is_file():
        with h5py.File(fields, "r") as f:
            last = f["steps"][sorted(f["steps"])[-1]]
            pts = last["gauss/points"][()] if "gauss/points" in last else \
                f["gauss/points"][()]
            eps = last["gauss/strain"][()]
        dev = eps - np.einsum("n,ij->nij", np.trace(eps, axis1=1, axis2=2) / 2.0,
                              np.eye(2))
        shear = np.sqrt(2.0 * np.einsum("nij,nij->n", dev, dev))
        # the colours stop at the 98th percentile: the toe's corner, where the wall
        # slides past the fixed toe, would take the whole scale
        top = float(np.percentile(100.0 * shear, 98.0))
        sc = bx.scatter(pts[:, 0], pts[:, 1], c=100.0 * shear, s=12.0 if len(pts) < 1000
                        else 3.0, cmap="viridis", vmax=top)
        fig.colorbar(sc, ax=bx, label="deviatoric strain [%]", extend="max")
        bx.set_aspect("equal")
        bx.set_xlabel("x [m]")
        bx.set_ylabel("y [m]")
        bx.set_title("at the end, on the deformed mesh (Gauss points)", fontsize=9)
    fig.tight_layout()
    return fig


def outputs(cells, count):
    t = tag(cells, count)
    return (OUT.with_name(OUT.stem + t + ".json"), FIGURE.with_name(FIGURE.stem + t + ".png"),
            SCRATCH / ("run" + t))


def main():
    import json

    cells_env = C.env_list("CELLS", "")
    cells = [int(c) for c in cells_env[0].split("x")] if cells_env else None
    count, procs = C.env_int("COUNT", 100), C.env_int("PROCS", 2)
    out, figure, run_dir = outputs(cells, count)
    if "--plot" in sys.argv:
        data = json.loads(out.read_text())
        visualize(data, run_dir / "fields.h5").savefig(figure, dpi=130)
        return
    data = {"benchmark": out.stem, "date": C.now(), "machine": C.machine_info(),
            "versions": C.our_versions(),
            "settings": {"example": C.display_path(EXAMPLE),
                         "cells": cells or "the example's graded 10 x 5", "count": count,
                         "processes": procs, "rve_test": {"axial_strain": RVE_STRAIN,
                                                          "increment": RVE_INCREMENT}}}
    lab_dir = SCRATCH / ("rve" + tag(None, count))
    data["rve_test"] = C.launch(__file__, ["rve", count, lab_dir], 1)
    print(f"RVE test: peak {data['rve_test']['peak_friction_angle']:.1f} deg, critical "
          f"{data['rve_test']['critical_friction_angle']:.1f} deg", flush=True)
    data["run"] = C.launch(__file__, ["run", cells_env[0] if cells else "-",
                                      data["rve_test"]["packing"], run_dir], procs,
                           timeout=8 * 3600)
    data["rve_test"]["packing"] = C.display_path(data["rve_test"]["packing"])
    score(data)
    r = data["run"]
    print(f"{r['gauss_points']} Gauss points, {len(r['iterations']) - 1} steps, "
          f"{sum(r['iterations'])} iterations, {r['cuts']} cuts, {r['wall_time']:.0f} s; "
          f"K peak {data['peak_K']:.2f} at {100 * data['peak_at_displacement_over_height']:.2f} "
          f"% of the wall's height, end {data['end_K']:.2f}; Rankine/Coulomb "
          f"{data['rankine_coulomb_K_p']['peak']:.2f} (peak phi), "
          f"{data['rankine_coulomb_K_p']['critical']:.2f} (critical)", flush=True)
    C.write_json(out, data)
    figure.parent.mkdir(parents=True, exist_ok=True)
    visualize(data, run_dir / "fields.h5").savefig(figure, dpi=130)
    print(f"wrote {C.display_path(out)}, {C.display_path(figure)}")


def worker(args):
    """``rve COUNT DIR`` or ``run CELLS PACKING DIR`` (CELLS "-": the example's mesh)."""
    if args[0] == "rve":
        r = rve_test(int(args[1]), Path(args[2]))
    else:
        cells = None if args[1] == "-" else [int(c) for c in args[1].split("x")]
        r = run_sample(cells, args[2], Path(args[3]))
    if r is not None:
        C.emit_result(r)


if __name__ == "__main__":
    C.entry(main, worker)
