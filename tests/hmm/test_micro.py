"""Micro models: the trial/commit/rollback protocol, consistent tangents, the DEM RVE
behind it, and the adaptive switch."""

import numpy as np
import pytest

import dem
from dem import rve as rvemod
from hmm.micro import Adaptive, DEMMicroModel, Hyperbolic, LinearElastic, stress_ratio
from hmm.problem_build import clone_rve


@pytest.fixture(scope="module")
def packing():
    law = dem.LinearSpring(kn=1e8, kt=5e7, mu=0.5)
    return rvemod.generate(2, 40, (0.8e-3, 1.2e-3), law, p0=1e5, friction=0.0, seed=2)


@pytest.mark.parametrize("model", [LinearElastic(1e6, 0.3, 3, stress0=-1e3),
                                   Hyperbolic(1e6, 0.3, 1e-3, 3, stress0=-1e3)])
def test_tangent_is_the_derivative_of_the_stress(model):
    rng = np.random.default_rng(0)
    deps = rng.uniform(-1e-3, 1e-3, (3, 3))
    deps = 0.5 * (deps + deps.T)
    s0, c = model.trial(deps)
    h = 1e-8
    for k, m in [(0, 0), (1, 2), (2, 2)]:
        e = np.zeros((3, 3))
        e[k, m] = e[m, k] = h
        s1, _ = model.trial(deps + e)
        fd = (s1 - s0) / h
        want = c[:, :, k, m] + c[:, :, m, k] if k != m else c[:, :, k, k]
        assert np.allclose(fd, want, rtol=1e-5, atol=1e-6 * np.abs(c).max())


def test_trials_start_from_the_committed_state():
    m = Hyperbolic(1e6, 0.3, 1e-3)
    a, _ = m.trial(np.diag([1e-3, 0.0]))
    m.trial(np.diag([5e-3, 0.0]))  # a different trial in between changes nothing
    b, _ = m.trial(np.diag([1e-3, 0.0]))
    assert np.array_equal(a, b)
    m.commit()
    c, _ = m.trial(np.zeros((2, 2)))
    assert np.array_equal(c, a)
    m.trial(np.diag([1e-3, 0.0]))
    m.rollback()
    assert np.array_equal(m.stress, a)


def test_dem_trials_repeat_bit_for_bit_and_commit(packing):
    m = DEMMicroModel(clone_rve(packing))
    deps = np.array([[-4e-4, 1e-4], [1e-4, 2e-4]])
    s1, c1 = m.trial(deps)
    m.trial(-deps)
    s2, c2 = m.trial(deps)
    assert np.array_equal(s1, s2) and np.array_equal(c1, c2)
    assert s1[0, 0] < m.stress[0, 0]  # compressed along x
    m.commit()
    s3, _ = m.trial(np.zeros((2, 2)))
    assert np.allclose(s3, s1, rtol=0.0, atol=2e-3 * abs(s1[0, 0]))  # relaxes in place
    m.rollback()
    assert np.array_equal(m.stress, s1)


def test_dem_steps_count_the_perturbation_probes(packing):
    """A trial's DEM work counts its load and the tangent's probes (d (d + 1) / 2
    relaxations), though each probe restores the state it started from."""
    deps = np.diag([-2e-4, 0.0])
    contact = DEMMicroModel(clone_rve(packing))
    contact.trial(deps)
    probed = DEMMicroModel(clone_rve(packing), tangent="perturbation")
    probed.trial(deps)
    assert contact.steps > 0
    # the same load (bit-identical RVEs), then three probes of at least one step each
    assert probed.steps >= contact.steps + 3


def test_adaptive_point_runs_dem_only_outside_its_elastic_range(packing):
    m = Adaptive(DEMMicroModel(clone_rve(packing)), strain_threshold=1e-4,
                 ratio_threshold=0.3)
    s_el, c_el = m.trial(np.diag([-3e-5, 0.0]))
    assert m.steps == 0 and not m.ran_dem
    assert np.array_equal(c_el, m.c_elastic)
    assert s_el[0, 0] == pytest.approx(m.stress[0, 0] + c_el[0, 0, 0, 0] * -3e-5)
    m.commit()
    assert not m.ran_dem and np.allclose(m.pending, np.diag([-3e-5, 0.0]))
    m.trial(np.diag([-2e-4, 0.0]))  # leaves the range: the RVE takes all the strain
    assert m.steps > 0
    m.rollback()
    assert not m.ran_dem  # not committed: still elastic
    m.trial(np.diag([-2e-4, 0.0]))
    m.commit()
    assert m.ran_dem and np.all(m.pending == 0.0)
    m.trial(np.diag([-1e-6, 0.0]))  # from now on always the DEM
    assert m.steps > 0
    assert m.measures()["ran_dem"] == 1.0


def test_stress_ratio_of_a_biaxial_state():
    assert stress_ratio(np.diag([-1.0, -3.0])) == pytest.approx(0.5)
    assert stress_ratio(np.diag([-1.0, -1.0, -4.0])) == pytest.approx(3.0 / 2.0)


def test_a_rejected_trial_leaves_the_rve_exactly_committed(packing):
    m = DEMMicroModel(clone_rve(packing))
    before = m.rve.snapshot()
    m.trial(np.diag([-1e-3, 5e-4]))
    m.rollback()
    after = m.rve.snapshot()
    assert before.keys() == after.keys()
    assert all(np.array_equal(before[k], after[k]) for k in before)


def test_adaptive_with_zero_range_is_the_all_dem_model(packing):
    """Thresholds below any strain: every trial runs the RVE, bit for bit as DEM."""
    dem_only = DEMMicroModel(clone_rve(packing))
    adaptive = Adaptive(DEMMicroModel(clone_rve(packing)), strain_threshold=1e-300,
                        ratio_threshold=1e-300)
    for deps in (np.diag([-2e-4, 1e-4]), np.diag([-3e-4, 1e-4])):
        a = dem_only.trial(deps)
        b = adaptive.trial(deps)
        assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
        dem_only.commit()
        adaptive.commit()


def test_the_perturbation_tangent_needs_relaxed_calls(packing):
    """Relaxed probes from a relaxed state give a positive stiffness a little below
    the contact tangent's (an upper bound); from the unbalanced state an unrelaxed
    call leaves, the probes measure its relaxation and the 'stiffness' comes out
    negative. The model refuses that combination, and so does a problem file."""
    deps = np.diag([-1e-3, 5e-4])
    diag = {}
    for relax in (True, False):
        rve = clone_rve(packing)
        rve.apply_strain(deps, relax=relax)
        cp = rve.tangent("perturbation", 1e-5, direction=deps)
        cc = rve.tangent("contact")
        diag[relax] = np.array([cp[0, 0, 0, 0], cp[1, 1, 1, 1]]) \
            / np.array([cc[0, 0, 0, 0], cc[1, 1, 1, 1]])
    assert np.all((diag[True] > 0.5) & (diag[True] < 1.0))
    assert np.all(diag[False] < 0.0)
    with pytest.raises(ValueError, match="relax = false use the contact tangent"):
        DEMMicroModel(clone_rve(packing), tangent="perturbation", relax=False)
    from dem.io.schema import SceneError
    from hmm.problem import validate_problem

    prob = {"mesh": {"size": [1.0, 1.0], "cells": [1, 1]},
            "dirichlet": [{"boundary": "bottom", "component": "y"}],
            "micro": {"model": "dem", "tangent": "perturbation", "relax": False}}
    with pytest.raises(SceneError, match=r'\[micro\] tangent = "perturbation" with relax'):
        validate_problem(prob)
