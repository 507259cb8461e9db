"""Loop compile: what a cold compile of the sphere time loop costs, and what it buys.

One scene, a 400-disk 2D periodic RVE (``dem.rve.generate``, consolidated to 100 kPa),
on one thread: the loop it runs is compiled in the process (``DEM_COMPILE_APART=0``)
into an empty numba cache. Reported per source tree:

- ``cold_s``: generation and 10 steps on the empty cache (the loop's compile, the
  measures' and the generation itself), and ``warm_s``, the same on the cache it left;
- ``s_per_1000_steps``: the median of 5 runs of 1,000 steps after it;
- ``passes_s``: numba's own timing of each compiler pass of the loop (summed over the
  loop's signatures compiled in the process), with ``llvm_s`` and ``compiler_s``.

Trees: this checkout, and ``BASE`` (a git revision, exported with ``git archive``) if
set, run one after the other. ``NO_PARALLEL=1`` adds this checkout with the loop
compiled without ``parallel=True`` (the one-thread loop's code is the same; numba
compiles it differently), in a cache of its own.

usage::

    python benchmarks/loop_compile.py                  # this checkout
    BASE=090a134 python benchmarks/loop_compile.py     # and the revision before
    NO_PARALLEL=1 python benchmarks/loop_compile.py    # and without parallel=True

writes ``benchmarks/results/loop_compile.json``.
"""

import json
import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "loop_compile.json"

PROBE = """
    import json, os, sys, time
    import numpy as np
    import dem
    from dem.rve import generate

    if os.environ.get("PROBE_NO_PARALLEL") == "1":  # the loop without parallel=True
        import dem.contact.loops as loops
        _kernel = loops.kernel
        loops.kernel = lambda fn=None, **kw: _kernel(fn, **{**kw, "parallel": False})

    t0 = time.perf_counter()
    rve = generate(2, 400, (0.8e-3, 1.2e-3), dem.LinearSpring(kn=1e8, kt=5e7, mu=0.5),
                   p0=1e5, seed=1)
    sim = rve.sim
    sim.run(10)
    setup = time.perf_counter() - t0
    runs = []
    for _ in range(5):
        t = time.perf_counter()
        sim.run(1000)
        runs.append(time.perf_counter() - t)
    passes, llvm, compiler = {}, 0.0, 0.0
    loop = sim._loop_args(0, True, False)[0]
    for meta in loop.get_metadata().values():
        meta = meta or {}  # none for a loop loaded from the cache
        for timings in meta.get("pipeline_times", {}).values():
            for name, t in timings.items():
                name = name.split("_", 1)[1]  # numba numbers its passes
                passes[name] = passes.get(name, 0.0) + t.init + t.run + t.finalize
        llvm += meta.get("timers", {}).get("llvm_lock", 0.0)
        compiler += meta.get("timers", {}).get("compiler_lock", 0.0)
    print(json.dumps({"setup_s": setup, "s_per_1000_steps": sorted(runs)[2],
                      "threads": sim.threads, "passes_s": passes, "llvm_s": llvm,
                      "compiler_s": compiler}))
"""


def probe(tree, cache, no_parallel=False):
    """The probe's answer in a fresh process on ``tree``'s sources and ``cache``."""
    env = C.worker_env(1)
    env.update(NUMBA_CACHE_DIR=str(cache), DEM_COMPILE_APART="0",
               PYTHONPATH=str(tree) + os.pathsep + env.get("PYTHONPATH", ""),
               PROBE_NO_PARALLEL="1" if no_parallel else "0")
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(PROBE)], env=env,
                          cwd=tree, capture_output=True, text=True, timeout=3600)
    if done.returncode != 0:
        raise SystemExit(f"the probe failed in {tree}:\n{done.stderr[-3000:]}")
    out = json.loads(done.stdout.strip().splitlines()[-1])
    out["process_s"] = time.perf_counter() - t0
    return out


def measure(tree, no_parallel=False):
    """Cold then warm on one empty cache."""
    with tempfile.TemporaryDirectory() as cache:
        cold = probe(tree, cache, no_parallel)
        warm = probe(tree, cache, no_parallel)
    top = sorted(cold["passes_s"].items(), key=lambda kv: -kv[1])
    return {"cold_s": cold["setup_s"], "warm_s": warm["setup_s"],
            "s_per_1000_steps": cold["s_per_1000_steps"],
            "s_per_1000_steps_warm": warm["s_per_1000_steps"],
            "threads": cold["threads"], "passes_s": dict(top),
            "llvm_s": cold["llvm_s"], "compiler_s": cold["compiler_s"]}


def report(label, r):
    top = ", ".join(f"{k} {v:.1f}" for k, v in list(r["passes_s"].items())[:5])
    print(f"{label:12s} cold {r['cold_s']:6.1f} s  warm {r['warm_s']:5.1f} s  "
          f"{r['s_per_1000_steps']:.4f} s/1000 steps  compiler {r['compiler_s']:5.1f} s "
          f"({top})", flush=True)


def main():
    result = {"benchmark": "loop_compile", "date": C.now(), "machine": C.machine_info(),
              "versions": C.our_versions(), "revision": C.git_revision(),
              "loadavg": C.loadavg(), "trees": {}}
    trees = [("this", C.REPO, False)]
    if os.environ.get("NO_PARALLEL") == "1":
        trees.append(("no_parallel", C.REPO, True))
    base = os.environ.get("BASE")
    with tempfile.TemporaryDirectory() as scratch:
        if base:
            tree = Path(scratch) / "base"
            tree.mkdir()
            archive = subprocess.run(["git", "archive", base], cwd=C.REPO, check=True,
                                     capture_output=True).stdout
            subprocess.run(["tar", "-x", "-C", str(tree)], input=archive, check=True)
            trees.insert(0, (f"base {base}", tree, False))
        for label, tree, no_parallel in trees:
            r = measure(tree, no_parallel)
            result["trees"][label] = r
            report(label, r)
    this = result["trees"]["this"]
    for label, r in result["trees"].items():
        if label != "this":
            r["cold_ratio_over_this"] = C.ratio(r["cold_s"], this["cold_s"])
            r["speed_ratio_this_over"] = C.ratio(r["s_per_1000_steps"],
                                                 this["s_per_1000_steps"])
    C.write_json(OUT, result)
    print(f"wrote {C.display_path(OUT)}")


if __name__ == "__main__":
    C.entry(main, None)
