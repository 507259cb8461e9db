"""Shapes as signed distance functions in the body frame.

A shape is the zero level set of its signed distance function ``sdf(X)`` (negative
inside), written in the body's reference frame: centre of mass at the origin, principal
axes along the frame axes. Each shape supplies its SDF kernel, a bounding radius and its
mass properties. This module holds the kinds the engine knows (:class:`Shape`) and the
shapes themselves.
"""

from enum import IntEnum

from .plane import Plane, sdf_plane
from .sphere import Sphere, sdf_sphere


class Shape(IntEnum):
    """Shape kinds; the pair of kinds decides the contact bucket (geometry kernel)."""

    SPHERE = 0  # a disk in 2D
    PLANE = 1   # a half-space wall (a line in 2D)


__all__ = ["Shape", "Sphere", "Plane", "sdf_sphere", "sdf_plane"]
