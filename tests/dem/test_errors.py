"""Bad input is refused at set-up with a message that says what is wrong; a run that
goes unphysical stops with :class:`dem.SimulationError` and hands its failure hooks the
last good state."""

import math
import re

import numpy as np
import pytest

import dem

R, RHO = 0.01, 2500.0
LAW = dem.LinearSpring(kn=1e5, kt=4e4, mu=0.3)


def pair(dim=3, gap=0.1 * R, speed=0.0, **kw):
    axis = np.eye(dim)[0]
    pos = [-(R + 0.5 * gap) * axis, (R + 0.5 * gap) * axis]
    return dem.Bodies.spheres(
        pos, radius=R, density=RHO, vel=[0.5 * speed * axis, -0.5 * speed * axis], **kw
    )


# --------------------------------------------------------------------------- time step
def test_dt_above_critical_step_is_refused_naming_both():
    dt_crit = dem.Simulation(pair(), LAW).dt_crit
    dt = 1.5 * dt_crit
    with pytest.raises(ValueError) as err:
        dem.Simulation(pair(), LAW, dt=dt)
    msg = str(err.value)
    assert f"{dt:.4g}" in msg
    assert f"{dt_crit:.4g}" in msg
    assert "allow_unstable_dt" in msg  # and says how to override


def test_allow_unstable_dt_overrides():
    dt_crit = dem.Simulation(pair(), LAW).dt_crit
    sim = dem.Simulation(pair(), LAW, dt=1.5 * dt_crit, allow_unstable_dt=True)
    assert sim.dt == 1.5 * dt_crit
    sim.run(3)  # it runs (the spheres are apart)
    assert sim.step == 3


def test_critical_step_is_the_verlet_limit_of_the_stiffest_contact():
    """``dt_crit = sqrt(2 m_min / k)``, with k the largest of kn and the tangential
    stiffness seen by translation and rotation together, ``kt (1 + m R^2 / I)``."""
    b = pair()
    m = b.mass[0]
    for law, k in (
        (dem.LinearSpring(kn=1e5), 1e5),
        (dem.LinearSpring(kn=1e5, kt=1e5), 3.5e5),
    ):
        assert dem.Simulation(b.copy(), law).dt_crit == pytest.approx(
            math.sqrt(2 * m / k)
        )
    # the lightest body decides
    mixed = dem.Bodies.spheres([[0, 0, 0], [1, 0, 0]], radius=[R, 0.5 * R], density=RHO)
    assert dem.Simulation(mixed, dem.LinearSpring(kn=1e5)).dt_crit == pytest.approx(
        math.sqrt(2 * mixed.mass[1] / 1e5)
    )


def test_default_dt_is_a_fraction_of_the_critical_step():
    sim = dem.Simulation(pair(), LAW)
    assert sim.dt == pytest.approx(dem.DT_FACTOR * sim.dt_crit)
    assert 0.0 < dem.DT_FACTOR < 1.0


@pytest.mark.parametrize("dt", [0.0, -1e-6, math.nan, math.inf])
def test_nonpositive_or_nonfinite_dt_is_refused(dt):
    with pytest.raises(ValueError, match="dt"):
        dem.Simulation(pair(), LAW, dt=dt, allow_unstable_dt=True)


# --------------------------------------------------------------------------- failures
def test_excessive_overlap_raises_and_hook_gets_last_good_state():
    speed = 200.0  # m/s: about R per step at the default dt
    bodies = pair(gap=2 * R, speed=speed)
    sim = dem.Simulation(bodies, LAW)
    seen = []
    sim.on_failure(lambda s, last_good: seen.append((s, last_good)))
    with pytest.raises(dem.SimulationError) as err:
        sim.run(1000)
    msg = str(err.value)
    assert re.search(r"\b0\b.*\b1\b", msg), msg  # names the two bodies
    assert "overlap" in msg
    assert len(seen) == 1
    hook_sim, last_good = seen[0]
    assert hook_sim is sim
    assert isinstance(last_good, dem.Bodies) and last_good is not sim.bodies
    good_overlap = 2 * R - np.linalg.norm(last_good.pos[1] - last_good.pos[0])
    bad_overlap = 2 * R - np.linalg.norm(sim.bodies.pos[1] - sim.bodies.pos[0])
    assert good_overlap <= sim.overlap_limit * R < bad_overlap
    assert np.all(np.isfinite(last_good.pos)) and np.all(np.isfinite(last_good.vel))
    # the snapshot is a copy: the failing step did not write into it
    assert not np.array_equal(last_good.pos, sim.bodies.pos)


def test_overlap_limit_is_configurable():
    bodies = pair(gap=-0.3 * R)  # 30 % overlap at rest
    with pytest.raises(dem.SimulationError):
        dem.Simulation(bodies.copy(), dem.LinearSpring(kn=1e5), overlap_limit=0.2).run(
            1
        )
    sim = dem.Simulation(bodies.copy(), dem.LinearSpring(kn=1e5), overlap_limit=0.5)
    sim.run(1)
    assert sim.step == 1


def test_nonfinite_state_during_a_run_raises():
    """``SimulationError`` covers a non-finite state, even of a contact-free body."""
    bodies = pair(gap=R)
    sim = dem.Simulation(bodies, LAW, gravity=[0.0, 0.0, -9.81])
    sim.run(2)
    sim.bodies.vel[0, 0] = math.nan  # e.g. written by a controller
    with pytest.raises(dem.SimulationError, match="non-finite"):
        sim.run(10)


def test_sphere_into_wall_at_huge_speed_raises():
    bodies = dem.Bodies.spheres(
        [[0.0, 2 * R]], radius=R, density=RHO, vel=[[0.0, -200.0]]
    )
    bodies.add_plane([0.0, 0.0], [0.0, 1.0])
    with pytest.raises(dem.SimulationError, match="overlap"):
        dem.Simulation(bodies, LAW).run(1000)


# --------------------------------------------------------------------------- input
@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_nonfinite_positions_are_refused(bad):
    pos = np.zeros((3, 3))
    pos[1] = [1.0, 0.0, 0.0]
    pos[2, 1] = bad
    with pytest.raises(ValueError, match="pos"):
        dem.Bodies.spheres(pos, radius=R, density=RHO)
    b = dem.Bodies.spheres(pos[:2], radius=R, density=RHO)
    with pytest.raises(ValueError, match="pos"):
        b.add_spheres(pos[2:], radius=R, density=RHO)
    assert b.n == 2  # nothing appended


def test_nonfinite_velocities_are_refused():
    with pytest.raises(ValueError, match="vel"):
        dem.Bodies.spheres(
            [[0.0, 0.0, 0.0]], radius=R, density=RHO, vel=[[math.nan, 0.0, 0.0]]
        )


@pytest.mark.parametrize("radius", [-R, 0.0, math.nan, math.inf])
def test_nonpositive_or_nonfinite_radius_is_refused(radius):
    with pytest.raises(ValueError, match="radius"):
        dem.Bodies.spheres([[0.0, 0.0], [1.0, 0.0]], radius=[R, radius], density=RHO)


@pytest.mark.parametrize("density", [-RHO, 0.0, math.nan])
def test_nonpositive_density_is_refused(density):
    with pytest.raises(ValueError, match="density"):
        dem.Bodies.spheres([[0.0, 0.0]], radius=R, density=density)


def test_bad_shapes_and_dimensions_are_refused():
    with pytest.raises(ValueError, match="shape"):
        dem.Bodies.spheres(np.zeros((2, 4)), radius=R, density=RHO)
    b = dem.Bodies.spheres(np.zeros((1, 3)), radius=R, density=RHO)
    with pytest.raises(ValueError):
        b.add_spheres(np.zeros((1, 2)), radius=R, density=RHO)
    with pytest.raises(ValueError):
        b.add_plane([0.0, 0.0], [0.0, 1.0])
    with pytest.raises(ValueError, match="normal"):
        b.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="gravity"):
        dem.Simulation(b, LAW, gravity=[0.0, -9.81])


@pytest.mark.parametrize(
    "kw",
    [
        dict(kn=0.0),
        dict(kn=-1.0),
        dict(kn=1e5, kt=-1.0),
        dict(kn=1e5, mu=-0.1),
        dict(kn=1e5, gamma_n=-1.0),
        dict(kn=1e5, restitution=0.0),
        dict(kn=1e5, restitution=1.5),
        dict(kn=math.nan),
    ],
)
def test_bad_law_parameters_are_refused(kw):
    with pytest.raises(ValueError):
        dem.LinearSpring(**kw)


@pytest.mark.parametrize("damping", [-0.1, 1.0])
def test_local_damping_out_of_range_is_refused(damping):
    with pytest.raises(ValueError, match="damping"):
        dem.Simulation(pair(), LAW, damping=damping)


def test_missing_sphere_law_is_named_at_setup():
    bodies = pair(mat_id=[0, 1])
    with pytest.raises(ValueError) as err:
        dem.Simulation(bodies, dem.ContactModel({(0, 0): LAW}))
    msg = str(err.value)
    assert "(0, 1)" in msg and "(1, 1)" in msg
    assert "(0, 0)" not in msg


def test_missing_wall_law_is_named_at_setup():
    bodies = pair()
    bodies.add_plane([0.0, 0.0, -R], [0.0, 0.0, 1.0], mat_id=3)
    model = dem.ContactModel(LAW, wall_law={(0, 2): LAW})
    with pytest.raises(ValueError, match=r"particle-wall materials \(0, 3\)"):
        dem.Simulation(bodies, model)


def test_missing_mesh_wall_law_is_named_at_setup():
    """A triangle-mesh wall's material counts as a wall's: without a particle-wall law
    for it the scene is refused before it runs (its contacts would have NaN forces)."""
    floor = dem.MeshWall([[-1.0, -1.0, -R], [1.0, -1.0, -R], [1.0, 1.0, -R]], [[0, 1, 2]],
                         mat_id=4)
    model = dem.ContactModel(LAW, wall_law={(0, 2): LAW})
    with pytest.raises(ValueError, match=r"particle-wall materials \(0, 4\)"):
        dem.Simulation(pair(), model, walls=[floor])


def test_mixed_law_kinds_in_one_bucket_are_refused():
    hertz = dem.HertzMindlin(young=1e8, poisson=0.3, restitution=0.5, mu=0.3)
    with pytest.raises(ValueError, match="same law kind"):
        dem.ContactModel({(0, 0): LAW, (0, 1): hertz})


@pytest.mark.parametrize("young, message", [
    ((math.inf, math.inf), "at most one side may be rigid"),
    ((1e8, math.nan), "young must be > 0"),
    ((-1e8, math.inf), "young must be > 0"),
    (0.0, "young must be > 0"),
])
def test_bad_hertz_moduli_are_refused(young, message):
    with pytest.raises(ValueError, match=message):
        dem.HertzMindlin(young=young, poisson=0.3, restitution=0.5, mu=0.3)


def test_a_rigid_side_keeps_the_time_step_and_damping_finite():
    """1/inf = 0: E* and G* of a rigid plane are those of the body's side alone, and
    the critical stiffness and damping ratios stay finite."""
    rigid = dem.HertzMindlin(young=(1e8, math.inf), poisson=(0.3, 0.2), restitution=0.5,
                             mu=0.3)
    assert rigid.e_star == pytest.approx(1e8 / (1 - 0.3**2), rel=1e-14)
    assert rigid.g_star == pytest.approx(1e8 / (2 * (2 - 0.3) * (1 + 0.3)), rel=1e-14)
    same = dem.HertzMindlin(young=1e8, poisson=0.3, restitution=0.5, mu=0.3)
    assert rigid.critical_stiffness(R) == pytest.approx(2.0 * same.critical_stiffness(R))
    assert rigid.damping_ratios(1.0, 3.5) == same.damping_ratios(1.0, 3.5)
    bodies = pair()
    bodies.add_plane([0.0, 0.0, -R], [0.0, 0.0, 1.0])
    sim = dem.Simulation(bodies, dem.ContactModel(same, wall_law=rigid))
    assert math.isfinite(sim.dt_crit) and 0.0 < sim.dt < sim.dt_stable
    assert dem.contact.laws.law_from_spec(rigid.spec()).e_star == rigid.e_star
