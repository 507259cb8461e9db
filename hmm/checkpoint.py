"""Checkpoint and restart of a multiscale run: the macro state and every micro model.

``checkpoint.h5`` in the output directory, rewritten atomically (a temporary file,
then a rename) every ``[output] checkpoint_every`` load steps::

    /            attrs: format = "hmm.checkpoint", version, software, config (the
                 problem as JSON), step, problem (a digest of the validated
                 problem, output settings excluded)
    /solver/     u (n_dofs,), sigma (n_gp, d, d), tangent (n_gp, d, d, d, d),
                 iterations (k,), attrs: t, cuts, trials; after a converged step
                 the last one's increment, last_increment (n_dofs,), and attr
                 last_step (its size, the extrapolated predictor's source)
    /curve/      the load-displacement curve so far (as in ``fields.h5``)
    /micro/NNNNNN/  each Gauss point's committed state (``MicroModel.export``)

Every dataset carries ``unit`` (and ``sign`` where it matters): :func:`checkpoint_units`.

``hmm run problem.toml --restart`` reads it, checks that the problem is the same,
and continues: the result is bit for bit that of an uninterrupted run, with any
number of ranks. A killed job loses at most the steps since the last checkpoint.
"""

import hashlib
import json
import math
import os

import h5py
import numpy as np

from dem.io.meta import state_units
from dem.io.files import write_h5_atomic
from dem.io.hdf5 import read_bounded
from dem.io.meta import COMPRESSION, ONE, TENSION, label, rules, stamp

from .io import WORK_CURVES, field_units

FORMAT = "hmm.checkpoint"
VERSION = 1


#: keys added to problem files after checkpoints of this version were first written,
#: as (section, key, default): a key at its default is left out of the digest, so that
#: a checkpoint of the same problem written before the key existed still restarts
#: (section None: a top-level key; a list section: every entry)
ADDED_KEYS = (("dirichlet", "gradient", None), ("dirichlet", "origin", None),
              (None, "periodic", []), ("load", "gradient", None))


def problem_digest(problem):
    """A digest of the validated problem that ignores where output goes (and the
    :data:`ADDED_KEYS` at their defaults)."""
    data = {k: v for k, v in problem.items() if k not in ("output", "source")}
    for section, key, default in ADDED_KEYS:
        if section is None:
            if key in data and data[key] == default:
                data = {k: v for k, v in data.items() if k != key}
            continue
        entries = data.get(section)
        if isinstance(entries, dict):
            data[section] = {k: v for k, v in entries.items()
                             if not (k == key and v == default)}
        elif isinstance(entries, list):
            data[section] = [{k: v for k, v in e.items() if not (k == key and v == default)}
                             for e in entries]
    text = json.dumps(data, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def checkpoint_units(dim):
    """The unit rules (:func:`dem.io.meta.rules`) of ``checkpoint.h5``: the solver
    state, the curve as in ``fields.h5`` and the micro states (those of a DEM state,
    :func:`dem.io.meta.state_units`)."""
    return rules((r"solver/u", "m", None), (r"solver/last_increment", "m", None),
                 (r"solver/sigma", "Pa", TENSION),
                 (r"solver/tangent", "Pa", None), (r"solver/p", "Pa", COMPRESSION),
                 (r"solver/iterations", ONE, None)) \
        + field_units(dim) + state_units(dim)


def save(path, problem, step, solver, curve, micro_states):
    """Write a checkpoint (rank 0) atomically."""

    def fill(f):
        stamp(f, FORMAT, VERSION, problem)
        f.attrs["step"] = int(step)
        f.attrs["problem"] = problem_digest(problem)
        g = f.create_group("solver")
        g.attrs["t"] = float(solver.t)
        g.attrs["cuts"] = int(solver.cuts)
        g.attrs["trials"] = int(solver.farm.n_trials)
        g.create_dataset("u", data=solver.u)
        g.create_dataset("sigma", data=solver.sigma)
        g.create_dataset("tangent", data=solver.tangent)
        last = getattr(solver, "last_step", None)
        if last is not None:  # the extrapolated predictor's source
            g.attrs["last_step"] = float(last[0])
            g.create_dataset("last_increment", data=last[1])
        if getattr(solver, "p", None) is not None:  # a saturated problem
            g.create_dataset("p", data=solver.p)
        g.create_dataset("iterations", data=np.asarray(solver.iterations, np.int64))
        for k, v in curve.items():
            f.create_dataset(f"curve/{k}", data=np.asarray(v, dtype=np.float64))
        for pt, state in micro_states.items():
            mg = f.create_group(f"micro/{pt:06d}")
            for k, v in state.items():
                mg.create_dataset(k, data=np.asarray(v))
        label(f, checkpoint_units(solver.sigma.shape[-1]))

    return write_h5_atomic(path, fill)


class Checkpoint:
    """A checkpoint opened for a restart (read-only; close when done).

    Every problem with the file is a ValueError with a one-line message: not HDF5,
    another format or problem, a missing part, an array of the wrong shape or dtype,
    or a dataset declaring more data than the file holds (refused before reading).
    """

    def __init__(self, path, problem):
        self.path = os.fspath(path)
        if not os.path.exists(self.path):
            raise FileNotFoundError(f"no checkpoint to restart from: {self.path}")
        try:
            self.f = h5py.File(self.path, "r")
        except OSError as err:
            raise ValueError(f"{self.path} is not a readable checkpoint ({err})") from None
        self._solver = None
        try:
            self._open(problem)
        except BaseException:
            self.close()
            raise

    def _open(self, problem):
        f = self.f
        tag = _text(f.attrs.get("format"))
        version = f.attrs.get("version")
        if tag != FORMAT or not isinstance(version, (int, np.integer)) \
                or version != VERSION:
            raise ValueError(f"{self.path} is not an {FORMAT} file (version {VERSION})")
        if _text(f.attrs.get("problem")) != problem_digest(problem):
            raise ValueError(f"{self.path} belongs to another problem (the problem file "
                             f"changed since it was written)")
        step = f.attrs.get("step")
        if not isinstance(step, (int, np.integer)) \
                or not 0 <= step <= problem["load"]["steps"]:
            raise ValueError(f"{self.path}: step {step!r} is not a load step of the "
                             f"problem")
        self.step = int(step)

    def check(self, macro, curve_names, porous=None, schedule=None):
        """Read and check the solver state and the curve against ``macro`` (and the
        pressure field ``porous`` with its time ``schedule``, a saturated problem)
        before anything is restored or an output file changed; ValueError if
        unusable."""
        try:
            g = self.f["solver"]
            n, gp, d = macro.n_dofs, macro.n_gp, macro.dim
            solver = {}
            for name, shape in (("u", (n,)), ("sigma", (gp, d, d)),
                                ("tangent", (gp, d, d, d, d))):
                solver[name] = self._array(g, name, shape, "f")
            if porous is not None:
                solver["p"] = self._array(g, "p", (porous.n_p,), "f")
            if "last_increment" in g:  # written since the extrapolated predictor
                h = float(g.attrs["last_step"])
                if not (math.isfinite(h) and h > 0.0):
                    raise ValueError(f"solver last_step {h} is not a positive step")
                solver["last_step"] = (h, self._array(g, "last_increment", (n,), "f"))
            solver["iterations"] = self._array(g, "iterations", None, "iu").ravel()
            for name, kind in (("t", float), ("cuts", int), ("trials", int)):
                solver[name] = kind(g.attrs[name])
            end = 1.0 if schedule is None else schedule.end
            if not 0.0 <= solver["t"] <= end * (1.0 + 1e-12):
                what = "load factor" if schedule is None else "time [s]"
                raise ValueError(f"solver {what} {solver['t']} is outside [0, {end:g}]")
            curve = {}
            for name in curve_names:
                if name in WORK_CURVES and name not in self.f["curve"]:
                    continue  # a checkpoint of an earlier version: filled below
                curve[name] = self._array(self.f["curve"], name, None, "fiu")
            for name in set(WORK_CURVES) & set(curve_names) - set(curve):
                curve[name] = np.full(len(curve["load_factor"]), np.nan)
            for g in range(macro.n_gp):
                if not isinstance(self.f.get(f"micro/{g:06d}"), h5py.Group):
                    raise ValueError(f"micro/{g:06d} is missing")
        except (KeyError, TypeError, ValueError, OverflowError, OSError) as err:
            raise ValueError(f"{self.path}: unusable checkpoint: "
                             f"{' '.join(str(err).split())}") from None
        self._solver, self._curve = solver, curve

    def _array(self, group, name, shape, kinds):
        ds = group[name]
        if not isinstance(ds, h5py.Dataset) or ds.dtype.kind not in kinds or (
                shape is not None and ds.shape != shape):
            raise ValueError(f"{group.name.strip('/')}/{name} is "
                             f"{getattr(ds, 'dtype', 'a group')}"
                             f"{getattr(ds, 'shape', '')}, expected "
                             f"{'numbers' if shape is None else shape}")
        return read_bounded(ds, f"{group.name.strip('/')}/{name}")

    def restore_solver(self, solver):
        """Set the solver's state from the checked checkpoint (:meth:`check`)."""
        s = self._solver
        solver.u, solver.sigma, solver.tangent = s["u"], s["sigma"], s["tangent"]
        solver.t, solver.cuts = s["t"], s["cuts"]
        if "p" in s:
            solver.p = s["p"]
        solver.last_step = s.get("last_step")
        solver.iterations = [int(x) for x in s["iterations"]]
        solver.farm.n_trials = s["trials"]

    def curve(self):
        """The checked load-displacement curve (:meth:`check`)."""
        return dict(self._curve)

    def micro_state(self, g):
        """Gauss point ``g``'s committed state, ``{name: array}``."""
        grp = self.f.get(f"micro/{g:06d}")
        if not isinstance(grp, h5py.Group):
            raise ValueError(f"{self.path}: micro/{g:06d} is missing")
        out = {}
        grp.visititems(lambda name, obj: out.__setitem__(name, read_bounded(obj))
                       if isinstance(obj, h5py.Dataset) else None)
        return out

    def close(self):
        if self.f is not None:
            self.f.close()
            self.f = None


def _text(value):
    return value.decode(errors="replace") if isinstance(value, bytes) else value
