"""Saturated problems from problem files: [fluid], [[drainage]], [time] and
[[platen]] validated, built and run as the Python API does; their output, restart,
and a DEM micro model answering undrained."""

import copy
import runpy
from pathlib import Path

import h5py
import numpy as np
import pytest

from dem.io.schema import SceneError
from hmm.coupling import SolverSettings
from hmm.farm import SerialFarm
from hmm.micro import LinearElastic
from hmm.porous import BiotSolver
from hmm.problem import validate_problem
from hmm.problem_build import build_loads, build_macro, build_porous
from hmm.run import run_problem

ROOT = Path(__file__).resolve().parents[2]

E, NU, Q, H = 1e7, 0.25, 1e4, 1.0

COLUMN = {
    "mesh": {"dim": 2, "element": "quad8", "size": [0.1, H], "cells": [1, 8]},
    "dirichlet": [{"boundary": "bottom", "component": "y"},
                  {"boundary": "left", "component": "x"},
                  {"boundary": "right", "component": "x"}],
    "pressure": [{"boundary": "top", "value": Q, "ramp": True}],
    "load": {"steps": 12},
    "fluid": {"permeability": 1.2e-10, "bulk_modulus": 2.2e9},
    "drainage": [{"boundary": "top", "pressure": 0.0}],
    "time": {"end": 1.0, "first": 0.01},
    "micro": {"model": "linear_elastic", "young": E, "poisson": NU},
}


def column(**changes):
    data = copy.deepcopy(COLUMN)
    for section, values in changes.items():
        if values is None:
            data.pop(section, None)
        elif isinstance(values, dict):
            data.setdefault(section, {}).update(values)
        else:
            data[section] = values
    return validate_problem(data, source="column.toml")


def test_a_problem_file_runs_the_solver_of_the_python_api(tmp_path):
    problem = column()
    out = run_problem(problem, tmp_path / "run", progress=False)
    macro = build_macro(problem)
    sup, fc, fr, _ = build_loads(problem, macro)
    porous, schedule = build_porous(problem, macro)
    s = BiotSolver(porous, SerialFarm([LinearElastic(E, NU) for _ in range(macro.n_gp)]),
                   sup, schedule, fc, fr, SolverSettings())
    for t in schedule.times():
        s.advance(t - s.t)
    assert out["time"] == pytest.approx(1.0)
    assert np.array_equal(out["p"], s.p) and np.array_equal(out["u"], s.u)
    assert out["load_factor"] == 1.0


def test_fields_carry_pressure_flux_and_total_stress(tmp_path):
    run_problem(column(), tmp_path, progress=False)
    with h5py.File(tmp_path / "fields.h5", "r") as f:
        last = f["steps"][sorted(f["steps"])[-1]]
        assert last.attrs["time"] == pytest.approx(1.0)
        assert f.attrs["pressure_element"] == "quad1"
        p = last["pore_pressure"][()]
        y = f["mesh/points"][:, 1]
        assert np.all(p[np.isclose(y, H)] == 0.0) and p.max() > 0.0
        # a column: the total vertical stress carries the load everywhere
        total = last["gauss/total_stress"][()]
        assert total[:, 1, 1] == pytest.approx(-Q, rel=1e-8)
        eff = last["gauss/stress"][()]
        pg = last["gauss/pore_pressure"][()]
        assert eff - pg[:, None, None] * np.eye(2) == pytest.approx(total, abs=1e-9 * Q)
        flux = last["gauss/darcy_flux"][()]
        assert np.all(flux[:, 1] > 0.0)  # water leaves upwards
        assert np.allclose(flux[:, 0], 0.0, atol=1e-10 * flux[:, 1].max())
        assert f["curve/time"][-1] == pytest.approx(1.0)
        assert np.all(np.diff(f["curve/pore_pressure/max"][1:]) < 0.0)  # 0: before
    xdmf = (tmp_path / "fields.xdmf").read_text()
    assert 'Name="pore_pressure" AttributeType="Scalar" Center="Node"' in xdmf
    assert 'Name="total_stress_yy"' in xdmf
    assert (tmp_path / "pore_pressure.png").stat().st_size > 0


def test_restart_of_a_saturated_run_repeats_it(tmp_path):
    problem = column(load={"steps": 4}, output={"checkpoint_every": 2})
    full = run_problem(problem, tmp_path / "full", progress=False)
    run_problem(problem, tmp_path / "cut", progress=False, stop_after=1)
    again = run_problem(problem, tmp_path / "cut", progress=False, restart=True)
    assert np.array_equal(full["p"], again["p"]) and np.array_equal(full["u"], again["u"])
    assert again["time"] == full["time"] == 1.0


@pytest.mark.parametrize("changes,message", [
    ({"fluid": None}, r"\[time\] applies to a saturated problem only"),
    ({"fluid": None, "time": None}, r"\[\[drainage\]\] #1 applies to a saturated"),
    ({"time": None}, r"needs \[time\] end"),
    ({"fluid": {"permeability": None}}, r"missing required key 'permeability'"),
    ({"fluid": {"permeability": [[1e-12, 2e-12], [2e-12, 1e-12]]}},
     r"symmetric positive definite"),
    ({"fluid": {"permeability": [1e-12, 1e-12]}}, r"2 rows of 2 numbers"),
    ({"fluid": {"biot": 0.3}}, r"biot must be in \[porosity, 1\]"),
    ({"mesh": {"element": "quad1"}}, r"needs a quadratic element"),
    ({"solver": {"kinematics": "finite"}}, r"finite\" needs an objective micro model"),
    ({"drainage": [{"boundary": "top", "pressure": 0.0, "flux": 1e-6}]},
     r"a pressure or a flux \(one of them\)"),
    ({"time": {"first": 0.5}}, r"longer than an equal step"),
    ({"fluid": None, "time": None, "drainage": None,
      "solver": {"coupling": "fixed_stress"}}, r"coupling applies to a saturated"),
    ({"solver": {"coupling": "staggered"}}, r"coupling must be"),
    ({"solver": {"predictor": "extrapolated"}}, r"extrapolated.*is for dry problems"),
])
def test_saturated_problem_files_are_checked_in_one_line(changes, message):
    with pytest.raises(SceneError, match=message) as err:
        column(**changes)
    assert "\n" not in str(err.value) and str(err.value).startswith("column.toml:")


def test_an_unknown_drainage_boundary_is_named():
    problem = column(drainage=[{"boundary": "roof", "pressure": 0.0}])
    with pytest.raises(SceneError, match=r"\[\[drainage\]\] #1 boundary \"roof\""):
        build_macro(problem)


def test_a_platen_carries_a_force_as_a_rigid_plate(tmp_path):
    """A dry block under a force on a rigid frictionless platen: its top moves as one,
    by the plane-strain uniaxial answer sigma H (1 - nu^2) / E."""
    data = {
        "mesh": {"dim": 2, "element": "quad2", "size": [0.2, 0.1], "cells": [4, 2]},
        "dirichlet": [{"boundary": "bottom", "component": "y"},
                      {"point": [0.0, 0.0], "component": "x"}],
        "platen": [{"boundary": "top", "component": "y"}],
        "traction": [{"boundary": "top", "value": [0.0, -Q]}],
        "load": {"steps": 1},
        "micro": {"model": "linear_elastic", "young": E, "poisson": NU},
    }
    problem = validate_problem(data, source="block.toml")
    out = run_problem(problem, tmp_path, progress=False)
    macro = build_macro(problem)
    top = out["u"][macro.dofs("top", 1)]
    assert np.ptp(top) == 0.0
    assert top[0] == pytest.approx(-Q * 0.1 * (1 - NU**2) / E, rel=1e-10)
    data["dirichlet"].append({"boundary": "top", "component": "y", "value": 0.0})
    with pytest.raises(SceneError, match=r"block.toml: \[\[platen\]\] #1 .* also held"):
        build_loads(validate_problem(data, source="block.toml"), macro)


def _last_gauss(path):
    """Strain, pore pressure and weights of the Gauss points at the last frame."""
    with h5py.File(path, "r") as f:
        last = f["steps"][sorted(f["steps"])[-1]]
        return (last["gauss/strain"][()], last["gauss/pore_pressure"][()],
                f["gauss/weights"][()])


def sealed_dem_sample(**solver):
    """A sealed quad8 element of 30-disk RVEs at 100 kPa, shortened by 1e-4 in two
    steps (``solver``: more [solver] keys)."""
    return validate_problem({
        "mesh": {"dim": 2, "element": "quad8", "size": [0.02, 0.04], "cells": [1, 1]},
        "dirichlet": [{"boundary": "bottom", "component": "y"},
                      {"boundary": "left", "component": "x"},
                      {"boundary": "top", "component": "y", "value": -4e-6}],
        "pressure": [{"boundary": "right", "value": 1e5}],
        "load": {"steps": 2},
        "fluid": {"permeability": 1e-15},
        "time": {"end": 1.0},
        "micro": {"model": "dem", "count": 30, "seed": 2, "p0": 1e5},
        "solver": {"tol_residual": 1e-2, "tol_displacement": 1e-2, **solver},
    })


def test_dem_rves_answer_undrained_at_constant_volume(tmp_path):
    """No drainage anywhere, water far stiffer than the packing: a shortened sample
    keeps its volume but for the water's own compression, and the squeezed water's
    pressure rises."""
    out = run_problem(sealed_dem_sample(), tmp_path, progress=False)
    eps, pg, w = _last_gauss(tmp_path / "fields.h5")
    axial = np.abs(eps[:, 1, 1]).mean()
    assert axial == pytest.approx(1e-4, rel=0.05)
    # no water leaves: the element's volume changes only by the water's compression,
    # tr eps = -p / M on average (M = K_f / n); the linear pressures hold the
    # element's volume, not each point's
    storage = 0.4 / 2.2e9
    volume = w @ np.trace(eps, axis1=1, axis2=2)
    assert volume == pytest.approx(-storage * (w @ pg), rel=1e-3)
    assert abs(volume) < 0.02 * axial * w.sum()
    assert np.all(pg > 0.0)  # shortened at constant volume: the water is squeezed
    assert out["cuts"] == 0


# ------------------------------------------------------------ limits: drained, undrained
ELEMENT = runpy.run_path(str(ROOT / "benchmarks" / "undrained_element.py"), run_name="bench")


@pytest.fixture(scope="module")
def packing(tmp_path_factory):
    """A 100-disk packing at 100 kPa, and its undrained test in ``hmm rve``
    (benchmarks/undrained_element.py). (An element of 40-disk RVEs does not stay
    uniform: their noise is larger than the stiffness of the element's non-uniform
    modes, and at a nominal 0.4 % its Gauss points' axial strains part from 0.2 % to
    0.6 %.)"""
    return ELEMENT["rve_test"](tmp_path_factory.mktemp("packing"))


def test_an_impermeable_element_carries_the_pore_pressure_of_the_rve_test(packing,
                                                                         tmp_path):
    """Low permeability, no drainage: an element of RVEs follows the constant-volume
    `hmm rve` test on the same packing, its deviator and the excess pore pressure
    its water carries within 5 % of the test's peak deviator, at every step, and it
    stays uniform."""
    path, lab = packing
    q, p, eyy = ELEMENT["element"](tmp_path, path, "undrained", **ELEMENT["UNDRAINED"])
    peak = lab.curves["q"].max()
    assert np.abs(q - lab.curves["q"]).max() < 0.05 * peak
    assert np.abs(p - lab.curves["excess_pore_pressure"]).max() < 0.05 * peak
    assert p[1:].min() > 0.5 * lab.curves["excess_pore_pressure"][1:].max()
    nominal = 0.001 * np.arange(eyy.shape[0])  # step 0 first
    assert np.abs(eyy - nominal[:, None]).max() < 0.05 * nominal[-1]


def test_a_permeable_element_loaded_slowly_is_drained(packing, tmp_path):
    """High permeability, drained sides, a slow load: the dry run's deviator within
    5 % of its peak, and no pore pressure to speak of."""
    path, _ = packing
    dry, _, _ = ELEMENT["element"](tmp_path, path, "dry")
    q, p, _ = ELEMENT["element"](tmp_path, path, "drained", **ELEMENT["DRAINED"])
    assert np.abs(q - dry).max() < 0.05 * dry.max()
    assert np.abs(p).max() < 1e-3 * dry.max()


@pytest.mark.parametrize("edit,message", [
    (("permeability = 8.333e-11", "permeability = 0.0"), "permeability must be > 0"),
    (('element = "quad8"', 'element = "quad1"'), "needs a quadratic element"),
    (('boundary = "top"\npressure = 0.0', 'boundary = "roof"\npressure = 0.0'),
     'boundary "roof" is not a boundary'),
    (("end = 1.0", "end = 0.0"), "end must be > 0"),
])
def test_hmm_run_refuses_bad_saturated_files_in_one_line(tmp_path, edit, message):
    from test_run import _hmm

    text = (ROOT / "examples" / "consolidation.toml").read_text()
    assert edit[0] in text
    (tmp_path / "c.toml").write_text(text.replace(edit[0], edit[1]))
    r = _hmm("run", "c.toml", "-o", "out", cwd=tmp_path)
    assert r.returncode == 2 and message in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / "out").exists()


def test_footing_consolidation_example_at_small_size(tmp_path):
    """examples/footing_consolidation.toml at small size (4 x 4 cells, 20-disk RVEs,
    4 time steps): the water under the footing first carries most of its load, then
    drains; the footing settles at once and keeps settling while it drains."""
    from hmm.problem import load_problem

    text = (ROOT / "examples" / "footing_consolidation.toml").read_text()
    for a, b in (("cells = [10, 10]", "cells = [4, 4]"), ("count = 100", "count = 20"),
                 ("steps = 20 ", "steps = 4 ")):
        assert a in text
        text = text.replace(a, b)
    (tmp_path / "f.toml").write_text(text)
    problem = load_problem(tmp_path / "f.toml")
    run_problem(problem, tmp_path / "out", progress=False)
    with h5py.File(tmp_path / "out" / "fields.h5", "r") as f:
        settle = -f["curve/displacement/footing"][:, 1]
        pmax = f["curve/pore_pressure/max"][()]
        time = f["curve/time"][()]
    assert time[-1] == pytest.approx(1000.0) and settle[0] == 0.0
    assert np.all(np.diff(settle) > 0.0)  # settles at once, then keeps settling
    assert settle[-1] > 1.5 * settle[1]
    assert 0.5e5 < pmax[1] <= 1e5  # the water carries most of the 100 kPa at first
    assert pmax[-1] < 0.05e5  # and has drained at the end


def test_undrained_biaxial_example_at_small_size(tmp_path):
    """examples/biaxial_undrained.toml at small size (1 x 2 cells, 20-disk RVEs, 3
    time steps to 0.6 %): the sealed sample keeps its volume but for the water's
    compression, ``tr eps = -n (p - p_0) / K_f`` on average to 1e-3, and its first
    steps contract the packing: the pore pressure rises above its 100 kPa."""
    from hmm.problem import load_problem

    text = (ROOT / "examples" / "biaxial_undrained.toml").read_text()
    for a, b in (("cells = [2, 4]", "cells = [1, 2]"), ("count = 100", "count = 20"),
                 ("steps = 25 ", "steps = 3 "), ("end = 5.0 ", "end = 0.6 "),
                 ("ramp = 5.0 ", "ramp = 0.6 "), ("value = -0.005 ", "value = -0.0006 ")):
        assert a in text
        text = text.replace(a, b)
    (tmp_path / "u.toml").write_text(text)
    problem = load_problem(tmp_path / "u.toml")
    out = run_problem(problem, tmp_path / "out", progress=False)
    fl = problem["fluid"]
    with h5py.File(tmp_path / "out" / "fields.h5", "r") as f:
        w = f["gauss/weights"][()]
        frames = [f["steps"][k] for k in sorted(f["steps"])][1:]
        for g in frames:
            volume = w @ np.trace(g["gauss/strain"][()], axis1=1, axis2=2)
            excess = w @ (g["gauss/pore_pressure"][()] - fl["initial_pressure"])
            assert volume == pytest.approx(-fl["porosity"] / fl["bulk_modulus"] * excess,
                                           rel=1e-3)
        assert w @ frames[0]["gauss/pore_pressure"][()] > 1.05e5 * w.sum()
    assert out["steps"] == 3


def test_3d_dem_rves_answer_undrained_on_quadratic_hexahedra(tmp_path):
    """hex20 displacements and hex1 pressures over 40-sphere RVEs (kn scaled for
    spheres as in the triaxial RVE test): no drainage, the element shortened by
    0.02 %; its volume changes only by the water's compression, tr eps = -p / M on
    average, and the water is squeezed."""
    problem = validate_problem({
        "mesh": {"dim": 3, "element": "hex20", "size": [0.02, 0.02, 0.02],
                 "cells": [1, 1, 1]},
        "dirichlet": [{"boundary": "front", "component": "z"},
                      {"boundary": "left", "component": "x"},
                      {"boundary": "bottom", "component": "y"},
                      {"boundary": "back", "component": "z", "value": -4e-6}],
        "pressure": [{"boundary": "right", "value": 1e5},
                     {"boundary": "top", "value": 1e5}],
        "load": {"steps": 2},
        "fluid": {"permeability": 1e-15},
        "time": {"end": 1.0},
        "micro": {"model": "dem", "count": 40, "seed": 5, "p0": 1e5, "kn": 1e5,
                  "kt": 5e4},
        "solver": {"tol_residual": 1e-2, "tol_displacement": 1e-2},
    })
    out = run_problem(problem, tmp_path, progress=False)
    eps, pg, w = _last_gauss(tmp_path / "fields.h5")
    assert np.abs(eps[:, 2, 2]).mean() == pytest.approx(2e-4, rel=0.05)
    volume = w @ np.trace(eps, axis1=1, axis2=2)
    assert volume == pytest.approx(-(0.4 / 2.2e9) * (w @ pg), rel=1e-3)
    assert np.all(pg > 0.0) and out["cuts"] == 0


def test_the_schema_offers_what_the_solver_takes():
    from hmm.porous import COUPLINGS, PERMEABILITY_LAWS
    from hmm.problem import SCHEMA

    assert SCHEMA["solver"].keys["coupling"].choices == COUPLINGS
    assert SCHEMA["fluid"].keys["permeability_law"].choices == PERMEABILITY_LAWS
