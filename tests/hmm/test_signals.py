"""Signals on a serial ``hmm run`` and ``hmm batch`` (a subprocess each): Ctrl-C
(SIGINT) or SIGTERM ends the command at once with one line and exit status 130 or
143; the last checkpoint loads and no ``.tmp`` file is left. The same under
``mpiexec -n 2`` is tests/mpi/test_signals_mpi.py."""

import re
import signal
import time

import h5py
import pytest
from signal_jobs import LIMIT_S, PROBLEM, Job, sweep, tmp_files

from hmm.checkpoint import Checkpoint
from hmm.problem import load_problem


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_ends_a_serial_run_with_one_line(tmp_path, signum):
    (tmp_path / "problem.toml").write_text(PROBLEM)
    out = tmp_path / "out"
    job = Job(["run", "problem.toml", "-o", "out", "--no-progress"], tmp_path)
    job.wait_for(lambda: (out / "checkpoint.h5").exists(), "checkpoint")
    time.sleep(0.5)
    code, elapsed = job.interrupt(job.proc.pid, signum)
    lines = job.lines
    name = signal.Signals(signum).name
    assert code == 128 + signum, (code, lines)
    assert elapsed < LIMIT_S
    assert len(lines) == 1 and re.fullmatch(
        rf"hmm run: error: interrupted by {name}; \S+checkpoint.h5 holds load step "
        r"\d+ \(continue with --restart\)", lines[0]), lines
    step = int(re.search(r"load step (\d+)", lines[0]).group(1))
    ck = Checkpoint(out / "checkpoint.h5", load_problem(tmp_path / "problem.toml"))
    try:
        assert ck.step == step >= 1
    finally:
        ck.close()
    with h5py.File(out / "fields.h5", "r") as f:
        assert len(f["steps"]) > step
    assert not tmp_files(out)


def test_ctrl_c_ends_a_serial_batch_at_once(tmp_path):
    from hmm.batch import read_batch

    (tmp_path / "sweep.toml").write_text(sweep())
    job = Job(["batch", "sweep.toml", "-o", "out", "--no-progress", "-v"], tmp_path)
    job.wait_for(lambda: any(" done on rank " in x for x in job.lines), "experiment done")
    code, elapsed = job.interrupt(job.proc.pid, signal.SIGINT)
    lines = job.lines
    assert code == 130, (code, lines)
    assert elapsed < LIMIT_S
    errors = job.errors()
    assert errors == ["hmm batch: error: interrupted by SIGINT; rerun the same command "
                      "to resume"], lines
    assert 1 <= len(read_batch(tmp_path / "out" / "batch.h5")) < 4


def test_a_signal_waits_for_the_end_of_a_held_block():
    """hmm.signals.held: a signal inside the block (an HDF5 write) is raised when the
    block ends, not inside it; one that arrived before the block is not raised again
    at its end."""
    from hmm import signals

    done = []
    with pytest.raises(signals.Interrupted, match="SIGTERM"):
        with signals.held():
            signals.interrupt(signal.SIGTERM)  # noted, not raised
            with signals.held():  # nested: the outer block raises
                done.append("inner")
            done.append("outer")
    assert done == ["inner", "outer"]
    signals.reported()
    with pytest.raises(signals.Interrupted):
        signals.interrupt(signal.SIGINT)
    with signals.held():
        done.append("after")
    assert done[-1] == "after"
    signals.reported()
