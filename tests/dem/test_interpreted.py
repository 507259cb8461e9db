"""The compiled loops and the same code run as plain Python agree bit for bit.

With ``NUMBA_DISABLE_JIT=1`` every kernel runs in the interpreter (tracebacks and
coverage work there); both follow IEEE double arithmetic, so a small scene with
friction, damping, walls and a neighbour rebuild must give identical numbers.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = """
import json, sys
import numpy as np
sys.path.insert(0, {root!r})
import dem
rng = np.random.default_rng(3)
x, h = np.arange(6) * 0.021, 0.011 + rng.uniform(0, 0.01, 6)  # a row above the floor
pos = np.stack([x, h] if {dim} == 2 else [x, np.zeros(6), h], 1)
bodies = dem.Bodies.spheres(pos, radius=0.01, density=2500.0,
                            vel=rng.normal(0, 0.2, (6, {dim})))
bodies.add_plane(np.zeros({dim}), np.eye({dim})[-1])
law = dem.LinearSpring(kn=1e5, kt=3e4, mu=0.4, restitution=0.6)
sim = dem.Simulation(bodies, law, gravity=-9.81 * np.eye({dim})[-1], damping=0.05,
                     skin=0.0005, threads=1)
sim.run(150)
print(json.dumps({{"pos": bodies.pos.tolist(), "rot": bodies.rot.tolist(),
                  "ang_vel": bodies.ang_vel.tolist(), "builds": sim.neighbors.n_builds}}))
"""


def _run(dim, disable_jit):
    env = dict(os.environ, NUMBA_DISABLE_JIT="1" if disable_jit else "0")
    out = subprocess.run([sys.executable, "-c", SCRIPT.format(root=str(ROOT), dim=dim)],
                         env=env, capture_output=True, text=True, timeout=300, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_interpreted_equals_compiled():
    for dim in (2, 3):
        jit, py = _run(dim, False), _run(dim, True)
        assert jit["builds"] > 1, "the scene should rebuild its neighbour list"
        for key in ("pos", "rot", "ang_vel"):
            assert np.array_equal(np.array(jit[key]), np.array(py[key])), (dim, key)
