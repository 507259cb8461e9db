"""Where a quasi-static cell stops relaxing: the time step of a close-packed box RVE.

The hexagonal close packing of ``examples/ex05_box_vs_periodic.py`` in its box of
smooth walls (:class:`dem.rve_box.BoxRVE`, Cundall local damping 0.5) takes three
oedometric increments of 0.2 % at time steps of ``FACTORS`` x dt_crit, with the paper's
viscoelastic law (dashpots: two-body damping ratio 0.73) and with the same springs
without dashpots. Each increment must relax to an unbalanced-force ratio of 1e-3
within ``CAP`` steps; a step past the stability line of the packing's stiffest mode
leaves it ringing and the increment ends in :class:`dem.rve.RelaxationError` (or, further
out, blows up: :class:`dem.SimulationError`).
Reported per law and step: the steps of each increment, or the failure; and the RVE's
default step (``dem.timestep.quasi_static_dt``) for comparison. This is the measurement
behind ``dem.timestep.QUASI_STATIC_FACTOR`` (docs/stability.md).

usage::

    python benchmarks/rve_step_limit.py   # writes benchmarks/results/rve_step_limit.json

environment: SIZES ("small full": 8 x 8 x 6 and 16 x 16 x 12 spheres), FACTORS
("0.05 0.07 0.085 0.093 0.1 0.15 0.2 0.3 0.4"), CAP (20000).
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "rve_step_limit.json"
GRID = {"small": (8, 8, 6), "full": (16, 16, 12)}
INCREMENTS = 3


def measure(size, factors, cap):
    import numpy as np

    import dem
    from dem.io.packing import hcp_layers
    from dem.rve import RelaxationError
    from dem.timestep import quasi_static_dt
    from dem.simulation import SimulationError
    from dem.rve_box import BoxRVE

    r = 0.5
    laws = {"viscoelastic": dem.Viscoelastic(kn=20.0, kt=10.0, gamma_n=0.08,
                                             gamma_t=0.04, mu=0.3),
            "elastic": dem.Elastic(kn=20.0, kt=10.0, mu=0.3)}
    n = GRID[size]
    pos = hcp_layers(*n, r)
    hi = np.array([n[0] * 2.0 * r + r, pos[:, 1].max() + r, pos[:, 2].max() + r])
    deps = np.diag([0.0, 0.0, -2e-3])
    rows = []
    for name, law in laws.items():
        def box(dt=None, law=law):
            return BoxRVE(dem.Bodies.spheres(pos, radius=r, density=1e-3), law,
                          lo=[0.0, 0.0, 0.0], hi=hi, damping=0.5, dt=dt,
                          max_relax_steps=cap)

        probe = box()
        dt_crit = probe.sim.dt_crit
        default = probe.sim.dt / dt_crit
        for f in factors:
            b = box(f * dt_crit) if f * dt_crit <= probe.sim.dt_stable else None
            if b is None:  # refused: run it anyway, the refusal is what is measured
                b = BoxRVE(dem.Bodies.spheres(pos, radius=r, density=1e-3), law,
                           lo=[0.0, 0.0, 0.0], hi=hi, damping=0.5, dt=None,
                           max_relax_steps=cap)
                b.sim.dt = f * dt_crit
            steps, failed = [], None
            for _ in range(INCREMENTS):
                try:
                    b.apply_strain(deps)
                    steps.append(b.last_relax_steps)
                except RelaxationError as err:
                    failed = "did not relax: " + str(err).split(";")[0]
                    break
                except SimulationError as err:
                    failed = "blew up: " + str(err).split(":")[0]
                    break
            rows.append({"size": size, "spheres": int(np.prod(n)), "law": name,
                         "factor": f, "steps": steps, "relaxed": failed is None,
                         "failure": failed,
                         "refused": bool(f * dt_crit > probe.sim.dt_stable),
                         "damping_ratio": probe.sim.damping_ratio,
                         "default_factor": default,
                         "stable_factor": probe.sim.dt_stable / dt_crit,
                         "default_formula": quasi_static_dt(probe.bodies, probe.sim.model,
                                                            None, 0.5) / dt_crit})
            print(f"{size} ({int(np.prod(n))}), {name}, dt = {f:g} dt_crit: "
                  + (f"relaxed in {steps} steps" if failed is None else "FAILED")
                  + f" (RVE default {default:.3f})", flush=True)
    return rows


def main():
    sizes = C.env_list("SIZES", "small full")
    factors = [float(x) for x in
               C.env_list("FACTORS", "0.05 0.07 0.085 0.093 0.1 0.15 0.2 0.3 0.4")]
    cap = C.env_int("CAP", 20000)
    rows = []
    for size in sizes:
        res = C.run_worker(__file__, ["measure", size, cap, *factors], threads=1,
                           timeout=7200)
        if not res.get("ok"):
            raise RuntimeError(f"{size}: {res['error']}")
        rows += res["rows"]
    C.write_json(OUT, {"benchmark": "rve_step_limit", "date": C.now(),
                       "machine": C.machine_info(), "versions": C.our_versions(),
                       "revision": C.git_revision(), "loadavg": C.loadavg(),
                       "increments": INCREMENTS, "cap": cap, "rows": rows})


def worker(args):
    size, cap, factors = args[1], int(args[2]), [float(x) for x in args[3:]]
    C.emit_result({"rows": measure(size, factors, cap)})


if __name__ == "__main__":
    C.entry(main, worker)
