"""Chung & Ooi (2011), benchmark test 2: a sphere hits a rigid plane normally.

An aluminium-alloy sphere (R = 0.1 m, E = 70 GPa, nu = 0.33, 2699 kg/m^3) meets a
rigid plane at 0.2 m/s, with no damping and no gravity. Hertz's theory gives the peak
overlap, the peak force and the contact duration in closed form, with
E* = E / (1 - nu^2) for a rigid plane; the simulation must match each within 1 %,
built through the Python API (``young=(E, inf)``) and through a scene file
(``rigid = true``). The plane given the sphere's own material halves E* and
overshoots the rigid-plane overlap by 2^(2/5) - 1 = 32 %: that is what the test
tells apart.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import dem
from dem.io.scene import build_simulation, load_scene

R, YOUNG, NU, DENSITY, SPEED = 0.1, 70e9, 0.33, 2699.0, 0.2
MASS = DENSITY * 4.0 / 3.0 * math.pi * R**3
E_STAR = YOUNG / (1.0 - NU**2)  # rigid plane: the sphere's side alone
GAP = 1e-6  # [m] between sphere and plane at the start
STEPS_PER_CONTACT = 2000


def hertz(e_star):
    """Hertz's closed forms: peak overlap [m], peak force [N], duration [s]."""
    delta = (15.0 * MASS * SPEED**2 / (16.0 * e_star * math.sqrt(R))) ** 0.4
    force = 4.0 / 3.0 * e_star * math.sqrt(R) * delta**1.5
    t_c = 2.868 * (MASS**2 / (R * e_star**2 * SPEED)) ** 0.2
    return delta, force, t_c


def hertz_ode_duration(e_star):
    """The contact duration [s] of m d'' = -4/3 E* sqrt(R) d^(3/2), d(0) = 0,
    d'(0) = v, integrated numerically."""
    k = 4.0 / 3.0 * e_star * math.sqrt(R)

    def rhs(t, y):
        return [y[1], -k / MASS * max(y[0], 0.0) ** 1.5]

    def leaves(t, y):
        return y[0]

    leaves.terminal, leaves.direction = True, -1.0
    t_guess = hertz(e_star)[2]
    sol = solve_ivp(rhs, (0.0, 2.0 * t_guess), [0.0, SPEED], events=leaves,
                    rtol=1e-11, atol=1e-16, max_step=t_guess / 200.0)
    return float(sol.t_events[0][0])


def dt_for(e_star):
    return hertz(e_star)[2] / STEPS_PER_CONTACT


def impact(sim):
    """Run the drop; the measured peak overlap [m], peak force [N] and duration [s]."""
    overlap = dem.Record(lambda s: R - s.bodies.pos[0, 2])
    force = dem.Record(lambda s: s.bodies.force[0, 2])
    sim.observers += [overlap, force]
    # 1.6: room for the contact of the plane of the sphere's material, 2^(2/5) longer
    sim.run(int((GAP / SPEED) / sim.dt) + int(1.6 * STEPS_PER_CONTACT))
    ov = np.array(overlap.values)
    assert ov[-1] < 0.0 and sim.bodies.vel[0, 2] > 0.0, "the sphere has not left the plane"
    return ov.max(), max(force.values), np.count_nonzero(ov > 0.0) * sim.dt


def api_simulation(wall_young):
    bodies = dem.Bodies.spheres([[0.0, 0.0, R + GAP]], radius=R, density=DENSITY)
    bodies.vel[0] = [0.0, 0.0, -SPEED]
    bodies.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    law = dem.HertzMindlin(young=(YOUNG, wall_young), poisson=NU, restitution=1.0, mu=0.0)
    return dem.Simulation(bodies, law, dt=dt_for(E_STAR))


def test_the_constant_2868_is_hertz_s():
    """The 2.868 of the duration's closed form, from integrating Hertz's equation."""
    t_ode = hertz_ode_duration(E_STAR)
    assert t_ode == pytest.approx(hertz(E_STAR)[2], rel=2e-4)


def test_sphere_on_a_rigid_plane_through_the_api():
    measured = impact(api_simulation(math.inf))
    delta, force, t_c = hertz(E_STAR)
    assert measured == pytest.approx((delta, force, hertz_ode_duration(E_STAR)), rel=0.01)
    assert measured[2] == pytest.approx(t_c, rel=0.01)


def test_the_sphere_s_own_material_on_the_plane_overshoots_by_32_percent():
    """E* of two equal bodies is half the rigid plane's: the overlap grows 2^(2/5)."""
    delta_own = impact(api_simulation(YOUNG))[0]
    delta_rigid = hertz(E_STAR)[0]
    assert delta_own / delta_rigid == pytest.approx(2.0**0.4, rel=0.01)
    assert delta_own / delta_rigid - 1.0 > 0.3


def _scene(tmp_path, wall):
    (tmp_path / "sphere.txt").write_text(f"0 0 {R + GAP!r} {R!r}\n")
    wall_keys = "".join(f"{k} = {v}\n" for k, v in wall.items())
    path = tmp_path / "chung_ooi.toml"
    path.write_text(f"""\
[simulation]
steps = 1
dt = {dt_for(E_STAR)!r}

[particles]
generator = "file"
file = "sphere.txt"
density = {DENSITY!r}
velocity = [0.0, 0.0, {-SPEED!r}]

[[walls]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
{wall_keys}
[contact]
law = "hertz_mindlin"
young = {YOUNG!r}
poisson = {NU!r}
restitution = 1.0
mu = 0.0
""")
    return build_simulation(load_scene(path))[0]


def test_sphere_on_a_rigid_plane_from_a_scene_file(tmp_path):
    sim = _scene(tmp_path, {"rigid": "true"})
    wall = sim.bodies.n - 1
    row = sim.parameter_table("pw")[sim.bodies.mat_id[0], sim.bodies.mat_id[wall]]
    assert row[0] == pytest.approx(E_STAR, rel=1e-12)
    delta, force, _ = hertz(E_STAR)
    assert impact(sim) == pytest.approx((delta, force, hertz_ode_duration(E_STAR)),
                                        rel=0.01)


def test_a_scene_wall_of_its_own_young_modulus(tmp_path):
    """A steel plane under the aluminium sphere: E* from both sides' moduli."""
    steel, nu_steel = 210e9, 0.3
    sim = _scene(tmp_path, {"young": steel, "poisson": nu_steel})
    b = sim.bodies
    e_star = 1.0 / ((1.0 - NU**2) / YOUNG + (1.0 - nu_steel**2) / steel)
    assert sim.parameter_table("pw")[b.mat_id[0], b.mat_id[b.n - 1]][0] == pytest.approx(
        e_star, rel=1e-12)
    # without material keys the wall has the sphere's: E* halves
    plain = _scene(tmp_path, {})
    assert plain.parameter_table("pw")[0, 0][0] == pytest.approx(0.5 * E_STAR, rel=1e-12)
