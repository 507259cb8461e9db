"""Reactions: each support sums the unbalanced force over the degrees of freedom it
holds and only those; the supports balance the applied loads; the printed unit is
N/m in 2D (per unit thickness) and N in 3D."""

import re

import numpy as np
import pytest

from hmm.cli import main, reaction_lines
from hmm.coupling import Solver, Supports
from hmm.farm import SerialFarm
from hmm.macro import Macro, structured_mesh
from hmm.micro import LinearElastic
from hmm.problem import validate_problem
from hmm.problem_build import build_loads, build_macro
from hmm.run import run_problem

E, NU = 1e6, 0.3
LAM, MU = E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU))
STRETCH, Q = 2e-3, 4e3  # [m] the right face's displacement, [Pa] the top's traction


def _patch(dim, element):
    """A box [0, L] x [0, H] (x [0, W]): rollers on the low faces, the right face pulled
    by STRETCH, a traction (0, -Q) on the top: a uniform stress field."""
    size = [2.0, 1.0, 0.5][:dim]
    conditions = [{"boundary": "left", "component": "x"},
                  {"boundary": "bottom", "component": "y"},
                  {"boundary": "right", "component": "x", "value": STRETCH}]
    if dim == 3:
        conditions.insert(2, {"boundary": "front", "component": "z"})
    return {"mesh": {"dim": dim, "element": element, "size": size,
                     "cells": [2, 3, 2][:dim]},
            "dirichlet": conditions,
            "traction": [{"boundary": "top", "value": [0.0, -Q, 0.0][:dim]}],
            "micro": {"model": "linear_elastic", "young": E, "poisson": NU},
            "load": {"steps": 1}}


def _uniform_stress(dim, size):
    """(sigma_xx, sigma_yy) of the patch: eps_xx = STRETCH / L, sigma_yy = -Q and
    sigma_zz = 0 in 3D (the back face is free), eps_zz = 0 in 2D (plane strain)."""
    exx = STRETCH / size[0]
    if dim == 2:
        eyy = (-Q - LAM * exx) / (LAM + 2 * MU)
        return (LAM + 2 * MU) * exx + LAM * eyy, -Q
    a = np.array([[LAM + 2 * MU, LAM], [LAM, LAM + 2 * MU]])
    eyy, ezz = np.linalg.solve(a, [-Q - LAM * exx, -LAM * exx])
    return (LAM + 2 * MU) * exx + LAM * (eyy + ezz), -Q


def _resultant(macro, f):
    """Sum of a nodal force vector per displacement component (d,)."""
    comp = np.empty(macro.n_dofs, int)
    for c in range(macro.dim):
        comp[macro.basis.get_dofs().all(f"u^{c + 1}")] = c
    return np.array([f[comp == c].sum() for c in range(macro.dim)])


@pytest.mark.parametrize("dim, element", [(2, "quad1"), (2, "quad8"), (3, "hex1")])
def test_each_support_carries_the_analytic_traction_and_no_more(tmp_path, dim, element):
    """The left and right faces carry sigma_xx times their area (length in 2D), the
    bottom Q times its area; a support reports nothing in a component it does not
    hold, although it shares corner nodes with supports that hold the others."""
    problem = validate_problem(_patch(dim, element))
    s = run_problem(problem, tmp_path / "out", progress=False)
    size = problem["mesh"]["size"]
    sxx, syy = _uniform_stress(dim, size)
    side = np.prod(size) / size[0]  # area of a face normal to x (2D: its length)
    base = np.prod(size) / size[1]
    r = {k: np.asarray(v) for k, v in s["reactions"].items()}
    tol = 1e-9 * Q * base
    assert r["right"][0] == pytest.approx(sxx * side, rel=1e-9)
    assert r["left"][0] == pytest.approx(-sxx * side, rel=1e-9)
    assert r["bottom"][1] == pytest.approx(-syy * base, rel=1e-9)
    assert np.all(r["right"][1:] == 0.0) and np.all(r["left"][1:] == 0.0)
    assert r["bottom"][0] == 0.0 and np.all(r["bottom"][2:] == 0.0)
    assert s["held"] == {"left": (0,), "bottom": (1,), "right": (0,),
                         **({"front": (2,)} if dim == 3 else {})}
    if dim == 3:
        assert abs(r["front"][2]) <= tol  # sigma_zz = 0
    # the supports balance the applied traction
    macro = build_macro(problem)
    _, f_const, f_ramp, _ = build_loads(problem, macro)
    total = sum(r.values()) + _resultant(macro, f_const + f_ramp)
    assert np.all(np.abs(total) <= tol)


def _clamped(dim, kinematics, model="linear_elastic"):
    """A block whose base is clamped (x, y (and z) held, listed after the left
    face's x: the base's left corner dofs in x are prescribed twice) under a top
    traction with a shear part: no uniform field, but the reactions must balance."""
    conditions = [{"boundary": "left", "component": "x"}] + [
        {"boundary": "bottom", "component": c} for c in "xyz"[:dim]]
    return {"mesh": {"dim": dim, "element": "quad1" if dim == 2 else "hex1",
                     "size": [1.0, 1.0, 1.0][:dim], "cells": [2, 2, 1][:dim]},
            "dirichlet": conditions,
            "traction": [{"boundary": "top", "value": [1e3, -5e3, 2e2][:dim]}],
            "micro": {"model": model, "young": E, "poisson": NU},
            "solver": {"kinematics": kinematics, "tol_residual": 1e-10,
                       "tol_displacement": 1e-10, "aitken": False},
            "load": {"steps": 2}}


@pytest.mark.parametrize("dim, kinematics, model", [
    (2, "small", "linear_elastic"), (3, "small", "linear_elastic"),
    (2, "finite", "neo_hookean"), (3, "finite", "hypoelastic")])
def test_a_corner_held_by_two_supports_counts_once(tmp_path, dim, kinematics, model):
    """The left face and the clamped base both hold the corner's x dof: it counts in
    the left support's reaction alone (the first listed), so the reactions plus the
    applied loads sum to zero, under small and finite kinematics."""
    problem = validate_problem(_clamped(dim, kinematics, model))
    s = run_problem(problem, tmp_path / "out", progress=False)
    macro = build_macro(problem)
    sup, f_const, f_ramp, _ = build_loads(problem, macro)
    corner = macro.dofs("left", 0)[np.isin(macro.dofs("left", 0), macro.dofs("bottom", 0))]
    assert corner.size and np.all(np.isin(corner, sup.held["left"][0]))
    assert not np.any(np.isin(corner, sup.held["bottom"][0]))
    load = _resultant(macro, f_const + f_ramp)
    total = sum(np.asarray(v) for v in s["reactions"].values()) + load
    assert np.all(np.abs(total) <= 1e-8 * np.abs(load).max())
    assert s["reactions"]["bottom"][1] > 0.0  # the base holds the block up


def test_saturated_supports_hold_only_their_components(tmp_path):
    """A consolidating column (as test_porous_problem's): the base carries the whole
    load in y, the side rollers nothing in y (their corners with the base are the
    base's in y), and the reactions balance the load."""
    q, width = 1e4, 0.1
    problem = validate_problem({
        "mesh": {"dim": 2, "element": "quad8", "size": [width, 1.0], "cells": [1, 8]},
        "dirichlet": [{"boundary": "bottom", "component": "y"},
                      {"boundary": "left", "component": "x"},
                      {"boundary": "right", "component": "x"}],
        "pressure": [{"boundary": "top", "value": q, "ramp": True}],
        "load": {"steps": 12},
        "fluid": {"permeability": 1.2e-10, "bulk_modulus": 2.2e9},
        "drainage": [{"boundary": "top", "pressure": 0.0}],
        "time": {"end": 1.0, "first": 0.01},
        "micro": {"model": "linear_elastic", "young": 1e7, "poisson": 0.25}})
    s = run_problem(problem, tmp_path / "out", progress=False)
    r = s["reactions"]
    assert r["bottom"][1] == pytest.approx(q * width, rel=1e-6)
    assert r["left"][1] == 0.0 and r["right"][1] == 0.0 and r["bottom"][0] == 0.0
    assert r["left"][0] + r["right"][0] == pytest.approx(0.0, abs=1e-9 * q * width)


def test_from_conditions_takes_the_first_value_and_owner():
    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [1, 1]), "quad1")
    left, bottom = macro.dofs("left", 0), macro.dofs("bottom", 0)
    sup = Supports.from_conditions([("left", 0, left, 0.0), ("bottom", 0, bottom, 1e-3),
                                    (None, 1, macro.dofs("bottom", 1), 0.0)])
    shared = np.intersect1d(left, bottom)
    assert shared.size == 1
    assert sup.values[np.searchsorted(sup.dofs, shared)] == 0.0
    assert set(sup.held) == {"left", "bottom"} and sup.boundaries == ("left", "bottom")
    assert shared[0] in sup.held["left"][0] and shared[0] not in sup.held["bottom"][0]
    assert np.unique(sup.dofs).size == sup.dofs.size == 5


def test_supports_without_held_give_each_dof_to_the_first_boundary():
    """The plain constructor (dofs and boundary names): a boundary reports only the
    prescribed dofs on it that no boundary before it reports."""
    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [2, 2]), "quad1")
    farm = SerialFarm([LinearElastic(E, NU, 2) for _ in range(macro.n_gp)])
    dofs = np.unique(np.concatenate([macro.dofs("left", 0), macro.dofs("bottom", 1)]))
    solver = Solver(macro, farm, Supports(dofs, np.zeros(dofs.size), ("bottom", "left")),
                    f_ramp=macro.traction_force("top", [0.0, -1e3]))
    solver.advance(1.0)
    r = solver.reactions()
    assert solver.held_components() == {"bottom": (1,), "left": (0,)}
    assert r["bottom"][1] == pytest.approx(1e3, rel=1e-9) and r["bottom"][0] == 0.0


def test_the_printed_reaction_names_held_components_and_the_unit(tmp_path, capsys):
    two = reaction_lines({"reactions": {"left": [-4017.0, 0.0]}, "held": {"left": (0,)},
                          "dim": 2})
    three = reaction_lines({"reactions": {"top": [0.0, 1.5, 0.0]},
                            "held": {"top": (1,)}, "dim": 3})
    assert two == ["reaction on left: x = -4017 N/m"]
    assert three == ["reaction on top: y = 1.5 N"]
    (tmp_path / "p.toml").write_text(
        "[mesh]\nsize = [2.0, 1.0]\ncells = [2, 1]\n"
        "[[dirichlet]]\nboundary = \"left\"\ncomponent = \"x\"\n"
        "[[dirichlet]]\nboundary = \"bottom\"\ncomponent = \"y\"\n"
        "[[traction]]\nboundary = \"top\"\nvalue = [0.0, -4e3]\n"
        "[micro]\nmodel = \"linear_elastic\"\nyoung = 1e6\npoisson = 0.3\n"
        "[load]\nsteps = 1\n")
    with pytest.raises(SystemExit) as code:
        main(["run", str(tmp_path / "p.toml"), "-o", str(tmp_path / "out"),
              "--no-progress"])
    assert code.value.code == 0
    out = capsys.readouterr().out
    assert "reaction on bottom: y = 8000 N/m" in out
    left = next(line for line in out.splitlines() if line.startswith("reaction on left"))
    assert re.fullmatch(r"reaction on left: x = \S+ N/m", left)  # x only: held in x


def test_a_point_support_reports_its_reaction(tmp_path):
    """A smooth base held in x at one vertex, a top traction with a shear part: the
    point alone holds the body against sliding, so its reaction is minus the shear
    force, and the base's is the weight of the normal part."""
    problem = validate_problem({
        "mesh": {"size": [1.0, 1.0], "cells": [2, 2]},
        "dirichlet": [{"boundary": "bottom", "component": "y"},
                      {"point": [0.5, 0.0], "component": "x"}],
        "traction": [{"boundary": "top", "value": [300.0, -2e3]}],
        "micro": {"model": "linear_elastic", "young": E, "poisson": NU},
        "load": {"steps": 1}})
    s = run_problem(problem, tmp_path / "out", progress=False)
    r = s["reactions"]
    assert set(r) == {"bottom", "point (0.5, 0)"}
    assert s["held"]["point (0.5, 0)"] == (0,)
    assert r["point (0.5, 0)"][0] == pytest.approx(-300.0, rel=1e-9)
    assert r["bottom"] == pytest.approx([0.0, 2e3], rel=1e-9)
