"""What a contact law called from the loops, not inlined, costs its own scenes.

A law's force kernel is inlined into the time loops (``@kernel(inline=True)``: linear,
Hertz-Mindlin) or compiled once and called (``hertz_sjkr``), so that it does not slow
the cold compile of every other law's loops (``dem.contact.laws.dispatch``). This
times the two on one scene: 4,096 spheres of 1 mm settled under gravity in a box of
five planes, Hertz-Mindlin (inlined) against Hertz-Mindlin with simplified JKR
cohesion at zero cohesion (called), which is the same law: the two runs end with the
same positions, bit for bit, and the script checks it. Each law runs in its own
process (one thread), the two in turn, ``RUNS`` times; each run settles ``SETTLE``
steps, then times ``REPS`` chunks of ``CHUNK`` steps (median). A third row, the
cohesive law at 3e4 J/m^3, is timed for reference.

usage::

    python benchmarks/law_call.py

Writes ``benchmarks/results/law_call.json``: ``s_per_chunk.<case>`` (medians over the
runs) and ``called_over_inlined``, the median of the runs' time ratios. About two
minutes; keep the cores quiet.
"""

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

OUT = C.RESULTS / "law_call.json"
SETTLE = C.env_int("SETTLE", 20000)
CHUNK = C.env_int("CHUNK", 2000)
REPS = C.env_int("REPS", 5)
RUNS = C.env_int("RUNS", 3)
R = 1e-3  # [m]
#: case -> (law, cohesion [J/m^3])
CASES = {"inlined": ("hertz_mindlin", None), "called": ("hertz_sjkr", 0.0),
         "called_cohesive": ("hertz_sjkr", 3e4)}


def scene(name, cohesion):
    """16^3 spheres on a jittered lattice in a box open at the top, gravity down."""
    import math

    import numpy as np

    import dem
    from dem.contact.laws import LAWS

    n = 16
    grid = np.stack(np.meshgrid(*(np.arange(n),) * 3, indexing="ij"), -1).reshape(-1, 3)
    rng = np.random.default_rng(1)
    pos = grid * 2.05 * R + 1.1 * R + rng.uniform(-0.02, 0.02, grid.shape) * R
    bodies = dem.Bodies.spheres(pos, radius=R * rng.uniform(0.95, 1.0, len(pos)),
                                density=2500.0)
    side = n * 2.05 * R + 0.2 * R
    for a in range(3):
        normal = np.eye(3)[a]
        bodies.add_plane(np.zeros(3), normal)
        if a < 2:
            bodies.add_plane(side * normal, -normal)
    extra = {} if cohesion is None else {"cohesion": cohesion}

    def law(young):
        return LAWS[name](young=young, poisson=0.25, restitution=0.5, mu=0.3, **extra)

    model = dem.ContactModel(law(1e7), wall_law=law((1e7, math.inf)))
    return dem.Simulation(bodies, model, gravity=[0.0, 0.0, -9.81])


def worker(args):
    import hashlib

    name, cohesion = args[0], (None if args[1] == "none" else float(args[1]))
    sim = scene(name, cohesion)
    sim.run(SETTLE)
    times = []
    for _ in range(REPS):
        t0 = time.perf_counter()
        sim.run(CHUNK)
        times.append(time.perf_counter() - t0)
    C.emit_result({"s_per_chunk": C.median(times), "spheres": int(sim.bodies.n),
                   "positions_sha1": hashlib.sha1(sim.bodies.pos.tobytes()).hexdigest()})


def main():
    out = {"date": C.now(), "machine": C.machine_info(), "revision": C.git_revision(),
           "loadavg": C.loadavg(), "settle_steps": SETTLE, "chunk": CHUNK, "reps": REPS,
           "runs": RUNS, "cases": {k: {"law": v[0], "cohesion": v[1]} for k, v in
                                   CASES.items()},
           "runs_s_per_chunk": {case: [] for case in CASES}}
    digests = {}
    for run in range(RUNS):  # the cases alternate, run after run
        for case, (name, cohesion) in CASES.items():
            r = C.run_worker(Path(__file__), [name, "none" if cohesion is None else cohesion],
                             1)
            if not r["ok"]:
                raise SystemExit(f"{case}: {r['error']}")
            out["runs_s_per_chunk"][case].append(r["s_per_chunk"])
            out["spheres"] = r["spheres"]
            digests.setdefault(case, set()).add(r["positions_sha1"])
            print(f"run {run + 1}, {case}: {r['s_per_chunk']:.3f} s per {CHUNK} steps",
                  flush=True)
    if digests["inlined"] != digests["called"]:
        raise SystemExit("the called law at zero cohesion did not end where Hertz-Mindlin "
                         "did: the comparison is not of one scene")
    per = out["runs_s_per_chunk"]
    out["s_per_chunk"] = {case: C.median(ts) for case, ts in per.items()}
    out["called_over_inlined"] = C.median(
        [a / b for a, b in zip(per["called"], per["inlined"], strict=True)])
    out["same_positions"] = True
    out["load_after"] = C.loadavg()
    print(f"called / inlined (median of {RUNS} runs): {out['called_over_inlined']:.3f}")
    C.write_json(OUT, out)


if __name__ == "__main__":
    C.entry(main, worker)
