"""The master-worker queue that runs the experiments of a sweep over MPI ranks.

:func:`run_batch` is collective over the ranks (``mpiexec -n N hmm batch sweep.toml``):

* rank 0, the master, keeps the queue: it hands one experiment to each idle worker
  (``send``/``recv`` with tags; the messages are small), records every reply in one
  HDF5 file (:class:`hmm.batch.Store`, flushed after each) and runs experiments itself
  between replies, answering the workers after every increment of its own experiment;
  with one rank it runs them all, through the same code;
* a worker runs what it is given (:func:`run_one`) and replies with the summary and
  the curves, or with the error; it checks for a stop message after every increment.

Faults: a :class:`dem.rve.RelaxationError` (the packing did not relax) is recorded as
a failed experiment and the batch goes on; any other exception is a bug or unusable
input: rank 0 tells every rank to stop (a rank busy with an experiment stops after
its current increment) and the batch ends with a message naming the experiment.
Every path through :func:`run_batch` ends with all workers stopped and the outcome
sent from rank 0, so no rank is left waiting. Every wait polls, and a SIGINT or
SIGTERM on any rank (:class:`hmm.signals.SignalWatch`) ends the batch on every rank
with :class:`hmm.signals.Interrupted` within milliseconds of its next check (after each
increment, in each wait); ``batch.h5`` holds every experiment recorded before it.

The sweep file, the experiment ids, ``batch.h5`` (and resuming it) and the summaries
are :mod:`hmm.batch`'s.
"""

import logging
import sys
import time
import traceback
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

from dem.io.schema import SceneError

from .batch import OUTPUTS, Store, write_summaries
from .experiment import compress, make_packing
from .farm import mpi_world
from .signals import Interrupted, SignalWatch, log_pids, raise_pending

log = logging.getLogger(__name__)

__all__ = ["BatchReport", "RankFailure", "run_batch", "run_one"]

TAG_TASK, TAG_STOP, TAG_DONE, TAG_FAILED, TAG_ABANDONED, TAG_OUTCOME = range(11, 17)
_POLL_S = 0.002  # sleep between probes while waiting (a blocking recv spins a core)


# --------------------------------------------------------------------------- one run
class _Stopped(Exception):
    """Rank 0 asked this rank to stop: the experiment under way is abandoned."""


def run_one(cfg, poll=None):
    """Run the test of a validated config in memory: ``(curves, summary)``.

    The procedure and the results are those of
    :func:`hmm.experiment.run_experiment`, which writes files; this writes nothing.
    ``poll()`` is called between the phases and after every increment; it may raise
    to abandon the test. ``summary["wall_time"]`` [s] is added.
    """
    t0 = time.perf_counter()
    poll = poll or (lambda: None)
    packing = make_packing(cfg)
    poll()
    result = compress(cfg, lambda k: poll(), packing)
    result.summary["wall_time"] = time.perf_counter() - t0
    return result.curves, result.summary


def _attempt(exp_id, cfg, poll):
    """Run one experiment: ``(tag, payload)`` for the reply to rank 0."""
    from dem.rve import RelaxationError

    try:
        curves, summary = run_one(cfg, poll)
    except _Stopped:
        return TAG_ABANDONED, exp_id
    except Exception as exc:  # noqa: BLE001 - reported to rank 0, which decides
        message = " ".join(f"{type(exc).__name__}: {exc}".split())
        return TAG_FAILED, (exp_id, isinstance(exc, RelaxationError), message,
                            traceback.format_exc())
    return TAG_DONE, (exp_id, curves, summary)


# --------------------------------------------------------------------------- ranks
@dataclass
class BatchReport:
    """What a batch did; the same object on every rank."""

    n_total: int
    n_skipped: int = 0  # already in batch.h5
    n_done: int = 0  # status "done" in batch.h5 at the end (resumed ones included)
    n_failed: int = 0  # status "failed" (RelaxationError)
    aborted: str = None  # the one-line reason the batch stopped early
    files: list = field(default_factory=list)
    wall_time: float = 0.0
    ranks: int = 1


class RankFailure(RuntimeError):
    """Raised on the workers when rank 0 failed; ``code`` is its exit status."""

    def __init__(self, code):
        super().__init__(f"the batch failed on rank 0 (exit status {code})")
        self.code = int(code)


class _Master:
    """Rank 0: the queue, the replies, the file; runs experiments itself too.

    Every worker always holds exactly one task or has been sent a stop. Rank 0
    answers a reply with the next task or the stop as soon as it sees it: at once
    when idle, else after its current increment (or packing phase).
    """

    def __init__(self, MPI, comm, watch=None):
        self.MPI, self.comm, self.watch = MPI, comm, watch
        self.workers = range(1, comm.size) if comm is not None else range(0)
        self.busy, self.stopped = {}, set()
        self.store, self.bar, self.queue, self.by_id = None, None, deque(), {}
        self.abort = None

    # -- workers
    def _send_next(self, rank):
        if self.queue and self.abort is None:
            e = self.queue.popleft()
            self.comm.send((e.id, e.config), dest=rank, tag=TAG_TASK)
            self.busy[rank] = e
        else:
            self.stop(rank)

    def stop(self, rank):
        if rank not in self.stopped:
            self.comm.send(None, dest=rank, tag=TAG_STOP)
            self.stopped.add(rank)

    def service(self, block=False):
        """Take every reply that has arrived (with ``block``: wait for one)."""
        if self.comm is None:
            return
        status = self.MPI.Status()
        while True:
            self.watch.check()
            if not self.comm.Iprobe(source=self.MPI.ANY_SOURCE,
                                    tag=self.MPI.ANY_TAG, status=status):
                if not block:
                    return
                time.sleep(_POLL_S)
                continue
            rank, tag = status.Get_source(), status.Get_tag()
            payload = self.comm.recv(source=rank, tag=tag)
            if tag == self.watch.tag:  # a signal on that rank
                self.watch.received(rank, payload)
                self.watch.check()
            self.busy.pop(rank, None)
            if self.store is not None:  # None while shutting down after a failure
                if tag == TAG_DONE:
                    self._record_done(self.by_id[payload[0]], *payload[1:], rank)
                elif tag == TAG_FAILED:
                    self._record_failure(self.by_id[payload[0]], *payload[1:], rank)
            if rank not in self.stopped:
                self._send_next(rank)
            block = False

    def shutdown(self, reason):
        """Stop every worker and take their last replies (after a failure)."""
        self.store, self.abort = None, self.abort or reason
        for rank in self.workers:
            self.stop(rank)
        deadline = time.monotonic() + 60.0
        while self.busy and time.monotonic() < deadline:
            self.service()
            time.sleep(_POLL_S)

    # -- results
    def _record_done(self, e, curves, summary, rank):
        self.store.done(e, curves, summary, rank)
        log.info("experiment %s done on rank %d in %.1f s", e.id, rank,
                 summary["wall_time"])
        self._tick()

    def _record_failure(self, e, is_relaxation, message, tb, rank):
        if is_relaxation:
            self.store.failed(e, message, rank)
            log.warning("experiment %s failed on rank %d: %s", e.id, rank, message)
            self._tick()
            return
        log.debug("experiment %s on rank %d:\n%s", e.id, rank, tb)
        if self.abort is None:
            self.abort = f"experiment {e.id} raised {message} (rank {rank})"
            for r in list(self.busy):  # they stop after their current increment
                self.stop(r)

    def _tick(self):
        if self.bar is not None:
            self.bar.update(1)

    # -- the loop
    def _poll(self):
        raise_pending()
        self.service()
        if self.abort is not None:
            raise _Stopped

    def run(self, store, todo, bar):
        """Hand out, run, record until the queue is empty; every worker stopped."""
        self.store, self.bar = store, bar
        self.queue, self.by_id = deque(todo), {e.id: e for e in todo}
        for rank in self.workers:
            self._send_next(rank)
        while self.abort is None:
            self.service()
            if not self.queue or self.abort is not None:
                break
            e = self.queue.popleft()
            tag, payload = _attempt(e.id, e.config, self._poll)
            if tag == TAG_DONE:
                self._record_done(e, *payload[1:], 0)
            elif tag == TAG_FAILED:
                self._record_failure(e, *payload[1:], 0)
        while self.busy:
            self.service(block=True)
        for rank in self.workers:
            self.stop(rank)


def run_batch(sweep, out_dir=None, overwrite=False, progress=None, world=None):
    """Run the experiments of a sweep; collective over the ranks of ``world``.

    Parameters
    ----------
    sweep : Sweep
        From :func:`load_sweep` (used on rank 0; other ranks may pass None).
    out_dir : str or Path, optional
        Output directory (default the sweep's ``[output] dir``).
    overwrite : bool
        Replace an existing ``batch.h5`` instead of resuming it.
    progress : bool, optional
        A progress bar over the experiments on rank 0 (default: stderr is a terminal).
    world : (MPI, comm), optional
        Default :func:`hmm.farm.mpi_world`; ``(None, None)`` runs in this process.

    Returns
    -------
    BatchReport
        On every rank. ``aborted`` is set when an experiment raised anything but a
        RelaxationError; the experiments finished before it are kept.

    Raises
    ------
    SceneError
        On every rank, before anything ran: ``batch.h5`` holds another sweep.
    """
    MPI, comm = mpi_world() if world is None else world
    if comm is None:
        return _lead(sweep, out_dir, overwrite, progress, _Master(None, None))
    log_pids(comm)
    watch = SignalWatch(comm, MPI).open()
    try:
        if comm.rank != 0:
            return _work(MPI, comm, watch)
        return _master(sweep, out_dir, overwrite, progress, _Master(MPI, comm, watch))
    finally:
        watch.close()


def _work(MPI, comm, watch):
    _serve(MPI, comm, watch)
    watch.wait(lambda: comm.Iprobe(source=0, tag=TAG_OUTCOME))
    outcome = comm.recv(source=0, tag=TAG_OUTCOME)
    if isinstance(outcome, str):
        raise SceneError(outcome)
    if isinstance(outcome, int):
        raise RankFailure(outcome)
    return outcome


def _master(sweep, out_dir, overwrite, progress, master):
    try:
        report = _lead(sweep, out_dir, overwrite, progress, master)
        master.watch.check()  # a signal while the summaries were written
    except Interrupted:
        raise  # every rank stops on its own (SignalWatch)
    except (SceneError, OSError) as exc:  # bad input, or an output the disk refuses:
        master.shutdown(str(exc))          # every rank ends with status 2
        _send_outcome(master.comm, str(exc))
        raise
    except BaseException:
        master.shutdown("rank 0 failed")
        _send_outcome(master.comm, 1)
        raise
    _send_outcome(master.comm, report)
    return report


def _send_outcome(comm, value):
    """The batch's outcome to every worker (each polls for it)."""
    for rank in range(1, comm.size):
        comm.send(value, dest=rank, tag=TAG_OUTCOME)


def _lead(sweep, out_dir, overwrite, progress, master):
    t0 = time.perf_counter()
    from dem.io.files import OutputError
    from dem.io.plan import check_new_files

    out = Path(sweep.out_dir if out_dir is None else out_dir)
    files = [out / name for name in OUTPUTS]
    check_new_files(files, True)  # a directory in the place of an output, before a run
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(out, err) from None
    store = Store(files[0], sweep, overwrite)
    try:
        todo = [e for e in sweep.experiments if e.id not in store.stored]
        n = len(sweep.experiments)
        report = BatchReport(n, n - len(todo), files=[str(f) for f in files],
                             ranks=1 if master.comm is None else master.comm.size)
        bar = None
        if (sys.stderr.isatty() if progress is None else progress) and todo:
            from tqdm import tqdm

            bar = tqdm(total=n, initial=report.n_skipped, unit="experiment",
                       leave=False)
        try:
            master.run(store, todo, bar)
        finally:
            if bar is not None:
                bar.close()
        report.aborted = master.abort
        statuses = list(store.stored.values())
    finally:
        store.close()
    report.n_done, report.n_failed = statuses.count("done"), statuses.count("failed")
    write_summaries(files[0], sweep, files[1], files[2])
    report.wall_time = time.perf_counter() - t0
    return report


def _serve(MPI, comm, watch):
    """A worker: run what rank 0 sends until it says stop."""
    status = MPI.Status()

    def poll():
        watch.check()
        if comm.Iprobe(source=0, tag=TAG_STOP):
            raise _Stopped

    while True:
        watch.wait(lambda: comm.Iprobe(source=0, tag=MPI.ANY_TAG, status=status))
        tag = status.Get_tag()
        payload = comm.recv(source=0, tag=tag)
        if tag == watch.tag:  # rank 0 stops on a signal
            watch.received(0, payload)
            watch.check()
        if tag == TAG_STOP:
            return
        reply_tag, reply = _attempt(*payload, poll)
        comm.send(reply, dest=0, tag=reply_tag)
