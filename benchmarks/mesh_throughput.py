"""Steps per second of a scene whose spheres press on a triangle-mesh wall.

The scene is the full-size bin of ``benchmarks/hopper_beverloo.py`` (2,744 spheres of
4 mm in a square bin of 16 d), its bottom closed: the spheres settle for ``SETTLE``
steps, then ``REPS`` chunks of ``CHUNK`` steps are timed on 1 and on 2 threads in
turn (the medians are kept). The spheres along the bin's bottom and sides have mesh
rows (about 1,400 sphere-face rows in all), so the sphere-mesh contacts are a large
part of a step.

``BASE=<git revision>`` times the engine at that revision too, on the same scene in
the same run (each code in its own process, the two in turn, ``RUNS`` times), and
reports the median of our ratios to it: how much a change to the engine bought or cost
on mesh scenes. The medians are kept because single runs here scatter by up to a
third.

usage::

    BASE=7fd19e3 python benchmarks/mesh_throughput.py

Writes ``benchmarks/results/mesh_throughput.json``: ``steps_per_s.<code>.<threads>``
(medians over the runs; each run's in ``runs_steps_per_s``) and, with ``BASE``,
``speedup_vs_base.<threads>``. About a minute per run; keep the cores quiet.
"""

import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

OUT = C.RESULTS / "mesh_throughput.json"
SETTLE = C.env_int("SETTLE", 20000)
CHUNK = C.env_int("CHUNK", 1000)
REPS = C.env_int("REPS", 7)
RUNS = C.env_int("RUNS", 3)
THREADS = (1, 2)


def closed_bin(side, height):
    """(vertices, faces) of a square bin [-side/2, side/2]^2 x [0, height] with a
    closed bottom, open at the top."""
    import numpy as np

    s = 0.5 * side
    ring = [[-s, -s], [s, -s], [s, s], [-s, s]]
    v = [[x, y, 0.0] for x, y in ring] + [[x, y, height] for x, y in ring]
    faces = [[0, 1, 2], [0, 2, 3]]
    for k in range(4):
        n = (k + 1) % 4
        faces += [[k, 4 + k, 4 + n], [k, 4 + n, n]]
    return np.array(v), np.array(faces)


def scene():
    """The Beverloo benchmark's bin at full size, its bottom closed (a dem.Simulation)."""
    import numpy as np

    import dem
    import hopper_beverloo as hb

    side = 16.0 * hb.D_SPHERE
    v, f = closed_bin(side, 16 * 1.1 * hb.D_SPHERE)
    return hb.filled_bin(dem.MeshWall(v, f), side, 14, np.random.default_rng(1))[0]


def worker(args):
    sim = scene()
    sim.run(SETTLE)
    times = {t: [] for t in THREADS}
    for t in THREADS:  # warm
        sim.threads = t  # the simulation's own setting: 1 runs the one-thread loop
        sim.run(CHUNK)
    for _ in range(REPS):  # the thread counts alternate, so that both see the same bed
        for t in THREADS:
            sim.threads = t
            t0 = time.perf_counter()
            sim.run(CHUNK)
            times[t].append(time.perf_counter() - t0)
    rates = {str(t): CHUNK / C.median(ts) for t, ts in times.items()}
    C.emit_result({"spheres": int(sim.bodies.n), "steps_per_s": rates,
                   "mesh_rows": int(sim.mesh_state.mrows.shape[0])})


def main():
    codes = {"dem": None}
    base = os.environ.get("BASE", "").strip()
    if base:
        codes["dem_base"] = C.source_tree(base)
    out = {"date": C.now(), "machine": C.machine_info(), "revision": C.git_revision(),
           "base": base or None, "settle_steps": SETTLE, "chunk": CHUNK, "reps": REPS,
           "runs": RUNS, "runs_steps_per_s": {code: [] for code in codes}}
    for run in range(RUNS):  # the codes alternate, run after run
        for code, tree in codes.items():
            r = C.run_worker(Path(__file__), [], max(THREADS), tree=tree)
            if not r["ok"]:
                raise SystemExit(f"{code}: {r['error']}")
            out["runs_steps_per_s"][code].append(r["steps_per_s"])
            out["spheres"], out["mesh_rows"] = r["spheres"], r["mesh_rows"]
            print(f"run {run + 1}, {code}: " + ", ".join(
                f"{t} thread(s) {s:.0f} steps/s" for t, s in r["steps_per_s"].items()),
                flush=True)
    per = out["runs_steps_per_s"]
    out["steps_per_s"] = {code: {str(t): C.median([x[str(t)] for x in runs])
                                 for t in THREADS} for code, runs in per.items()}
    if base:
        out["speedup_vs_base"] = {str(t): C.median(
            [a[str(t)] / b[str(t)] for a, b in zip(per["dem"], per["dem_base"], strict=True)])
            for t in THREADS}
        print(f"speedup vs {base} (median of {RUNS} runs): " + ", ".join(
            f"{t} thread(s) {s:.2f}" for t, s in out["speedup_vs_base"].items()))
    out["load_after"] = C.loadavg()
    C.write_json(OUT, out)


if __name__ == "__main__":
    C.entry(main, worker)
