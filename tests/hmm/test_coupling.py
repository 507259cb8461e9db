"""The macro solver: analytic patch tests on every element, Newton's convergence rate,
initial stress in equilibrium, step cutting and its limit."""

import itertools

import numpy as np
import pytest

from dem.rve import RelaxationError
from hmm.coupling import Solver, SolverError, SolverSettings, Supports
from hmm.farm import MicroFailure, SerialFarm
from hmm.macro import Macro, structured_mesh
from hmm.micro import Hyperbolic, LinearElastic, MicroModel

E, NU = 1e6, 0.3


def _rollers(macro, shorten):
    """Smooth supports on the low faces, the top face moved down by ``shorten``."""
    d = macro.dim
    dofs, vals = [], []
    for name, c in (("left", 0), ("bottom", 1), ("front", 2))[:d]:
        k = macro.dofs(name, c)
        dofs.append(k)
        vals.append(np.zeros(k.size))
    top = macro.dofs("top", 1)
    dofs.append(top)
    vals.append(np.full(top.size, -shorten))
    dofs, first = np.unique(np.concatenate(dofs), return_index=True)
    return Supports(dofs, np.concatenate(vals)[first], ("top",))


@pytest.mark.parametrize("element",
                         ["quad1", "quad2", "quad8", "tri1", "tri2", "hex1", "tet1"])
def test_uniaxial_compression_is_exact_on_every_element(element):
    """Rollers on the low faces, the top pushed down: a uniform strain field that every
    element represents exactly; the stress and the reaction are analytic (plane strain
    in 2D: sigma_yy = E eps / (1 - nu^2); 3D with free sides: sigma_yy = E eps)."""
    d = 2 if element in ("quad1", "quad2", "quad8", "tri1", "tri2") else 3
    size = [1.0, 2.0, 1.5][:d]
    macro = Macro(structured_mesh(element, size, [2, 3, 2][:d]), element)
    farm = SerialFarm([LinearElastic(E, NU, d) for _ in range(macro.n_gp)])
    solver = Solver(macro, farm, _rollers(macro, 0.02))
    solver.advance(1.0)
    eps = -0.02 / size[1]
    want = E * eps / (1 - NU**2) if d == 2 else E * eps
    assert solver.iterations == [1]  # linear: the predictor is the answer
    assert np.allclose(solver.sigma[:, 1, 1], want, rtol=1e-10)
    area = np.prod(size) / size[1]
    assert solver.reactions()["top"][1] == pytest.approx(want * area, rel=1e-10)


def test_quad8_is_the_serendipity_element_with_2x2_gauss_points():
    """8 nodes (16 dofs) and 4 Gauss points per element, the element of YADE's FEMxDEM;
    it still represents a quadratic displacement exactly (its strain is linear)."""
    macro = Macro(structured_mesh("quad8", [1.0, 2.0], [2, 4]), "quad8")
    assert (macro.n_elems, macro.n_qp, macro.n_gp) == (8, 4, 32)
    assert macro.basis.element_dofs.shape[0] == 16
    x, y = macro.basis.doflocs
    u = np.where(np.arange(macro.n_dofs) % 2 == 0, x * y, y**2)  # (xy, y^2)
    gp = macro.gauss_points()
    eps = macro.strain(u)
    assert np.allclose(eps[:, 0, 0], gp[:, 1])
    assert np.allclose(eps[:, 1, 1], 2.0 * gp[:, 1])
    assert np.allclose(eps[:, 0, 1], 0.5 * gp[:, 0])


def test_newton_converges_quadratically_with_a_consistent_tangent():
    macro = Macro(structured_mesh("quad1", [1.0, 2.0], [2, 3]), "quad1")
    farm = SerialFarm([Hyperbolic(E, NU, 1e-3) for _ in range(macro.n_gp)])
    tight = SolverSettings(tol_residual=1e-13, tol_displacement=1e-13)
    solver = Solver(macro, farm, _rollers(macro, 0.01), settings=tight)
    res = []
    solver.advance(1.0, on_iteration=lambda it, r, d: res.append(r))
    assert res[-1] < 1e-13 and len(res) <= 7
    # quadratic: each residual below a constant times the square of the last (until
    # round-off)
    for a, b in itertools.pairwise(res[1:]):
        assert b < 10.0 * a * a or b < 1e-14


def test_confined_initial_state_is_in_equilibrium():
    """A pressure p0 on the free faces balances an initial stress -p0 I: a load step
    with nothing else moves nothing."""
    p0 = 1e5
    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [2, 2]), "quad1")
    farm = SerialFarm([LinearElastic(E, NU, 2, stress0=-p0) for _ in range(macro.n_gp)])
    f = macro.pressure_force("right", p0) + macro.pressure_force("top", p0)
    solver = Solver(macro, farm, _rollers(macro, 0.0), f_const=f)
    solver.advance(1.0)
    assert np.abs(solver.u).max() < 1e-15
    assert np.allclose(solver.sigma, -p0 * np.eye(2))


class _Brittle(MicroModel):
    """Linear elastic, but fails on strain increments larger than ``limit``."""

    def __init__(self, limit):
        self.inner = LinearElastic(E, NU, 2)
        self.limit = limit
        self.stress = self.inner.stress

    def trial(self, deps):
        if np.abs(deps).max() > self.limit:
            raise RelaxationError(f"increment {np.abs(deps).max():.3g} too large")
        return self.inner.trial(deps)

    def commit(self):
        self.inner.commit()
        self.stress = self.inner.stress

    def rollback(self):
        self.inner.rollback()


def test_a_failing_micro_model_cuts_the_step_until_it_passes():
    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [1, 1]), "quad1")
    farm = SerialFarm([_Brittle(3e-3) for _ in range(macro.n_gp)])
    solver = Solver(macro, farm, _rollers(macro, 0.01))
    solver.advance(1.0)  # eps = 1e-2 > 3e-3: cut to 1/4 (2.5e-3), then steps of that
    assert solver.t == pytest.approx(1.0)
    assert solver.cuts == 4  # 1 -> 1/2 -> 1/4, then each regrowth to 1/2 fails once
    assert solver.sigma[0, 1, 1] == pytest.approx(E * -0.01 / (1 - NU**2), rel=1e-10)


def test_step_cutting_stops_at_the_minimum_with_the_point_named():
    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [1, 1]), "quad1")
    farm = SerialFarm([_Brittle(1e-9) for _ in range(macro.n_gp)])
    solver = Solver(macro, farm, _rollers(macro, 0.01),
                    settings=SolverSettings(min_step=0.1))
    with pytest.raises(SolverError, match=r"Gauss point 0: RelaxationError: increment"):
        solver.advance(1.0)
    assert solver.t == 0.0 and np.all(solver.u == 0.0)  # nothing committed
    assert solver.cuts == 4  # 1 -> 1/2 -> ... -> 1/16 < 0.1: stop


class _Noisy(LinearElastic):
    """Linear elastic plus a stress jitter of relative size ``noise`` that changes at
    every trial (deterministic), as a small RVE's slips do."""

    def __init__(self, noise, seed):
        super().__init__(E, NU, 2)
        self.noise = noise
        self.rng = np.random.default_rng(seed)

    def trial(self, deps):
        sig, c = super().trial(deps)
        jitter = self.rng.uniform(-1.0, 1.0, sig.shape)
        return sig + self.noise * np.abs(sig).max() * 0.5 * (jitter + jitter.T), c


def test_a_residual_at_the_micro_noise_floor_converges_on_the_correction_alone():
    """Stresses that jitter by 1 % keep the residual near 1 % of the internal force
    however small the step: the residual check cuts down to the minimum step and
    stops; the correction alone (FEMxDEM's criterion) converges, within the noise of
    the exact answer."""
    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [2, 2]), "quad1")

    def solver(check):
        farm = SerialFarm([_Noisy(1e-2, g) for g in range(macro.n_gp)])
        st = SolverSettings(tol_residual=1e-3, tol_displacement=1e-2, min_step=1 / 8,
                            check_residual=check)
        return Solver(macro, farm, _rollers(macro, 0.01), settings=st)

    with pytest.raises(SolverError, match="did not converge even at the minimum step"):
        solver(True).advance(1.0)
    s = solver(False)
    s.advance(1.0)
    assert s.t == 1.0
    want = E * -0.01 / (1 - NU**2)
    assert np.allclose(s.sigma[:, 1, 1], want, rtol=0.03)


class _Jitter(LinearElastic):
    """Confined linear elastic plus a jitter of ``amplitude`` [Pa] at every trial,
    whatever the increment: a relaxed RVE's noise, the same over a tiny step."""

    def __init__(self, amplitude, seed, p0):
        super().__init__(E, NU, 2, stress0=-p0)
        self.amplitude = amplitude
        self.rng = np.random.default_rng(seed)

    def trial(self, deps):
        sig, c = super().trial(deps)
        jitter = self.rng.uniform(-1.0, 1.0, sig.shape)
        return sig + self.amplitude * 0.5 * (jitter + jitter.T), c


def test_a_small_step_in_equilibrium_converges_without_the_residual_check():
    """Under 100 kPa of confinement, a step that adds 11 Pa of axial stress with
    10 Pa of noise: every correction is a large part of the step's displacement, so
    the correction criterion alone never passes, but the residual is 1e-4 of the
    internal force from the first iteration and ends the step."""
    p0 = 1e5
    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [2, 2]), "quad1")
    farm = SerialFarm([_Jitter(10.0, g, p0) for g in range(macro.n_gp)])
    f = macro.pressure_force("right", p0) + macro.pressure_force("top", p0)
    sup = _rollers(macro, 1e-5)
    st = SolverSettings(tol_residual=1e-2, tol_displacement=1e-2, check_residual=False,
                        max_iterations=5, min_step=1.0)
    steps = []
    s = Solver(macro, farm, sup, f_const=f, settings=st)
    s.advance(1.0, on_iteration=lambda it, r, d: steps.append((r, d)))
    assert s.t == 1.0 and s.iterations == [1]
    r, d = steps[0]
    assert r < 1e-3 and d > 1e-2  # in equilibrium, though the correction is not small
    assert np.allclose(s.sigma[:, 1, 1], -p0 - 11.0, atol=30.0)


class _BrittleJitter(LinearElastic):
    """Linear elastic with a jitter of ``amplitude`` [Pa] at every trial; fails
    (recoverably) on strain increments larger than ``limit``."""

    def __init__(self, amplitude, limit, seed):
        super().__init__(E, NU, 2)
        self.amplitude, self.limit = amplitude, limit
        self.rng = np.random.default_rng(seed)

    def trial(self, deps):
        if np.abs(deps).max() > self.limit:
            raise RelaxationError(f"increment {np.abs(deps).max():.3g} too large")
        sig, c = super().trial(deps)
        jitter = self.rng.uniform(-1.0, 1.0, sig.shape)
        return sig + self.amplitude * 0.5 * (jitter + jitter.T), c


def test_a_cut_step_is_judged_at_the_size_of_the_nominal_step():
    """Without the residual check, the correction is measured against the step's
    displacement scaled to the nominal step: the micro noise in a correction does
    not shrink with a cut. Steps of 1 % shortening fail and are cut to quarters; with
    a jitter of 2 % of the full step's stress, a quarter's first correction is 0.3 to
    0.7 % of the nominal step's displacement and it converges at once; the same
    quarters asked for as nominal steps see corrections of 1.2 to 3.4 % of theirs
    and stop at the minimum step."""
    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [2, 2]), "quad1")
    full = E * 0.01 / (1 - NU**2)  # axial stress of the nominal step [Pa]

    def solver(shorten, limit):
        farm = SerialFarm([_BrittleJitter(2e-2 * full, limit, g)
                           for g in range(macro.n_gp)])
        st = SolverSettings(tol_residual=1e-6, tol_displacement=1e-2, min_step=1 / 8,
                            check_residual=False, max_iterations=8)
        return Solver(macro, farm, _rollers(macro, shorten), settings=st)

    cut = solver(0.01, limit=0.3 * 0.01)  # a half step of 0.5 % strain fails too
    cut.advance(1.0)
    assert cut.t == pytest.approx(1.0) and cut.cuts >= 2
    assert cut.iterations == [1, 1, 1, 1]  # four quarters
    # within the jitter (2 %) and the noise of the corrections accepted with it
    assert np.allclose(cut.sigma[:, 1, 1], -full, rtol=4e-2)
    quarters = solver(0.0025, limit=np.inf)
    with pytest.raises(SolverError, match="did not converge even at the minimum step"):
        quarters.advance(1.0)


class _Buggy(LinearElastic):
    def trial(self, deps):
        if deps.any():
            raise KeyError("a bug")
        return super().trial(deps)


def test_a_micro_model_bug_stops_the_run_without_cutting():
    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [1, 1]), "quad1")
    farm = SerialFarm([_Buggy(E, NU, 2) for _ in range(macro.n_gp)])
    solver = Solver(macro, farm, _rollers(macro, 0.01))
    with pytest.raises(SolverError, match=r"stopped: Gauss point 0: KeyError"):
        solver.advance(1.0)
    assert solver.cuts == 0


def test_farm_names_the_failing_point():
    farm = SerialFarm([LinearElastic(E, NU, 2), _Brittle(0.0)])
    with pytest.raises(MicroFailure, match="Gauss point 1") as err:
        farm.trial(np.full((2, 2, 2), 1e-3))
    assert err.value.point == 1 and err.value.recoverable


def test_body_force_reaction_is_the_weight():
    macro = Macro(structured_mesh("quad1", [1.0, 2.0], [2, 4]), "quad1")
    farm = SerialFarm([LinearElastic(E, NU, 2) for _ in range(macro.n_gp)])
    sup = _rollers(macro, 0.0)
    sup = Supports(sup.dofs, sup.values, ("bottom",))
    gamma = 2e4  # N/m^3, downwards
    solver = Solver(macro, farm, Supports(np.setdiff1d(sup.dofs, macro.dofs("top", 1)),
                                          np.zeros(np.setdiff1d(
                                              sup.dofs, macro.dofs("top", 1)).size),
                                          ("bottom",)),
                    f_ramp=macro.body_force([0.0, -gamma]))
    solver.advance(1.0)
    # the support holds the column up: the reaction on the body is the weight, upwards
    assert solver.reactions()["bottom"][1] == pytest.approx(gamma * 2.0, rel=1e-10)


def test_one_element_under_homogeneous_strain_follows_the_standalone_rve():
    """Rollers on two faces, the other two moved: every Gauss point sees the same
    strain, and its stress path is that of the standalone RVE given the same
    increments (same packing), to round-off."""
    import dem
    from dem import rve as rvemod
    from hmm.micro import DEMMicroModel
    from hmm.problem_build import clone_rve

    law = dem.LinearSpring(kn=1e8, kt=5e7, mu=0.5)
    packing = rvemod.generate(2, 30, (0.8e-3, 1.2e-3), law, p0=1e5, friction=0.0, seed=4)
    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [1, 1]), "quad1")
    farm = SerialFarm([DEMMicroModel(clone_rve(packing)) for _ in range(macro.n_gp)])
    dofs = np.concatenate([macro.dofs(b, c) for b, c in
                           (("left", 0), ("bottom", 1), ("right", 0), ("top", 1))])
    vals = np.concatenate([np.zeros(macro.dofs("left", 0).size),
                           np.zeros(macro.dofs("bottom", 1).size),
                           np.full(macro.dofs("right", 0).size, 4e-4),
                           np.full(macro.dofs("top", 1).size, -8e-4)])
    solver = Solver(macro, farm, Supports(dofs, vals, ("top",)))
    alone = clone_rve(packing)
    for k in (1, 2):
        solver.advance(0.5)
        s_alone = alone.apply_strain(np.diag([2e-4, -4e-4]))
        assert np.allclose(macro.strain(solver.u), np.diag([4e-4, -8e-4]) * k / 2,
                           rtol=1e-12, atol=1e-18)
        for g in range(macro.n_gp):
            assert np.array_equal(solver.sigma[g], s_alone)
