"""Biot's u-p solver against closed forms: Terzaghi's column and Mandel's problem.

Terzaghi: a laterally confined column of height 1 m (quad8 / quad1, 1 x 16 cells),
drained at the top, loaded there at once by 10 kPa, linear-elastic micro models
(E = 10 MPa, nu = 0.25), incompressible constituents, c_v = 1 m^2/s. The nodal pore
pressures along the column against the series solution at Tv = 0.05, 0.2, 0.5 and 1
(400 equal steps to Tv = 1), as the largest error over the column relative to the
load (``terzaghi_max_error``, the bar: 1 %); the error at Tv = 0.2 for 10, 20, 40 and
80 equal steps (1 x 32 cells) and its observed order (``time_order``, backward
Euler: 1); the first step at Vermeer and Verruijt's bound ``h^2 / (6 c_v)`` and at
half of it, the pressure's overshoot above the load (``first_step_overshoot``).

Mandel: a quarter of a 2 x 1 m specimen (quad8 / quad1, 16 x 2 cells), rigid
frictionless plates (a ``[[platen]]``) carrying 2 x 10 kN/m, drained traction-free
sides, K_f = 40 MPa and porosity 0.4 (nu_u = 0.48, B = 0.94): the centre's pressure
over time against the closed form (``mandel_max_error``, relative to its initial
value p0; the bar: 2 %) and the peak of the Mandel-Cryer effect
(``mandel_peak``, numeric and exact).

Writes benchmarks/results/porous_verification.json and
docs/figures/porous_verification.png. No peers: the closed forms are the reference
(hmm.poroelastic_solutions). Runs in about 15 s.
"""

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "porous_verification.json"
FIGURE = C.REPO / "docs" / "figures" / "porous_verification.png"
E, NU, Q, H, CV = 1e7, 0.25, 1e4, 1.0, 1.0
TVS = (0.05, 0.2, 0.5, 1.0)


def _solver(macro, porous, dofs, schedule, force, ties=()):
    import numpy as np

    from hmm.coupling import SolverSettings, Supports
    from hmm.farm import SerialFarm
    from hmm.micro import LinearElastic
    from hmm.porous import BiotSolver

    farm = SerialFarm([LinearElastic(E, NU) for _ in range(macro.n_gp)])
    return BiotSolver(porous, farm, Supports(dofs, np.zeros(dofs.size), ties=ties),
                      schedule, f_ramp=force, settings=SolverSettings(aitken=False))


def terzaghi_run(cells, schedule, stops):
    """Nodal pressures along the column at the times ``stops`` [s]: {t: (depth, p)}."""
    import numpy as np

    from hmm.macro import Macro, structured_mesh
    from hmm.porous import Fluid, PorousMacro

    macro = Macro(structured_mesh("quad8", [0.1, H], [1, cells]), "quad8", "small")
    m_c = E * (1 - NU) / ((1 + NU) * (1 - 2 * NU))
    porous = PorousMacro(macro, Fluid(permeability=CV / m_c * 1e-3, bulk_modulus=np.inf),
                         drained={"top": 0.0})
    dofs = np.unique(np.concatenate([macro.dofs("bottom", 1), macro.dofs("left", 0),
                                     macro.dofs("right", 0)]))
    s = _solver(macro, porous, dofs, schedule, macro.pressure_force("top", Q))
    on = np.isclose(macro.mesh.p[0], 0.0)
    order = np.argsort(-macro.mesh.p[1][on])
    depth = (H - macro.mesh.p[1][on])[order]
    out = {}
    for t in schedule.times():
        s.advance(t - s.t)
        for want in stops:
            if np.isclose(s.t, want):
                out[want] = (depth, porous.nodal_pressure(s.p)[on][order])
    return out, m_c


def terzaghi():
    import numpy as np

    from hmm import poroelastic_solutions as exact
    from hmm.porous import TimeSchedule

    t0 = time.perf_counter()
    got, m_c = terzaghi_run(16, TimeSchedule(end=1.0, steps=400), TVS)
    wall = time.perf_counter() - t0
    mat = exact.BiotMaterial.from_young(E, NU, mobility=CV / m_c)
    curves, errors = {}, {}
    for tv in TVS:
        depth, p = got[tv]
        ref = exact.terzaghi_pressure(depth, tv, H, mat, Q)
        errors[str(tv)] = float(np.abs(p - ref).max() / Q)
        curves[str(tv)] = {"depth": depth.tolist(), "p": p.tolist()}
    conv = []
    for steps in (10, 20, 40, 80):
        g, _ = terzaghi_run(32, TimeSchedule(end=0.2, steps=steps), (0.2,))
        depth, p = g[0.2]
        conv.append(float(np.abs(p - exact.terzaghi_pressure(depth, 0.2, H, mat, Q)).max()
                          / Q))
    order = [float(np.log2(a / b)) for a, b in zip(conv[:-1], conv[1:], strict=True)]
    overshoot = {}
    for f in (1.0, 0.5):
        dt = f * (H / 16) ** 2 / (6 * CV)
        g, _ = terzaghi_run(16, TimeSchedule(end=dt, steps=1), (dt,))
        overshoot[str(f)] = float(g[dt][1].max() / Q - 1.0)
    return {"terzaghi_max_error": errors, "terzaghi_wall_seconds": wall,
            "terzaghi_curves": curves, "time_steps": [10, 20, 40, 80],
            "time_errors": conv, "time_order": order,
            "first_step_overshoot": overshoot}


def mandel():
    import numpy as np

    from hmm import poroelastic_solutions as exact
    from hmm.macro import Macro, structured_mesh
    from hmm.porous import Fluid, PorousMacro, TimeSchedule

    a, b, force = 1.0, 0.5, 1e4
    macro = Macro(structured_mesh("quad8", [a, b], [16, 2]), "quad8", "small")
    fluid = Fluid(permeability=1e-10, bulk_modulus=4e7, porosity=0.4)
    porous = PorousMacro(macro, fluid, drained={"right": 0.0})
    mat = exact.BiotMaterial.from_young(E, NU, storage_modulus=1 / fluid.storage,
                                        mobility=1e-7)
    end = 2.0 * a * a / mat.consolidation_coefficient_mandel
    dofs = np.unique(np.concatenate([macro.dofs("left", 0), macro.dofs("bottom", 1)]))
    s = _solver(macro, porous, dofs, TimeSchedule(end=end, steps=100, first=5e-4 * end),
                macro.pressure_force("top", force / a), ties=(macro.dofs("top", 1),))
    p0 = exact.mandel_initial_pressure(a, force, mat)
    centre = int(np.flatnonzero(np.isclose(macro.mesh.p[0], 0)
                                & np.isclose(macro.mesh.p[1], 0))[0])
    t0 = time.perf_counter()
    times, got, want = [], [], []
    for t in s.schedule.times():
        s.advance(t - s.t)
        times.append(s.t)
        got.append(float(porous.nodal_pressure(s.p)[centre] / p0))
        want.append(float(exact.mandel_pressure(np.zeros(1), s.t, a, force, mat)[0] / p0))
    return {"mandel_max_error": float(np.abs(np.array(got) - want).max()),
            "mandel_peak": {"ours": max(got),
                            "exact": exact.mandel_cryer_peak(a, force, mat)},
            "mandel_wall_seconds": time.perf_counter() - t0,
            "mandel_material": {"undrained_poisson": mat.undrained_poisson,
                                "skempton": mat.skempton,
                                "consolidation_coefficient":
                                    mat.consolidation_coefficient_mandel},
            "mandel_curve": {"time_factor": (np.array(times)
                                             * mat.consolidation_coefficient_mandel
                                             / a**2).tolist(),
                             "ours": got, "exact": want}}


def figure(res):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker
    import numpy as np

    from dem.io.hdf5 import save_figure
    from hmm import poroelastic_solutions as exact

    fig, axs = plt.subplots(1, 3, figsize=(13, 4))
    ax = axs[0]
    m_c = E * (1 - NU) / ((1 + NU) * (1 - 2 * NU))
    mat = exact.BiotMaterial.from_young(E, NU, mobility=CV / m_c)
    z = np.linspace(0, H, 200)
    for tv, c in res["terzaghi_curves"].items():
        line, = ax.plot(exact.terzaghi_pressure(z, float(tv), H, mat, Q) / Q, z, "-",
                        lw=1)
        ax.plot(np.array(c["p"]) / Q, c["depth"], "o", ms=3, color=line.get_color(),
                label=f"Tv = {tv}")
    ax.invert_yaxis()
    ax.set_xlabel("pore pressure / load [-]")
    ax.set_ylabel("depth below the drained top [m]")
    ax.set_title("(a) Terzaghi: nodes (dots), series (lines)", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax = axs[1]
    ax.loglog(res["time_steps"], res["time_errors"], "o-", label="ours, Tv = 0.2")
    ref = res["time_errors"][0] * 10 / np.array(res["time_steps"])
    ax.loglog(res["time_steps"], ref, "k--", lw=0.8, label="order 1")
    ax.set_xticks(res["time_steps"], [str(n) for n in res["time_steps"]])
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xlabel("time steps to Tv = 0.2")
    ax.set_ylabel("largest error / load [-]")
    ax.set_title("(b) backward Euler in time", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    ax = axs[2]
    c = res["mandel_curve"]
    ax.semilogx(c["time_factor"], c["exact"], "k-", lw=1, label="closed form")
    ax.semilogx(c["time_factor"], c["ours"], "o", ms=3, label="ours (centre node)")
    ax.axhline(1.0, color="grey", lw=0.6)
    ax.set_xlabel("c t / a^2 [-]")
    ax.set_ylabel("p(centre) / p0 [-]")
    ax.set_title(f"(c) Mandel-Cryer: peak {res['mandel_peak']['ours']:.3f} "
                 f"(exact {res['mandel_peak']['exact']:.3f})", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, FIGURE)
    plt.close(fig)


def main():
    res = {"benchmark": "porous_verification", "date": C.now(),
           "machine": C.machine_info(), "versions": C.our_versions()}
    res.update(terzaghi())
    res.update(mandel())
    res["status"] = "ok" if (max(res["terzaghi_max_error"].values()) < 0.01
                             and res["mandel_max_error"] < 0.02) else "bar missed"
    C.write_json(OUT, res)
    figure(res)
    print(f"Terzaghi: largest error / load {max(res['terzaghi_max_error'].values()):.4f} "
          f"(Tv {', '.join(res['terzaghi_max_error'])}); time order "
          f"{', '.join(f'{o:.2f}' for o in res['time_order'])}; first step overshoot "
          f"{res['first_step_overshoot']['1.0']:.2e} at the bound, "
          f"{res['first_step_overshoot']['0.5']:.3f} at half of it")
    print(f"Mandel: largest error / p0 {res['mandel_max_error']:.4f}, peak "
          f"{res['mandel_peak']['ours']:.4f} (exact {res['mandel_peak']['exact']:.4f})")
    print(f"wrote {C.display_path(OUT)} and {C.display_path(FIGURE)}")


if __name__ == "__main__":
    main()
