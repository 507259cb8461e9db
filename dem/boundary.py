"""The deformable periodic cell of a representative volume element.

A :class:`PeriodicCell` is a parallelogram (2D) or parallelepiped (3D) whose edge
vectors are the columns of the cell matrix ``H`` (d, d) [m]; the scene repeats with
the lattice ``H n``, n integer. The cell deforms by a velocity gradient ``L``
(d, d) [1/s], ``dH/dt = L H``, and every body follows the affine field ``L x`` plus
its own *fluctuation*: with a cell, ``Bodies.vel`` holds the fluctuation velocity,
so the kinetic energy and the kinetic stress are those of the fluctuations. One time
step maps positions and the cell by the same ``M = I + dt L``, so a body that does not
fluctuate keeps its fractional coordinates ``s = H^-1 (x - origin)`` exactly.

``L = D + W`` may have a spin ``W`` (a finite-strain Gauss point hands its RVE the
whole displacement gradient). The material then turns: each step turns every body's
orientation, and every contact's tangential spring, by the rotation ``R`` of
``M = R U`` (its polar factor), and ``Bodies.ang_vel`` holds the spin *fluctuation*
about it. The relative velocity of a contact adds ``D l`` to the fluctuations'
difference, ``l`` the branch vector across the periodic image: the spin moves both
bodies of a pair, and their surfaces, together. A rigid rotation of the cell thus
turns positions, orientations and contact forces alike, exactly, whatever the
angle per step, and the Cauchy stress of the packing turns with it.

Any basis of the lattice describes the same periodic scene. When simple shear has
skewed the cell so that a perpendicular width falls below a set fraction of its
edge length, :meth:`PeriodicCell.reduce` swaps ``H`` for a less skewed basis of the
same lattice (``H M``, ``M`` an integer matrix of determinant 1): accumulated shear
has no limit.

The equations of motion of the fluctuations omit the ``-L v`` term of the SLLOD
equations: it is of order ``|L| |v|`` and vanishes in the quasi-static regime the
cell is meant for (inertial number well below 1e-3).
"""

import math

import numpy as np


class PeriodicCell:
    """A periodic cell with edge vectors the columns of ``h`` [m].

    Parameters
    ----------
    h : (d, d) array_like or (d,) array_like
        Cell matrix (columns are the edge vectors), or the edge lengths of an
        orthogonal cell.
    origin : (d,) array_like, optional
        Corner of the cell [m] (default 0).

    Attributes
    ----------
    h : (d, d) float64, the cell matrix, updated in place as the cell deforms
    lgrad : (d, d) float64, the velocity gradient L [1/s]; set it to deform the cell
    periodic : (d,) bool, all True

    Examples
    --------
    >>> cell = PeriodicCell([2.0, 1.0])
    >>> float(cell.volume)
    2.0
    >>> cell.fractional(np.array([[1.0, 0.5]])).tolist()
    [[0.5, 0.5]]
    """

    #: :meth:`reduce` acts once a perpendicular width falls below this fraction of
    #: the length of the edge across it (a square cell: at a shear of 1.73)
    SKEW_LIMIT = 0.5

    def __init__(self, h, origin=None):
        h = np.array(h, dtype=np.float64)
        if h.ndim == 1:
            h = np.diag(h)
        if h.ndim != 2 or h.shape[0] != h.shape[1] or h.shape[0] not in (2, 3):
            raise ValueError(f"cell matrix must be (2, 2) or (3, 3), got shape {h.shape}")
        if not np.all(np.isfinite(h)):
            raise ValueError("cell matrix must be finite")
        if not np.linalg.det(h) > 0.0:
            raise ValueError("cell matrix must have a positive determinant (right-handed, "
                             "non-degenerate edge vectors)")
        d = h.shape[0]
        self.h = h
        self.lgrad = np.zeros((d, d))
        self.origin = np.zeros(d) if origin is None else np.asarray(origin, np.float64)
        if self.origin.shape != (d,):
            raise ValueError(f"origin must have {d} components")
        self.periodic = np.ones(d, bool)
        self.n_reductions = 0

    @property
    def dim(self):
        return self.h.shape[0]

    @property
    def volume(self):
        """Cell volume [m^3] (area [m^2] in 2D)."""
        return float(np.linalg.det(self.h))

    def matrix(self):
        """The cell matrix itself (not a copy: the time-step loop updates it)."""
        return self.h

    def widths(self):
        """Perpendicular distances between opposite faces [m], (d,)."""
        return 1.0 / np.linalg.norm(np.linalg.inv(self.h), axis=1)

    def fractional(self, pos):
        """Fractional coordinates ``H^-1 (x - origin)`` of positions (n, d)."""
        return np.linalg.solve(self.h, (pos - self.origin).T).T

    def wrap(self, pos, ids):
        """Bring bodies ``ids`` into the cell (in place); velocities, being fluctuations,
        are unchanged."""
        if len(ids) == 0:
            return
        s = self.fractional(pos[ids])
        s -= np.floor(s)
        pos[ids] = self.origin + s @ self.h.T

    def image_shift(self, img):
        """Cartesian shifts ``H n`` [m] of integer images (m, d)."""
        return img @ self.h.T

    def reduce(self):
        """Replace ``H`` by a less skewed basis of the same lattice when it is too skewed.

        Size reduction of each edge against the others (Lagrange-Gauss in 2D, repeated
        passes in 3D) until no edge shortens. Returns True if the basis changed; the
        bodies must then be wrapped and the neighbour list rebuilt (the simulation
        does both at its next rebuild).
        """
        edge = np.linalg.norm(self.h, axis=0)
        if np.min(self.widths() / edge) >= self.SKEW_LIMIT:
            return False
        h = self.h.copy()
        d = self.dim
        for _ in range(16):
            changed = False
            for c in range(d):
                for a in range(d):
                    if a == c:
                        continue
                    k = np.rint(h[:, c] @ h[:, a] / (h[:, a] @ h[:, a]))
                    if k != 0.0:
                        h[:, c] -= k * h[:, a]
                        changed = True
            if not changed:
                break
        if np.allclose(h, self.h, rtol=0.0, atol=0.0):
            return False
        self.h[:, :] = h
        self.n_reductions += 1
        return True

    def copy(self):
        out = PeriodicCell(self.h.copy(), self.origin.copy())
        out.lgrad[:, :] = self.lgrad
        out.n_reductions = self.n_reductions
        return out


def load_steps(deps, max_step_strain):
    """Steps that impose the increment ``deps`` (d, d) of the displacement gradient
    with no step straining the cell by more than ``max_step_strain``: the largest
    entry of the stretch ``U - I`` of ``I + deps = R U`` over it, at least one step
    for any non-zero increment. A rotation strains nothing: the spin of a step is not
    limited (the cell turns its contacts and bodies exactly, :mod:`dem.boundary`). A
    symmetric increment is its own stretch.

    Examples
    --------
    >>> load_steps(np.diag([1e-3, -5e-4]), 1e-5)
    100
    >>> c, s = np.cos(0.5), np.sin(0.5)
    >>> load_steps(np.array([[c - 1.0, -s], [s, c - 1.0]]), 1e-5)  # a rigid turn
    1
    """
    deps = np.asarray(deps, dtype=np.float64)
    if not deps.any():
        return 0
    if np.array_equal(deps, deps.T):
        stretch = deps
    else:
        w, sv, vt = np.linalg.svd(np.eye(deps.shape[0]) + deps)
        stretch = (vt.T * sv) @ vt - np.eye(deps.shape[0])
    return max(1, math.ceil(np.abs(stretch).max() / max_step_strain))


def matrix_root(a, n):
    """The principal ``n``-th root of a (d, d) matrix ``a`` (a deformation map: no
    eigenvalue on the closed negative real axis).

    A symmetric ``a`` from its eigenvectors, ``V diag(lambda^(1/n)) V^T``; any other
    as ``exp(log(a) / n)``: square roots (Denman and Beavers' iteration) until ``a``
    is within 1/4 of the identity, Mercator's series for the logarithm, Taylor's for
    the exponential, each to round-off. Microseconds for the 2 x 2 and 3 x 3 maps of
    an RVE, where a general-purpose fractional power takes milliseconds.

    Examples
    --------
    >>> a = np.array([[1.0, 0.3], [0.0, 1.0]])  # simple shear: not diagonalisable
    >>> r = matrix_root(a, 4)
    >>> bool(np.allclose(np.linalg.matrix_power(r, 4), a, rtol=0.0, atol=1e-15))
    True
    """
    a = np.asarray(a, dtype=np.float64)
    d = a.shape[0]
    eye = np.eye(d)
    if np.array_equal(a, a.T):
        lam, vec = np.linalg.eigh(a)
        return (vec * lam ** (1.0 / n)) @ vec.T
    halvings = 0
    while np.abs(a - eye).max() > 0.25:
        if halvings == 64:
            raise ValueError("matrix_root: no principal root (an eigenvalue on the "
                             "negative real axis?)")
        y, z = a, eye
        for _ in range(100):  # Denman-Beavers: y -> sqrt(a), z -> its inverse
            y, z = 0.5 * (y + np.linalg.inv(z)), 0.5 * (z + np.linalg.inv(y))
            if np.abs(y @ y - a).max() <= 1e-15 * np.abs(a).max():
                break
        a = y
        halvings += 1
    x = a - eye
    log = np.zeros((d, d))
    term = eye
    for m in range(1, 200):  # log(I + x) = x - x^2/2 + x^3/3 - ...
        term = term @ x
        log += (term if m % 2 else -term) / m
        if np.abs(term).max() <= 1e-17 * m:
            break
    log *= 2.0**halvings / n
    out = eye.copy()
    term = eye
    for m in range(1, 100):  # exp(log) = I + log + log^2/2 + ...
        term = term @ log / m
        out += term
        if np.abs(term).max() <= 1e-17:
            break
    return out


def cell_map(lgrad, dt, n):
    """The cell map of ``n`` steps at a constant velocity gradient: (I + dt L)^n."""
    return np.linalg.matrix_power(np.eye(lgrad.shape[0]) + dt * lgrad, int(n))
