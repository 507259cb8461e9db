"""The wall-bounded box RVE: wall stress, control, state, files, and the periodic RVE."""

import numpy as np
import pytest

import dem
from dem import rve, rve_box
from dem.io.checkpoint import save_checkpoint

LAW = dem.LinearSpring(kn=1e8, kt=5e7, mu=0.5)
P0 = 1e5
PACKING = {"dim": 2, "n": 40, "radius": (0.8e-3, 1.2e-3), "law": LAW, "p0": P0,
           "friction": 0.0, "seed": 5, "damping": 0.5}


@pytest.fixture(scope="module")
def box():
    """A small 2D box packing (frictionless consolidation, mu = 0.5 after)."""
    return rve_box.generate_box(**PACKING)


def _chains(n_x, n_y, r, gap):
    """``n_y`` horizontal chains of ``n_x`` touching disks, touching the x-walls;
    ``gap`` [m] between the chains (and between the outer chains and the y-walls)."""
    x = (2 * np.arange(n_x) + 1) * r
    y = gap + r + np.arange(n_y) * (2 * r + gap)
    pos = np.stack(np.meshgrid(x, y, indexing="ij"), -1).reshape(-1, 2)
    hi = np.array([2 * r * n_x, n_y * (2 * r + gap) + gap])
    return dem.Bodies.spheres(pos, radius=r, density=2650.0), np.zeros(2), hi


def test_chains_between_walls_give_the_series_spring_stress():
    """Frictionless chains of n disks between the x-walls: shortening the box by
    |eps| L_x loads the n + 1 springs of each chain in series, so
    sigma_xx = -n_y kn |eps| L_x / ((n + 1) L_y) exactly, sigma_yy = 0, and the
    perturbation tangent is that slope."""
    law = dem.LinearSpring(kn=1e8)
    n_x, n_y, r = 3, 2, 1e-3
    bodies, lo, hi = _chains(n_x, n_y, r, gap=2e-5)
    box = rve_box.BoxRVE(bodies, law, lo, hi, damping=0.5, tol=1e-9)
    eps = -1e-4
    s = box.apply_strain(np.diag([eps, 0.0]))
    assert box.deformation[0, 0] == pytest.approx(1.0 + eps, rel=1e-12)
    lx, ly = hi - lo
    slope = n_y * law.kn * lx / ((n_x + 1) * ly)
    assert s[0, 0] == pytest.approx(slope * eps, rel=1e-6)
    assert s[1, 1] == 0.0 and s[0, 1] == pytest.approx(0.0, abs=1e-9 * slope)
    c = box.tangent("perturbation", probe=-1e-5)
    assert c[0, 0, 0, 0] == pytest.approx(slope, rel=1e-3)
    assert c[1, 1, 1, 1] == 0.0  # no chain along y


def test_wall_stress_is_the_wall_forces_over_their_areas(box):
    s = box.stress()
    forces = box.sim.wall_forces()
    length = box.lengths()
    vol = np.prod(length)
    for a in range(2):
        area = vol / length[a]
        lo, hi = (forces[int(w)][a] for w in box.walls[a])
        # the lower wall is pushed towards -x_a, the upper one towards +x_a
        assert lo < 0.0 < hi
        assert s[a, a] == pytest.approx(0.5 * (lo - hi) / area, rel=1e-12)
    # in equilibrium the boundary average is the Love-Weber volume average
    out = box.response()
    assert out["unbalanced"] < box.tol
    assert np.abs(out["stress_love"] - s).max() < 2e-3 * P0


def test_consolidation_reaches_the_target_pressure(box):
    out = box.response()
    assert np.diag(out["stress"]) == pytest.approx([-P0, -P0], rel=2e-3)
    assert out["unbalanced"] < box.tol
    assert out["n_wall_contacts"] > 0
    assert 3.0 < out["coordination"] < 5.0  # frictionless consolidation: dense
    assert 0.1 < out["void_ratio"] < 0.4
    assert box.law.mu == 0.5 and box.wall_law.mu == 0.0
    assert np.all(np.diag(box.deformation) < 0.8)  # the walls closed in on the cloud


def test_mixed_control_holds_the_lateral_stress(box):
    """Drained biaxial path: three axial (y) strain increments by the walls, the
    lateral (x) stress held by the servo. After each relaxed increment it is at its
    target; while the walls move it lags (a proportional servo with a time constant of
    4 checks, against a load lasting 2 checks) but by a fraction of the target only."""
    snap = box.snapshot()
    l0 = box.lengths()
    seen = []
    axial = [box.stress()[1, 1]]
    for _ in range(3):
        s = box.load(np.diag([0.0, -1e-3]), stress=[-P0, 0.0], mask=[True, False],
                     progress=lambda _: seen.append(box.stress()[0, 0]))
        assert s[0, 0] == pytest.approx(-P0, rel=2e-3)
        axial.append(s[1, 1])
    assert np.all(np.diff(axial) < 0.0) and axial[-1] < -1.2 * P0  # loaded axially
    assert np.abs(np.array(seen) + P0).max() < 0.2 * P0
    stretch = box.lengths() / l0
    assert stretch[1] == pytest.approx((1.0 - 1e-3) ** 3, rel=1e-9)
    assert stretch[0] > 1.0  # free to widen under constant lateral stress
    box.restore(snap)


def test_shear_is_refused_with_a_clear_message(box):
    with pytest.raises(ValueError, match="box RVE has no shear mode"):
        box.apply_strain(np.array([[-1e-4, 1e-5], [1e-5, 0.0]]))
    with pytest.raises(ValueError, match="no shear mode"):
        box.load(stress=np.full((2, 2), -P0), mask=np.ones((2, 2), bool))
    with pytest.raises(ValueError, match="finite"):
        box.apply_strain(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="tangent method"):
        box.tangent("secant")


def test_snapshot_restore_repeats_a_load_bit_for_bit(box):
    snap = box.snapshot()
    deps = np.diag([-5e-4, 1e-4])
    s1 = box.apply_strain(deps)
    pos1 = box.bodies.pos.copy()
    box.restore(snap)
    s2 = box.apply_strain(deps)
    assert np.array_equal(s1, s2) and np.array_equal(pos1, box.bodies.pos)
    box.restore(snap)
    assert np.array_equal(box.bodies.pos, snap["b.pos"])


def test_saved_box_loads_and_continues_bit_for_bit(box, tmp_path):
    snap = box.snapshot()
    box.save(tmp_path / "b.h5", note="test")
    again = rve_box.BoxRVE.load_file(tmp_path / "b.h5")
    assert again.law.spec() == box.law.spec()
    assert again.wall_law.spec() == box.wall_law.spec()
    assert np.array_equal(again.deformation, box.deformation)
    deps = np.diag([0.0, -3e-4])
    assert np.array_equal(again.apply_strain(deps), box.apply_strain(deps))
    box.restore(snap)
    plain = save_checkpoint(box.sim, tmp_path / "p.h5")  # no box RVE settings
    with pytest.raises(ValueError, match="no /box_rve group"):
        rve_box.BoxRVE.load_file(plain)


def test_relaxation_that_cannot_finish_says_so(box):
    snap = box.snapshot()
    box.max_relax_steps = 10
    try:
        with pytest.raises(rve.RelaxationError, match="did not relax within 10 steps"):
            box.apply_strain(np.diag([-1e-2, 0.0]))
    finally:
        box.max_relax_steps = 200_000
        box.restore(snap)
    assert np.all(box.bodies.vel[box.walls.ravel()] == 0.0)  # the walls were stopped


def test_a_consolidation_that_fails_restores_the_law_s_friction():
    """A frictionless first stage capped at 100 steps raises, and the law's friction
    (0.5) is back on the packing, as after a stage that settles."""
    lo, hi, pos = rve_box.box_cloud(2, np.full(20, 1e-3), 0.4, seed=1)
    bodies = dem.Bodies.spheres(pos, radius=1e-3, density=2650.0)
    packing = rve_box.BoxRVE(bodies, LAW, lo, hi, damping=0.5, max_relax_steps=100)
    with pytest.raises(rve.RelaxationError, match="did not relax within 100 steps"):
        packing.consolidate(P0, friction=0.0)
    assert packing.law.mu == 0.5


@pytest.mark.slow  # from a cold numba cache: compiles the periodic cell's loop
def test_box_and_periodic_packings_respond_alike(box):
    """The same grains at the same pressure, one periodic and one between walls, under
    the same drained biaxial step: both stiffen axially by a comparable amount
    (walls make the box softer: contacts at the walls and a looser layer next to
    them) and both widen laterally."""
    cell = rve.generate(**PACKING)
    deps = np.diag([0.0, -2e-3])
    out = {}
    for name, r in (("box", box), ("cell", cell)):
        snap = r.snapshot()
        s0 = r.stress()[1, 1]
        c = r.tangent()[1, 1, 1, 1]
        f0 = r.deformation.copy()
        s = r.load(deps, stress=[-P0, 0.0], mask=[True, False])
        out[name] = (s[1, 1] - s0, c, r.deformation[0, 0] / f0[0, 0])
        r.restore(snap)
    (ds_box, c_box, wx_box), (ds_cell, c_cell, wx_cell) = out["box"], out["cell"]
    assert ds_box < 0.0 and ds_cell < 0.0  # compression stiffens both
    assert 1.0 / 3.0 < ds_box / ds_cell < 3.0
    assert 1.0 / 3.0 < c_box / c_cell < 3.0  # contact tangents of the same order
    assert wx_box > 1.0 and wx_cell > 1.0


def test_a_box_packing_of_too_soft_contacts_is_warned_of(caplog):
    """generate_box judges the law against p0 before consolidating, as rve.generate
    does (kn / p0 = 1e-4 here; the 10-step cap then stops it)."""
    law = dem.LinearSpring(kn=10.0, kt=5.0, mu=0.5)
    with caplog.at_level("WARNING", logger="dem.rve"):
        with pytest.raises(rve.RelaxationError):
            rve_box.generate_box(2, 20, 1e-3, law, P0, seed=1, max_relax_steps=10)
    assert "overlaps will be large (soft contacts)" in caplog.text
