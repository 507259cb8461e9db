"""Where one time step goes: the shared static scene on one thread, stage by stage.

``python benchmarks/step_profile.py`` settles the scene for 200 steps, then times short
runs of the compiled step loop from the same saved state (restored before every run):
the full step, the step with the sphere-wall contacts only, and the step with no
contacts at all (the body passes). Each stage is the difference of two neighbours:
sphere-sphere contacts = full - walls only, sphere-wall contacts = walls only - none.
(Taking the walls away instead would let the bed fall, and its contacts open while it
falls: a run without walls is cheaper than the pairs' share of a full step, and the
difference would charge the walls with it.) Each run's first step remakes the inner
contact list, which counts with the sphere contacts. Writes
``benchmarks/results/step_profile.json``. Environment: ``STEPS`` (50 per run), ``REPS``
(7, median).

``BASE=<git revision>`` profiles that revision too (its sources exported into
``benchmarks/work/trees``, run by this script in a fresh process), the two in turn
``ROUNDS`` times (3), and reports each stage's time of this checkout over the
revision's (median of the rounds' ratios) in ``results/step_profile_base.json``:
``BASE=a7808d7 python benchmarks/step_profile.py`` finds the stage in which the engine
lost time against the revision before rolling resistance.
"""

import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common as C

OUT = C.RESULTS / "step_profile.json"
OUT_BASE = C.RESULTS / "step_profile_base.json"
STATE = ("pos", "vel", "rot", "ang_vel", "force", "torque")
BUNDLES = ("pair_state", "wall_state")  # the contact state (dem.state)
STAGES = ("sphere-sphere contacts", "sphere-wall contacts", "body passes")


def profile():
    """``(info, step_s, stages_s)`` of the static scene on one thread."""
    import numba

    sdir, why = C.scene_dir()
    if sdir is None:
        raise SystemExit(why)
    numba.set_num_threads(1)
    sim, info = C.build_scene(sdir, "static")
    sim.threads = 1
    sim.run(200)
    b, nl = sim.bodies, sim.neighbors
    saved = {k: getattr(b, k).copy() for k in STATE}
    kept = {k: [a.copy() for a in getattr(sim, k)] for k in BUNDLES}
    pairs, wpairs = nl.pairs, nl.wall_pairs
    steps, reps = C.env_int("STEPS", 50), C.env_int("REPS", 7)

    def timed(with_pairs, with_walls):
        times = []
        for _ in range(reps):
            for k, v in saved.items():
                getattr(b, k)[...] = v
            for k, arrays in kept.items():
                for a, v in zip(getattr(sim, k), arrays, strict=True):
                    a[...] = v
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
    walls = timed(False, True)
    none = timed(False, False)
    stages = dict(zip(STAGES, (full - walls, walls - none, none), strict=True))
    info = {"n": info["N"], "verlet_pairs": int(pairs.shape[0]),
            "wall_pairs": int(wpairs.shape[0]), "threads": 1, "steps_per_run": steps,
            "reps": reps}
    return info, full, stages


def show(label, step, stages):
    print(f"{label}: one step {1e3 * step:.3f} ms on one thread")
    for name, t in stages.items():
        print(f"  {name:24s} {1e3 * t:6.3f} ms  {100 * t / step:5.1f}%")


def worker(_args):
    info, step, stages = profile()
    C.emit_result({**info, "step_s": step, "stages_s": stages})


def compare(revision):
    """This checkout against ``revision``, in turn, ``ROUNDS`` times."""
    tree = C.source_tree(revision)
    rounds = C.env_int("ROUNDS", 3)
    runs = {"this": [], "base": []}
    for r in range(rounds):
        for code, t in (("this", None), ("base", tree)):
            res = C.run_worker(Path(__file__), [], 1, tree=t)
            if not res.get("ok"):
                raise SystemExit(f"step_profile ({code}): {res.get('error')}")
            runs[code].append(res)
            show(f"round {r + 1}, {'this checkout' if t is None else revision}",
                 res["step_s"], res["stages_s"])
    ratios = {"step": statistics.median(a["step_s"] / b["step_s"] for a, b in
                                        zip(runs["this"], runs["base"], strict=True))}
    for s in STAGES:
        ratios[s] = statistics.median(a["stages_s"][s] / b["stages_s"][s] for a, b in
                                      zip(runs["this"], runs["base"], strict=True))
    print(f"this checkout's time over {revision}'s (median of {rounds} rounds):")
    for k, v in ratios.items():
        print(f"  {k:24s} {v:.3f}")
    C.write_json(OUT_BASE, {"base": revision, "rounds": rounds, "time_ratio": ratios,
                            "runs": runs, "date": C.now(), "machine": C.machine_info()})
    print(f"wrote {C.display_path(OUT_BASE)}")


def main():
    sdir, why = C.scene_dir()
    if sdir is None:
        print(f"skipped: {why}")
        C.write_json(OUT, {"status": "skipped", "reason": why, "date": C.now()})
        return
    base = os.environ.get("BASE", "").strip()
    if base:
        compare(base)
        return
    info, step, stages = profile()
    show("this checkout", step, stages)
    C.write_json(OUT, {**info, "step_s": step, "stages_s": stages, "date": C.now(),
                       "machine": C.machine_info()})
    print(f"wrote {C.display_path(OUT)}")


if __name__ == "__main__":
    C.entry(main, worker)
