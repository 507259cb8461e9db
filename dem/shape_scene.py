"""The part of :class:`dem.Simulation` that runs scenes with non-spherical shapes.

A scene with level-set shapes (boxes, polytopes, compounds, user SDFs) runs the shape
loop (:func:`dem.contact.shape_loop.shape_stepper`). Contact detection works on
*parts*: one per body, one per convex part of a compound. Pairs of parts are grouped
into buckets by their shape kinds, and each bucket runs the detection method of its
kinds. :class:`ShapeScene` holds these tables and calls the loop; ``Simulation``
inherits it. Its state arrays are the shape bundles of :mod:`dem.state`.
"""

import numpy as np

from .contact.shape_contacts import method_for, pair_incidence, wall_method_for
from .contact.shape_loop import BucketIndex, Detection, PartArrays, shape_stepper
from .neighbors import carry_history, incidence
from .shapes import Shape
from .state import NeighborArrays, ShapePairState, ShapeWallState


class ShapeScene:
    """Buckets, parts and the compiled loop of a scene with non-spherical shapes (a
    base of :class:`dem.Simulation`, which provides the bodies, neighbour lists, model
    and contact-state bundles)."""

    def _shape_setup(self, periodic):
        """Buckets of the scene's kinds and the loop compiled for them."""
        b = self.bodies
        force_admm = self.detection == "admm"
        self._part_table()
        kinds = sorted({int(k) for k in np.unique(self._ekind) if k != Shape.PLANE})
        self._bucket_keys = [(ka, kb) for ka in kinds for kb in kinds if ka <= kb]
        self._bucket_methods = np.array([method_for(ka, kb, force_admm)
                                         for ka, kb in self._bucket_keys], np.int64)
        has_walls = bool(np.any(b.kind == Shape.PLANE))
        self._wall_kinds = kinds if has_walls else []
        self._wall_methods = np.array([wall_method_for(k, force_admm)
                                       for k in self._wall_kinds], np.int64)
        customs = {id(sh.user_sdf): sh.user_sdf for sh in b.table.shapes
                   if getattr(sh, "code", None) == Shape.CUSTOM}
        if len(customs) > 1:
            raise ValueError("a scene may hold one user-defined SDF function (shapes of it "
                             "may differ by their parameters)")
        custom = next(iter(customs.values())) if customs else None
        self._shape_kernel = shape_stepper(
            self.dim, tuple(sorted(set(self._bucket_methods.tolist()))),
            tuple(sorted(set(self._wall_methods.tolist()))), self.model.kind("pp").code,
            self.model.kind("pw").code, periodic=periodic, custom_sdf=custom)

    def _part_table(self):
        """The parts detection works on: one per body, one per convex part of a
        compound (body-frame poses from the shape table's part pool)."""
        b, t, d = self.bodies, self.bodies.table, self.dim
        comp = np.flatnonzero(b.kind == Shape.COMPOUND)
        count = np.ones(b.n, np.int64)
        rows = b.shape[comp].astype(np.int64)
        count[comp] = t.cstart[rows + 1] - t.cstart[rows]
        self._estart = np.concatenate(([0], np.cumsum(count))).astype(np.int64)
        self._ecount = count
        self._has_parts = comp.size > 0
        ebody = np.repeat(np.arange(b.n, dtype=np.int64), count)
        self._ekind = b.kind[ebody].astype(np.int64)
        self._eshape = b.shape[ebody].astype(np.int64)
        ne = ebody.size
        eoff, eq, eprad = np.zeros((ne, 3)), np.zeros((ne, 4)), np.full(ne, -1.0)
        if d == 3:
            eq[:, 0] = 1.0
        for body, s in zip(comp, rows, strict=True):
            e = slice(self._estart[body], self._estart[body + 1])
            pool = slice(t.cstart[s], t.cstart[s + 1])
            self._ekind[e] = t.part_kind[pool]
            self._eshape[e] = t.part_row[pool]
            eoff[e], eq[e], eprad[e] = t.part_off[pool], t.part_rot[pool], t.part_rad[pool]
        if not self._has_parts:  # the kernel reads the body arrays themselves
            ebody, eoff, eq, eprad = ebody[:0], eoff[:0], eq[:0], eprad[:0]
        self._ebody, self._eoff, self._eq, self._eprad = ebody, eoff, eq, eprad
        self._epos = np.zeros((ne, d))
        self._erot = np.zeros((ne, b.rot.shape[1]))
        self._erad = np.zeros(ne)
        self._enormal = np.zeros((ne, d))

    def _expand_parts(self):
        """One row per pair of parts in the lists just built (runs in part order)."""
        nl, count = self.neighbors, self._ecount
        reps = count[nl.pairs[:, 0]] * count[nl.pairs[:, 1]]
        nl.pairs = np.repeat(nl.pairs, reps, axis=0)
        nl.img = np.repeat(nl.img, reps, axis=0)
        nl.wall_pairs = np.repeat(nl.wall_pairs, count[nl.wall_pairs[:, 0]], axis=0)

    def _part_ids(self, pairs):
        """The parts (m, 2) of the rows of an expanded list: the r-th row of the run of
        (i, j) is parts (r // n_j, r % n_j) of i and j."""
        m = pairs.shape[0]
        if not self._has_parts:
            return pairs
        out = np.zeros((m, 2), np.int32)
        if m == 0:
            return out
        rows = np.arange(m)
        new = np.r_[True, np.any(pairs[1:] != pairs[:-1], axis=1)]
        r = rows - np.maximum.accumulate(np.where(new, rows, 0))
        nj = self._ecount[pairs[:, 1]]
        out[:, 0] = self._estart[pairs[:, 0]] + r // nj
        out[:, 1] = self._estart[pairs[:, 1]] + r % nj
        return out

    def _shape_rebuild(self, old):
        nl = self.neighbors
        counts = self._row_counts()
        ss = self.shape_state = ShapePairState.zeros(counts, self.dim)
        sw = self.shape_wall_state = ShapeWallState.zeros(counts, self.dim)
        if old[0] is not None and old[4] is not None:  # ADMM warm starts carry over
            carry_history(old[0], old[4].warm, nl.pairs, ss.warm)
            carry_history(old[1], old[5].wwarm, nl.wall_pairs, sw.wwarm)
        self._shape_index()

    def _shape_index(self):
        """Pairs and wall pairs grouped by bucket; each body's pair and wall rows."""
        b, nl = self.bodies, self.neighbors
        n, m, mw = b.n, nl.pairs.shape[0], nl.wall_pairs.shape[0]
        self._parts = self._part_ids(nl.pairs)
        self._wparts = self._part_ids(nl.wall_pairs)
        kinds = self._ekind
        lut = np.full((len(Shape), len(Shape)), -1, np.int64)  # (kind, kind) -> bucket
        for q, (ka, kb) in enumerate(self._bucket_keys):
            lut[ka, kb] = lut[kb, ka] = q
        code = lut[kinds[self._parts[:, 0]], kinds[self._parts[:, 1]]]
        self._order = np.argsort(code, kind="stable").astype(np.int64)
        self._bstart = np.searchsorted(code[self._order],
                                       np.arange(len(self._bucket_keys) + 1)).astype(np.int64)
        wlut = np.full(len(Shape), -1, np.int64)
        wlut[self._wall_kinds] = np.arange(len(self._wall_kinds))
        wcode = wlut[kinds[self._wparts[:, 0]]]
        self._worder = np.argsort(wcode, kind="stable").astype(np.int64)
        self._wbstart = np.searchsorted(wcode[self._worder],
                                        np.arange(len(self._wall_kinds) + 1)).astype(np.int64)
        self._inc_start = np.zeros(n + 1, np.int64)
        self._inc_list = np.zeros(2 * m, np.int64)
        pair_incidence(nl.pairs, n, self._inc_start, self._inc_list)
        self._winc_start = np.zeros(n + 1, np.int64)
        self._winc_list = np.zeros(mw, np.int64)
        incidence(nl.wall_pairs, n, 0, self._winc_start, self._winc_list)

    def _shape_args(self, n_steps, prime, resume):
        b, nl = self.bodies, self.neighbors
        if self._has_parts:
            parts = (self._ekind, self._eshape, self._epos, self._erot, self._erad,
                     self._enormal)
        else:
            parts = (self._kind64, self._shape64, b.pos, b.rot, b.radius, b.normal)
        return (
            n_steps, prime, resume, self._settings(), self._body_arrays(),
            self._cell_arrays(), NeighborArrays(nl.pairs, nl.img, nl.wall_pairs, nl.pos_ref),
            self.pair_state, self.wall_state, self.shape_state, self.shape_wall_state,
            Detection(b.table.arrays(), self.admm_tol, self.admm_max_iter),
            PartArrays(self._has_parts, self._ebody, self._eoff, self._eq, self._eprad,
                       *parts),
            BucketIndex(self._parts, self._order, self._bstart, self._bucket_methods,
                        self._inc_start, self._inc_list),
            BucketIndex(self._wparts, self._worder, self._wbstart, self._wall_methods,
                        self._winc_start, self._winc_list),
            self._params_pp, self._params_pw, self._status, self.wall_work)
