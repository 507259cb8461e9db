"""Where one time step goes: the shared static scene on one thread, stage by stage.

``python benchmarks/step_profile.py`` settles the scene for a few steps, then times
short runs of the compiled step loop from the same saved state (restored before every
run): the full step, the step without sphere-wall contacts, and the step with no
contacts at all (body passes only). Differences give each stage's cost; each run's
first step remakes the inner contact list, which counts with the sphere contacts. Writes
``benchmarks/results/step_profile.json``. Environment: ``STEPS`` (50 per run), ``REPS``
(7, median).
"""

import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common as C

OUT = C.REPO / "benchmarks" / "results" / "step_profile.json"
STATE = ("pos", "vel", "rot", "ang_vel", "force", "torque")
SIM = ("hist", "whist", "touch", "fpair", "wforce", "wtorque")


def main():
    import numba

    sdir, why = C.scene_dir()
    if sdir is None:
        print(f"skipped: {why}")
        C.write_json(OUT, {"status": "skipped", "reason": why, "date": C.now()})
        return
    numba.set_num_threads(1)
    sim, info = C.build_scene(sdir, "static")
    sim.threads = 1
    sim.run(200)
    b, nl = sim.bodies, sim.neighbors
    saved = {k: getattr(b, k).copy() for k in STATE}
    saved |= {k: getattr(sim, k).copy() for k in SIM}
    pairs, wpairs = nl.pairs, nl.wall_pairs
    steps, reps = C.env_int("STEPS", 50), C.env_int("REPS", 7)

    def timed(with_pairs, with_walls):
        times = []
        for _ in range(reps):
            for k, v in saved.items():
                getattr(b if k in STATE else sim, k)[...] = v
            nl.pairs = pairs if with_pairs else pairs[:0]
            nl.wall_pairs = wpairs if with_walls else wpairs[:0]
            sim._index()  # the inner list is remade at the first step
            nl.pos_ref[:] = b.pos
            t = time.perf_counter()
            done = sim._call(steps, False)
            times.append((time.perf_counter() - t) / max(done, 1))
        nl.pairs, nl.wall_pairs = pairs, wpairs
        sim._index()
        return statistics.median(times)

    full = timed(True, True)
    no_walls = timed(True, False)
    bodies = timed(False, False)
    stages = {"sphere-sphere contacts": no_walls - bodies,
              "sphere-wall contacts": full - no_walls,
              "body passes": bodies}
    print(f"{info['N']} spheres, {pairs.shape[0]} Verlet pairs, {wpairs.shape[0]} wall "
          f"pairs; one step {1e3 * full:.2f} ms on one thread")
    for name, t in stages.items():
        print(f"  {name:24s} {1e3 * t:6.3f} ms  {100 * t / full:5.1f}%")
    C.write_json(OUT, {"n": info["N"], "verlet_pairs": int(pairs.shape[0]),
                       "wall_pairs": int(wpairs.shape[0]), "threads": 1,
                       "steps_per_run": steps, "reps": reps, "step_s": full,
                       "stages_s": stages, "date": C.now(),
                       "machine": C.machine_info()})
    print(f"wrote {C.display_path(OUT)}")


if __name__ == "__main__":
    main()
