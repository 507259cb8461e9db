"""A dry run agrees with the real run (issue 32, item 4).

For a corpus of cases per command (valid files, and one case per class of input
error: invalid keys, bad packing files, existing and foreign outputs, outputs that are
directories or cannot be made, restarts from missing, foreign or too-late
checkpoints), ``--dry-run`` is run first and must write nothing; then the real run
(stopped once everything it reads is read, or a one-step elastic run) must accept
exactly what the dry run accepted. Refusals are one line with exit status 2.
"""

import contextlib
import copy
import re
from pathlib import Path
from unittest import mock

import h5py
import numpy as np
import pytest
from test_hostile_inputs import BASES, ELASTIC, ROOT, _stop, listing, run_cli, to_toml, \
    write_rve_packing


def agree(prog, argv, tmp, stop=None):
    """``prog argv --dry-run``, then the real run (``stop``: the function that starts
    its work, replaced by a stop): both exit statuses, after checking that the dry run
    wrote nothing and that a refusal is one line."""
    before = listing(tmp)
    dirs = sorted(p for p in Path(tmp).rglob("*") if p.is_dir())
    code_dry, out, err = run_cli(prog, [*argv, "--dry-run"], tmp)
    assert listing(tmp) == before, "the dry run wrote a file"
    assert sorted(p for p in Path(tmp).rglob("*") if p.is_dir()) == dirs, \
        "the dry run made a directory"
    assert code_dry in (0, 2), err
    if code_dry == 2:
        assert err.count("\n") == 1 and "error: " in err, err
    else:
        assert "valid;" in out, out
    with mock.patch(stop, _stop) if stop else contextlib.nullcontext(), \
            mock.patch("hmm.io.write_figures"):
        code, _, err_real = run_cli(prog, [*argv, "--no-progress"], tmp)
    assert code in (0, 2), err_real
    assert (code == 0) == (code_dry == 0), \
        f"dry run {code_dry} ({err.strip()}), real run {code} ({err_real.strip()})"
    return code_dry


def occupied(tmp):
    """A file where an output directory would go."""
    (tmp / "afile").write_text("not a directory")


# --------------------------------------------------------------------------- dem run
SCENE_CASES = {
    "valid": ([], None, 0),
    "invalid key": ([], lambda t: _edit_scene(t, "particles", "count", -1), 2),
    "output exists": ([], lambda t: _touch(t / "out" / "scene.h5"), 2),
    "output exists, --overwrite": (["--overwrite"],
                                   lambda t: _touch(t / "out" / "scene.h5"), 0),
    "xdmf exists": ([], lambda t: _touch(t / "out" / "scene.xdmf"), 2),
    "output is a directory": (["--overwrite"],
                              lambda t: (t / "out" / "scene.h5").mkdir(parents=True), 2),
    "output directory is a file": (["-o", "afile"], occupied, 2),
    "output directory under a file": (["-o", "afile/sub"], occupied, 2),
}


def _touch(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"an earlier result")


def _edit_scene(tmp, section, key, value):
    scene = copy.deepcopy(BASES["scene"])
    scene[section][key] = value
    (tmp / "scene.toml").write_text(to_toml(scene))


@pytest.mark.parametrize("case", SCENE_CASES)
def test_dem_run_dry_run_agrees_with_the_run(tmp_path, case):
    extra, setup, expected = SCENE_CASES[case]
    (tmp_path / "scene.toml").write_text(to_toml(BASES["scene"]))
    if setup:
        setup(tmp_path)
    argv = ["run", "scene.toml", "-o", "out", *extra] if "-o" not in extra else \
        ["run", "scene.toml", *extra]
    assert agree("dem", argv, tmp_path, "dem.simulation.Simulation.prime") == expected


# --------------------------------------------------------------------------- hmm run
def _stopped(tmp):
    """The elastic problem stopped after load step 1 in ``out``."""
    code, _, err = run_cli("hmm", ["run", "problem.toml", "-o", "out", "--stop-after",
                                   "1", "--no-progress"], tmp)
    assert code == 0, err


def _other_problem(tmp):
    _stopped(tmp)
    changed = copy.deepcopy(ELASTIC)
    changed["micro"]["young"] = 2e6
    (tmp / "problem.toml").write_text(to_toml(changed))


def _without_fields(tmp):
    _stopped(tmp)
    (tmp / "out" / "fields.h5").unlink()


def _foreign_fields(tmp):
    """A stopped run whose fields.h5 was replaced by another program's file."""
    _stopped(tmp)
    path = tmp / "out" / "fields.h5"
    path.unlink()
    with h5py.File(path, "w") as f:
        f.attrs["format"] = "hmm.batch"
        f.create_dataset("steps/00000/x", data=np.zeros(3))


RUN_CASES = {
    "valid": ([], None, 0),
    "invalid key": ([], lambda t: (t / "problem.toml").write_text(
        to_toml({**ELASTIC, "load": {"steps": 0}})), 2),
    "fields.h5 exists": ([], lambda t: _touch(t / "out" / "fields.h5"), 2),
    "fields.h5 exists, --overwrite": (["--overwrite"],
                                      lambda t: _touch(t / "out" / "fields.h5"), 0),
    "fields.h5 is a directory": (["--overwrite"],
                                 lambda t: (t / "out" / "fields.h5").mkdir(parents=True),
                                 2),
    "output directory under a file": (["-o", "afile/sub"], occupied, 2),
    "restart": (["--restart", "--stop-after", "2"], _stopped, 0),
    "restart without a checkpoint": (["--restart"], None, 2),
    "restart from another problem": (["--restart"], _other_problem, 2),
    "restart stopping before the checkpoint": (["--restart", "--stop-after", "1"],
                                               _stopped, 2),
    "restart without fields.h5": (["--restart"], _without_fields, 2),
    "restart into a foreign fields.h5": (["--restart", "--stop-after", "2"],
                                         _foreign_fields, 2),
    "a foreign fields.h5, --overwrite": (["--overwrite", "--stop-after", "2"],
                                         _foreign_fields, 0),
}


@pytest.mark.parametrize("case", RUN_CASES)
def test_hmm_run_dry_run_agrees_with_the_run(tmp_path, case):
    extra, setup, expected = RUN_CASES[case]
    (tmp_path / "problem.toml").write_text(to_toml(ELASTIC))
    if setup:
        setup(tmp_path)
    argv = ["run", "problem.toml", *extra]
    if "-o" not in extra:
        argv += ["-o", "out"]
    if "--stop-after" not in extra:
        argv += ["--stop-after", "1"]
    assert agree("hmm", argv, tmp_path) == expected


PACKED = {**ELASTIC, "micro": {"model": "dem", "packing": "packing.h5"}}


@pytest.mark.parametrize("edit, expected", [
    (None, 0),
    (lambda p: p.write_bytes(p.read_bytes()[:500]), 2),  # truncated
    (lambda p: p.write_text("not hdf5"), 2),
    (lambda p: p.unlink(), 2),
    (lambda p: _set_attr(p, "format", "something else"), 2),
])
def test_hmm_run_dry_run_reads_the_micro_packing(tmp_path, edit, expected):
    (tmp_path / "problem.toml").write_text(to_toml(PACKED))
    write_rve_packing(tmp_path / "packing.h5")
    if edit:
        edit(tmp_path / "packing.h5")
    code = agree("hmm", ["run", "problem.toml", "-o", "out"], tmp_path,
                 "hmm.run._solve")
    assert code == expected


def _set_attr(path, name, value):
    with h5py.File(path, "a") as f:
        f.attrs[name] = value


def test_hmm_run_dry_run_reads_a_packing_file_of_the_wrong_dimension(tmp_path):
    problem = copy.deepcopy(PACKED)
    problem["mesh"] = {"dim": 3, "element": "hex1", "size": [1.0, 1.0, 1.0],
                       "cells": [1, 1, 1]}
    problem["dirichlet"] = [{"boundary": "bottom", "component": c} for c in "xyz"]
    problem["dirichlet"].append({"boundary": "top", "component": "z", "value": -0.01})
    (tmp_path / "problem.toml").write_text(to_toml(problem))
    write_rve_packing(tmp_path / "packing.h5")
    assert agree("hmm", ["run", "problem.toml", "-o", "out"], tmp_path,
                 "hmm.run._solve") == 2
    _, _, err = run_cli("hmm", ["run", "problem.toml", "-o", "out", "--dry-run"],
                        tmp_path)
    assert "packing is 2D, the mesh 3D" in err


@pytest.mark.parametrize("center, expected", [([0.5, 0.5], 2), ([5.0, 5.0], 0)])
def test_hmm_run_dry_run_reads_the_packing_of_a_spot_that_holds_a_point(
        tmp_path, center, expected):
    """An [[imperfection]] packing is read when a Gauss point lies in its spot, by the
    run and by the dry run alike; a spot that holds none is never read."""
    problem = {**PACKED, "imperfection": [{"center": center, "radius": 0.6,
                                           "packing": "weak.h5"}]}
    (tmp_path / "problem.toml").write_text(to_toml(problem))
    write_rve_packing(tmp_path / "packing.h5")
    (tmp_path / "weak.h5").write_text("not a packing")
    assert agree("hmm", ["run", "problem.toml", "-o", "out"], tmp_path,
                 "hmm.run._solve") == expected


# --------------------------------------------------------------------------- hmm rve
RVE_FROM_FILE = {"packing": {"file": "packing.h5"},
                 "test": {"axial_strain": 0.01, "increment": 0.005}}

RVE_CASES = {
    "valid": ([], None, 0),
    "invalid key": ([], lambda t: (t / "rve.toml").write_text(to_toml(
        {**RVE_FROM_FILE, "test": {"axial_strain": -1.0}})), 2),
    "garbage packing": ([], lambda t: (t / "packing.h5").write_text("garbage"), 2),
    "missing packing": ([], lambda t: (t / "packing.h5").unlink(), 2),
    "output exists": ([], lambda t: _touch(t / "out" / "rve_test.h5"), 2),
    "figure exists": ([], lambda t: _touch(t / "out" / "rve_test.png"), 2),
    "output exists, --overwrite": (["--overwrite"],
                                   lambda t: _touch(t / "out" / "rve_test.h5"), 0),
    "output is a directory": (["--overwrite"],
                              lambda t: (t / "out" / "rve_test.h5").mkdir(parents=True),
                              2),
    "output directory under a file": (["-o", "afile/sub"], occupied, 2),
}


@pytest.mark.parametrize("case", RVE_CASES)
def test_hmm_rve_dry_run_agrees_with_the_run(tmp_path, case):
    extra, setup, expected = RVE_CASES[case]
    (tmp_path / "rve.toml").write_text(to_toml(RVE_FROM_FILE))
    write_rve_packing(tmp_path / "packing.h5")
    if setup:
        setup(tmp_path)
    argv = ["rve", "rve.toml", *extra] + ([] if "-o" in extra else ["-o", "out"])
    assert agree("hmm", argv, tmp_path, "hmm.experiment.compress") == expected


def test_hmm_rve_dry_run_of_a_generated_packing_prints_the_plan(tmp_path):
    (tmp_path / "rve.toml").write_text(to_toml(BASES["rve"]))
    assert agree("hmm", ["rve", "rve.toml", "-o", "out"], tmp_path,
                 "hmm.experiment.make_packing") == 0
    _, out, _ = run_cli("hmm", ["rve", "rve.toml", "-o", "out", "--dry-run"], tmp_path)
    n = BASES["rve"]["packing"]["count"]
    assert f"test of {n} particles (2D, generated)" in out
    assert "increments" in out and "memory about" in out and "particle-increments" in out
    assert re.search(r"; time (about|under) \S+ \S+ on one core \(cost model, warm "
                     r"kernels\)$", out.strip())


# --------------------------------------------------------------------------- hmm batch
def _resumable(tmp):
    """A batch file of this sweep, no experiment in it yet."""
    from hmm.batch import Store, load_sweep

    (tmp / "out").mkdir()
    Store(tmp / "out" / "batch.h5", load_sweep(tmp / "sweep.toml"), False).close()


def _foreign(tmp):
    (tmp / "out").mkdir()
    with h5py.File(tmp / "out" / "batch.h5", "w") as f:
        f.attrs["format"] = "some.other.format"


BATCH_CASES = {
    "valid": ([], None, 0),
    "invalid key": ([], lambda t: (t / "sweep.toml").write_text(to_toml(
        {**BASES["sweep"], "sweep": {"grid": {"test.nothing": [1, 2]}}})), 2),
    "resume": ([], _resumable, 0),
    "a foreign batch file": ([], _foreign, 2),
    "a foreign batch file, --overwrite": (["--overwrite"], _foreign, 0),
    "garbage batch file": ([], lambda t: _touch(t / "out" / "batch.h5"), 2),
    "batch.h5 is a directory": ([], lambda t: (t / "out" / "batch.h5").mkdir(
        parents=True), 2),
    "output directory under a file": (["-o", "afile/sub"], occupied, 2),
}


@pytest.mark.parametrize("case", BATCH_CASES)
def test_hmm_batch_dry_run_agrees_with_the_run(tmp_path, case):
    extra, setup, expected = BATCH_CASES[case]
    (tmp_path / "sweep.toml").write_text(to_toml(BASES["sweep"]))
    if setup:
        setup(tmp_path)
    argv = ["batch", "sweep.toml", *extra] + ([] if "-o" in extra else ["-o", "out"])
    assert agree("hmm", argv, tmp_path, "hmm.queue._Master.run") == expected


# --------------------------------------------------------------------------- the plan
def test_dry_runs_print_the_plan(tmp_path):
    (tmp_path / "scene.toml").write_text(to_toml(BASES["scene"]))
    code, out, err = run_cli("dem", ["run", "scene.toml", "--dry-run"], tmp_path)
    assert code == 0, err
    steps = BASES["scene"]["simulation"]["steps"]
    assert f"{steps} steps" in out and f"work {30 * steps:.3g} particle-steps" in out
    assert "on one core (cost model, warm kernels)" in out
    (tmp_path / "problem.toml").write_text(to_toml(ELASTIC))
    code, out, err = run_cli("hmm", ["run", "problem.toml", "-o", "out", "--dry-run"],
                             tmp_path)
    assert code == 0, err
    assert "2 elements, 8 Gauss points, 2 load steps; output out (new)" in out
    code, out, err = run_cli("hmm", ["run", str(ROOT / "examples" / "biaxial.toml"),
                                     "-o", "out", "--dry-run"], tmp_path)
    assert code == 0, err
    assert "work at least 256 RVE calls (32 Gauss points x 8 load steps" in out
    assert re.search(r"; time (about|under) \S+ \S+ on one core", out)
    (tmp_path / "sweep.toml").write_text(to_toml(BASES["sweep"]))
    code, out, err = run_cli("hmm", ["batch", "sweep.toml", "--dry-run"], tmp_path)
    assert code == 0, err
    assert "8 experiments (8 to run, 0 already in" in out and "particle-increments" in out
    assert re.search(r"; time (about|under) \S+ \S+ on one core \(cost model, warm "
                     r"kernels\)$", out.strip())


def test_a_restart_dry_run_names_the_steps_left(tmp_path):
    (tmp_path / "problem.toml").write_text(to_toml(ELASTIC))
    _stopped(tmp_path)
    fields = (tmp_path / "out" / "fields.h5").read_bytes()
    code, out, err = run_cli("hmm", ["run", "problem.toml", "-o", "out", "--restart",
                                     "--dry-run"], tmp_path)
    assert code == 0, err
    assert "load steps 2 to 2 of 2; output out (restart from step 1)" in out
    assert (tmp_path / "out" / "fields.h5").read_bytes() == fields
