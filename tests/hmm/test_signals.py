"""Signals on a serial ``hmm run`` and ``hmm batch`` (a subprocess each): Ctrl-C
(SIGINT) or SIGTERM ends the command at once with one line and exit status 130 or
143; the last checkpoint loads and no ``.tmp`` file is left. The same under
``mpiexec -n 2`` is tests/mpi/test_signals_mpi.py."""

import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import h5py
import pytest

from hmm.checkpoint import Checkpoint
from hmm.problem import load_problem

ROOT = Path(__file__).resolve().parents[2]
LIMIT_S = 5.0
START_S = 240.0  # a watchdog for the start (imports, a cold numba cache)

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
"""


def _start(args, cwd):
    """``python -m hmm ARGS`` with its stderr lines collected as they come."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT),
                                                       os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.Popen([sys.executable, "-m", "hmm", *args], cwd=cwd, env=env,
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    lines = []
    reader = threading.Thread(target=lambda: lines.extend(
        x.rstrip("\n") for x in proc.stderr), daemon=True)
    reader.start()
    return proc, lines, reader


def _wait_for(proc, ready, lines):
    t0 = time.monotonic()
    while not ready():
        assert proc.poll() is None, f"ended before the signal: {lines}"
        assert time.monotonic() - t0 < START_S, "the run did not start"
        time.sleep(0.05)


def _interrupt(proc, signum, reader):
    t0 = time.monotonic()
    proc.send_signal(signum)
    try:
        code = proc.wait(timeout=60.0)
    except subprocess.TimeoutExpired:
        proc.kill()
        code = proc.wait()
    elapsed = time.monotonic() - t0
    reader.join(5.0)
    return code, elapsed


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_ends_a_serial_run_with_one_line(tmp_path, signum):
    (tmp_path / "problem.toml").write_text(PROBLEM)
    out = tmp_path / "out"
    proc, lines, reader = _start(["run", "problem.toml", "-o", "out", "--no-progress"],
                                 tmp_path)
    _wait_for(proc, lambda: (out / "checkpoint.h5").exists(), lines)
    time.sleep(0.5)
    code, elapsed = _interrupt(proc, signum, reader)
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
    assert not [p for p in out.iterdir() if p.name.endswith(".tmp")]


def test_ctrl_c_ends_a_serial_batch_at_once(tmp_path):
    from hmm.batch import read_batch

    (tmp_path / "sweep.toml").write_text(SWEEP)
    proc, lines, reader = _start(["batch", "sweep.toml", "-o", "out", "--no-progress",
                                  "-v"], tmp_path)
    _wait_for(proc, lambda: any(" done on rank " in x for x in lines), lines)
    code, elapsed = _interrupt(proc, signal.SIGINT, reader)
    assert code == 130, (code, lines)
    assert elapsed < LIMIT_S
    errors = [x for x in lines if not x.startswith("hmm: INFO")]
    assert errors == ["hmm batch: error: interrupted by SIGINT; rerun the same command "
                      "to resume"], lines
    assert 1 <= len(read_batch(tmp_path / "out" / "batch.h5")) < 4
