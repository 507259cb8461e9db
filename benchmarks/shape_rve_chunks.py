"""What a polygon RVE's call spends outside its compiled stepping.

The sphere RVE's relaxation and servo checks run inside the compiled step loop; the
loop of level-set shapes runs in chunks, with the same check made from Python between
them (``dem.rve_servo``). This measures what that costs: a periodic RVE of ``N``
(default 100) pentagons and hexagons, consolidated to 100 kPa (the packing of the
polygon tests, ``tests/dem/test_rve.py``, at ``N``), then from the same saved state

- a Gauss point's call: an axial strain increment of 1e-4, the relaxation and the
  contact tangent (``RVE.apply_strain(deps, tangent=True)``);
- a drained increment: 1e-3 of axial strain with the lateral stress servoed at
  100 kPa (``RVE.load``);

each ``REPS`` (default 5) times, one thread. Each call's wall time is split into the
time spent inside the step loop's calls (``Simulation.run``, its own Python entry
included) and the rest: the checks between chunks, with their measures, and the final
measure. A third figure is the Python entry cost of one call of the shape loop (50
calls of one step against one call of 50). Compiling the checks into the shape loop
would save at most the entry costs and the checks' Python, not their measures.

usage::

    python benchmarks/shape_rve_chunks.py

Writes ``benchmarks/results/shape_rve_chunks.json`` (``calls.<case>``: medians of the
wall time, the time in the loop, the steps, the loop calls and ``outside_share``;
``loop_entry_s``). About a minute and a half with warm kernels; keep the cores quiet.
"""

import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

os.environ.update(C.worker_env(1))  # one thread, set before numba is imported

OUT = C.RESULTS / "shape_rve_chunks.json"


def _polygon(r, rng):
    from dem.shapes import ConvexPolygon

    return ConvexPolygon.regular(5 + int(rng.integers(2)), r)


def _timed(sim):
    """Wrap ``sim.run`` to add its wall time, calls and steps to the returned dict."""
    inner, spent = sim.run, {}

    def run(n_steps, progress=None):
        t, s0 = time.perf_counter(), sim.step
        try:
            return inner(n_steps, progress=progress)
        finally:
            spent["loop_s"] += time.perf_counter() - t
            spent["loop_calls"] += 1
            spent["steps"] += sim.step - s0

    sim.run = run
    return inner, spent


def _entry_cost(rve, snap, inner, reps):
    """Seconds of the Python entry of one call of the loop (median over ``reps``)."""
    costs = []
    for _ in range(reps):
        rve.restore(snap)
        t = time.perf_counter()
        for _ in range(50):
            inner(1)
        apart = time.perf_counter() - t
        rve.restore(snap)
        t = time.perf_counter()
        inner(50)
        costs.append((apart - (time.perf_counter() - t)) / 49)
    return C.median(costs)


def main():
    import dem
    from dem import rve as rve_mod

    n, reps = C.env_int("N", 100), C.env_int("REPS", 5)
    law = dem.LinearSpring(kn=1e8, kt=5e7, mu=0.5)
    rve = rve_mod.generate(2, n, (0.8e-3, 1.2e-3), law, p0=1e5, seed=6, damping=0.5,
                           shape=_polygon)
    snap = rve.snapshot()
    inner, spent = _timed(rve.sim)
    lateral = np.array([[False, False], [False, True]])
    cases = {
        "strain_1e-4_tangent": lambda: rve.apply_strain(np.diag([-1e-4, 0.0]),
                                                        tangent=True),
        "drained_1e-3": lambda: rve.load(np.diag([-1e-3, 0.0]), np.diag([0.0, -1e5]),
                                         lateral),
    }
    calls = {}
    for name, call in cases.items():
        rows = []
        for _ in range(reps):
            rve.restore(snap)
            spent.update(loop_s=0.0, loop_calls=0, steps=0)
            t = time.perf_counter()
            call()
            rows.append({"wall_s": time.perf_counter() - t, **spent})
        rows.sort(key=lambda r: r["wall_s"])
        row = rows[len(rows) // 2]
        row["outside_share"] = 1.0 - row["loop_s"] / row["wall_s"]
        calls[name] = row
        print(f"{name}: {row['wall_s'] * 1e3:.1f} ms, {row['steps']} steps in "
              f"{row['loop_calls']} loop calls ({row['loop_s'] * 1e3:.1f} ms), outside "
              f"the loop {100 * row['outside_share']:.1f} %", flush=True)
    rve.sim.run = inner
    entry = _entry_cost(rve, snap, inner, reps)
    print(f"Python entry of one call of the shape loop: {entry * 1e3:.3f} ms", flush=True)
    C.write_json(OUT, {"benchmark": "shape_rve_chunks", "date": C.now(),
                       "machine": C.machine_info(), "revision": C.git_revision(),
                       "loadavg": C.loadavg(), "polygons": n, "reps": reps,
                       "calls": calls, "loop_entry_s": entry})


if __name__ == "__main__":
    main()
