"""Sweeps of standalone RVE tests (``hmm batch``), in one process: expansion and ids,
input errors, resume, the failure policy, the files."""

import argparse
import csv
import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from problems import sweep_text

from dem.io.schema import SceneError, schema_markdown
from hmm import batch, queue
from hmm.batch import BATCH_SCHEMA, expand, load_sweep, read_batch
from hmm.cli import cmd_batch

ROOT = Path(__file__).resolve().parents[2]

#: 3 experiments of 36 disks, 2 increments each (about a second each)
SWEEP = sweep_text(36, 1, 0.02, 0.01)

_RUN_ONE = queue.run_one

BASE = {"packing": {"count": 36, "radius": [0.8e-3, 1.2e-3], "p0": 1e5},
        "contact": {"law": "linear", "kn": 1e8, "kt": 5e7, "mu": 0.5}}


def _write(tmp_path, text, name="sweep.toml"):
    path = tmp_path / name
    path.write_text(text + f'\n[output]\ndir = "{(tmp_path / "out").as_posix()}"\n')
    return path


def _cmd(path, output=None, overwrite=False):
    return cmd_batch(argparse.Namespace(file=path, output=output, overwrite=overwrite,
                                        no_progress=True))


def _numbers(path):
    """{id: (attrs without run metadata, curves)} of a batch file."""
    return {k: ({a: v for a, v in r["attrs"].items() if a not in batch.RUN_METADATA},
                r["curves"]) for k, r in read_batch(path).items()}


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def assert_same_numbers(a, b):
    a, b = _numbers(a), _numbers(b)
    assert sorted(a) == sorted(b)
    for k in a:
        assert repr(a[k][0]) == repr(b[k][0]), k
        assert sorted(a[k][1]) == sorted(b[k][1]), k
        for name in a[k][1]:
            np.testing.assert_array_equal(a[k][1][name], b[k][1][name], err_msg=k)


class _Counting:
    """Stands in for run_one: counts calls, may raise on the n-th or for an id."""

    def __init__(self, raise_on=None, error=None):
        self.calls, self.raise_on, self.error = [], raise_on, error

    def __call__(self, cfg, poll=None):
        self.calls.append(cfg["source"].split()[-1])
        if self.raise_on in (len(self.calls), self.calls[-1]):
            raise self.error
        return _RUN_ONE(cfg, poll)


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """The 3 experiments run without interruption: (sweep file, output dir)."""
    tmp = tmp_path_factory.mktemp("finished")
    path = _write(tmp, SWEEP)
    assert _cmd(path) == 0
    return path, tmp / "out"


# --------------------------------------------------------------------------- input
def test_grid_is_the_product_in_order_with_stable_ids():
    grid = {"test.confining": [5e4, 1e5, 2e5], "packing": {"seed": [1, 2]}}
    s = expand({"base": BASE, "sweep": {"grid": grid}}, "s.toml")
    assert [(e.overrides["test.confining"], e.overrides["packing.seed"])
            for e in s.experiments] == [(c, k) for c in (5e4, 1e5, 2e5) for k in (1, 2)]
    assert s.parameters == ["test.confining", "packing.seed"]
    ids = [e.id for e in s.experiments]
    assert len(set(ids)) == 6 and ids[0].startswith("000-") and ids[5][:4] == "005-"
    again = expand({"base": BASE, "sweep": {"grid": {
        "test.confining": [50000, 100000, 200000], "packing.seed": [1, 2]}}}, "t.toml")
    assert [e.id for e in again.experiments] == ids  # dotted or quoted, 5e4 or 50000
    assert s.experiments[3].config["test"]["confining"] == 1e5
    assert s.experiments[3].config["packing"]["seed"] == 2
    other = expand({"base": BASE, "sweep": {"grid": {"packing.seed": [1, 2]}}})
    assert other.experiments[0].id != ids[0]  # the hash is of the overrides


def test_list_sweep_and_default_output():
    s = expand({"base": BASE, "sweep": {"list": [
        {"test.confining": 5e4}, {"contact": {"mu": 0.3}, "packing.count": 40}]}},
        "dir/runs.toml")
    assert [e.overrides for e in s.experiments] == [
        {"test.confining": 5e4}, {"contact.mu": 0.3, "packing.count": 40}]
    assert s.parameters == ["test.confining", "contact.mu", "packing.count"]
    assert s.experiments[1].config["contact"]["mu"] == 0.3
    assert s.experiments[1].config["test"]["confining"] == 1e5  # default p0
    assert s.out_dir == "output/runs"


@pytest.mark.parametrize("edit, message", [
    (('"test.confining"', '"test.confining_pressure"'),
     ("[sweep] grid: unknown key path 'test.confining_pressure' (did you mean "
      "'test.confining'?)")),
    (("[5e4, 1e5, 2e5]", "[5e4, -1e5]"),
     "experiment 001-"),
    (("[5e4, 1e5, 2e5]", "[5e4, -1e5]"),
     ": [test] confining must be > 0, got -100000"),
    (("[5e4, 1e5, 2e5]", '[5e4, "high"]'), "confining must be a number"),
    (("[5e4, 1e5, 2e5]", "[]"), "'test.confining' must be a non-empty array"),
    (("[5e4, 1e5, 2e5]", "[1e5, 1e5]"), "have the same overrides"),
    (('"test.confining"', '"output.dir"'), "unknown key path 'output.dir'"),
    (("[sweep.grid]", "[sweep.table]"), "[sweep] needs exactly one of grid and list"),
    (("[base.test]", "[base.output]\ndir = 'x'\n[base.test]"),
     "[base] output is not used"),
    (("[base.packing]", "[solver]\n[base.packing]"), "unknown section [solver]"),
    (("count = 36", "count = 36.5"), "count must be an integer, got 36.5"),
])
def test_bad_sweeps_fail_in_one_line_without_output(tmp_path, capsys, edit, message):
    path = _write(tmp_path, SWEEP.replace(*edit, 1))
    assert _cmd(path) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"hmm batch: error: {path}")
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_unreadable_sweep(tmp_path, capsys):
    assert _cmd(tmp_path / "nothing.toml") == 2
    assert "cannot read sweep file" in capsys.readouterr().err


# --------------------------------------------------------------------------- runs
def test_outputs(finished, capsys):
    path, out = finished
    data = read_batch(out / "batch.h5")
    sweep = load_sweep(path)
    assert sorted(data) == [e.id for e in sweep.experiments]
    for e in sweep.experiments:
        a = data[e.id]["attrs"]
        assert a["status"] == "done" and a["confining"] == e.overrides["test.confining"]
        assert json.loads(a["overrides"]) == e.overrides
        assert data[e.id]["curves"]["axial_strain"].shape == (3,)
        assert 5.0 < a["peak_friction_angle"] < 45.0
    rows = _rows(out / "summary.csv")
    assert [r["id"] for r in rows] == [e.id for e in sweep.experiments]
    first = data[rows[0]["id"]]["attrs"]
    assert float(rows[0]["peak_friction_angle"]) == first["peak_friction_angle"]
    assert float(rows[0]["e0"]) == first["initial_void_ratio"]
    assert rows[0]["status"] == "done" and float(rows[2]["test.confining"]) == 2e5
    assert (out / "summary.png").read_bytes()[:4] == b"\x89PNG"
    assert not list(out.glob("*.tmp"))


def test_rerun_skips_what_is_stored(finished, tmp_path, monkeypatch, capsys):
    path, out = finished
    shutil.copytree(out, tmp_path / "out")
    fake = _Counting()
    monkeypatch.setattr(queue, "run_one", fake)
    assert _cmd(path, output=tmp_path / "out") == 0
    assert fake.calls == []
    assert "(0 run, 3 already in batch.h5)" in capsys.readouterr().out
    assert_same_numbers(tmp_path / "out" / "batch.h5", out / "batch.h5")


def test_interrupted_then_resumed_equals_uninterrupted(finished, tmp_path,
                                                       monkeypatch, capsys):
    path, out = finished
    cut = _Counting(raise_on=2, error=KeyboardInterrupt())
    monkeypatch.setattr(queue, "run_one", cut)
    assert _cmd(path, output=tmp_path) == 130
    assert "interrupted" in capsys.readouterr().err
    with h5py.File(tmp_path / "batch.h5") as f:
        assert list(f) == [cut.calls[0]]  # what finished was kept
    again = _Counting()
    monkeypatch.setattr(queue, "run_one", again)
    assert _cmd(path, output=tmp_path) == 0
    assert again.calls == cut.calls[1:] + [load_sweep(path).experiments[2].id]
    assert_same_numbers(tmp_path / "batch.h5", out / "batch.h5")
    assert (tmp_path / "summary.csv").read_text() == (out / "summary.csv").read_text()


def test_a_changed_sweep_is_refused_unless_overwrite(finished, tmp_path, capsys):
    _, out = finished
    shutil.copytree(out, tmp_path / "out")
    h5 = tmp_path / "out" / "batch.h5"
    stamp = h5.stat().st_mtime_ns
    changed = _write(tmp_path, SWEEP.replace("mu = 0.5", "mu = 0.4").replace(
        "[5e4, 1e5, 2e5]", "[5e4]"))
    assert _cmd(changed) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"hmm batch: error: {h5} holds experiment 000-")
    assert "--overwrite" in err and err.count("\n") == 1
    assert h5.stat().st_mtime_ns == stamp
    assert _cmd(changed, overwrite=True) == 0
    assert len(read_batch(h5)) == 1


def test_relaxation_failure_is_recorded_and_the_batch_goes_on(tmp_path, capsys):
    text = SWEEP.split("[sweep.grid]")[0] + (
        '[[sweep.list]]\n"test.confining" = 5e4\n'
        '[[sweep.list]]\n"test.max_relax_steps" = 1\n')
    assert _cmd(_write(tmp_path, text)) == 1
    assert "1 done, 1 failed" in capsys.readouterr().out
    data = read_batch(tmp_path / "out" / "batch.h5")
    status = {k: (r["attrs"]["status"], r["attrs"].get("message", "")) for k, r in
              data.items()}
    assert [s for s, _ in status.values()] == ["done", "failed"]
    assert "RelaxationError" in list(status.values())[1][1]
    rows = _rows(tmp_path / "out" / "summary.csv")
    assert rows[1]["status"] == "failed" and rows[1]["peak_friction_angle"] == ""
    assert rows[1]["test.confining"] == "100000.0"  # not swept there: the default p0
    assert (tmp_path / "out" / "summary.png").exists()


def test_any_other_error_stops_the_batch_naming_the_experiment(tmp_path, monkeypatch,
                                                               capsys):
    path = _write(tmp_path, SWEEP)
    bad = load_sweep(path).experiments[1].id
    monkeypatch.setattr(queue, "run_one", _Counting(bad, ValueError("injected")))
    assert _cmd(path) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"hmm batch: error: experiment {bad} raised ValueError: "
                          f"injected") and err.count("\n") == 1
    assert "1 of 3 experiments done" in err
    data = read_batch(tmp_path / "out" / "batch.h5")
    assert len(data) == 1 and bad not in data  # a bug's experiment is not recorded
    rows = _rows(tmp_path / "out" / "summary.csv")
    assert [r["status"] for r in rows] == ["done", "not run", "not run"]


# --------------------------------------------------------------------------- docs
def test_example_is_valid():
    s = load_sweep(ROOT / "examples" / "sweep.toml")
    assert len(s.experiments) == 8 and s.parameters[0] == "test.confining"
    with pytest.raises(SceneError, match="unknown section"):
        expand({"base": BASE, "sweep": {"grid": {"packing.seed": [1]}}, "x": {}})


def test_docs_hold_the_generated_reference():
    page = (ROOT / "docs" / "batch.md").read_text()
    assert schema_markdown(BATCH_SCHEMA).strip() in page, (
        "docs/batch.md is out of date: paste schema_markdown(BATCH_SCHEMA) into it")


def test_a_batch_of_undrained_tests_is_refused_in_one_line(tmp_path):
    path = _write(tmp_path, SWEEP.replace("[base.test]\n", "[base.test]\nkind = \"undrained\"\n"))
    with pytest.raises(SceneError, match=r"kind = \"undrained\": a batch sweeps drained"):
        load_sweep(path)


@pytest.mark.parametrize("tag", [None, "hmm.fields"])
def test_a_foreign_hdf5_file_is_refused_not_overwritten(tmp_path, capsys, tag):
    """An existing batch.h5 that another program wrote (a fields.h5 carries its own
    tag; older ones and other programs' files none) is refused in one line, untouched."""
    h5 = tmp_path / "out" / "batch.h5"
    h5.parent.mkdir()
    with h5py.File(h5, "w") as f:
        f.create_dataset("mesh/points", data=np.zeros((4, 3)))
        if tag is not None:
            f.attrs["format"] = tag
    stamp = h5.stat().st_mtime_ns
    assert _cmd(_write(tmp_path, SWEEP)) == 2
    err = capsys.readouterr().err
    what = f"a '{tag}' file" if tag else "an HDF5 file without a format tag"
    assert err == (f"hmm batch: error: {h5} is {what}, not a batch file ('hmm.batch'); "
                   f"pass --overwrite to replace it or choose another --output\n")
    assert h5.stat().st_mtime_ns == stamp
    with h5py.File(h5) as f:
        assert list(f) == ["mesh"]


def test_an_empty_batch_file_resumes(tmp_path, monkeypatch):
    """A batch.h5 cut short before its first write (no tag, nothing in it) is resumed."""
    h5 = tmp_path / "out" / "batch.h5"
    h5.parent.mkdir()
    h5py.File(h5, "w").close()
    sweep = load_sweep(_write(tmp_path, SWEEP))
    store = batch.Store(h5, sweep, overwrite=False)
    try:
        assert store.stored == {}
        assert store.f.attrs["format"] == "hmm.batch"
    finally:
        store.f.close()
