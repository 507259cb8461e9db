"""Cold start: what a new user waits for the kernels to compile.

Each kernel family is compiled by a tiny run in a fresh process with an empty numba
cache (cold), then run again on the cache it left (warm); the family's compile time is
the difference. ``demo`` is what ``make demo`` runs (``hmm demo``), cold and warm.
Families: ``sphere`` (a 3D scene of spheres and a wall), ``rve2`` and ``rve3`` (a
periodic RVE of disks or spheres: generation and consolidation, one strain call and its
tangent),
``shape2`` and ``shape3`` (polygons or boxes on a floor), ``peridynamics`` (a 2D LPS
plate). One thread, medians over REPS.

usage::

    python benchmarks/cold_start.py     # writes benchmarks/results/cold_start.json

environment: REPS (1), FAMILIES (all).
"""

import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "cold_start.json"

SCRIPTS = {
    "sphere": """
        import dem
        b = dem.Bodies.empty(3)
        b.add_spheres([[0.0, 0.0, 0.01 * k] for k in range(1, 6)], 0.004, density=2500.0)
        b.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
        sim = dem.Simulation(b, dem.LinearSpring(kn=1e4, kt=3e3, mu=0.5),
                             gravity=[0.0, 0.0, -9.81])
        sim.run(100)
    """,
    "rve2": """
        import numpy as np, dem
        from dem.rve import generate
        r = generate(2, 30, (0.8e-3, 1.2e-3), dem.LinearSpring(kn=1e8, kt=5e7, mu=0.5),
                     p0=1e5, seed=1)
        r.apply_strain(np.diag([0.0, -1e-4])); r.tangent()
    """,
    "rve3": """
        import numpy as np, dem
        from dem.rve import generate
        r = generate(3, 40, (0.8e-3, 1.2e-3), dem.LinearSpring(kn=1e5, kt=5e4, mu=0.5),
                     p0=1e5, seed=1)
        r.apply_strain(np.diag([0.0, 0.0, -1e-4])); r.tangent()
    """,
    "shape2": """
        import dem
        b = dem.Bodies.empty(2)
        b.add_shapes(dem.ConvexPolygon.regular(6, 0.01), [[0.0, 0.011], [0.001, 0.035]],
                     density=2500.0)
        b.add_plane([0.0, 0.0], [0.0, 1.0])
        sim = dem.Simulation(b, dem.LinearSpring(kn=1e6, kt=2e5, mu=0.5),
                             gravity=[0.0, -9.81])
        sim.run(100)
    """,
    "shape3": """
        import dem
        b = dem.Bodies.empty(3)
        b.add_shapes(dem.Box([0.01, 0.01, 0.01]), [[0.0, 0.0, 0.011],
                                                   [0.001, 0.0, 0.035]], density=2500.0)
        b.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
        sim = dem.Simulation(b, dem.LinearSpring(kn=1e6, kt=2e5, mu=0.5),
                             gravity=[0.0, 0.0, -9.81])
        sim.run(100)
    """,
    "peridynamics": """
        import dem
        from dem import peridynamics as pd
        dx = 0.01
        b = dem.Bodies.empty(2)
        ids = pd.add_points(b, pd.lattice([0, 0], [0.1, 0.1], dx), dx, density=1000.0,
                            thickness=0.01)
        m = pd.LPS(E=1e9, nu=0.25, density=1000.0, plane="stress", s_crit=1.5e-3)
        sim = pd.PDSimulation(b, m, ids, horizon=3 * dx, damping=0.3)
        sim.run(50)
    """,
}


def _wall(cmd, cache):
    env = C.worker_env(1)
    env["NUMBA_CACHE_DIR"] = str(cache)
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, cwd=C.REPO, check=True, capture_output=True,
                   timeout=3600)
    return time.perf_counter() - t0


def cold_and_warm(cmd, reps):
    """Median seconds of ``cmd`` on an empty cache and on the cache it left."""
    cold, warm = [], []
    for _ in range(reps):
        with tempfile.TemporaryDirectory() as cache:
            cold.append(_wall(cmd, cache))
            warm.append(_wall(cmd, cache))
    return C.median(cold), C.median(warm)


def main():
    reps = C.env_int("REPS", 1)
    names = C.env_list("FAMILIES", " ".join(SCRIPTS))
    result = {"benchmark": "cold_start", "date": C.now(), "machine": C.machine_info(),
              "versions": C.our_versions(), "revision": C.git_revision(),
              "loadavg": C.loadavg(), "reps": reps, "families": {}}
    with tempfile.TemporaryDirectory() as out:
        demo = [sys.executable, "-m", "hmm", "demo", "-o", out, "--overwrite",
                "--no-progress"]
        cold, warm = cold_and_warm(demo, reps)
    result.update(demo_seconds_cold=cold, demo_seconds_warm=warm)
    print(f"demo          cold {cold:6.1f} s   warm {warm:6.1f} s", flush=True)
    total = 0.0
    for name in names:
        cmd = [sys.executable, "-c", textwrap.dedent(SCRIPTS[name])]
        cold, warm = cold_and_warm(cmd, reps)
        result["families"][name] = {"cold_s": cold, "warm_s": warm,
                                    "compile_s": cold - warm}
        total += cold - warm
        print(f"{name:13s} cold {cold:6.1f} s   warm {warm:6.1f} s   compile "
              f"{cold - warm:6.1f} s", flush=True)
    result["compile_seconds_total"] = total
    C.write_json(OUT, result)
    print(f"wrote {C.display_path(OUT)}")


if __name__ == "__main__":
    C.entry(main, None)
