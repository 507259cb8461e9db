"""Finite kinematics (updated Lagrangian): the Newton matrix is the derivative of the
residual, a rigid rotation turns the stress exactly, objective laws against closed
forms, a patch test on a distorted mesh, one element against a standalone RVE, and
what happens when an element inverts."""

import math

import numpy as np
import pytest
from skfem import Basis, BilinearForm, FacetBasis, asm
from skfem.helpers import ddot, dot, mul, sym_grad, trace

import dem
from dem import rve as rvemod
from dem.io.schema import SceneError
from dem.observers import elastic_energy
from hmm.coupling import Solver, SolverError, SolverSettings, Supports
from hmm.farm import SerialFarm
from hmm.loads import CurrentBodyForce, CurrentTraction, FollowerPressure
from hmm.macro import Macro, _inverse_and_det, structured_mesh
from hmm.micro import DEMMicroModel, Hypoelastic, LinearElastic, NeoHookean
from hmm.problem import validate_problem
from hmm.problem_build import clone_rve
from hmm.tensors import log_strain, spatial_tangent

E, NU = 1e6, 0.3


def _turn(theta):
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def _all_nodes(macro, path):
    """Supports holding every degree of freedom on ``x = path(t) X``: a homogeneous
    deformation prescribed along the schedule."""
    x0 = macro.basis.doflocs  # (d, n_dofs): the position each dof belongs to
    comp = np.zeros(macro.n_dofs, int)
    for c in range(macro.dim):
        comp[macro.basis.nodal_dofs[c]] = c
        if macro.basis.facet_dofs.size:
            comp[macro.basis.facet_dofs[c]] = c
        if macro.basis.interior_dofs.size:
            comp[macro.basis.interior_dofs[c]] = c
        if macro.dim == 3 and macro.basis.edge_dofs.size:
            comp[macro.basis.edge_dofs[c]] = c
    dofs = np.arange(macro.n_dofs)

    def values(t):
        f = path(t)
        x = f @ x0[:, dofs]
        return (x - x0[:, dofs])[comp, dofs]

    return Supports(dofs, values(1.0), ("top",), path=values)


def _solve(macro, models, supports, steps, settings=None, loads=()):
    solver = Solver(macro, SerialFarm(models), supports, settings=settings, loads=loads)
    for _ in range(steps):
        solver.advance(1.0 / steps)
    return solver


# --------------------------------------------------------------------------- the tangent
@pytest.mark.parametrize("element", ["quad1", "quad8", "tri2"])
def test_newton_matrix_is_the_derivative_of_the_residual(element):
    """Internal force with a neo-Hookean law, a follower pressure, a traction per
    current area and a body force per current volume: each stiffness equals the
    central difference of its force over every degree of freedom."""
    macro = Macro(structured_mesh(element, [1.0, 1.0], [2, 2]), element, "finite")
    u = 0.02 * np.random.default_rng(1).standard_normal(macro.n_dofs)
    zero = np.zeros(macro.n_dofs)

    def internal(v):
        farm = SerialFarm([NeoHookean(E, NU) for _ in range(macro.n_gp)])
        sig, c = farm.trial(macro.increment_gradient(zero, v))
        return macro.internal_force(sig, v), macro.stiffness(c, v, sig)

    terms = [(lambda v: internal(v)[0], internal(u)[1]),
             (lambda v: macro.pressure_force("top", 1e5, v),
              macro.pressure_stiffness("top", 1e5, u)),
             (lambda v: macro.traction_force("right", [1e4, -2e4], v),
              macro.traction_stiffness("right", [1e4, -2e4], u)),
             (lambda v: macro.body_force([1e4, -2e4], v),
              macro.body_force_stiffness([1e4, -2e4], u))]
    h = 1e-6
    for force, k in terms:
        k = k.toarray()
        fd = np.empty_like(k)
        for j in range(macro.n_dofs):
            e = np.zeros(macro.n_dofs)
            e[j] = h
            fd[:, j] = (force(u + e) - force(u - e)) / (2.0 * h)
        assert np.abs(k - fd).max() <= 1e-8 * np.abs(k).max()


@BilinearForm
def _reference_stiffness(u, v, w):
    return ddot(sym_grad(v), np.einsum("ijkl...,kl...->ij...", w.C, sym_grad(u)))


@BilinearForm
def _reference_stiffness_finite(u, v, w):
    gu = mul(u.grad, w.Finv)
    return ddot(mul(v.grad, w.Finv), np.einsum("ijkl...,kl...->ij...", w.A, gu)) * w.J


@BilinearForm
def _reference_pressure_stiffness(u, v, w):
    g = mul(u.grad, w.Finv)  # d(n da) = (tr g I - g^T) n da, g = grad_x du
    return -w.p * (trace(g) * dot(w.m, v) - dot(np.einsum("ji...,j...->i...", g, w.m), v))


@pytest.mark.parametrize("element, cells", [("quad8", [2, 2]), ("hex20", [1, 2, 1]),
                                            ("tet10", [1, 1, 1]), ("hex1", [2, 1, 1])])
def test_the_newton_matrix_equals_skfem_bilinear_forms(element, cells):
    """The Newton matrix and the follower pressure's load stiffness, assembled as array
    products over all elements at once, equal skfem's BilinearForm assembly of the
    same weak forms to round-off, for a random tangent (no symmetries), stresses and
    deformation, small and finite."""
    rng = np.random.default_rng(7)
    for kinematics in ("small", "finite"):
        macro = Macro(structured_mesh(element, [1.0] * len(cells), cells), element,
                      kinematics)
        d = macro.dim
        c = rng.standard_normal((macro.n_gp, d, d, d, d))
        sig = rng.standard_normal((macro.n_gp, d, d))
        sig += np.swapaxes(sig, 1, 2)
        u = 0.05 * rng.standard_normal(macro.n_dofs)
        k = macro.stiffness(c, u, sig)
        if kinematics == "small":
            ref = asm(_reference_stiffness, macro.basis, C=macro.from_gp(c))
        else:
            finv, jac = _inverse_and_det(macro.basis.interpolate(u).grad
                                         + np.eye(d)[:, :, None, None])
            ref = asm(_reference_stiffness_finite, macro.basis,
                      A=macro.from_gp(spatial_tangent(sig, c)), Finv=finv, J=jac)
            fb = FacetBasis(macro.mesh, macro.elem, facets=macro.mesh.boundaries["top"],
                            intorder=macro.order)
            finv, m = macro._facet_current(fb, u)
            p_ref = asm(_reference_pressure_stiffness, fb, p=1e5, m=m, Finv=finv)
            p_k = macro.pressure_stiffness("top", 1e5, u)
            assert abs(p_k - p_ref).max() <= 1e-14 * abs(p_ref).max()
        assert abs(k - ref).max() <= 1e-14 * abs(ref).max()


def test_small_kinematics_ignores_the_configuration():
    """Under small kinematics a displacement changes no form: the same vectors and
    matrices as without it, to the bit."""
    macro = Macro(structured_mesh("quad8", [1.0, 1.0], [2, 2]), "quad8")
    u = 0.05 * np.random.default_rng(2).standard_normal(macro.n_dofs)
    sig = np.random.default_rng(3).standard_normal((macro.n_gp, 2, 2))
    sig = sig + np.swapaxes(sig, 1, 2)
    c = np.broadcast_to(LinearElastic(E, NU).tangent, (macro.n_gp, 2, 2, 2, 2))
    assert np.array_equal(macro.internal_force(sig, u), macro.internal_force(sig))
    assert (macro.stiffness(c, u, sig) != macro.stiffness(c)).nnz == 0
    assert np.array_equal(macro.pressure_force("top", 1e5, u),
                          macro.pressure_force("top", 1e5))
    assert np.array_equal(macro.increment_gradient(u, u), macro.strain(u))


# --------------------------------------------------------------------------- rotation
def test_rigid_rotation_turns_the_stress_of_analytic_laws_exactly():
    """A pre-stressed quad8 element (hypoelastic: an initial deviatoric stress;
    neo-Hookean: stretched first) turned rigidly by 90 degrees in 20 steps: the
    Cauchy stress is the initial one turned, to 1e-10."""
    macro = Macro(structured_mesh("quad8", [1.0, 2.0], [1, 1]), "quad8", "finite")
    s0 = np.array([[-1e3, 2e2], [2e2, -3e3]])
    cases = ((lambda: Hypoelastic(E, NU, stress0=s0), np.eye(2)),
             (lambda: NeoHookean(E, NU), np.diag([1.2, 0.9])))
    for make, stretch in cases:
        def path(t, stretch=stretch):  # t <= 0.2: the stretch; then the quarter turn
            if t <= 0.2:
                return np.eye(2) + t / 0.2 * (stretch - np.eye(2))
            return _turn(0.5 * math.pi * (t - 0.2) / 0.8) @ stretch

        solver = Solver(macro, SerialFarm([make() for _ in range(macro.n_gp)]),
                        _all_nodes(macro, path))
        for k in range(25):
            solver.advance(0.04)
            if k == 4:
                before = solver.sigma.copy()
        q = _turn(0.5 * math.pi)
        scale = np.abs(before).max()
        assert np.abs(solver.sigma - q @ before @ q.T).max() <= 1e-10 * scale
        assert np.abs(macro.deformation(solver.u) - q @ stretch).max() < 1e-12
    np.testing.assert_allclose(  # the hypoelastic stress before the turn: s0
        Hypoelastic(E, NU, stress0=s0).trial(np.zeros((2, 2)))[0], s0)


def _shear_then_turn(t):
    """The deformation of the turn tests at load factor t: a simple shear of 2e-3 to
    t = 0.2, then a rigid turn of 90 degrees to t = 1."""
    shear = np.array([[1.0, 2e-3], [0.0, 1.0]])
    if t <= 0.2:
        return np.eye(2) + t / 0.2 * (shear - np.eye(2))
    return _turn(0.5 * math.pi * (t - 0.2) / 0.8) @ shear


def test_rigid_rotation_turns_a_dem_rve_with_it():
    """One element of 30-disk RVEs, sheared by 2e-3, then turned rigidly by 90 degrees
    in 20 steps: the stress comes back turned, within the relaxation tolerance, the
    contacts store the same elastic energy, and the macro stress does no work on the
    turn (the midpoint stretching of a rigid step is zero)."""
    law = dem.LinearSpring(kn=1e8, kt=5e7, mu=0.5)
    packing = rvemod.generate(2, 30, (0.8e-3, 1.2e-3), law, p0=1e5, friction=0.0, seed=4)
    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [1, 1]), "quad1", "finite")
    models = [DEMMicroModel(clone_rve(packing)) for _ in range(macro.n_gp)]
    solver = Solver(macro, SerialFarm(models), _all_nodes(macro, _shear_then_turn))
    work = 0.0
    for k in range(25):
        sig0 = solver.sigma.copy()
        solver.advance(0.04)
        if k == 4:
            before = solver.sigma.copy()
            energy = elastic_energy(models[0].rve.sim)
        elif k > 4:  # the work of the stress on the step's midpoint stretching
            g = solver.increment
            rate = np.linalg.solve(np.swapaxes(np.eye(2) + 0.5 * g, 1, 2),
                                   np.swapaxes(g, 1, 2)).swapaxes(1, 2)
            d = 0.5 * (rate + np.swapaxes(rate, 1, 2))
            work += float(np.sum(0.5 * (sig0 + solver.sigma) * d))
    q = _turn(0.5 * math.pi)
    scale = np.abs(before).max()
    assert np.abs(before[:, 0, 1]).max() > 1e3  # the shear loaded the packing
    assert np.abs(solver.sigma - q @ before @ q.T).max() <= 3e-3 * scale
    assert elastic_energy(models[0].rve.sim) == pytest.approx(energy, rel=3e-3)
    assert abs(work) <= 1e-12 * scale


def test_rigid_rotation_turns_an_rve_of_polygons_with_it():
    """The same turn for an RVE of level-set shapes (12 hexagons, the problem file's
    ``shape = "polygon"``): sheared, then turned rigidly by 90 degrees in 10 steps, the
    stress comes back turned within the relaxation tolerance and every hexagon's
    orientation has turned by the same 90 degrees (its contacts act on the shape's
    turned outline, not on a disk's)."""
    import copy

    from hmm.problem_build import build_macro, model_factory
    from hmm.run import DEMO

    prob = copy.deepcopy(DEMO)
    prob["mesh"].update(cells=[1, 1], size=[1.0, 1.0])
    prob["micro"].update(count=12, shape="polygon", sides=6, seed=3)
    prob["solver"]["kinematics"] = "finite"
    problem = validate_problem(prob)
    macro = build_macro(problem)
    assert macro.finite
    factory = model_factory(problem, 2, points=macro.gauss_points())
    models = [factory(g) for g in range(macro.n_gp)]
    rve = models[0].rve
    assert (rve.bodies.shape >= 0).all()  # every body a hexagon (a shape-table row)
    solver = Solver(macro, SerialFarm(models), _all_nodes(macro, _shear_then_turn))
    for k in range(12):
        solver.advance(0.2 / 2 if k < 2 else 0.08)
        if k == 1:
            before = solver.sigma.copy()
            angles = rve.bodies.rot[:, 0].copy()
    q = _turn(0.5 * math.pi)
    assert solver.t == pytest.approx(1.0)
    assert np.abs(before[:, 0, 1]).max() > 1e3  # the shear loaded the packing
    np.testing.assert_allclose(rve.bodies.rot[:, 0] - angles, 0.5 * math.pi,
                               atol=2e-3)
    assert np.abs(solver.sigma - q @ before @ q.T).max() <= 3e-3 * np.abs(before).max()


# --------------------------------------------------------------------------- closed forms
def _simple_shear(steps, gamma):
    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [1, 1]), "quad1", "finite")
    models = [Hypoelastic(E, NU) for _ in range(macro.n_gp)]
    path = lambda t: np.array([[1.0, gamma * t], [0.0, 1.0]])  # noqa: E731
    return _solve(macro, models, _all_nodes(macro, path), steps).sigma[0]


def test_simple_shear_of_the_jaumann_law_converges_to_its_closed_form():
    """Simple shear to gamma = 4: sigma_xy = G sin(gamma), sigma_xx = -sigma_yy =
    G (1 - cos(gamma)); the error falls with the square of the step."""
    gamma = 4.0
    g = E / (2.0 * (1.0 + NU))
    exact = g * np.array([[1.0 - math.cos(gamma), math.sin(gamma)],
                          [math.sin(gamma), math.cos(gamma) - 1.0]])
    errors = [np.abs(_simple_shear(n, gamma) - exact).max() / g for n in (40, 80, 160)]
    assert errors[-1] < 2e-3
    for coarse, fine in zip(errors, errors[1:], strict=False):
        assert coarse / fine == pytest.approx(4.0, rel=0.15)


def _distorted(element, cells, seed=5, amount=0.08):
    """A unit square mesh with its interior vertices moved at random."""
    mesh = structured_mesh(element, [1.0, 1.0], cells)
    p = mesh.p.copy()
    inner = np.all((p > 1e-9) & (p < 1.0 - 1e-9), axis=0)
    p[:, inner] += np.random.default_rng(seed).uniform(-amount, amount,
                                                       (2, inner.sum()))
    return type(mesh)(p, mesh.t).with_defaults()


def _uniaxial(element, steps, settings, on_iteration=None, macro_cls=Macro):
    """Plane-strain uniaxial stretch of a distorted unit block to lambda = 2: rollers
    on the left and bottom faces, the right face pulled, the top free (on a regular
    mesh the geometric stiffness would not enter Newton's corrections)."""
    macro = macro_cls(_distorted(element, [3, 3]), element, "finite")
    dofs = [macro.dofs("left", 0), macro.dofs("bottom", 1), macro.dofs("right", 0)]
    vals = [np.zeros(dofs[0].size), np.zeros(dofs[1].size), np.full(dofs[2].size, 1.0)]
    dofs, first = np.unique(np.concatenate(dofs), return_index=True)
    solver = Solver(macro, SerialFarm([NeoHookean(E, NU) for _ in range(macro.n_gp)]),
                    Supports(dofs, np.concatenate(vals)[first], ("right",)),
                    settings=settings)
    for _ in range(steps):
        solver.advance(1.0 / steps, on_iteration=on_iteration)
    return macro, solver


def test_neo_hookean_uniaxial_stretch_converges_quadratically_to_the_analytic_stress():
    """Stretch 2 in 10 steps: the lateral stretch makes sigma_yy vanish, sigma_xx is
    the closed form, the reaction is sigma_xx times the current width; Newton's
    residual falls quadratically (the geometric stiffness is in the matrix)."""
    lam, mu = E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU))
    from scipy.optimize import brentq

    lat = brentq(lambda s: mu * (s * s - 1.0) + lam * math.log(2.0 * s), 0.3, 1.0)
    jac = 2.0 * lat
    sxx = (mu * 3.0 + lam * math.log(jac)) / jac
    residuals = []
    st = SolverSettings(tol_residual=1e-13, tol_displacement=1e-13, max_iterations=12,
                        aitken=False)
    macro, solver = _uniaxial("quad8", 10, st,
                              lambda it, r, d: residuals.append((it, r)))
    np.testing.assert_allclose(solver.sigma[:, 0, 0], sxx, rtol=1e-9)
    assert np.abs(solver.sigma[:, 1, 1]).max() < 1e-8 * sxx
    np.testing.assert_allclose(macro.deformation(solver.u)[:, 1, 1], lat, rtol=1e-9)
    assert solver.reactions()["right"][0] == pytest.approx(sxx * lat, rel=1e-9)
    # the last step's residuals: each about the square of the one before
    start = max(i for i, (it, _) in enumerate(residuals) if it == 1)
    last = [r for _, r in residuals[start:]]
    rates = [math.log(b) / math.log(a) for a, b in zip(last, last[1:], strict=False)
             if 1e-12 < b < a < 1e-2]
    assert rates and min(rates) > 1.8


def _sheared_block(steps, settings, macro_cls=Macro, on_iteration=None):
    """A neo-Hookean block, base clamped, top face moved by (0.6, 0.3): a
    non-homogeneous large deformation (the corners turn)."""
    macro = macro_cls(structured_mesh("quad8", [1.0, 1.0], [3, 3]), "quad8", "finite")
    dofs = [macro.dofs("bottom", 0), macro.dofs("bottom", 1), macro.dofs("top", 0),
            macro.dofs("top", 1)]
    vals = [np.zeros(dofs[0].size), np.zeros(dofs[1].size), np.full(dofs[2].size, 0.6),
            np.full(dofs[3].size, 0.3)]
    dofs, first = np.unique(np.concatenate(dofs), return_index=True)
    solver = Solver(macro, SerialFarm([NeoHookean(E, NU) for _ in range(macro.n_gp)]),
                    Supports(dofs, np.concatenate(vals)[first], ("top",)),
                    settings=settings)
    for _ in range(steps):
        solver.advance(1.0 / steps, on_iteration=on_iteration)
    return solver


def test_newton_with_the_geometric_stiffness_is_quadratic_without_it_linear():
    """A clamped block sheared and stretched (a non-homogeneous field): with the
    geometric stiffness the residual falls quadratically; with the material part of
    the matrix alone Newton reaches the same answer in more iterations."""
    st = SolverSettings(tol_residual=1e-11, tol_displacement=1e-11, max_iterations=60,
                        aitken=False)
    residuals = []
    full = _sheared_block(5, st, on_iteration=lambda it, r, d: residuals.append((it, r)))
    start = max(i for i, (it, _) in enumerate(residuals) if it == 1)
    last = [r for _, r in residuals[start:]]
    rates = [math.log(b) / math.log(a) for a, b in zip(last, last[1:], strict=False)
             if 1e-12 < b < a < 1e-2]
    assert rates and min(rates) > 1.8

    class MaterialOnly(Macro):
        def stiffness(self, tangent, u=None, sigma=None):
            return super().stiffness(tangent, u, np.zeros_like(sigma))

    solver = _sheared_block(5, st, macro_cls=MaterialOnly)
    np.testing.assert_allclose(solver.sigma, full.sigma, rtol=0.0,
                               atol=1e-7 * np.abs(full.sigma).max())
    assert sum(solver.iterations) > 2 * sum(full.iterations)


# --------------------------------------------------------------------------- patch test
def test_patch_test_on_a_distorted_mesh():
    """A distorted 3 x 3 quad8 mesh, its boundary nodes on x = F X (stretch, shear and
    a turn): every node follows F, every Gauss point has the neo-Hookean stress of F,
    to the solver's tolerance."""
    mesh = _distorted("quad8", [3, 3])
    macro = Macro(mesh, "quad8", "finite")
    f = _turn(0.4) @ np.array([[1.3, 0.2], [0.1, 0.8]])
    bnd = np.unique(np.concatenate([macro.basis.get_dofs(b).all() for b in
                                    ("left", "right", "bottom", "top")]))
    x0 = macro.basis.doflocs
    comp = np.zeros(macro.n_dofs, int)
    for c in range(2):
        comp[macro.basis.nodal_dofs[c]] = c
        comp[macro.basis.facet_dofs[c]] = c
    target = ((f - np.eye(2)) @ x0)[comp, np.arange(macro.n_dofs)]
    st = SolverSettings(tol_residual=1e-12, tol_displacement=1e-12, max_iterations=20)
    solver = _solve(macro, [NeoHookean(E, NU) for _ in range(macro.n_gp)],
                    Supports(bnd, target[bnd]), 5, st)
    assert np.abs(solver.u - target).max() < 1e-10
    sig = NeoHookean(E, NU).response(f)[0]
    assert np.abs(solver.sigma - sig).max() < 1e-7 * np.abs(sig).max()


# --------------------------------------------------------------------------- DEM
def test_one_element_at_finite_strain_equals_a_standalone_rve():
    """Every Gauss point of one element under a prescribed homogeneous path with
    shear and spin (x = F(t) X) gets the increments F_n+1 F_n^-1 - I (to round-off),
    and its stress is that of a standalone RVE given the same increments, bit for
    bit."""
    law = dem.LinearSpring(kn=1e8, kt=5e7, mu=0.5)
    packing = rvemod.generate(2, 30, (0.8e-3, 1.2e-3), law, p0=1e5, friction=0.0, seed=4)
    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [1, 1]), "quad1", "finite")
    farm = SerialFarm([DEMMicroModel(clone_rve(packing)) for _ in range(macro.n_gp)])
    path = lambda t: _turn(0.3 * t) @ np.array([[1.0 - 2e-3 * t, 3e-3 * t],  # noqa: E731
                                                [0.0, 1.0 + 1e-3 * t]])
    solver = Solver(macro, farm, _all_nodes(macro, path))
    alone = [clone_rve(packing) for _ in range(macro.n_gp)]
    for k in range(3):
        solver.advance(1.0 / 3.0)
        exact = path((k + 1) / 3.0) @ np.linalg.inv(path(k / 3.0)) - np.eye(2)
        assert np.abs(solver.increment - exact).max() < 1e-14
        for g in range(macro.n_gp):
            assert np.array_equal(solver.sigma[g], alone[g].apply_strain(
                solver.increment[g]))
    assert abs(solver.sigma[0, 0, 1]) > 1e3  # the path sheared the packing


def test_one_hex20_element_at_finite_strain_equals_standalone_3d_rves():
    """The 3D case of the test above: one hex20 element (8 Gauss points) of 40-sphere
    periodic RVEs on a homogeneous path of stretch, shear and a turn about (1, 1, 1):
    every point gets F_n+1 F_n^-1 - I to round-off, and its stress is bit for bit
    that of a standalone RVE given the same increments."""
    law = dem.LinearSpring(kn=1e5, kt=5e4, mu=0.5)
    packing = rvemod.generate(3, 40, (0.8e-3, 1.2e-3), law, p0=1e5, friction=0.0, seed=2)
    macro = Macro(structured_mesh("hex20", [1.0, 1.0, 1.0], [1, 1, 1]), "hex20", "finite")
    farm = SerialFarm([DEMMicroModel(clone_rve(packing)) for _ in range(macro.n_gp)])
    axis = np.ones(3) / math.sqrt(3.0)
    k_x = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                    [-axis[1], axis[0], 0.0]])

    def path(t):  # Rodrigues' turn by 0.2 t after a stretch and shear
        turn = np.eye(3) + math.sin(0.2 * t) * k_x + (1.0 - math.cos(0.2 * t)) * k_x @ k_x
        return turn @ np.array([[1.0 - 2e-3 * t, 2e-3 * t, 0.0],
                                [0.0, 1.0 + 1e-3 * t, -1e-3 * t],
                                [0.0, 0.0, 1.0 + 5e-4 * t]])

    solver = Solver(macro, farm, _all_nodes(macro, path))
    alone = [clone_rve(packing) for _ in range(macro.n_gp)]
    for k in range(2):
        solver.advance(0.5)
        exact = path((k + 1) / 2.0) @ np.linalg.inv(path(k / 2.0)) - np.eye(3)
        assert np.abs(solver.increment - exact).max() < 1e-14
        for g in range(macro.n_gp):
            assert np.array_equal(solver.sigma[g], alone[g].apply_strain(
                solver.increment[g]))
    assert abs(solver.sigma[0, 0, 1]) > 1e3  # the path sheared the packing


def test_small_and_finite_agree_to_the_order_of_the_strain():
    """At 1e-4 strain the two kinematics (linear elasticity / neo-Hookean with the
    same small-strain moduli) differ by about the strain times the stress."""
    out = []
    for kin, law in (("small", LinearElastic), ("finite", NeoHookean)):
        macro, solver = None, None
        macro = Macro(structured_mesh("quad8", [1.0, 2.0], [2, 2]), "quad8", kin)
        dofs = [macro.dofs("left", 0), macro.dofs("bottom", 1), macro.dofs("top", 1)]
        vals = [np.zeros(dofs[0].size), np.zeros(dofs[1].size),
                np.full(dofs[2].size, -2e-4)]
        dofs, first = np.unique(np.concatenate(dofs), return_index=True)
        solver = _solve(macro, [law(E, NU) for _ in range(macro.n_gp)],
                        Supports(dofs, np.concatenate(vals)[first]), 2)
        out.append(solver.sigma)
    scale = np.abs(out[0]).max()
    diff = np.abs(out[0] - out[1]).max()
    assert 1e-6 * scale < diff < 5e-4 * scale


# --------------------------------------------------------------------------- loads
def test_follower_pressure_all_round_gives_a_hydrostatic_cauchy_stress():
    """A neo-Hookean block under a follower pressure on its four sides (a corner
    pinned, its neighbour held against turning): the Cauchy stress is -p I
    exactly, on the compressed block; a dead pressure on the initial sides is not."""
    p = 2e5
    out = {}
    for follower in (True, False):
        macro = Macro(structured_mesh("quad8", [1.0, 1.0], [2, 2]), "quad8", "finite")
        corner = macro.basis.nodal_dofs[:, 0]
        right = macro.basis.nodal_dofs[1, np.argmin(np.linalg.norm(
            macro.mesh.p.T - [1.0, 0.0], axis=1))]
        dofs = np.append(corner, right)
        sides = ("left", "right", "bottom", "top")
        if follower:
            loads = [FollowerPressure(s, p, ramp=True) for s in sides]
            solver = Solver(macro, SerialFarm([NeoHookean(E, NU) for _ in
                                               range(macro.n_gp)]),
                            Supports(dofs, np.zeros(3)), loads=loads,
                            settings=SolverSettings(1e-12, 1e-12, 20))
        else:
            f = sum(macro.pressure_force(s, p) for s in sides)
            solver = Solver(macro, SerialFarm([NeoHookean(E, NU) for _ in
                                               range(macro.n_gp)]),
                            Supports(dofs, np.zeros(3)), f_ramp=f,
                            settings=SolverSettings(1e-12, 1e-12, 20))
        for _ in range(4):
            solver.advance(0.25)
        out[follower] = solver.sigma
    np.testing.assert_allclose(out[True], np.broadcast_to(-p * np.eye(2), out[True].shape),
                               rtol=0.0, atol=1e-8 * p)
    assert np.abs(out[False] + p * np.eye(2)).max() > 1e-3 * p


def test_current_loads_are_configuration_dependent_terms():
    """Tractions and body forces per current area/volume are load terms of their own
    (with their stiffness), refused under small kinematics."""
    small = Macro(structured_mesh("quad1", [1.0, 1.0], [1, 1]), "quad1")
    with pytest.raises(ValueError, match="finite kinematics"):
        Solver(small, SerialFarm([LinearElastic(E, NU) for _ in range(small.n_gp)]),
               Supports(np.array([0]), np.zeros(1)),
               loads=[CurrentTraction("top", (0.0, -1.0)), CurrentBodyForce((0.0, -1.0))])


# --------------------------------------------------------------------------- failures
def test_an_inverting_element_cuts_the_step_and_stops_naming_it():
    """Squashing a neo-Hookean element flat in one step: every try inverts it, the
    step is cut down to the minimum, and the error names the element."""
    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [1, 1]), "quad1", "finite")
    dofs = [macro.dofs("bottom", 1), macro.dofs("bottom", 0), macro.dofs("top", 1)]
    vals = [np.zeros(dofs[0].size), np.zeros(dofs[1].size), np.full(dofs[2].size, -1.5)]
    dofs, first = np.unique(np.concatenate(dofs), return_index=True)
    solver = Solver(macro, SerialFarm([NeoHookean(E, NU) for _ in range(macro.n_gp)]),
                    Supports(dofs, np.concatenate(vals)[first]),
                    settings=SolverSettings(min_step=0.25))
    with pytest.raises(SolverError, match=r"element 0 inverts \(det F = "):
        solver.advance(1.0)
    assert solver.t == pytest.approx(0.5)  # what converged before the stop is kept
    assert np.all(np.linalg.det(macro.deformation(solver.u)) > 0.0)


def test_kinematics_key_is_validated():
    base = {"mesh": {"size": [1.0, 1.0], "cells": [1, 1]},
            "dirichlet": [{"boundary": "bottom", "component": "y"}],
            "micro": {"model": "linear_elastic", "young": E, "poisson": NU}}
    assert validate_problem(base)["solver"]["kinematics"] == "small"
    dem_problem = dict(base, micro={"model": "dem"})
    assert validate_problem(dem_problem)["solver"]["kinematics"] == "finite"
    with pytest.raises(SceneError, match=r"\[solver\] kinematics"):
        validate_problem(dict(base, solver={"kinematics": "large"}))
    with pytest.raises(SceneError, match="small-strain law"):
        validate_problem(dict(base, solver={"kinematics": "finite"}))
    with pytest.raises(ValueError, match="small-strain law"):
        macro = Macro(structured_mesh("quad1", [1.0, 1.0], [1, 1]), "quad1", "finite")
        Solver(macro, SerialFarm([LinearElastic(E, NU) for _ in range(macro.n_gp)]),
               Supports(np.array([0]), np.zeros(1)))


def test_log_strain_of_a_stretch_and_a_turn():
    f = _turn(0.7) @ np.diag([math.e, 1.0 / math.e])
    eps = log_strain(f)
    np.testing.assert_allclose(eps, _turn(0.7) @ np.diag([1.0, -1.0]) @ _turn(0.7).T,
                               atol=1e-14)


INVERTS = """
[mesh]
size = [1.0, 1.0]
cells = [1, 1]

[[dirichlet]]
boundary = "bottom"
component = "y"

[[dirichlet]]
boundary = "bottom"
component = "x"

[[dirichlet]]
boundary = "top"
component = "y"
value = -1.2

[micro]
model = "neo_hookean"
young = 1e6
poisson = 0.3

[load]
steps = 3

[solver]
min_step = 0.25
"""


def _hmm(*args, cwd):
    """``hmm ARGS`` in this process from ``cwd``: (exit status, stderr)."""
    import contextlib
    import io
    import os

    from hmm.cli import main

    err = io.StringIO()
    here = os.getcwd()
    os.chdir(cwd)
    code = 0
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                main(list(args))
            except SystemExit as exc:
                code = exc.code
    finally:
        os.chdir(here)
    return code, err.getvalue()


def test_a_run_whose_element_inverts_stops_naming_it_and_the_step(tmp_path):
    """Squashed by 1.2 times its height in three steps: the third step would invert
    the element; the run stops with exit 1, one line naming the element and the load
    step, and fields.h5 ends at the last converged state, the deformed mesh in it."""
    import h5py

    (tmp_path / "p.toml").write_text(INVERTS)
    code, err = _hmm("run", "p.toml", "-o", "out", "--no-progress", cwd=tmp_path)
    assert code == 1
    lines = [line for line in err.splitlines() if "error" in line]
    assert len(lines) == 1
    assert "load step 3 of 3" in lines[0] and "element 0 inverts" in lines[0]
    with h5py.File(tmp_path / "out" / "fields.h5") as f:
        assert f.attrs["kinematics"] == "finite"
        assert (f.attrs["format"], f.attrs["version"]) == ("hmm.fields", 2)
        step = int(f.attrs["last_converged_step"])
        t = float(f.attrs["last_converged_load_factor"])
        assert step >= 2 and 2.0 / 3.0 <= t < 1.0 / 1.2
        pts = f[f"steps/{step:05d}/points"][()]
        assert pts[:, 1].max() == pytest.approx(1.0 - 1.2 * t)


def test_an_unknown_kinematics_is_one_line_and_exit_2(tmp_path):
    (tmp_path / "p.toml").write_text(INVERTS + '\nkinematics = "large"\n')
    code, err = _hmm("run", "p.toml", "-o", "out", cwd=tmp_path)
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and "kinematics" in err


def test_adaptive_counts_the_stretch_not_the_turn():
    """Under finite kinematics an Adaptive point turned by 30 degrees stays elastic
    (its thresholds see the stretch, which is zero) and turns its stress and
    tangent exactly; a stretch past the threshold then runs the RVE on everything it
    owes, the turn included, as the standalone RVE given the same map does."""
    from hmm.micro import Adaptive
    from hmm.tensors import rotate4

    law = dem.LinearSpring(kn=1e8, kt=5e7, mu=0.5)
    packing = rvemod.generate(2, 30, (0.8e-3, 1.2e-3), law, p0=1e5, friction=0.0, seed=4)
    point = Adaptive(DEMMicroModel(clone_rve(packing)), 1e-4, 0.3, finite=True)
    s0, c0 = point.stress.copy(), point.c_elastic.copy()
    q = _turn(math.radians(30.0))
    sig, c = point.trial(q - np.eye(2))
    point.commit()
    assert not point.active and point.steps == 0
    np.testing.assert_allclose(sig, q @ s0 @ q.T, rtol=0.0, atol=1e-9 * np.abs(s0).max())
    np.testing.assert_allclose(c, rotate4(c0, q), rtol=0.0, atol=1e-9 * np.abs(c0).max())
    stretch = np.diag([1.0 - 5e-4, 1.0 + 2e-4])
    sig, _ = point.trial(stretch - np.eye(2))
    point.commit()
    assert point.active
    alone = clone_rve(packing)
    assert np.array_equal(sig, alone.apply_strain(stretch @ q - np.eye(2)))


def test_a_finite_strain_run_restarts_bit_for_bit(tmp_path):
    """Stopped after step 1 and restarted from its checkpoint, a finite-strain run
    (neo-Hookean, a follower pressure) ends bit for bit as the uninterrupted one."""
    import h5py

    text = INVERTS.replace("value = -1.2", "value = -0.3").replace(
        "[load]", '[[pressure]]\nboundary = "right"\nvalue = 1e5\nramp = true\n\n'
                  "[output]\ncheckpoint_every = 1\n\n[load]")
    (tmp_path / "p.toml").write_text(text)
    assert _hmm("run", "p.toml", "-o", "full", cwd=tmp_path)[0] == 0
    assert _hmm("run", "p.toml", "-o", "cut", "--stop-after", "1", cwd=tmp_path)[0] == 0
    code, err = _hmm("run", "p.toml", "-o", "cut", "--restart", cwd=tmp_path)
    assert code == 0, err
    with h5py.File(tmp_path / "full" / "fields.h5") as a, \
            h5py.File(tmp_path / "cut" / "fields.h5") as b:
        for name in ("steps/00003/points", "steps/00003/gauss/stress",
                     "curve/force/bottom"):
            assert np.array_equal(a[name][()], b[name][()])


# --------------------------------------------------------------------------- 3D elements
@pytest.mark.parametrize(("element", "integration", "per_cell"), [
    ("hex20", None, 8), ("hex20", "full", 27), ("hex27", None, 27),
    ("hex27", "reduced", 8), ("tet10", None, 4)])
def test_patch_test_of_the_quadratic_3d_elements(element, integration, per_cell):
    """The quadratic 3D elements (20- and 27-node hexahedra, reduced or full
    integration, 10-node tetrahedra) on a 2 x 1 x 1 box whose boundary follows x = F X
    (stretch, shear and a turn): every node follows F and every Gauss point has the
    neo-Hookean stress of F, to the solver's tolerance; the Gauss points per element
    are the chosen rule's."""
    mesh = structured_mesh(element, [2.0, 1.0, 1.0], [2, 1, 1])
    macro = Macro(mesh, element, "finite", integration)
    assert macro.n_qp == per_cell and macro.n_gp == per_cell * mesh.nelements
    c, s = math.cos(0.3), math.sin(0.3)
    f = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.array(
        [[1.2, 0.1, 0.0], [0.05, 0.9, 0.1], [0.0, 0.0, 1.1]])
    # the nodal values of the linear field x - X (a projection exact for it: a rule
    # that integrates the quadratic mass matrix; the element's own may not)
    target = Basis(mesh, macro.elem, intorder=6).project(
        lambda x: np.einsum("ij,j...->i...", f - np.eye(3), x))
    bnd = macro.basis.get_dofs().all()
    st = SolverSettings(tol_residual=1e-12, tol_displacement=1e-12, max_iterations=20)
    solver = _solve(macro, [NeoHookean(E, NU, dim=3) for _ in range(macro.n_gp)],
                    Supports(bnd, target[bnd]), 4, st)
    assert np.abs(solver.u - target).max() < 1e-10
    sig = NeoHookean(E, NU, dim=3).response(f)[0]
    assert np.abs(solver.sigma - sig).max() < 1e-7 * np.abs(sig).max()


def test_integration_is_a_choice_of_the_quadratic_quads_and_hexahedra():
    """[mesh] integration: 2 or 3 points per axis on quad8; refused, in one line, on an
    element without that choice (tet10) and for an unknown rule."""
    base = {"mesh": {"size": [1.0, 1.0], "cells": [1, 1], "element": "quad8"},
            "dirichlet": [{"boundary": "bottom", "component": "y"}],
            "micro": {"model": "neo_hookean", "young": E, "poisson": NU}}
    from hmm.macro import INTEGRATION
    from hmm.problem_build import build_macro
    from hmm.problem_schema import QUADRATURE_CHOICE

    assert set(QUADRATURE_CHOICE) == set(INTEGRATION)  # the file and the solver agree
    for rule, n in ((None, 4), ("reduced", 4), ("full", 9)):
        prob = {**base, "mesh": {**base["mesh"], "integration": rule}}
        assert build_macro(validate_problem(prob)).n_qp == n
    three = {**base, "mesh": {"dim": 3, "size": [1.0, 1.0, 1.0], "cells": [1, 1, 1],
                              "element": "tet10", "integration": "full"}}
    with pytest.raises(SceneError, match=r"\[mesh\] integration applies to quad2, "
                                         r"quad8, hex20, hex27, not to element "
                                         r"\"tet10\""):
        validate_problem(three)
    with pytest.raises(ValueError, match="integration must be"):
        Macro(structured_mesh("hex20", [1.0] * 3, [1, 1, 1]), "hex20",
              integration="exact")


@pytest.mark.parametrize(("element", "topology", "corners"), [
    ("hex20", "Hexahedron", 8), ("tet10", "Tetrahedron", 4)])
def test_a_quadratic_3d_run_writes_its_deformed_mesh(tmp_path, element, topology,
                                                     corners):
    """A problem file on hex20 / tet10 elements runs to its end and writes the XDMF
    ParaView reads: the cells by their corners (VTK's order), the moved points."""
    import h5py

    from hmm.run import run_problem

    prob = validate_problem({
        "mesh": {"dim": 3, "element": element, "size": [1.0, 1.0, 1.0],
                 "cells": [1, 1, 1]},
        "dirichlet": [{"boundary": "bottom", "component": c, "value": 0.0}
                      for c in "xyz"] + [{"boundary": "top", "component": "y",
                                          "value": -0.1}],
        "micro": {"model": "neo_hookean", "young": E, "poisson": NU},
        "load": {"steps": 2}})
    summary = run_problem(prob, tmp_path / "out", progress=False)
    assert summary["load_factor"] == pytest.approx(1.0)
    xdmf = (tmp_path / "out" / "fields.xdmf").read_text()
    assert f'TopologyType="{topology}"' in xdmf
    with h5py.File(tmp_path / "out" / "fields.h5") as f:
        assert f["mesh/cells"].shape[1] == corners
        last = f["steps"][sorted(f["steps"])[-1]]
        top = f["mesh/points"][:, 1] == 1.0
        np.testing.assert_allclose(last["points"][top, 1], 0.9, atol=1e-12)
