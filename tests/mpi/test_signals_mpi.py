"""Signals under ``mpiexec -n 2``: SIGINT or SIGTERM on the worker rank, on rank 0 or
on ``mpiexec`` itself ends a small ``hmm run`` or ``hmm batch`` within 5 s, with
exit status 130 or 143 and one line naming the signal and the rank; the last
checkpoint loads, ``fields.h5`` and ``batch.h5`` open, no ``.tmp`` file is left.

Each test starts its own job, ``mpiexec -n 2 python -m hmm ...``, from rank 0 of the
test session (``make test-mpi``) or from a plain pytest; the other session rank
waits in a polled barrier, so the two cores stay free for the job. A rank's pid is
found in ``/proc`` by its ``PMI_RANK`` and a marker in its environment.
"""

import os
import re
import signal
import subprocess
import sys
import textwrap
import threading
import time
import uuid
from pathlib import Path

import h5py
import pytest

MPI = pytest.importorskip("mpi4py.MPI")

pytestmark = pytest.mark.mpi
COMM = MPI.COMM_WORLD
MPIEXEC = str(Path(sys.executable).parent / "mpiexec")
ROOT = Path(__file__).resolve().parents[2]
LIMIT_S = 5.0  # the promise: the whole job ends within this after the signal
START_S = 240.0  # a watchdog for the job's start (imports, a cold numba cache)

#: linear-elastic points, a checkpoint every load step: a long run of cheap steps
PROBLEM = """
[mesh]
size = [1.0, 2.0]
cells = [2, 2]

[[dirichlet]]
boundary = "bottom"
component = "y"

[[dirichlet]]
boundary = "left"
component = "x"

[[dirichlet]]
boundary = "top"
component = "y"
value = -0.01

[micro]
model = "linear_elastic"
young = 1e6
poisson = 0.3

[load]
steps = 5000

[output]
checkpoint_every = 1
"""

#: 8 experiments of 30 disks, 40 increments each: seconds each, far from done
SWEEP = """
[base.packing]
count = 30
radius = [0.8e-3, 1.2e-3]
p0 = 1e5
seed = 2
[base.contact]
law = "linear"
kn = 1e8
kt = 5e7
mu = 0.5
[base.test]
axial_strain = 0.2
increment = 0.005
[sweep.grid]
"test.confining" = [5e4, 1e5, 2e5, 4e5]
"packing.seed" = [1, 2]
"""


@pytest.fixture
def workdir(tmp_path_factory):
    """A directory of rank 0's; the other rank waits, polling, until the test ends."""
    path = None
    if COMM.rank == 0:
        path = tmp_path_factory.mktemp("signals")
    yield path
    request = COMM.Ibarrier()
    while not request.Test():
        time.sleep(0.01)


def _environment(marker):
    """This environment without the session's own MPI variables, plus a marker."""
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("PMI_", "HYDRA_", "MPIR_", "MPI_LOCAL"))}
    env.update(HMM_SIGNAL_TEST=marker, NUMBA_NUM_THREADS="1",
               PYTHONPATH=os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]))
    return env


def _rank_pid(marker, rank):
    """The pid of ``rank`` of the job whose processes carry ``marker``."""
    want = {f"HMM_SIGNAL_TEST={marker}".encode(), f"PMI_RANK={rank}".encode()}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                env = set((d / "environ").read_bytes().split(b"\0"))
            except OSError:
                continue
            if want <= env:
                return int(d.name)
    raise AssertionError(f"no process of rank {rank} found")


class Job:
    """``mpiexec -n 2 python -m hmm ARGS`` with its stderr read line by line."""

    def __init__(self, args, cwd):
        self.marker = uuid.uuid4().hex
        self.proc = subprocess.Popen([MPIEXEC, "-n", "2", sys.executable, "-m", "hmm",
                                      *args], cwd=cwd, env=_environment(self.marker),
                                     stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.PIPE, text=True,
                                     start_new_session=True)
        self.lines = []
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        for line in self.proc.stderr:
            self.lines.append(line.rstrip("\n"))

    def wait_for(self, ready, what):
        t0 = time.monotonic()
        while not ready():
            assert self.proc.poll() is None, f"the job ended before {what}: {self.lines}"
            assert time.monotonic() - t0 < START_S, f"no {what} in {START_S} s"
            time.sleep(0.05)

    def interrupt(self, who, signum):
        """Send ``signum`` to rank ``who`` (or to mpiexec); (exit status, seconds)."""
        pid = self.proc.pid if who == "mpiexec" else _rank_pid(self.marker, who)
        t0 = time.monotonic()
        os.kill(pid, signum)
        try:
            code = self.proc.wait(timeout=60.0)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            code = self.proc.wait()
        elapsed = time.monotonic() - t0
        self.reader.join(5.0)
        return code, elapsed

    def errors(self):
        """stderr without log lines and without mpiexec's own notices."""
        return [x for x in self.lines
                if x.strip() and not x.startswith(("hmm: INFO", "[mpiexec@"))]


def _tmp_files(directory):
    return sorted(p.name for p in Path(directory).iterdir() if p.name.endswith(".tmp"))


@pytest.mark.parametrize("who, signum", [(1, signal.SIGINT), (1, signal.SIGTERM),
                                         (0, signal.SIGTERM),
                                         ("mpiexec", signal.SIGINT)])
def test_a_signal_ends_a_run_in_seconds_with_one_line(workdir, who, signum):
    if COMM.rank != 0:
        return
    from hmm.checkpoint import Checkpoint
    from hmm.problem import load_problem

    (workdir / "problem.toml").write_text(PROBLEM)
    out = workdir / "out"
    job = Job(["run", "problem.toml", "-o", "out", "--no-progress"], workdir)
    job.wait_for(lambda: (out / "checkpoint.h5").exists(), "checkpoint")
    time.sleep(0.5)  # well into the run
    code, elapsed = job.interrupt(who, signum)
    name = signal.Signals(signum).name
    assert code == 128 + signum, (code, job.lines)
    assert elapsed < LIMIT_S, f"the job took {elapsed:.1f} s to end"
    errors = job.errors()
    rank = "[01]" if who == "mpiexec" else str(who)  # mpiexec signals every rank
    assert len(errors) == 1 and re.fullmatch(
        rf"hmm run: error: interrupted by {name} on rank {rank}; \S+checkpoint.h5 "
        rf"holds load step \d+ \(continue with --restart\)", errors[0]), errors
    step = int(re.search(r"load step (\d+)", errors[0]).group(1))
    ck = Checkpoint(out / "checkpoint.h5", load_problem(workdir / "problem.toml"))
    try:
        assert ck.step == step >= 1
    finally:
        ck.close()
    with h5py.File(out / "fields.h5", "r") as f:
        assert len(f["steps"]) > step and "curve" in f
    assert not _tmp_files(out)


@pytest.mark.parametrize("who, signum", [(1, signal.SIGINT), ("mpiexec", signal.SIGTERM)])
def test_a_signal_ends_a_batch_in_seconds_with_one_line(workdir, who, signum):
    if COMM.rank != 0:
        return
    from hmm.batch import read_batch

    (workdir / "sweep.toml").write_text(textwrap.dedent(SWEEP))
    out = workdir / "out"
    job = Job(["batch", "sweep.toml", "-o", "out", "--no-progress", "-v"], workdir)
    job.wait_for(lambda: any(" done on rank " in x for x in job.lines),
                 "experiment done")
    code, elapsed = job.interrupt(who, signum)
    name = signal.Signals(signum).name
    assert code == 128 + signum, (code, job.lines)
    assert elapsed < LIMIT_S, f"the job took {elapsed:.1f} s to end"
    errors = job.errors()
    rank = "[01]" if who == "mpiexec" else str(who)
    assert len(errors) == 1 and re.fullmatch(
        rf"hmm batch: error: interrupted by {name} on rank {rank}; rerun the same "
        r"command to resume", errors[0]), errors
    stored = read_batch(out / "batch.h5")
    assert 1 <= len(stored) < 8
    assert not _tmp_files(out)
