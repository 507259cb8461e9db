"""The cost model of the dry runs (``dem.cost``) against real runs of the examples.

For each example command: the estimate its ``--dry-run`` gives (the seconds it logs
with ``-v``), then the command itself, run REPS times after one warm-up run (warm
numba cache), on one thread. Reported per case: the estimate, the median wall time
of the whole command (start-up included) and their ratio; overall, the median and the
extreme ratios. An estimate is meant to hold within a factor of about three.

usage::

    python benchmarks/cost_model.py        # writes benchmarks/results/cost_model.json

environment: REPS (1), CASES (all: pour rve_biaxial sweep biaxial).
"""

import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "cost_model.json"

#: name: (module, command, input file)
CASES = {
    "pour": ("dem", "run", "examples/scenes/pour.toml"),
    "rve_biaxial": ("hmm", "rve", "examples/rve_biaxial.toml"),
    "sweep": ("hmm", "batch", "examples/sweep.toml"),
    "biaxial": ("hmm", "run", "examples/biaxial.toml"),
}


def _command(module, command, path, out, *extra):
    return [sys.executable, "-m", module, command, path, "-o", str(out), "--overwrite",
            "--no-progress", *extra]


def estimate(module, command, path, out):
    """The dry run's estimate [s] (the cost model's seconds, logged with -v)."""
    p = subprocess.run(_command(module, command, path, out, "--dry-run", "-v"),
                       env=C.worker_env(1), cwd=C.REPO, capture_output=True, text=True,
                       timeout=600)
    m = re.search(r"cost model: ([0-9.eE+-]+) s", p.stderr + p.stdout)
    if p.returncode != 0 or m is None:
        raise RuntimeError(f"{module} {command} {path} --dry-run: rc={p.returncode}: "
                           f"{(p.stderr or p.stdout).strip()[-300:]}")
    return float(m.group(1))


def wall(module, command, path, out):
    """Wall time [s] of the whole command."""
    t0 = time.perf_counter()
    subprocess.run(_command(module, command, path, out), env=C.worker_env(1), cwd=C.REPO,
                   check=True, capture_output=True, timeout=3600)
    return time.perf_counter() - t0


def main():
    reps = C.env_int("REPS", 1)
    names = C.env_list("CASES", " ".join(CASES))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            module, command, path = CASES[name]
            out = Path(tmp) / name
            est = estimate(module, command, path, out)
            wall(module, command, path, out)  # warm-up: compiles on a cold cache
            times = [wall(module, command, path, out) for _ in range(reps)]
            t = C.median(times)
            rows.append({"case": name, "command": f"{module} {command} {path}",
                         "estimate_s": est, "wall_s": t, "wall_times": times,
                         "ratio_measured_to_estimate": t / est})
            print(f"{name:12s} estimate {est:8.3g} s   measured {t:8.3g} s   "
                  f"ratio {t / est:.2f}", flush=True)
    ratios = [r["ratio_measured_to_estimate"] for r in rows]
    result = {"benchmark": "cost_model", "date": C.now(), "machine": C.machine_info(),
              "versions": C.our_versions(), "revision": C.git_revision(),
              "loadavg": C.loadavg(), "reps": reps,
              "rows": rows, "median_ratio": C.median(ratios),
              "min_ratio": min(ratios), "max_ratio": max(ratios)}
    C.write_json(OUT, result)
    print(f"wrote {C.display_path(OUT)}")


if __name__ == "__main__":
    C.entry(main, None)
