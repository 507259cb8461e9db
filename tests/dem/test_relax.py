"""Relaxation with its checks inside the compiled loop: Simulation.relax and the RVE's
strain-controlled call, against the same checks made in Python between chunks."""

import numpy as np
import pytest

import dem
from dem import packings, rve
from dem.observers import Periodic
from dem.shapes import ConvexPolygon

LAW = dem.LinearSpring(kn=1e8, kt=5e7, mu=0.5)


@pytest.fixture(scope="module")
def packing():
    """60 disks at 100 kPa (frictionless consolidation, mu = 0.5 after)."""
    return rve.generate(2, 60, (0.8e-3, 1.2e-3), LAW, p0=1e5, friction=0.0, seed=5,
                        damping=0.5)


class _Counter:
    """An observer that fires every 13 steps: it splits the compiled chunks at steps
    that are not checks."""

    def __init__(self):
        self.trigger = Periodic(13)
        self.calls = 0

    def __call__(self, sim):
        self.calls += 1


def _state(sim):
    b = sim.bodies
    return [b.pos.copy(), b.vel.copy(), b.ang_vel.copy(), sim.pair_state.hist.copy()]


def _disturbed(packing, snap):
    """The packing out of balance: 3e-4 of axial strain imposed without relaxing."""
    packing.restore(snap)
    packing.apply_strain(np.diag([-3e-4, 0.0]), relax=False)
    return packing.snapshot()


def test_relax_stops_at_the_check_python_would_stop_at(packing):
    """relax() and a loop of run(every) with unbalanced_force() between give the
    same steps and the same state bit for bit, with an observer splitting the
    compiled chunks between checks."""
    snap = packing.snapshot()
    start = _disturbed(packing, snap)
    sim, tol, every = packing.sim, 1e-3, 7
    obs = _Counter()
    sim.observers.append(obs)
    try:
        packing.restore(start)
        s0 = sim.step
        out = sim.relax(tol, max_steps=100_000, every=every)
        relaxed = _state(sim)
        assert out.status == "relaxed" and out.steps == sim.step - s0 > 10 * every
        assert out.steps % every == 0 and out.checks == out.steps // every + 1
        assert out.unbalanced == sim.unbalanced_force() < tol
        assert out.contacts == packing.response(tangent=False)["n_contacts"]
        calls = obs.calls
        packing.restore(start)
        steps = 0
        while sim.unbalanced_force() >= tol:
            sim.run(every, progress=False)
            steps += every
        assert steps == out.steps and obs.calls == 2 * calls
        for a, b in zip(relaxed, _state(sim), strict=True):
            assert np.array_equal(a, b)
    finally:
        sim.observers.remove(obs)
        packing.restore(snap)


def test_unbalanced_force_is_the_rve_measure_bit_for_bit(packing):
    snap = packing.snapshot()
    _disturbed(packing, snap)
    ratio = packing.sim.unbalanced_force()
    assert ratio > packing.tol
    assert ratio == packing.response(tangent=False)["unbalanced"]
    packing.restore(snap)


def test_relax_ends_at_its_cap_or_when_the_packing_comes_apart(packing):
    snap = packing.snapshot()
    sim = packing.sim
    try:
        _disturbed(packing, snap)
        out = sim.relax(tol=0.0, max_steps=120, every=50)  # never below 0
        assert (out.status, out.steps, out.checks) == ("cap", 120, 3)
        assert out.unbalanced > 0.0
        out = sim.relax(tol=1e-3, max_steps=0)
        assert out.steps == 0 and out.checks == 1
        packing.restore(snap)
        packing.apply_strain(np.diag([2e-2, 2e-2]), relax=False)  # every contact opens
        out = sim.relax(1e-3, 10_000, every=20, min_coordination=1.0, apart_checks=3)
        assert (out.status, out.steps, out.contacts) == ("apart", 40, 0)  # checks 0, 20, 40
        assert out.unbalanced == np.inf
    finally:
        packing.restore(snap)


def test_relax_refuses_bad_arguments_and_shapes(packing):
    sim = packing.sim
    for kwargs, what in [({"every": 0}, "every >= 1"), ({"max_steps": -1}, "max_steps"),
                         ({"tol": -1.0}, "tol and min_coordination"),
                         ({"apart_checks": -2}, "apart_checks")]:
        with pytest.raises(ValueError, match=what):
            sim.relax(**kwargs)
    bodies = packings.shape_bodies(2, np.array([[0.0, 0.0], [3e-3, 0.0]]),
                                   np.array([1e-3, 1e-3]),
                                   lambda r, rng: ConvexPolygon.regular(5, r), 2650.0, 0)
    shapes = dem.Simulation(bodies, LAW)
    for call in (shapes.relax, shapes.unbalanced_force):
        with pytest.raises(ValueError, match="needs a scene of spheres or disks"):
            call()


@pytest.mark.parametrize("relax", [True, False])
def test_compiled_and_chunked_calls_agree_bit_for_bit(packing, relax):
    """A strain-controlled call runs its checks in the compiled loop; with a progress
    callback it steps in chunks with the checks in Python: the same steps, stress,
    tangent and state."""
    snap = packing.snapshot()
    deps = np.array([[-6e-4, 2e-4], [-1e-4, 2e-4]])
    reports = []
    try:
        s_fast, c_fast = packing.apply_strain(deps, relax=relax, tangent=True)
        fast = _state(packing.sim) + [packing.deformation.copy(), packing.last_relax_steps]
        packing.restore(snap)
        s_slow = packing.load(deps, relax=relax, progress=reports.append, tangent=True)
        slow = _state(packing.sim) + [packing.deformation.copy(), packing.last_relax_steps]
        assert reports and reports[-1] == packing.last_relax_steps
        assert np.array_equal(s_fast, s_slow)
        assert np.array_equal(c_fast, packing.tangent())
        for a, b in zip(fast, slow, strict=True):
            assert np.array_equal(a, b)
    finally:
        packing.restore(snap)


def test_both_drives_fail_alike(packing):
    """The step cap and a packing that comes apart end both drives with the same
    error at the same step."""
    snap = packing.snapshot()
    cases = [(np.diag([-1e-2, 0.0]), rve.RelaxationError, "did not relax within 10 steps",
              {"max_relax_steps": 10, "max_step_strain": 1e-3}),
             (np.diag([2e-2, 2e-2]), rve.PackingApart, "came apart", {})]
    try:
        for deps, kind, what, settings in cases:
            saved = {k: getattr(packing, k) for k in settings}
            for k, v in settings.items():
                setattr(packing, k, v)
            messages, steps = [], []
            for progress in (None, lambda s: None):
                packing.restore(snap)
                with pytest.raises(kind, match=what) as err:
                    packing.load(deps, progress=progress)
                messages.append(str(err.value))
                steps.append(packing.sim.step)
            for k, v in saved.items():
                setattr(packing, k, v)
            assert messages[0] == messages[1] and steps[0] == steps[1]
    finally:
        packing.restore(snap)
