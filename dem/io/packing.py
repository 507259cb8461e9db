"""Particle packings for scenes: lattices, random loose clouds, files.

Plain functions of arrays (SI units); a problem is a ``ValueError`` with a one-line
message. :mod:`dem.io.scene` turns these messages into scene-file errors.
"""

import numpy as np

from ..limits import PARTICLES, LimitError
from .text import fmt as _fmt
from .text import reason as _reason
from .text import show as _show


def radii(r, n, rng):
    """``n`` radii [m]: ``r`` itself, or uniform in ``[r[0], r[1]]`` when ``r`` is a pair."""
    if isinstance(r, list):
        return rng.uniform(r[0], r[1], n)
    return np.full(n, float(r))


def hcp_layers(nx, ny, nz, radius):
    """Centres (nx ny nz, 3) [m] of touching spheres in HCP (ABAB) order.

    Each layer is a hexagonal layer of ``ny`` rows of ``nx`` spheres along x (rows
    ``sqrt(3) r`` apart, every other row shifted by ``r``); layers are ``2 sqrt(2/3) r``
    apart and every other layer (B) sits over the hollows of the one below (A), shifted
    by ``(r, r / sqrt(3))``. The lowest spheres along each axis touch its zero plane.
    With even ``ny`` and ``nz`` the layers tile a periodic cell of
    ``(2 r nx, sqrt(3) r ny, 2 sqrt(2/3) r nz)``.

    Examples
    --------
    >>> x = hcp_layers(2, 2, 2, 0.5)
    >>> x.shape, bool(np.isclose(np.linalg.norm(x[4] - x[0]), 1.0))  # B touches A
    ((8, 3), True)
    """
    dx, dy, dz = 2.0 * radius, np.sqrt(3.0) * radius, 2.0 * np.sqrt(2.0 / 3.0) * radius
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    x = radius + i * dx + radius * ((j + k) % 2)
    y = radius + j * dy + radius / np.sqrt(3.0) * (k % 2)
    z = radius + k * dz
    return np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)


def lattice_packing(lo, hi, r, spacing, count, rng):
    """Spheres on a simple cubic (square) lattice filling the box ``lo``..``hi`` [m].

    ``count`` None fills the box; x varies fastest. Raises ValueError if they do not fit.
    """
    r_max = max(r) if isinstance(r, list) else r
    if spacing is None:
        spacing = 2.1 * r_max
    elif spacing < 2.0 * r_max:
        raise ValueError(f"spacing must be >= 2 x the largest radius ({_fmt(2 * r_max)} m), "
                 f"got {_fmt(spacing)}")
    n_axis = np.floor((hi - lo - 2.0 * r_max) / spacing * (1 + 1e-12)) + 1.0  # float:
    if np.any(n_axis < 1):                                    # a huge box cannot wrap
        raise ValueError(f"box lo..hi is too small for one particle of radius {_fmt(r_max)} m")
    with np.errstate(over="ignore"):
        sites = float(np.prod(n_axis))
    if count is None:
        PARTICLES.check(sites, "lattice sites in the box (set count to take fewer)")
        count = int(sites)
    else:
        PARTICLES.check(count, "count")
    # the first `count` sites do not depend on axes longer than `count`
    n_axis = np.minimum(n_axis, count).astype(int)
    sites = int(np.prod(n_axis, dtype=float)) if sites > count else int(sites)
    if count > sites:
        raise ValueError(f"count = {count} exceeds the {sites} lattice sites in the box "
                 f"({' x '.join(map(str, n_axis))} at spacing {_fmt(spacing)} m)")
    # x varies fastest, the last axis slowest: layers fill from lo upwards
    idx = np.stack(np.unravel_index(np.arange(count), n_axis[::-1])[::-1], axis=1)
    return lo + r_max + spacing * idx, radii(r, count, rng)


#: solid fraction beyond which random sequential addition cannot place disks (2D) or
#: spheres (3D): the jamming limits 0.547 and 0.384
RSA_LIMIT = {2: 0.547, 3: 0.384}


def check_random_fits(lo, hi, r, count):
    """Refuse (ValueError) a random packing that cannot be made, before anything is
    allocated: more than :data:`dem.limits.PARTICLES` particles, or ``count`` particles
    of at least the smallest radius filling more of the box than random placement can.
    """
    PARTICLES.check(count, "count")
    d = len(lo)
    r_min = np.float64(min(r) if isinstance(r, list) else r)
    with np.errstate(over="ignore", invalid="ignore"):
        ball = np.pi * r_min**2 if d == 2 else 4.0 / 3.0 * np.pi * r_min**3
        box = float(np.prod(np.asarray(hi, float) - np.asarray(lo, float)))
        fraction = float(count * ball / box)
    if fraction > RSA_LIMIT[d]:
        raise ValueError(f"count = {count} particles of radius >= {_fmt(r_min)} m fill "
                         f"{fraction:.3g} of the box lo..hi; random placement stops at "
                         f"about {RSA_LIMIT[d]}: enlarge lo..hi or lower count")


def random_packing(lo, hi, radius, rng, attempts_per_particle=200):
    """Random sequential addition of non-overlapping spheres, largest first.

    Positions (n, d) [m] of spheres of ``radius`` (n,) inside the box ``lo``..``hi``;
    raises ValueError when the box cannot take them.
    """
    n, d = radius.shape[0], lo.shape[0]
    order = np.argsort(-radius, kind="stable")
    radius = radius[order]
    cell = 2.0 * radius[0]
    pos = np.empty((n, d))
    grid = {}
    offsets = [tuple(o) for o in np.ndindex(*(3,) * d)]
    budget = attempts_per_particle * n + 1000
    placed = 0
    while placed < n:
        r = radius[placed]
        if np.any(hi - lo < 2.0 * r):
            raise ValueError(f"box lo..hi is too small for one particle of radius {_fmt(r)} m")
        batch = rng.uniform(lo + r, hi - r, (64, d))
        for x in batch:
            budget -= 1
            c = tuple(int(v) for v in np.floor(x / cell))
            near = [j for o in offsets
                    for j in grid.get(tuple(a + b - 1
                                            for a, b in zip(c, o, strict=True)), ())]
            if near:
                dist = np.linalg.norm(pos[near] - x, axis=1)
                if np.any(dist < radius[near] + r):
                    continue
            pos[placed] = x
            grid.setdefault(c, []).append(placed)
            placed += 1
            break
        if budget <= 0 and placed < n:
            raise ValueError(f"could place only {placed} of count = {n} non-overlapping "
                     f"particles in the box; enlarge lo..hi or lower count")
    out = np.empty_like(pos)
    out[order] = pos
    return out


def read_packing(path, dim):
    """Positions (n, dim) and radii (n,) [m] from rows ``x y [z] r`` of a text file.

    Raises ValueError (message starting with ``file:``) for an unreadable file, more
    rows than :data:`dem.limits.PARTICLES` (counted before the file is parsed), wrong
    columns, non-finite values or overlapping spheres (naming the first pair).
    """
    try:
        _check_rows(path)
        with open(path, encoding="utf-8") as f:
            rows = np.loadtxt(f, ndmin=2, comments="#")
    except LimitError:
        raise
    except OSError as exc:
        raise ValueError(f"file: cannot read {path}: {_reason(exc)}") from exc
    except ValueError as exc:
        raise ValueError(f"file: {path}: {_reason(exc)}") from exc
    ncol = dim + 1
    if rows.shape[0] == 0:
        raise ValueError(f"file: {path} holds no particles")
    if rows.shape[1] != ncol:
        names = "x y z r" if dim == 3 else "x y r"
        raise ValueError(f"file: {path} must have {ncol} columns ({names}) for "
                 f"dim = {dim}, got {rows.shape[1]}")
    bad = ~np.all(np.isfinite(rows), axis=1) | (rows[:, -1] <= 0.0)
    if bad.any():
        k = int(np.argmax(bad))
        raise ValueError(f"file: {path}: particle {k} needs finite values and radius > 0, "
                 f"got {_show(rows[k].tolist())}")
    pos, radius = np.ascontiguousarray(rows[:, :-1]), np.ascontiguousarray(rows[:, -1])
    pair = first_overlap(pos, radius)
    if pair is not None:
        i, j, ov = pair
        raise ValueError(f"file: {path}: particles {i} and {j} (0-based rows) overlap by "
                 f"{_fmt(ov)} m")
    return pos, radius


def _check_rows(path):
    """Refuse (LimitError) a particle file of more rows than the particle limit,
    streaming it line by line (nothing of its size is held)."""
    limit = PARTICLES.value()
    n = 0
    with open(path, "rb") as f:
        for line in f:
            text = line.lstrip()
            if text and not text.startswith(b"#"):
                n += 1
                if n > limit:
                    raise LimitError(f"file: {path} holds more than {limit} particles, "
                                     f"the limit; set the environment variable "
                                     f"{PARTICLES.env} to raise it")


def first_overlap(pos, radius):
    """The overlapping pair (i, j, overlap [m]) with the smallest (i, j), or None."""
    from scipy.spatial import cKDTree

    if pos.shape[0] < 2:
        return None
    pairs = cKDTree(pos).query_pairs(2.0 * float(radius.max()), output_type="ndarray")
    if pairs.shape[0] == 0:
        return None
    i, j = pairs.min(axis=1), pairs.max(axis=1)
    ov = radius[i] + radius[j] - np.linalg.norm(pos[i] - pos[j], axis=1)
    hit = ov > 1e-12 * np.minimum(radius[i], radius[j])
    if not hit.any():
        return None
    i, j, ov = i[hit], j[hit], ov[hit]
    k = np.lexsort((j, i))[0]
    return int(i[k]), int(j[k]), float(ov[k])
