"""Cost of one Gauss-point call: a periodic RVE takes a strain increment, relaxes, and
returns its stress and tangent.

The packing: 400 disks (2D; radii uniform in 0.8-1.2 mm, linear springs kn = 1e8 N/m,
kt = 5e7 N/m, friction 0.5, consolidated frictionless to 100 kPa), or 1,000 spheres (3D,
kn = 1e5 N/m). From the same committed state, each call restores it, applies an axial
strain increment of 1e-4 (100 steps at the default cap of 1e-5 per step), relaxes to an
unbalanced-force ratio of 1e-3 and computes the contact tangent (eq 29) -- what
``hmm.micro.DEMMicroModel.trial`` does. Reported: median wall time per call over REPS
calls, the DEM steps per call, and the stepping rate (particle-steps per second of the
deforming-cell loop on one thread) measured on a plain run of the same packing. Also
timed from the same state: one increment of a drained test (``drained_*``: an axial
strain of 1e-3 with the lateral stresses held at 100 kPa by the servo, as ``hmm rve``
runs it). ``*_outside_steps`` is a call's time less its steps at the plain stepping
rate: what the call spends outside the step loop.

usage::

    python benchmarks/rve_call.py            # writes benchmarks/results/rve_call.json

environment: REPS (20), DIMS ("2 3").
"""

import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "rve_call.json"


def measure(dim, reps):
    import numpy as np

    import dem
    from dem import rve

    n = 400 if dim == 2 else 1000
    kn = 1e8 if dim == 2 else 1e5
    law = dem.LinearSpring(kn=kn, kt=0.5 * kn, mu=0.5)
    t0 = time.perf_counter()
    r = rve.generate(dim, n, (0.8e-3, 1.2e-3), law, p0=1e5, friction=0.0, seed=1)
    t_gen = time.perf_counter() - t0
    snap = r.snapshot()

    def calls(strain, relax):
        deps = np.zeros((dim, dim))
        deps[-1, -1] = -strain
        return C.time_rve_calls(r, snap, deps, reps, relax=relax)

    times, steps = calls(1e-4, True)
    times_unrelaxed, steps_unrelaxed = calls(1e-3, False)
    times_drained, steps_drained = drained(r, snap, reps)
    r.restore(snap)
    n_steps = 2000
    t0 = time.perf_counter()
    r.sim.run(n_steps, progress=False)
    t_run = time.perf_counter() - t0
    step = t_run / n_steps
    return {"dim": dim, "particles": n, "generation_time": t_gen,
            "call_time": C.median(times), "call_times": times,
            "steps_per_call": steps,
            "outside_steps": C.median(times) - steps * step,
            "unrelaxed_call_time": C.median(times_unrelaxed),
            "unrelaxed_steps_per_call": steps_unrelaxed,
            "unrelaxed_outside_steps": C.median(times_unrelaxed) - steps_unrelaxed * step,
            "drained_call_time": C.median(times_drained),
            "drained_steps_per_call": steps_drained,
            "drained_outside_steps": C.median(times_drained) - steps_drained * step,
            "particle_steps_per_s": n * n_steps / t_run,
            "step_time": step}


def drained(r, snap, reps):
    """``reps`` increments of a drained test, each from ``snap``: an axial strain of
    1e-3 with every lateral stress held at 100 kPa by the servo (``RVE.load`` with a
    stress target, as ``hmm rve`` runs a biaxial or triaxial test), after one warm-up.
    Their wall times [s] and the median of their DEM steps."""
    import numpy as np

    d = r.dim
    deps = np.zeros((d, d))
    deps[-1, -1] = -1e-3
    mask = [True] * (d - 1) + [False]
    target = [-1e5] * (d - 1) + [0.0]
    times, steps = [], []
    for _ in range(reps + 1):
        r.restore(snap)
        s0 = r.sim.step
        t0 = time.perf_counter()
        r.load(deps, stress=target, mask=mask)
        times.append(time.perf_counter() - t0)
        steps.append(r.sim.step - s0)
    r.restore(snap)
    return times[1:], C.median(steps[1:])


def main():
    reps = C.env_int("REPS", 20)
    dims = [int(x) for x in C.env_list("DIMS", "2 3")]
    rows = [measure(d, reps) for d in dims]
    data = {"benchmark": "rve_call", "date": C.now(), "machine": C.machine_info(),
            "versions": C.our_versions(), "revision": C.git_revision(),
            "loadavg": C.loadavg(), "reps": reps, "rows": rows}
    C.write_json(OUT, data)
    for r in rows:
        print(f"{r['dim']}D, {r['particles']} particles: call {1e3 * r['call_time']:.2f} ms "
              f"({r['steps_per_call']:.0f} steps, {1e3 * r['outside_steps']:.2f} ms outside "
              f"them); unrelaxed call of 1e-3 {1e3 * r['unrelaxed_call_time']:.2f} ms "
              f"({r['unrelaxed_steps_per_call']:.0f} steps, "
              f"{1e3 * r['unrelaxed_outside_steps']:.2f} ms outside them); drained "
              f"increment of 1e-3 {1e3 * r['drained_call_time']:.1f} ms "
              f"({r['drained_steps_per_call']:.0f} steps, "
              f"{1e3 * r['drained_outside_steps']:.2f} ms outside them); stepping "
              f"{r['particle_steps_per_s'] / 1e6:.2f} M particle-steps/s "
              f"({1e6 * r['step_time']:.0f} us per step); packing made in "
              f"{r['generation_time']:.1f} s")


if __name__ == "__main__":
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    main()
