"""The shape registry: every kind has one class stating its traits, and the modules that
choose by kind follow the classes (dem/shapes/registry.py)."""

import pytest

from dem.contact import shape_contacts as sc
from dem.io import checkpoint, geometry
from dem.rve import POLYTOPES
from dem.shapes import ConvexPolygon, Shape
from dem.shapes.registry import SHAPES, TRAITS, kinds_with


def test_every_kind_has_one_class_that_states_every_trait():
    assert sorted(SHAPES) == sorted(int(k) for k in Shape)
    for code, cls in SHAPES.items():
        assert int(cls.code) == code
        for trait in TRAITS:
            assert isinstance(cls.__dict__.get(trait), bool), (
                f"{cls.__name__} does not state {trait!r} in its own class body")


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
