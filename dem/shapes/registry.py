"""The shapes the engine knows: one class per kind, and what each kind can do.

Each shape's own file states its kind (``code``, from :mod:`dem.shapes.kinds`) and its
traits as class attributes:

``polytope``
    it has vertices and faces: the exact polytope detection of
    :mod:`dem.contact.detection.polytope` serves its pairs, a periodic RVE takes it,
    and the XDMF output draws its surface;
``stored``
    it is a row of the shape table that a checkpoint or packing file keeps (spheres
    and planes need no row; a user's SDF is code, not data).

The modules that choose by kind ask :func:`kinds_with` rather than listing kinds, so a
new kind of shape is its own file, its code in :mod:`dem.shapes.kinds` and a line here.
"""

from .box import Box
from .compound import Compound
from .custom import CustomShape
from .kinds import Shape
from .plane import Plane
from .polygon import ConvexPolygon
from .polyhedron import ConvexPolyhedron
from .sphere import Sphere

#: the class of each kind, by code
SHAPES = {int(cls.code): cls for cls in (Sphere, Plane, Box, ConvexPolygon,
                                         ConvexPolyhedron, CustomShape, Compound)}
#: the traits every shape class states
TRAITS = ("polytope", "stored")


def kinds_with(trait):
    """The kinds (:class:`Shape`, in code order) whose shape has ``trait``.

    >>> [k.name for k in kinds_with("polytope")]
    ['BOX', 'POLYGON', 'POLYHEDRON']
    >>> [k.name for k in kinds_with("stored")]
    ['BOX', 'POLYGON', 'POLYHEDRON', 'COMPOUND']
    """
    if trait not in TRAITS:
        raise ValueError(f"unknown shape trait {trait!r}; known: {', '.join(TRAITS)}")
    return tuple(Shape(code) for code, cls in sorted(SHAPES.items()) if getattr(cls, trait))


__all__ = ["SHAPES", "TRAITS", "kinds_with"]
