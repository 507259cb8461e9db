"""Environment failures are input errors (issue 32): a full disk, a read-only
filesystem or a directory in place of an output ends every command in one line naming
the file and the cause, exit status 2, no ``.tmp`` file left, and nothing that was
complete before the run damaged.

The disks are small tmpfs mounts under ``tmp_path`` (root only: the tests that need
one are skipped, and say so, where mounting is not allowed). The commands run as
subprocesses, so that everything they print, HDF5's library included, and how they
end (a crash would be a negative status) is what the test sees.
"""

import errno
import os
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from problems import elastic_problem

from dem.io.files import H5Output, OutputError, write_h5_atomic
from dem.io.hdf5 import save_figure

SCENE = """
[simulation]
dim = 3
steps = 200
gravity = [0.0, 0.0, -9.81]
[particles]
generator = "random"
count = 30
lo = [0.0, 0.0, 0.0]
hi = [0.08, 0.08, 0.16]
radius = [0.004, 0.005]
density = 2500.0
seed = 1
[[walls]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[contact]
law = "linear"
kn = 1.0e4
kt = 5.0e3
mu = 0.5
restitution = 0.3
[output]
every = 10
"""

#: two elastic elements: the micro model is analytic, a run takes a second
PROBLEM = elastic_problem(4, cells=(1, 2), checkpoint_every=1)

_PACKING = """
count = 36
radius = [0.8e-3, 1.2e-3]
p0 = 1e5
seed = 1
"""
_CONTACT = """
law = "linear"
kn = 1e8
kt = 5e7
mu = 0.5
"""
_TEST = """
axial_strain = 0.02
increment = 0.01
"""
RVE = f"[packing]\ndim = 2\n{_PACKING}[contact]\n{_CONTACT}[test]\n{_TEST}"


def sweep(confining):
    """A sweep of 36-disk tests, one per confining pressure."""
    return (f"[base.packing]\n{_PACKING}[base.contact]\n{_CONTACT}[base.test]\n{_TEST}"
            f'[sweep.grid]\n"test.confining" = {list(confining)}\n')


COMMANDS = {  # name: (argv before -o, input file name, its text, output files)
    "dem run": (["-m", "dem", "run"], "scene.toml", SCENE, ["scene.h5"]),
    "hmm run": (["-m", "hmm", "run"], "problem.toml", PROBLEM, ["fields.h5"]),
    "hmm rve": (["-m", "hmm", "rve"], "rve.toml", RVE, ["rve_test.h5"]),
    "hmm batch": (["-m", "hmm", "batch"], "sweep.toml", sweep([5e4, 1e5]),
                  ["batch.h5"]),
}


# --------------------------------------------------------------------------- helpers
@pytest.fixture
def disk(tmp_path):
    """A 2 MiB tmpfs mounted at ``tmp_path / "disk"``, unmounted afterwards."""
    where = tmp_path / "disk"
    where.mkdir()
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs to fill or make read-only needs root")
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2M", "tmpfs", str(where)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.strip()}")
    yield where
    subprocess.run(["umount", "-l", str(where)], capture_output=True)


def fill(where, free_kib):
    """Fill the disk at ``where`` with ``filler`` up to ``free_kib`` KiB left."""
    (where / "filler").unlink(missing_ok=True)
    st = os.statvfs(where)
    size = st.f_bavail * st.f_frsize - free_kib * 1024
    with open(where / "filler", "wb") as fh:
        fh.write(b"\0" * max(size, 0))
    return where / "filler"


def read_only(where, on=True):
    subprocess.run(["mount", "-o", f"remount,{'ro' if on else 'rw'}", str(where)],
                   check=True)


def run(name, where, out, *extra):
    """``name`` (a key of COMMANDS) as a subprocess from ``where`` into ``out``:
    ``(exit status, stdout, stderr)``."""
    argv, file, text, _ = COMMANDS[name]
    if not (where / file).exists():
        (where / file).write_text(text)
    env = {**os.environ, "MPLBACKEND": "Agg"}
    done = subprocess.run([sys.executable, *argv, file, "-o", str(out), "--no-progress",
                           *extra], cwd=where, capture_output=True, text=True, env=env,
                          timeout=300)
    return done.returncode, done.stdout, done.stderr


def assert_one_line(name, err, out_dir, cause):
    """Exactly one line, ``<prog>: error: cannot write <a file in out_dir>: <cause>``."""
    prog = "dem" if name == "dem run" else name
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"{prog}: error: cannot write {out_dir}"), err
    assert cause in lines[0], err


def files(root):
    """Every file below ``root`` (the filler excluded) with its bytes."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(Path(root).rglob("*"))
            if p.is_file() and p.name != "filler"}


def assert_clean(root):
    """No ``.tmp`` file, and every HDF5 file left opens."""
    names = files(root)
    assert not [n for n in names if n.endswith(".tmp")], sorted(names)
    for n in names:
        if n.endswith(".h5"):
            with h5py.File(Path(root) / n, "r"):
                pass


# --------------------------------------------------------------------------- full disk
@pytest.mark.parametrize("name", list(COMMANDS))
def test_a_full_disk_is_one_line_and_leaves_no_partial_file(disk, name):
    """The disk is full from the start: the first output the command writes fails."""
    fill(disk, 4)
    code, _, err = run(name, disk, "out")
    assert code == 2, err
    assert_one_line(name, err, "out/", "No space left on device (the disk is full)")
    assert not (disk / "out").exists() or files(disk / "out") == {}
    assert_clean(disk)


@pytest.mark.parametrize("free_kib", [40, 60, 80, 100])
def test_hmm_run_on_a_disk_that_fills_continues_with_restart(disk, tmp_path, free_kib):
    """The disk fills during the run: one line naming the file, the checkpoint it
    names loads, and after space is freed ``--restart`` ends as a run that never
    stopped."""
    filler = fill(disk, free_kib)
    code, _, err = run("hmm run", disk, "out")
    assert code == 2, err
    assert_one_line("hmm run", err, "out/", "No space left on device")
    assert_clean(disk)
    if not (disk / "out" / "checkpoint.h5").exists():
        return  # it failed before the first checkpoint: nothing to continue
    assert "(continue with --restart)" in err
    filler.unlink()
    code, out, err = run("hmm run", disk, "out", "--restart")
    assert code == 0, err
    ref = tmp_path / "ref"
    ref.mkdir()
    code, ref_out, err = run("hmm run", ref, "out")
    assert code == 0, err
    assert [x for x in out.splitlines() if x.startswith("reaction")] == \
        [x for x in ref_out.splitlines() if x.startswith("reaction")]
    with h5py.File(disk / "out/fields.h5", "r") as a, \
            h5py.File(ref / "out/fields.h5", "r") as b:
        assert sorted(a["steps"]) == sorted(b["steps"])
        np.testing.assert_array_equal(a["curve/force/top"][()], b["curve/force/top"][()])


def test_a_restart_on_a_full_disk_keeps_the_checkpoint(disk):
    code, _, err = run("hmm run", disk, "out", "--stop-after", "2")
    assert code == 0, err
    before = files(disk / "out")
    fill(disk, 0)
    code, _, err = run("hmm run", disk, "out", "--restart")
    assert code == 2, err
    assert_one_line("hmm run", err, "out/", "No space left on device")
    assert "out/checkpoint.h5 holds load step 2" in err
    after = files(disk / "out")
    assert after["checkpoint.h5"] == before["checkpoint.h5"]
    assert_clean(disk)
    with h5py.File(disk / "out/fields.h5", "r") as f:
        assert sorted(f["steps"]) == ["00000", "00001", "00002"]


def test_a_resumed_batch_on_a_full_disk_keeps_its_experiments(disk):
    code, _, err = run("hmm batch", disk, "out")
    assert code == 0, err
    with h5py.File(disk / "out/batch.h5", "r") as f:
        stored = sorted(f)
    assert len(stored) == 2
    before = files(disk / "out")
    (disk / "sweep.toml").write_text(sweep([5e4, 1e5, 2e5, 4e5]))
    filler = fill(disk, 0)
    code, _, err = run("hmm batch", disk, "out")
    assert code == 2, err
    assert_one_line("hmm batch", err, "out/", "No space left on device")
    assert_clean(disk)
    with h5py.File(disk / "out/batch.h5", "r") as f:
        assert set(stored) <= set(f)
    after = files(disk / "out")
    assert {k: after.get(k) for k in ("summary.csv", "summary.png")} == \
        {k: before[k] for k in ("summary.csv", "summary.png")}
    filler.unlink()
    code, out, err = run("hmm batch", disk, "out")
    assert code == 0, err
    assert "4 experiments" in out
    with h5py.File(disk / "out/batch.h5", "r") as f:
        assert len(f) == 4


@pytest.mark.parametrize("free_kib", [40, 80])
def test_hmm_rve_on_a_disk_that_fills_names_the_file(disk, free_kib):
    fill(disk, free_kib)
    code, _, err = run("hmm rve", disk, "out")
    assert code == 2, err
    assert_one_line("hmm rve", err, "out/", "No space left on device")
    assert_clean(disk)


@pytest.mark.parametrize("name, free_kib", [("hmm batch", 4), ("hmm run", 60)])
def test_under_mpiexec_every_rank_ends_with_status_2(disk, name, free_kib):
    """Rank 0 names the file once; the workers end with the same status (MPICH's
    ``mpiexec`` ORs the ranks' statuses: a worker's 1 made it 3)."""
    argv, file, text, _ = COMMANDS[name]
    (disk / file).write_text(text)
    fill(disk, free_kib)
    mpiexec = str(Path(sys.executable).parent / "mpiexec")
    env = {**os.environ, "MPLBACKEND": "Agg", "NUMBA_NUM_THREADS": "1"}
    done = subprocess.run([mpiexec, "-n", "2", sys.executable, *argv, file, "-o", "out",
                           "--no-progress"], cwd=disk, capture_output=True, text=True,
                          env=env, timeout=300)
    assert done.returncode == 2, done.stderr
    assert_one_line(name, done.stderr, "out/", "No space left on device")
    assert_clean(disk)


# --------------------------------------------------------------------------- read-only
@pytest.mark.parametrize("name", list(COMMANDS))
def test_a_read_only_filesystem_is_one_line_and_changes_nothing(disk, name):
    """A new output directory, and an existing complete output with --overwrite."""
    code, _, err = run(name, disk, "done")
    assert code == 0, err
    before = files(disk)
    read_only(disk)
    try:
        code, _, err = run(name, disk, "new")
        assert code == 2, err
        assert len(err.splitlines()) == 1 and "new" in err, err
        assert "read-only" in err.lower() or "Read-only file system" in err, err
        code, _, err = run(name, disk, "done", "--overwrite")
        assert code == 2, err
        assert len(err.splitlines()) == 1 and "done" in err, err
        assert files(disk) == before
    finally:
        read_only(disk, on=False)


# --------------------------------------------------------------------------- directories
@pytest.mark.parametrize("name, blocked", [("dem run", "scene_walls.xdmf"),
                                           ("hmm batch", "summary.png"),
                                           ("hmm rve", "rve_test.png")])
def test_a_directory_in_place_of_an_output_is_refused_before_the_run(tmp_path, name,
                                                                    blocked):
    (tmp_path / "out" / blocked).mkdir(parents=True)
    code, _, err = run(name, tmp_path, "out", "--overwrite")
    assert code == 2, err
    assert len(err.splitlines()) == 1 and f"out/{blocked}" in err, err
    assert "directory" in err
    assert files(tmp_path / "out") == {}


# --------------------------------------------------------------------------- the library
def test_an_hdf5_file_on_a_full_disk_closes_once_and_says_so(disk):
    """h5py writes through the guarded file: the first failure is an OutputError,
    the file then closes without a second error (nothing unraisable is printed)."""
    fill(disk, 64)
    unraisable = []
    hook, sys.unraisablehook = sys.unraisablehook, unraisable.append
    try:
        out = H5Output(disk / "x.h5", "w")
        with pytest.raises(OutputError) as info:
            try:
                for k in range(1000):
                    out.h5.create_dataset(f"d{k}", data=np.arange(4096.0))
                    out.h5.flush()
            except Exception as err:  # noqa: BLE001 - the guard decides what it was
                raise out.failure(err) from None
        del out
        import gc

        gc.collect()
    finally:
        sys.unraisablehook = hook
    assert info.value.errno == errno.ENOSPC
    assert str(info.value).startswith(f"cannot write {disk / 'x.h5'}: No space left")
    assert unraisable == []
    with h5py.File(disk / "x.h5", "r") as f:  # as at its last flush
        assert len(f) > 0


def test_atomic_writes_leave_no_tmp_on_a_full_disk(disk):
    fill(disk, 8)
    with pytest.raises(OutputError, match="cannot write .*a.h5: No space left"):
        write_h5_atomic(disk / "a.h5", lambda f: f.create_dataset(
            "x", data=np.random.default_rng(0).random(10**5)))  # zeros would be sparse
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot(np.random.default_rng(0).random(10**4))
    with pytest.raises(OutputError, match="cannot write .*a.png: No space left"):
        save_figure(fig, disk / "a.png", dpi=300)
    plt.close(fig)
    assert files(disk) == {}


@pytest.mark.parametrize("code, words", [
    (errno.ENOSPC, "No space left on device (the disk is full); free space"),
    (errno.EDQUOT, "(the disk quota is used up); free space"),
    (errno.EROFS, "Read-only file system; choose another --output"),
    (errno.EACCES, "Permission denied; choose another --output"),
    (errno.EISDIR, "Is a directory; remove the directory"),
])
def test_the_cause_is_named_with_what_to_do(code, words):
    err = OutputError("out/fields.h5", OSError(code, os.strerror(code)))
    assert str(err).startswith("cannot write out/fields.h5: ")
    assert words in str(err) and "\n" not in str(err)
    assert isinstance(err, OSError) and err.errno == code


def test_a_failed_write_is_not_retried(tmp_path):
    """After a failed write the guard drops the later ones (HDF5's clean-up)."""
    out = H5Output(tmp_path / "x.h5", "w")
    out.h5.create_dataset("x", data=np.zeros(3))
    out.h5.flush()
    size = os.path.getsize(tmp_path / "x.h5")
    out.io.error = OSError(errno.ENOSPC, "No space left on device")
    out.h5.create_dataset("y", data=np.zeros(10**4))
    with pytest.raises(OutputError):
        out.close()
    assert os.path.getsize(tmp_path / "x.h5") == size



def test_a_file_being_written_is_locked_like_hdf5_locks_it(tmp_path):
    """A second writer (another process, or this one) is refused before it empties
    the file, as HDF5's own lock refused it."""
    first = H5Output(tmp_path / "x.h5", "w")
    first.h5.create_dataset("x", data=np.arange(3.0))
    first.h5.flush()
    for mode in ("w", "a"):
        with pytest.raises(OutputError, match="x.h5: the file is open in another process"):
            H5Output(tmp_path / "x.h5", mode)
    first.close()
    again = H5Output(tmp_path / "x.h5", "a")
    np.testing.assert_array_equal(again.h5["x"][()], np.arange(3.0))
    again.close()
