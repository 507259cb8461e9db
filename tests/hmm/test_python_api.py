"""The public Python API of ``hmm``: what it exports, that importing it is cheap, that
a problem file is built through it, and that its conditions fail with one line
naming the condition. docs/python_api.md runs a whole problem through it
(tests/test_doc_pages.py)."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import hmm
from hmm.problem import validate_problem
from hmm.problem_build import build_loads, build_macro

ROOT = Path(__file__).resolve().parents[2]


def test_import_hmm_loads_nothing_heavy():
    code = ("import sys, hmm; print(sorted(m for m in sys.modules "
            "if m.split('.')[0] in ('skfem', 'dem', 'scipy', 'h5py') or m.startswith('hmm.')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"


def test_every_export_resolves_and_is_documented():
    assert hmm.__all__ == sorted(hmm.__all__)
    for name in hmm.__all__:
        obj = getattr(hmm, name)
        assert name in dir(hmm)
        if callable(obj):
            assert obj.__doc__ and obj.__doc__.strip(), name
    assert hmm.Solver is __import__("hmm.coupling", fromlist=["Solver"]).Solver
    with pytest.raises(AttributeError, match="no attribute 'Solvr'"):
        hmm.Solvr  # noqa: B018


PROBLEM = {
    "mesh": {"element": "quad8", "size": [0.04, 0.08], "cells": [2, 3]},
    "boundary": [{"name": "footing", "of": "top", "lo": [0.0, 0.08], "hi": [0.02, 0.08]}],
    "dirichlet": [{"boundary": "bottom", "component": "y"},
                  {"point": [0.0, 0.0], "component": "x"},
                  {"boundary": "footing", "gradient": [[0.0, 0.0], [0.0, -0.01]],
                   "component": "y", "origin": [0.0, 0.02]}],
    "platen": [{"boundary": "right", "component": "x"}],
    "pressure": [{"boundary": "right", "value": 1e5},
                 {"boundary": "left", "value": 2e4, "ramp": True}],
    "traction": [{"boundary": "top", "value": [1e3, -2e3]}],
    "body_force": {"value": [0.0, -2e4]},
    "micro": {"model": "linear_elastic", "young": 1e7, "poisson": 0.3},
}


def test_a_problem_file_is_built_through_the_public_api():
    problem = validate_problem(PROBLEM)
    macro = build_macro(problem)
    sup, f_const, f_ramp, loads = build_loads(problem, macro)

    mesh = hmm.cut_boundary(hmm.structured_mesh("quad8", [0.04, 0.08], [2, 3]),
                            "footing", of="top", lo=[0.0, 0.08], hi=[0.02, 0.08])
    mine = hmm.Macro(mesh, "quad8", "small")
    s2 = hmm.supports(mine, [hmm.Dirichlet("bottom", "y"),
                             hmm.Dirichlet(point=[0.0, 0.0], component=0),
                             hmm.Dirichlet("footing", "y", gradient=[[0, 0], [0, -0.01]],
                                           origin=[0.0, 0.02])],
                      platens=[hmm.Platen("right", "x")])
    c2, r2, l2 = hmm.external_forces(mine, [
        hmm.Pressure("right", 1e5), hmm.Pressure("left", 2e4, ramp=True),
        hmm.Traction("top", (1e3, -2e3)), hmm.BodyForce((0.0, -2e4))])
    np.testing.assert_array_equal(sup.dofs, s2.dofs)
    np.testing.assert_array_equal(sup.values, s2.values)
    assert [t.tolist() for t in sup.ties] == [t.tolist() for t in s2.ties]
    np.testing.assert_array_equal(f_const, c2)
    np.testing.assert_array_equal(f_ramp, r2)
    assert loads == l2 == ()
    # the footing moves by -0.01 (y - 0.02) = -6e-4 m at y = 0.08
    foot = mine.dofs("footing", 1)
    np.testing.assert_allclose(s2.values[np.searchsorted(s2.dofs, foot)], -6e-4,
                               rtol=1e-12)


def test_finite_kinematics_turns_follower_loads_into_configuration_loads():
    macro = hmm.Macro(hmm.structured_mesh("quad1", [1.0, 1.0], [1, 1]), "quad1", "finite")
    f_const, f_ramp, loads = hmm.external_forces(macro, [
        hmm.Pressure("right", 1e5), hmm.Pressure("left", 1e5, follower=False),
        hmm.Traction("top", (0.0, -1e3), per="current"), hmm.BodyForce((0.0, -1e4))])
    assert [type(x).__name__ for x in loads] == ["FollowerPressure", "CurrentTraction"]
    assert np.abs(f_const).max() > 0 and np.abs(f_ramp).max() > 0
    with pytest.raises(TypeError, match="a load must be a Pressure, Traction or BodyForce"):
        hmm.external_forces(macro, [hmm.Dirichlet("top", "y")])


MACRO = None


def unit_macro():
    global MACRO
    if MACRO is None:
        MACRO = hmm.Macro(hmm.structured_mesh("quad1", [1.0, 1.0], [2, 2]))
    return MACRO


@pytest.mark.parametrize("kwargs, message", [
    ({"dirichlet": [hmm.Dirichlet("top", "y"), hmm.Dirichlet("roof", "y")]},
     r'^dirichlet #2: boundary "roof" is not a boundary of the mesh \(known: bottom, '
     r"left, right, top\)$"),
    ({"dirichlet": [hmm.Dirichlet(point=[0.3, 0.0], component="x")]},
     r"^dirichlet #1: point = \[0.3, 0.0\] is not a vertex of the mesh$"),
    ({"dirichlet": [hmm.Dirichlet("top")]},
     r"^dirichlet #1: needs a component \(or a gradient\)$"),
    ({"dirichlet": [hmm.Dirichlet("top", "x", value=0.1, gradient=0.01)]},
     r"^dirichlet #1: takes a value or a gradient, not both$"),
    ({"dirichlet": [hmm.Dirichlet("top", "z")]},
     r"^dirichlet #1: component 'z' does not exist in 2D \(x, y or 0..1\)$"),
    ({"dirichlet": [hmm.Dirichlet("top", gradient=[[1.0, 0.0]])]},
     r"^dirichlet #1: gradient must be a number or 2 x 2, got shape \(1, 2\)$"),
    ({"dirichlet": [hmm.Dirichlet("top", "x")], "platens": [hmm.Platen("top", "x")]},
     r'^platen #1: boundary "top" x is also held'),
    ({"dirichlet": [hmm.Dirichlet("top", "x")], "gradient": 0.01},
     r"^gradient applies to periodic pairs: none given$"),
    ({"dirichlet": [hmm.Dirichlet(point=[0.0, 0.0], gradient=0.0)],
      "periodic": [hmm.Periodic("left", "top")]},
     r'^periodic #1: the nodes of "top" are not those of "left" shifted by \[0.5, 0.5\] m'),
])
def test_conditions_that_do_not_fit_name_the_condition(kwargs, message):
    with pytest.raises(ValueError, match=message):
        hmm.supports(unit_macro(), **kwargs)


def test_make_farm_is_serial_outside_mpi():
    farm = hmm.make_farm(3, 2, lambda g: hmm.LinearElastic(1e6 * (g + 1), 0.25))
    assert isinstance(farm, hmm.SerialFarm) and farm.n == 3
    assert [m.tangent[0, 0, 0, 0] for m in farm.models] == pytest.approx(
        [1e6 * (g + 1) * 0.75 / (1.25 * 0.5) for g in range(3)])


def test_the_api_page_is_linked():
    for page in ("README.md", "docs/multiscale.md"):
        assert "python_api.md" in (ROOT / page).read_text(), page
