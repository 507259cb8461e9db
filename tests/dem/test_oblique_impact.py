"""Oblique impacts of a sphere on a plane with damped contacts (Maw, Barber & Fawcett's
test, as Chung & Ooi and the DEM codes run it).

In gross sliding the tangential impulse is the friction coefficient times the normal
one, whatever the dashpots: the tangential spring and its dashpot act in parallel and
the Coulomb slider in series with them, so while the contact slides the pair carries
exactly the friction force. The spring that once absorbed the dashpot's excess (and
pointed backwards while the dashpot alone exceeded the friction limit) gave 0.80 mu at
e = 0.3, mu = 0.3, 70 deg. The slider's limit is mu times the repulsive normal force:
at low restitution the normal dashpot pulls at the end of a contact (the damped laws
of LIGGGHTS and LAMMPS do too), which carries no friction, so the tangential impulse is
mu times the compressive normal impulse; against the whole change of normal momentum
it is up to 7 % more at e = 0.3, and the rebound spin ``2.5 jt / (m R)`` as much above
``2.5 mu (1 + e) v_n / R``.
"""

import math

import numpy as np
import pytest

import dem

R, RHO, SPEED = 0.01, 2500.0, 1.0


def impact(law, angle_deg, max_steps=200_000):
    """A sphere hitting the plane z = 0 at ``angle_deg`` from the normal with no spin.

    Returns ``(jn, jn_plus, jt, spin, vn_before, vn_after)``: the normal impulse [N s]
    (the change of momentum), its compressive part (the sum of the repulsive normal
    forces times dt: what a Coulomb slider has to work with), the tangential impulse,
    the spin after [rad/s] and the normal speeds [m/s].
    """
    b = dem.Bodies.empty(3)
    th = math.radians(angle_deg)
    vel = [SPEED * math.sin(th), 0.0, -SPEED * math.cos(th)]
    b.add_spheres([[0.0, 0.0, R * 1.0001]], R, RHO, vel=[vel])
    b.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    sim = dem.Simulation(b, law, gravity=[0.0, 0.0, 0.0])
    m = b.mass[0]
    v0 = b.vel[0].copy()
    jn_plus = 0.0  # the sphere starts a hair above the plane: every step counts
    while not (b.pos[0, 2] > R and b.vel[0, 2] > 0.0) and sim.step < max_steps:
        sim.run(1, progress=False)
        jn_plus += max(b.force[0, 2], 0.0) * sim.dt
    assert sim.step < max_steps, "the sphere did not leave the plane"
    dv = b.vel[0] - v0
    return m * dv[2], jn_plus, -m * dv[0], b.ang_vel[0, 1], -v0[2], b.vel[0, 2]


def laws(e, mu):
    hm = dem.HertzMindlin(young=7.0e10, poisson=0.3, restitution=e, mu=mu)
    # a linear law with both dashpots: the restitution one and a tangential one
    kn = 1.0e6
    m_eff = RHO * 4.0 / 3.0 * math.pi * R**3
    lin = dem.LinearSpring(kn=kn, kt=2.0 / 7.0 * kn, mu=mu, restitution=e,
                           gamma_t=0.5 * math.sqrt(kn * m_eff))
    return {"hertz_mindlin": hm, "linear": lin}


CASES = [(e, mu, angle) for e in (0.3, 0.7, 0.98) for mu in (0.1, 0.3, 0.5)
         for angle in (45.0, 70.0, 85.0)
         # gross sliding from start to end: the slip outlasts the impulse
         if math.tan(math.radians(angle)) > 3.5 * mu * (1.0 + e) * 1.05]


@pytest.mark.parametrize("name", ["hertz_mindlin", "linear"])
def test_in_gross_sliding_the_tangential_impulse_is_mu_times_the_normal(name):
    assert len(CASES) >= 12
    m = RHO * 4.0 / 3.0 * math.pi * R**3
    for e, mu, angle in CASES:
        jn, jn_plus, jt, spin, vn, vn_after = impact(laws(e, mu)[name], angle)
        where = f"{name}, e = {e}, mu = {mu}, {angle} deg"
        assert vn_after / vn == pytest.approx(e, rel=0.02), where
        assert jn == pytest.approx(m * (1.0 + e) * vn, rel=0.02), where
        # the slider's limit is mu times the repulsive normal force: at low e the
        # normal dashpot pulls at the end of the contact, which takes no friction
        assert jt / (mu * jn_plus) == pytest.approx(1.0, abs=0.01), where
        assert 1.0 - 1e-9 <= jn_plus / jn < (1.09 if e < 0.5 else 1.02), where
        # the spin: the friction's moment about the centre, -R z x (-jt x) = R jt y
        # (the lever is the centre's height above the plane, short of R by the overlap,
        # under 1 % of R here)
        assert spin == pytest.approx(2.5 * jt / (m * R), rel=0.01), where


def test_the_issue_case_and_a_sticking_one():
    """e = 0.3, mu = 0.3, 70 deg (0.80 mu before the slider was in series with the
    spring and its dashpot); at 10 deg the contact sticks: less than mu."""
    jn, jn_plus, jt, _, _, _ = impact(laws(0.3, 0.3)["hertz_mindlin"], 70.0)
    assert jt / (0.3 * jn_plus) == pytest.approx(1.0, abs=0.005)
    jn, jn_plus, jt, spin, vn, _ = impact(laws(0.3, 0.3)["hertz_mindlin"], 10.0)
    assert 0.0 < jt < 0.3 * jn_plus * 0.9
    assert spin > 0.0 and np.isfinite(spin)


@pytest.mark.parametrize("name", ["hertz_mindlin", "linear"])
def test_limit_damping_rebounds_with_e_and_slides_with_mu(name):
    """With the normal force clipped at zero (limit_damping) the dashpot never pulls:
    the whole normal impulse is compressive, the damping is remapped so that a head-on
    impact rebounds with e (dem.contact.restitution), and in gross sliding the
    tangential impulse is mu times the whole normal impulse, the rebound spin
    2.5 mu (1 + e) v_n / R."""
    for e in (0.3, 0.7):
        law = laws(e, 0.3)[name]
        clipped = dem.contact.laws.law_from_spec({**law.spec(), "limit_damping": True})
        _, _, _, _, vn, vn_after = impact(clipped, 0.0)
        # to the default step's accuracy (about 22 steps per contact: under 1 %)
        assert vn_after / vn == pytest.approx(e, rel=1e-2), e
        jn, jn_plus, jt, spin, vn, _ = impact(clipped, 70.0)
        assert jn_plus == pytest.approx(jn, rel=1e-9)
        assert jt == pytest.approx(0.3 * jn, rel=1e-2)
        assert spin == pytest.approx(2.5 * 0.3 * (1.0 + e) * vn / R, rel=2e-2)
        # without the clip the pull at the end of a low-e contact carries no friction
        jn, jn_plus, jt, _, _, _ = impact(law, 70.0)
        assert (jn_plus / jn > 1.03) == (e < 0.5)


def test_the_clipped_damping_inverts_the_rebound():
    from dem.contact.restitution import clipped_damping, clipped_rebound, unclipped_ratio

    for kind in ("linear", "hertz"):
        for e in (0.1, 0.5, 0.95):
            assert clipped_rebound(kind, clipped_damping(kind, e)) == pytest.approx(e, 1e-9)
    # the clip makes the rebound faster: more damping for the same e
    assert clipped_damping("linear", 0.5) > unclipped_ratio(0.5)
    with pytest.raises(ValueError, match=r"restitution must be in \(0, 1\]"):
        clipped_damping("linear", 0.0)
