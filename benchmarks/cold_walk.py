"""Cold start of the tutorial and the examples: what a new user waits for on a first run.

``benchmarks/cold_start.py`` times the kernel families and ``hmm demo``; this times the
walks a new user takes next, each in a fresh process with an empty numba cache (cold),
then again on the cache it left (warm), one thread:

- ``tutorial``: every block of ``docs/tutorial.md`` in page order
  (``tests/test_tutorial.py::test_tutorial_runs_as_written``);
- ``examples``: every example at the size its tests run it (``tests/test_examples.py``),
  one pytest process, with each test's own cold and warm time (pytest's durations; a
  test's cold time includes the kernels it is the first to compile).

The compile time is cold minus warm. ``CASES`` picks some (default both).

usage::

    python benchmarks/cold_walk.py      # writes benchmarks/results/cold_walk.json

About 15 minutes; keep the cores quiet.
"""

import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

OUT = C.RESULTS / "cold_walk.json"
NODES = {"tutorial": ["tests/test_tutorial.py::test_tutorial_runs_as_written"],
         "examples": ["tests/test_examples.py"]}
#: a line of pytest's ``--durations=0`` report: seconds, phase, test id
DURATION = re.compile(r"^\s*([0-9.]+)s\s+(call|setup|teardown)\s+(\S+)")


def _pytest(nodes, cache):
    """Wall time [s] of ``pytest nodes`` on the numba cache ``cache``, and each test's
    time [s] (setup, call and teardown summed); raises if a test fails."""
    env = C.worker_env(1)
    env["NUMBA_CACHE_DIR"] = str(cache)
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--durations=0",
           "--durations-min=0", *nodes]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, env=env, cwd=C.REPO, capture_output=True, text=True,
                       timeout=7200, check=False)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(nodes)} failed:\n{p.stdout[-3000:]}")
    tests = {}
    for line in p.stdout.splitlines():
        m = DURATION.match(line)
        if m:
            tests[m.group(3)] = tests.get(m.group(3), 0.0) + float(m.group(1))
    return wall, tests


def main():
    cases = C.env_list("CASES", " ".join(NODES))
    result = {"benchmark": "cold_walk", "date": C.now(), "machine": C.machine_info(),
              "versions": C.our_versions(), "revision": C.git_revision(),
              "loadavg": C.loadavg(), "cases": {}}
    for case in cases:
        with tempfile.TemporaryDirectory() as cache:
            cold, cold_tests = _pytest(NODES[case], cache)
            warm, warm_tests = _pytest(NODES[case], cache)
        tests = {t: {"cold_s": cold_tests[t], "warm_s": warm_tests.get(t)}
                 for t in sorted(cold_tests, key=cold_tests.get, reverse=True)}
        result["cases"][case] = {"cold_s": cold, "warm_s": warm, "compile_s": cold - warm,
                                 "tests": tests}
        print(f"{case:10s} cold {cold:7.1f} s   warm {warm:7.1f} s   compile "
              f"{cold - warm:7.1f} s", flush=True)
        for t, v in list(tests.items())[:8]:
            print(f"    {t}: cold {v['cold_s']:.1f} s, warm {v['warm_s'] or 0.0:.1f} s")
    result["load_after"] = C.loadavg()
    C.write_json(OUT, result)
    print(f"wrote {C.display_path(OUT)}")


if __name__ == "__main__":
    C.entry(main, None)
