"""The shape kinds, defined once: :class:`Shape` and its codes as plain integers.

A body's ``kind`` (``Bodies.kind``) and a shape-table row's ``kind``
(``ShapeTable.kind``) hold these codes; the pair of kinds decides a contact's bucket
(its geometry kernel). Compiled kernels compare against the plain integers below,
which numba freezes as constants, so a branch on a constant kind folds away at
compile time. Both forms come from the one enum: no other module binds a kind's name
to a number (``tests/test_architecture.py``).
"""

from enum import IntEnum


class Shape(IntEnum):
    """Shape kinds; the pair of kinds decides the contact bucket (geometry kernel)."""

    SPHERE = 0      # a disk in 2D
    PLANE = 1       # a half-space wall (a line in 2D)
    BOX = 2         # a rectangle in 2D
    POLYGON = 3     # convex, 2D
    POLYHEDRON = 4  # convex, 3D
    CUSTOM = 5      # a user-defined SDF
    COMPOUND = 6    # a union of convex parts (each part its own contact)


SPHERE = int(Shape.SPHERE)
PLANE = int(Shape.PLANE)
BOX = int(Shape.BOX)
POLYGON = int(Shape.POLYGON)
POLYHEDRON = int(Shape.POLYHEDRON)
CUSTOM = int(Shape.CUSTOM)
COMPOUND = int(Shape.COMPOUND)

__all__ = ["BOX", "COMPOUND", "CUSTOM", "PLANE", "POLYGON", "POLYHEDRON", "SPHERE", "Shape"]
