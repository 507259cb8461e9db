"""Shapes as signed distance functions in the body frame.

A shape is the zero level set of its signed distance function ``sdf(X)`` (negative
inside), written in the body's reference frame: centre of mass at the origin, principal
axes along the frame axes. Each shape supplies its SDF kernel, a bounding radius and its
mass properties. This module holds the kinds the engine knows (:class:`Shape`) and the
shapes themselves.
"""

from enum import IntEnum

from .box import Box
from .compound import Compound
from .custom import CustomShape
from .plane import Plane, sdf_plane
from .polygon import ConvexPolygon
from .polyhedron import ConvexPolyhedron
from .sphere import Sphere, sdf_sphere


class Shape(IntEnum):
    """Shape kinds; the pair of kinds decides the contact bucket (geometry kernel)."""

    SPHERE = 0      # a disk in 2D
    PLANE = 1       # a half-space wall (a line in 2D)
    BOX = 2         # a rectangle in 2D
    POLYGON = 3     # convex, 2D
    POLYHEDRON = 4  # convex, 3D
    CUSTOM = 5      # a user-defined SDF
    COMPOUND = 6    # a union of convex parts (each part its own contact)


__all__ = ["Box", "Compound", "ConvexPolygon", "ConvexPolyhedron", "CustomShape", "Plane",
           "Shape", "Sphere", "sdf_plane", "sdf_sphere"]
