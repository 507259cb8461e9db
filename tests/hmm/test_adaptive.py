"""The adaptive micro model at its two limits: the hand-over of the strain it owes the
RVE, and a farm that never leaves the elastic range under the macro solver."""

import numpy as np
import pytest

import dem
from dem import rve as rvemod
from hmm.coupling import Solver, Supports
from hmm.farm import SerialFarm
from hmm.macro import Macro, structured_mesh
from hmm.micro import Adaptive, DEMMicroModel
from hmm.problem_build import clone_rve


@pytest.fixture(scope="module")
def packing():
    law = dem.LinearSpring(kn=1e8, kt=5e7, mu=0.5)
    return rvemod.generate(2, 30, (0.8e-3, 1.2e-3), law, p0=1e5, friction=0.0, seed=3)


def test_the_switch_hands_the_rve_all_the_strain_it_owes(packing):
    """Two elastic steps, then a trial outside the range: the RVE takes the three
    increments at once and ends where a DEM point given their sum in one trial does,
    bit for bit (no strain is lost or counted twice at the switch)."""
    steps = [np.diag([-2e-5, 1e-5]), np.array([[-3e-5, 1e-5], [1e-5, 0.0]]),
             np.diag([-4e-4, 1e-4])]
    m = Adaptive(DEMMicroModel(clone_rve(packing)), strain_threshold=1e-4,
                 ratio_threshold=1e6)
    for deps in steps[:2]:
        m.trial(deps)
        m.commit()
    assert not m.ran_dem
    s, c = m.trial(steps[2])
    m.commit()
    assert m.ran_dem
    alone = DEMMicroModel(clone_rve(packing))
    s_alone, c_alone = alone.trial(sum(steps))
    assert np.array_equal(s, s_alone) and np.array_equal(c, c_alone)


def test_a_farm_that_stays_elastic_is_a_linear_body(packing):
    """Thresholds out of reach: no DEM step is ever taken, every load step converges
    in one Newton iteration (the points answer linearly with their constant contact
    tangent, which the predictor already uses), and the reaction grows linearly with
    the prescribed displacement. The loads that hold the RVEs' initial stress are its
    own internal force, so the start is in equilibrium."""
    macro = Macro(structured_mesh("quad1", [0.02, 0.04], [1, 2]), "quad1")
    farm = SerialFarm([Adaptive(DEMMicroModel(clone_rve(packing)), 1e6, 1e6)
                       for _ in range(macro.n_gp)])
    rough = [macro.dofs(b, c) for b, c in (("bottom", 0), ("bottom", 1), ("top", 0))]
    top = macro.dofs("top", 1)
    dofs, first = np.unique(np.concatenate(rough + [top]), return_index=True)
    vals = np.concatenate([np.zeros(sum(k.size for k in rough)),
                           np.full(top.size, -2e-4)])
    solver = Solver(macro, farm, Supports(dofs, vals[first], ("top",)),
                    f_const=macro.internal_force(farm.stress()))
    reactions = []
    for _ in range(3):
        solver.advance(1.0 / 3.0)
        assert not farm.steps.any()
        reactions.append(solver.reactions()["top"])
    assert solver.iterations == [1, 1, 1]
    assert reactions[0][1] < 0.0  # the top support pushes the body down
    scale = np.abs(reactions[0]).max()
    for k, r in enumerate(reactions, start=1):
        assert np.allclose(r, k * reactions[0], rtol=0.0, atol=1e-9 * scale)
    eps = macro.strain(solver.u)
    assert np.ptp(eps[:, 0, 0]) > 0.05 * np.abs(eps[:, 1, 1]).max()  # not homogeneous
