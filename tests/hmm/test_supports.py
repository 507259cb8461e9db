"""Supports that hold a body, and those that do not.

A rigid motion the supports leave free makes the tangent singular: the problem file is
refused in one line naming the motion (the null space of the rigid modes on the held
degrees of freedom, so a rotation about an axis through any point counts). A
prescribed displacement that the supports turn into a rigid rotation is no such case:
the body carries no stress, and the step converges at once.
"""

import numpy as np
import pytest

import hmm
from dem.io.schema import SceneError
from hmm.conditions import Dirichlet, Periodic, free_rigid_motions, supports
from hmm.macro import Macro, structured_mesh
from hmm.problem import validate_problem
from hmm.run import run_problem


def _held(element, size, cells, conditions, periodic=()):
    macro = Macro(structured_mesh(element, size, cells), element=element)
    return free_rigid_motions(macro, supports(macro, conditions, periodic=periodic))


@pytest.mark.parametrize("conditions, free", [
    ([Dirichlet("bottom", "y")], ["a translation along x"]),
    ([Dirichlet("left", "x")], ["a translation along y"]),
    ([Dirichlet("bottom", "y"), Dirichlet("left", "x")], []),
    # one point held in x: the bottom's y and that point stop every rigid motion
    ([Dirichlet("bottom", "y"), Dirichlet(None, "x", point=[0.0, 0.0])], []),
    ([], ["a translation along x", "a translation along y",
          "a rotation about an axis along z"]),
])
def test_rigid_motions_left_free_in_2d(conditions, free):
    assert sorted(_held("quad2", [1.0, 2.0], [2, 2], conditions)) == sorted(free)


def test_rigid_motions_left_free_in_3d():
    fix = [Dirichlet("bottom", "y"), Dirichlet("left", "x"), Dirichlet("front", "z")]
    assert _held("hex20", [1.0, 2.0, 1.0], [1, 2, 1], fix) == []
    # the bottom held in y and z: x slides
    free = _held("hex1", [1.0, 2.0, 1.0], [2, 2, 2],
                 [Dirichlet("bottom", "y"), Dirichlet("bottom", "z")])
    assert free == ["a translation along x"]
    # held only where the axis of a rotation about x through the origin meets them:
    # the bottom (y = 0) in z and the front (z = 0) in y
    free = _held("hex1", [1.0, 2.0, 1.0], [2, 2, 2],
                 [Dirichlet("bottom", "z"), Dirichlet("front", "y"), Dirichlet("left", "x")])
    assert free == ["a rotation about an axis along x"]


def test_periodic_pairs_need_a_point_held():
    pairs = [Periodic("left", "right"), Periodic("bottom", "top")]
    assert sorted(_held("quad1", [1.0, 1.0], [2, 2], [], pairs)) == [
        "a translation along x", "a translation along y"]
    point = [Dirichlet(None, c, point=[0.0, 0.0]) for c in "xy"]
    assert _held("quad1", [1.0, 1.0], [2, 2], point, pairs) == []


def _problem(dirichlet, element="hex1"):
    return validate_problem({
        "mesh": {"dim": 3, "element": element, "size": [0.05, 0.1, 0.05],
                 "cells": [2, 4, 2]},
        "dirichlet": dirichlet, "load": {"steps": 1},
        "micro": {"model": "linear_elastic", "young": 1e7, "poisson": 0.3}})


def test_a_problem_that_leaves_a_body_free_is_refused_in_one_line(tmp_path):
    problem = _problem([{"boundary": "bottom", "component": c} for c in "yz"]
                       + [{"boundary": "top", "component": "y", "value": -1e-4}])
    with pytest.raises(SceneError) as err:
        run_problem(problem, tmp_path, progress=False)
    msg = str(err.value)
    assert "\n" not in msg
    assert "leave a translation along x free: no load step can converge" in msg


@pytest.mark.parametrize("element", ["hex1", "tet1"])
def test_a_prescribed_rigid_rotation_converges_with_no_stress(tmp_path, element):
    """The top (y = 0.1 m) pushed 0.1 mm in z, the bottom held in z, the front in y,
    the left in x: the solution is the rotation about x of 1e-3 rad through the
    origin, which the small-strain body takes without stress. It once never
    converged: the residual was compared with an internal force of round-off."""
    problem = _problem([{"boundary": "bottom", "component": "z"},
                        {"boundary": "front", "component": "y"},
                        {"boundary": "left", "component": "x"},
                        {"boundary": "top", "component": "z", "value": -1e-4}], element)
    out = run_problem(problem, tmp_path, progress=False)
    assert out["iterations"] == [1] and out["cuts"] == 0
    f = hmm.read_fields(tmp_path / "fields.h5")
    u = f.fields["displacement"][-1]
    x = f.points.T if f.points.shape[0] == 3 else f.points
    theta = -1e-4 / 0.1
    np.testing.assert_allclose(u[:, 2], theta * x[:, 1], atol=1e-12)
    np.testing.assert_allclose(u[:, 1], -theta * x[:, 2], atol=1e-12)
    np.testing.assert_allclose(u[:, 0], 0.0, atol=1e-12)
    assert np.abs(f.fields["gauss/stress"][-1]).max() < 1e-6  # [Pa], of E = 1e7 Pa
