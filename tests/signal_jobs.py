"""Shared by the signal tests (tests/hmm/test_signals.py serially,
tests/mpi/test_signals_mpi.py under ``mpiexec -n 2``): the small run and sweep they
interrupt, and a job started as a subprocess whose stderr is read line by line."""

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from problems import elastic_problem, sweep_text

ROOT = Path(__file__).resolve().parents[1]
LIMIT_S = 5.0  # the promise: the whole job ends within this after the signal
START_S = 240.0  # a watchdog for the job's start (imports, a cold numba cache)

#: linear-elastic points, a checkpoint every load step: a long run of cheap steps
PROBLEM = elastic_problem(5000, checkpoint_every=1)

#: experiments of 30 disks, 40 increments each: seconds each, far from done
SWEEP = sweep_text(30, 2, 0.2, 0.005, "[5e4, 1e5, 2e5, 4e5]")


def sweep(seeds=None):
    """:data:`SWEEP` (4 experiments), times the packing seeds given."""
    if seeds is None:
        return SWEEP
    return SWEEP + f'"packing.seed" = {list(seeds)}\n'


def default_signals():
    """In a child before it runs: SIGINT and SIGTERM back to their default handlers.

    A shell starts a background job (``make test &``, a CI runner) with SIGINT
    ignored, and the child inherits that; the commands rightly leave an ignored
    signal ignored, so a test that sends one must undo it first."""
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, signal.SIG_DFL)


class Job:
    """``PREFIX python -m hmm ARGS`` in ``cwd``, its stderr collected as it comes.

    ``prefix`` is empty for a serial command or e.g. ``[mpiexec, "-n", "2"]``; ``env``
    is the whole environment (default: this one with the project on PYTHONPATH).
    """

    def __init__(self, args, cwd, prefix=(), env=None):
        if env is None:
            env = dict(os.environ)
        env = dict(env, PYTHONPATH=os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]))
        self.proc = subprocess.Popen([*prefix, sys.executable, "-m", "hmm", *args],
                                     cwd=cwd, env=env, stdin=subprocess.DEVNULL,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                     text=True, start_new_session=bool(prefix),
                                     preexec_fn=default_signals)
        self.lines = []
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        for line in self.proc.stderr:
            self.lines.append(line.rstrip("\n"))

    def wait_for(self, ready, what):
        """Poll ``ready()`` until it holds; fail if the job ends or takes too long."""
        t0 = time.monotonic()
        while not ready():
            assert self.proc.poll() is None, f"the job ended before {what}: {self.lines}"
            assert time.monotonic() - t0 < START_S, f"no {what} in {START_S} s"
            time.sleep(0.05)

    def interrupt(self, pid, signum):
        """Send ``signum`` to ``pid``; (exit status, seconds until the job ended)."""
        t0 = time.monotonic()
        os.kill(pid, signum)
        try:
            code = self.proc.wait(timeout=60.0)
        except subprocess.TimeoutExpired:
            if self.proc.pid == os.getpgid(self.proc.pid):
                os.killpg(self.proc.pid, signal.SIGKILL)
            else:
                self.proc.kill()
            code = self.proc.wait()
        elapsed = time.monotonic() - t0
        self.reader.join(5.0)
        return code, elapsed

    def errors(self):
        """stderr without log lines and without mpiexec's own notices."""
        return [x for x in self.lines
                if x.strip() and not x.startswith(("hmm: INFO", "[mpiexec@"))]


def tmp_files(directory):
    """The names of the ``.tmp`` files left in ``directory``."""
    return sorted(p.name for p in Path(directory).iterdir() if p.name.endswith(".tmp"))
