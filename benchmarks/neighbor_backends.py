"""Verlet-list build time: the cell list against scipy's k-d tree, on the shared scene.

``python benchmarks/neighbor_backends.py`` builds the neighbour list of the 16,250-sphere
packing (skin 0.5 R) with each backend, REPS times (default 7) on one thread, checks
that both find the same pairs, and writes ``benchmarks/results/neighbor_backends.json``
with the median build times and their ratio. Also timed, from the cell list's pairs:
the compaction of the step loop's inner list (``inner_list_compaction_s``: the pairs
closer than ``r_i + r_j + skin_inner`` laid out block by block, what every inner-list
refresh does after flagging them), the same REPS times.
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
    compaction = inner_compaction(bodies, pairs["cell"], p["SKIN"], reps)
    print(f"inner-list compaction {1e3 * compaction['median_s']:.2f} ms "
          f"({compaction['inner']} of {pairs['cell'].shape[0]} pairs)")
    same = bool(np.array_equal(pairs["cell"], pairs["kdtree"]))
    ratio = result["kdtree"]["median_s"] / result["cell"]["median_s"]
    print(f"same pairs: {same}; k-d tree / cell list time: {ratio:.2f}")
    C.write_json(OUT, {"n": int(pos.shape[0]), "skin": p["SKIN"], "reps": reps,
                       "threads": 1, "backends": result, "same_pairs": same,
                       "ratio_kdtree_over_cell": ratio,
                       "inner_list_compaction_s": compaction, "date": C.now(),
                       "machine": C.machine_info()})
    print(f"wrote {C.display_path(OUT)}")


def inner_compaction(bodies, pairs, skin, reps):
    """Median time of the inner list's compaction (:func:`_compact_inner`) for the
    pairs closer than ``r_i + r_j + INNER_SKIN skin``."""
    import numpy as np

    from dem.contact.sphere_contacts import N_BLOCKS, _compact_inner
    from dem.simulation import INNER_SKIN

    i, j = pairs[:, 0], pairs[:, 1]
    gap = np.linalg.norm(bodies.pos[j] - bodies.pos[i], axis=1) - bodies.radius[i] \
        - bodies.radius[j]
    near = (gap < INNER_SKIN * skin).astype(np.int64)
    m, n = pairs.shape[0], bodies.n
    out = (np.zeros(m, np.int64), np.zeros(2, np.int64), np.zeros(N_BLOCKS + 1, np.int64),
           np.zeros(n + 1, np.int64), np.zeros((m, 2), np.int64))
    _compact_inner(pairs, near, n, *out)  # compile / warm up
    times = []
    for _ in range(reps):
        t = time.perf_counter()
        _compact_inner(pairs, near, n, *out)
        times.append(time.perf_counter() - t)
    return {"median_s": statistics.median(times), "runs_s": times,
            "inner": int(out[1][0])}


if __name__ == "__main__":
    main()
