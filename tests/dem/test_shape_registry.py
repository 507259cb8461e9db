"""The shape registry: every kind has one class stating its traits, and the modules that
choose by kind follow the classes (dem/shapes/registry.py)."""

import pytest

from dem.contact import shape_contacts as sc
from dem.io import checkpoint, geometry
from dem.rve import POLYTOPES
from dem.shapes import Box, ConvexPolygon, Shape
from dem.shapes.registry import (DESCRIPTIONS, SHAPES, TRAITS, grain_name, kinds_with,
                                 packing_maker, packing_shapes)


def test_every_kind_has_one_class_that_states_every_trait():
    assert sorted(SHAPES) == sorted(int(k) for k in Shape)
    for code, cls in SHAPES.items():
        assert int(cls.code) == code
        for trait in TRAITS:
            assert isinstance(cls.__dict__.get(trait), bool), (
                f"{cls.__name__} does not state {trait!r} in its own class body")
        for name in DESCRIPTIONS:
            assert name in cls.__dict__, (
                f"{cls.__name__} does not state {name!r} in its own class body")
        if cls.packing is not None:
            assert "packing_maker" in cls.__dict__, cls.__name__


def test_the_modules_that_choose_by_kind_read_the_registry():
    assert kinds_with("polytope") == (Shape.BOX, Shape.POLYGON, Shape.POLYHEDRON)
    assert kinds_with("stored") == (Shape.BOX, Shape.POLYGON, Shape.POLYHEDRON,
                                    Shape.COMPOUND)
    assert POLYTOPES == kinds_with("polytope")
    assert geometry.SURFACE_KINDS == kinds_with("polytope")
    assert checkpoint._STORABLE_KINDS == kinds_with("stored")


def test_detection_follows_the_polytope_trait(monkeypatch):
    """Each pair of polytope kinds gets the exact polytope solver; a kind that stops
    being a polytope loses it, with the error that names the kinds."""
    for ka in kinds_with("polytope"):
        for kb in kinds_with("polytope"):
            if ka <= kb:
                assert sc.method_for(ka, kb) == sc.M_POLY
    assert sc.method_for(Shape.SPHERE, Shape.BOX) == sc.M_SPHERE_BOX
    assert sc.method_for(Shape.SPHERE, Shape.POLYGON) == sc.M_SPHERE_POLY
    assert sc.method_for(Shape.POLYGON, Shape.CUSTOM) == sc.M_ADMM
    monkeypatch.setattr(ConvexPolygon, "polytope", False)
    with pytest.raises(ValueError, match="no contact detection for shape kinds 3 and 3"):
        sc.method_for(Shape.POLYGON, Shape.POLYGON)


def test_an_unknown_trait_is_refused_with_the_known_ones():
    with pytest.raises(ValueError, match="unknown shape trait 'round'; known: polytope, "
                                         "stored"):
        kinds_with("round")


def test_packings_and_summaries_read_the_registry(monkeypatch):
    """The files' shape choices, the packing generator's shapes and the summaries'
    names of the grains come from the shape classes."""
    import numpy as np

    import dem
    from hmm.experiment_config import RVE_SCHEMA, shape_maker
    from hmm.experiment_summary import grains
    from hmm.problem_schema import SCHEMA as PROBLEM

    names = tuple(packing_shapes())
    assert names == ("sphere", "box", "polygon")
    assert RVE_SCHEMA["packing"].keys["shape"].choices == names
    assert PROBLEM["micro"].keys["shape"].choices == names
    rng = np.random.default_rng(0)
    assert shape_maker({"shape": "sphere", "dim": 2}) is None
    cube = shape_maker({"shape": "box", "dim": 3})(0.3, rng)
    assert isinstance(cube, Box) and np.allclose(np.linalg.norm(cube.half_extents), 0.3)
    hexagon = shape_maker({"shape": "polygon", "dim": 2, "sides": 6, "sides_max": None})
    assert hexagon(1.0, rng).vertices.shape == (6, 2)
    with pytest.raises(ValueError, match="no generated packings of shape 'cone'; known: "
                                         "sphere, box, polygon"):
        packing_maker("cone", {}, 3)
    b = dem.Bodies.spheres([[0.0, 0.0], [1.0, 0.0]], radius=0.1, density=1000.0)
    assert grains(b) == "disks" == grain_name(Shape.SPHERE, 2)
    monkeypatch.setattr(dem.shapes.Sphere, "grains", ("coins", "balls"))
    assert grains(b) == "coins"
    assert grain_name(Shape.PLANE, 3) is None
