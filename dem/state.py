"""The particle table: every body of a scene as one struct-of-arrays.

Row ``i`` of every field is body ``i``. A scene is 2D or 3D and the arrays say so: a 2D
scene stores ``pos`` as (n, 2), one rotation angle per body in ``rot`` (n, 1) and a
scalar angular velocity in ``ang_vel`` (n, 1); a 3D scene stores unit quaternions
``rot`` (n, 4) as (w, x, y, z), body to world, and ``ang_vel`` (n, 3) in the world frame.
Walls (planes) are bodies too: fixed, moved only by their prescribed velocity.
"""

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .contact.detection.admm.solver import N_WARM
from .rotation import matrix_to_quat, quat_mul, quat_rotate
from .shapes import Plane, Shape
from .shapes.table import ShapeTable


def n_rot(dim):
    """Rotational degrees of freedom: 1 in 2D, 3 in 3D."""
    return 1 if dim == 2 else 3


@dataclass(eq=False)
class Bodies:
    """Struct-of-arrays particle table (SI units).

    Attributes
    ----------
    pos : (n, d) float64 [m]
    vel : (n, d) float64 [m/s]
    rot : (n, 4) float64 unit quaternion (w, x, y, z) in 3D; (n, 1) angle [rad] in 2D
    ang_vel : (n, 3) float64 [rad/s] world frame in 3D; (n, 1) in 2D
    force : (n, d) float64 [N], the force of the last step
    torque : (n, 3) or (n, 1) float64 [N m]
    radius : (n,) float64 [m], bounding radius (the radius for spheres; 0 for planes)
    mass : (n,) float64 [kg] (inf for fixed bodies)
    inertia : (n, 3) or (n, 1) float64 principal moments [kg m^2]
    kind : (n,) int32, :class:`dem.shapes.Shape` of each body
    mat_id : (n,) int32, material row in the contact model's parameter table
    is_fixed : (n,) bool, moved only by its prescribed ``vel``; forces do not act on it
    normal : (n, d) float64, world-frame normal of plane bodies (zero rows otherwise)
    density : (n,) float64 [kg/m^3]
    shape : (n,) int32, row of the body's shape in ``table`` (-1 for spheres and planes)
    table : ShapeTable, the non-sphere shapes (see :mod:`dem.shapes.table`)
    """

    dim: int
    pos: np.ndarray
    vel: np.ndarray
    rot: np.ndarray
    ang_vel: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    radius: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    kind: np.ndarray
    mat_id: np.ndarray
    is_fixed: np.ndarray
    normal: np.ndarray
    density: np.ndarray = field(default=None)
    shape: np.ndarray = field(default=None)
    table: ShapeTable = field(default=None)

    def __post_init__(self):
        if self.shape is None:
            self.shape = np.full(self.pos.shape[0], -1, np.int32)
        if self.table is None:
            self.table = ShapeTable()

    # ------------------------------------------------------------------ construction
    @classmethod
    def empty(cls, dim):
        """A table with no bodies, for scenes of dimension ``dim`` (2 or 3)."""
        if dim not in (2, 3):
            raise ValueError(f"dimension must be 2 or 3, got {dim}")
        nr = n_rot(dim)
        z = lambda *s: np.zeros(s, dtype=np.float64)  # noqa: E731
        return cls(dim=dim, pos=z(0, dim), vel=z(0, dim), rot=z(0, 4 if dim == 3 else 1),
                   ang_vel=z(0, nr), force=z(0, dim), torque=z(0, nr), radius=z(0),
                   mass=z(0), inertia=z(0, nr), kind=np.zeros(0, np.int32),
                   mat_id=np.zeros(0, np.int32), is_fixed=np.zeros(0, bool),
                   normal=z(0, dim), density=z(0), shape=np.zeros(0, np.int32),
                   table=ShapeTable())

    @classmethod
    def spheres(cls, pos, radius, density, vel=None, mat_id=0):
        """Spheres (3D) or disks (2D) at ``pos``; the dimension is ``pos.shape[1]``.

        Parameters
        ----------
        pos : (n, d) array_like [m], d = 2 or 3
        radius : float or (n,) array_like [m], > 0
        density : float or (n,) array_like [kg/m^3] (per unit thickness in 2D), > 0
        vel : (n, d) array_like [m/s], optional
        mat_id : int or (n,) array_like, material index

        Examples
        --------
        >>> b = Bodies.spheres([[0.0, 0.0], [1.0, 0.0]], radius=0.5, density=1.0)
        >>> b.dim, b.n, round(float(b.mass[0]), 6)
        (2, 2, 0.785398)
        """
        pos = np.atleast_2d(np.asarray(pos, dtype=np.float64))
        if pos.ndim != 2 or pos.shape[1] not in (2, 3):
            raise ValueError(f"pos must have shape (n, 2) or (n, 3), got {pos.shape}")
        b = cls.empty(pos.shape[1])
        b.add_spheres(pos, radius, density, vel=vel, mat_id=mat_id)
        return b

    def add_spheres(self, pos, radius, density, vel=None, mat_id=0):
        """Append spheres/disks; returns their body indices (int32 array)."""
        pos = np.atleast_2d(np.asarray(pos, dtype=np.float64))
        n, d = pos.shape
        if d != self.dim:
            raise ValueError(f"pos has dimension {d}, the scene is {self.dim}D")
        radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), (n,)).copy()
        density = np.broadcast_to(np.asarray(density, dtype=np.float64), (n,)).copy()
        if not np.all(np.isfinite(pos)):
            raise ValueError("pos must be finite")
        if not np.all(radius > 0.0) or not np.all(np.isfinite(radius)):
            raise ValueError("radius must be positive and finite")
        if not np.all(density > 0.0) or not np.all(np.isfinite(density)):
            raise ValueError("density must be positive and finite")
        vol = 4.0 / 3.0 * np.pi * radius**3 if d == 3 else np.pi * radius**2
        mass = density * vol
        nr = n_rot(d)
        k = 0.4 if d == 3 else 0.5
        inertia = np.repeat((k * mass * radius**2)[:, None], nr, axis=1)
        rot = np.zeros((n, 4 if d == 3 else 1))
        if d == 3:
            rot[:, 0] = 1.0
        v = np.zeros((n, d)) if vel is None else np.broadcast_to(
            np.asarray(vel, dtype=np.float64), (n, d)).copy()
        if not np.all(np.isfinite(v)):
            raise ValueError("vel must be finite")
        return self._append(pos=pos, vel=v, rot=rot, radius=radius, mass=mass,
                            inertia=inertia, kind=Shape.SPHERE, mat_id=mat_id,
                            is_fixed=False, normal=np.zeros((n, d)), density=density)

    def add_plane(self, point, normal, velocity=None, mat_id=0):
        """Append a wall through ``point`` (d,) [m] with free-side ``normal`` (d,).

        The wall is a fixed body: it moves with its prescribed ``velocity`` (d,) [m/s]
        and forces do not act on it. Returns its body index.
        """
        shape = Plane(normal)
        point = np.asarray(point, dtype=np.float64).reshape(1, -1)
        if point.shape[1] != self.dim or shape.normal.shape[0] != self.dim:
            raise ValueError(f"a wall in a {self.dim}D scene needs {self.dim}D point and normal")
        v = np.zeros((1, self.dim)) if velocity is None else np.asarray(
            velocity, dtype=np.float64).reshape(1, self.dim)
        if not np.all(np.isfinite(point)) or not np.all(np.isfinite(v)):
            raise ValueError("wall point and velocity must be finite")
        rot = np.zeros((1, 4 if self.dim == 3 else 1))
        if self.dim == 3:
            rot[:, 0] = 1.0
        idx = self._append(pos=point, vel=v, rot=rot, radius=np.zeros(1),
                           mass=np.full(1, np.inf), inertia=np.full((1, n_rot(self.dim)), np.inf),
                           kind=Shape.PLANE, mat_id=mat_id, is_fixed=True,
                           normal=shape.normal[None, :], density=np.zeros(1))
        return int(idx[0])

    def add_shapes(self, shape, pos, density, rot=None, vel=None, ang_vel=None, mat_id=0):
        """Append bodies of one level-set ``shape`` (Box, ConvexPolygon, ...); returns ids.

        The shape may be given in any frame: it is re-centred on its centre of mass and
        turned onto its principal axes (:meth:`principal`), and each body is placed so
        that the shape's own frame sits at ``pos`` with orientation ``rot``. All bodies
        share one row of the shape table unless a state object later grows them.

        Parameters
        ----------
        shape : a shape object with ``principal``/``rows`` (see :mod:`dem.shapes`)
        pos : (n, d) array_like [m], where each body puts the origin of the shape's frame
        density : float [kg/m^3] (per metre of thickness in 2D), > 0
        rot : (n,) angles [rad] in 2D, (n, 4) unit quaternions (w, x, y, z) in 3D, optional
        vel : (n, d) [m/s], optional; ang_vel : (n, 1) or (n, 3) [rad/s], world frame
        mat_id : int or (n,) material index

        Examples
        --------
        >>> from dem.shapes import Box
        >>> b = Bodies.empty(2)
        >>> ids = b.add_shapes(Box([0.5, 0.25]), [[0.0, 0.0], [2.0, 0.0]], density=1000.0)
        >>> ids.tolist(), float(b.mass[0]), round(float(b.radius[0]), 4)
        ([0, 1], 500.0, 0.559)
        """
        d = self.dim
        pos = np.atleast_2d(np.asarray(pos, dtype=np.float64))
        if pos.ndim != 2 or pos.shape[1] != d:
            raise ValueError(f"pos must have shape (n, {d}), got {pos.shape}")
        n = pos.shape[0]
        if getattr(shape, "dim", d) != d:
            raise ValueError(f"a {shape.dim}D shape cannot go into a {d}D scene")
        density = float(density)
        if not (density > 0.0 and np.isfinite(density)):
            raise ValueError(f"density must be positive and finite, got {density}")
        if not np.all(np.isfinite(pos)):
            raise ValueError("pos must be finite")
        principal, rotation, centroid = shape.principal(density)
        mass, _, _ = principal.mass_properties(density)
        moments = np.asarray(principal.principal_moments(density), np.float64).reshape(-1)
        s = self.table.add(principal.rows(), principal)
        rotation = np.asarray(rotation, np.float64)
        centroid = np.asarray(centroid, np.float64).reshape(d)
        if d == 2:
            ang = np.zeros(n) if rot is None else np.broadcast_to(
                np.asarray(rot, np.float64).reshape(-1), (n,)).copy()
            c, sn = np.cos(ang), np.sin(ang)
            world = np.stack([c * centroid[0] - sn * centroid[1],
                              sn * centroid[0] + c * centroid[1]], axis=1)
            body_rot = (ang + np.arctan2(rotation[1, 0], rotation[0, 0]))[:, None]
        else:
            q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)) if rot is None else np.broadcast_to(
                np.asarray(rot, np.float64), (n, 4)).copy()
            norm = np.linalg.norm(q, axis=1, keepdims=True)
            if not np.all(norm > 0.0):
                raise ValueError("rot quaternions must be non-zero")
            q = q / norm
            world = np.stack([quat_rotate(qq, centroid) for qq in q])
            qp = matrix_to_quat(rotation)
            body_rot = np.stack([quat_mul(qq, qp) for qq in q])
        v = np.zeros((n, d)) if vel is None else np.broadcast_to(
            np.asarray(vel, dtype=np.float64), (n, d)).copy()
        idx = self._append(pos=pos + world, vel=v, rot=body_rot,
                           radius=np.full(n, principal.bounding_radius),
                           mass=np.full(n, mass),
                           inertia=np.tile(moments, (n, 1)), kind=int(principal.code),
                           mat_id=mat_id, is_fixed=False, normal=np.zeros((n, d)),
                           density=np.full(n, density), shape=s)
        if ang_vel is not None:
            self.ang_vel[idx] = np.broadcast_to(np.asarray(ang_vel, np.float64),
                                                (n, self.n_rot))
        return idx

    def _append(self, *, pos, vel, rot, radius, mass, inertia, kind, mat_id, is_fixed,
                normal, density, shape=-1):
        n0, n = self.n, pos.shape[0]
        nr = n_rot(self.dim)

        def cat(a, b):
            return np.ascontiguousarray(np.concatenate([a, b], axis=0))

        self.pos = cat(self.pos, pos)
        self.vel = cat(self.vel, vel)
        self.rot = cat(self.rot, rot)
        self.ang_vel = cat(self.ang_vel, np.zeros((n, nr)))
        self.force = cat(self.force, np.zeros((n, self.dim)))
        self.torque = cat(self.torque, np.zeros((n, nr)))
        self.radius = cat(self.radius, radius)
        self.mass = cat(self.mass, mass)
        self.inertia = cat(self.inertia, inertia)
        self.kind = cat(self.kind, np.full(n, int(kind), np.int32))
        self.mat_id = cat(self.mat_id, np.broadcast_to(np.asarray(mat_id, np.int32), (n,)))
        self.is_fixed = cat(self.is_fixed, np.full(n, bool(is_fixed)))
        self.normal = cat(self.normal, normal)
        self.density = cat(self.density, density)
        self.shape = cat(self.shape, np.broadcast_to(np.asarray(shape, np.int32), (n,)))
        return np.arange(n0, n0 + n, dtype=np.int32)

    # ------------------------------------------------------------------ queries
    @property
    def n(self):
        """Number of bodies (walls included)."""
        return self.pos.shape[0]

    @property
    def n_rot(self):
        return n_rot(self.dim)

    def ids(self, kind):
        """Indices (int32) of the bodies of one :class:`Shape` kind."""
        return np.flatnonzero(self.kind == int(kind)).astype(np.int32)

    def fix(self, ids, velocity=None):
        """Make bodies fixed: forces no longer act on them; they move at ``velocity``."""
        ids = np.atleast_1d(np.asarray(ids, dtype=np.int64))
        self.is_fixed[ids] = True
        self.vel[ids] = 0.0 if velocity is None else np.asarray(velocity, dtype=np.float64)
        self.ang_vel[ids] = 0.0

    def set_radius(self, ids, radius):
        """Change sphere radii [m] keeping the density: mass and inertia follow."""
        ids = np.atleast_1d(np.asarray(ids, dtype=np.int64))
        radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), ids.shape)
        self.radius[ids] = radius
        vol = 4.0 / 3.0 * np.pi * radius**3 if self.dim == 3 else np.pi * radius**2
        free = ~self.is_fixed[ids]
        m = self.density[ids] * vol
        self.mass[ids[free]] = m[free]
        k = 0.4 if self.dim == 3 else 0.5
        self.inertia[ids[free]] = (k * m * radius**2)[free, None]

    def sort_spatially(self, cell=None):
        """Reorder the particles along a Z-order (Morton) curve of cells, in place.

        Neighbours then sit close together in memory, which makes the contact loop
        faster (a few percent to tens of percent, growing with the scene). Call it while
        setting a scene up, before keeping any body index (trackers, state objects):
        rows are renumbered. Walls keep their rows.

        Parameters
        ----------
        cell : float, optional
            Cell size [m]; default the largest sphere diameter.

        Returns
        -------
        order : (n,) int64
            The new row ``r`` holds what was row ``order[r]``.

        Examples
        --------
        >>> b = Bodies.spheres([[3.0, 0.0], [0.0, 0.0], [1.0, 0.0]], radius=0.5, density=1.0)
        >>> b.sort_spatially().tolist(), b.pos[:, 0].tolist()
        ([1, 2, 0], [0.0, 1.0, 3.0])
        """
        rows = np.flatnonzero(self.kind != Shape.PLANE).astype(np.int32)
        order = np.arange(self.n)
        if rows.size < 2:
            return order
        p = self.pos[rows]
        cell = 2.0 * float(self.radius[rows].max()) if cell is None else float(cell)
        bits = 21 if self.dim == 3 else 31
        c = np.floor((p - p.min(axis=0)) / cell).astype(np.int64)
        c = np.clip(c, 0, (1 << bits) - 1)
        key = np.zeros(rows.size, np.int64)
        for bit in range(bits):
            for a in range(self.dim):
                key |= ((c[:, a] >> bit) & 1) << (self.dim * bit + a)
        order[rows] = rows[np.argsort(key, kind="stable")]
        for name in self.ARRAYS:
            setattr(self, name, np.ascontiguousarray(getattr(self, name)[order]))
        return order

    ARRAYS = ("pos", "vel", "rot", "ang_vel", "force", "torque", "radius", "mass",
              "inertia", "kind", "mat_id", "is_fixed", "normal", "density", "shape")

    def copy(self):
        """A deep copy of the table."""
        return Bodies(dim=self.dim, table=self.table.copy(),
                      **{k: getattr(self, k).copy() for k in self.ARRAYS})

    @property
    def has_shapes(self):
        """Whether any body is neither a sphere nor a plane."""
        return bool(np.any(self.shape >= 0))


# --------------------------------------------------------------------------- contacts
# The contact state is a few bundles: NamedTuples of arrays, one row per row of a
# neighbour list. Each bundle's ``COLUMNS`` describes its fields; snapshots, restores
# and checkpoints iterate the bundles (:meth:`dem.Simulation.state_bundles`), so the
# list of what a step carries to the next exists here only.

class Column(NamedTuple):
    """How one array of a state bundle is shaped: rows (``"pair"``, ``"wall"`` or
    ``"body"``), trailing shape (ints and the names ``"d"``, the dimension, ``"r"``, the
    rotational degrees of freedom, ``"2r"``, twice those, ``"h"``, the contact model's
    history width ``counts["hist"]``, 3 if not given), dtype, and what it holds."""

    rows: str
    tail: tuple
    dtype: type
    doc: str

    def shape(self, counts, dim):
        """The array's shape for ``counts`` {"pair": m, "wall": mw, "body": n, and
        optionally "hist": the history width}."""
        sizes = {"d": dim, "r": n_rot(dim), "2r": 2 * n_rot(dim),
                 "h": counts.get("hist", 3)}
        return (counts[self.rows], *(sizes.get(t, t) for t in self.tail))


def _zeros(cls, counts, dim):
    """A bundle of zero arrays for ``counts`` {"pair": m, "wall": mw, "body": n}."""
    return cls(*(np.zeros(c.shape(counts, dim), c.dtype) for c in cls.COLUMNS))


def _checked(cls, arrays, counts, dim, where=""):
    """A bundle of ``arrays`` (a mapping by field name), each checked against its
    column's shape and dtype; a ValueError names the first that is missing or wrong."""
    out = []
    for name, c in zip(cls._fields, cls.COLUMNS, strict=True):
        if name not in arrays:
            raise ValueError(f"{where}{name} is missing")
        a = arrays[name]
        want = c.shape(counts, dim)
        if a.shape != want or a.dtype != np.dtype(c.dtype):
            raise ValueError(f"{where}{name} is {a.dtype}{list(a.shape)}, expected "
                             f"{np.dtype(c.dtype)}{list(want)}")
        out.append(a)
    return cls(*out)


def bundle(cls):
    """Make a NamedTuple of arrays, whose class attribute ``COLUMNS`` describes its
    fields, a state bundle: it gains the constructors ``zeros(counts, dim)`` and
    ``checked(arrays, counts, dim, where="")``."""
    if len(cls.COLUMNS) != len(cls._fields):
        raise TypeError(f"{cls.__name__}: one column per field")
    cls.zeros = classmethod(_zeros)
    cls.checked = classmethod(_checked)
    return cls


@bundle
class PairState(NamedTuple):
    """Contact state of every row of the Verlet pair list (row ``k`` of
    ``neighbors.pairs``): what a step carries to the next."""

    hist: np.ndarray
    touch: np.ndarray
    fpair: np.ndarray

    COLUMNS = (Column("pair", ("h",), np.float64,
                      "law history: tangential spring [m], then any rolling state"),
               Column("pair", (), np.uint8, "1 while the pair touches"),
               Column("pair", ("d",), np.float64, "contact force on the first body [N]"))


@bundle
class WallState(NamedTuple):
    """Contact state of every row of the body-wall list (``neighbors.wall_pairs``)."""

    whist: np.ndarray
    wforce: np.ndarray
    wtorque: np.ndarray

    COLUMNS = (Column("wall", ("h",), np.float64,
                      "law history: tangential spring [m], then any rolling state"),
               Column("wall", ("d",), np.float64, "contact force on the body [N]"),
               Column("wall", ("r",), np.float64, "contact torque on the body [N m]"))


#: contact geometry kept per contact: overlap [m] (> 0 while touching), then the
#: contact point [m] and the normal (3 components each, zero padded in 2D)
N_GEOM = 7


@bundle
class ShapePairState(NamedTuple):
    """What scenes with non-spherical shapes add per Verlet pair row."""

    warm: np.ndarray
    iters: np.ndarray
    pgeom: np.ndarray
    tpair: np.ndarray

    COLUMNS = (Column("pair", (N_WARM,), np.float64, "ADMM warm start"),
               Column("pair", (), np.int64, "ADMM iterations of the last solve"),
               Column("pair", (N_GEOM,), np.float64, "overlap [m], point [m], normal"),
               Column("pair", ("2r",), np.float64, "contact torques on both bodies [N m]"))


@bundle
class ShapeWallState(NamedTuple):
    """What scenes with non-spherical shapes add per body-wall row."""

    wwarm: np.ndarray
    witers: np.ndarray
    wgeom: np.ndarray

    COLUMNS = (Column("wall", (N_WARM,), np.float64, "ADMM warm start"),
               Column("wall", (), np.int64, "ADMM iterations of the last solve"),
               Column("wall", (N_GEOM,), np.float64, "overlap [m], point [m], normal"))


# --------------------------------------------------------------------------- kernel views
# What a compiled step loop takes, a few tuples instead of dozens of arrays. They hold
# the arrays themselves (no copies) and are made afresh at every call, so they never
# outlive an array that was replaced.

class BodyArrays(NamedTuple):
    """The per-body arrays of a step loop: :class:`Bodies`' own, and the inverse
    masses and inertias (0 for fixed bodies) and fixed flags (uint8) the simulation
    keeps beside them."""

    pos: np.ndarray
    vel: np.ndarray
    rot: np.ndarray
    ang_vel: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    radius: np.ndarray
    mass: np.ndarray
    inv_mass: np.ndarray
    inv_inertia: np.ndarray
    is_fixed: np.ndarray
    normal: np.ndarray
    mat_id: np.ndarray


class CellArrays(NamedTuple):
    """The periodic cell of a step loop: its matrix ``hmat`` (d, d) [m], velocity
    gradient ``lgrad`` (d, d) [1/s], ``cellref`` (2, d, d), the inverse matrix at the
    Verlet build and at the inner list's making, and ``is_cell``: True for a deforming
    cell (an orthogonal periodic box or no box passes False and a zero ``lgrad``)."""

    hmat: np.ndarray
    lgrad: np.ndarray
    cellref: np.ndarray
    is_cell: bool


class StepSettings(NamedTuple):
    """The settings of a step loop: time step [s], gravity (d,) [m/s^2], local damping,
    Verlet skin [m], overlap limit (fraction of the smaller radius), the inner list's
    skin [m] (sphere loop), and the largest radius growth since the Verlet build [m]
    (state objects)."""

    dt: float
    gravity: np.ndarray
    damping: float
    skin: float
    overlap_limit: float
    skin_inner: float
    grow: float


class ServoDrive(NamedTuple):
    """An RVE's drive under mixed control, checked in the compiled loop
    (:mod:`dem.contact.servo`): stress targets ``target`` (d, d) [Pa] on the components
    of ``mask`` (d, d, symmetric), the velocity gradient ``l_load`` (d, d) [1/s] of the
    strain increment, ``settings`` and ``state`` (the ``SET_*`` and ``ST_*`` entries of
    :mod:`dem.contact.servo`), the velocity gradient [1/s] and steps of each chunk
    between checks (``log`` (k, d, d), ``log_n`` (k,)), and the measure's scratch:
    contacts per body ``degree`` (n,), ``stress`` (d, d), ``tangent`` (d, d, d, d),
    ``fabric`` (d, d). Empty ``settings``: no drive (a plain relaxation)."""

    target: np.ndarray
    mask: np.ndarray
    l_load: np.ndarray
    settings: np.ndarray
    state: np.ndarray
    log: np.ndarray
    log_n: np.ndarray
    degree: np.ndarray
    stress: np.ndarray
    tangent: np.ndarray
    fabric: np.ndarray


class RelaxCheck(NamedTuple):
    """The checks of the sphere loop (:mod:`dem.contact.relaxation`): every ``every``
    steps (0: never) the loop computes the unbalanced-force ratio and stops below
    ``tol``, or when the coordination number was below ``min_coordination`` at
    ``apart_checks`` checks in a row (0: never); with a ``servo``
    (:class:`ServoDrive`) each check is that drive's instead. ``net`` (n, d) is
    scratch; ``out`` (5,) holds the ratio, contacts and low checks in a row of the last
    check, the checks made, and the steps to the next check (counted down by the loop,
    so that a run split into calls checks where one call would)."""

    every: int
    tol: float
    min_coordination: float
    apart_checks: int
    net: np.ndarray
    out: np.ndarray
    servo: ServoDrive


class NeighborArrays(NamedTuple):
    """The neighbour lists of a step loop: Verlet pairs (m, 2) int32 and their periodic
    image offsets ``img`` (m, d) int32, body-wall pairs (mw, 2) int32, and the
    positions at the build ``pos_ref`` (n, d) [m]."""

    pairs: np.ndarray
    img: np.ndarray
    wall_pairs: np.ndarray
    pos_ref: np.ndarray
