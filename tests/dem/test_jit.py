"""The compile paths of ``dem._jit``: specialised loops, and numba's disk cache of them.

Numba keys its disk cache on a function's code and closure cells, not on its globals,
so a loop compiled with globals replaced (:func:`dem._jit.specialise`) must stay off
the disk, while the loops the factories build for the package's own kernels must load
from it in a new process: a shape scene run twice, each time in a fresh process, over
the suite's own disk cache, compiles nothing the second time (numba's own cache log,
``NUMBA_DEBUG_CACHE``, says which files it wrote and read). The first run compiles
what the suite has not compiled yet; that a time loop's first compile runs in a child
process, which writes the cache, is ``tests/dem/test_cost.py``'s test.
"""

import os
import subprocess
import sys
from pathlib import Path

import numba
import pytest

from dem import _jit
from dem._jit import specialise

ROOT = Path(__file__).resolve().parents[2]

_SCALE = 2.0


def _scaled(x):
    return _SCALE * x


def test_specialise_binds_globals_and_keeps_bound_loops_off_the_disk():
    plain = specialise(_scaled)
    same = specialise(_scaled, _SCALE=_SCALE)  # the object it holds: no replacement
    bound = specialise(_scaled, _SCALE=10.0)
    assert plain(3.0) == same(3.0) == 6.0
    assert bound(3.0) == 30.0
    assert _scaled(3.0) == 6.0  # the module's function is untouched
    if numba.config.DISABLE_JIT:
        return
    assert bound.stats.cache_path is None  # globals are not in numba's cache key
    if _jit.CACHE:
        assert plain.stats.cache_path is not None
        assert same.stats.cache_path is not None


SCENE = """
import sys
import numpy as np
sys.path.insert(0, {root!r})
import dem
from dem.shapes import Box
bodies = dem.Bodies.empty(2)
bodies.add_shapes(Box([0.01, 0.01]), [[0.0, 0.0105], [0.003, 0.0312]], 1000.0)
bodies.add_plane(np.zeros(2), np.eye(2)[-1])
sim = dem.Simulation(bodies, dem.LinearSpring(kn=1e5), gravity=[0.0, -9.81], threads=1)
sim.run(5)
"""


def _cache_log():
    """Run the shape scene in a new process; the data files numba saved and loaded."""
    env = dict(os.environ, NUMBA_DEBUG_CACHE="1", DEM_JIT_CACHE="1", NUMBA_DISABLE_JIT="0")
    out = subprocess.run([sys.executable, "-c", SCENE.format(root=str(ROOT))], env=env,
                         capture_output=True, text=True, timeout=900, check=True)
    saved, loaded = set(), set()
    for line in out.stdout.splitlines():
        if line.startswith("[cache] data saved to "):
            saved.add(line.split(" to ", 1)[1])
        elif line.startswith("[cache] data loaded from "):
            loaded.add(line.split(" from ", 1)[1])
    return saved, loaded


@pytest.mark.slow  # compiles the 2D shape loop if the suite has not (about a minute)
def test_a_shape_loop_loads_from_the_disk_cache_in_a_new_process():
    saved1, loaded1 = _cache_log()
    # the scene's time loop, built by its factory (shape_loop.shape_stepper) through
    # dem._jit, is compiled by a child process (dem._jit.prepare) or an earlier test,
    # never saved by this process, which loads it
    assert any("shape_stepper" in path for path in loaded1), sorted(loaded1)
    assert not any("shape_stepper" in path for path in saved1), sorted(saved1)
    saved2, loaded2 = _cache_log()
    assert not saved2, f"compiled again in a new process: {sorted(saved2)}"
    assert any("shape_stepper" in path for path in loaded2), sorted(loaded2)
    assert loaded2 <= saved1 | loaded1
