"""Verlet-list build time: the cell list against scipy's k-d tree, on the shared scene.

``python benchmarks/neighbor_backends.py`` builds the neighbour list of the 16,250-sphere
packing (skin 0.5 R) with each backend, REPS times (default 7) on one thread, checks
that both find the same pairs, and writes ``benchmarks/results/neighbor_backends.json``
with the median build times and their ratio.
"""

import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import _common as C

OUT = C.REPO / "benchmarks" / "results" / "neighbor_backends.json"


def main():
    import numpy as np

    import dem
    from dem.neighbors import NeighborList

    sdir, why = C.scene_dir()
    if sdir is None:
        print(f"skipped: {why}")
        C.write_json(OUT, {"status": "skipped", "reason": why, "date": C.now()})
        return
    p = C.load_params(sdir)
    pos, radius = C.load_packing(sdir)
    bodies = dem.Bodies.spheres(pos, radius=radius, density=p["RHO"])
    bodies.sort_spatially()
    reps = C.env_int("REPS", 7)
    result, pairs = {}, {}
    for backend in ("cell", "kdtree"):
        nl = NeighborList(p["SKIN"], backend=backend)
        nl.build(bodies)  # compile / warm up
        times = []
        for _ in range(reps):
            t = time.perf_counter()
            nl.build(bodies)
            times.append(time.perf_counter() - t)
        pairs[backend] = nl.pairs.copy()
        result[backend] = {"median_s": statistics.median(times), "runs_s": times,
                           "pairs": int(nl.pairs.shape[0])}
        print(f"{backend:7s} {1e3 * result[backend]['median_s']:.1f} ms "
              f"({result[backend]['pairs']} pairs)")
    same = bool(np.array_equal(pairs["cell"], pairs["kdtree"]))
    ratio = result["kdtree"]["median_s"] / result["cell"]["median_s"]
    print(f"same pairs: {same}; k-d tree / cell list time: {ratio:.2f}")
    C.write_json(OUT, {"n": int(pos.shape[0]), "skin": p["SKIN"], "reps": reps,
                       "threads": 1, "backends": result, "same_pairs": same,
                       "ratio_kdtree_over_cell": ratio, "date": C.now(),
                       "machine": C.machine_info()})
    print(f"wrote {C.display_path(OUT)}")


if __name__ == "__main__":
    main()
