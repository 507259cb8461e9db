"""The 3D triaxial examples (examples/triaxial_3d.toml and the gmsh cylinder of
examples/triaxial_cylinder.toml): the gmsh route against a homogeneous elastic answer,
and the DEM run at small size (1 x 2 x 1 hex20, 60-sphere RVEs, 2 steps) with its
fabric fields and a restart bit for bit. The same run on two ranks is in
tests/mpi/test_farm_mpi.py."""

from pathlib import Path

import h5py
import numpy as np
import pytest

from problems import small_triaxial

from hmm.problem import load_problem
from hmm.problem_build import build_macro
from hmm.run import run_problem

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_the_example_files_build_what_they_say():
    """The cuboid: 16 hex20 with 8 points each, 128 RVEs of 1,000 spheres, rough
    platens, four confined sides, a weak spot holding Gauss points near the left side;
    the cylinder: gmsh's physical groups are its boundaries."""
    from hmm.problem_build import spot_of

    prob = load_problem(EXAMPLES / "triaxial_3d.toml")
    macro = build_macro(prob)
    assert (macro.n_elems, macro.n_qp, prob["micro"]["count"]) == (16, 8, 1000)
    held = {(d["boundary"], d["component"]) for d in prob["dirichlet"]}
    assert held == {(b, c) for b in ("bottom", "top") for c in "xyz"}
    assert sorted(p["boundary"] for p in prob["pressure"]) == sorted(
        ["left", "right", "front", "back"])
    spot = spot_of(prob, macro.gauss_points())
    inside = macro.gauss_points()[spot == 0]
    assert 0 < len(inside) < 16 and np.all(inside[:, 0] < 0.025)
    cyl = build_macro(load_problem(EXAMPLES / "triaxial_cylinder.toml"))
    assert {"bottom", "top", "side"} <= set(cyl.mesh.boundaries)
    assert cyl.n_gp == 48 * 8


def test_a_gmsh_cylinder_under_cell_pressure_has_the_homogeneous_elastic_answer(tmp_path):
    """The gmsh mesh, its named boundaries and the pressure on its curved (faceted)
    side, with a linear-elastic micro model, smooth platens and small kinematics:
    every Gauss point carries sigma_xx = sigma_zz = -p, no shear, and
    sigma_yy = E eps_a - 2 nu p, to round-off."""
    prob = load_problem(EXAMPLES / "triaxial_cylinder.toml")
    p, e_mod, nu, push, height = 1e5, 2e7, 0.3, -1e-4, 0.1
    base, top = ({**d} for b in ("bottom", "top") for d in prob["dirichlet"]
                 if (d["boundary"], d["component"]) == (b, "y"))
    pins = [{**base, "boundary": None, "point": at, "component": c}
            for at, c in (([0.0, 0.0, 0.0], "x"), ([0.0, 0.0, 0.0], "z"),
                          ([0.0, 0.0, 0.025], "x"))]  # no rigid slip or turn
    prob["dirichlet"] = [base, *pins, {**top, "value": push}]  # smooth platens
    prob["micro"] = {**prob["micro"], "model": "linear_elastic", "young": e_mod,
                     "poisson": nu, "stress0": 0.0}
    prob["solver"].update(kinematics="small", tol_residual=1e-10, tol_displacement=1e-10)
    prob["load"]["steps"] = 1
    prob["pressure"][0]["value"] = p
    run_problem(prob, tmp_path, progress=False)
    with h5py.File(tmp_path / "fields.h5") as f:
        sig = f["steps/00001/gauss/stress"][()]
    expected = np.diag([-p, e_mod * push / height - 2.0 * nu * p, -p])
    np.testing.assert_allclose(sig, np.broadcast_to(expected, sig.shape), rtol=0.0,
                               atol=1e-7 * p)


@pytest.fixture(scope="module")
def triaxial(tmp_path_factory):
    """The small triaxial, run whole and again in two jobs (stopped after step 1,
    restarted from its checkpoint)."""
    base = tmp_path_factory.mktemp("triaxial")
    prob = small_triaxial()
    prob["output"]["checkpoint_every"] = 1
    full = run_problem(prob, base / "full", progress=False)
    run_problem(prob, base / "cut", progress=False, stop_after=1)
    again = run_problem(prob, base / "cut", progress=False, restart=True)
    return base, full, again


def test_the_small_triaxial_compresses_and_its_contacts_turn_to_the_axis(triaxial):
    """Rough platens, 100 kPa on the sides: the axial stress grows past the cell
    pressure, the sides keep it, the platens balance; the contact fabric (trace 1 at
    every point) gains normals along the axis and its anisotropy grows."""
    base, full, _ = triaxial
    assert full["load_factor"] == pytest.approx(1.0) and full["cuts"] == 0
    with h5py.File(base / "full" / "fields.h5") as f:
        s0, s2 = f["steps/00000"], f["steps/00002"]
        sig = s2["gauss/stress"][()]
        fab0, fab2 = s0["gauss/fabric"][()], s2["gauss/fabric"][()]
        a0, a2 = s0["anisotropy"][()], s2["anisotropy"][()]
        top = f["curve/force/top"][()]
        bottom = f["curve/force/bottom"][()]
        assert {"fabric_xx", "fabric_yy", "fabric_zz", "anisotropy"} <= set(s2)
    area = 0.05 * 0.05
    assert -top[-1, 1] / area > 1.3e5  # above the 100 kPa of the sides
    assert np.all(np.diff(-top[:, 1]) > 0.0)
    np.testing.assert_allclose(top[-1], -bottom[-1], atol=1e-9 * abs(top[-1, 1]))
    assert np.mean(sig[:, 1, 1]) < 1.2 * np.mean(sig[:, 0, 0]) < 0.0
    np.testing.assert_allclose(np.trace(fab2, axis1=1, axis2=2), 1.0, atol=1e-12)
    gain = fab2 - fab0
    assert np.all(gain[:, 1, 1] > gain[:, 0, 0]) and np.all(gain[:, 1, 1] > gain[:, 2, 2])
    assert np.all(a2 > a0)


def test_the_small_triaxial_counts_its_work(triaxial):
    """The curve's work per load step adds up to the run's: every farm trial calls
    each of the 16 RVEs once, and each call runs DEM steps and takes time; a run
    without rolling resistance writes no couple stress."""
    base, full, _ = triaxial
    with h5py.File(base / "full" / "fields.h5") as f:
        work = {k: f["curve/work"][k][()] for k in ("rve_calls", "rve_seconds", "dem_steps")}
        assert not any(k.startswith("couple_stress") for k in f["steps/00002"])
        assert f["curve/work/rve_seconds"].attrs["unit"] == "s"
    # step 0: the trial of the starting state; then one trial a Newton iteration
    assert work["rve_calls"][0] == 16
    assert list(work["rve_calls"][1:]) == [16 * i for i in full["iterations"]]
    assert work["rve_calls"].sum() == full["work"]["rve_calls"] == 16 * full["trials"]
    assert work["dem_steps"].sum() == full["work"]["dem_steps"]
    assert np.all(work["dem_steps"][1:] > 0) and np.all(work["rve_seconds"] > 0.0)


def test_the_small_triaxial_restarts_bit_for_bit_and_writes_its_views(triaxial):
    base, full, again = triaxial
    assert np.array_equal(full["u"], again["u"])
    assert np.array_equal(full["sigma"], again["sigma"])
    with h5py.File(base / "full" / "fields.h5") as a, \
            h5py.File(base / "cut" / "fields.h5") as b:
        for name in ("gauss/fabric", "anisotropy", "void_ratio", "points"):
            assert np.array_equal(a["steps/00002/" + name][()], b["steps/00002/" + name][()])
    xdmf = (base / "full" / "fields.xdmf").read_text()
    assert 'Name="anisotropy"' in xdmf and 'Name="fabric_yy"' in xdmf
    assert (base / "full" / "deviatoric_strain.png").stat().st_size > 10_000


@pytest.mark.parametrize("element", ["hex27", "tet10"])
def test_the_other_quadratic_elements_run_dem_rves_and_restart(element, tmp_path):
    """One cube of hex27 (27 Gauss points) or of tet10 (4 a tetrahedron) under the
    example's loads, with 60-sphere RVEs: the platen's load grows past the cell
    pressure, and a run stopped after step 1 and restarted ends bit for bit where the
    whole run ends."""
    prob = small_triaxial()
    prob["mesh"].update(element=element, cells=[1, 1, 1], size=[0.05, 0.05, 0.05],
                        integration=None)
    prob["output"]["checkpoint_every"] = 1
    full = run_problem(prob, tmp_path / "full", progress=False)
    run_problem(prob, tmp_path / "cut", progress=False, stop_after=1)
    again = run_problem(prob, tmp_path / "cut", progress=False, restart=True)
    assert full["load_factor"] == pytest.approx(1.0)
    assert -full["reactions"]["top"][1] / 0.05 ** 2 > 1.3e5
    assert np.array_equal(full["u"], again["u"])
    assert np.array_equal(full["sigma"], again["sigma"])
