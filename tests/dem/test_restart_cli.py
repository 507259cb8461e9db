"""``dem run --restart``: a scene run stopped at a checkpoint (by its step count or by
a signal) and continued gives the uninterrupted run's frames bit for bit, insertion
included; foreign or missing checkpoints are refused in one line."""

import os
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest
from signal_jobs import default_signals
from test_cli import _insert_scene, assert_one_line_error, run_cli, write_scene

STEPS = 1200


def _scene(every=300):
    s = _insert_scene()
    s["simulation"]["steps"] = STEPS
    s["output"] = {"every": 200, "checkpoint_every": every}
    return s


def _frames(path):
    """Every dataset of every frame: ``{frame/name: array}`` and the frame steps."""
    out, steps = {}, []
    with h5py.File(path, "r") as f:
        for name in sorted(f["frames"]):
            g = f["frames"][name]
            steps.append(int(g.attrs["step"]))
            g.visititems(lambda k, d, name=name: out.__setitem__(f"{name}/{k}", d[()])
                         if isinstance(d, h5py.Dataset) else None)
    return out, steps


def _same_frames(a, b):
    fa, sa = _frames(a)
    fb, sb = _frames(b)
    assert sa == sb
    assert fa.keys() == fb.keys()
    for k in fa:
        np.testing.assert_array_equal(fa[k], fb[k], err_msg=k)


@pytest.fixture(scope="module")
def whole(tmp_path_factory):
    """The uninterrupted run (its checkpoints written as it goes)."""
    tmp = tmp_path_factory.mktemp("whole")
    path = write_scene(tmp, _scene())
    from dem.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["run", str(path), "-o", str(tmp / "out"), "--no-progress"])
    assert exc.value.code == 0
    return tmp / "out"


def test_a_run_continued_from_its_checkpoint_is_the_whole_run(whole, tmp_path, capsys):
    with h5py.File(whole / "checkpoint.h5", "r") as f:
        assert int(f.attrs["step"]) == STEPS  # the end of the run
        assert f["insert"]["ids"].size == 30
    path = write_scene(tmp_path, _scene())
    out = tmp_path / "out"
    code, text, err = run_cli(["run", path, "-o", out, "--steps", 500], capsys)
    assert code == 0, err
    assert f"checkpoint {out / 'checkpoint.h5'} (step 500)" in text
    code, text, err = run_cli(["run", path, "-o", out, "--dry-run", "--restart"], capsys)
    assert code == 0, err
    assert "700 steps from the checkpoint at step 500" in text and "(continued)" in text
    code, text, err = run_cli(["run", path, "-o", out, "--restart"], capsys)
    assert code == 0, err
    assert f"{STEPS} x dt" in text and "(from the checkpoint at step 500)" in text
    _same_frames(whole / "scene.h5", out / "scene.h5")
    with h5py.File(out / "checkpoint.h5", "r") as a, \
            h5py.File(whole / "checkpoint.h5", "r") as b:
        for name in ("bodies/pos", "bodies/vel", "contacts/hist", "insert/ids"):
            np.testing.assert_array_equal(a[name][()], b[name][()], err_msg=name)


def _start(path, out):
    """``dem run`` of a long scene in a subprocess, once it is writing frames."""
    proc = subprocess.Popen([sys.executable, "-m", "dem", "run", str(path), "-o",
                             str(out), "--no-progress"], text=True, env=ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            preexec_fn=default_signals)
    deadline = time.monotonic() + 240.0
    while not (out / "scene.h5.tmp").exists() and time.monotonic() < deadline:
        time.sleep(0.2)
    time.sleep(0.5)  # running
    return proc


def _interrupted(tmp_path, scene, signum):
    """Run ``scene`` (made long) in a subprocess, send ``signum`` once it runs; its
    output folder and stderr, after checking the exit status 128 + signum."""
    scene["simulation"]["steps"] = 10_000_000
    out = tmp_path / "out"
    proc = _start(write_scene(tmp_path, scene), out)
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signum, err
    return out, err


def _dem(*args):
    proc = subprocess.run([sys.executable, "-m", "dem", "run", *map(str, args),
                           "--no-progress"], env=ENV, text=True, capture_output=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


ENV = dict(os.environ, NUMBA_NUM_THREADS="1")


def test_a_signal_stops_the_run_at_a_checkpoint_that_continues_it(tmp_path):
    """SIGTERM mid-run: the frames so far are kept, a checkpoint at the step it
    stopped is written, exit 143; continued, the run ends as one never stopped."""
    s = _scene(every=10_000_000)  # no periodic checkpoint before the signal
    out, err = _interrupted(tmp_path, s, signal.SIGTERM)
    assert_one_line_error(err, "interrupted by SIGTERM at step ",
                          "checkpoint.h5 holds step ", "(continue with --restart)")
    stopped = int(err.split("at step ")[1].split(";")[0])
    with h5py.File(out / "checkpoint.h5", "r") as f:
        assert int(f.attrs["step"]) == stopped
    _, steps = _frames(out / "scene.h5")
    assert steps[-1] <= stopped < steps[-1] + 200
    # continued a little past the stop, against the same steps run in one go
    end = stopped + 450
    s["simulation"]["steps"] = end
    _dem(write_scene(tmp_path, s), "-o", out, "--restart")
    _dem(write_scene(tmp_path, s, "whole.toml"), "-o", tmp_path / "whole")
    _same_frames(tmp_path / "whole" / "whole.h5", out / "scene.h5")
    with h5py.File(out / "checkpoint.h5", "r") as f:
        assert int(f.attrs["step"]) == end


def test_without_checkpoints_a_signal_says_so(tmp_path):
    out, err = _interrupted(tmp_path, _scene(every=0), signal.SIGINT)
    assert_one_line_error(err, "interrupted by SIGINT at step ", "no checkpoint")
    assert (out / "scene.h5").exists() and not (out / "checkpoint.h5").exists()


def test_a_foreign_missing_or_late_checkpoint_is_refused(whole, tmp_path, capsys):
    out = tmp_path / "out"
    path = write_scene(tmp_path, _scene())
    code, _, err = run_cli(["run", path, "-o", out, "--restart"], capsys)
    assert code == 2
    assert_one_line_error(err, "--restart: no checkpoint", "checkpoint_every")
    other = _scene()
    other["contact"]["mu"] = 0.3
    (out).mkdir()
    (out / "checkpoint.h5").write_bytes((whole / "checkpoint.h5").read_bytes())
    code, _, err = run_cli(["run", write_scene(tmp_path, other, "other.toml"), "-o", out,
                            "--restart"], capsys)
    assert code == 2
    assert_one_line_error(err, "was written for another scene")
    code, _, err = run_cli(["run", path, "-o", out, "--restart", "--steps", 100], capsys)
    assert code == 2
    assert_one_line_error(err, f"holds step {STEPS}, past the scene's 100 steps")
    # without --restart an existing checkpoint is an output to refuse
    code, _, err = run_cli(["run", path, "-o", out], capsys)
    assert code == 2
    assert_one_line_error(err, "checkpoint.h5 exists; pass --overwrite")
