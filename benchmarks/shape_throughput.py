"""Throughput of level-set shapes: settled packings of 5,000 polygons (2D) and polyhedra (3D).

``python benchmarks/shape_throughput.py`` builds, for each dimension, N bodies (default
5,000; ``N=...``) of random convex shapes (polygons: 4 to 8 vertices; polyhedra: hulls
of 8 to 14 random points) on a loose lattice in a box of walls, pours them under gravity
with local damping until they have settled (kinetic energy below 1e-6 of the potential
energy drop, or ``SETTLE_STEPS``), then times REPS (default 3) chunks of STEPS (default
200) steps of the settled packing on 1 and on 2 threads, each in a fresh process
(the packing is handed over in ``benchmarks/work``). Writes
``benchmarks/results/shape_throughput.json``: median body-steps/s, contacts per body,
the share of each detection method, and the 2-thread speed-up, after each dimension
(``DIMS="2"`` runs 2D only and keeps the file's 3D result). Contact detection is the
exact polytope solver (the default); ``DETECTION=admm`` times ADMM instead.
"""

import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common as C

OUT = C.RESULTS / "shape_throughput.json"
RHO = 2500.0
SIZE = 0.01  # circumradius scale of the shapes [m]


def _shapes(dim, rng, n_kinds=16):
    from dem.shapes import ConvexPolygon, ConvexPolyhedron

    kinds = []
    for _ in range(n_kinds):
        if dim == 2:
            m = int(rng.integers(4, 9))
            ang = np.sort(rng.uniform(0, 2 * np.pi, m))
            ang += np.linspace(0, 2 * np.pi, m, endpoint=False) - ang.mean() + np.pi
            r = SIZE * rng.uniform(0.8, 1.0, m)
            kinds.append(ConvexPolygon(np.stack([r * np.cos(ang), r * np.sin(ang)], 1)))
        else:
            pts = rng.normal(size=(int(rng.integers(8, 15)), 3))
            pts *= SIZE / np.linalg.norm(pts, axis=1, keepdims=True)
            pts *= rng.uniform(0.8, 1.0, (pts.shape[0], 1))
            kinds.append(ConvexPolyhedron.from_vertices(pts))
    return kinds


def build(dim, n, seed=1):
    """N random shapes on a lattice in an open-top box of walls; returns bodies."""
    import dem

    rng = np.random.default_rng(seed)
    kinds = _shapes(dim, rng)
    per_row = int(round(n ** (1 / dim) * (1.6 if dim == 2 else 1.3)))
    spacing = 2.1 * SIZE
    b = dem.Bodies.empty(dim)
    k = np.arange(n)
    pos = np.zeros((n, dim))
    if dim == 2:
        pos[:, 0] = spacing * (k % per_row + 0.5)
        pos[:, 1] = spacing * (k // per_row + 0.5)
    else:
        pos[:, 0] = spacing * (k % per_row + 0.5)
        pos[:, 1] = spacing * ((k // per_row) % per_row + 0.5)
        pos[:, 2] = spacing * (k // per_row**2 + 0.5)
    choice = rng.integers(0, len(kinds), n)
    for s, shape in enumerate(kinds):
        rows = np.flatnonzero(choice == s)
        if rows.size == 0:
            continue
        if dim == 2:
            rot = rng.uniform(0, 2 * np.pi, rows.size)
        else:
            q = rng.normal(size=(rows.size, 4))
            rot = q / np.linalg.norm(q, axis=1, keepdims=True)
        b.add_shapes(shape, pos[rows], RHO, rot=rot)
    width = spacing * per_row
    for a in range(dim - 1):
        e = np.eye(dim)[a]
        b.add_plane(np.zeros(dim), e)
        b.add_plane(width * e, -e)
    b.add_plane(np.zeros(dim), np.eye(dim)[-1])
    return b


#: per dimension: a 2D body is a 1 m thick prism (0.6 kg per polygon), so the 45 rows of
#: a 5,000-polygon column weigh 260 N; kn = 1e6 N/m keeps the bottom's overlaps near 2 %
#: of the size (at 1e4 they would exceed it, and the pour fails on its overlap limit)
LAW_ARGS = {2: dict(kn=1e6, kt=5e5, mu=0.4, restitution=0.3),
            3: dict(kn=1e4, kt=5e3, mu=0.4, restitution=0.3)}


def settle(dim, n, path):
    import dem
    from dem.observers import kinetic_energy

    b = build(dim, n)
    g = -9.81 * np.eye(dim)[-1]
    sim = dem.Simulation(b, dem.LinearSpring(**LAW_ARGS[dim]), gravity=g, damping=0.4)
    sim.bodies.sort_spatially()
    sim = dem.Simulation(sim.bodies, dem.LinearSpring(**LAW_ARGS[dim]), gravity=g,
                         damping=0.4)
    z0 = float(np.sum(b.mass[~b.is_fixed] * b.pos[~b.is_fixed, -1]))
    cap = C.env_int("SETTLE_STEPS", 100000)
    t = time.perf_counter()
    ratio = 1.0
    while sim.step < cap:
        sim.run(1000)
        drop = 9.81 * (z0 - float(np.sum(b.mass[~b.is_fixed] * b.pos[~b.is_fixed, -1])))
        ratio = sum(kinetic_energy(b)) / max(drop, 1e-300)
        print(f"  settling {dim}D: step {sim.step}, kinetic / potential drop {ratio:.2e}",
              flush=True)
        if ratio < 1e-6:
            break
    from dem.io.checkpoint import write_bodies

    write_bodies(b, path)
    return {"settle_steps": sim.step, "settle_s": time.perf_counter() - t,
            "settled_ratio": ratio, "dt": sim.dt}


def worker(dim, path, steps, reps, detection):
    import numba

    import dem
    from dem.io.checkpoint import read_bodies

    b = read_bodies(path)
    g = -9.81 * np.eye(dim)[-1]
    sim = dem.Simulation(b, dem.LinearSpring(**LAW_ARGS[dim]), gravity=g, damping=0.4,
                         threads=numba.config.NUMBA_NUM_THREADS, detection=detection)
    sim.run(20)  # compile, build lists
    times = []
    for _ in range(reps):
        t = time.perf_counter()
        sim.run(steps)
        times.append(time.perf_counter() - t)
    c = sim.contacts()
    n_free = int(np.sum(~b.is_fixed))
    methods = {}
    keys = getattr(sim, "_bucket_keys", [])
    for q, key in enumerate(keys):
        lo, hi = sim._bstart[q], sim._bstart[q + 1]
        rows = sim._order[lo:hi]
        methods[f"{key[0]}-{key[1]}"] = int(np.sum(sim.shape_state.pgeom[rows, 0] > 0.0))
    C.emit_result({"median_s": C.median(times), "runs_s": times, "steps": steps,
                   "bodies": n_free,
                   "body_steps_per_s": n_free * steps / C.median(times),
                   "contacts_per_body": 2.0 * np.sum(~c["is_wall"]) / n_free,
                   "touching_by_bucket": methods})


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        dim, path, steps, reps, det = sys.argv[2:7]
        worker(int(dim), path, int(steps), int(reps), det)
        return
    n = C.env_int("N", 5000)
    steps, reps = C.env_int("STEPS", 200), C.env_int("REPS", 3)
    detection = os.environ.get("DETECTION", "auto")
    C.WORK.mkdir(parents=True, exist_ok=True)
    out = {"n": n, "steps": steps, "reps": reps, "detection": detection,
           "law": {f"{d}d": v for d, v in LAW_ARGS.items()}, "date": C.now(),
           "machine": C.machine_info(), "dims": {}}
    dims = [int(d) for d in os.environ.get("DIMS", "2 3").split()]
    if OUT.exists():  # a dimension not rerun keeps its last result
        import json

        old = json.loads(OUT.read_text())
        if old.get("n") == n:
            out["dims"] = {k: v for k, v in old.get("dims", {}).items()
                           if int(k[0]) not in dims}
    for dim in dims:
        path = C.WORK / f"settled_{dim}d_{n}.h5"
        info = settle(dim, n, path)
        res = {"settle": info}
        for threads in (1, 2):
            r = C.run_worker(Path(__file__), [dim, path, steps, reps, detection], threads)
            res[f"threads_{threads}"] = r
            if r.get("ok"):
                print(f"{dim}D, {threads} thread(s): {r['body_steps_per_s'] / 1e6:.3f} M "
                      f"body-steps/s, {r['contacts_per_body']:.2f} contacts per body")
            else:
                print(f"{dim}D, {threads} thread(s) failed: {r.get('error')}")
        if res["threads_1"].get("ok") and res["threads_2"].get("ok"):
            res["speedup_2_threads"] = (res["threads_2"]["body_steps_per_s"]
                                        / res["threads_1"]["body_steps_per_s"])
        out["dims"][f"{dim}d"] = res
        C.write_json(OUT, out)  # after each dimension: a long 3D settling may be cut
        print(f"wrote {C.display_path(OUT)}")


if __name__ == "__main__":
    import numpy as np

    main()
else:
    import numpy as np
