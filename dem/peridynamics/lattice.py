"""Material points on a lattice and their families (the bonds within the horizon).

A peridynamic body is a set of material points on a square (2D) or cubic (3D) lattice
of spacing ``dx``, each standing for one cell of volume ``dx^d`` (times the thickness in
2D). Holes and other cuts are predicates on the points; cracks are predicates on the
bonds. Families are found once, in the reference configuration, with a cell list, and
stored as persistent bonds in CSR form: point ``i``'s bonds are rows
``start[i]:start[i + 1]`` of ``nbr`` (the neighbour's index, ascending), ``xi`` (the
reference bond vector) and ``length``.
"""

from dataclasses import dataclass

import numpy as np

from .._jit import kernel


def lattice(lo, hi, dx, keep=None):
    """Cell centres of a lattice of spacing ``dx`` filling the box ``[lo, hi]``.

    Parameters
    ----------
    lo, hi : (d,) array_like [m]
        Opposite corners of the box; each side is rounded to a whole number of cells.
    dx : float [m]
        Lattice spacing.
    keep : callable, optional
        ``keep(x) -> bool (n,)`` on the ``(n, d)`` centres: the points to keep (a hole is
        ``keep = lambda x: ((x - c) ** 2).sum(1) > r ** 2``).

    Returns
    -------
    (n, d) float64 array [m]

    Examples
    --------
    >>> lattice([0, 0], [1.0, 0.5], 0.25).shape
    (8, 2)
    """
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    if lo.shape != hi.shape or lo.ndim != 1 or lo.size not in (2, 3):
        raise ValueError(f"lo and hi must both have 2 or 3 components, got {lo.shape}, {hi.shape}")
    if not (dx > 0.0 and np.isfinite(dx)):
        raise ValueError(f"dx must be positive and finite, got {dx}")
    counts = np.rint((hi - lo) / dx).astype(np.int64)
    if np.any(counts < 1):
        raise ValueError(f"the box {lo} .. {hi} holds no cell of size {dx}")
    axes = [lo[k] + (np.arange(counts[k]) + 0.5) * dx for k in range(lo.size)]
    pos = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, lo.size)
    if keep is not None:
        mask = np.asarray(keep(pos), dtype=bool)
        if mask.shape != (pos.shape[0],):
            raise ValueError(f"keep must return one bool per point, got shape {mask.shape}")
        pos = pos[mask]
    return np.ascontiguousarray(pos)


def crack(a, b):
    """A 2D pre-crack along the segment ``a``-``b``: a bond predicate for :meth:`Family.build`
    that cuts every bond whose reference segment crosses it."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.shape != (2,) or b.shape != (2,):
        raise ValueError("crack() takes two 2D end points")

    def cross(u, v):
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    def cut(xi, xj):
        d1 = cross(b - a, xi - a)
        d2 = cross(b - a, xj - a)
        d3 = cross(xj - xi, a - xi)
        d4 = cross(xj - xi, b - xi)
        return (d1 * d2 < 0.0) & (d3 * d4 < 0.0)

    return cut


@dataclass(eq=False)
class Family:
    """Bonds of every point within the horizon, in CSR form (rows of point ``i``:
    ``start[i]:start[i + 1]``).

    Attributes
    ----------
    start : (n + 1,) int64
    nbr : (nb,) int64, the neighbour of each bond, ascending within a row
    xi : (nb, d) float64 [m], reference bond vector ``X_j - X_i``
    length : (nb,) float64 [m], ``|xi|``
    broken : (nb,) uint8, 1 once the bond has broken (both directions break together)
    twin : (nb,) int64, the row of the same bond seen from its other end
    """

    start: np.ndarray
    nbr: np.ndarray
    xi: np.ndarray
    length: np.ndarray
    broken: np.ndarray
    twin: np.ndarray

    @property
    def n_bonds(self):
        """Number of bonds, each counted once per direction."""
        return self.nbr.shape[0]

    @classmethod
    def build(cls, pos, horizon, solid=None, cut=None):
        """Families of the points at ``pos`` (n, d) in their reference configuration.

        Parameters
        ----------
        pos : (n, d) array_like [m]
        horizon : float [m]
            Bonds join points closer than ``horizon`` (a tolerance of 1e-9 of it decides
            lattice points at exactly the horizon, which are included).
        solid : (n,) int array_like, optional
            Points bond only within their own solid; a negative label bonds nothing
            (DEM bodies in the same table).
        cut : callable, optional
            ``cut(xi, xj) -> bool (m,)`` on bond end points (m, d): bonds to leave out,
            e.g. :func:`crack`.

        Examples
        --------
        >>> f = Family.build(lattice([0, 0], [1, 1], 0.25), horizon=0.26)
        >>> int(f.n_bonds), int(f.start[6] - f.start[5])  # an interior point has 4
        (48, 4)
        """
        pos = np.ascontiguousarray(pos, dtype=np.float64)
        n = pos.shape[0]
        if not (horizon > 0.0 and np.isfinite(horizon)):
            raise ValueError(f"horizon must be positive and finite, got {horizon}")
        label = np.zeros(n, np.int64) if solid is None else np.asarray(solid, np.int64)
        if label.shape != (n,):
            raise ValueError(f"solid must have one label per point, got {label.shape}")
        reach = horizon * (1.0 + 1e-9)
        pairs = pairs_within(pos, np.full(n, 0.5 * reach), 0.0, label)
        if cut is not None and pairs.shape[0]:
            drop = np.asarray(cut(pos[pairs[:, 0]], pos[pairs[:, 1]]), dtype=bool)
            pairs = pairs[~drop]
        both = np.concatenate([pairs, pairs[:, ::-1]])
        order = np.lexsort((both[:, 1], both[:, 0]))
        both = both[order]
        start = np.searchsorted(both[:, 0], np.arange(n + 1)).astype(np.int64)
        nbr = np.ascontiguousarray(both[:, 1], dtype=np.int64)
        xi = pos[nbr] - pos[both[:, 0]]
        length = np.sqrt((xi**2).sum(axis=1))
        key = both[:, 0] * n + both[:, 1]  # ascending
        twin = np.searchsorted(key, both[:, 1] * n + both[:, 0]).astype(np.int64)
        return cls(start, nbr, np.ascontiguousarray(xi), length,
                   np.zeros(nbr.shape[0], np.uint8), twin)

    def owner(self):
        """The point each bond belongs to, (nb,) int64."""
        return np.repeat(np.arange(self.start.size - 1), np.diff(self.start))

    def _features(self):
        x = self.xi
        if x.shape[1] == 2:
            phi = np.stack([x[:, 0] ** 2, x[:, 1] ** 2, x[:, 0] * x[:, 1]], axis=1)
        else:
            phi = np.stack([x[:, 0] ** 2, x[:, 1] ** 2, x[:, 2] ** 2, x[:, 0] * x[:, 1],
                            x[:, 1] * x[:, 2], x[:, 2] * x[:, 0]], axis=1)
        return phi / (self.length**2)[:, None]

    def dilation_weights(self, omega, vol, mvol, corrected):
        """Per-bond weights ``q`` of the LPS dilation ``theta_i = sum_j w |xi| e V_j q``.

        Uncorrected, ``q = d / m_i``: exact for any homogeneous deformation of a full
        (bulk) family, but not of one cut by a free surface. Corrected, ``q = n . Q_i n``
        (``n`` the bond's direction) with the symmetric ``Q_i`` that makes ``theta_i =
        tr(eps)`` exactly for every homogeneous small strain ``eps`` of the point's own
        family (``Q_i = (d / m_i) I`` in a bulk family of a square or cubic lattice). A
        point whose family cannot resolve every strain, or whose corrected weights are not
        all positive (a corner), keeps ``d / m_i``.
        """
        n, d = self.start.size - 1, self.xi.shape[1]
        own = self.owner()
        plain = np.divide(d, mvol, out=np.zeros(n), where=mvol > 0.0)[own]
        if not corrected or self.n_bonds == 0:
            return plain
        phi = self._features()  # n⊗n as (xx, yy, xy) or (xx, yy, zz, xy, yz, zx)
        k = phi.shape[1]
        rhs = np.r_[np.ones(d), np.zeros(k - d)]
        # sum_j w V_j |xi|^2 (n . eps n)(n . Q n) = tr(eps) for every eps
        g = omega * vol[self.nbr] * self.length**2
        sym = np.r_[np.ones(d), 2.0 * np.ones(k - d)]  # eps_xy appears twice in n . eps n
        mom = np.zeros((n, k, k))
        np.add.at(mom, own, g[:, None, None] * (phi * sym)[:, :, None] * phi[:, None, :])
        return self._solve(mom, rhs, phi, own, plain)

    @staticmethod
    def _solve(mom, rhs, phi, own, plain):
        n, k = mom.shape[0], mom.shape[1]
        ok = np.linalg.cond(mom) < 1e8
        q = np.zeros((n, k))
        if ok.any():
            b = np.broadcast_to(rhs, (int(ok.sum()), k))
            q[ok] = np.linalg.solve(mom[ok], b[..., None])[..., 0]
        out = (phi * q[own]).sum(1)
        ok &= np.bincount(own, out <= 0.0, minlength=n) == 0  # a weight <= 0 softens a bond
        return np.where(ok[own], out, plain)


def pairs_within(pos, reach, skin, label):
    """Pairs ``(i, j)``, ``i < j``, with ``|x_j - x_i| < reach_i + reach_j + skin``.

    Points with a negative ``label`` are skipped and two points pair only when their
    labels are equal (equal labels everywhere pair every point). A cell list sized by the
    largest reach: O(n) for lattice scenes.
    """
    pos = np.ascontiguousarray(pos, dtype=np.float64)
    n = pos.shape[0]
    if n == 0:
        return np.zeros((0, 2), np.int64)
    cell = 2.0 * float(np.max(reach)) + skin
    lo = pos.min(axis=0)
    span = pos.max(axis=0) - lo
    while np.prod(np.floor(span / cell) + 1.0) > 8.0 * n + 1000.0:
        cell *= 2.0  # sparse scenes: fewer, fuller cells rather than a huge empty grid
    idx = np.floor((pos - lo) / cell).astype(np.int64)
    dims = idx.max(axis=0) + 1
    flat = np.ravel_multi_index(idx.T, dims)
    order = np.argsort(flat, kind="stable").astype(np.int64)
    cstart = np.searchsorted(flat[order], np.arange(int(np.prod(dims)) + 1)).astype(np.int64)
    count = np.zeros(1, np.int64)
    args = (pos, np.ascontiguousarray(reach, dtype=np.float64), float(skin),
            np.ascontiguousarray(label, dtype=np.int64), idx, dims.astype(np.int64), order,
            cstart)
    _cell_pairs(*args, np.zeros((0, 2), np.int64), count)
    out = np.zeros((int(count[0]), 2), np.int64)
    _cell_pairs(*args, out, count)
    return out


@kernel
def _cell_pairs(pos, reach, skin, label, idx, dims, order, cstart, out, count):
    """Pairs within reach through the cell list; counts only when ``out`` is empty."""
    n, d = pos.shape
    fill = out.shape[0] > 0
    m = 0
    nb = 3**d
    for i in range(n):
        if label[i] < 0:
            continue
        for q in range(nb):
            flat = 0
            inside = True
            rem = q
            for k in range(d):
                c = idx[i, k] + rem % 3 - 1
                rem //= 3
                if c < 0 or c >= dims[k]:
                    inside = False
                    break
                flat = flat * dims[k] + c
            if not inside:
                continue
            for s in range(cstart[flat], cstart[flat + 1]):
                j = order[s]
                if j <= i or label[j] != label[i]:
                    continue
                r2 = 0.0
                for k in range(d):
                    dx = pos[j, k] - pos[i, k]
                    r2 += dx * dx
                lim = reach[i] + reach[j] + skin
                if r2 < lim * lim:
                    if fill:
                        out[m, 0] = i
                        out[m, 1] = j
                    m += 1
    count[0] = m
