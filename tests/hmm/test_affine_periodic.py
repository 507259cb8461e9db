"""Affine boundary displacements (u = G x) and periodic macro boundaries.

The affine patch test through a problem file: on a distorted mesh whose whole
boundary is driven by u = G x, a homogeneous elastic body deforms homogeneously, so
every Gauss point's strain is sym G and the stress is uniform (small kinematics), and
the deformed mesh is (I + G) X (finite kinematics). A periodic cell tied by
u(x + L) = u(x) + G L returns the affine field when uniform, and with a soft
inclusion a fluctuation u - G x that is periodic, with the average strain sym G.
"""

from pathlib import Path

import numpy as np
import pytest

import hmm
from dem.io.schema import SceneError
from hmm.problem import load_problem, validate_problem
from hmm.problem_build import build_farm, build_loads, build_macro
from hmm.run import run_problem

ROOT = Path(__file__).resolve().parents[2]

SIDES = {2: ("left", "right", "bottom", "top"),
         3: ("left", "right", "bottom", "top", "front", "back")}


def distorted_mesh(path, element, cells, seed=0):
    """A unit square (cube) of ``cells`` per axis with its interior vertices moved by
    up to a quarter of a cell, saved to ``path`` with its named faces."""
    mesh = hmm.structured_mesh(element, [1.0] * len(cells), cells)
    p = mesh.p.copy()
    inner = np.all((p > 1e-12) & (p < 1.0 - 1e-12), axis=0)
    rng = np.random.default_rng(seed)
    p[:, inner] += rng.uniform(-0.25, 0.25, (p.shape[0], inner.sum())) / max(cells)
    mesh = type(mesh)(p, mesh.t).with_defaults()
    mesh.save(str(path))
    return mesh


def toml_matrix(g):
    return "[" + ", ".join("[" + ", ".join(repr(float(v)) for v in row) + "]"
                           for row in g) + "]"


def affine_problem(tmp_path, element, cells, g, model, kinematics, steps=2):
    """A problem file: the distorted mesh, every face driven by u = G x."""
    dim = len(cells)
    distorted_mesh(tmp_path / "mesh.msh", element, cells)
    faces = "".join(f'[[dirichlet]]\nboundary = "{b}"\ngradient = {toml_matrix(g)}\n\n'
                    for b in SIDES[dim])
    text = (f'[mesh]\ndim = {dim}\nelement = "{element}"\nfile = "mesh.msh"\n\n{faces}'
            f'[load]\nsteps = {steps}\n\n'
            f'[micro]\nmodel = "{model}"\nyoung = 2e7\npoisson = 0.3\n\n'
            f'[solver]\nkinematics = "{kinematics}"\ntol_residual = 1e-11\n'
            f'tol_displacement = 1e-11\naitken = false\n')
    (tmp_path / "patch.toml").write_text(text)
    return load_problem(tmp_path / "patch.toml")


def solve(problem):
    """Build what a run builds and take the whole schedule; the solver and macro."""
    macro = build_macro(problem)
    sup, f_const, f_ramp, loads = build_loads(problem, macro)
    solver = hmm.Solver(macro, build_farm(problem, macro), sup, f_const, f_ramp,
                        hmm.SolverSettings.from_section(problem["solver"]), loads)
    n = problem["load"]["steps"]
    for _ in range(n):
        solver.advance(1.0 / n)
    return macro, solver


def test_affine_patch_small_2d_through_run(tmp_path):
    g = np.array([[2e-3, 1.5e-3], [-0.5e-3, -1e-3]])
    problem = affine_problem(tmp_path, "quad1", [4, 4], g, "linear_elastic", "small")
    summary = run_problem(problem, tmp_path / "out")
    macro = build_macro(problem)
    eps = macro.strain(summary["u"])
    np.testing.assert_allclose(eps, np.broadcast_to(0.5 * (g + g.T), eps.shape),
                               rtol=0, atol=1e-14)
    sig = summary["sigma"]
    np.testing.assert_allclose(sig, np.broadcast_to(sig[0], sig.shape), rtol=1e-11,
                               atol=0)
    # every node, the inner ones too, sits at G x; the faces are the supports
    np.testing.assert_allclose(macro.nodal_displacement(summary["u"]),
                               macro.mesh.p.T @ g.T, rtol=0, atol=1e-15)
    assert set(summary["held"]) == set(SIDES[2])
    assert all(summary["held"][b] == (0, 1) for b in SIDES[2])


@pytest.mark.parametrize("element, cells", [("quad8", [3, 3]), ("hex1", [2, 2, 2])])
def test_affine_patch_small_quadratic_and_3d(tmp_path, element, cells):
    d = len(cells)
    g = np.arange(1.0, d * d + 1).reshape(d, d) * 1e-4 - 4e-4
    macro, solver = solve(affine_problem(tmp_path, element, cells, g,
                                         "linear_elastic", "small", steps=1))
    eps = macro.strain(solver.u)
    np.testing.assert_allclose(eps, np.broadcast_to(0.5 * (g + g.T), eps.shape),
                               rtol=0, atol=1e-14)
    np.testing.assert_allclose(solver.sigma, np.broadcast_to(solver.sigma[0],
                                                             solver.sigma.shape),
                               rtol=1e-10, atol=0)


@pytest.mark.parametrize("element, cells", [("quad1", [3, 3]), ("hex1", [2, 2, 2])])
def test_affine_patch_finite_moves_the_mesh_to_one_plus_g_x(tmp_path, element, cells):
    d = len(cells)
    g = np.zeros((d, d))
    g[0, 0], g[0, 1], g[1, 0], g[1, 1] = 0.08, 0.05, -0.03, -0.06
    macro, solver = solve(affine_problem(tmp_path, element, cells, g, "neo_hookean",
                                         "finite", steps=3))
    x0 = macro.mesh.p.T
    np.testing.assert_allclose(macro.current_points(solver.u), x0 @ (np.eye(d) + g).T,
                               rtol=0, atol=1e-12)
    f = macro.deformation(solver.u)
    np.testing.assert_allclose(f, np.broadcast_to(np.eye(d) + g, f.shape), atol=1e-12)
    sig = solver.sigma
    np.testing.assert_allclose(sig, np.broadcast_to(sig[0], sig.shape), rtol=1e-9,
                               atol=1e-9 * np.abs(sig).max())
    assert abs(solver.t - 1.0) < 1e-12


def test_affine_component_and_origin(tmp_path):
    """A gradient with a component holds that component only; the origin stays put."""
    problem = validate_problem({
        "mesh": {"size": [1.0, 1.0], "cells": [2, 2]},
        "dirichlet": [{"boundary": "top", "component": "x", "gradient": 0.01,
                       "origin": [0.5, 0.0]},
                      {"boundary": "bottom", "component": "y"}],
        "micro": {"model": "linear_elastic", "young": 1e6, "poisson": 0.3}})
    macro = build_macro(problem)
    sup, *_ = build_loads(problem, macro)
    top_x = macro.dofs("top", 0)
    assert np.isin(top_x, sup.dofs).all() and not np.isin(macro.dofs("top", 1),
                                                         sup.dofs).any()
    x = macro.basis.doflocs[0, top_x]
    got = sup.values[np.searchsorted(sup.dofs, top_x)]
    np.testing.assert_allclose(got, 0.01 * (x - 0.5), rtol=0, atol=1e-17)


BASE = {"mesh": {"size": [1.0, 1.0], "cells": [2, 2]},
        "micro": {"model": "linear_elastic", "young": 1e6, "poisson": 0.3}}


@pytest.mark.parametrize("edit, message", [
    ({"dirichlet": [{"boundary": "top", "value": 0.1, "gradient": 0.01}]},
     r"\[\[dirichlet\]\] #1 takes a value or a gradient, not both"),
    ({"dirichlet": [{"boundary": "top", "origin": [0.0, 0.0], "component": "x"}]},
     r"\[\[dirichlet\]\] #1 origin applies to an affine displacement"),
    ({"dirichlet": [{"boundary": "top"}]},
     r"\[\[dirichlet\]\] #1 needs a component \(x, y or z\) with a value, or a gradient"),
    ({"dirichlet": [{"boundary": "top", "gradient": [[0.0, 1.0]]}]},
     r"\[\[dirichlet\]\] #1 gradient must be a number or 2 rows of 2 numbers"),
    ({"dirichlet": [{"boundary": "top", "component": "x"}],
      "load": {"gradient": 0.01}}, r"\[load\] gradient applies to \[\[periodic\]\]"),
    ({"dirichlet": [{"point": [0.0, 0.0], "gradient": 0.0}],
      "periodic": [{"boundary": "left", "image": "left"}]},
     r"\[\[periodic\]\] #1 boundary and image are both \"left\""),
    ({"dirichlet": [{"point": [0.0, 0.0], "gradient": 0.0}],
      "periodic": [{"boundary": "left", "image": "right"},
                   {"boundary": "right", "image": "top"}]},
     r"\[\[periodic\]\] #2 \"right\" is in \[\[periodic\]\] #1 already"),
])
def test_bad_affine_and_periodic_keys_name_the_key(edit, message):
    with pytest.raises(SceneError, match="^<problem>: " + message):
        validate_problem({**BASE, **edit})


@pytest.mark.parametrize("edit, message", [
    ({"dirichlet": [{"point": [0.0, 0.0], "gradient": 0.0}],
      "periodic": [{"boundary": "left", "image": "roof"}]},
     r"\[\[periodic\]\] #1 image \"roof\" is not a boundary of the mesh"),
    ({"dirichlet": [{"point": [0.0, 0.0], "gradient": 0.0}],
      "boundary": [{"name": "half", "of": "right", "lo": [1.0, 0.0], "hi": [1.0, 0.5]}],
      "periodic": [{"boundary": "left", "image": "half"}]},
     r"\[\[periodic\]\] #1 \"left\" has 3 nodes and \"half\" 2"),
    ({"dirichlet": [{"point": [0.0, 0.0], "gradient": 0.0}],
      "periodic": [{"boundary": "left", "image": "top"}]},
     r"\[\[periodic\]\] #1 the nodes of \"top\" are not those of \"left\" shifted"),
    ({"dirichlet": [{"boundary": "bottom", "component": "y"},
                    {"boundary": "top", "component": "y"}],
      "periodic": [{"boundary": "bottom", "image": "top"}]},
     r"\[\[periodic\]\] the pairs tie held degrees of freedom at"),
])
def test_periodic_pairs_that_do_not_fit_the_mesh_name_the_pair(edit, message):
    problem = validate_problem({**BASE, **edit})
    with pytest.raises(SceneError, match="^<problem>: " + message):
        build_loads(problem, build_macro(problem))


def periodic_cell(inclusion, kinematics="small"):
    """A unit cell, 6 x 6 bilinear elements, left/right and bottom/top periodic, its
    corner at the origin held, loaded by an average gradient G; the stiff matrix has
    a soft disc (E / 100) in the middle when ``inclusion``. Finite kinematics: a
    neo-Hookean material and a larger G."""
    macro = hmm.Macro(hmm.structured_mesh("quad1", [1.0, 1.0], [6, 6]), "quad1",
                      kinematics)
    g = np.array([[0.01, 0.004], [0.0, -0.005]])
    law = hmm.LinearElastic
    if kinematics == "finite":
        g, law = 10.0 * g, hmm.NeoHookean
    soft = np.linalg.norm(macro.gauss_points() - 0.5, axis=1) < 0.3
    farm = hmm.SerialFarm([law(1e6 if (s and inclusion) else 1e8, 0.3) for s in soft])
    sup = hmm.supports(macro, [hmm.Dirichlet(point=[0.0, 0.0], gradient=0.0)],
                       periodic=[hmm.Periodic("left", "right"),
                                 hmm.Periodic("bottom", "top")], gradient=g)
    settings = hmm.SolverSettings(tol_residual=1e-11, tol_displacement=1e-11,
                                  aitken=False)
    solver = hmm.Solver(macro, farm, sup, settings=settings)
    solver.advance(0.5)
    solver.advance(0.5)
    return macro, solver, g


def images(mesh, a, b, shift):
    """Vertices of boundary ``a`` and of their images on ``b`` (``shift`` away)."""
    na = np.unique(mesh.facets[:, mesh.boundaries[a]])
    nb = np.unique(mesh.facets[:, mesh.boundaries[b]])
    x = mesh.p.T
    j = [int(np.argmin(np.linalg.norm(x[nb] - (x[k] + shift), axis=1))) for k in na]
    return na, nb[j]


@pytest.mark.parametrize("kinematics", ["small", "finite"])
def test_uniform_periodic_cell_returns_the_affine_field(kinematics):
    macro, solver, g = periodic_cell(inclusion=False, kinematics=kinematics)
    np.testing.assert_allclose(macro.nodal_displacement(solver.u),
                               macro.mesh.p.T @ g.T, rtol=0, atol=1e-14)
    f = macro.deformation(solver.u)  # I + grad u: I + G everywhere
    np.testing.assert_allclose(f, np.broadcast_to(np.eye(2) + g, f.shape), rtol=0,
                               atol=1e-13)


def test_periodic_cell_with_a_soft_inclusion_has_a_periodic_fluctuation():
    macro, solver, g = periodic_cell(inclusion=True)
    x = macro.mesh.p.T
    w = macro.nodal_displacement(solver.u) - x @ g.T  # the fluctuation
    assert np.abs(w).max() > 1e-2 * np.abs(x @ g.T).max()  # the inclusion shows
    for a, b, shift in (("left", "right", [1.0, 0.0]), ("bottom", "top", [0.0, 1.0])):
        na, nb = images(macro.mesh, a, b, np.array(shift))
        np.testing.assert_allclose(w[nb], w[na], rtol=0, atol=1e-15)
    # the average strain is sym G, and the held corner carries no force
    eps, vol = macro.strain(solver.u), macro.weights()
    mean = np.einsum("nij,n->ij", eps, vol) / vol.sum()
    np.testing.assert_allclose(mean, 0.5 * (g + g.T), rtol=0, atol=1e-14)
    sig = solver.sigma
    assert np.abs(sig - sig[0]).max() > 0.1 * np.abs(sig).max()  # not uniform
    (force,) = solver.reactions().values()
    assert np.abs(force).max() < 1e-9 * np.abs(macro.internal_force(sig)).max()


def test_periodic_problem_file_runs_a_simple_shear_cell(tmp_path):
    """The same cell from a problem file: [[periodic]] pairs and [load] gradient."""
    g = [[0.0, 0.02], [0.0, 0.0]]
    problem = validate_problem({
        "mesh": {"size": [0.5, 0.25], "cells": [4, 2]},
        "dirichlet": [{"point": [0.0, 0.0], "component": "x"},
                      {"point": [0.0, 0.0], "component": "y"}],
        "periodic": [{"boundary": "left", "image": "right"},
                     {"boundary": "bottom", "image": "top"}],
        "load": {"steps": 2, "gradient": g},
        "micro": {"model": "linear_elastic", "young": 1e7, "poisson": 0.25},
        "solver": {"tol_residual": 1e-11, "tol_displacement": 1e-11}})
    macro, solver = solve(problem)
    eps = macro.strain(solver.u)
    np.testing.assert_allclose(eps[:, 0, 1], 0.01, rtol=1e-12)
    np.testing.assert_allclose(eps[:, 0, 0], 0.0, atol=1e-15)
    shear = 1e7 / (2 * 1.25)
    np.testing.assert_allclose(solver.sigma[:, 0, 1], 2 * shear * 0.01, rtol=1e-11)


def test_affine_boundaries_are_load_displacement_curves():
    from hmm.run import driven_components

    problem = validate_problem({
        **BASE, "dirichlet": [{"boundary": "bottom", "component": "y"},
                              {"boundary": "top", "gradient": [[0.0, 0.01], [0.0, 0.0]]},
                              {"boundary": "right", "component": "y", "gradient": 0.01},
                              {"boundary": "left", "value": -0.001, "component": "x"}]})
    assert driven_components(problem, 2) == [("top", 0), ("right", 1), ("left", 0)]


def test_periodic_cube_ties_its_eight_corners_and_returns_the_affine_field():
    macro = hmm.Macro(hmm.structured_mesh("hex1", [1.0, 0.5, 0.5], [2, 2, 2]), "hex1")
    g = np.array([[1e-3, 2e-3, 0.0], [0.0, -5e-4, 1e-3], [3e-4, 0.0, 2e-4]])
    sup = hmm.supports(macro, [hmm.Dirichlet(point=[0.0, 0.0, 0.0], gradient=0.0)],
                       periodic=[hmm.Periodic("left", "right"),
                                 hmm.Periodic("bottom", "top"),
                                 hmm.Periodic("front", "back")], gradient=g)
    corner = {len(t) for t in sup.ties}
    assert max(corner) == 8 and sup.ties[0][0] in sup.dofs  # the held corner leads
    farm = hmm.SerialFarm([hmm.LinearElastic(1e8, 0.3, dim=3) for _ in range(macro.n_gp)])
    solver = hmm.Solver(macro, farm, sup, settings=hmm.SolverSettings(
        tol_residual=1e-11, tol_displacement=1e-11, aitken=False))
    solver.advance(1.0)
    np.testing.assert_allclose(macro.nodal_displacement(solver.u),
                               macro.mesh.p.T @ g.T, rtol=0, atol=1e-15)


def test_keys_added_at_their_defaults_leave_the_checkpoint_digest_alone():
    """A checkpoint written before affine and periodic boundaries existed restarts: the
    new keys at their defaults do not change the problem's digest; set, they do."""
    import copy

    from hmm.checkpoint import ADDED_KEYS, problem_digest
    from hmm.problem import load_problem

    problem = load_problem(ROOT / "examples" / "biaxial.toml")
    older = copy.deepcopy(problem)  # the same problem as an older version validated it
    for section, key, _ in ADDED_KEYS:
        if section is None:
            older.pop(key)
        elif isinstance(older[section], dict):
            older[section].pop(key)
        else:
            for entry in older[section]:
                entry.pop(key)
    assert problem_digest(problem) == problem_digest(older)
    changed = copy.deepcopy(problem)
    changed["load"]["gradient"] = [[0.0, 0.0], [0.0, -0.01]]
    assert problem_digest(changed) != problem_digest(problem)
