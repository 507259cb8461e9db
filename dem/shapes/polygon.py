"""Convex polygon (2D, a prism of unit thickness): SDF from its edges, exact mass props.

Inside, the signed distance is the largest signed distance to the edge lines,
``max_e (n_e . x - o_e)`` with ``n_e`` the outward unit normal of edge ``e`` and ``o_e``
its offset (exact for a convex polygon, "eq 27"); outside it is the Euclidean distance
to the nearest edge segment.
"""

import numpy as np

from .kinds import POLYGON
from .massprops import (
    boundary_mass_properties,
    check_body_frame,
    check_density,
    check_scale,
)



def as_points(points, dim):
    """Coerce ``points`` to float64 (m, dim); also say whether a single point was given.

    Raises ValueError if the trailing axis is not ``dim`` long.
    """
    x = np.asarray(points, dtype=np.float64)
    single = x.ndim == 1
    x = np.atleast_2d(x)
    if x.ndim != 2 or x.shape[1] != dim:
        raise ValueError(f"points must have shape (m, {dim}) or ({dim},), "
                         f"got {np.shape(points)}")
    return x, single


def convex_hull_2d(points, tol=1e-12):
    """Indices of the convex hull of 2D points, counter-clockwise (monotone chain).

    Collinear points along an edge and repeated points are dropped: a turn counts only
    if its cross product exceeds ``tol`` times the squared extent of the point set.

    Parameters
    ----------
    points : ndarray, shape (m, 2), float64
        Points [m].
    tol : float
        Relative tolerance for collinearity.

    Returns
    -------
    ndarray, shape (k,), int64
        Hull vertices in counter-clockwise order, starting from the lowest-x point;
        fewer than 3 entries if the points are collinear.
    """
    p = np.asarray(points, dtype=np.float64)
    order = np.lexsort((p[:, 1], p[:, 0]))
    extent = float(np.ptp(p, axis=0).max()) if len(p) else 0.0
    eps = tol * extent * extent

    def cross(o, a, b):
        return ((p[a, 0] - p[o, 0]) * (p[b, 1] - p[o, 1])
                - (p[a, 1] - p[o, 1]) * (p[b, 0] - p[o, 0]))

    def chain(indices):
        out = []
        for i in indices:
            while len(out) >= 2 and cross(out[-2], out[-1], i) <= eps:
                out.pop()
            out.append(int(i))
        return out

    lower = chain(order)
    upper = chain(order[::-1])
    hull = lower[:-1] + upper[:-1]
    if extent == 0.0 or len(hull) < 3:
        return np.asarray(hull[:2], dtype=np.int64)
    return np.asarray(hull, dtype=np.int64)


def segment_distance(x, a, b):
    """Distance [m] from points ``x`` (m, d) to segments ``a -> b`` (t, d); (m, t)."""
    ab = b - a  # (t, d)
    ap = x[:, None, :] - a[None, :, :]  # (m, t, d)
    len2 = np.einsum("td,td->t", ab, ab)
    t = np.clip(np.einsum("mtd,td->mt", ap, ab) / len2, 0.0, 1.0)
    diff = ap - t[..., None] * ab
    return np.sqrt(np.einsum("mtd,mtd->mt", diff, diff))


class ConvexPolygon:
    """A convex polygon in 2D: a prism of unit thickness (1 m).

    Parameters
    ----------
    vertices : array_like, shape (k, 2), float
        Points [m] in any order, k >= 3; the polygon is their convex hull, stored
        counter-clockwise (points inside the hull or on an edge are dropped).

    Attributes
    ----------
    vertices : ndarray, shape (k, 2)
        Hull vertices [m], counter-clockwise.
    normals : ndarray, shape (k, 2)
        Outward unit normal of edge ``e`` (from ``vertices[e]`` to ``vertices[e+1]``).
    offsets : ndarray, shape (k,)
        Edge offsets [m]: the polygon is ``{x : normals @ x <= offsets}``.

    Examples
    --------
    >>> tri = ConvexPolygon([[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]])
    >>> tri.vertices.tolist()
    [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]
    >>> tri.volume(), round(tri.inertia_tensor(1.0), 12)
    (0.5, 0.055555555556)
    >>> float(tri.sdf([0.5, -0.5]))
    0.5
    """

    dim = 2
    code = POLYGON
    polytope = True
    stored = True
    grains = ("polygons", "polygons")
    packing = "polygon"

    @classmethod
    def packing_maker(cls, keys, dim):
        """The ``shape(r, rng)`` of :func:`dem.rve.generate`: a regular polygon of
        circumradius ``r`` with ``keys["sides"]`` corners, or a number drawn uniformly
        up to ``keys["sides_max"]`` when that is given."""
        lo = keys["sides"]
        hi = lo if keys.get("sides_max") is None else keys["sides_max"]
        return lambda r, rng: cls.regular(int(rng.integers(lo, hi + 1)), r)

    def __init__(self, vertices):
        v = np.asarray(vertices, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 2:
            raise ValueError(f"polygon vertices must have shape (k, 2), got {v.shape}")
        if not np.isfinite(v).all():
            raise ValueError("polygon vertices must be finite")
        if v.shape[0] < 3:
            raise ValueError(f"a polygon needs at least 3 points, got {v.shape[0]}")
        hull = convex_hull_2d(v)
        if len(hull) < 3:
            raise ValueError("polygon points are collinear (or coincide): zero area")
        v = v[hull]
        edges = np.roll(v, -1, axis=0) - v
        length = np.linalg.norm(edges, axis=1)
        self.vertices = v
        self.normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1) / length[:, None]
        self.offsets = np.einsum("kd,kd->k", self.normals, v)
        area = self.volume()
        extent = float(np.ptp(v, axis=0).max())
        if not area > 1e-12 * extent * extent:
            raise ValueError(f"polygon has (near) zero area {area:.3e} m^2")

    @classmethod
    def regular(cls, n, circumradius):
        """A regular ``n``-gon (n >= 3) of ``circumradius`` [m] centred at the origin.

        A vertex lies on the +x axis.

        Examples
        --------
        >>> sq = ConvexPolygon.regular(4, 1.0)
        >>> round(sq.volume(), 12), round(sq.bounding_radius, 12)
        (2.0, 1.0)
        """
        if int(n) != n or n < 3:
            raise ValueError(f"a regular polygon needs an integer n >= 3, got {n}")
        r = float(circumradius)
        if not (r > 0.0 and np.isfinite(r)):
            raise ValueError(f"circumradius must be a positive finite number [m], "
                             f"got {circumradius}")
        angle = 2.0 * np.pi * np.arange(int(n)) / int(n)
        return cls(r * np.stack([np.cos(angle), np.sin(angle)], axis=1))

    @property
    def bounding_radius(self):
        """Largest distance [m] of the boundary from the frame origin."""
        return float(np.linalg.norm(self.vertices, axis=1).max())

    def sdf(self, points):
        """Signed distance [m] of points (m, 2) or one point (2,) [m]; negative inside.

        Returns an array (m,) or a float.
        """
        x, single = as_points(points, 2)
        d = (x @ self.normals.T - self.offsets).max(axis=1)
        out = d > 0.0
        if out.any():
            d[out] = segment_distance(
                x[out], self.vertices, np.roll(self.vertices, -1, axis=0)).min(axis=1)
        return float(d[0]) if single else d

    def _edges(self):
        k = len(self.vertices)
        return np.stack([np.arange(k), (np.arange(k) + 1) % k], axis=1)

    def volume(self):
        """Area [m^2] (volume per metre of thickness)."""
        return boundary_mass_properties(self.vertices, self._edges(), 1.0)[0]

    def centroid(self):
        """Centroid (2,) [m] in this frame."""
        return boundary_mass_properties(self.vertices, self._edges(), 1.0)[1]

    def mass_properties(self, density):
        """Mass [kg], centroid (2,) [m] and polar moment about the centroid [kg m^2].

        Parameters
        ----------
        density : float
            Mass density [kg/m^3]; the mass is per metre of thickness.
        """
        return boundary_mass_properties(self.vertices, self._edges(),
                                        check_density(density))

    def inertia_tensor(self, density):
        """Polar moment [kg m^2] about the centroid at ``density`` [kg/m^3]."""
        return self.mass_properties(density)[2]

    def principal_moments(self, density):
        """Polar moment (1,) [kg m^2] about the centroid at ``density`` [kg/m^3]."""
        return np.array([self.inertia_tensor(density)])

    def principal(self, density=1.0):
        """The polygon re-centred on its centroid: ``(shape, rotation, centroid)``.

        A body-frame point ``x`` of ``shape`` sits at ``rotation @ x + centroid`` in
        this frame; ``rotation`` is the 2x2 identity (the 2D inertia is a scalar).
        ``density`` [kg/m^3] is accepted for a common interface; it does not matter.
        """
        check_density(density)
        c = self.centroid()
        shape = ConvexPolygon(self.vertices - c)
        residual = shape.centroid()  # one refinement for far-from-origin polygons
        shape = ConvexPolygon(shape.vertices - residual)
        return shape, np.eye(2), c + residual

    def scaled(self, s):
        """The polygon scaled by ``s`` > 0 about the frame origin."""
        return ConvexPolygon(self.vertices * check_scale(s))

    def rows(self):
        """Row of the engine's shape table, in the body frame (see ``dem.shapes``).

        Raises ValueError if the centroid is not at the origin (call ``principal()``).
        """
        check_body_frame(self.centroid(), None, self.bounding_radius, "polygon")
        k = len(self.vertices)
        return {
            "kind": int(self.code),
            "param": np.zeros(4),
            "verts": np.column_stack([self.vertices, np.zeros(k)]),
            "faces": np.column_stack([self.normals, np.zeros(k), self.offsets]),
            "tris": np.zeros((0, 3), dtype=np.int64),
            "bounding_radius": self.bounding_radius,
        }

    def __repr__(self):
        return f"ConvexPolygon({len(self.vertices)} vertices)"
