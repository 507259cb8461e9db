"""Farms: everything the macro solver asks of its Gauss points goes through one.

A farm owns the micro models of the Gauss points (flat index ``e * n_qp + q``: element
``e``, quadrature point ``q``) and answers for all of them at once:

``trial(deps)``
    (n, d, d) strain increments in, (n, d, d) stresses and (n, d, d, d, d) tangents
    out, from the committed states;
``commit()`` / ``rollback()``
    after a converged / a failed load step;
``measures()``
    per-point arrays of the committed state (:func:`hmm.micro.measure_shapes`: void
    ratio, coordination, ran_dem, fabric, anisotropy, couple stress) and the cost of
    the last trial (seconds, DEM steps), and ``work``: the RVE calls, their seconds
    and DEM steps since the farm was made.

:class:`SerialFarm` runs them in this process; an MPI farm with the same calls
distributes them over ranks. A micro model that raises ends the trial with a
:class:`MicroFailure` naming the Gauss point, so the solver can cut the step.

Signals (:mod:`hmm.signals`): under MPI the farm opens a
:class:`~hmm.signals.SignalWatch` with itself, so that SIGINT or SIGTERM on any rank
ends it on every rank with :class:`~hmm.signals.Interrupted`; serially,
:func:`~hmm.signals.interrupt` raises it at once.
"""

import logging
import math
import time

import numpy as np

from .micro import measure_shapes
from .signals import SignalWatch, log_pids, raise_pending

log = logging.getLogger(__name__)


def flatten_measures(rows, dim):
    """(n, width) array of the micro models' ``measures()`` rows, in the order and
    shapes of :func:`hmm.micro.measure_shapes` (what a farm gathers)."""
    shapes = measure_shapes(dim)
    width = sum(math.prod(shape) for shape in shapes.values())
    return np.array([np.concatenate([np.ravel(np.asarray(r[k], dtype=np.float64))
                                     for k in shapes]) for r in rows],
                    dtype=np.float64).reshape(len(rows), width)


def unflatten_measures(flat, dim):
    """The dict of (n, ...) arrays of :func:`flatten_measures`' rows ``flat``."""
    out, at = {}, 0
    for k, shape in measure_shapes(dim).items():
        size = math.prod(shape)
        out[k] = flat[:, at:at + size].reshape(flat.shape[0], *shape)
        at += size
    return out


def mpi_world():
    """``(MPI, COMM_WORLD)`` when this process runs under ``mpiexec`` with more than one
    rank, else ``(None, None)``. mpi4py is imported in this module only (here and by
    :class:`MPIFarm`), and only when needed: a serial run never loads MPI."""
    import os

    if not any(k in os.environ for k in ("PMI_RANK", "PMI_SIZE", "OMPI_COMM_WORLD_SIZE",
                                         "MPI_LOCALNRANKS", "PMIX_RANK")):
        return None, None
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    return (MPI, comm) if comm.Get_size() > 1 else (None, None)


class MicroFailure(RuntimeError):
    """A micro model failed; ``point`` is its Gauss point index. ``recoverable``: the
    physics failed (an RVE that cannot relax, a blown-up step), which a smaller load
    step may cure; anything else is a bug or bad input, and the run must stop."""

    def __init__(self, point, message, recoverable=False):
        super().__init__(f"Gauss point {point}: {message}")
        self.point = int(point)
        self.recoverable = bool(recoverable)


def _recoverable(err):
    from dem.simulation import SimulationError

    return isinstance(err, (SimulationError, ArithmeticError))


class SerialFarm:
    """The Gauss points' micro models, run one after the other in this process."""

    def __init__(self, models):
        self.models = list(models)
        if not self.models:
            raise ValueError("a farm needs at least one micro model")
        self.dim = self.models[0].dim
        if any(m.dim != self.dim for m in self.models):
            raise ValueError("every micro model of a farm must have the same dimension")
        n, d = len(self.models), self.dim
        self.n = n
        self.cost = np.zeros(n)  # seconds of each point's last trial
        self.steps = np.zeros(n, np.int64)  # DEM steps of each point's last trial
        self._sig = np.empty((n, d, d))
        self._c = np.empty((n, d, d, d, d))
        self.n_trials = 0
        #: the farm's work since it was made: RVE (micro model) calls, their seconds
        #: (summed over points) and DEM steps
        self.work = np.zeros(3)

    def trial(self, deps):
        raise_pending()
        deps = np.asarray(deps, dtype=np.float64)
        if deps.shape != (self.n, self.dim, self.dim):
            raise ValueError(f"strain increments must be ({self.n}, {self.dim}, "
                             f"{self.dim}), got {deps.shape}")
        for k, m in enumerate(self.models):
            t0 = time.perf_counter()
            try:
                self._sig[k], self._c[k] = m.trial(deps[k])
            except Exception as err:  # any failure of a point is reported as its own
                raise MicroFailure(k, f"{type(err).__name__}: {err}",
                                   _recoverable(err)) from err
            self.cost[k] = time.perf_counter() - t0
            self.steps[k] = getattr(m, "steps", 0)
            self.work += (1.0, self.cost[k], self.steps[k])
        self.n_trials += 1
        return self._sig.copy(), self._c.copy()

    def commit(self):
        for m in self.models:
            m.commit()

    def rollback(self):
        for m in self.models:
            m.rollback()

    def measures(self):
        out = unflatten_measures(flatten_measures(
            [m.measures() for m in self.models], self.dim), self.dim)
        out["cost"] = self.cost.copy()
        out["steps"] = self.steps.copy()
        out["work"] = self.work.copy()
        return out

    def stress(self):
        """Committed stresses (n, d, d) [Pa]."""
        return np.array([m.stress for m in self.models])

    def export(self):
        """Every point's committed state, ``{g: {name: array}}`` (for checkpoints)."""
        return {g: m.export() for g, m in enumerate(self.models)}

    def load(self, read):
        """Set every point's committed state from ``read(g) -> {name: array}``."""
        for g, m in enumerate(self.models):
            m.load(read(g))


def make_farm(n, dim, factory):
    """A farm of the micro models ``factory(g)`` of ``n`` Gauss points ``g = 0..n-1``
    (each ``dim``-dimensional): an :class:`MPIFarm` when this process is one of several
    MPI ranks (every rank must call this, and every rank but 0 then calls
    :meth:`MPIFarm.serve`), else a :class:`SerialFarm`. Under MPI each rank builds only
    the models of the points it owns."""
    _, comm = mpi_world()
    if comm is not None:
        return MPIFarm(comm, n, dim, factory)
    return SerialFarm([factory(g) for g in range(n)])


class MPIFarm:
    """The Gauss points spread over the ranks of ``comm`` in contiguous blocks.

    Every rank builds the farm; rank 0 then calls :meth:`trial`, :meth:`commit`,
    :meth:`rollback`, :meth:`measures`, :meth:`stress` exactly as on a
    :class:`SerialFarm`, and :meth:`close` at the end, while the other ranks sit in
    :meth:`serve`. Per call, rank 0 broadcasts a command; strain increments go out by
    ``Scatterv`` and stresses, tangents and costs come back by ``Gatherv``, as float64
    buffers. A micro model's exception is caught on its rank and reported to rank 0
    with the Gauss point's id (a :class:`MicroFailure`), so no rank is ever left
    waiting. At each commit, ownership is rebalanced from the measured cost of the
    last trial: points change rank with their committed state (``export``/``load``),
    never inside a load step. Results are bit for bit those of a serial farm.

    Commands go to the other ranks as point-to-point messages that they poll for,
    and after a trial every rank reports ready before the gathers start, so no rank
    ever blocks while another computes. A SIGINT or SIGTERM on any rank
    (:class:`~hmm.signals.SignalWatch`, opened with the farm) ends the farm on every rank with
    :class:`~hmm.signals.Interrupted` at rank 0's next check: between its micro-model calls, at
    each call of the farm or in a wait. Committed states are untouched: the last
    checkpoint and the steps written so far stay valid.

    Parameters
    ----------
    comm : mpi4py communicator
    n, dim : int
        Gauss points and dimension.
    factory : callable
        ``factory(g)`` builds point ``g``'s micro model in its initial state (on the
        rank that owns it).
    """

    #: rebalance when the largest rank's cost exceeds the mean by this factor
    IMBALANCE = 1.1

    def __init__(self, comm, n, dim, factory):
        from mpi4py import MPI  # the farm exists only under MPI

        self.comm, self._MPI = comm, MPI
        self.rank, self.size = comm.Get_rank(), comm.Get_size()
        self.n, self.dim = int(n), int(dim)
        self.factory = factory
        self.bounds = np.round(np.linspace(0, self.n, self.size + 1)).astype(np.int64)
        lo, hi = self.bounds[self.rank], self.bounds[self.rank + 1]
        self.cost = np.zeros(self.n)
        self.steps = np.zeros(self.n, np.int64)
        self.n_trials = 0
        self.work = np.zeros(3)  # as SerialFarm.work (rank 0)
        self.n_migrated = 0  # points moved between ranks so far
        self._open = True
        log_pids(comm)
        self.watch = SignalWatch(comm, MPI, leader=True).open()
        top = self.watch.tag  # the farm's own tags, just under the watch's
        self._tag_cmd, self._tag_ready, self._tag_go = top - 1, top - 2, top - 3
        self.models = {}
        try:
            self.models = {g: factory(g) for g in range(lo, hi)}
        except BaseException:
            self.watch.close()
            raise

    # ------------------------------------------------------------------ rank 0
    def trial(self, deps):
        deps = np.ascontiguousarray(deps, dtype=np.float64)
        if deps.shape != (self.n, self.dim, self.dim):
            raise ValueError(f"strain increments must be ({self.n}, {self.dim}, "
                             f"{self.dim}), got {deps.shape}")
        self._command("trial")
        return self._trial(deps)

    def commit(self):
        self._command("commit")
        self._commit()

    def rollback(self):
        self._command("rollback")
        self._rollback()

    def measures(self):
        self._command("measures")
        return self._measures()

    def stress(self):
        self._command("stress")
        return self._stress()

    def export(self):
        """Every point's committed state on rank 0, ``{g: {name: array}}``."""
        self._command("export")
        return self._export()

    def load(self, read):
        """Set the committed state of this rank's points from ``read(g)``; every rank
        calls it (each reads its own points), before rank 0 starts driving."""
        for g, m in self.models.items():
            m.load(read(g))

    def close(self):
        """Release the other ranks from :meth:`serve` and put the signal handlers
        back (rank 0; idempotent). Never raises: a signal that arrives after the
        last call of the farm lets the finished run end normally."""
        if self._open and self.rank == 0:
            self._open = False
            self.watch.close()
            if not self.watch.stopped:
                for r in range(1, self.size):
                    self.comm.send("stop", dest=r, tag=self._tag_cmd)
        self._open = False

    def _command(self, cmd):
        self.watch.check()
        for r in range(1, self.size):
            self.comm.send(cmd, dest=r, tag=self._tag_cmd)

    # ------------------------------------------------------------------ other ranks
    def serve(self):
        """Answer rank 0's commands until it closes the farm (or stops it:
        :class:`Interrupted`)."""
        try:
            self._serve()
        finally:
            self._open = False
            self.watch.close()

    def _serve(self):
        while True:
            self.watch.wait(lambda: self.comm.Iprobe(source=0, tag=self._tag_cmd))
            cmd = self.comm.recv(source=0, tag=self._tag_cmd)
            if cmd == "stop":
                return
            if cmd == "trial":
                self._trial(None)
            elif cmd == "commit":
                self._commit()
            elif cmd == "rollback":
                self._rollback()
            elif cmd == "measures":
                self._measures()
            elif cmd == "stress":
                self._stress()
            elif cmd == "export":
                self._export()

    # ------------------------------------------------------------------ collectives
    def _mine(self):
        return range(self.bounds[self.rank], self.bounds[self.rank + 1])

    def _counts(self, per_point):
        c = np.diff(self.bounds) * per_point
        return c, np.concatenate([[0], np.cumsum(c)[:-1]])

    def _scatter(self, full, per_point):
        own = np.empty(len(self._mine()) * per_point)
        counts, displs = self._counts(per_point)
        send = [full, counts, displs, self._MPI.DOUBLE] if self.rank == 0 else None
        self.comm.Scatterv(send, own, root=0)
        return own

    def _gather(self, own, per_point):
        counts, displs = self._counts(per_point)
        full = np.empty(self.n * per_point) if self.rank == 0 else None
        recv = [full, counts, displs, self._MPI.DOUBLE] if self.rank == 0 else None
        self.comm.Gatherv(np.ascontiguousarray(own, dtype=np.float64), recv, root=0)
        return full

    def _trial(self, deps):
        d = self.dim
        dd, d4 = d * d, d ** 4
        mine = self._mine()
        own = self._scatter(deps.ravel() if deps is not None else None, dd)
        own = own.reshape(len(mine), d, d)
        sig = np.zeros((len(mine), dd))
        c = np.zeros((len(mine), d4))
        cost = np.zeros((len(mine), 2))
        failure = None
        for k, g in enumerate(mine):
            self.watch.check()
            if self.watch.told_at is not None:
                break  # a signal here: rank 0 stops the farm after this trial
            t0 = time.perf_counter()
            try:
                s, t = self.models[g].trial(own[k])
            except Exception as err:  # noqa: BLE001 - reported with the point's id
                failure = (g, f"{type(err).__name__}: {err}", _recoverable(err))
                break
            sig[k], c[k] = s.ravel(), t.ravel()
            cost[k] = time.perf_counter() - t0, getattr(self.models[g], "steps", 0)
        failures = self._meet(failure)
        sig = self._gather(sig, dd)
        c = self._gather(c, d4)
        cost = self._gather(cost, 2)
        if self.rank != 0:
            return None
        if self._told:  # a rank got a signal and skipped its points: its message
            self.watch.wait(lambda: False)  # is on its way; stop when it is in
        self.n_trials += 1
        cost = cost.reshape(self.n, 2)
        self.cost[:] = cost[:, 0]
        self.steps[:] = cost[:, 1]
        self.work += (np.count_nonzero(cost[:, 0] > 0.0), cost[:, 0].sum(), cost[:, 1].sum())
        bad = [f for f in failures if f is not None]
        if bad:
            raise MicroFailure(*min(bad))
        return sig.reshape(self.n, d, d), c.reshape(self.n, d, d, d, d)

    def _meet(self, failure):
        """Every rank past its micro models, polled: rank 0 collects each rank's
        failure (or None) and sends the go for the gathers."""
        comm = self.comm
        if self.rank != 0:
            comm.send((failure, self.watch.told_at is not None), dest=0,
                      tag=self._tag_ready)
            self.watch.wait(lambda: comm.Iprobe(source=0, tag=self._tag_go))
            comm.recv(source=0, tag=self._tag_go)
            return None
        failures, self._told = [failure], False
        for r in range(1, self.size):
            self.watch.wait(lambda r=r: comm.Iprobe(source=r, tag=self._tag_ready))
            failure, told = comm.recv(source=r, tag=self._tag_ready)
            failures.append(failure)
            self._told |= told
        for r in range(1, self.size):
            comm.send(None, dest=r, tag=self._tag_go)
        return failures

    def _commit(self):
        for m in self.models.values():
            m.commit()
        self._rebalance()

    def _rollback(self):
        for m in self.models.values():
            m.rollback()

    def _measures(self):
        mine = list(self._mine())
        own = flatten_measures([self.models[g].measures() for g in mine], self.dim)
        width = own.shape[1]
        full = self._gather(own, width)
        if self.rank != 0:
            return None
        out = unflatten_measures(full.reshape(self.n, width), self.dim)
        out["cost"] = self.cost.copy()
        out["steps"] = self.steps.copy()
        out["work"] = self.work.copy()
        return out

    def _stress(self):
        d = self.dim
        mine = list(self._mine())
        own = np.array([np.asarray(self.models[g].stress).ravel() for g in mine])
        full = self._gather(own.reshape(len(mine), d * d), d * d)
        return None if self.rank != 0 else full.reshape(self.n, d, d)

    def _export(self):
        parts = self.comm.gather({g: m.export() for g, m in self.models.items()}, root=0)
        if self.rank != 0:
            return None
        return {g: st for part in parts for g, st in part.items()}

    def balance_cost(self):
        """Cost of each point that the rebalancing evens out: its last trial's
        measured time (an elastic point still costs a little)."""
        return np.maximum(self.cost, 1e-6)

    def _rebalance(self):
        """New contiguous blocks of equal measured cost; points move with their
        committed state."""
        new = None
        if self.rank == 0:
            cum = np.concatenate([[0.0], np.cumsum(self.balance_cost())])
            per_rank = np.diff(cum[self.bounds])
            if self.n >= self.size and per_rank.max() > self.IMBALANCE * per_rank.mean():
                cuts = np.searchsorted(cum, cum[-1] * np.arange(1, self.size) / self.size)
                new = np.concatenate([[0], np.clip(cuts, 0, self.n), [self.n]])
                new = new.astype(np.int64)
                for k in range(1, self.size):  # every rank keeps at least one point
                    new[k] = min(max(new[k], new[k - 1] + 1), self.n - (self.size - k))
                if np.array_equal(new, self.bounds):
                    new = None
        new = self.comm.bcast(new, root=0)
        if new is None:
            return
        old = self.bounds
        owner_old = np.repeat(np.arange(self.size), np.diff(old))
        owner_new = np.repeat(np.arange(self.size), np.diff(new))
        requests = []
        for g in list(self.models):
            dest = owner_new[g]
            if dest != self.rank:
                requests.append(self.comm.isend(self.models.pop(g).export(), dest=dest,
                                                tag=g))
        for g in range(new[self.rank], new[self.rank + 1]):
            if owner_old[g] != self.rank:
                m = self.factory(g)
                m.load(self.comm.recv(source=owner_old[g], tag=g))
                self.models[g] = m
        for r in requests:
            r.wait()
        self.n_migrated += int(np.count_nonzero(owner_old != owner_new))
        self.bounds = new
