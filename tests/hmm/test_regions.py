"""Named parts of boundaries (``[[boundary]]``) and weak spots (``[[imperfection]]``)
in problem files."""

import copy

import numpy as np
import pytest

from dem.io.schema import SceneError
from hmm.problem import validate_problem
from hmm.problem_build import build_macro, model_factory, spot_of
from hmm.run import run_problem

ELASTIC = {
    "mesh": {"size": [1.0, 1.0], "cells": [4, 2]},
    "dirichlet": [{"boundary": "bottom", "component": "y"},
                  {"boundary": "left", "component": "x"},
                  {"boundary": "top", "component": "y", "value": -0.01}],
    "micro": {"model": "linear_elastic", "young": 1e6, "poisson": 0.3},
    "load": {"steps": 1},
}


def _split_top(prob):
    """The same problem with the top platen given as two cut boundaries."""
    prob = copy.deepcopy(prob)
    prob["boundary"] = [{"name": "a", "of": "top", "lo": [0.0, 1.0], "hi": [0.25, 1.0]},
                        {"name": "b", "of": "top", "lo": [0.25, 1.0], "hi": [1.0, 1.0]}]
    prob["dirichlet"][2:] = [{"boundary": n, "component": "y", "value": -0.01}
                             for n in ("a", "b")]
    return prob


def test_cut_boundaries_partition_their_parent_and_load_it_the_same(tmp_path):
    whole = validate_problem(ELASTIC)
    split = validate_problem(_split_top(ELASTIC))
    b = build_macro(split).mesh.boundaries
    assert len(b["a"]) == 1 and len(b["b"]) == 3
    assert sorted(np.concatenate([b["a"], b["b"]])) == sorted(b["top"])
    u1 = run_problem(whole, tmp_path / "whole", progress=False)
    u2 = run_problem(split, tmp_path / "split", progress=False)
    np.testing.assert_allclose(u2["u"], u1["u"], rtol=0, atol=1e-15)
    # the platen pulls the body down on both parts (they share one node)
    assert u2["reactions"]["a"][1] < 0.0 and u2["reactions"]["b"][1] < 0.0


@pytest.mark.parametrize("edit, message", [
    (lambda b: b.update(of="roof"), 'of = "roof" is not a boundary of the mesh'),
    (lambda b: b.update(name="left"), 'name = "left" is taken'),
    (lambda b: b.update(lo=[2.0, 1.0], hi=[3.0, 1.0]), 'no facet of "top"'),
])
def test_bad_cut_boundaries_name_the_key(edit, message):
    prob = _split_top(ELASTIC)
    edit(prob["boundary"][0])
    with pytest.raises(SceneError, match=message) as err:
        build_macro(validate_problem(prob))
    assert "[[boundary]] #1" in str(err.value) and "\n" not in str(err.value)


def _graded(prob, x, y):
    prob = copy.deepcopy(prob)
    del prob["mesh"]["size"], prob["mesh"]["cells"]
    prob["mesh"].update(x=x, y=y)
    return prob


def test_a_graded_mesh_has_its_edges_and_passes_the_patch_test(tmp_path):
    """Element edges given per axis: a uniform choice builds the structured mesh's
    problem to round-off; a graded one (a row 0.03 high, as under a retaining wall's
    toe) has a vertex on every edge, a boundary cut at the row's top holds that row
    alone, and the uniaxial compression stays uniform, at the plane-strain closed
    form, in every element."""
    uniform = _graded(ELASTIC, [0.0, 0.25, 0.5, 0.75, 1.0], [0.0, 0.5, 1.0])
    u0 = run_problem(validate_problem(ELASTIC), tmp_path / "cells", progress=False)
    u1 = run_problem(validate_problem(uniform), tmp_path / "edges", progress=False)
    np.testing.assert_allclose(u1["u"], u0["u"], rtol=0, atol=1e-15)
    graded = _graded(ELASTIC, [0.0, 0.1, 0.4, 1.0], [0.0, 0.03, 0.2, 1.0])
    graded["boundary"] = [{"name": "toe", "of": "right", "lo": [1.0, 0.0],
                           "hi": [1.0, 0.03]}]
    prob = validate_problem(graded)
    mesh = build_macro(prob).mesh
    assert sorted(set(mesh.p[1].round(12))) == [0.0, 0.03, 0.2, 1.0]
    assert len(mesh.boundaries["toe"]) == 1
    run_problem(prob, tmp_path / "graded", progress=False)
    import h5py

    with h5py.File(tmp_path / "graded" / "fields.h5") as f:
        sig = f["steps/00001/gauss/stress"][()]
    e, nu = 1e6, 0.3
    np.testing.assert_allclose(sig[:, 1, 1], e * -0.01 / (1.0 - nu**2), rtol=1e-10)
    np.testing.assert_allclose(sig[:, 0, 0], 0.0, atol=1e-6)


@pytest.mark.parametrize("edit, message", [
    (lambda m: m.update(x=[0.0, 0.5, 0.5, 1.0]), "x must increase from each number"),
    (lambda m: m.update(x=[1.0]), "x must be an array of at least 2 increasing"),
    (lambda m: m.pop("y"), r"needs the element edges along every axis \(x, y\)"),
    (lambda m: m.update(size=[1.0, 1.0]), "takes the element edges x, y, or size"),
    (lambda m: [m.pop(a) for a in "xy"], r"needs size and cells, the element edges"),
])
def test_bad_element_edges_name_the_key(edit, message):
    prob = _graded(ELASTIC, [0.0, 0.5, 1.0], [0.0, 1.0])
    edit(prob["mesh"])
    with pytest.raises(SceneError, match=message) as err:
        validate_problem(prob)
    assert "[mesh]" in str(err.value) and "\n" not in str(err.value)


def test_imperfection_needs_dem_points():
    prob = copy.deepcopy(ELASTIC)
    prob["imperfection"] = [{"center": [0.5, 0.5], "radius": 0.1}]
    with pytest.raises(SceneError, match=r'\[\[imperfection\]\] #1 needs \[micro\]'):
        validate_problem(prob)


def test_spot_points_take_the_first_spot_that_holds_them():
    prob = {"imperfection": [{"center": [0.0, 0.0], "radius": 1.0},
                             {"center": [1.0, 0.0], "radius": 1.0}]}
    pts = np.array([[0.5, 0.0], [1.5, 0.0], [3.0, 0.0], [-1.0, 0.0]])
    assert spot_of(prob, pts).tolist() == [0, 1, -1, 0]


def test_weak_spot_points_start_from_their_own_packing():
    """Gauss points in the spot get its friction and its looser consolidation; the
    others share the ordinary packing."""
    prob = copy.deepcopy(ELASTIC)
    prob["mesh"]["cells"] = [2, 1]
    prob["micro"] = {"model": "dem", "count": 16, "p0": 1e5, "seed": 3,
                     "consolidation_friction": 0.0, "mu": 0.5}
    prob["imperfection"] = [{"center": [0.0, 0.0], "radius": 0.3, "mu": 0.25,
                             "consolidation_friction": 0.5}]
    prob = validate_problem(prob)
    macro = build_macro(prob)
    pts = macro.gauss_points()
    spot = spot_of(prob, pts)
    assert spot.tolist().count(0) == 1  # the Gauss point next to the corner
    make = model_factory(prob, 2, points=pts)
    models = [make(g) for g in range(macro.n_gp)]
    mu = np.array([m.rve.law.mu for m in models])
    voids = np.array([m.measures()["void_ratio"] for m in models])
    weak = spot == 0
    assert np.all(mu[weak] == 0.25) and np.all(mu[~weak] == 0.5)
    assert np.all(voids[~weak] == voids[~weak][0])  # one ordinary packing, copied
    assert voids[weak][0] > voids[~weak][0]  # consolidated with friction: looser
    with pytest.raises(ValueError, match="coordinates"):
        model_factory(prob, 2)


def test_point_support_holds_one_vertex_and_lets_the_base_widen(tmp_path):
    """A smooth base held in x at its middle vertex only: under a symmetric vertical
    load the elastic body widens symmetrically about that vertex (Poisson), the
    point carries no horizontal force, and u_x is exactly zero there alone."""
    prob = copy.deepcopy(ELASTIC)
    prob["dirichlet"][1] = {"point": [0.5, 0.0], "component": "x"}
    prob = validate_problem(prob)
    s = run_problem(prob, tmp_path / "out", progress=False)
    macro = build_macro(prob)
    ux = macro.nodal_displacement(s["u"])[:, 0]
    x, y = macro.mesh.p
    base = np.isclose(y, 0.0)
    mid = base & np.isclose(x, 0.5)
    assert ux[mid] == 0.0
    assert np.all(ux[base & (x > 0.5)] > 0.0) and np.all(ux[base & (x < 0.5)] < 0.0)
    np.testing.assert_allclose(ux[base & np.isclose(x, 0.0)],
                               -ux[base & np.isclose(x, 1.0)], rtol=1e-9)
    assert "left" not in s["reactions"]  # a point is not a boundary with a reaction


@pytest.mark.parametrize("entry, message", [
    ({"point": [0.4, 0.0], "component": "x"}, r"point = \[0.4, 0.0\] is not a vertex"),
    ({"component": "x"}, "needs a boundary or a point"),
    ({"boundary": "left", "point": [0.5, 0.0], "component": "x"},
     "needs a boundary or a point"),
])
def test_bad_point_supports_name_the_key(entry, message):
    prob = copy.deepcopy(ELASTIC)
    prob["dirichlet"][1] = entry
    with pytest.raises(SceneError, match=message) as err:
        build_macro(validate_problem(prob))
    assert "[[dirichlet]] #2" in str(err.value) and "\n" not in str(err.value)
