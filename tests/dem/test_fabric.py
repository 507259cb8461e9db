"""The anisotropy of a contact fabric (dem.observers.fabric_anisotropy) against the
densities of normals it is the Fourier amplitude of."""

import math

import numpy as np
import pytest

from dem.observers import fabric_anisotropy


def _weighted_fabric(normals, weights):
    return np.einsum("c,ci,cj->ij", weights, normals, normals) / weights.sum()


@pytest.mark.parametrize("a, theta_a", [(0.0, 0.0), (0.3, 0.0), (0.7, 1.1), (1.0, -0.4)])
def test_2d_anisotropy_is_the_amplitude_of_the_normals_density(a, theta_a):
    """Normals at evenly spaced angles with the density ``1 + a cos 2(theta - theta_a)``
    (exact for the second harmonic on 16 angles) give back ``a``."""
    theta = np.linspace(0.0, 2.0 * math.pi, 16, endpoint=False)
    n = np.c_[np.cos(theta), np.sin(theta)]
    f = _weighted_fabric(n, 1.0 + a * np.cos(2.0 * (theta - theta_a)))
    assert np.trace(f) == pytest.approx(1.0, abs=1e-14)
    assert fabric_anisotropy(f) == pytest.approx(a, abs=1e-13)


def test_3d_anisotropy_is_the_amplitude_of_the_normals_density():
    """On a product rule exact for polynomials of degree 5 on the sphere (Gauss-Legendre
    in cos(theta), even in phi), the density ``1 + a_ij n_i n_j`` with a random
    deviatoric ``a_ij`` gives ``F' = 2/15 a_ij`` and the anisotropy
    ``sqrt(3/2 a_ij a_ij)``; about an axis of symmetry that is the amplitude of
    ``1 + a (3 cos^2 theta - 1) / 3``."""
    x, w = np.polynomial.legendre.leggauss(4)
    phi = np.linspace(0.0, 2.0 * math.pi, 8, endpoint=False)
    ct, ph = np.meshgrid(x, phi, indexing="ij")
    st = np.sqrt(1.0 - ct ** 2)
    n = np.c_[(st * np.cos(ph)).ravel(), (st * np.sin(ph)).ravel(), ct.ravel()]
    wq = np.repeat(w, phi.size)
    rng = np.random.default_rng(4)
    m = rng.uniform(-0.3, 0.3, (3, 3))
    a = 0.5 * (m + m.T)
    a -= np.trace(a) / 3.0 * np.eye(3)
    f = _weighted_fabric(n, wq * (1.0 + np.einsum("ij,ci,cj->c", a, n, n)))
    np.testing.assert_allclose(f - np.eye(3) / 3.0, 2.0 / 15.0 * a, atol=1e-15)
    assert fabric_anisotropy(f) == pytest.approx(math.sqrt(1.5 * np.sum(a * a)), rel=1e-13)
    axial = 0.4 * np.diag([-1.0, -1.0, 2.0]) / 3.0  # 0.4 (3 n_z^2 - 1) / 3
    f = _weighted_fabric(n, wq * (1.0 + np.einsum("ij,ci,cj->c", axial, n, n)))
    assert fabric_anisotropy(f) == pytest.approx(0.4, rel=1e-13)


def test_isotropic_fabrics_have_none_and_a_fabric_of_no_contacts_is_nan():
    assert fabric_anisotropy(np.eye(2) / 2.0) == 0.0
    assert fabric_anisotropy(np.eye(3) / 3.0) == pytest.approx(0.0, abs=1e-15)
    assert math.isnan(fabric_anisotropy(np.zeros((3, 3))))
    assert math.isnan(fabric_anisotropy(np.full((2, 2), np.nan)))
    # all normals along one axis: the largest a second harmonic can fit
    assert fabric_anisotropy(np.diag([1.0, 0.0])) == pytest.approx(2.0)
    assert fabric_anisotropy(np.diag([0.0, 0.0, 1.0])) == pytest.approx(7.5)
