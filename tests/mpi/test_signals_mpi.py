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
import sys
import time
import uuid
from pathlib import Path

import h5py
import pytest
from signal_jobs import LIMIT_S, PROBLEM, Job, sweep, tmp_files

MPI = pytest.importorskip("mpi4py.MPI")

pytestmark = pytest.mark.mpi
COMM = MPI.COMM_WORLD
MPIEXEC = str(Path(sys.executable).parent / "mpiexec")


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
    env.update(HMM_SIGNAL_TEST=marker, NUMBA_NUM_THREADS="1")
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


def _job(args, cwd):
    """``mpiexec -n 2 python -m hmm ARGS``; its processes carry a marker."""
    marker = uuid.uuid4().hex
    job = Job(args, cwd, prefix=[MPIEXEC, "-n", "2"], env=_environment(marker))
    job.marker = marker
    return job


def _interrupt(job, who, signum):
    """Send ``signum`` to rank ``who`` (or to mpiexec); (exit status, seconds)."""
    pid = job.proc.pid if who == "mpiexec" else _rank_pid(job.marker, who)
    return job.interrupt(pid, signum)


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
    job = _job(["run", "problem.toml", "-o", "out", "--no-progress"], workdir)
    job.wait_for(lambda: (out / "checkpoint.h5").exists(), "checkpoint")
    time.sleep(0.5)  # well into the run
    code, elapsed = _interrupt(job, who, signum)
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
    assert not tmp_files(out)


@pytest.mark.parametrize("who, signum", [(1, signal.SIGINT), ("mpiexec", signal.SIGTERM)])
def test_a_signal_ends_a_batch_in_seconds_with_one_line(workdir, who, signum):
    if COMM.rank != 0:
        return
    from hmm.batch import read_batch

    (workdir / "sweep.toml").write_text(sweep([1, 2]))
    out = workdir / "out"
    job = _job(["batch", "sweep.toml", "-o", "out", "--no-progress", "-v"], workdir)
    job.wait_for(lambda: any(" done on rank " in x for x in job.lines),
                 "experiment done")
    code, elapsed = _interrupt(job, who, signum)
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
    assert not tmp_files(out)
