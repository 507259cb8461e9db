"""Sphere (3D) or disk (2D) of radius ``R``: ``sdf(X) = |X| - R``."""

import math

import numpy as np

from .._jit import kernel
from .kinds import SPHERE


@kernel
def sdf_sphere(x, radius):
    """Signed distance of body-frame point ``x`` (d,) [m] to a sphere/disk of ``radius`` [m]."""
    s = 0.0
    for a in range(x.shape[0]):
        s += x[a] * x[a]
    return math.sqrt(s) - radius


class Sphere:
    """A sphere in 3D, a disk in 2D (the disk is a cylinder of unit thickness, 1 m).

    Parameters
    ----------
    radius : float
        Radius [m], > 0.

    Examples
    --------
    >>> s = Sphere(0.5)
    >>> round(s.volume(3), 6), round(s.volume(2), 6)
    (0.523599, 0.785398)
    >>> round(float(s.sdf(np.array([1.0, 0.0, 0.0]))), 6)
    0.5
    """

    code = SPHERE
    polytope = False
    stored = False  # no shape-table row: a sphere is its radius
    grains = ("disks", "spheres")  # what a packing of them is, in 2D and 3D
    packing = "sphere"  # its name as a generated packing's shape ([packing] shape)

    @classmethod
    def packing_maker(cls, keys, dim):
        """The ``shape(r, rng)`` of :func:`dem.rve.generate` for a packing of these:
        None, spheres and disks are the generator's own."""
        return None

    def __init__(self, radius):
        radius = float(radius)
        if not radius > 0.0 or not math.isfinite(radius):
            raise ValueError(f"sphere radius must be a positive finite number, got {radius}")
        self.radius = radius

    def sdf(self, x):
        """Signed distance [m] of body-frame point ``x`` (d,) [m]; negative inside."""
        return sdf_sphere(np.asarray(x, dtype=np.float64), self.radius)

    @property
    def bounding_radius(self):
        """Radius [m] of the smallest origin-centred ball holding the shape."""
        return self.radius

    def volume(self, dim):
        """Volume [m^3] in 3D, area [m^2] (per metre of thickness) in 2D."""
        r = self.radius
        return 4.0 / 3.0 * math.pi * r**3 if dim == 3 else math.pi * r**2

    def inertia(self, dim, density):
        """Principal moments of inertia [kg m^2] about the centre: (3,) in 3D, (1,) in 2D."""
        m = density * self.volume(dim)
        r = self.radius
        if dim == 3:
            return np.full(3, 0.4 * m * r * r)
        return np.array([0.5 * m * r * r])
