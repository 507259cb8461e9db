"""The only place numba options are chosen.

``kernel`` is ``numba.njit`` with the project defaults: cached on disk (turn off with
``DEM_JIT_CACHE=0``), IEEE arithmetic (no ``fastmath``) and numpy's error model, so a
division by zero gives ``inf``/``nan`` that the run loop detects instead of raising.
The threading layer is chosen here too: OpenMP where available, never TBB.

Numba checks a cached kernel against its own source file only, not against the
functions it inlines from other files: after an edit to a contact law or a detection
kernel (or an upgrade of the package) it would load a time loop compiled with the old
code. The cache therefore lives in a folder named after a hash of every source file of
the package, ``<NUMBA_CACHE_DIR or the package's __pycache__>/dem-<hash>``: a changed
file means a cold compile, never a stale kernel.
"""

import hashlib
import os

import numba

CACHE = os.environ.get("DEM_JIT_CACHE", "1") != "0"


def source_stamp():
    """A hash of the package's Python sources (names and contents), 16 hex digits."""
    root = os.path.dirname(os.path.abspath(__file__))
    h = hashlib.sha256()
    for folder, subfolders, files in os.walk(root):
        subfolders[:] = sorted(d for d in subfolders if d != "__pycache__")
        for name in sorted(f for f in files if f.endswith(".py")):
            path = os.path.join(folder, name)
            h.update(os.path.relpath(path, root).encode())
            with open(path, "rb") as f:
                h.update(f.read())
    return h.hexdigest()[:16]


if CACHE:
    _base = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.path.dirname(os.path.abspath(__file__)), "__pycache__")
    numba.config.CACHE_DIR = os.path.join(_base, "dem-" + source_stamp())

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
