"""Oblique impacts of a sphere on a rigid plane: friction with damped contacts.

A sphere (R = 1 cm, 2500 kg/m^3, 1 m/s, no spin) hits the plane z = 0 at 5 to 85 deg
from the normal, for restitution e from 0.3 to 0.98 and friction mu from 0.1 to 0.5,
with Hertz-Mindlin and with a linear law carrying a tangential dashpot. In gross
sliding (tan(angle) > 3.5 mu (1 + e), with a 5 % margin: the slip outlasts the
contact) the tangential
impulse must be mu times the normal one and the rebound spin ``2.5 mu (1 + e) v_n / R``.

Two normal impulses are reported: the whole change of normal momentum, and its
compressive part (the repulsive normal forces summed over the steps), which is what a
Coulomb slider works with; the difference is the pull of the normal dashpot at the end
of a low-restitution contact. Every case runs twice: with the normal force as the laws
give it, and with ``limit_damping`` (the force clipped at zero, the damping remapped so
the rebound keeps e), where the two impulses are one. Writes
benchmarks/results/oblique_impact.json (keys ``max_deviation_compressive``,
``max_deviation_total``, ``max_spin_deviation``, ``max_restitution_deviation`` over the
gross-sliding cases without the clip, the same under ``limit_damping``, and every
case) and docs/figures/oblique_impact.png.
Run: python benchmarks/oblique_impact.py (``--figure`` redraws the figure from the JSON)
"""

import itertools
import math
import sys
import time
from pathlib import Path

import numpy as np

import dem
from dem.io.hdf5 import save_figure

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

R, RHO, SPEED = 0.01, 2500.0, 1.0
OUT = C.RESULTS / "oblique_impact.json"
PNG = C.REPO / "docs" / "figures" / "oblique_impact.png"
ANGLES = [5.0, 15.0, 25.0, 35.0, 45.0, 55.0, 65.0, 70.0, 75.0, 80.0, 85.0]
RESTITUTIONS = [0.3, 0.5, 0.7, 0.9, 0.98]
FRICTIONS = [0.1, 0.3, 0.5]


def law(name, e, mu, limit=False):
    if name == "hertz_mindlin":
        return dem.HertzMindlin(young=7.0e10, poisson=0.3, restitution=e, mu=mu,
                                limit_damping=limit)
    kn, m = 1.0e6, RHO * 4.0 / 3.0 * math.pi * R**3
    return dem.LinearSpring(kn=kn, kt=2.0 / 7.0 * kn, mu=mu, restitution=e,
                            gamma_t=0.5 * math.sqrt(kn * m), limit_damping=limit)


def impact(contact_law, angle_deg):
    """(jn, jn_plus, jt [N s], spin [rad/s], vn before, vn after [m/s])."""
    b = dem.Bodies.empty(3)
    th = math.radians(angle_deg)
    b.add_spheres([[0.0, 0.0, R * 1.0001]], R, RHO,
                  vel=[[SPEED * math.sin(th), 0.0, -SPEED * math.cos(th)]])
    b.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    sim = dem.Simulation(b, contact_law, gravity=[0.0, 0.0, 0.0])
    v0, m = b.vel[0].copy(), b.mass[0]
    jn_plus = 0.0
    while not (b.pos[0, 2] > R and b.vel[0, 2] > 0.0):
        sim.run(1, progress=False)
        jn_plus += max(b.force[0, 2], 0.0) * sim.dt
    dv = b.vel[0] - v0
    return m * dv[2], jn_plus, -m * dv[0], b.ang_vel[0, 1], -v0[2], b.vel[0, 2]


def summary(cases):
    """The largest deviations over the gross-sliding cases (restitution: every case)."""
    gross = [c for c in cases if c["gross_sliding"]]
    return {"n_gross_sliding": len(gross),
            "max_deviation_compressive": max(abs(c["ratio_compressive"] - 1) for c in gross),
            "max_deviation_total": max(abs(c["ratio_total"] - 1) for c in gross),
            "max_spin_deviation": max(abs(c["spin_ratio"] - 1) for c in gross),
            "max_restitution_deviation": max(abs(c["e_measured"] / c["e"] - 1)
                                             for c in cases)}


def main():
    cases = []
    t0 = time.perf_counter()
    for limit, name, e, mu, angle in itertools.product(
            (False, True), ("hertz_mindlin", "linear"), RESTITUTIONS, FRICTIONS, ANGLES):
        jn, jn_plus, jt, spin, vn, vn_after = impact(law(name, e, mu, limit), angle)
        cases.append({
            "law": name, "limit_damping": limit, "e": e, "mu": mu, "angle_deg": angle,
            "gross_sliding": math.tan(math.radians(angle)) > 3.5 * mu * (1.0 + e) * 1.05,
            "psi": math.tan(math.radians(angle)) / (mu * (1.0 + e)),
            "e_measured": vn_after / vn,
            "ratio_compressive": jt / (mu * jn_plus),
            "ratio_total": jt / (mu * jn),
            "spin_ratio": spin / (2.5 * mu * (1.0 + e) * vn / R)})
    plain = [c for c in cases if not c["limit_damping"]]
    data = {
        "machine": C.machine_info(), "software": C.our_versions(), "date": C.now(),
        "seconds": time.perf_counter() - t0, "n_cases": len(plain), **summary(plain),
        "limit_damping": summary([c for c in cases if c["limit_damping"]]),
        "cases": cases}
    C.write_json(OUT, data)
    save_figure(figure(cases), PNG, data=f"{OUT.name}")
    for label, table in (("normal force not clipped", data),
                         ("limit_damping", data["limit_damping"])):
        print(label)
        for k, v in table.items():
            if k.startswith(("n_gross", "max_")):
                print(f"  {k}: {v:.4g}" if isinstance(v, float) else f"  {k}: {v}")
    print(f"wrote {C.display_path(OUT)} and {C.display_path(PNG)}")


def figure(cases):
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, axes = plt.subplots(2, 2, figsize=(11.0, 7.6), sharey=True, sharex=True)
    colours = dict(zip(RESTITUTIONS, plt.cm.viridis(np.linspace(0.0, 0.9, 5)),
                       strict=True))
    for row, limit in enumerate((False, True)):
        for ax, name, title in zip(axes[row], ("hertz_mindlin", "linear"),
                                   ("Hertz-Mindlin", "linear, tangential dashpot"),
                                   strict=True):
            for e in RESTITUTIONS:
                rows = sorted((c for c in cases if c["law"] == name and c["e"] == e
                               and c.get("limit_damping", False) == limit),
                              key=lambda c: c["psi"])
                psi = [c["psi"] for c in rows]
                ax.plot(psi, [c["ratio_compressive"] for c in rows], "o", ms=4,
                        color=colours[e])
                ax.plot(psi, [c["ratio_total"] for c in rows], "x", ms=4,
                        color=colours[e])
            ax.axvline(3.5, color="k", ls=":", lw=1.0)
            ax.axhline(1.0, color="k", lw=0.8)
            ax.set_xscale("log")
            ax.set_title(f"{title}, " + ("limit_damping" if limit
                                         else "normal force not clipped"))
            if row == 1:
                ax.set_xlabel("tan(angle) / (mu (1 + e)) [-] (gross sliding right of 3.5)")
        axes[row, 0].set_ylabel("tangential / (mu x normal) impulse [-]")
    axes[0, 0].set_ylim(0.0, 1.25)
    handles = [Line2D([], [], ls="", marker="s", color=colours[e], label=f"e = {e}")
               for e in RESTITUTIONS]
    handles += [Line2D([], [], ls="", marker="o", color="k",
                       label="over the compressive normal impulse"),
                Line2D([], [], ls="", marker="x", color="k",
                       label="over the whole change of normal momentum")]
    fig.legend(handles=handles, loc="lower center", ncol=7, fontsize=8,
               bbox_to_anchor=(0.5, 0.0), handletextpad=0.3, columnspacing=1.2)
    fig.tight_layout(rect=(0.0, 0.05, 1.0, 1.0))
    return fig


if __name__ == "__main__":
    if "--figure" in sys.argv:  # redraw from the saved JSON
        import json

        save_figure(figure(json.loads(OUT.read_text())["cases"]), PNG, data=OUT.name)
    else:
        main()
