"""Closed forms of linear poroelasticity: the material constants against hand values,
Terzaghi's consolidation against the classical table and its own two series, and
Mandel's problem against its roots, its undrained and drained elastic limits, the
Mandel-Cryer overshoot and the fluid mass balance."""

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.special import polygamma

from hmm.poroelastic_solutions import (
    BiotMaterial,
    _terzaghi_fourier,
    _terzaghi_images,
    mandel_cryer_peak,
    mandel_displacement_top,
    mandel_initial_pressure,
    mandel_pressure,
    mandel_roots,
    terzaghi_degree,
    terzaghi_initial_pressure,
    terzaghi_pressure,
    terzaghi_settlement,
)

# K = 1e8, G = 6e7: nu = 1.8e8 / 7.2e8 = 1/4; K_u = K + M = 1.1e9
MAT = BiotMaterial(bulk=1e8, shear=6e7, biot=1.0, storage_modulus=1e9, mobility=1e-10)
SOFT = BiotMaterial(bulk=2e7, shear=1.5e7, biot=0.8, storage_modulus=5e8,
                    mobility=3e-11)
H, Q = 2.0, 1e5
A, B, F = 1.0, 2.0, 1e4


def _t_of_tv(tv, material=MAT, height=H):
    return np.asarray(tv) * height**2 / material.consolidation_coefficient_1d


def _t_mandel(tf, material=MAT, a=A):
    return np.asarray(tf) * a**2 / material.consolidation_coefficient_mandel


# --------------------------------------------------------------------------- material
def test_undrained_constants_by_hand():
    assert MAT.poisson == pytest.approx(0.25, rel=1e-14)
    assert MAT.undrained_bulk == pytest.approx(1.1e9, rel=1e-14)
    # (3 * 1.1e9 - 1.2e8) / (2 * (3.3e9 + 6e7)) = 3.18e9 / 6.72e9
    assert MAT.undrained_poisson == pytest.approx(3.18 / 6.72, rel=1e-14)
    assert MAT.skempton == pytest.approx(1 / 1.1, rel=1e-14)
    assert MAT.constrained == pytest.approx(1.8e8, rel=1e-14)
    # kappa / (1/M + 1/(K + 4G/3)) = 1e-10 / (1e-9 + 1/1.8e8)
    assert MAT.consolidation_coefficient_1d == pytest.approx(
        1e-10 / (1e-9 + 1 / 1.8e8), rel=1e-14)


@pytest.mark.parametrize("m", [MAT, SOFT])
def test_derived_constants_agree_with_each_other(m):
    nu, nu_u, b = m.poisson, m.undrained_poisson, m.skempton
    assert b == pytest.approx(3 * (nu_u - nu) / (m.biot * (1 - 2 * nu) * (1 + nu_u)),
                              rel=1e-12)
    assert m.consolidation_coefficient_mandel == pytest.approx(
        m.consolidation_coefficient_1d, rel=1e-12)
    again = BiotMaterial.from_young(2 * m.shear * (1 + nu), nu, biot=m.biot,
                                    storage_modulus=m.storage_modulus,
                                    mobility=m.mobility)
    assert again.bulk == pytest.approx(m.bulk, rel=1e-12)
    assert again.shear == pytest.approx(m.shear, rel=1e-12)


def test_incompressible_constituents_limit():
    stiff = [BiotMaterial(bulk=1e8, shear=6e7, storage_modulus=s, mobility=1e-10)
             for s in (1e12, 1e15, math.inf)]
    assert [m.undrained_poisson for m in stiff] == pytest.approx([0.5] * 3, abs=1e-4)
    assert [m.skempton for m in stiff] == pytest.approx([1.0] * 3, abs=1e-4)
    assert stiff[-1].undrained_poisson == 0.5 and stiff[-1].skempton == 1.0
    assert stiff[-1].consolidation_coefficient_mandel == pytest.approx(
        stiff[-1].consolidation_coefficient_1d, rel=1e-12)


def test_invalid_material_is_refused():
    with pytest.raises(ValueError):
        BiotMaterial(bulk=1e8, shear=6e7, biot=1.2, mobility=1e-10)
    with pytest.raises(ValueError):
        BiotMaterial(bulk=1e8, shear=-1.0, mobility=1e-10)


# --------------------------------------------------------------------------- Terzaghi
def test_terzaghi_degree_classical_values():
    u50, u90 = terzaghi_degree(_t_of_tv([0.197, 0.848]), H, MAT)
    assert abs(u50 - 0.5) < 1e-3 and abs(u90 - 0.9) < 1e-3
    assert terzaghi_degree(0.0, H, MAT) == 0.0
    assert terzaghi_degree(_t_of_tv(1e-6), H, MAT) == pytest.approx(
        2 * math.sqrt(1e-6 / math.pi), rel=1e-12)
    assert terzaghi_degree(_t_of_tv(20.0), H, MAT) == pytest.approx(1.0, abs=1e-15)


def test_terzaghi_series_agree_across_the_switch():
    zeta = np.linspace(0, 1, 21)
    for tv in (0.02, 0.1, 0.3):
        assert np.allclose(_terzaghi_fourier(zeta, tv, 200), _terzaghi_images(zeta, tv),
                           rtol=0, atol=1e-13)
    just = _t_of_tv(0.1 * (1 + np.array([-1e-12, 0.0, 1e-12])))
    assert np.ptp(terzaghi_degree(just, H, MAT)) < 1e-11


def test_terzaghi_initial_pressure():
    p0 = terzaghi_initial_pressure(MAT, Q)
    assert p0 == pytest.approx(Q * 1e9 / (1.8e8 + 1e9), rel=1e-14)
    stiff = BiotMaterial(bulk=1e8, shear=6e7, biot=0.7, mobility=1e-10)
    assert terzaghi_initial_pressure(stiff, Q) == pytest.approx(Q / 0.7, rel=1e-14)
    z = np.array([0.0, 1e-3, 0.5, 1.0, 2.0])
    tiny = terzaghi_pressure(z, _t_of_tv(1e-12), H, MAT, Q)
    assert tiny[0] == 0.0 and np.allclose(tiny[1:], p0, rtol=1e-12)
    assert np.array_equal(terzaghi_pressure(z, 0.0, H, MAT, Q), np.r_[0.0, [p0] * 4])


@pytest.mark.parametrize("tv", [0.003, 0.05, 0.197, 0.6])
def test_terzaghi_pressure_integral_is_one_minus_degree(tv):
    t = _t_of_tv(tv, SOFT)
    p0 = terzaghi_initial_pressure(SOFT, Q)
    area, _ = quad(lambda z: terzaghi_pressure(z, t, H, SOFT, Q), 0, H,
                   epsabs=1e-12 * p0 * H, epsrel=1e-12, limit=200)
    assert area == pytest.approx((1 - terzaghi_degree(t, H, SOFT)) * p0 * H, rel=1e-6)
    # settlement from the effective stress: s = (q H - alpha int p dz) / (K + 4G/3)
    s = (Q * H - SOFT.biot * area) / SOFT.constrained
    assert terzaghi_settlement(t, H, SOFT, Q) == pytest.approx(s, rel=1e-9)


def test_terzaghi_settlement_limits():
    s = terzaghi_settlement(_t_of_tv([0.0, 30.0]), H, MAT, Q)
    assert s == pytest.approx([Q * H / (1.8e8 + 1e9), Q * H / 1.8e8], rel=1e-12)
    stiff = BiotMaterial(bulk=1e8, shear=6e7, mobility=1e-10)
    assert terzaghi_settlement(0.0, H, stiff, Q) == 0.0
    with pytest.raises(ValueError):
        terzaghi_degree(-1.0, H, MAT)


# ----------------------------------------------------------------------------- Mandel
@pytest.mark.parametrize("m", [MAT, SOFT])
def test_mandel_roots_solve_the_equation_on_their_branches(m):
    r = mandel_roots(m, 200)
    slope = (1 - m.poisson) / (m.undrained_poisson - m.poisson)
    branch = np.arange(200) * np.pi
    assert np.all((r > branch) & (r < branch + np.pi / 2))
    assert np.max(np.abs(np.sin(r) - slope * r * np.cos(r)) / (slope * r)) < 1e-12
    assert np.max(np.abs(np.tan(r[:5]) / (slope * r[:5]) - 1)) < 1e-12


def test_mandel_pressure_starts_uniform():
    p0 = mandel_initial_pressure(A, F, MAT)
    assert p0 == pytest.approx(F * MAT.skempton * (1 + MAT.undrained_poisson) / (3 * A))
    x = np.linspace(-0.9, 0.9, 19) * A
    p = mandel_pressure(x, _t_mandel(1e-6), A, F, MAT, terms=2500)
    assert np.max(np.abs(p / p0 - 1)) < 1e-3
    assert np.allclose(mandel_pressure([-A, A], _t_mandel(1e-2), A, F, MAT), 0,
                       atol=1e-12 * p0)
    assert np.array_equal(mandel_pressure([0.0, A], 0.0, A, F, MAT), [p0, 0.0])


def test_mandel_cryer_overshoot_then_decay():
    p0 = mandel_initial_pressure(A, F, MAT)
    tf = np.logspace(-3, 1, 81)
    centre = np.array([mandel_pressure(0.0, t, A, F, MAT) for t in _t_mandel(tf)]) / p0
    peak = mandel_cryer_peak(A, F, MAT)
    assert 1.0 < peak and centre.max() > 1.0
    assert centre.max() <= peak + 1e-12
    assert centre.max() == pytest.approx(peak, rel=1e-3)
    assert abs(centre[-1]) < 1e-6
    assert mandel_pressure(0.0, _t_mandel(50.0), A, F, MAT) == pytest.approx(
        0.0, abs=1e-15 * p0)


@pytest.mark.parametrize("m", [MAT, SOFT])
def test_mandel_displacement_elastic_limits(m):
    nu, nu_u, g = m.poisson, m.undrained_poisson, m.shear
    # plane strain, free sides: eps_yy = -(F/a)(1 - nu^2)/E, E = 2G(1 + nu)
    drained = -B * (F / A) * (1 - nu**2) / (2 * g * (1 + nu))
    undrained = -B * (F / A) * (1 - nu_u**2) / (2 * g * (1 + nu_u))
    u = mandel_displacement_top(_t_mandel([0.0, 80.0], m), A, B, F, m)
    assert u == pytest.approx([undrained, drained], rel=1e-6)
    # the series itself reaches the undrained value: its partial sums plus the tail
    # sum_{n>N} 1/(slope a_n^2), a_n ~ (n - 1/2) pi
    r = mandel_roots(m, 2000)
    slope = (1 - nu) / (nu_u - nu)
    sc = np.sin(r) * np.cos(r)
    total = np.sum(sc / (r - sc)) + polygamma(1, 2000.5) / (slope * np.pi**2)
    assert total == pytest.approx((nu_u - nu) / (2 * (1 - nu_u)), rel=1e-9)


@pytest.mark.parametrize("tf", [0.01, 0.1, 0.7])
def test_mandel_plate_load_is_carried(tf):
    """Plate equilibrium: u_y/b = -F(1 - nu)/(2Ga) + alpha(1 - 2nu)/(2Ga) int_0^a p."""
    m, t = SOFT, _t_mandel(tf, SOFT)
    area, _ = quad(lambda x: mandel_pressure(x, t, A, F, m), 0, A, epsrel=1e-12,
                   limit=200)
    nu, g = m.poisson, m.shear
    expected = -F * (1 - nu) / (2 * g * A) + m.biot * (1 - 2 * nu) / (2 * g * A) * area
    assert mandel_displacement_top(t, A, B, F, m) / B == pytest.approx(expected,
                                                                     rel=1e-9)


@pytest.mark.parametrize("tf", [0.02, 0.3])
def test_mandel_fluid_mass_balance(tf):
    """(1/M) p_t + alpha eps_vol_t = kappa p_xx, eps_xx from sigma_xx = 0."""
    m, t = SOFT, _t_mandel(tf, SOFT)
    lam = m.bulk - 2 * m.shear / 3
    dt, dx = 1e-4 * t, 1e-3 * A
    x = np.array([0.0, 0.3, 0.8]) * A

    def p(x, t):
        return mandel_pressure(x, t, A, F, m)

    def eps_vol(x, t):
        eps_yy = mandel_displacement_top(t, A, B, F, m) / B
        return eps_yy + (m.biot * p(x, t) - lam * eps_yy) / m.constrained

    p_t = (p(x, t + dt) - p(x, t - dt)) / (2 * dt)
    ev_t = (eps_vol(x, t + dt) - eps_vol(x, t - dt)) / (2 * dt)
    p_xx = (p(x + dx, t) - 2 * p(x, t) + p(x - dx, t)) / dx**2
    lhs = p_t / m.storage_modulus + m.biot * ev_t
    assert lhs == pytest.approx(m.mobility * p_xx, rel=1e-5)
