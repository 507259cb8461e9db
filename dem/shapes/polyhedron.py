"""Convex polyhedron (3D): SDF from its faces and boundary triangles, exact mass props.

Inside, the signed distance is ``max_f (n_f . x - o_f)`` over the face planes (outward
unit normals ``n_f``, offsets ``o_f``), exact for a convex solid; outside it is the
Euclidean distance to the nearest boundary triangle.
"""

import numpy as np

from .kinds import POLYHEDRON
from .massprops import (
    boundary_mass_properties,
    check_body_frame,
    check_density,
    check_scale,
    moments_about_axes,
    principal_axes,
)
from .polygon import ConvexPolygon, as_points, convex_hull_2d


_COPLANAR = 1e-9  # relative tolerance for merging hull facets into one face
_CHUNK = 1 << 18  # points x triangles per block in the distance evaluation


def triangle_distance(x, a, b, c):
    """Distance [m] from points ``x`` (p, 3) to triangles ``(a, b, c)`` (p, 3) pairwise.

    Returns (p,): the distance to the plane where the projection falls inside the
    triangle, else the distance to the nearest of its three edges.
    """
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    height = np.einsum("pd,pd->p", x - a, n)
    q = x - height[:, None] * n  # projection on the plane
    inside = np.ones(len(x), dtype=bool)
    for p0, p1 in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("pd,pd->p", np.cross(p1 - p0, q - p0), n) >= 0.0
    edge = np.minimum(np.minimum(_segment_pairs(x, a, b), _segment_pairs(x, b, c)),
                      _segment_pairs(x, c, a))
    return np.where(inside, np.abs(height), edge)


def _segment_pairs(x, a, b):
    """Distance [m] from points ``x`` (p, 3) to segments ``a -> b`` (p, 3), pairwise."""
    ab = b - a
    ap = x - a
    t = np.clip(np.einsum("pd,pd->p", ap, ab) / np.einsum("pd,pd->p", ab, ab), 0.0, 1.0)
    diff = ap - t[:, None] * ab
    return np.sqrt(np.einsum("pd,pd->p", diff, diff))


class ConvexPolyhedron:
    """A convex polyhedron in 3D.

    Build it with :meth:`from_vertices`, :meth:`from_faces` or :meth:`extrude`;
    ``ConvexPolyhedron(vertices)`` is :meth:`from_vertices`.

    Attributes
    ----------
    vertices : ndarray, shape (k, 3)
        Vertices [m] (corners only: points inside faces or on edges are dropped).
    normals : ndarray, shape (f, 3)
        Outward unit normals of the faces (coplanar hull facets merged).
    offsets : ndarray, shape (f,)
        Face offsets [m]: the solid is ``{x : normals @ x <= offsets}``.
    triangles : ndarray, shape (t, 3), int64
        Boundary triangles (indices into ``vertices``), counter-clockwise seen from
        outside; each face is fanned from its first vertex.

    Examples
    --------
    >>> cube = ConvexPolyhedron.from_vertices(
    ...     [[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    >>> len(cube.vertices), len(cube.normals), len(cube.triangles)
    (8, 6, 12)
    >>> round(cube.volume(), 12), float(cube.sdf([0.0, 0.0, 3.0]))
    (8.0, 2.0)
    """

    dim = 3
    code = POLYHEDRON
    polytope = True
    stored = True
    grains = ("polyhedra", "polyhedra")
    packing = None  # no generated packings of them (yet)

    def __init__(self, vertices):
        other = ConvexPolyhedron.from_vertices(vertices)
        self.__dict__.update(other.__dict__)

    @classmethod
    def _from_parts(cls, vertices, normals, offsets, triangles):
        shape = cls.__new__(cls)
        shape.vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        shape.normals = np.ascontiguousarray(normals, dtype=np.float64)
        shape.offsets = np.ascontiguousarray(offsets, dtype=np.float64)
        shape.triangles = np.ascontiguousarray(triangles, dtype=np.int64)
        return shape

    @classmethod
    def from_vertices(cls, vertices):
        """The convex hull of points ``vertices`` (k, 3) [m], k >= 4, not coplanar.

        Coplanar hull facets are merged into one face, whose vertices are ordered
        counter-clockwise (seen from outside) and fanned into triangles.
        """
        v = np.asarray(vertices, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(
                f"polyhedron vertices must have shape (k, 3), got {v.shape}")
        if not np.isfinite(v).all():
            raise ValueError("polyhedron vertices must be finite")
        if v.shape[0] < 4:
            raise ValueError(f"a polyhedron needs at least 4 points, got {v.shape[0]}")
        extent = float(np.ptp(v, axis=0).max())
        from scipy.sparse import coo_matrix  # scipy here, not at import: it costs a second
        from scipy.sparse.csgraph import connected_components
        from scipy.spatial import ConvexHull, QhullError

        try:
            hull = ConvexHull(v)
        except QhullError as err:
            raise ValueError("polyhedron points are coplanar (or coincide): zero volume"
                             ) from err
        if not hull.volume > 1e-12 * extent**3:
            raise ValueError(f"polyhedron has (near) zero volume {hull.volume:.3e} m^3")
        size = float(np.linalg.norm(v - v.mean(axis=0), axis=1).max())
        # merge neighbouring hull facets whose planes coincide (n.x + d <= 0 inside)
        eq = hull.equations
        i = np.repeat(np.arange(len(eq)), 3)
        j = hull.neighbors.ravel()
        same = ((np.abs(eq[i, :3] - eq[j, :3]).max(axis=1) < _COPLANAR)
                & (np.abs(eq[i, 3] - eq[j, 3]) < _COPLANAR * size))
        n_faces, label = connected_components(
            coo_matrix((np.ones(same.sum()), (i[same], j[same])), shape=(len(eq),) * 2),
            directed=False)
        normals = np.zeros((n_faces, 3))
        np.add.at(normals, label, eq[:, :3])
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        order = np.argsort(label, kind="stable")
        bounds = np.searchsorted(label[order], np.arange(n_faces + 1))
        rings = []
        for f in range(n_faces):
            ids = np.unique(hull.simplices[order[bounds[f]:bounds[f + 1]]])
            if len(ids) == 3:  # a lone triangle: orient it by its normal
                a, b, c = v[ids]
                ring = ids if np.cross(b - a, c - a) @ normals[f] > 0 else ids[::-1]
            else:
                ring = ids[_face_ring(v[ids], normals[f])]
            rings.append(ring)
        keep = np.unique(np.concatenate(rings))  # corners only
        new_index = np.full(len(v), -1)
        new_index[keep] = np.arange(len(keep))
        verts = v[keep]
        offsets, tris = [], []
        for f, ring in enumerate(rings):
            ring = new_index[ring]
            offsets.append(float(np.mean(verts[ring] @ normals[f])))
            tris += [[ring[0], ring[i], ring[i + 1]] for i in range(1, len(ring) - 1)]
        return cls._from_parts(verts, normals, np.array(offsets), np.array(tris))

    @classmethod
    def from_faces(cls, normals, offsets):
        """The solid ``{x : normals @ x <= offsets}`` from half-spaces.

        Parameters
        ----------
        normals : array_like, shape (f, 3), float
            Outward normals (any non-zero length; normalised here).
        offsets : array_like, shape (f,), float
            Offsets [m] for the given normal lengths.

        Raises ValueError if the region is empty, flat or unbounded.

        Examples
        --------
        >>> n = np.vstack([np.eye(3), -np.eye(3)])
        >>> round(ConvexPolyhedron.from_faces(n, np.ones(6)).volume(), 12)
        8.0
        """
        n = np.asarray(normals, dtype=np.float64)
        o = np.asarray(offsets, dtype=np.float64)
        if n.ndim != 2 or n.shape[1] != 3 or o.shape != (n.shape[0],):
            raise ValueError(f"normals must be (f, 3) and offsets (f,), got {n.shape} "
                             f"and {o.shape}")
        if not (np.isfinite(n).all() and np.isfinite(o).all()):
            raise ValueError("face normals and offsets must be finite")
        length = np.linalg.norm(n, axis=1)
        if not (length > 0.0).all():
            raise ValueError("face normals must be non-zero")
        if n.shape[0] < 4:
            raise ValueError(
                f"a bounded polyhedron needs at least 4 faces, got {n.shape[0]}")
        n, o = n / length[:, None], o / length
        # Chebyshev centre: maximise r subject to n . x + r <= o (|n| = 1)
        scale = max(float(np.abs(o).max()), 1e-300)
        from scipy.optimize import linprog
        from scipy.spatial import HalfspaceIntersection, QhullError

        lp = linprog(c=[0.0, 0.0, 0.0, -1.0],
                     A_ub=np.column_stack([n, np.ones(len(o))]), b_ub=o / scale,
                     bounds=[(None, None)] * 3 + [(0.0, 1.0e6)])
        if lp.status == 2:
            raise ValueError("half-spaces bound an empty or flat region (infeasible)")
        if lp.status != 0:
            raise ValueError(f"half-spaces: interior point not found ({lp.message})")
        if lp.x[3] >= 1.0e6 - 1.0:
            raise ValueError("half-spaces bound an unbounded region")
        if not lp.x[3] > 1e-9:
            raise ValueError("half-spaces bound an empty or flat region")
        try:
            with np.errstate(divide="ignore", invalid="ignore"):  # unbounded: inf, nan
                hs = HalfspaceIntersection(np.column_stack([n, -o]), lp.x[:3] * scale)
        except QhullError as err:
            raise ValueError("half-spaces bound no finite solid") from err
        pts = hs.intersections
        if not np.isfinite(pts).all():
            raise ValueError("half-spaces bound an unbounded region")
        return cls.from_vertices(pts)

    @classmethod
    def extrude(cls, polygon, height):
        """Prism of a :class:`ConvexPolygon` (x, y) extruded along z by ``height`` [m].

        The prism spans ``-height / 2 <= z <= height / 2``.

        Examples
        --------
        >>> prism = ConvexPolyhedron.extrude(ConvexPolygon.regular(6, 1.0), 2.0)
        >>> len(prism.vertices), len(prism.normals)
        (12, 8)
        """
        if not isinstance(polygon, ConvexPolygon):
            polygon = ConvexPolygon(polygon)
        hz = 0.5 * float(height)
        if not (hz > 0.0 and np.isfinite(hz)):
            raise ValueError(
                f"height must be a positive finite number [m], got {height}")
        v = polygon.vertices
        k = len(v)
        return cls.from_vertices(np.vstack([np.column_stack([v, np.full(k, -hz)]),
                                            np.column_stack([v, np.full(k, hz)])]))

    @property
    def bounding_radius(self):
        """Largest distance [m] of the boundary (a vertex) from the frame origin."""
        return float(np.linalg.norm(self.vertices, axis=1).max())

    def sdf(self, points):
        """Signed distance [m] of points (m, 3) or one point (3,) [m]; negative inside.

        Returns an array (m,) or a float.
        """
        x, single = as_points(points, 3)
        d = np.empty(len(x))
        step = max(1, _CHUNK // len(self.normals))
        for start in range(0, len(x), step):
            d[start:start + step] = (x[start:start + step] @ self.normals.T
                                     - self.offsets).max(axis=1)
        out = np.flatnonzero(d > 0.0)
        if out.size:
            d[out] = self._outside_distance(x[out])
        return float(d[0]) if single else d

    def _outside_distance(self, x):
        """Exact distance [m] of points ``x`` (m, 3) outside the solid to its boundary.

        A triangle is measured only if the point sees its face (the nearest boundary
        point of a convex solid lies on such a face) and its bounding ball is no
        farther than the nearest vertex (an upper bound of the distance).
        """
        a, b, c = (self.vertices[self.triangles[:, k]] for k in range(3))
        n = np.cross(b - a, c - a)
        n /= np.linalg.norm(n, axis=1)[:, None]
        o = np.einsum("td,td->t", n, a)
        centre = (a + b + c) / 3.0
        reach = np.sqrt(np.max([np.einsum("td,td->t", p - centre, p - centre)
                                for p in (a, b, c)], axis=0))
        from scipy.spatial import cKDTree
        from scipy.spatial.distance import cdist

        upper = cKDTree(self.vertices).query(x)[0] * (1.0 + 1e-12)
        dist = np.empty(len(x))
        step = max(1, _CHUNK // len(self.triangles))
        for start in range(0, len(x), step):
            xs, ub = x[start:start + step], upper[start:start + step]
            near = (cdist(xs, centre) - reach <= ub[:, None]) & (xs @ n.T > o)
            i, t = np.nonzero(near)
            best = np.full(len(xs), np.inf)
            np.minimum.at(best, i, triangle_distance(xs[i], a[t], b[t], c[t]))
            dist[start:start + step] = best
        return dist

    def volume(self):
        """Volume [m^3]."""
        return boundary_mass_properties(self.vertices, self.triangles, 1.0)[0]

    def centroid(self):
        """Centroid (3,) [m] in this frame."""
        return boundary_mass_properties(self.vertices, self.triangles, 1.0)[1]

    def mass_properties(self, density):
        """``(mass [kg], centroid (3,) [m], inertia (3, 3) [kg m^2])``, exact.

        The inertia tensor is about the centroid, in this frame's axes.

        Parameters
        ----------
        density : float
            Mass density [kg/m^3].
        """
        return boundary_mass_properties(self.vertices, self.triangles,
                                        check_density(density))

    def inertia_tensor(self, density):
        """Inertia tensor (3, 3) [kg m^2] about the centroid at ``density`` [kg/m^3]."""
        return self.mass_properties(density)[2]

    def principal_moments(self, density):
        """Principal moments (3,) [kg m^2] at ``density`` [kg/m^3].

        In x, y, z order if this frame is principal (as for the shape from
        :meth:`principal`), else ascending.
        """
        return moments_about_axes(self.inertia_tensor(density))

    def principal(self, density=1.0):
        """The polyhedron in its body frame: ``(shape, rotation, centroid)``.

        ``shape`` has its centroid at the origin and its principal axes (ascending
        moments) along x, y, z; a body-frame point ``x`` of ``shape`` sits at
        ``rotation @ x + centroid`` in this frame (``rotation`` (3, 3), det +1). The
        density [kg/m^3] scales the moments and does not change the axes.
        """
        c = self.centroid()
        centred = self._moved(np.eye(3), c)
        residual = centred.centroid()  # one refinement for far-from-origin shapes
        centred = centred._moved(np.eye(3), residual)
        _, rot = principal_axes(centred.inertia_tensor(density))
        return centred._moved(rot, np.zeros(3)), rot, c + residual

    def _moved(self, rot, c):
        """This shape expressed in the frame with origin ``c`` and axes ``rot``."""
        verts = (self.vertices - c) @ rot
        normals = self.normals @ rot
        offsets = self.offsets - self.normals @ c
        return ConvexPolyhedron._from_parts(verts, normals, offsets, self.triangles)

    def scaled(self, s):
        """The polyhedron scaled by ``s`` > 0 about the frame origin."""
        s = check_scale(s)
        return ConvexPolyhedron._from_parts(self.vertices * s, self.normals,
                                            self.offsets * s, self.triangles)

    def rows(self):
        """Row of the engine's shape table, in the body frame (see ``dem.shapes``).

        Raises ValueError if the centroid is not at the origin or the axes are not
        principal (call ``principal()`` first).
        """
        _, c, inertia = self.mass_properties(1.0)
        check_body_frame(c, inertia, self.bounding_radius, "polyhedron")
        return {
            "kind": int(self.code),
            "param": np.zeros(4),
            "verts": self.vertices.copy(),
            "faces": np.column_stack([self.normals, self.offsets]),
            "tris": self.triangles.copy(),
            "bounding_radius": self.bounding_radius,
        }

    def __repr__(self):
        return (f"ConvexPolyhedron({len(self.vertices)} vertices, "
                f"{len(self.normals)} faces)")


def _face_ring(points, normal):
    """Corners of a planar convex face (indices), counter-clockwise about ``normal``."""
    u = np.cross(normal, [1.0, 0.0, 0.0])
    if np.linalg.norm(u) < 0.5:
        u = np.cross(normal, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(normal, u)  # (u, w, normal) right-handed
    return convex_hull_2d(np.column_stack([points @ u, points @ w]))
