"""`hmm run` and `hmm demo`: problem files validated to one line, a multiscale run with
DEM RVEs at the Gauss points, the files it writes."""

import copy
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from problems import elastic_problem

from dem.io.schema import SceneError
from hmm.problem import load_problem, validate_problem
from hmm.problem_schema import schema_markdown
from hmm.run import DEMO, run_problem

ROOT = Path(__file__).resolve().parents[2]

ELASTIC = elastic_problem(2)


def _hmm(*args, cwd):
    """``hmm ARGS`` run in this process from ``cwd``: (returncode, stdout, stderr).
    One test runs the real console entry point as a subprocess."""
    import contextlib
    import io
    import os

    from hmm.cli import main

    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                main(list(args))
            except SystemExit as exc:
                code = exc.code
    finally:
        os.chdir(here)
    return subprocess.CompletedProcess(args, code, out.getvalue(), err.getvalue())


def test_a_problem_file_runs_and_writes_its_outputs(tmp_path):
    (tmp_path / "p.toml").write_text(ELASTIC)
    r = _hmm("run", "p.toml", "--no-progress", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = tmp_path / "output" / "p"
    for f in ("fields.h5", "fields.xdmf", "load_displacement.png",
              "deviatoric_strain.png"):
        assert (out / f).stat().st_size > 0
    with h5py.File(out / "fields.h5") as f:
        assert sorted(f["steps"]) == ["00000", "00001", "00002"]
        sig = f["steps/00002/gauss/stress"][()]
        force = f["curve/force/top"][()]
    assert np.allclose(sig[:, 1, 1], 1e6 * -0.005 / (1 - 0.09), rtol=1e-10)
    assert force[-1, 1] == pytest.approx(sig[0, 1, 1] * 1.0, rel=1e-10)
    again = _hmm("run", "p.toml", "--no-progress", cwd=tmp_path)
    assert again.returncode == 2 and "--overwrite" in again.stderr
    assert len(again.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("edit, message", [
    (lambda t: t.replace("young = 1e6", "young = -1e6"), "young must be > 0"),
    (lambda t: t.replace("[load]", "[load]\nstep = 3"), "did you mean 'steps'"),
    (lambda t: t.replace('boundary = "left"', 'boundary = "wall"'),
     'boundary "wall" is not a boundary of the mesh'),
    (lambda t: t.replace('size = [1.0, 2.0]', 'size = [1.0, 2.0]\nelement = "hex1"'),
     'element "hex1" does not fit dim = 2'),
    (lambda t: t.replace('cells = [2, 2]', 'cells = [2.5, 2]'), "cells must be integers"),
    (lambda t: t + "\n[output\n", "invalid TOML"),
])
def test_bad_problem_files_end_in_one_line(tmp_path, edit, message):
    (tmp_path / "p.toml").write_text(edit(ELASTIC))
    r = _hmm("run", "p.toml", cwd=tmp_path)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hmm run: error: p.toml")
    assert message in lines[0]
    assert not (tmp_path / "output").exists()


def test_dry_run_validates_only(tmp_path):
    (tmp_path / "p.toml").write_text(ELASTIC)
    r = subprocess.run([sys.executable, "-m", "hmm", "run", "p.toml", "--dry-run"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=300,
                       check=False)
    assert r.returncode == 0 and "16 Gauss points" in r.stdout
    assert not (tmp_path / "output").exists()


def test_the_dry_run_sizes_each_rve_call_by_the_load_step():
    """The cost model's strain increment per call: the platen's travel over the
    sample's height per load step, or a prescribed gradient per step; none for a run
    driven by forces alone."""
    from hmm.dryrun import strain_increment

    box = np.array([[0.0, 0.04, 0.04, 0.0], [0.0, 0.0, 0.08, 0.08]])
    assert strain_increment(DEMO, box) == pytest.approx(0.0008 / 0.08 / 8)
    sheared = {"dirichlet": [{"boundary": "top", "gradient": [[0.0, 0.01], [0.0, 0.0]]}],
               "load": {"steps": 10}}
    assert strain_increment(sheared, box) == pytest.approx(1e-3)
    periodic = {"dirichlet": [], "load": {"steps": 4, "gradient": 0.02}}
    assert strain_increment(periodic, box) == pytest.approx(5e-3)
    assert strain_increment({"dirichlet": [{"boundary": "bottom", "component": "y",
                                            "value": 0.0}], "load": {"steps": 4}},
                            box) is None


def test_multiscale_biaxial_with_dem_rves(tmp_path):
    """The demo problem, shrunk: 2 elements, 8 RVEs of 30 disks, 2 load steps. The
    sample carries more axial than lateral load, the lateral stress stays near the
    confining pressure, and every point ran the DEM."""
    prob = copy.deepcopy(DEMO)
    prob["mesh"]["cells"] = [1, 2]
    prob["micro"]["count"] = 30
    prob["load"]["steps"] = 2
    prob["dirichlet"][2]["value"] = -0.0004
    summary = run_problem(validate_problem(prob), tmp_path / "out", progress=False)
    assert summary["load_factor"] == pytest.approx(1.0)
    assert summary["dem_points"] == summary["gauss_points"] == 8
    with h5py.File(tmp_path / "out" / "fields.h5") as f:
        sig = f["steps/00002/gauss/stress"][()]
    width = DEMO["mesh"]["size"][0]
    top = summary["reactions"]["top"][1]
    assert -top / width > 1.05e5  # axial stress above the confinement
    assert np.mean(sig[:, 0, 0]) == pytest.approx(-1e5, rel=0.1)


def test_multiscale_with_polygon_rves(tmp_path):
    """[micro] shape = "polygon": the Gauss points run RVEs of hexagons (one element,
    4 points of 12 hexagons, one load step) and the run converges with the lateral
    stress near the confining pressure; a polygon in a 3D mesh is refused."""
    from hmm.problem_build import build_macro, model_factory

    prob = copy.deepcopy(DEMO)
    prob["mesh"]["cells"] = [1, 1]
    prob["micro"].update(count=12, shape="polygon", sides=6)
    prob["load"]["steps"] = 1
    prob["dirichlet"][2]["value"] = -0.0002
    problem = validate_problem(prob)
    macro = build_macro(problem)
    model = model_factory(problem, 2, points=macro.gauss_points())(0)
    corners = np.diff(model.rve.bodies.table.arrays()[2])
    assert set(corners[model.rve.bodies.shape].tolist()) == {6}
    summary = run_problem(problem, tmp_path / "out", progress=False)
    assert summary["load_factor"] == pytest.approx(1.0)
    assert summary["dem_points"] == summary["gauss_points"] == 4
    with h5py.File(tmp_path / "out" / "fields.h5") as f:
        sig = f["steps/00001/gauss/stress"][()]
    assert np.mean(sig[:, 0, 0]) == pytest.approx(-1e5, rel=0.1)
    three = copy.deepcopy(prob)
    three["mesh"].update(dim=3, element="hex1", size=[1.0, 1.0, 1.0], cells=[1, 1, 1])
    with pytest.raises(SceneError, match=r'\[micro\] shape = "polygon" needs dim = 2'):
        validate_problem(three)


def test_demo_problem_is_valid_and_documented():
    p = validate_problem(DEMO, "<demo>")
    assert p["micro"]["model"] == "dem"
    doc = (ROOT / "docs" / "multiscale.md").read_text()
    assert schema_markdown() in doc  # the reference is generated, never edited
    with pytest.raises(SceneError, match="needs supports"):
        validate_problem({**DEMO, "dirichlet": []})


def test_example_problem_file_is_the_demo():
    example = load_problem(ROOT / "examples" / "biaxial.toml")
    demo = validate_problem(DEMO, "<demo>")
    for section in demo:
        if section not in ("source", "output"):
            assert example[section] == demo[section], section


def test_restart_continues_a_stopped_run_bit_for_bit(tmp_path):
    (tmp_path / "p.toml").write_text(ELASTIC.replace(
        "steps = 2", "steps = 3").replace("[load]", "[output]\ncheckpoint_every = 1\n\n[load]"))
    assert _hmm("run", "p.toml", "-o", "full", cwd=tmp_path).returncode == 0
    assert _hmm("run", "p.toml", "-o", "cut", "--stop-after", "1",
                cwd=tmp_path).returncode == 0
    r = _hmm("run", "p.toml", "-o", "cut", "--restart", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    with h5py.File(tmp_path / "full" / "fields.h5") as a, \
            h5py.File(tmp_path / "cut" / "fields.h5") as b:
        assert sorted(a["steps"]) == sorted(b["steps"])
        for name in ("steps/00003/displacement", "steps/00003/gauss/stress",
                     "curve/force/top", "curve/load_factor"):
            assert np.array_equal(a[name][()], b[name][()])
    (tmp_path / "p.toml").write_text((tmp_path / "p.toml").read_text().replace(
        "young = 1e6", "young = 2e6"))
    r = _hmm("run", "p.toml", "-o", "cut", "--restart", cwd=tmp_path)
    assert r.returncode == 2 and "belongs to another problem" in r.stderr


def test_a_checkpoint_without_the_work_curves_restarts_with_them_unknown(tmp_path):
    """A checkpoint written before the runs counted their work (no ``curve/work``)
    restarts: the steps it holds get NaN work (unknown, not zero), the steps run after
    the restart their own counts, and the rest of the curve is as without the loss. The
    first step after a restart also counts the call of every point that re-evaluates
    its starting state (16 points here), as it does with the work curves intact."""
    (tmp_path / "p.toml").write_text(ELASTIC.replace(
        "steps = 2", "steps = 3").replace("[load]", "[output]\ncheckpoint_every = 1\n\n[load]"))
    assert _hmm("run", "p.toml", "-o", "full", cwd=tmp_path).returncode == 0
    assert _hmm("run", "p.toml", "-o", "cut", "--stop-after", "1",
                cwd=tmp_path).returncode == 0
    with h5py.File(tmp_path / "cut" / "checkpoint.h5", "a") as f:
        del f["curve/work"]  # as an earlier version wrote it
    r = _hmm("run", "p.toml", "-o", "cut", "--restart", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    with h5py.File(tmp_path / "full" / "fields.h5") as a, \
            h5py.File(tmp_path / "cut" / "fields.h5") as b:
        for name in ("rve_calls", "rve_seconds", "dem_steps"):
            full, cut = a["curve/work/" + name][()], b["curve/work/" + name][()]
            assert cut.shape == full.shape == (4,)
            assert np.isnan(cut[:2]).all() and np.isfinite(cut[2:]).all(), name
        calls = a["curve/work/rve_calls"][()]
        assert np.array_equal(b["curve/work/rve_calls"][2:], calls[2:] + [16, 0])
        assert np.array_equal(a["curve/force/top"][()], b["curve/force/top"][()])


def test_the_field_plot_shows_void_ratio_only_where_every_point_ran_its_rve():
    from hmm.run_figures import _second_panel

    void = np.array([0.19, 0.25])
    values, title, _, _ = _second_panel(np.array([1.0, 1.0]), void)
    assert title == "void ratio [-]" and values is void
    # an elastic point has no packing: its share of DEM says where the RVEs ran
    for dem, v in ((np.array([1.0, 0.0]), void), (np.ones(2), np.array([0.2, np.nan]))):
        values, title, _, limits = _second_panel(dem, v)
        assert title.startswith("share of Gauss points") and values is dem
        assert limits == (0.0, 1.0)


def test_micro_rolling_resistance_keys():
    """[micro] mu_roll gives the RVEs' law rolling resistance; refused with polygons."""
    micro = {**DEMO["micro"], "mu_roll": 0.1, "eta_roll": 0.3}
    p = validate_problem({**DEMO, "micro": micro})
    assert (p["micro"]["mu_roll"], p["micro"]["eta_roll"]) == (0.1, 0.3)
    with pytest.raises(SceneError, match=r"\[micro\] mu_roll: rolling resistance acts "
                                         "between spheres and disks"):
        validate_problem({**DEMO, "micro": {**micro, "shape": "polygon"}})


def test_micro_contact_stiffness_defaults_follow_the_dimension():
    """Without kn, [micro] gives disks 1e8 N/m per metre and spheres 1e5 N/m: both
    kn / (p0 r^(d-2)) = 1e3 at the default p0 and mean radius; kt defaults to kn / 2;
    given values are kept."""
    from hmm.problem_build import micro_stiffness

    micro = {k: v for k, v in DEMO["micro"].items() if k not in ("kn", "kt")}
    mc = validate_problem({**DEMO, "micro": micro})["micro"]
    assert mc["kn"] is None and mc["kt"] is None
    r = float(np.mean(mc["radius"]))
    for dim in (2, 3):
        law = micro_stiffness(mc, dim)
        assert law["kn"] / (mc["p0"] * r ** (dim - 2)) == pytest.approx(1e3)
        assert law["kt"] == 0.5 * law["kn"]
    given = micro_stiffness({**mc, "kn": 2e7, "kt": 0.0}, 3)
    assert (given["kn"], given["kt"]) == (2e7, 0.0)
