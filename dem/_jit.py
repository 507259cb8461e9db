"""The only place numba options are chosen.

``kernel`` is ``numba.njit`` with the project defaults: cached on disk (turn off with
``DEM_JIT_CACHE=0``), IEEE arithmetic (no ``fastmath``) and numpy's error model, so a
division by zero gives ``inf``/``nan`` that the run loop detects instead of raising.
The threading layer is chosen here too: OpenMP where available, never TBB.
"""

import os

import numba

CACHE = os.environ.get("DEM_JIT_CACHE", "1") != "0"

if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = "omp"


def kernel(fn=None, *, parallel=False, inline=False):
    """``numba.njit`` with project defaults; ``parallel=True`` only where a prange exists.

    ``inline=True`` inlines the function into its callers at numba's IR level: for the
    small per-contact kernels (laws) called from hot loops, where a real call would pass
    every array as a dozen scalar arguments.
    """
    deco = numba.njit(cache=CACHE, parallel=parallel, fastmath=False, error_model="numpy",
                      inline="always" if inline else "never")
    return deco if fn is None else deco(fn)


def set_threads(n):
    """Set the number of numba threads used by parallel kernels (1 .. NUMBA_NUM_THREADS)."""
    numba.set_num_threads(int(n))


def get_threads():
    """Number of numba threads parallel kernels use now."""
    return numba.get_num_threads()
