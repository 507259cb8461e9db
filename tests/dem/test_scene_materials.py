"""Scene files with particle groups, [[contact]] pairs and walls of their own material
(:mod:`dem.io.materials`): which law each pair of bodies gets."""

import math

import numpy as np
import pytest
from test_cli import HERTZ, base_scene, write_scene

from dem import HertzMindlin, LinearSpring
from dem.io.scene import build_simulation, load_scene


def build(tmp_path, scene):
    return build_simulation(load_scene(write_scene(tmp_path, scene)))[0]


def pw_row(sim, wall):
    """The particle-wall parameter row between particle 0 and wall ``wall`` (its
    index among the walls)."""
    b = sim.bodies
    w = np.flatnonzero(b.kind == b.kind[-1])[wall]
    return sim.parameter_table("pw")[b.mat_id[0], b.mat_id[w]]


def test_one_contact_table_keeps_one_material_row(tmp_path):
    """A scene of one [contact] table and no wall material builds as before: every
    body on row 0, one law for every pair."""
    scene = base_scene()
    scene["particles"]["group"] = "sand"
    sim = build(tmp_path, scene)
    assert np.all(sim.bodies.mat_id == 0)
    assert list(sim.model.laws["pp"]) == [None] and list(sim.model.laws["pw"]) == [None]


def test_a_wall_of_its_own_linear_material(tmp_path):
    """The wall's kn, kt and mu replace the [contact] values (kt = 0 too); the
    restitution stays."""
    scene = base_scene()
    scene["walls"].append({"point": [0.0, 0.0, 0.1], "normal": [0.0, 0.0, -1.0],
                           "kn": 3.0e4, "kt": 0.0, "mu": 0.2})
    sim = build(tmp_path, scene)
    c = scene["contact"]
    floor = LinearSpring(kn=c["kn"], kt=c["kt"], mu=c["mu"], restitution=c["restitution"])
    lid = LinearSpring(kn=3.0e4, kt=0.0, mu=0.2, restitution=c["restitution"])
    np.testing.assert_array_equal(pw_row(sim, 0), floor.row())
    np.testing.assert_array_equal(pw_row(sim, 1), lid.row())
    pp = sim.parameter_table("pp")
    np.testing.assert_array_equal(pp[0, 0], floor.row())
    # the lid is the stiffest contact: it sets the time step
    assert sim.model.max_stiffness(sim.bodies) == 3.0e4


def test_a_rigid_hertz_wall_and_a_soft_one(tmp_path):
    scene = base_scene()
    scene["contact"] = dict(HERTZ)
    scene["walls"][0]["rigid"] = True
    scene["walls"].append({"point": [0.0, 0.0, 0.1], "normal": [0.0, 0.0, -1.0],
                           "young": 2.0e6, "poisson": 0.45, "restitution": 0.7})
    sim = build(tmp_path, scene)
    h = HERTZ
    rigid = HertzMindlin(young=(h["young"], math.inf), poisson=h["poisson"],
                         restitution=1.0, mu=h["mu"])
    soft = HertzMindlin(young=(h["young"], 2.0e6), poisson=(h["poisson"], 0.45),
                        restitution=0.7, mu=h["mu"])
    np.testing.assert_array_equal(pw_row(sim, 0), rigid.row())
    np.testing.assert_array_equal(pw_row(sim, 1), soft.row())
    assert pw_row(sim, 0)[0] == pytest.approx(h["young"] / (1 - h["poisson"] ** 2))


def _sand_and_gravel(wall_tables):
    scene = base_scene()
    linear = scene["contact"]
    scene["particles"]["group"] = "sand"
    scene["insert"] = {"count": 2, "rate": 1e6, "lo": [0.0, 0.0, 0.05],
                       "hi": [0.03, 0.03, 0.08], "radius": 0.005, "every": 1,
                       "group": "gravel"}
    scene["contact"] = [
        {**linear, "pair": ["sand", "sand"]},
        {**linear, "pair": ["gravel", "sand"], "kn": 2.0e4},
        {**linear, "pair": ["gravel", "gravel"], "kn": 4.0e4},
        *wall_tables(linear),
    ]
    return scene


def test_groups_and_contact_pairs(tmp_path):
    """Sand on a floor, gravel inserted: each pair of groups its own law."""
    scene = _sand_and_gravel(lambda linear: [
        {**linear, "pair": ["sand", "walls"], "kn": 3.0e4},
        {**linear, "pair": ["walls", "gravel"], "kn": 5.0e4}])
    sim = build(tmp_path, scene)
    b = sim.bodies
    sand, wall = b.mat_id[0], b.mat_id[-1]
    gravel = sim.controllers[0].mat_id
    assert len({sand, gravel, wall}) == 3
    pp, pw = sim.model.table("pp", 3)[..., 0], sim.model.table("pw", 3)[..., 0]
    assert (pp[sand, sand], pp[sand, gravel], pp[gravel, sand], pp[gravel, gravel]) == (
        1.0e4, 2.0e4, 2.0e4, 4.0e4)
    assert (pw[sand, wall], pw[gravel, wall]) == (3.0e4, 5.0e4)
    sim.run(1, progress=False)  # the gravel comes in on its own row
    new = sim.controllers[0].ids
    assert len(new) >= 1 and np.all(b.mat_id[new] == gravel)
    assert sim.parameter_table("pp")[gravel, sand, 0] == 2.0e4


def test_the_walls_law_may_be_of_another_kind(tmp_path):
    """One kind per bucket: Hertz-Mindlin on the walls under linear particle pairs."""
    scene = _sand_and_gravel(lambda linear: [
        {**HERTZ, "pair": ["sand", "walls"]},
        {**HERTZ, "pair": ["walls", "gravel"], "young": 2.0e7}])
    sim = build(tmp_path, scene)
    assert sim.model.kind("pp") is LinearSpring and sim.model.kind("pw") is HertzMindlin
    sand, wall = sim.bodies.mat_id[0], sim.bodies.mat_id[-1]
    pw = sim.model.table("pw", 3)
    assert pw[sim.controllers[0].mat_id, wall, 0] == pytest.approx(2.0 * pw[sand, wall, 0])


def test_rolling_resistance_from_the_contact_table_and_a_wall(tmp_path):
    """[contact] mu_roll and eta_roll give the laws rolling resistance (k_roll defaults
    to 2.25 mu_roll^2); a wall's own mu_roll replaces it for that wall; limit_damping
    sets the law's clip."""
    scene = base_scene()
    scene["contact"].update({"mu_roll": 0.2, "eta_roll": 0.3, "limit_damping": True})
    scene["walls"][0]["mu_roll"] = 0.05
    sim = build(tmp_path, scene)
    assert sim.model.rolling and sim.model.n_hist == 10
    pp = sim.parameter_table("pp")[0, 0]
    np.testing.assert_allclose(pp[-5:], [0.2, 2.25 * 0.2**2, 0.3, 0.0, 0.0])
    np.testing.assert_allclose(pw_row(sim, 0)[-5:], [0.05, 2.25 * 0.05**2, 0.3, 0.0, 0.0])
    assert pp[6] == 1.0 and sim.model.kind("pp")(kn=1.0).row()[6] == 0.0  # limit_damping
    # without the keys: no rolling, and the short history rows
    plain = build(tmp_path, base_scene())
    assert not plain.model.rolling and plain.model.n_hist == 3
