"""Compile memory: what a process keeps after compiling time loops cold.

numba keeps the intermediate objects of every ``parallel=True`` compilation alive for
the life of the process (numba issue 5667): about 1.5-3 GB per sphere time loop. A
process that compiles several loops (a test session, a notebook trying 2D and 3D with
and without rolling resistance) then outgrows a laptop. ``dem._jit.prepare`` compiles
a loop missing from the disk cache in a child process and loads it from the cache.

A fresh process with an empty numba cache runs three small scenes, each needing its
own loop (2D, 2D with rolling resistance, 3D), and reports its resident memory after
each, once with the child (``DEM_COMPILE_APART=1``, the default) and once compiling
in the process (``DEM_COMPILE_APART=0``). One thread.

usage::

    python benchmarks/compile_memory.py   # writes benchmarks/results/compile_memory.json
"""

import json
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "compile_memory.json"

SCRIPT = """
    import json, math
    import numpy as np
    import dem

    def rss_mb():
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmRSS"):
                    return int(line.split()[1]) / 1024.0

    def sphere_on_plane(dim, rolling):
        up = np.eye(dim)[-1]
        law = dem.LinearSpring(kn=1e4, kt=4e3, mu=0.5, restitution=0.5,
                               rolling=dem.Rolling(mu_roll=0.1) if rolling else None)
        b = dem.Bodies.spheres([0.0101 * up], radius=0.01, density=2500.0)
        b.add_plane(np.zeros(dim), up)
        return dem.Simulation(b, law, gravity=-9.81 * up)

    out = {"import": rss_mb()}
    for name, dim, rolling in (("2d", 2, False), ("2d_rolling", 2, True),
                               ("3d", 3, False)):
        sphere_on_plane(dim, rolling).run(10)
        out[name] = rss_mb()
    print(json.dumps(out))
"""


def measure(apart):
    """Resident MB after each stage, and the wall time, in a fresh process."""
    with tempfile.TemporaryDirectory() as cache:
        env = C.worker_env(1)
        env.update(NUMBA_CACHE_DIR=cache, DEM_COMPILE_APART="1" if apart else "0")
        t0 = time.perf_counter()
        done = subprocess.run([sys.executable, "-c", textwrap.dedent(SCRIPT)], env=env,
                              cwd=C.REPO, check=True, capture_output=True, text=True,
                              timeout=3600)
        wall = time.perf_counter() - t0
    return json.loads(done.stdout.strip().splitlines()[-1]), wall


def main():
    result = {"benchmark": "compile_memory", "date": C.now(), "machine": C.machine_info(),
              "versions": C.our_versions(), "revision": C.git_revision(),
              "loadavg": C.loadavg()}
    for label, apart in (("child", True), ("in_process", False)):
        rss, wall = measure(apart)
        result[label] = {"rss_mb": rss, "wall_s": wall}
        print(f"{label:10s} " + "  ".join(f"{k} {v:7.0f} MB" for k, v in rss.items())
              + f"   {wall:6.1f} s", flush=True)
    last = list(result["child"]["rss_mb"])[-1]
    result["rss_ratio_in_process_over_child"] = C.ratio(
        result["in_process"]["rss_mb"][last], result["child"]["rss_mb"][last])
    C.write_json(OUT, result)
    print(f"wrote {C.display_path(OUT)}")


if __name__ == "__main__":
    C.entry(main, None)
