"""Periodic boundary conditions on the macro mesh, by condensing degrees of freedom.

A pair of opposite boundaries (``boundary`` and its ``image``, the same nodes shifted
by ``L``) is tied node by node: ``u(x + L) = u(x) + G L``, ``G`` the average
displacement gradient [-]. The tied degrees of freedom of one component form groups
(a corner of a 2D cell on two pairs: four nodes, one group); the first of a group
stands for it in the reduced system (:func:`hmm.coupling.tie_map`) and every other
member is that one plus its jump ``(G (x_m - x_first))_c``, prescribed and ramped with
the load factor like any prescribed displacement. Newton corrections keep the jumps,
so the fluctuation ``u - G x`` is periodic to round-off.

A group may contain one held degree of freedom (a point support at a corner, against
rigid translation): it then stands for the group.
"""

import numpy as np
from scipy.spatial import cKDTree


class PairError(ValueError):
    """A periodic pair that does not fit: ``index`` (0-based; None: the pairs
    together) and the one-line ``reason``."""

    def __init__(self, index, reason):
        self.index, self.reason = index, reason
        super().__init__(reason if index is None else f"pair #{index + 1}: {reason}")


def periodic_ties(macro, pairs, gradient, fixed, taken=()):
    """``(groups, jumps)`` for periodic ``pairs`` (each with ``boundary`` and
    ``image``): the tied degree-of-freedom groups, the first of each standing for it,
    and each member's jump from the first (m,) [m] at load factor 1.

    ``fixed`` are the held degrees of freedom (at most one per group; it stands for
    its group), ``taken`` the groups of platens, which periodic pairs may not touch.
    Raises :class:`PairError` naming the pair and the cause.
    """
    d = macro.dim
    n = macro.n_dofs
    locs = macro.basis.doflocs.T  # (n_dofs, d) [m]
    scale = float(np.ptp(macro.mesh.p, axis=1).max())
    tol = 1e-9 * scale
    parent = np.arange(n)
    comp = np.full(n, -1)

    def root(k):
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    busy = np.concatenate([np.asarray(t) for t in taken]) if taken else np.zeros(0, int)
    for i, pair in enumerate(pairs):
        try:
            a_all, b_all = _pair_dofs(macro, pair, locs, tol)
        except ValueError as err:
            raise PairError(i, str(err)) from None
        for c in range(d):
            a, b = a_all[c], b_all[c]
            if np.intersect1d(np.concatenate([a, b]), busy).size:
                raise PairError(i, f"\"{pair.boundary}\" or "
                                     f"\"{pair.image}\" is also a platen")
            comp[a] = comp[b] = c
            for ka, kb in zip(a, b, strict=True):
                ra, rb = root(ka), root(kb)
                if ra != rb:
                    parent[max(ra, rb)] = min(ra, rb)
    roots = np.array([root(k) for k in range(n)])
    held = np.zeros(n, bool)
    held[np.asarray(fixed, dtype=np.int64)] = True
    groups, jumps = [], []
    order = np.argsort(roots, kind="stable")
    starts = np.flatnonzero(np.diff(roots[order], prepend=-1))
    for members in np.split(order, starts[1:]):
        if members.size < 2:
            continue
        on = members[held[members]]
        if on.size > 1:
            shown = " and ".join("(" + ", ".join(f"{x:g}" for x in locs[k]) + ")"
                                 for k in on[:2])
            raise PairError(None, f"the pairs tie held degrees of freedom "
                                 f"at {shown} to each other: hold one node of a "
                                 f"periodic group only (a point support)")
        first = on[0] if on.size else members[0]
        group = np.concatenate([[first], members[members != first]])
        jumps.append((locs[group] - locs[first]) @ gradient[comp[first]])
        groups.append(group)
    return groups, jumps


def _pair_dofs(macro, pair, locs, tol):
    """For each component, the dofs of ``pair.boundary`` and, in the same order, their
    images on ``pair.image``; ValueError if the two are not translates."""
    known = macro.mesh.boundaries or {}
    for name in (pair.boundary, pair.image):
        if name not in known:
            raise ValueError(f"boundary \"{name}\" is not a boundary of the mesh "
                             f"(known: {', '.join(sorted(known)) or 'none'})")
    a_all, b_all = [], []
    for c in range(macro.dim):
        a, b = macro.dofs(pair.boundary, c), macro.dofs(pair.image, c)
        if a.size != b.size:
            raise ValueError(f"\"{pair.boundary}\" has {a.size} nodes and "
                             f"\"{pair.image}\" {b.size}: they are not images of each "
                             f"other")
        shift = locs[b].mean(axis=0) - locs[a].mean(axis=0)
        if np.linalg.norm(shift) <= tol:
            raise ValueError(f"\"{pair.boundary}\" and \"{pair.image}\" are the same "
                             f"boundary")
        dist, j = cKDTree(locs[b]).query(locs[a] + shift)
        if dist.max() > tol or np.unique(j).size != j.size:
            bad = locs[a[int(np.argmax(dist))]]
            raise ValueError(f"the nodes of \"{pair.image}\" are not those of "
                             f"\"{pair.boundary}\" shifted by "
                             f"[{', '.join(f'{s:g}' for s in shift)}] m (the node at "
                             f"({', '.join(f'{x:g}' for x in bad)}) has no image)")
        a_all.append(a)
        b_all.append(b[j])
    return a_all, b_all

