"""Signals: SIGINT and SIGTERM end an ``hmm`` command with one line, serially or on
every MPI rank together.

Under MPI a :class:`SignalWatch` notes SIGINT and SIGTERM on every rank and turns them
into :class:`Interrupted` on all ranks together, within milliseconds of a rank's next
check (between micro-model calls and in every wait; the waits poll instead of blocking).
Serially, :func:`interrupt` raises it at once. The MPI farm (:class:`hmm.farm.MPIFarm`)
and the batch queue (:mod:`hmm.queue`) open a watch; the ``mpi4py`` module reaches it
from :func:`hmm.farm.mpi_world`, the only place it is imported.
"""

import contextlib
import logging
import signal
import threading
import time

log = logging.getLogger(__name__)

__all__ = ["GRACE_S", "Interrupted", "SignalWatch", "held", "interrupt", "log_pids",
           "raise_pending", "reported"]

_POLL_S = 1e-3  # sleep between two polls of a wait
_SPINS = 50  # polls without sleep first: a quick answer is not delayed by a sleep
GRACE_S = 3.0  # how long a stopping rank waits for the others before the job is aborted


class Interrupted(BaseException):
    """SIGINT or SIGTERM ended the run: signal ``signum`` arrived on ``rank``.

    A BaseException, like KeyboardInterrupt, so that ``except Exception`` lets it
    through. ``code`` is the exit status, 128 + signum (130 for SIGINT, 143 for
    SIGTERM). ``settled`` is False when some rank did not answer within
    :data:`GRACE_S`; the caller then ends the job with ``comm.Abort(code)``.
    """

    def __init__(self, signum, rank=None, settled=True):
        self.signum, self.rank, self.settled = int(signum), rank, bool(settled)
        where = "" if rank is None else f" on rank {rank}"
        super().__init__(f"interrupted by {signal.Signals(self.signum).name}{where}")

    @property
    def code(self):
        return 128 + self.signum


_raised = []  # signals interrupt() raised that the command has not reported yet


_holding = [0]  # depth of the held() blocks running


def interrupt(signum, frame=None):
    """The handler of SIGINT and SIGTERM in a serial ``hmm`` command: raise
    :class:`Interrupted` at once (at the end of a :func:`held` block, if one runs),
    and again at the next :func:`raise_pending` should Python drop it (an exception
    raised inside a weakref callback or a ``__del__``, of which h5py has many, is only
    printed)."""
    _raised.append(signum)
    if _holding[0]:
        return
    raise Interrupted(signum)


@contextlib.contextmanager
def held():
    """Hold a serial command's SIGINT and SIGTERM while the block runs, and raise
    :class:`Interrupted` when it ends if one arrived. For HDF5 writes: the library
    calls back into Python (the file objects of :mod:`dem.io.files`), and an exception
    raised inside such a call leaves its state broken, so that the file can no longer
    be flushed or closed ("Can't decrement id ref count"). A signal that arrived
    before the block is not raised again here."""
    before = len(_raised)
    _holding[0] += 1
    try:
        yield
    finally:
        _holding[0] -= 1
    if not _holding[0] and len(_raised) > before:
        raise Interrupted(_raised[-1])


def raise_pending():
    """Raise again a signal :func:`interrupt` raised that was not reported."""
    if _raised:
        raise Interrupted(_raised[0])


def reported():
    """The command has reported the interruption (forget it)."""
    _raised.clear()


class SignalWatch:
    """SIGINT and SIGTERM on any rank of ``comm``, made known to every rank.

    While open, the handlers only note a signal. :meth:`check`, called between
    micro-model calls and in the polls of :meth:`wait`, tells every other rank (one
    small message each, on the communicator's highest tag) and raises
    :class:`Interrupted` naming the signal and the rank where it arrived. A rank that
    stops first waits (at most :data:`GRACE_S`) to hear from every other rank, taking
    any message still addressed to it, so that all ranks leave together and nothing is
    left unread when MPI finalizes.

    ``MPI`` is the ``mpi4py.MPI`` module of ``comm`` (from :func:`hmm.farm.mpi_world`,
    which keeps the import of mpi4py in one place).

    ``leader``: only rank 0 decides when to stop (the farm, whose collectives must not
    be left half joined): another rank that gets a signal tells every rank and goes on
    answering until it hears rank 0 stop; if rank 0 is silent for :data:`GRACE_S`
    (stuck in a long micro-model call), it aborts the job, the last resort.
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self, comm, MPI, leader=False):
        self.comm, self.MPI = comm, MPI
        self.rank, self.size = comm.Get_rank(), comm.Get_size()
        self.tag = comm.Get_attr(MPI.TAG_UB)  # above every tag otherwise in use
        self.leader = bool(leader)
        self.signum = None  # the first signal that arrived here
        self.origin = None  # (signum, rank) of the interruption, once known
        self.heard = set()  # ranks whose message has arrived
        self.told_at = None  # when this rank told the others (monotonic clock)
        self.stopped = False
        self._old = {}

    def open(self):
        """Install the handlers (from the main thread only); returns self."""
        if threading.current_thread() is threading.main_thread():
            for s in self.SIGNALS:
                self._old[s] = signal.signal(s, self._note)
        return self

    def close(self):
        """Put the previous handlers back."""
        for s, handler in self._old.items():
            signal.signal(s, handler)
        self._old = {}

    def _note(self, signum, frame):
        if self.signum is None:
            self.signum = signum

    def _take(self, drain=False):
        """Receive the stop messages that have arrived (with ``drain``: any message,
        so that no rank stays blocked sending to this one)."""
        status = self.MPI.Status()
        tag = self.MPI.ANY_TAG if drain else self.tag
        while self.comm.Iprobe(source=self.MPI.ANY_SOURCE, tag=tag, status=status):
            src, got = status.Get_source(), status.Get_tag()
            msg = self.comm.recv(source=src, tag=got)
            if got == self.tag:
                self.received(src, msg)

    def received(self, src, msg):
        """Record a stop message from rank ``src`` (taken by the caller's own probe)."""
        self.heard.add(src)
        if self.origin is None:
            self.origin = tuple(msg)

    def _tell(self):
        if self.told_at is None:
            self.told_at = time.monotonic()
            for r in range(self.size):
                if r != self.rank:
                    self.comm.send(self.origin, dest=r, tag=self.tag)

    def pending(self):
        """True once an interruption is known on this rank (noted or heard)."""
        if self.origin is None and self.signum is not None:
            self.origin = (self.signum, self.rank)
        self._take()
        return self.origin is not None

    def check(self):
        """Raise :class:`Interrupted` if the job is to stop (see the class)."""
        if not self.pending() or self.stopped:
            return
        if self.leader and self.rank != 0 and 0 not in self.heard:
            self._tell()  # rank 0 decides; it hears this at its next check
            if time.monotonic() - self.told_at > GRACE_S:
                self._abort()
            return
        self.stop()

    def stop(self):
        """Tell the others, hear from them (at most GRACE_S), raise Interrupted."""
        self.pending()
        self._tell()
        self.stopped = True
        deadline = time.monotonic() + GRACE_S
        while len(self.heard) < self.size - 1 and time.monotonic() < deadline:
            self._take(drain=True)
            time.sleep(_POLL_S)
        signum, rank = self.origin
        raise Interrupted(signum, rank, settled=len(self.heard) == self.size - 1)

    def _abort(self):
        signum, rank = self.origin
        log.error("interrupted by %s on rank %d; rank 0 did not answer within %g s: "
                  "ending the job", signal.Signals(signum).name, rank, GRACE_S)
        self.comm.Abort(128 + signum)

    def wait(self, ready):
        """Poll ``ready()`` until it is true, checking for an interruption between
        polls (a short sleep after the first few: no core spins)."""
        n = 0
        while not ready():
            self.check()
            n += 1
            if n > _SPINS:
                time.sleep(_POLL_S)


def log_pids(comm):
    """Log (INFO, rank 0) every rank's process id: hydra's banner for a rank lost to
    SIGKILL names its PID only, and the survivors are killed before they can speak.
    Collective."""
    import os
    import socket

    pids = comm.gather((os.getpid(), socket.gethostname()), root=0)
    if comm.Get_rank() == 0:
        log.info("ranks' process ids: %s", ", ".join(
            f"rank {r} pid {pid} on {host}" for r, (pid, host) in enumerate(pids)))
