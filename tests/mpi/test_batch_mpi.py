"""``hmm batch`` under ``mpiexec -n 2`` (``make test-mpi``): the batch file equals the
serial one number for number, a bug on either rank ends the job on every rank with the
experiment's id, and bad input ends it with exit status 2.

Every rank runs each test; outcomes are broadcast from rank 0 so all ranks pass or fail
together. A watchdog ends the process (and with it the job) if a test hangs.
"""

import argparse
import faulthandler
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
from problems import sweep_text

MPI = pytest.importorskip("mpi4py.MPI")

from hmm import batch, queue
from hmm.batch import load_sweep, read_batch
from hmm.cli import cmd_batch
from hmm.queue import run_batch

pytestmark = pytest.mark.mpi
COMM = MPI.COMM_WORLD
HANG_S = 300  # far beyond any test here: a watchdog, not a benchmark

#: 3 experiments of 30 disks, 2 increments each
SWEEP = sweep_text(30, 2, 0.02, 0.01)


@pytest.fixture
def workdir():
    """A directory shared by the ranks (rank 0 makes and removes it)."""
    path = Path(COMM.bcast(tempfile.mkdtemp(prefix="batch_mpi_")
                           if COMM.rank == 0 else None, root=0))
    faulthandler.dump_traceback_later(HANG_S, exit=True)
    yield path
    faulthandler.cancel_dump_traceback_later()
    COMM.Barrier()
    if COMM.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


def _sweep_file(workdir, text=SWEEP):
    path = workdir / "sweep.toml"
    if COMM.rank == 0:
        path.write_text(text + f'[output]\ndir = "{(workdir / "out").as_posix()}"\n')
    COMM.Barrier()
    return path


def _cmd(path):
    return cmd_batch(argparse.Namespace(file=path, output=None, overwrite=False,
                                        no_progress=True))


def _agree(ok, message=""):
    ok, message = COMM.bcast((bool(ok), message) if COMM.rank == 0 else None, root=0)
    assert ok, message


def _differences(a, b):
    """Where two batch files differ in anything but the run metadata."""
    a, b = read_batch(a), read_batch(b)
    if sorted(a) != sorted(b):
        return [f"ids {sorted(a)} != {sorted(b)}"]
    out = []
    for k in a:
        for name in set(a[k]["attrs"]) | set(b[k]["attrs"]):
            if name not in batch.RUN_METADATA and \
                    repr(a[k]["attrs"].get(name)) != repr(b[k]["attrs"].get(name)):
                out.append(f"{k} attribute {name}")
        for name in set(a[k]["curves"]) | set(b[k]["curves"]):
            if not np.array_equal(a[k]["curves"].get(name), b[k]["curves"].get(name)):
                out.append(f"{k} curve {name}")
    return out


def test_two_ranks_write_the_serial_numbers(workdir):
    path = _sweep_file(workdir)
    # the serial reference, on every rank at once (each its own file)
    serial = workdir / f"serial{COMM.rank}"
    report = run_batch(load_sweep(path), serial, progress=False, world=(None, None))
    assert report.n_done == 3
    COMM.Barrier()
    code = _cmd(path)
    _agree(code == 0, f"exit status {code}")
    diff, ranks = [], {0, 1}
    if COMM.rank == 0:
        stored = read_batch(workdir / "out/batch.h5")
        ranks = {r["attrs"]["rank"] for r in stored.values()}
        diff = _differences(workdir / "out/batch.h5", workdir / "serial0/batch.h5")
        diff += _differences(workdir / "serial1/batch.h5", workdir / "serial0/batch.h5")
    _agree(not diff, f"2-rank and serial batches differ: {diff}")
    _agree(ranks == {0, 1} or COMM.size == 1, f"experiments ran on ranks {ranks}")


@pytest.mark.parametrize("faulty_rank", [1, 0])
def test_a_bug_ends_the_job_naming_the_experiment(workdir, monkeypatch, capsys,
                                                  faulty_rank):
    """A ValueError on the worker (rank 0 is then busy with its own experiment), or on
    rank 0 (the worker is then busy): every rank stops with status 1 in seconds."""
    if COMM.size < 2:
        pytest.skip("needs a worker: run through `make test-mpi` (mpiexec -n 2)")
    path = _sweep_file(workdir)
    run = queue.run_one

    def faulty(cfg, poll=None):
        if COMM.rank == faulty_rank:
            raise ValueError("injected fault")
        return run(cfg, poll)

    monkeypatch.setattr(queue, "run_one", faulty)
    t0 = time.perf_counter()
    code = _cmd(path)
    elapsed = time.perf_counter() - t0
    codes = COMM.gather(code, root=0)
    _agree(COMM.rank != 0 or codes == [1] * COMM.size, f"exit statuses {codes}")
    ok, err = True, ""
    if COMM.rank == 0:
        err = capsys.readouterr().err
        # rank 1 gets the first experiment; rank 0 takes the next for itself
        first = load_sweep(path).experiments[1 - faulty_rank].id
        ok = (err.startswith(f"hmm batch: error: experiment {first} raised "
                             f"ValueError: injected fault (rank {faulty_rank})")
              and err.count("\n") == 1
              and not read_batch(workdir / "out/batch.h5"))
    _agree(ok, f"message: {err}")
    _agree(elapsed < 60.0, f"the job took {elapsed:.1f} s to end")


def test_bad_input_ends_every_rank_with_status_2(workdir, capsys):
    path = _sweep_file(workdir, SWEEP.replace("5e4,", "-5e4,"))
    code = _cmd(path)
    codes = COMM.gather(code, root=0)
    _agree(COMM.rank != 0 or codes == [2] * COMM.size, f"exit statuses {codes}")
    ok = True
    if COMM.rank == 0:
        err = capsys.readouterr().err
        ok = ("confining must be > 0" in err and err.count("\n") == 1
              and not (workdir / "out").exists())
    _agree(ok, "no one-line error, or output written")
