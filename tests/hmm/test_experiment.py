"""The standalone RVE compression test (``hmm rve``): physics, files, input errors."""

import argparse
import copy
from pathlib import Path

import h5py
import numpy as np
import pytest

from dem.io.schema import SceneError, schema_markdown
from dem.rve import RVE
from hmm.cli import cmd_rve
from hmm.experiment import (
    RVE_SCHEMA,
    load_config,
    run_experiment,
    validate_config,
)

ROOT = Path(__file__).resolve().parents[2]
P0 = 1.0e5

#: a dense 2D packing of 50 disks, compressed by 6 % in 20 increments
SMALL = {
    "packing": {"count": 50, "radius": [0.8e-3, 1.2e-3], "p0": P0, "seed": 5},
    "contact": {"law": "linear", "kn": 1.0e8, "kt": 5.0e7, "mu": 0.5},
    "test": {"axial_strain": 0.06, "increment": 3e-3},
}

GENERATED = """
[packing]
count = 50
radius = [0.8e-3, 1.2e-3]
p0 = 1e5
[contact]
law = "linear"
kn = 1e8
kt = 5e7
mu = 0.5
"""


POLYGONS = """
[packing]
count = 24
radius = [0.8e-3, 1.2e-3]
p0 = 1e5
seed = 6
shape = "polygon"
sides = 5
sides_max = 6
[contact]
law = "linear"
kn = 1e8
kt = 5e7
mu = 0.5
"""


def _config(data, out):
    cfg = validate_config(copy.deepcopy(data), "small.toml")
    cfg["output"]["dir"] = str(out)
    return cfg


@pytest.fixture(scope="module")
def biaxial(tmp_path_factory):
    out = tmp_path_factory.mktemp("biaxial")
    return run_experiment(_config(SMALL, out), progress=False), out


def _write(tmp_path, text, name="rve.toml"):
    path = tmp_path / name
    path.write_text(text + f'\n[output]\ndir = "{(tmp_path / "out").as_posix()}"\n')
    return path


def _cmd(path, overwrite=False):
    return cmd_rve(argparse.Namespace(file=path, output=None, overwrite=overwrite))


# --------------------------------------------------------------------------- physics
def test_lateral_stress_is_held_at_the_confining_pressure(biaxial):
    result, _ = biaxial
    stress, tol = result.curves["stress"], result.config["test"]["stress_tol"]
    lateral = -stress[:, 0, 0]
    assert np.all(np.abs(lateral - P0) <= tol * P0 * (1 + 1e-12))


def test_axial_strain_follows_the_increments(biaxial):
    result, _ = biaxial
    ea = result.curves["axial_strain"]
    np.testing.assert_allclose(ea, 3e-3 * np.arange(21), rtol=0, atol=1e-12)


def test_stress_ratio_rises_to_a_plausible_peak(biaxial):
    """Isotropic start, a peak after the start, 10-40 degrees for mu = 0.5 disks,
    softening after it."""
    s, ratio = biaxial[0].summary, biaxial[0].curves["stress_ratio"]
    assert abs(ratio[0]) < 0.1
    assert ratio[1] > ratio[0] + 0.1
    assert 10.0 < s["peak_friction_angle"] < 40.0
    assert s["peak_axial_strain"] > 0.0
    assert s["critical_friction_angle"] < s["peak_friction_angle"]
    assert s["peak_friction_angle"] == pytest.approx(
        biaxial[0].curves["friction_angle"].max())


def test_dense_packing_dilates_and_compression_is_positive(biaxial):
    """eps_v is (V0 - V) / V0, as from the void ratio; the dense packing ends dilated
    (eps_v < 0) with a positive dilatancy angle at the peak."""
    c, s = biaxial[0].curves, biaxial[0].summary
    e = c["void_ratio"]
    np.testing.assert_allclose(c["volumetric_strain"], 1 - (1 + e) / (1 + e[0]),
                               rtol=0, atol=1e-10)
    assert c["volumetric_strain"][-1] < -0.005
    assert s["dilatancy_angle"] > 0.0
    assert s["initial_void_ratio"] == e[0]


def test_outputs_hold_the_curves_and_the_packing(biaxial):
    result, out = biaxial
    with h5py.File(out / "rve_test.h5") as f:
        for name, values in result.curves.items():
            np.testing.assert_array_equal(f[name][()], values)
        assert f.attrs["peak_friction_angle"] == result.summary["peak_friction_angle"]
        assert f["stress"].attrs["unit"] == "Pa"
    assert (out / "rve_test.png").read_bytes()[:4] == b"\x89PNG"
    assert not list(out.glob("*.tmp"))
    packing = RVE.load_file(out / "packing.h5")
    assert packing.bodies.n == 50


def test_the_packing_file_says_what_made_it(biaxial):
    """packing.h5: a dem.checkpoint file with the project's version, the [packing] and
    [contact] that made it, and a unit on every dataset."""
    import json

    from dem.io.meta import software

    _, out = biaxial
    units = {}
    with h5py.File(out / "packing.h5") as f:
        assert (f.attrs["format"], f.attrs["version"]) == ("dem.checkpoint", 1)
        assert f.attrs["software"] == software()
        config = json.loads(f.attrs["config"])
        f.visititems(lambda name, obj: units.__setitem__(name, obj.attrs.get("unit"))
                     if isinstance(obj, h5py.Dataset) else None)
    assert config["packing"]["count"] == 50 and config["contact"]["kn"] > 0
    assert units["bodies/pos"] == "m" and units["rve/deformation"] == "1"
    assert not [k for k, u in units.items() if u in (None, "unknown")]


def test_same_seed_same_curves(biaxial, tmp_path):
    again = run_experiment(_config(SMALL, tmp_path), progress=False)
    for name, values in biaxial[0].curves.items():
        np.testing.assert_array_equal(again.curves[name], values, err_msg=name)


def test_saved_packing_restarts_the_same_test(biaxial, tmp_path):
    """``[packing] file`` = the saved packing: same law, pressure and curves."""
    _, out = biaxial
    path = _write(tmp_path, f'[packing]\nfile = "{(out / "packing.h5").as_posix()}"\n'
                            '[test]\naxial_strain = 0.06\nincrement = 3e-3')
    result = run_experiment(load_config(path), progress=False)
    assert result.summary["confining"] == P0
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "rve_test.h5", "rve_test.png"]
    for name, values in biaxial[0].curves.items():
        np.testing.assert_array_equal(result.curves[name], values, err_msg=name)


def test_triaxial_holds_both_lateral_stresses(tmp_path):
    """Spheres: kn scaled to keep overlaps ~ 1e-3 r at p0, as the disks'."""
    data = copy.deepcopy(SMALL)
    data["packing"].update(dim=3, count=40)
    data["contact"].update(kn=1.0e5, kt=5.0e4)
    data["test"].update(axial_strain=4e-3, increment=2e-3)
    result = run_experiment(_config(data, tmp_path), progress=False)
    stress = result.curves["stress"]
    assert stress.shape == (3, 3, 3)
    lateral = -np.stack([stress[:, 0, 0], stress[:, 1, 1]])
    assert np.all(np.abs(lateral - P0) <= 1e-3 * P0 * (1 + 1e-12))
    assert np.all(np.diff(-stress[:, 2, 2]) > 0.0)   # the axial stress rises
    assert np.all(np.diff(result.curves["stress_ratio"]) > 0.0)


def test_polygon_packing_from_the_file_keys(tmp_path, capsys):
    """[packing] shape = "polygon": 24 polygons of 5 or 6 corners at the circumradii
    drawn, consolidated and compressed like disks (the lateral stress held, the axial
    stress rising), reported as polygons; the same file gives the same curves."""
    text = POLYGONS + "[test]\naxial_strain = 2e-3\nincrement = 1e-3\n"
    path = _write(tmp_path, text)
    cfg = load_config(path)
    assert cfg["packing"]["shape"] == "polygon" and cfg["packing"]["sides"] == 5
    result = run_experiment(cfg, progress=False)
    rve = RVE.load_file(tmp_path / "out" / "packing.h5")
    corners = np.diff(rve.bodies.table.arrays()[2])[rve.bodies.shape]
    assert set(corners.tolist()) == {5, 6}
    radii = rve.bodies.table.arrays()[8][rve.bodies.shape] * rve.bodies.table.arrays()[1][
        rve.bodies.shape]
    assert np.all((radii >= 0.8e-3 - 1e-15) & (radii <= 1.2e-3 + 1e-15))
    assert result.summary["particles"] == "polygons"
    stress = result.curves["stress"]
    assert np.all(np.abs(-stress[:, 0, 0] - P0) <= 1e-3 * P0 * (1 + 1e-12))
    assert np.all(np.diff(-stress[:, 1, 1]) > 0.0)
    again = run_experiment(load_config(path), progress=False, overwrite=True)
    np.testing.assert_array_equal(again.curves["stress"], stress)
    assert _cmd(path, overwrite=True) == 0
    assert "24 polygons" in capsys.readouterr().out


# --------------------------------------------------------------------------- CLI
def test_cli_prints_the_summary_and_refuses_to_overwrite(biaxial, tmp_path, capsys):
    _, out = biaxial
    path = _write(tmp_path, f'[packing]\nfile = "{(out / "packing.h5").as_posix()}"\n'
                            '[test]\naxial_strain = 4e-3\nincrement = 2e-3')
    assert _cmd(path) == 0
    shown = capsys.readouterr().out
    assert "peak friction angle" in shown and "rve_test.h5" in shown
    h5 = tmp_path / "out" / "rve_test.h5"
    stamp = h5.stat().st_mtime_ns
    assert _cmd(path) == 2
    err = capsys.readouterr().err
    assert err.startswith("hmm rve: error: output file") and "--overwrite" in err
    assert err.count("\n") == 1
    assert h5.stat().st_mtime_ns == stamp
    assert _cmd(path, overwrite=True) == 0


def test_cli_reports_a_failed_relaxation(biaxial, tmp_path, capsys):
    _, out = biaxial
    path = _write(tmp_path, f'[packing]\nfile = "{(out / "packing.h5").as_posix()}"\n'
                            '[test]\naxial_strain = 6e-3\nincrement = 3e-3\n'
                            'max_relax_steps = 1')
    assert _cmd(path) == 1
    err = capsys.readouterr().err
    assert err.startswith("hmm rve: error: the test failed: RVE did not relax")
    assert err.count("\n") == 1
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("edit, message", [
    (("[test]", "[test]\nincrements = 1e-3"),
     "[test] unknown key 'increments' (did you mean 'increment'?)"),
    (("p0 = 1e5", "p0 = -1e5"), "[packing] p0 must be > 0, got -100000"),
    (("count = 50", 'count = "fifty"'), "count must be an integer, got \"fifty\""),
    (("[test]", "[test]\naxial_strain = 0.01\nincrement = 0.02"),
     "[test] increment = 0.02 must not exceed axial_strain = 0.01"),
    (("count = 50\n", ""), "[packing] missing required key 'count'"),
    (("[packing]", '[packing]\nfile = "none.h5"'),
     "[packing] count is not used with file"),
    (("[packing]", "[packing]\ndim = 4"), "[packing] dim must be 2 or 3, got 4"),
    (("law = \"linear\"", "law = \"hooke\""),
     'law must be "linear", "hertz_mindlin" or "hertz_sjkr"'),
    (("[packing]", '[packing]\nshape = "polyhedron"'),
     "[packing] shape must be \"sphere\", \"box\" or \"polygon\""),
    (("[packing]", '[packing]\nshape = "polygon"\ndim = 3'),
     '[packing] shape = "polygon" needs dim = 2 (in 3D use "box")'),
    (("[packing]", "[packing]\nsides = 5"), "[packing] sides is for shape = \"polygon\""),
    (("[packing]", '[packing]\nshape = "polygon"\nsides = 6\nsides_max = 5'),
     "[packing] sides_max = 5 must be at least sides = 6"),
    (("[packing]", '[packing]\nshape = "polygon"\nsides = 2'),
     "[packing] sides must be in [3, 64], got 2"),
    (("[packing]", '[packing]\nfile = "none.h5"\nshape = "box"'),
     "is not used with file"),
    ((("[packing]", '[packing]\nshape = "polygon"'), ("mu = 0.5", "mu = 0.5\nmu_roll = 0.1")),
     '[contact] mu_roll: rolling resistance acts between spheres and disks, not with '
     "shape = 'polygon'"),
    (("mu = 0.5", "mu = 0.5\nmu_roll = -0.1"), "[contact] mu_roll must be >= 0"),
])
def test_bad_files_fail_in_one_line_without_output(tmp_path, capsys, edit, message):
    text = GENERATED + "[test]\n"
    for old, new in (edit if isinstance(edit[0], tuple) else (edit,)):
        text = text.replace(old, new, 1)
    path = _write(tmp_path, text)
    assert _cmd(path) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"hmm rve: error: {path}: ")
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("text, message", [
    ('[packing]\nfile = "missing.h5"', "missing.h5 does not exist"),
    ('[packing]\nfile = "bad.h5"', "cannot use file"),
    ('[packing]\nfile = "bad.h5"\n[contact]\nlaw = "linear"',
     "[contact] is not used with [packing] file"),
])
def test_bad_packing_files_fail_in_one_line(tmp_path, capsys, text, message):
    (tmp_path / "bad.h5").write_text("not hdf5")
    assert _cmd(_write(tmp_path, text)) == 2
    err = capsys.readouterr().err
    assert err.startswith("hmm rve: error: ") and message in err
    assert err.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_unreadable_and_invalid_toml(tmp_path, capsys):
    assert _cmd(tmp_path / "nothing.toml") == 2
    assert "cannot read RVE test file" in capsys.readouterr().err
    path = tmp_path / "broken.toml"
    path.write_text("[packing\n")
    assert _cmd(path) == 2
    assert "invalid TOML" in capsys.readouterr().err


# --------------------------------------------------------------------------- docs
def test_example_is_valid():
    cfg = load_config(ROOT / "examples" / "rve_biaxial.toml")
    assert cfg["packing"]["dim"] == 2
    assert cfg["test"]["confining"] == cfg["packing"]["p0"]
    with pytest.raises(SceneError, match="unknown section"):
        validate_config({**SMALL, "solver": {}})


def test_undrained_example_is_valid():
    cfg = load_config(ROOT / "examples" / "rve_undrained.toml")
    assert cfg["test"]["kind"] == "undrained"


def test_docs_hold_the_generated_reference():
    page = (ROOT / "docs" / "rve.md").read_text()
    assert schema_markdown(RVE_SCHEMA).strip() in page, (
        "docs/rve.md is out of date: paste schema_markdown(RVE_SCHEMA) into it")


# --------------------------------------------------------------------------- other tests
@pytest.fixture(scope="module")
def undrained(tmp_path_factory):
    out = tmp_path_factory.mktemp("undrained")
    data = copy.deepcopy(SMALL)
    data["test"].update(kind="undrained", axial_strain=0.03)
    return run_experiment(_config(data, out), progress=False), out


def test_undrained_test_holds_the_volume_and_reads_the_pore_pressure(undrained):
    res, _ = undrained
    c, s = res.curves, res.summary
    assert np.abs(c["volumetric_strain"]).max() < 1e-12
    lateral = -c["stress"][:, 0, 0]
    assert np.array_equal(c["excess_pore_pressure"], P0 - lateral)
    assert c["excess_pore_pressure"][0] == pytest.approx(0.0, abs=1e-3 * P0)
    assert s["kind"] == "undrained" and s["peak_deviator"] == c["q"].max()


def test_a_packing_that_dilates_drained_sucks_water_undrained(biaxial, undrained):
    """The dense packing dilates in the drained test; held at constant volume it
    pulls its water into suction and its mean effective stress climbs."""
    assert biaxial[0].summary["final_volumetric_strain"] < 0.0
    s = undrained[0].summary
    assert s["final_excess_pore_pressure"] < 0.0
    assert s["final_mean_stress"] > P0
    assert s["final_deviator"] > 0.0


def test_oedometric_test_has_no_lateral_strain_and_a_plausible_k0(tmp_path):
    data = copy.deepcopy(SMALL)
    data["test"].update(kind="oedometric", axial_strain=0.006, increment=2e-3)
    res = run_experiment(_config(data, tmp_path), progress=False)
    c, s = res.curves, res.summary
    assert c["volumetric_strain"] == pytest.approx(c["axial_strain"], abs=1e-12)
    sig_a = -c["stress"][:, 1, 1]
    assert np.all(np.diff(sig_a) > 0.0)
    assert 0.2 < s["k0"] < 0.9 and 0.2 < s["final_k0"] < 0.9
    assert s["constrained_modulus"] > 0.0
    with h5py.File(tmp_path / "rve_test.h5", "r") as f:
        assert f.attrs["kind"] == "oedometric" and "k0" in f


def test_cli_prints_the_undrained_and_oedometric_summaries(undrained, tmp_path, capsys):
    cfg_text = GENERATED + "[test]\nkind = \"undrained\"\naxial_strain = 0.006\n" \
        "increment = 0.003\n"
    assert _cmd(_write(tmp_path, cfg_text)) == 0
    out = capsys.readouterr().out
    assert "undrained biaxial test (constant volume)" in out
    assert "excess pore pressure" in out and "phase transformation" in out
    path = _write(tmp_path, cfg_text.replace("undrained", "oedometric"), "oedo.toml")
    assert cmd_rve(argparse.Namespace(file=path, output=None, overwrite=True)) == 0
    assert "K0" in capsys.readouterr().out


def test_the_undrained_example_liquefies_and_reports_it(tmp_path):
    """The example's loose 200-disk packing (seed 2) loses its effective stress at
    constant volume: the test ends there with the state recorded (the water carries
    the whole confining pressure) instead of failing on a packing that came apart."""
    cfg = load_config(ROOT / "examples" / "rve_undrained.toml")
    cfg["output"]["dir"] = str(tmp_path)
    res = run_experiment(cfg, progress=False)
    s, c = res.summary, res.curves
    assert s["liquefied"] and s["final_mean_stress"] < 0.01 * P0
    assert c["excess_pore_pressure"][-1] == pytest.approx(P0, rel=0.01)
    assert s["softening"] < 0.01 and s["peak_deviator"] > 0.3 * P0
    assert np.abs(c["volumetric_strain"]).max() < 1e-12


def _run_kind(tmp_path, **test):
    data = copy.deepcopy(SMALL)
    data["test"] = test
    return run_experiment(_config(data, tmp_path), progress=False)


def test_isotropic_compression_and_unloading(tmp_path):
    """The mean stress follows its targets up to p_max and back. The dense packing
    (consolidated without friction) deforms at its contacts only: it comes back to
    its void ratio, its compression and swelling indices agree within 1 %. A loose
    one (consolidated with friction 0.5) is softer and keeps part of its
    compression."""
    res = _run_kind(tmp_path / "dense", kind="isotropic", p_max=4e5, steps=4)
    c, s = res.curves, res.summary
    want = P0 * 4.0 ** (np.array([0, 1, 2, 3, 4, 3, 2, 1, 0]) / 4)
    assert c["p"] == pytest.approx(want, rel=2e-3)
    assert np.all(np.diff(c["void_ratio"][:5]) < 0.0)
    assert s["compression_index"] == pytest.approx(s["swelling_index"], rel=0.01)
    assert abs(s["final_volumetric_strain"]) < 1e-5
    data = copy.deepcopy(SMALL)
    data["packing"]["consolidation_friction"] = 0.5
    data["test"] = {"kind": "isotropic", "p_max": 4e5, "steps": 4}
    loose = run_experiment(_config(data, tmp_path / "loose"), progress=False).summary
    assert loose["bulk_modulus"] < 0.8 * s["bulk_modulus"]
    assert loose["final_volumetric_strain"] > 10 * abs(s["final_volumetric_strain"])
    assert loose["compression_index"] > loose["swelling_index"]


def test_simple_shear_holds_the_normal_stress_and_mobilises_friction(tmp_path):
    """The normal stress stays at the confining pressure, the lateral strain at zero;
    tau / sigma_n rises to a peak friction angle of a dense frictional packing."""
    res = _run_kind(tmp_path, kind="simple_shear", axial_strain=0.03, increment=3e-3)
    c, s = res.curves, res.summary
    assert c["normal_stress"][1:] == pytest.approx(P0, rel=2e-3)
    assert c["shear_strain"] == pytest.approx(np.linspace(0.0, 0.03, 11), rel=1e-3)
    f = c["stress"]
    assert np.all(c["shear_stress"][1:] > 0.0) and np.allclose(f[:, 0, 1], f[:, 1, 0])
    assert 10.0 < s["peak_friction_angle"] < 40.0
    assert s["final_normal_strain"] < 0.0  # the dense packing dilates


def test_cyclic_undrained_loading_builds_pore_pressure(tmp_path):
    """Strain cycles at constant volume: the axial strain follows the triangle wave,
    the volume never changes, and the cycles raise the excess pore pressure."""
    res = _run_kind(tmp_path, kind="cyclic", axial_strain=1e-3, increment=5e-4,
                    cycles=2)
    c, s = res.curves, res.summary
    wave = 1e-3 * np.array([0, .5, 1, .5, 0, -.5, -1, -.5, 0, .5, 1, .5, 0, -.5, -1,
                            -.5, 0])
    n = len(c["axial_strain"])
    assert c["axial_strain"] == pytest.approx(wave[:n], abs=1e-12)
    assert np.abs(c["volumetric_strain"]).max() < 1e-12
    assert s["max_pore_pressure_ratio"] > 0.0
    assert s["cycles_run"] == pytest.approx((n - 1) / 8)


@pytest.mark.parametrize("test,message", [
    ({"kind": "drained", "cycles": 3}, 'cycles applies to kind = "cyclic"'),
    ({"kind": "isotropic", "p_max": 5e4}, "p_max = 50000 Pa must exceed"),
])
def test_keys_of_another_kind_are_refused(test, message):
    data = copy.deepcopy(SMALL)
    data["test"] = test
    with pytest.raises(SceneError, match=message):
        validate_config(data, "small.toml")


def test_the_printed_report_of_each_kind_of_test():
    """hmm rve's report: the drained test's critical state is the mean over the last 20 %
    of the axial strain; an undrained test without a phase transformation says so, and
    one that liquefied says where; every report ends with the wall time and files."""
    from hmm.experiment_summary import report

    s = {"n_particles": 60, "particles": "disks", "confining": 1e5, "dim": 2,
         "initial_void_ratio": 0.2, "wall_time": 1.5, "peak_friction_angle": 23.4,
         "peak_stress_ratio": 0.43, "peak_axial_strain": 0.02, "dilatancy_angle": 3.2,
         "critical_friction_angle": 21.2, "final_volumetric_strain": -0.01}
    text = report("t.toml", {**s, "kind": "drained"}, ["out/a.h5", "out/b.png"], 0.05)
    assert text.startswith("hmm rve t.toml: drained biaxial test, 60 disks")
    assert "(mean over axial strain >= 4.00 %)" in text
    assert text.endswith("wall time                1.5 s\n"
                         "  output                   out/a.h5, out/b.png")
    und = {**s, "kind": "undrained", "dim": 3, "peak_deviator": 2e5, "peak_mean_stress": 1e5,
           "phase_transformation_mean_stress": float("nan"),
           "final_excess_pore_pressure": 5e4, "max_excess_pore_pressure": 6e4,
           "liquefied": True, "liquefaction_axial_strain": 0.012, "softening": 0.1}
    text = report("t.toml", und, [], 0.05)
    assert "undrained triaxial test (constant volume)" in text
    assert "phase transformation     none" in text
    assert "liquefied                at axial strain 1.20 %" in text
