"""The extrapolated predictor ([solver] predictor = "extrapolated"): a load step's first
guess from the last converged step, against the committed tangents'."""

import numpy as np
import pytest

from hmm.coupling import Solver, SolverSettings, Supports
from hmm.farm import SerialFarm
from hmm.macro import Macro, structured_mesh
from hmm.micro import Hyperbolic, isotropic_tangent

E, NU = 1e6, 0.3


class _ElasticTangent(Hyperbolic):
    """A softening law that answers with its initial, elastic tangent, as the contact
    tangent of a DEM RVE is stiffer than the packing once contacts slide."""

    def trial(self, deps):
        sig, _ = super().trial(deps)
        return sig, isotropic_tangent(2, E / (3.0 * (1.0 - 2.0 * NU)), E / (2.0 * (1.0 + NU)))


def _footing(model, settings, steps=16):
    """A rigid footing on half the top of a 1 m square of quad8, pushed 2 cm."""
    macro = Macro(structured_mesh("quad8", [1.0, 1.0], [4, 4]), "quad8")
    x = macro.basis.doflocs
    base = np.concatenate([macro.dofs("bottom", 0), macro.dofs("bottom", 1)])
    top = macro.dofs("top", 1)
    foot = top[x[0, top] <= 0.5]
    sup = Supports(np.concatenate([base, foot]),
                   np.concatenate([np.zeros(base.size), np.full(foot.size, -0.02)]), ("top",))
    solver = Solver(macro, SerialFarm([model(E, NU, 2e-3) for _ in range(macro.n_gp)]),
                    sup, settings=settings)
    for _ in range(steps):
        solver.advance(1.0 / steps)
    return solver, float(solver.reactions()["top"][1])


def test_the_extrapolated_guess_saves_iterations_of_a_stiff_tangent():
    """With a tangent stiffer than the material, each Newton correction undershoots;
    the last step's displacements, scaled, start near the answer: under a quarter of
    the iterations, and the footing's load within 0.2 % of the answer of an exact
    tangent at a tight tolerance, as the tangent predictor's is."""
    _, exact = _footing(Hyperbolic, SolverSettings(tol_residual=1e-10, tol_displacement=1e-10))
    loads, its = {}, {}
    for pred in ("tangent", "extrapolated"):
        st = SolverSettings(tol_residual=1e-3, tol_displacement=1e-3, check_residual=False,
                            max_iterations=60, predictor=pred)
        solver, loads[pred] = _footing(_ElasticTangent, st)
        its[pred] = sum(solver.iterations)
        assert solver.cuts == 0
    assert its["extrapolated"] < 0.25 * its["tangent"]
    for pred, load in loads.items():
        assert load == pytest.approx(exact, rel=2e-3), pred


def test_the_predictor_is_checked():
    with pytest.raises(ValueError, match="predictor must be one of tangent, extrapolated"):
        SolverSettings(predictor="secant")
