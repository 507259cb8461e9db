"""Neighbour search: a Verlet list with a skin, built over an O(n) cell list.

The list holds every particle pair closer than ``r_i + r_j + skin`` as a half list
(``i < j``), sorted by ``(i, j)``, with the periodic image of ``j`` for periodic axes,
and every (particle, wall) pair closer than ``r_i + skin``; ``r`` is a sphere's radius
or a shape's bounding radius. It stays valid while no body
has moved more than ``skin / 2`` since the build. Contact history survives a rebuild:
rows are carried to the new list by pair key ``(i, j)`` with a linear merge of the two
sorted lists. A k-d tree backend (``scipy.spatial.cKDTree``) builds the same list.

Kernels have fixed capacity and return the number of pairs they needed; the Python
wrapper regrows and retries.
"""

import logging

import numpy as np

from ._jit import kernel
from .boundary import PeriodicCell
from .shapes import Shape

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------- kernels
@kernel
def build_cell_pairs(pos, radius, sphere_ids, skin, lo, length, n_cells, periodic,
                     hmat, hinv, triclinic, pairs_out, img_out):
    """Half Verlet list over a cell list; returns the number of pairs found.

    ``sphere_ids`` ascending. ``lo`` (d,), ``length`` (d,) bound the grid, ``n_cells``
    (d,) int64 cells per axis, ``periodic`` (d,) bool. Positions on periodic axes must
    lie in ``[lo, lo + length)``. ``triclinic``: the grid lives in the fractional
    coordinates ``hinv (x - lo)`` of a periodic cell with matrix ``hmat`` (every axis
    periodic, ``length`` unused), and images are the nearest in fractional terms,
    ``x_j - x_i + hmat img``. Writes up to ``pairs_out.shape[0]`` pairs; a return value
    larger than that means the buffers overflowed and nothing past the capacity was
    written.

    The candidates are read from copies of the positions and radii in cell order, so a
    cell's members sit side by side; a cell holds its members in ascending order, so
    the scan of a cell from its end stops at the first ``j <= i``. Without periodic
    axes, the distance is the plain one, without images (a 2D copy has a zero third
    coordinate, which adds an exact zero).
    """
    d = pos.shape[1]
    ns = sphere_ids.shape[0]
    cap = pairs_out.shape[0]
    coords, start, items = _bin_spheres(pos, sphere_ids, lo, length, n_cells, hinv,
                                        triclinic)
    stencil = _stencil(n_cells, periodic)
    plain = not triclinic
    for a in range(d):
        plain = plain and not periodic[a]
    cpos = np.zeros((ns, 3))  # members in cell order
    crad = np.empty(ns)
    cid = np.empty(ns, np.int64)
    for q in range(ns):
        j = sphere_ids[items[q]]
        cid[q] = j
        crad[q] = radius[j]
        for a in range(d):
            cpos[q, a] = pos[j, a]
    buf = np.empty(64, np.int64)
    bimg = np.zeros((64, d), np.int64)
    order = np.empty(64, np.int64)
    n_pairs = 0
    shift = np.zeros(d)
    xi = np.zeros(3)
    for s in range(ns):
        i = sphere_ids[s]
        for a in range(d):
            xi[a] = pos[i, a]
        m = 0
        for t in range(stencil.shape[0]):
            c = _stencil_cell(coords, s, stencil, t, n_cells, periodic)
            if c < 0:
                continue
            for q in range(start[c + 1] - 1, start[c] - 1, -1):
                j = cid[q]
                if j <= i:
                    break
                cut = radius[i] + crad[q] + skin
                if plain:
                    dx = cpos[q, 0] - xi[0]
                    dy = cpos[q, 1] - xi[1]
                    dz = cpos[q, 2] - xi[2]
                    r2 = dx * dx + dy * dy + dz * dz
                else:
                    r2 = _image_distance2(cpos, q, xi, d, length, periodic, hmat, hinv,
                                          triclinic, shift)
                if r2 < cut * cut:
                    if m == buf.shape[0]:
                        buf, bimg, order = _grow_row(buf, bimg, m)
                    buf[m] = j
                    if not plain:
                        for a in range(d):
                            bimg[m, a] = -np.int64(shift[a])
                    m += 1
        _sort_row(buf, order, m)
        for u in range(m):
            if n_pairs < cap:
                pairs_out[n_pairs, 0] = i
                pairs_out[n_pairs, 1] = buf[order[u]]
                for a in range(d):
                    img_out[n_pairs, a] = bimg[order[u], a]
            n_pairs += 1
    return n_pairs


@kernel(inline=True)
def _stencil_cell(coords, s, stencil, t, n_cells, periodic):
    """The flat index of sphere s's neighbour cell ``stencil[t]``, wrapped on periodic
    axes; -1 past an open edge."""
    c = 0
    for a in range(n_cells.shape[0]):
        ca = coords[s, a] + stencil[t, a]
        if ca < 0 or ca >= n_cells[a]:
            if not periodic[a]:
                return -1
            ca = (ca + n_cells[a]) % n_cells[a]
        c = c * n_cells[a] + ca
    return c


@kernel(inline=True)
def _grow_row(buf, bimg, m):
    """A row's buffers at twice their size, the first ``m`` slots kept."""
    nb = np.empty(2 * m, np.int64)
    nb[:m] = buf[:m]
    ni = np.zeros((2 * m, bimg.shape[1]), np.int64)
    ni[:m] = bimg[:m]
    return nb, ni, np.empty(2 * m, np.int64)


@kernel
def _bin_spheres(pos, sphere_ids, lo, length, n_cells, hinv, triclinic):
    """Each sphere's cell coordinates ``(ns, d)`` and the cells' members as a CSR pair
    ``(start, items)``: cell ``c`` holds ``items[start[c]:start[c + 1]]``, in order."""
    d = pos.shape[1]
    ns = sphere_ids.shape[0]
    n_tot = 1
    for a in range(d):
        n_tot *= n_cells[a]
    cell_of = np.empty(ns, np.int64)
    coords = np.empty((ns, d), np.int64)
    counts = np.zeros(n_tot + 1, np.int64)
    for s in range(ns):
        i = sphere_ids[s]
        c = 0
        for a in range(d):
            if triclinic:
                f = 0.0
                for e in range(d):
                    f += hinv[a, e] * (pos[i, e] - lo[e])
                f *= n_cells[a]
            else:
                f = (pos[i, a] - lo[a]) / length[a] * n_cells[a]
            ci = int(np.floor(f))
            ci = max(ci, 0)
            if ci >= n_cells[a]:
                ci = n_cells[a] - 1
            coords[s, a] = ci
            c = c * n_cells[a] + ci
        cell_of[s] = c
        counts[c + 1] += 1
    for c in range(n_tot):
        counts[c + 1] += counts[c]
    start = counts.copy()
    items = np.empty(ns, np.int64)
    fill = counts[:-1].copy()
    for s in range(ns):
        c = cell_of[s]
        items[fill[c]] = s
        fill[c] += 1
    return coords, start, items


@kernel
def _stencil(n_cells, periodic):
    """The neighbour-cell offsets ``(n_stencil, d)``, decoded once, not per particle;
    deduplicated on an axis with fewer than 3 cells."""
    d = n_cells.shape[0]
    offs = np.empty((d, 3), np.int64)
    n_off = np.empty(d, np.int64)
    for a in range(d):
        m = 0
        for o in (-1, 0, 1):
            if n_cells[a] == 1 and o != 0:
                continue
            if n_cells[a] == 2 and o == 1 and periodic[a]:
                continue
            offs[a, m] = o
            m += 1
        n_off[a] = m
    n_stencil = 1
    for a in range(d):
        n_stencil *= n_off[a]
    stencil = np.empty((n_stencil, d), np.int64)
    for t in range(n_stencil):
        rem = t
        for a in range(d - 1, -1, -1):
            stencil[t, a] = offs[a, rem % n_off[a]]
            rem //= n_off[a]
    return stencil


@kernel(inline=True)
def _image_distance2(cpos, q, xi, d, length, periodic, hmat, hinv, triclinic, shift):
    """Squared distance from a sphere at ``xi`` to the nearest image of the one at
    ``cpos[q]``; that image's shift (in cell vectors, or lengths on a rectangular grid)
    is written to ``shift``."""
    r2 = 0.0
    if triclinic:
        for a in range(d):
            ds = 0.0
            for e in range(d):
                ds += hinv[a, e] * (cpos[q, e] - xi[e])
            shift[a] = np.floor(ds + 0.5)
        for a in range(d):
            dx = cpos[q, a] - xi[a]
            for e in range(d):
                dx -= hmat[a, e] * shift[e]
            r2 += dx * dx
    else:
        for a in range(d):
            dx = cpos[q, a] - xi[a]
            if periodic[a]:
                sh = np.floor(dx / length[a] + 0.5)
                dx -= sh * length[a]
                shift[a] = sh
            else:
                shift[a] = 0.0
            r2 += dx * dx
    return r2


@kernel(inline=True)
def _sort_row(buf, order, m):
    """Insertion sort of a row's first ``m`` slots by ``buf`` into ``order`` (rows are
    short)."""
    for u in range(m):
        order[u] = u
    for u in range(1, m):
        t = order[u]
        v = u - 1
        while v >= 0 and buf[order[v]] > buf[t]:
            order[v + 1] = order[v]
            v -= 1
        order[v + 1] = t


@kernel
def build_wall_pairs(pos, radius, sphere_ids, wall_ids, normal, skin, pairs_out):
    """(sphere, wall) pairs with ``(x_i - p_w) . n_w - r_i < skin``, sorted by sphere."""
    cap = pairs_out.shape[0]
    d = pos.shape[1]
    m = 0
    for s in range(sphere_ids.shape[0]):
        i = sphere_ids[s]
        for w in range(wall_ids.shape[0]):
            j = wall_ids[w]
            gap = -radius[i]
            for a in range(d):
                gap += (pos[i, a] - pos[j, a]) * normal[j, a]
            if gap < skin:
                if m < cap:
                    pairs_out[m, 0] = i
                    pairs_out[m, 1] = j
                m += 1
    return m


@kernel
def carry_history(old_pairs, old_hist, new_pairs, new_hist_out):
    """Copy history rows whose pair key ``(i, j)`` is in both lists (both sorted).

    A key may repeat (a compound's parts: one row per pair of parts, in the same order
    in both lists): the k-th row of a run carries the k-th row of the old run. Rows of
    new pairs start at zero. Returns the number of rows carried.
    """
    new_hist_out[:] = 0.0
    a = 0
    carried = 0
    n_old = old_pairs.shape[0]
    for b in range(new_pairs.shape[0]):
        i, j = new_pairs[b, 0], new_pairs[b, 1]
        while a < n_old and (old_pairs[a, 0] < i or (old_pairs[a, 0] == i and old_pairs[a, 1] < j)):
            a += 1
        if a < n_old and old_pairs[a, 0] == i and old_pairs[a, 1] == j:
            new_hist_out[b, :] = old_hist[a, :]
            carried += 1
            a += 1
    return carried


@kernel
def incidence(pairs, n, col, start_out, list_out):
    """CSR of the rows of ``pairs`` where column ``col`` equals each body, rows in order.

    ``start_out`` (n + 1,), ``list_out`` (m,) int64. A stable counting sort: the gather
    that sums per-pair forces onto bodies visits them in a fixed order.
    """
    start_out[:] = 0
    for k in range(pairs.shape[0]):
        start_out[pairs[k, col] + 1] += 1
    for b in range(n):
        start_out[b + 1] += start_out[b]
    fill = start_out[:n].copy()
    for k in range(pairs.shape[0]):
        b = pairs[k, col]
        list_out[fill[b]] = k
        fill[b] += 1


# --------------------------------------------------------------------------- Python side
class Box:
    """The simulation domain: bounds ``lo``/``hi`` (d,) [m], periodic axes (d,) bool.

    Exported as ``dem.Domain`` (``dem.Box`` is the box-shaped particle).

    Non-periodic axes need no bounds (the cell grid follows the particles); a periodic
    axis wraps positions into ``[lo, hi)``.
    """

    def __init__(self, lo, hi, periodic):
        self.lo = np.asarray(lo, dtype=np.float64)
        self.hi = np.asarray(hi, dtype=np.float64)
        self.periodic = np.asarray(periodic, dtype=bool)
        if np.any(self.periodic & ~(self.hi > self.lo)):
            raise ValueError("a periodic axis needs hi > lo")

    @property
    def length(self):
        return self.hi - self.lo

    def matrix(self):
        """Cell matrix H (d, d) [m] (diagonal: an orthogonal box)."""
        return np.diag(np.where(self.periodic, self.length, 0.0))

    def wrap(self, pos, ids):
        """Wrap positions of bodies ``ids`` into the box on periodic axes (in place)."""
        if not self.periodic.any():
            return
        p = pos[ids]
        ax = self.periodic
        p[:, ax] = self.lo[ax] + np.mod(p[:, ax] - self.lo[ax], self.length[ax])
        pos[ids] = p


class NeighborList:
    """Verlet list with skin over a cell list (``backend="cell"``) or a k-d tree.

    Attributes (after :meth:`build`)
    ----------
    pairs : (m, 2) int32, sphere pairs ``i < j`` sorted by ``(i, j)``
    img : (m, d) int32, periodic image of j relative to i
    wall_pairs : (mw, 2) int32, (sphere, wall) pairs sorted by sphere
    pos_ref : (n, d), positions at the build; ``n_builds`` counts builds.
    """

    def __init__(self, skin, backend="cell", box=None):
        if not skin > 0.0:
            raise ValueError(f"skin must be positive, got {skin}")
        if backend not in ("cell", "kdtree"):
            raise ValueError(f"neighbour backend must be 'cell' or 'kdtree', got {backend!r}")
        self.skin = float(skin)
        self.backend = backend
        self.box = box
        self.n_builds = 0
        #: rows of the cell search's pair buffer (grown on overflow; 0 before the first
        #: build). Part of the state: it decides how the next build fills its buffer
        self.capacity = 0
        self.pairs = None

    def build(self, bodies):
        """Rebuild both lists from the current positions (wrapping periodic axes)."""
        d = bodies.dim
        # every particle (sphere or shape, by its bounding radius) against every other
        spheres = np.flatnonzero(bodies.kind != Shape.PLANE).astype(np.int32)
        walls = bodies.ids(Shape.PLANE)
        box = self.box or Box(np.zeros(d), np.zeros(d), np.zeros(d, bool))
        box.wrap(bodies.pos, spheres)
        if spheres.size == 0:
            pairs, img = np.zeros((0, 2), np.int32), np.zeros((0, d), np.int32)
        elif self.backend == "cell":
            pairs, img = self._build_cell(bodies, spheres, box)
        else:
            pairs, img = self._build_kdtree(bodies, spheres, box)
        mw_cap = max(16, spheres.size * max(walls.size, 1))
        wbuf = np.empty((min(mw_cap, 4 * spheres.size + 16), 2), np.int32)
        mw = build_wall_pairs(bodies.pos, bodies.radius, spheres, walls, bodies.normal,
                              self.skin, wbuf)
        if mw > wbuf.shape[0]:
            wbuf = np.empty((mw, 2), np.int32)
            mw = build_wall_pairs(bodies.pos, bodies.radius, spheres, walls, bodies.normal,
                                  self.skin, wbuf)
        self.pairs, self.img = pairs, img
        self.wall_pairs = wbuf[:mw].copy()
        self.pos_ref = bodies.pos.copy()
        self.n_builds += 1
        return self

    def _build_cell(self, bodies, spheres, box):
        d = bodies.dim
        pos, radius = bodies.pos, bodies.radius
        rmax = float(radius[spheres].max())
        cell = 2.0 * rmax + self.skin
        triclinic = isinstance(box, PeriodicCell)
        if triclinic:  # the grid counts perpendicular widths, in fractional coordinates
            hmat = box.h
            hinv = np.linalg.inv(hmat)
            lo, length = box.origin, box.widths()
        else:
            hmat = hinv = np.eye(d)
            lo = np.where(box.periodic, box.lo, pos[spheres].min(axis=0))
            length = np.where(box.periodic, box.length,
                              pos[spheres].max(axis=0) - lo + 1e-12)
        if np.any(box.periodic & (length < 2.0 * cell)):
            raise ValueError(
                f"periodic cell width {length[box.periodic].min():.4g} m is less than "
                f"twice the neighbour cut-off {cell:.4g} m")
        n_cells = np.maximum(1, np.floor(length / cell)).astype(np.int64)
        while np.prod(n_cells) > 8 * spheres.size + 64:  # sparse scenes: coarser grid
            n_cells = np.maximum(1, n_cells // 2)
        if self.capacity == 0:
            self.capacity = 8 * spheres.size + 64
        while True:
            pairs = np.empty((self.capacity, 2), np.int32)
            img = np.empty((self.capacity, d), np.int32)
            m = build_cell_pairs(pos, radius, spheres, self.skin, lo, length, n_cells,
                                 box.periodic, hmat, hinv, triclinic, pairs, img)
            if m <= self.capacity:
                return pairs[:m].copy(), img[:m].copy()
            log.debug("neighbour list overflow (%d > %d pairs): regrowing", m, self.capacity)
            self.capacity = int(1.25 * m) + 16

    def _build_kdtree(self, bodies, spheres, box):
        from scipy.spatial import cKDTree

        if isinstance(box, PeriodicCell):
            raise ValueError("the kdtree neighbour backend needs an orthogonal Domain; "
                             "a PeriodicCell uses backend='cell'")
        d = bodies.dim
        pos = bodies.pos[spheres]
        radius = bodies.radius[spheres]
        cut = 2.0 * radius.max() + self.skin
        if box.periodic.any():
            # cKDTree's periodic mode needs every axis periodic: pad open axes with a huge box
            span = pos.max(axis=0) - pos.min(axis=0) + 4.0 * cut + 1.0
            size = np.where(box.periodic, box.length, 1e3 * span)
            shifted = np.where(box.periodic, pos - box.lo, pos - pos.min(axis=0) + cut)
            tree = cKDTree(shifted, boxsize=size)
        else:
            tree = cKDTree(pos)
            shifted = pos
        raw = tree.query_pairs(cut, output_type="ndarray")
        if raw.size == 0:
            return np.zeros((0, 2), np.int32), np.zeros((0, d), np.int32)
        a, b = raw[:, 0], raw[:, 1]
        dx = shifted[b] - shifted[a]
        img = np.zeros((raw.shape[0], d), np.int64)
        if box.periodic.any():
            sh = np.floor(dx / np.where(box.periodic, box.length, 1.0) + 0.5)
            sh[:, ~box.periodic] = 0.0
            dx -= sh * np.where(box.periodic, box.length, 0.0)
            img = -sh.astype(np.int64)
        keep = np.einsum("ij,ij->i", dx, dx) < (radius[a] + radius[b] + self.skin) ** 2
        i, j, img = spheres[a[keep]], spheres[b[keep]], img[keep]
        swap = i > j
        i, j = np.where(swap, j, i), np.where(swap, i, j)
        img[swap] = -img[swap]
        order = np.lexsort((j, i))
        pairs = np.stack([i[order], j[order]], axis=1).astype(np.int32)
        return pairs, img[order].astype(np.int32)
