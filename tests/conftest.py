"""Shared test set-up: headless plotting and one warm-up of the compiled DEM loops.

``tests/`` is on ``sys.path`` (pytest's rootdir conftest), so test modules import the
pure-numpy references with ``import naive``.
"""

import os
import sys
from pathlib import Path

os.environ["MPLBACKEND"] = "Agg"  # before anything imports matplotlib

# pytest puts ``tests/`` on sys.path, where ``tests/dem`` (no __init__.py) would be
# imported as a namespace package ``dem`` shadowing the real one whenever the project
# root is not on sys.path too (``pytest`` run as a script, or from another directory).
# Put the root first, as ``pythonpath = ["."]`` in pyproject.toml would.
ROOT = str(Path(__file__).resolve().parents[1])
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import numba  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import dem  # noqa: E402  (the real package, resolved before tests/dem is seen)
from dem.neighbors import Box, NeighborList  # noqa: E402


def _warm_scene(dim):
    """A few steps of two spheres on a wall: compiles the (dim, linear, linear) loop."""
    pos = np.zeros((2, dim))
    pos[:, -1] = [0.0101, 0.0302]
    bodies = dem.Bodies.spheres(pos, radius=0.01, density=2500.0)
    bodies.add_plane(np.zeros(dim), np.eye(dim)[-1])
    gravity = -9.81 * np.eye(dim)[-1]
    sim = dem.Simulation(
        bodies, dem.LinearSpring(kn=1e5, kt=2e4, mu=0.3), gravity=gravity
    )
    sim.run(10)
    return sim


@pytest.fixture(scope="session", autouse=True)
def warm_kernels():
    """Compile (or load from numba's cache) the common 2D and 3D loops once per session.

    Test durations then measure physics, not compilation. ``Simulation.run`` picks its
    own thread count (``threads``); everything else (``Simulation.prime``, direct
    kernel calls) runs on one numba thread: the scenes are small and the cores shared.

    ``DEM_TEST_WARM=0`` skips the warm-up: ``make test`` sets it for the half of the
    suite that starts with the level-set shapes, so that the two halves, side by side on
    one numba cache, do not both compile these loops at the same time (the other half's
    warm-up has written them to the cache by the time the shapes' tests need them).
    """
    numba.set_num_threads(1)
    if os.environ.get("DEM_TEST_WARM", "1") == "0":
        return None
    sims = {dim: _warm_scene(dim) for dim in (2, 3)}
    for dim in (2, 3):
        b = sims[dim].bodies.copy()
        NeighborList(
            0.004, "cell", Box(-np.ones(dim), np.ones(dim), [True] * dim)
        ).build(b)
    return sims
