"""Hertz-Mindlin with simplified JKR cohesion (``dem/contact/laws/hertz_sjkr.py``), a law
added as one file: analytic rest overlaps, an undamped collision that keeps its energy,
and the scene file's keys, for a wall of its own cohesion too.

Without gravity, a contact at rest has zero force: ``4/3 E* sqrt(R* delta) delta`` equals
the attraction ``2 pi R* k delta``, so ``delta* = 9 pi^2 k^2 R* / (4 E*^2)``.
"""

import math

import numpy as np
import pytest

import dem
from dem.contact.laws import LAWS, HertzSJKR, law_from_spec
from dem.io.scene import build_simulation, load_scene

R, YOUNG, NU, RHO = 1e-3, 1e7, 0.25, 2500.0
COHESION = 6.7e4  # [J/m^3]: delta* about 1e-3 R on a rigid plane


def law(restitution=0.3, cohesion=COHESION, wall=False):
    young = (YOUNG, math.inf) if wall else YOUNG
    return HertzSJKR(young=young, poisson=NU, restitution=restitution, mu=0.3,
                     cohesion=cohesion)


def stack(gaps, restitution, cohesion=COHESION):
    """A grain on a rigid plane and a second grain above it, the two contacts ``gaps``
    [m] apart (negative: overlapping), no gravity."""
    z = R + gaps[0]
    bodies = dem.Bodies.spheres([[0.0, 0.0, z], [0.0, 0.0, z + 2.0 * R + gaps[1]]],
                                radius=R, density=RHO)
    bodies.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    model = dem.ContactModel(law(restitution, cohesion),
                             wall_law=law(restitution, cohesion, wall=True))
    return dem.Simulation(bodies, model)


def overlaps(sim):
    z = sim.bodies.pos[:2, 2]
    return R - z[0], 2.0 * R - (z[1] - z[0])


def test_grains_settle_at_the_rest_overlap_on_a_plane_and_on_each_other():
    plane, pair = law(wall=True), law()
    # a rigid plane: R* = R, E* = E/(1-nu^2); two grains: R* = R/2, E* half that
    assert plane.e_star == pytest.approx(2.0 * pair.e_star, rel=1e-14)
    expected = (plane.rest_overlap(R), pair.rest_overlap(R / 2))
    assert expected[1] == pytest.approx(2.0 * expected[0], rel=1e-12)
    # started at half the rest overlaps: each contact swings in its own well
    sim = stack(gaps=(-0.5 * expected[0], -0.5 * expected[1]), restitution=0.3)
    sim.run(30_000)
    np.testing.assert_allclose(overlaps(sim), expected, rtol=1e-6)
    assert np.abs(sim.bodies.vel[:2]).max() < 1e-9


def test_without_cohesion_the_touching_grains_part():
    sim = stack(gaps=(-1e-9, -1e-9), restitution=0.3, cohesion=0.0)
    sim.run(2000)
    assert max(overlaps(sim)) < 0.0


def test_an_undamped_collision_rebounds_with_its_approach_speed():
    """The attraction is conservative: what the well takes on the way in, it gives back
    on the way out; the contact lasts longer than Hertz's alone."""
    speed, gap = 5e-3, 1e-8  # the kinetic energy about 3x the well's depth
    bodies = dem.Bodies.spheres([[0.0, 0.0, R + gap]], radius=R, density=RHO)
    bodies.vel[0, 2] = -speed
    bodies.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    durations = []
    for cohesion in (COHESION, 0.0):
        rigid = law(restitution=1.0, cohesion=cohesion, wall=True)
        sim = dem.Simulation(bodies.copy(), rigid, dt=2.5e-7)  # 2,000 steps a contact
        depth = dem.Record(lambda s: R - s.bodies.pos[0, 2])
        sim.observers.append(depth)
        sim.run(int(gap / speed / sim.dt) + 6000)
        assert sim.bodies.vel[0, 2] == pytest.approx(speed, rel=1e-5)
        durations.append(np.count_nonzero(np.array(depth.values) > 0.0))
    assert durations[0] > durations[1]


def test_the_force_is_minus_the_energy_gradient_and_the_tangent_its_derivative():
    row = law().row()
    table = row[None, None, :]
    r_eff, ov, h = 5e-4, 2e-6, 1e-11

    def fn(d):
        return LAWS["hertz_sjkr"].force(d, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, r_eff, 1e-6, table,
                                        0, 0, np.zeros((1, 3)), 0, 0.0)[2]

    def energy(d):
        return LAWS["hertz_sjkr"].energy(d, r_eff, row, np.zeros((1, 3)), 0)

    assert fn(ov) == pytest.approx((energy(ov + h) - energy(ov - h)) / (2 * h), rel=1e-5)
    kn, _ = LAWS["hertz_sjkr"].stiffness(ov, r_eff, row)
    assert kn == pytest.approx((fn(ov + h) - fn(ov - h)) / (2 * h), rel=1e-5)
    # attractive below the rest overlap, repulsive above it
    rest = law().rest_overlap(r_eff)
    assert fn(0.5 * rest) < 0.0 < fn(2.0 * rest)


def test_the_law_round_trips_as_data_and_refuses_negative_cohesion():
    original = law()
    copy = law_from_spec(original.spec())
    assert type(copy) is HertzSJKR and np.array_equal(copy.row(), original.row())
    assert copy.with_friction(0.1).row()[3] == 0.1
    with pytest.raises(ValueError, match="cohesion must be finite and >= 0"):
        law(cohesion=-1.0)


def test_a_scene_file_gives_a_wall_its_own_cohesion(tmp_path):
    (tmp_path / "grains.txt").write_text(f"0 0 {R!r} {R!r}\n")
    path = tmp_path / "sticky.toml"
    path.write_text(f"""\
[simulation]
steps = 1

[particles]
generator = "file"
file = "grains.txt"
density = {RHO!r}

[[walls]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
rigid = true
cohesion = 0.0

[[walls]]
point = [0.0, 0.0, 0.1]
normal = [0.0, 0.0, -1.0]

[contact]
law = "hertz_sjkr"
young = {YOUNG!r}
poisson = {NU!r}
mu = 0.3
cohesion = {COHESION!r}
""")
    sim = build_simulation(load_scene(path))[0]
    table, mat = sim.parameter_table("pw"), sim.bodies.mat_id
    own, shared = table[mat[0], mat[1]], table[mat[0], mat[2]]
    assert own[5] == 0.0 and shared[5] == COHESION
    assert own[0] == pytest.approx(law(wall=True).e_star, rel=1e-14)
    assert shared[0] == pytest.approx(law().e_star, rel=1e-14)
    path.write_text(path.read_text().replace(f"cohesion = {COHESION!r}", "cohesion = -1.0"))
    with pytest.raises(Exception, match="cohesion"):
        load_scene(path)
