"""Non-convex bodies as unions of convex parts.

A :class:`Compound` is one rigid body whose shape is the union of convex parts (spheres,
boxes, polygons, polyhedra), each placed in the compound's frame by an offset and a
rotation. Its signed distance is the minimum of the parts' (exact outside the union, a
bound inside where parts overlap). Contact detection never sees the union: every part
is detected against every part of a neighbour, by the method of that pair of part
kinds, and each touching pair of parts is its own contact, with its own history. Two
compounds may therefore touch at several points at once, and a part touching a wall
is a wall contact of its own.

Mass properties
---------------
Exact to round-off when every part is a polytope (box, polygon, polyhedron), however
they overlap: mass, first moment and inertia are additive over sets, so the union's
are the inclusion-exclusion sum over the parts' intersections, and an intersection of
convex polytopes is a convex polytope (its vertices from the half-spaces of its
members). Subsets whose intersection is empty end the enumeration below them. Exact
too when spheres overlap nothing. Otherwise (overlapping spheres) the union is
integrated on a regular grid of ``GRID[d]`` cells along its longest side, each cell
counted with the smoothed indicator ``clip(0.5 - sdf / h, 0, 1)`` and its own second
moment ``h^2 / 12`` per axis; the relative error is measured in
``tests/dem/test_compound.py`` (two overlapping spheres or disks, centres 0.43 and
1.7 radii apart, against a slice-by-slice integral): below 1e-4 in volume and 5e-4
in the moments (relative to the largest) in 3D, below 1e-6 and 1e-5 in 2D. It takes
0.2 to 0.3 s per compound shape.
"""

import math

import numpy as np

from ..rotation import matrix_to_quat, quat_to_matrix
from .box import Box
from .kinds import COMPOUND
from .massprops import check_density, moments_about_axes, principal_axes
from .polygon import ConvexPolygon, as_points
from .polyhedron import ConvexPolyhedron
from .sphere import Sphere

#: grid cells along the longest side of the union, for overlapping spheres
GRID = {2: 1024, 3: 160}
#: an intersection whose inscribed ball is below this fraction of its parts' size is
#: empty
EMPTY = 1e-9


def _rotation(rotation, dim):
    """A part's rotation as a (d, d) matrix: from an angle (2D), a matrix or a
    quaternion."""
    if rotation is None:
        return np.eye(dim)
    r = np.asarray(rotation, np.float64)
    if dim == 2:
        if r.ndim == 0 or r.size == 1:
            a = float(r.reshape(-1)[0])
            return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    elif r.shape == (4,):
        norm = np.linalg.norm(r)
        if not norm > 0.0:
            raise ValueError("a part's quaternion must be non-zero")
        return quat_to_matrix(r / norm)
    if r.shape != (dim, dim) or not np.isfinite(r).all():
        raise ValueError(f"a part's rotation must be an angle (2D), a quaternion (3D) "
                         f"or a ({dim}, {dim}) matrix, got shape {r.shape}")
    if not (np.allclose(r.T @ r, np.eye(dim), atol=1e-9) and np.linalg.det(r) > 0.0):
        raise ValueError("a part's rotation matrix must be a proper rotation")
    return r


class Compound:
    """A rigid body that is the union of convex parts.

    Parameters
    ----------
    parts : sequence of ``(shape, offset)`` or ``(shape, offset, rotation)``
        ``shape``: a :class:`Sphere`, :class:`Box`, :class:`ConvexPolygon` or
        :class:`ConvexPolyhedron`; a body-frame point ``x`` of the part's own body frame
        (:meth:`principal`) sits at ``rotation @ x + offset`` in the compound's frame.
        ``offset`` (d,) [m]; ``rotation``: an angle [rad] in 2D, a unit quaternion
        (w, x, y, z) or a (3, 3) matrix in 3D (default: none).
    dim : int, optional
        2 or 3 (default: the parts', or the offsets' length for spheres only).

    Examples
    --------
    An L of two unit squares, exact:

    >>> L = Compound([(Box([0.5, 0.5]), [0.0, 0.0]), (Box([0.5, 0.5]), [1.0, 0.0]),
    ...               (Box([0.5, 0.5]), [0.0, 1.0])])
    >>> L.volume(), [round(float(c), 12) for c in L.centroid()]
    (3.0, [0.333333333333, 0.333333333333])

    A cross of two overlapping bars: the centre square counts once.

    >>> X = Compound([(Box([1.5, 0.5]), [0.0, 0.0]), (Box([0.5, 1.5]), [0.0, 0.0])])
    >>> X.volume()
    5.0
    """

    code = COMPOUND
    polytope = False  # its parts are; each is its own contact
    stored = True
    grains = None
    packing = None

    def __init__(self, parts, dim=None):
        parts = list(parts)
        if not parts:
            raise ValueError("a compound needs at least one part")
        dims = {p[0].dim for p in parts if not isinstance(p[0], Sphere)}
        if dim is not None:
            dims.add(int(dim))
        if not dims:  # spheres only: the offsets say
            dims.add(np.asarray(parts[0][1]).size)
        if len(dims) != 1:
            raise ValueError(f"a compound's parts mix dimensions {sorted(dims)}")
        self.dim = d = dims.pop()
        if d not in (2, 3):
            raise ValueError(f"dimension must be 2 or 3, got {d}")
        self.parts = []  # (principal shape, rotation (d, d), offset (d,))
        for k, item in enumerate(parts):
            if len(item) not in (2, 3):
                raise ValueError(f"part {k} must be (shape, offset) or (shape, offset, "
                                 f"rotation)")
            shape, offset = item[0], np.asarray(item[1], np.float64).reshape(-1)
            if isinstance(shape, Compound):
                raise ValueError(f"part {k}: a compound cannot hold a compound (list "
                                 f"its parts instead)")
            if not isinstance(shape, (Sphere, Box, ConvexPolygon, ConvexPolyhedron)):
                raise ValueError(f"part {k}: a compound's parts are spheres, boxes, "
                                 f"polygons or polyhedra, got {type(shape).__name__}")
            if offset.shape != (d,) or not np.isfinite(offset).all():
                raise ValueError(f"part {k}: offset must be {d} finite numbers [m]")
            rot = _rotation(item[2] if len(item) == 3 else None, d)
            if isinstance(shape, Sphere):
                self.parts.append((shape, rot, offset))
                continue
            try:  # already in its body frame: kept as it is
                shape.rows()
                principal, r_p, c_p = shape, np.eye(d), np.zeros(d)
            except ValueError:
                principal, r_p, c_p = shape.principal(1.0)
            self.parts.append((principal, rot @ np.asarray(r_p, np.float64),
                               rot @ np.asarray(c_p, np.float64).reshape(d) + offset))

    # ------------------------------------------------------------------ geometry
    @property
    def bounding_radius(self):
        """Largest distance [m] of the union from the frame origin."""
        return float(max(np.linalg.norm(t) + s.bounding_radius
                         for s, _, t in self.parts))

    def sdf(self, points):
        """Signed distance [m] of points (m, d) or one point (d,) [m]: the parts'
        minimum."""
        x, single = as_points(points, self.dim)
        best = np.full(x.shape[0], np.inf)
        for shape, rot, t in self.parts:
            local = (x - t) @ rot  # rot.T @ (x - t), row by row
            if isinstance(shape, Sphere):
                d = np.linalg.norm(local, axis=1) - shape.radius
            else:
                d = np.atleast_1d(shape.sdf(local))
            best = np.minimum(best, d)
        return float(best[0]) if single else best

    def _halfspaces(self, k):
        """Part k (a polytope) as ``A x <= b`` in the compound frame."""
        shape, rot, t = self.parts[k]
        faces = shape.rows()["faces"]
        n = faces[:, :self.dim] @ rot.T
        return n, faces[:, 3] + n @ t

    def _polytope_moments(self, members):
        """(volume, first moment, inertia about the origin) of the members'
        intersection, or None if it is empty."""
        d = self.dim
        normals, offsets = zip(*(self._halfspaces(k) for k in members), strict=True)
        a, b = np.vstack(normals), np.concatenate(offsets)
        size = max(self.parts[k][0].bounding_radius for k in members)
        from scipy.optimize import linprog  # here: scipy.optimize costs a second to import
        from scipy.spatial import HalfspaceIntersection, QhullError

        lp = linprog(np.r_[np.zeros(d), -1.0],
                     A_ub=np.column_stack([a, np.ones(len(b))]), b_ub=b,
                     bounds=[(None, None)] * d + [(0.0, None)])
        if lp.status != 0 or not lp.x[d] > EMPTY * size:
            return None
        if len(members) == 1:
            shape, rot, t = self.parts[members[0]]
            verts = _vertices(shape) @ rot.T + t
        else:
            try:
                verts = HalfspaceIntersection(np.column_stack([a, -b]),
                                              lp.x[:d]).intersections
            except QhullError:
                return None
        poly = ConvexPolygon(verts) if d == 2 else ConvexPolyhedron.from_vertices(verts)
        m, c, inertia = poly.mass_properties(1.0)
        return m, m * c, _to_origin(inertia, m, c, d)

    def _sphere_alone(self, k):
        """Whether sphere part k overlaps no other part."""
        s, _, t = self.parts[k]
        for q, (shape, rot, u) in enumerate(self.parts):
            if q == k:
                continue
            if isinstance(shape, Sphere):
                gap = np.linalg.norm(t - u) - shape.radius
            else:
                gap = float(shape.sdf((t - u) @ rot))
            if gap < s.radius * (1.0 - 1e-12):
                return False
        return True

    def _moments(self):
        """(volume, first moment (d,), inertia about the origin) at unit density."""
        if hasattr(self, "_cached"):
            return self._cached
        d = self.dim
        spheres = [k for k, p in enumerate(self.parts) if isinstance(p[0], Sphere)]
        if spheres and not all(self._sphere_alone(k) for k in spheres):
            self._cached = self._grid_moments()
            return self._cached
        vol, first = 0.0, np.zeros(d)
        inertia = 0.0 if d == 2 else np.zeros((3, 3))
        for k in spheres:
            s, _, t = self.parts[k]
            m = s.volume(d)
            moment = s.inertia(d, 1.0)
            vol += m
            first = first + m * t
            own = moment[0] if d == 2 else np.diag(moment)
            inertia = inertia + _to_origin(own, m, t, d)
        poly = [k for k in range(len(self.parts)) if k not in spheres]
        # inclusion-exclusion, depth first: a subset with an empty intersection ends its
        # branch (every superset is empty too)
        stack = [((k,), k) for k in reversed(poly)]
        while stack:
            members, last = stack.pop()
            mom = self._polytope_moments(members)
            if mom is None:
                continue
            sign = 1.0 if len(members) % 2 else -1.0
            vol += sign * mom[0]
            first = first + sign * mom[1]
            inertia = inertia + sign * mom[2]
            stack.extend((members + (q,), q) for q in reversed(poly) if q > last)
        self._cached = (vol, first, inertia)
        return self._cached

    def _grid_moments(self):
        """The union's moments on a regular grid (see the module docstring)."""
        d = self.dim
        lo = np.min([t - s.bounding_radius for s, _, t in self.parts], axis=0)
        hi = np.max([t + s.bounding_radius for s, _, t in self.parts], axis=0)
        h = float((hi - lo).max()) / GRID[d]
        n = np.ceil((hi - lo) / h).astype(int) + 2
        axes = [lo[a] - 0.5 * h + h * (np.arange(n[a]) + 0.5) for a in range(d)]
        vol, first = 0.0, np.zeros(d)
        second = np.zeros((d, d))  # sum of w x x^T
        for ix in range(n[0]):  # one slab at a time keeps memory small
            slab = np.stack(np.meshgrid(axes[0][ix:ix + 1], *axes[1:], indexing="ij"),
                            axis=-1).reshape(-1, d)
            w = np.clip(0.5 - self.sdf(slab) / h, 0.0, 1.0) * h**d
            keep = w > 0.0
            x, w = slab[keep], w[keep]
            vol += w.sum()
            first += w @ x
            second += (x * w[:, None]).T @ x
        second += vol * h * h / 12.0 * np.eye(d)
        if d == 2:
            return vol, first, float(np.trace(second))
        return vol, first, np.trace(second) * np.eye(3) - second

    def volume(self):
        """Volume [m^3] in 3D, area [m^2] in 2D."""
        return float(self._moments()[0])

    def centroid(self):
        """Centroid (d,) [m] in this frame."""
        vol, first, _ = self._moments()
        return first / vol

    def mass_properties(self, density):
        """``(mass [kg], centroid (d,) [m], inertia about the centroid)``: the polar
        moment (2D) or the (3, 3) tensor in this frame's axes (3D)."""
        rho = check_density(density)
        vol, first, inertia = self._moments()
        c = first / vol
        zero = 0.0 if self.dim == 2 else np.zeros((3, 3))
        about_c = inertia - _to_origin(zero, vol, c, self.dim)
        return rho * vol, c, rho * about_c

    def inertia_tensor(self, density):
        """Polar moment (2D) or inertia tensor (3, 3) (3D) [kg m^2] about the
        centroid."""
        return self.mass_properties(density)[2]

    def principal_moments(self, density):
        """Principal moments [kg m^2]: (1,) in 2D; (3,) in 3D, in x, y, z order when
        this frame is principal."""
        inertia = self.inertia_tensor(density)
        if self.dim == 2:
            return np.array([float(inertia)])
        return moments_about_axes(inertia)

    def principal(self, density=1.0):
        """The compound in its body frame: ``(shape, rotation, centroid)``; a body-frame
        point ``x`` of ``shape`` sits at ``rotation @ x + centroid`` in this frame.

        A frame that is principal already (products of inertia within 1e-12 of the
        moments, centroid within 1e-12 of the size from the origin) is kept."""
        c = self.centroid()
        size = self.bounding_radius
        if np.linalg.norm(c) <= 1e-12 * size:  # round-off of an origin-centred union
            c = np.zeros(self.dim)
        rot = np.eye(self.dim)
        inertia = self.inertia_tensor(density)
        if self.dim == 3 and (np.abs(inertia - np.diag(np.diag(inertia))).max()
                              > 1e-12 * np.abs(inertia).max()):
            _, rot = principal_axes(inertia)
        out = Compound.__new__(Compound)
        out.dim = self.dim
        out.parts = [(s, rot.T @ r, rot.T @ (t - c)) for s, r, t in self.parts]
        return out, rot, c

    def scaled(self, s):
        raise ValueError("a compound cannot be grown or scaled by a state object")

    def rows(self):
        """The compound's own row of the shape table (its parts get rows of their own,
        see :meth:`dem.shapes.table.ShapeTable.add`)."""
        return {"kind": COMPOUND, "param": np.zeros(4), "verts": np.zeros((0, 3)),
                "faces": np.zeros((0, 4)), "tris": np.zeros((0, 3), np.int64),
                "bounding_radius": self.bounding_radius}

    def part_poses(self):
        """Per part: ``(shape, offset (3,), orientation)`` in the compound's frame, the
        orientation an angle [rad] (2D) or a unit quaternion (w, x, y, z) (3D)."""
        out = []
        for s, r, t in self.parts:
            off = np.zeros(3)
            off[:self.dim] = t
            q = (math.atan2(r[1, 0], r[0, 0]) if self.dim == 2 else matrix_to_quat(r))
            out.append((s, off, q))
        return out

    def __repr__(self):
        names = ", ".join(type(s).__name__ for s, _, _ in self.parts)
        return f"Compound({len(self.parts)} parts: {names})"


def _vertices(shape):
    """A polytope's vertices (k, d) in its own frame."""
    if isinstance(shape, Box):
        return shape.corners()
    return shape.vertices


def _to_origin(inertia_c, m, c, d):
    """Inertia about the origin of a body of mass m, centroid c, inertia_c about c."""
    cc = float(c @ c)
    if d == 2:
        return inertia_c + m * cc
    return inertia_c + m * (cc * np.eye(3) - np.outer(c, c))

