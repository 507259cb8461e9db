"""Plane (a half-space wall; a line in 2D): ``sdf(X) = n . X`` with ``n`` its free-side normal.

The solid is the half-space behind the plane; its free side is the side ``n`` points to,
so a particle in front of the wall has positive signed distance to it.
"""

import numpy as np

from .._jit import kernel
from .kinds import PLANE


@kernel
def sdf_plane(x, normal):
    """Signed distance [m] of ``x`` (d,) to the solid half-space ``{X : n.X <= 0}``."""
    s = 0.0
    for a in range(x.shape[0]):
        s += normal[a] * x[a]
    return s


class Plane:
    """An infinite wall through the body origin with unit normal ``normal`` (d,).

    Particles live on the side the normal points to. A plane has no mass properties:
    it is always a fixed body, moved only by a prescribed velocity.

    Examples
    --------
    >>> p = Plane([0.0, 0.0, 2.0])
    >>> p.normal.tolist()
    [0.0, 0.0, 1.0]
    """

    code = PLANE
    polytope = False
    stored = False  # no shape-table row: a plane is its normal
    grains = None  # a wall, not a grain
    packing = None

    def __init__(self, normal):
        n = np.asarray(normal, dtype=np.float64)
        norm = np.linalg.norm(n)
        if n.ndim != 1 or n.shape[0] not in (2, 3) or not np.isfinite(norm) or norm == 0.0:
            raise ValueError(f"plane normal must be a non-zero 2- or 3-vector, got {normal}")
        self.normal = n / norm

    def sdf(self, x):
        """Distance [m] of body-frame point ``x`` in front of the plane (negative behind)."""
        return float(np.dot(self.normal, np.asarray(x, dtype=np.float64)))

    @property
    def bounding_radius(self):
        return np.inf
