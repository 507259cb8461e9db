"""3D lattice cantilever of bonded beams: sections, bending stiffness, calibration."""

import itertools
import runpy
from pathlib import Path

import numpy as np
import pytest

from dem.peridynamics.beam_lattice import (
    _offsets,
    lattice_cantilever,
    lattice_constants,
)
from dem.peridynamics.beam_kernels import bond_beam_3d

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "beams_lattice.py"
E, DENSITY = 1.0e9, 1000.0


def x_bonds_of_one_bay(bodies, bonds):
    """Rows of the bonds along x that leave the clamped layer x = 0."""
    i, j = bonds.pairs.T
    dx = bodies.pos[j] - bodies.pos[i]
    return np.flatnonzero((bodies.pos[i, 0] == 0.0) & (np.abs(dx[:, 1]) < 1e-12)
                          & (np.abs(dx[:, 2]) < 1e-12))


@pytest.mark.parametrize("n", [1, 2, 3, 6])
def test_nearest_sections_sum_to_the_bar(n):
    # cell-centred fibres: sum A = h w and sum (A z^2 + I) = w h^3 / 12 exactly
    height, width = 0.1, 0.2
    s = height / n
    bodies, bonds = lattice_cantilever(3, 2 * n, n, 2 * s, height, width, E, DENSITY)
    rows = x_bonds_of_one_bay(bodies, bonds)
    assert rows.size == 2 * n * n
    z = bodies.pos[bonds.pairs[rows, 0], 2]
    ea, ei_about_y = bonds.params[rows, 1], bonds.params[rows, 3]  # c = -y for x bonds
    assert ea.sum() == pytest.approx(E * height * width, rel=1e-12)
    assert np.sum(ea * z**2 + ei_about_y) == pytest.approx(E * width * height**3 / 12,
                                                           rel=1e-12)


def quat_about_y(angle):
    return np.column_stack([np.cos(angle / 2), np.zeros_like(angle), np.sin(angle / 2),
                            np.zeros_like(angle)])


@pytest.mark.parametrize("n", [2, 3])
def test_nearest_lattice_carries_pure_bending_with_the_bars_EI(n):
    """Bend the bar into the arc of curvature kappa (plane sections turned by
    -kappa x about y, no lateral strain since nu = 0): every body inside is in
    equilibrium and the tip layer carries the moment E I kappa.

    The field is exact for the linearised lattice. What is left is geometric: a
    fibre force N turns by kappa s from one bond to the next and pushes its body
    across the bar by N kappa s, so the tolerance is 1e-6 of the largest fibre force
    for kappa s = 5e-7.
    """
    length, side = 0.5, 0.1
    s = side / n
    bodies, bonds = lattice_cantilever(round(length / s) + 1, n, n, length, side, side,
                                       E, DENSITY)
    kappa = 1e-5  # [1/m]
    x, z = bodies.pos[:, 0].copy(), bodies.pos[:, 2].copy()
    bodies.pos[:, 0] = (1.0 / kappa - z) * np.sin(kappa * x)
    bodies.pos[:, 2] = z * np.cos(kappa * x) + 2.0 * np.sin(0.5 * kappa * x)**2 / kappa
    bodies.rot[:] = quat_about_y(-kappa * x)
    force, torque, _ = bonds.forces(bodies)
    ei = E * side**4 / 12.0
    inside = (x > 0.0) & (x < length - 1e-12)
    fibre = E * s**2 * kappa * side / 2  # force in the outermost fibre [N]
    assert np.abs(force[inside]).max() < 1e-6 * fibre
    assert np.abs(torque[inside]).max() < 1e-6 * fibre * s
    tip = np.flatnonzero(x > length - 1e-12)
    arm = bodies.pos[tip] - bodies.pos[tip].mean(axis=0)
    moment = torque[tip].sum(axis=0) + np.cross(arm, force[tip]).sum(axis=0)
    assert np.abs(force[tip].sum(axis=0)).max() < 1e-6 * fibre
    # the bonds pull the tip back: the moment applied there is -moment
    np.testing.assert_allclose(-moment, [0.0, -ei * kappa, 0.0], atol=1e-6 * ei * kappa)


def centre_stress(bodies, bonds, centre, strain, h):
    """Virial stress [Pa] at body ``centre`` under the uniform ``strain`` (3, 3),
    bodies unturned, as the central difference of strains +-h (the second-order
    part cancels): ``-(1 / 2 s^3) sum_bonds (x_o - x_c) (x) F_o``."""
    s = bonds.params[:, 0].min()
    rows = np.flatnonzero(np.any(bonds.pairs == centre, axis=1))
    ref = bodies.pos.copy()
    out = []
    for sign in (1.0, -1.0):
        bodies.pos[:] = ref + sign * h * (ref - ref[centre]) @ strain.T
        sigma = np.zeros((3, 3))
        for k in rows:
            f = np.array(bond_beam_3d(k, bonds.pairs, bonds.params, bonds.frames,
                                      bodies.pos, bodies.rot)[:3])  # on pairs[k, 1]
            i, j = bonds.pairs[k]
            sigma -= np.outer(bodies.pos[j] - bodies.pos[i], f)
        out.append(sigma / (2.0 * s**3))
    bodies.pos[:] = ref
    return (out[0] - out[1]) / (2.0 * h)


@pytest.mark.parametrize("ratio", [None, 1.5, 1.8, 2.4, 3.0])
def test_calibrated_lattice_has_youngs_modulus_E_in_uniaxial_stress(ratio):
    m = 1 if ratio is None else int(np.floor(ratio))
    n, s = 2 * m + 1, 0.02
    bodies, bonds = lattice_cantilever(n, n, n, (n - 1) * s, n * s, n * s, E, DENSITY,
                                       radius=None if ratio is None else ratio * s)
    centre = (n**3 - 1) // 2
    n_bonds = np.count_nonzero(np.any(bonds.pairs == centre, axis=1))
    assert n_bonds == len(_offsets(1.0 if ratio is None else ratio))
    nu = lattice_constants(1.0 if ratio is None else ratio).poisson
    strain = np.diag([1.0, -nu, -nu])
    sigma = centre_stress(bodies, bonds, centre, strain, h=1e-6)
    assert sigma[0, 0] == pytest.approx(E, rel=1e-6)
    assert np.abs(sigma - np.diag([sigma[0, 0], 0.0, 0.0])).max() < 1e-6 * E


def test_nearest_lattice_is_isotropic_with_poisson_zero():
    c = lattice_constants(1.0)
    assert (c.c11, c.c12, c.c44, c.young, c.poisson) == (1.0, 0.0, 0.5, 1.0, 0.0)


def test_lattice_must_be_cubic():
    with pytest.raises(ValueError, match="not a cubic lattice"):
        lattice_cantilever(11, 2, 3, 1.0, 0.1, 0.1, E, DENSITY)


def test_example_errors_fall_as_bodies_are_added(tmp_path):
    ex = runpy.run_path(str(EXAMPLE), run_name="example")
    table = ex["main"](small=True, out=tmp_path / "lattice.png")
    assert (tmp_path / "lattice.png").stat().st_size > 0
    near, radius = table["nearest"], table["radius"]
    ns = sorted(near)
    # nearest neighbours: within 1 % of EB plus the shear deflection of G = E / 2,
    # and closer with every refinement
    errors = [abs(near[n]["timoshenko"]) for n in ns]
    assert all(a > b for a, b in itertools.pairwise(errors)), near
    assert errors[-1] < 0.01
    # the radius lattice is too soft (surface bodies miss bonds), less so when finer
    errors = [radius[n]["eb"] for n in ns]
    assert all(a > b > 0 for a, b in itertools.pairwise(errors)), radius
