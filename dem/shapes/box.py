"""Box (3D) or rectangle (2D) of half extents ``h``, axis-aligned, about the origin.

Signed distance ("eq 26"): with ``q = |x| - h`` componentwise,
``sdf(x) = |max(q, 0)| + min(max_a q_a, 0)``; exact inside and outside.
"""

import math

import numpy as np

from .kinds import BOX
from .massprops import check_density, check_scale
from .polygon import as_points



class Box:
    """An axis-aligned box (3D) or rectangle (2D, a prism of unit thickness, 1 m).

    Its frame is its body frame: the centroid is the origin and the axes are principal.

    Parameters
    ----------
    half_extents : array_like, shape (d,), float
        Half side lengths [m], all > 0 and finite; ``d`` (2 or 3) is the dimension.

    Examples
    --------
    >>> b = Box([1.0, 0.5, 0.25])
    >>> b.dim, b.volume()
    (3, 1.0)
    >>> float(b.sdf([2.0, 0.0, 0.0])), float(b.sdf([0.0, 0.0, 0.0]))
    (1.0, -0.25)
    >>> b.principal_moments(12.0).tolist()   # m (b^2 + c^2) / 12 with full sides
    [1.25, 4.25, 5.0]
    """

    code = BOX
    polytope = True   # vertices and faces: exact detection, a surface in XDMF
    stored = True     # a shape-table row that checkpoints keep
    grains = ("squares", "cubes")
    packing = "box"

    @classmethod
    def packing_maker(cls, keys, dim):
        """The ``shape(r, rng)`` of :func:`dem.rve.generate`: a square or cube of
        half-diagonal ``r``."""
        return lambda r, rng: cls([r / math.sqrt(dim)] * dim)

    def __init__(self, half_extents):
        h = np.array(half_extents, dtype=np.float64)
        if h.ndim != 1 or h.shape[0] not in (2, 3):
            raise ValueError(
                f"box half_extents must have 2 or 3 entries, got {np.shape(h)}")
        if not np.isfinite(h).all():
            raise ValueError(f"box half_extents must be finite, got {h.tolist()}")
        if not (h > 0.0).all():
            raise ValueError(f"box half_extents must be > 0 [m], got {h.tolist()}")
        self.half_extents = h
        self.dim = h.shape[0]

    @property
    def bounding_radius(self):
        """Distance [m] of a corner from the centre."""
        return float(np.linalg.norm(self.half_extents))

    def sdf(self, points):
        """Signed distance [m] of points (m, d) or one point (d,) [m]; negative inside.

        Returns an array (m,) or a float.
        """
        x, single = as_points(points, self.dim)
        q = np.abs(x) - self.half_extents
        d = np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)
        return float(d[0]) if single else d

    def volume(self):
        """Volume [m^3] in 3D, area [m^2] in 2D."""
        return float(np.prod(2.0 * self.half_extents))

    def centroid(self):
        """Centroid (d,) [m]: the origin."""
        return np.zeros(self.dim)

    def principal_moments(self, density):
        """Principal moments [kg m^2] about the centre: (3,) in 3D, polar (1,) in 2D.

        Parameters
        ----------
        density : float
            Mass density [kg/m^3]; per metre of thickness in 2D.
        """
        m = check_density(density) * self.volume()
        h2 = self.half_extents**2
        if self.dim == 2:
            return np.array([m * h2.sum() / 3.0])
        return m * (h2.sum() - h2) / 3.0

    def inertia_tensor(self, density):
        """Inertia about the centre [kg m^2]: (3, 3) in 3D, the polar moment in 2D."""
        moments = self.principal_moments(density)
        return float(moments[0]) if self.dim == 2 else np.diag(moments)

    def mass_properties(self, density):
        """``(mass [kg], centroid (d,) [m], inertia)`` at ``density`` [kg/m^3]."""
        return (check_density(density) * self.volume(), self.centroid(),
                self.inertia_tensor(density))

    def principal(self, density=1.0):
        """``(self, identity, zeros)``: a box's frame is already principal."""
        check_density(density)
        return self, np.eye(self.dim), np.zeros(self.dim)

    def scaled(self, s):
        """The box scaled by ``s`` > 0."""
        return Box(self.half_extents * check_scale(s))

    def corners(self):
        """Corners [m]: (4, 2) counter-clockwise in 2D; (8, 3) in 3D.

        In 3D, corner ``i`` has coordinate ``a`` at ``+h_a`` where bit ``a`` of ``i`` is
        set, else at ``-h_a``.
        """
        h = self.half_extents
        if self.dim == 2:
            return np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]) * h
        bits = (np.arange(8)[:, None] >> np.arange(3)) & 1
        return (2.0 * bits - 1.0) * h

    def rows(self):
        """Row of the engine's shape table (the box is always in its body frame).

        ``verts``: the corners (see :meth:`corners`); ``faces``: in 2D face ``e`` is the
        edge from corner ``e`` to ``e + 1``, in 3D the faces are ``-x, +x, -y, +y, -z,
        +z``; ``tris`` (3D): two outward triangles per face, in face order.
        """
        h = self.half_extents
        verts = self.corners()
        if self.dim == 2:
            normals = np.array([[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])
            faces = np.column_stack([normals, np.zeros(4), np.abs(normals) @ h])
            return self._row(np.column_stack([verts, np.zeros(4)]), faces,
                             np.zeros((0, 3), dtype=np.int64))
        faces, tris = [], []
        bits = (np.arange(8)[:, None] >> np.arange(3)) & 1
        for a in range(3):
            b, c = (a + 1) % 3, (a + 2) % 3  # e_a = e_b x e_c
            for side in (0, 1):
                n = np.zeros(3)
                n[a] = 2.0 * side - 1.0
                faces.append([*n, h[a]])
                # quad counter-clockwise in (e_b, e_c), seen from +e_a
                quad = [int(np.flatnonzero((bits[:, a] == side) & (bits[:, b] == sb)
                                           & (bits[:, c] == sc))[0])
                        for sb, sc in ((0, 0), (1, 0), (1, 1), (0, 1))]
                if side == 0:  # seen from -e_a the order reverses
                    quad = quad[::-1]
                tris += [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]]
        return self._row(verts, np.array(faces), np.array(tris, dtype=np.int64))

    def _row(self, verts, faces, tris):
        param = np.zeros(4)
        param[: self.dim] = self.half_extents
        return {"kind": int(self.code), "param": param, "verts": verts, "faces": faces,
                "tris": tris, "bounding_radius": self.bounding_radius}

    def __repr__(self):
        return f"Box(half_extents={self.half_extents.tolist()})"
