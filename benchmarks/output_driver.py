"""Cost of writing HDF5 output through a Python file object (``dem.io.files``).

The project's writers hand h5py a Python file object so that a write the disk refuses
ends in one error (issue 32) rather than in HDF5's own failure paths. This measures
what that costs: :class:`dem.io.H5Writer` writes 30 frames of a 20 x 20 x 20 lattice of
spheres on a floor (8,001 bodies, their contacts included, about 176 MB), once through
the file object and once through HDF5's own driver (a stand-in with h5py's default
file), median of REPS runs each, in one process.

usage::

    python benchmarks/output_driver.py    # writes benchmarks/results/output_driver.json

environment: REPS (3).
"""

import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "output_driver.json"


class _Native:
    """HDF5's own driver behind the interface of dem.io.files.H5Output."""

    def __init__(self, path, mode="w", name=None):
        import h5py

        self.h5 = h5py.File(path, mode)

    def failure(self, err):
        return None

    def close(self, sync=False):
        self.h5.close()

    def abandon(self):
        self.h5.close()


def _scene():
    import numpy as np

    import dem

    n = 20
    b = dem.Bodies.empty(3)
    g = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
    b.add_spheres(g * 0.0099 + 0.005, 0.005, density=2500.0)
    b.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    sim = dem.Simulation(b, dem.LinearSpring(kn=1e4, kt=5e3, mu=0.5),
                         gravity=[0.0, 0.0, -9.81])
    sim.run(10, progress=False)
    return sim


def _write(sim, frames=30):
    from dem.io import H5Writer

    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "a.h5")
        t0 = time.perf_counter()
        w = H5Writer(path, every=10**9, contacts=True)
        for _ in range(frames):
            w(sim)
        w.close()
        return time.perf_counter() - t0, os.path.getsize(path)


def main():
    import dem.io.hdf5 as h5mod

    reps = C.env_int("REPS", 3)
    sim = _scene()
    _write(sim, 2)  # warm-up
    ours = [_write(sim) for _ in range(reps)]
    real = h5mod.H5Output
    h5mod.H5Output = _Native
    try:
        native = [_write(sim) for _ in range(reps)]
    finally:
        h5mod.H5Output = real
    t_ours, t_native = C.median([t for t, _ in ours]), C.median([t for t, _ in native])
    result = {"benchmark": "output_driver", "date": C.now(), "machine": C.machine_info(),
              "versions": C.our_versions(), "revision": C.git_revision(),
              "loadavg": C.loadavg(), "reps": reps, "bodies": sim.bodies.n,
              "frames": 30, "file_mb": ours[0][1] / 1e6, "file_object_s": t_ours,
              "native_s": t_native, "ratio_file_object_to_native": t_ours / t_native}
    C.write_json(OUT, result)
    print(f"file object {t_ours:.3f} s, HDF5 driver {t_native:.3f} s: "
          f"{t_ours / t_native:.3f}; wrote {C.display_path(OUT)}")


if __name__ == "__main__":
    C.entry(main, None)
