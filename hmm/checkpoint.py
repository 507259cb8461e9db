"""Checkpoint and restart of a multiscale run: the macro state and every micro model.

``checkpoint.h5`` in the output directory, rewritten atomically (a temporary file,
then a rename) every ``[output] checkpoint_every`` load steps::

    /            attrs: format = "hmm.checkpoint", version, step, problem (a digest
                 of the validated problem, output settings excluded)
    /solver/     u (n_dofs,), sigma (n_gp, d, d), tangent (n_gp, d, d, d, d),
                 iterations (k,), attrs: t, cuts, trials
    /curve/      the load-displacement curve so far (as in ``fields.h5``)
    /micro/NNNNNN/  each Gauss point's committed state (``MicroModel.export``)

``hmm run problem.toml --restart`` reads it, checks that the problem is the same,
and continues: the result is bit for bit that of an uninterrupted run, with any
number of ranks. A killed job loses at most the steps since the last checkpoint.
"""

import hashlib
import json
import os

import h5py
import numpy as np

from dem.io.hdf5 import publish

FORMAT = "hmm.checkpoint"
VERSION = 1


def problem_digest(problem):
    """A digest of the validated problem that ignores where output goes."""
    data = {k: v for k, v in problem.items() if k not in ("output", "source")}
    text = json.dumps(data, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def save(path, problem, step, solver, curve, micro_states):
    """Write a checkpoint (rank 0) atomically."""
    path = os.fspath(path)
    tmp = path + ".tmp"
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs["format"] = FORMAT
            f.attrs["version"] = VERSION
            f.attrs["step"] = int(step)
            f.attrs["problem"] = problem_digest(problem)
            g = f.create_group("solver")
            g.attrs["t"] = float(solver.t)
            g.attrs["cuts"] = int(solver.cuts)
            g.attrs["trials"] = int(solver.farm.n_trials)
            g.create_dataset("u", data=solver.u)
            g.create_dataset("sigma", data=solver.sigma)
            g.create_dataset("tangent", data=solver.tangent)
            g.create_dataset("iterations", data=np.asarray(solver.iterations, np.int64))
            for k, v in curve.items():
                f.create_dataset(f"curve/{k}", data=np.asarray(v, dtype=np.float64))
            for pt, state in micro_states.items():
                mg = f.create_group(f"micro/{pt:06d}")
                for k, v in state.items():
                    mg.create_dataset(k, data=np.asarray(v))
        publish(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return path


class Checkpoint:
    """A checkpoint opened for a restart (read-only; close when done)."""

    def __init__(self, path, problem):
        self.path = os.fspath(path)
        if not os.path.exists(self.path):
            raise FileNotFoundError(f"no checkpoint to restart from: {self.path}")
        try:
            self.f = h5py.File(self.path, "r")
        except OSError as err:
            raise ValueError(f"{self.path} is not a readable checkpoint ({err})") from None
        f = self.f
        tag = f.attrs.get("format")
        if isinstance(tag, bytes):
            tag = tag.decode()
        if tag != FORMAT or f.attrs.get("version") != VERSION:
            self.close()
            raise ValueError(f"{self.path} is not an {FORMAT} file (version {VERSION})")
        digest = f.attrs["problem"]
        digest = digest.decode() if isinstance(digest, bytes) else str(digest)
        if digest != problem_digest(problem):
            self.close()
            raise ValueError(f"{self.path} belongs to another problem (the problem file "
                             f"changed since it was written)")
        self.step = int(f.attrs["step"])

    def restore_solver(self, solver):
        g = self.f["solver"]
        n, gp = solver.macro.n_dofs, solver.macro.n_gp
        d = solver.macro.dim
        for name, shape in (("u", (n,)), ("sigma", (gp, d, d)),
                            ("tangent", (gp, d, d, d, d))):
            if g[name].shape != shape:
                raise ValueError(f"{self.path}: solver/{name} has shape {g[name].shape}, "
                                 f"expected {shape}")
        solver.u = g["u"][()]
        solver.sigma = g["sigma"][()]
        solver.tangent = g["tangent"][()]
        solver.t = float(g.attrs["t"])
        solver.cuts = int(g.attrs["cuts"])
        solver.iterations = [int(x) for x in g["iterations"][()]]
        solver.farm.n_trials = int(g.attrs["trials"])

    def curve(self):
        out = {}
        self.f["curve"].visititems(lambda name, obj: out.__setitem__(name, obj[()])
                                   if isinstance(obj, h5py.Dataset) else None)
        return out

    def micro_state(self, g):
        grp = self.f[f"micro/{g:06d}"]
        out = {}
        grp.visititems(lambda name, obj: out.__setitem__(name, obj[()])
                       if isinstance(obj, h5py.Dataset) else None)
        return out

    def close(self):
        if self.f is not None:
            self.f.close()
            self.f = None
