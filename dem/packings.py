"""Random packings of an RVE: size distributions, loose periodic clouds, shaped bodies.

:func:`dem.rve.generate` consolidates what these make.
"""

import math

import numpy as np

from .boundary import PeriodicCell
from .limits import PARTICLES
from .shapes import Shape
from .state import Bodies


def particle_radii(n, radius, fractions=None, seed=0):
    """``n`` radii [m] drawn from a size distribution, largest first.

    Parameters
    ----------
    radius : float, (r_min, r_max) or sequence of radii
        One size; a range (uniform in radius, by number); or size classes.
    fractions : sequence of float, optional
        With size classes: the fraction of solid volume in each class (a grading
        curve), normalised to 1.
    seed : int

    Examples
    --------
    >>> r = particle_radii(9, [1.0, 2.0], fractions=[0.5, 0.5])
    >>> r.tolist().count(2.0), r.tolist().count(1.0)  # equal volumes: 8 small per large
    (1, 8)
    """
    n = int(n)
    if n < 1:
        raise ValueError(f"the number of particles must be >= 1, got {n}")
    PARTICLES.check(n, "the number of particles")
    rng = np.random.default_rng(seed)
    r = np.atleast_1d(np.asarray(radius, dtype=np.float64))
    if not (np.all(np.isfinite(r)) and np.all(r > 0.0)):
        raise ValueError(f"radii must be positive and finite, got {radius}")
    if fractions is None:
        if r.size == 1:
            out = np.full(n, r[0])
        elif r.size == 2:
            if not r[1] >= r[0]:
                raise ValueError(f"radius range must be (r_min, r_max), got {radius}")
            out = rng.uniform(r[0], r[1], n)
        else:
            raise ValueError("several radii need their volume fractions")
    else:
        f = np.asarray(fractions, dtype=np.float64)
        if f.shape != r.shape or np.any(f < 0.0) or not f.sum() > 0.0:
            raise ValueError("fractions must be non-negative, one per radius, not all zero")
        # numbers per class from volume fractions (3D weights; the same ranking in 2D)
        w = f / r**3
        counts = np.floor(n * w / w.sum()).astype(int)
        rest = n - counts.sum()
        order = np.argsort(-(n * w / w.sum() - counts))
        counts[order[:rest]] += 1
        out = np.repeat(r, counts)
    return np.sort(out)[::-1].copy()


def cloud_lengths(dim, radii, solid_fraction, aspect=None, what="a box: an edge"):
    """Edge lengths [m] of a box that ``radii`` fill to ``solid_fraction``.

    Checks that the fraction is one random addition reaches (at most 0.5 in 2D, 0.35
    in 3D) and that every edge spans at least two diameters (``what`` names the edge in
    that error). ``aspect`` (d,) sets the edge ratios (default a cube).
    """
    if dim not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim}")
    limit = 0.5 if dim == 2 else 0.35
    if not 0.0 < solid_fraction <= limit:
        raise ValueError(f"solid_fraction of a random loose cloud must be in (0, {limit}], "
                         f"got {solid_fraction}")
    vol = (math.pi * radii**2).sum() if dim == 2 else (4.0 / 3.0 * math.pi * radii**3).sum()
    a = np.ones(dim) if aspect is None else np.asarray(aspect, dtype=np.float64)
    lengths = (vol / solid_fraction / np.prod(a)) ** (1.0 / dim) * a
    if np.any(lengths < 4.0 * radii.max()):
        raise ValueError(f"too few particles for {what} would be shorter than 2 particle "
                         "diameters")
    return lengths


def random_addition(radii, lengths, solid_fraction, seed=0, periodic=True):
    """Non-overlapping random positions [m] for ``radii`` in the box ``[0, lengths]``.

    Random sequential addition in the given order, up to 10,000 tries a particle.
    ``periodic``: centres anywhere, distances by the minimum image; otherwise every
    particle lies wholly inside the box. ``solid_fraction`` only names the fraction in
    the error when a particle finds no place.
    """
    rng = np.random.default_rng(seed)
    pos = np.empty((radii.size, lengths.size))
    for k, r in enumerate(radii):
        lo, span = (0.0, lengths) if periodic else (r, lengths - 2.0 * r)
        for _ in range(10000):
            x = lo + rng.uniform(0.0, 1.0, lengths.size) * span
            d = pos[:k] - x
            if periodic:
                d -= lengths * np.rint(d / lengths)
            if k == 0 or np.all(np.einsum("ij,ij->i", d, d) >= (radii[:k] + r) ** 2):
                pos[k] = x
                break
        else:
            raise ValueError(f"could not place particle {k} of {radii.size} at solid "
                             f"fraction {solid_fraction}: lower it")
    return pos


def loose_cloud(dim, radii, solid_fraction, seed=0, aspect=None):
    """A periodic cell and non-overlapping random positions for ``radii``.

    Random sequential addition, largest first, in a cell sized for
    ``solid_fraction`` (below the jamming limit of random addition: about 0.5 in 2D,
    0.35 in 3D). ``aspect`` (d,) sets the cell's edge ratios (default a cube).
    Returns ``(cell, pos)``.
    """
    radii = np.asarray(radii, dtype=np.float64)
    lengths = cloud_lengths(dim, radii, solid_fraction, aspect, "a periodic cell: its edge")
    pos = random_addition(radii, lengths, solid_fraction, seed, periodic=True)
    return PeriodicCell(lengths), pos


def solid_volume(bodies):
    """Volume [m^3] (area [m^2] in 2D) of the particles: spheres/disks from their
    radii, shapes as mass over density."""
    sph = bodies.kind == Shape.SPHERE
    r = bodies.radius[sph]
    v = float(np.pi * (r**2).sum()) if bodies.dim == 2 else float(
        4.0 / 3.0 * np.pi * (r**3).sum())
    shaped = ~sph & (bodies.kind != Shape.PLANE)
    return v + float(np.sum(bodies.mass[shaped] / bodies.density[shaped]))


def shape_bodies(dim, pos, radii, shape, density, seed=0):
    """Bodies of ``shape(r, rng)`` (see :func:`generate`) at ``pos`` (n, d), one per
    radius, at random orientations drawn, with the shapes, from ``seed``."""
    rng = np.random.default_rng([int(seed), 1])  # a stream apart from the cloud's
    bodies = Bodies.empty(dim)
    for r, x in zip(radii, pos, strict=True):
        sh = shape(float(r), rng)
        if getattr(sh, "dim", dim) != dim or not hasattr(sh, "bounding_radius"):
            raise ValueError(f"shape(r, rng) must return a {dim}D polytope, got {sh!r}")
        if sh.bounding_radius > r * (1.0 + 1e-9):
            raise ValueError(f"shape(r, rng) returned a body of bounding radius "
                             f"{sh.bounding_radius:.6g} m for r = {r:.6g} m (must be <= r)")
        if dim == 2:
            rot = [rng.uniform(0.0, 2.0 * np.pi)]
        else:
            q = rng.normal(size=4)
            rot = (q / np.linalg.norm(q))[None]
        bodies.add_shapes(sh, x[None], density=density, rot=rot)
    return bodies
