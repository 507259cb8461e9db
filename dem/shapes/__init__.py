"""Shapes as signed distance functions in the body frame.

A shape is the zero level set of its signed distance function ``sdf(X)`` (negative
inside), written in the body's reference frame: centre of mass at the origin, principal
axes along the frame axes. Each shape supplies its SDF kernel, a bounding radius and its
mass properties. This package holds the kinds the engine knows (:class:`Shape`, defined in
:mod:`dem.shapes.kinds`) and the shapes themselves.
"""

from .box import Box
from .compound import Compound
from .custom import CustomShape
from .kinds import Shape
from .plane import Plane, sdf_plane
from .polygon import ConvexPolygon
from .polyhedron import ConvexPolyhedron
from .sphere import Sphere, sdf_sphere

__all__ = ["Box", "Compound", "ConvexPolygon", "ConvexPolyhedron", "CustomShape", "Plane",
           "Shape", "Sphere", "sdf_plane", "sdf_sphere"]
