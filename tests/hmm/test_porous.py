"""Biot's u-p solver (hmm.porous) against closed forms (hmm.poroelastic_solutions):
Terzaghi's consolidation on every stable pair, first-order convergence in time, the
first instant without oscillation, Mandel's problem and its Mandel-Cryer effect, a
steady Darcy flow through an anisotropic column."""

import numpy as np
import pytest

from hmm.coupling import SolverError, SolverSettings, Supports
from hmm.farm import SerialFarm
from hmm.macro import Macro, structured_mesh
from hmm.micro import LinearElastic
from hmm import poroelastic_solutions as exact
from hmm.porous import BiotSolver, Fluid, PorousMacro, TimeSchedule

E, NU, Q, H = 1e7, 0.25, 1e4, 1.0  # [Pa], [-], load [Pa], column height [m]
M_C = E * (1 - NU) / ((1 + NU) * (1 - 2 * NU))  # constrained modulus
CV = 1.0  # [m^2/s] consolidation coefficient (incompressible constituents)


MATERIAL = exact.BiotMaterial.from_young(E, NU, mobility=CV / M_C)


def terzaghi(depth, tv):
    """Pore pressure of Terzaghi's column at ``depth`` below the drained top."""
    return exact.terzaghi_pressure(depth, tv * H * H / CV, H, MATERIAL, Q)


def column(element="quad8", cells=16, bulk_modulus=np.inf):
    """A laterally confined column, drained at the top, loaded there at once."""
    mesh = structured_mesh(element, [0.1, H], [1, cells])
    macro = Macro(mesh, element, "small")
    fluid = Fluid(permeability=CV / M_C * 1e-3, viscosity=1e-3,
                  bulk_modulus=bulk_modulus)
    porous = PorousMacro(macro, fluid, drained={"top": 0.0})
    farm = SerialFarm([LinearElastic(E, NU, dim=2) for _ in range(macro.n_gp)])
    dofs = np.unique(np.concatenate([macro.dofs("bottom", 1), macro.dofs("left", 0),
                                     macro.dofs("right", 0)]))
    return porous, farm, Supports(dofs, np.zeros(dofs.size), ("bottom",)), \
        macro.pressure_force("top", Q)


def run(schedule, stop_at=(), **kw):
    """Solve the column over ``schedule``; the nodal pressures along x = 0 at the
    step ends in ``stop_at`` [s], with their depths."""
    porous, farm, sup, f = column(**kw)
    s = BiotSolver(porous, farm, sup, schedule, f_ramp=f,
                   settings=SolverSettings(aitken=False))
    x = porous.macro.mesh.p.T
    on = np.isclose(x[:, 0], 0.0)
    depth = H - x[on, 1]
    out = {}
    for t in schedule.times():
        s.advance(t - s.t)
        for want in stop_at:
            if np.isclose(s.t, want):
                out[want] = porous.nodal_pressure(s.p)[on]
    return s, depth, out


def test_terzaghi_isochrones_within_one_percent_of_the_load():
    tvs = (0.05, 0.2, 0.5, 1.0)
    _, depth, got = run(TimeSchedule(end=1.0, steps=400), stop_at=tvs)
    for tv in tvs:
        err = np.abs(got[tv] - terzaghi(depth, tv)).max() / Q
        assert err < 0.01, (tv, err)


def test_terzaghi_degree_of_consolidation_follows_the_settlement():
    s, _, _ = run(TimeSchedule(end=0.5, steps=200))
    settle = -s.u[s.macro.dofs("top", 1)].mean()
    assert settle == pytest.approx(
        exact.terzaghi_settlement(np.array([0.5]), H, MATERIAL, Q)[0], rel=5e-3)


def test_backward_euler_converges_at_first_order_in_time():
    errors = []
    for steps in (10, 20, 40):
        _, depth, got = run(TimeSchedule(end=0.2, steps=steps), stop_at=(0.2,),
                            cells=32)
        errors.append(np.abs(got[0.2] - terzaghi(depth, 0.2)).max())
    rates = np.log2(np.array(errors[:-1]) / errors[1:])
    assert np.all((rates > 0.8) & (rates < 1.3)), rates


@pytest.mark.parametrize("cells", [16, 32])
def test_first_step_at_the_vermeer_verruijt_bound_does_not_oscillate(cells):
    """A load applied at once: with a first step of h^2 / (6 c_v) (h the element
    size) the pressure rises monotonically from the drained top to the load it
    carries undrained (p = q, incompressible constituents), with no overshoot;
    below that bound it overshoots (the boundary layer is thinner than an
    element), which the solver warns about."""
    dt = (H / cells) ** 2 / (6.0 * CV)
    _, depth, got = run(TimeSchedule(end=dt, steps=1), stop_at=(dt,), cells=cells)
    p = got[dt][np.argsort(depth)]
    assert p[0] == 0.0
    assert np.all(np.diff(p) >= -1e-9 * Q)
    assert p.max() <= Q * (1 + 1e-9)
    assert p[-1] == pytest.approx(Q, rel=1e-9)
    _, depth, got = run(TimeSchedule(end=0.5 * dt, steps=1), stop_at=(0.5 * dt,),
                        cells=cells)
    assert got[0.5 * dt].max() > Q * 1.01


def test_a_first_step_below_the_bound_is_announced(caplog):
    porous, farm, sup, f = column(cells=16)
    dt = (H / 16) ** 2 / (6.0 * CV)
    s = BiotSolver(porous, farm, sup, TimeSchedule(end=0.5 * dt, steps=1), f_ramp=f)
    with caplog.at_level("WARNING", logger="hmm.porous"):
        s.advance(0.5 * dt)
    assert "Vermeer" in caplog.text and "oscillate" in caplog.text
    assert porous.oscillation_bound(farm_tangent(s)) == pytest.approx(dt, rel=1e-6)


def farm_tangent(solver):
    return solver.tangent


def test_compressible_fluid_takes_its_share_of_the_load():
    """Undrained with a compressible fluid: p0 = alpha M q / (M_c + alpha^2 M)."""
    kf, n = 2e7, 0.4
    m = kf / n
    _, depth, got = run(TimeSchedule(end=1e-6, steps=1), stop_at=(1e-6,),
                        bulk_modulus=kf)
    deep = got[1e-6][depth > 0.5 * H]
    assert deep == pytest.approx(m * Q / (M_C + m), rel=1e-4)


@pytest.mark.parametrize("element", ["quad1", "tri1"])
def test_equal_order_pairs_are_refused(element):
    macro = Macro(structured_mesh(element, [1.0, 1.0], [1, 1]), element, "small")
    with pytest.raises(ValueError, match="equal orders"):
        PorousMacro(macro, Fluid(permeability=1e-12))


@pytest.mark.parametrize("element,cells,steps,tol", [("tri2", [1, 16], 80, 0.01),
                                                     ("hex20", [1, 1, 6], 25, 0.02),
                                                     ("tet10", [1, 1, 6], 25, 0.02)])
def test_other_stable_pairs_consolidate_as_terzaghi(element, cells, steps, tol):
    d = len(cells)
    mesh = structured_mesh(element, [0.1] * (d - 1) + [H] if d == 3 else [0.1, H],
                           cells)
    top, bottom = ("back", "front") if d == 3 else ("top", "bottom")
    macro = Macro(mesh, element, "small")
    porous = PorousMacro(macro, Fluid(permeability=CV / M_C * 1e-3,
                                      bulk_modulus=np.inf), drained={top: 0.0})
    axis = d - 1  # the column's axis
    farm = SerialFarm([LinearElastic(E, NU, dim=d) for _ in range(macro.n_gp)])
    sides = [macro.dofs(b, c) for b, c in (("left", 0), ("right", 0))]
    if d == 3:
        sides += [macro.dofs(b, 1) for b in ("bottom", "top")]
    dofs = np.unique(np.concatenate([macro.dofs(bottom, axis), *sides]))
    s = BiotSolver(porous, farm, Supports(dofs, np.zeros(dofs.size), (bottom,)),
                   TimeSchedule(end=0.2, steps=steps),
                   f_ramp=macro.pressure_force(top, Q),
                   settings=SolverSettings(aitken=False))
    for t in s.schedule.times():
        s.advance(t - s.t)
    depth = H - porous.macro.mesh.p[axis]
    err = np.abs(porous.nodal_pressure(s.p) - terzaghi(depth, 0.2)).max() / Q
    assert err < tol


def test_inflow_through_an_anisotropic_column_reaches_darcy():
    """Steady state: an inflow qbar at the base, drained top: p = qbar (H - y) /
    kappa_yy, whatever kappa_xx."""
    porous, farm, sup, _ = column(cells=8)
    macro = porous.macro
    kappa_yy = CV / M_C
    fluid = Fluid(permeability=np.diag([7.0, 1.0]) * kappa_yy * 1e-3,
                  bulk_modulus=np.inf)
    qbar = 1e-6
    porous = PorousMacro(macro, fluid, drained={"top": 0.0}, inflow={"bottom": qbar})
    s = BiotSolver(porous, farm, sup, TimeSchedule(end=10.0, steps=40, first=0.01),
                   settings=SolverSettings(aitken=False))
    for t in s.schedule.times():
        s.advance(t - s.t)
    y = macro.mesh.p[1]
    assert porous.nodal_pressure(s.p) == pytest.approx(qbar * (H - y) / kappa_yy,
                                                       rel=1e-6, abs=1e-9 * Q)
    assert porous.darcy_flux(s.p)[:, 1] == pytest.approx(qbar, rel=1e-6)


def test_mandel_cryer_effect_at_the_centre_within_two_percent():
    """Mandel's problem on a quarter: rigid frictionless plates (a tied top, force
    F on it), drained traction-free sides. The centre's pressure first rises above
    its undrained value p0, then dissipates; the solution follows the closed form
    within 2 % of p0 over the whole history, and the plate's settlement too."""
    a, b, force, kf, n = 1.0, 0.5, 1e4, 4e7, 0.4
    mesh = structured_mesh("quad8", [a, b], [16, 2])
    macro = Macro(mesh, "quad8", "small")
    fluid = Fluid(permeability=1e-10, bulk_modulus=kf, porosity=n)
    porous = PorousMacro(macro, fluid, drained={"right": 0.0})
    mat = exact.BiotMaterial.from_young(E, NU, storage_modulus=1.0 / fluid.storage,
                                        mobility=1e-7)
    end = a * a / mat.consolidation_coefficient_mandel
    dofs = np.unique(np.concatenate([macro.dofs("left", 0), macro.dofs("bottom", 1)]))
    top = macro.dofs("top", 1)
    s = BiotSolver(porous, SerialFarm([LinearElastic(E, NU) for _ in range(macro.n_gp)]),
                   Supports(dofs, np.zeros(dofs.size), ("bottom",), ties=(top,)),
                   TimeSchedule(end=end, steps=100, first=1e-3 * end),
                   f_ramp=macro.pressure_force("top", force / a),
                   settings=SolverSettings(aitken=False))
    p0 = exact.mandel_initial_pressure(a, force, mat)
    centre = int(np.flatnonzero(np.isclose(mesh.p[0], 0) & np.isclose(mesh.p[1], 0))[0])
    got, want = [], []
    for t in s.schedule.times():
        s.advance(t - s.t)
        got.append(porous.nodal_pressure(s.p)[centre] / p0)
        want.append(exact.mandel_pressure(np.zeros(1), s.t, a, force, mat)[0] / p0)
    assert np.abs(np.array(got) - want).max() < 0.02
    assert max(got) == pytest.approx(exact.mandel_cryer_peak(a, force, mat), abs=0.02)
    assert max(got) > 1.05  # the rise above p0 is resolved, not noise
    assert np.ptp(s.u[top]) == 0.0  # the plate is rigid
    assert s.u[top][0] == pytest.approx(
        exact.mandel_displacement_top(np.array([s.t]), a, b, force, mat)[0], rel=0.01)


def test_fixed_stress_split_reaches_the_monolithic_answer():
    """The split converges to the same pressures (to its tolerance), in more
    iterations: a linear micro model takes one monolithic iteration per step."""
    tight = SolverSettings(tol_residual=1e-8, tol_displacement=1e-8, max_iterations=60)
    out = {}
    for coupling in ("monolithic", "fixed_stress"):
        porous, farm, sup, f = column(cells=8)
        s = BiotSolver(porous, farm, sup, TimeSchedule(end=0.1, steps=5), f_ramp=f,
                       settings=tight, coupling=coupling)
        for t in s.schedule.times():
            s.advance(t - s.t)
        out[coupling] = s
    mono, split = out["monolithic"], out["fixed_stress"]
    assert split.p == pytest.approx(mono.p, rel=1e-6, abs=1e-6 * Q)
    assert mono.iterations == [1] * 5 and min(split.iterations) > 2
    with pytest.raises(ValueError, match="coupling must be"):
        BiotSolver(*column()[:3], TimeSchedule(end=1.0, steps=1), coupling="staggered")


class _NanStress(LinearElastic):
    def trial(self, deps):
        sig, c = super().trial(deps)
        return sig * np.nan, c


@pytest.mark.parametrize("model,bound,message", [
    (LinearElastic, 1.0, r"pore pressure .* Pa is beyond 1 Pa"),
    (_NanStress, None, "non-finite")])
def test_a_diverging_pressure_stops_the_run_at_the_last_converged_step(model, bound,
                                                                        message):
    """A pore pressure beyond the solver's bound (here lowered to 1 Pa to trip it) or
    a micro model answering NaN: every cut fails, the solver stops with the reason
    and keeps the last converged state."""
    porous, _, sup, f = column(cells=4)
    farm = SerialFarm([model(E, NU) for _ in range(porous.macro.n_gp)])
    s = BiotSolver(porous, farm, sup, TimeSchedule(end=1.0, steps=4), f_ramp=f,
                   settings=SolverSettings(max_iterations=8, min_step=0.25))
    assert s.pressure_bound > 100 * Q  # by default far above what the load makes
    if bound is not None:
        s.pressure_bound = bound
    with pytest.raises(SolverError, match=message):
        s.advance(0.25)
    assert s.t == 0.0 and np.all(s.p == 0.0) and np.all(s.u == 0.0)


def test_kozeny_carman_permeability_follows_the_compaction():
    """A column compacted by 2 % (a prescribed top displacement), an inflow at its
    base: the steady pressure gradient is the flux over the permeability of the
    compacted porosity, k_0 [n^3 / (1 - n)^2] / [n_0^3 / (1 - n_0)^2] with
    n = 1 - (1 - n_0) / (1 - 0.02)."""
    porous, farm, _, _ = column(cells=8)
    macro = porous.macro
    n0, qbar, strain = 0.4, 1e-6, 0.02
    fluid = Fluid(permeability=CV / M_C * 1e-3, bulk_modulus=np.inf, porosity=n0,
                  permeability_law="kozeny_carman")
    porous = PorousMacro(macro, fluid, drained={"top": 0.0}, inflow={"bottom": qbar})
    top = macro.dofs("top", 1)
    dofs = np.unique(np.concatenate([macro.dofs("bottom", 1), macro.dofs("left", 0),
                                     macro.dofs("right", 0), top]))
    values = np.where(np.isin(dofs, top), -strain * H, 0.0)
    s = BiotSolver(porous, farm, Supports(dofs, values), TimeSchedule(end=20.0, steps=40,
                                                                      first=0.01),
                   settings=SolverSettings(aitken=False))
    for t in s.schedule.times():
        s.advance(t - s.t)
    n = 1.0 - (1.0 - n0) / (1.0 - strain)
    ratio = (n**3 / (1 - n) ** 2) / (n0**3 / (1 - n0) ** 2)
    # to 1e-4: the seepage force compacts the base a little more than the top
    assert porous.permeability_ratio(s.u) == pytest.approx(ratio, rel=1e-4)
    y = macro.mesh.p[1]
    assert porous.nodal_pressure(s.p) == pytest.approx(
        qbar * (H - y) / (CV / M_C * ratio), rel=1e-4, abs=1e-9 * Q)
    assert porous.darcy_flux(s.p, s.u)[:, 1] == pytest.approx(qbar, rel=1e-6)
    with pytest.raises(ValueError, match="permeability_law must be"):
        Fluid(permeability=1e-12, permeability_law="cubic")
