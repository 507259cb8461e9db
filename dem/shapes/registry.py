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

and two descriptions:

``grains``
    what a packing of them is called in 2D and 3D (``("disks", "spheres")``), or None
    (a wall, a user's shape): the summaries of laboratory tests say it;
``packing``
    its name as the shape of a generated packing (``[packing] shape`` of ``hmm rve``,
    ``[micro] shape`` of a problem file), or None; such a class has
    ``packing_maker(keys, dim)``, the ``shape(r, rng)`` of :func:`dem.rve.generate`.

The modules that choose by kind ask :func:`kinds_with`, :func:`grain_name` and
:func:`packing_shapes` rather than listing kinds, so a new kind of shape is its own
file, its code in :mod:`dem.shapes.kinds` and a line here.
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
#: the descriptions every shape class states (a value or None)
DESCRIPTIONS = ("grains", "packing")


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


def grain_name(kind, dim):
    """What a packing of bodies of ``kind`` is called in ``dim`` (2 or 3), or None.

    >>> grain_name(Shape.SPHERE, 2), grain_name(Shape.BOX, 3), grain_name(Shape.PLANE, 3)
    ('disks', 'cubes', None)
    """
    names = SHAPES[int(kind)].grains
    return None if names is None else names[dim - 2]


def packing_shapes():
    """The shapes a packing can be generated of, by name (in code order), with their
    classes.

    >>> list(packing_shapes())
    ['sphere', 'box', 'polygon']
    """
    return {cls.packing: cls for _, cls in sorted(SHAPES.items()) if cls.packing}


def packing_maker(name, keys, dim):
    """The ``shape(r, rng)`` of :func:`dem.rve.generate` for a generated packing of
    shape ``name`` (:func:`packing_shapes`), from its section's keys (``sides``,
    ``sides_max`` for polygons); None for spheres."""
    shapes = packing_shapes()
    if name not in shapes:
        raise ValueError(f"no generated packings of shape {name!r}; known: "
                         f"{', '.join(shapes)}")
    return shapes[name].packing_maker(keys, dim)


__all__ = ["DESCRIPTIONS", "SHAPES", "TRAITS", "grain_name", "kinds_with", "packing_maker",
           "packing_shapes"]
