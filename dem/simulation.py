"""Simulation: bodies + contact model + integrator + controllers + observers."""

import logging
import math

import numba
import numpy as np

from ._jit import prepare
from .boundary import PeriodicCell
from .contact.loops import stepper
from .contact.sphere_contacts import N_BLOCKS, InnerIndex, inner_index
from .contact.model import ContactModel
from .mesh_scene import MeshScene
from .scene_measures import MeasureScene, never_check
from .neighbors import NeighborList, carry_history, incidence
from .progress import progress_bar
from .shape_scene import ShapeScene
from .shapes import Shape
from .state import (
    BodyArrays,
    Bodies,
    CellArrays,
    NeighborArrays,
    PairState,
    ShapePairState,
    ShapeWallState,
    StepSettings,
    WallState,
)
from .status import (CAME_APART, NOCONVERGE, NONFINITE, NOT_RELAXED, OK, OVERLAP, REBUILD,
                     RELAXED)
from .timestep import DT_FACTOR, STABLE_FACTOR, stable_time_step

log = logging.getLogger(__name__)

#: the step loop evaluates the Verlet pairs within this fraction of the skin (the
#: inner list, refreshed from the Verlet list when a body has moved half of it)
INNER_SKIN = 0.05
#: scenes with fewer bodies run on one thread unless told otherwise
PARALLEL_MIN_BODIES = 1000


class SimulationError(RuntimeError):
    """A run stopped on a physical failure (non-finite state, excessive overlap)."""


class Simulation(ShapeScene, MeshScene, MeasureScene):
    """A DEM scene advanced in time.

    Parameters
    ----------
    bodies : Bodies
        The particle table (spheres/disks and walls); modified in place by :meth:`run`.
    model : ContactModel or Law
        Contact laws (a bare :class:`~dem.contact.laws.Law` acts on every pair).
    dt : float, optional
        Time step [s]; default ``DT_FACTOR * dt_crit``, or half the largest step
        accepted where heavy dashpots make that smaller. A step above ``STABLE_FACTOR``
        x the limit of a close packing of these bodies (:func:`packing_stability` of
        the contact modes and the local damping, x ``dt_crit``) is refused unless
        ``allow_unstable_dt=True``.
    gravity : (d,) array_like, optional
        Gravitational acceleration [m/s^2].
    damping : float
        Cundall local damping coefficient in [0, 1) (0: none).
    skin : float, optional
        Verlet skin [m]; default 0.4 x the mean sphere radius.
    box : Box, optional
        Periodic axes and their bounds.
    neighbor_backend : {"cell", "kdtree"}
    overlap_limit : float
        A contact whose overlap exceeds this fraction of the smaller radius stops the
        run (default 0.5).
    detection : {"auto", "admm"}
        Contact detection for non-spherical bodies: closed forms and the exact polytope
        solver where they exist, ADMM otherwise ("auto"), or ADMM for every pair of
        non-spherical bodies ("admm"; for comparisons). Sphere scenes ignore it.
    admm_tol : float
        ADMM stopping tolerance, relative to the smaller body's bounding radius.
    admm_max_iter : int
        ADMM iteration cap per solve (a warm solve retries cold after at most
        ``dem.contact.detection.admm.WARM_MAX_ITER`` = 50 of them; a cold one that
        hits the cap stops the run, naming the pair).
    walls : sequence of MeshWall, optional
        Triangle-mesh walls (3D sphere scenes; :mod:`dem.mesh_scene`). They move with
        their prescribed motion and are moved in place.
    threads : int, optional
        Threads for the compiled loops; default all of numba's threads for scenes of
        at least ``PARALLEL_MIN_BODIES`` bodies, else 1 (threads only cost time on
        small scenes). Results do not depend on it.
    observers, controllers, state_objects : sequences
        Observers read the state when their trigger fires after a step; controllers
        may change it when their trigger fires before a step; state objects are
        advanced by RK2 every step (see :mod:`dem.state_objects`).
    """

    def __init__(self, bodies, model, dt=None, gravity=None, damping=0.0, skin=None,
                 box=None, neighbor_backend="cell", overlap_limit=0.5, observers=(),
                 controllers=(), state_objects=(), allow_unstable_dt=False, threads=None,
                 detection="auto", admm_tol=1e-8, admm_max_iter=200, walls=()):
        if not isinstance(model, ContactModel):
            model = ContactModel(model)
        self.bodies = bodies
        self.model = model
        self.dim = bodies.dim
        walls = list(walls)
        model.check(bodies, [w.mat_id for w in walls if hasattr(w, "mat_id")])
        if not 0.0 <= damping < 1.0:
            raise ValueError(f"damping must be in [0, 1), got {damping}")
        #: the largest step accepted: STABLE_FACTOR x a close packing's limit
        self.dt_stable, factor, self.dt_crit, m_min, k_max = stable_time_step(
            bodies, model, damping)
        #: largest damping ratio of the contact modes (dashpots lower the stable step)
        self.damping_ratio = (model.max_damping_ratio(bodies, m_min)
                              if math.isfinite(self.dt_crit) else 0.0)
        if dt is None:
            if not math.isfinite(self.dt_crit):
                raise ValueError("dt must be given for a scene without free spheres")
            # heavy dashpots can put the accurate step past the stable one
            dt = min(DT_FACTOR * self.dt_crit, 0.5 * self.dt_stable)
        dt = float(dt)
        if not (dt > 0.0 and math.isfinite(dt)):
            raise ValueError(f"dt must be positive and finite, got {dt}")
        if dt > self.dt_stable and not allow_unstable_dt:
            raise ValueError(
                f"dt = {dt:.4g} s exceeds the stable time step dt_stable = "
                f"{self.dt_stable:.4g} s: {STABLE_FACTOR:g} x a close packing's limit, "
                f"{factor:.3g} x the two-body limit {self.dt_crit:.4g} s (lightest body "
                f"{m_min:.4g} kg, stiffest contact {k_max:.4g} N/m, contact damping ratio "
                f"{self.damping_ratio:.3g}, local damping {damping:g}); pass "
                f"allow_unstable_dt=True to run anyway")
        self.dt = dt
        g = np.zeros(self.dim) if gravity is None else np.asarray(gravity, dtype=np.float64)
        if g.shape != (self.dim,):
            raise ValueError(f"gravity must have {self.dim} components, got {g.shape}")
        self.gravity = g
        self.damping = float(damping)
        if not overlap_limit > 0.0:
            raise ValueError(f"overlap_limit must be positive, got {overlap_limit}")
        self.overlap_limit = float(overlap_limit)
        sph = bodies.kind != Shape.PLANE
        if skin is None:
            skin = 0.4 * float(bodies.radius[sph].mean()) if sph.any() else 1.0
        self.box = box
        self.neighbors = NeighborList(skin, backend=neighbor_backend, box=box)
        self.observers = list(observers)
        self.controllers = list(controllers)
        self.state_objects = list(state_objects)
        if threads is None:
            big = bodies.n >= PARALLEL_MIN_BODIES
            threads = numba.config.NUMBA_NUM_THREADS if big else 1
        self.threads = max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS))
        self.step = 0
        self.time = 0.0
        self.wall_work = np.zeros(1)
        self.n_inner_refreshes = 0  # diagnostics: inner contact list remade
        self._status = np.zeros(4, np.int64)
        periodic = box is not None and bool(np.any(box.periodic))
        self.cell = box if isinstance(box, PeriodicCell) else None
        if detection not in ("auto", "admm"):
            raise ValueError(f"detection must be 'auto' or 'admm', got {detection!r}")
        if not (admm_tol > 0.0 and int(admm_max_iter) >= 1):
            raise ValueError("admm_tol must be positive and admm_max_iter >= 1")
        self.detection = detection
        self.admm_tol = float(admm_tol)
        self.admm_max_iter = int(admm_max_iter)
        self.shaped = bodies.has_shapes
        self._mesh_setup(walls, periodic)
        if self.shaped:
            self._shape_setup(periodic)
        else:
            # the time loop's compile-time choices; one thread or several picks
            # between two kernels at every call (dem.contact.loops.stepper)
            self._loop_key = dict(dim=self.dim, law_pp=model.kind("pp").code,
                                  law_pw=model.kind("pw").code, periodic=periodic,
                                  deform=self.cell is not None, rolling=model.rolling,
                                  mesh=self.has_mesh)
        d = self.dim
        self._lgrad = self.cell.lgrad if self.cell is not None else np.zeros((d, d))
        self._cellref = np.zeros((2, d, d))  # H^-1 at the Verlet build, at the inner list
        self._primed = False
        self._prepared = None  # the time loop last made ready (dem._jit.prepare)
        self._check = never_check(d)  # the sphere loop's relaxation check (relax())
        self._failure_hooks = []

    # ------------------------------------------------------------------ set-up
    def _refresh_tables(self):
        b = self.bodies
        n_mat = max(int(b.mat_id.max()) + 1 if b.n else 1, self._mesh_n_mat())
        self._params_pp = self.model.table("pp", n_mat)
        self._params_pw = self.model.table("pw", n_mat)
        with np.errstate(divide="ignore"):
            self._inv_mass = np.where(b.is_fixed, 0.0, 1.0 / b.mass)
            self._inv_inertia = np.where(b.is_fixed[:, None], 0.0, 1.0 / b.inertia)
        d = self.dim
        self._hmat = self.box.matrix() if self.box is not None else np.zeros((d, d))
        self._fixed = b.is_fixed.astype(np.uint8)
        self._kind64 = b.kind.astype(np.int64)
        self._shape64 = b.shape.astype(np.int64)

    def _rebuild(self):
        """Rebuild the neighbour lists, carrying contact history by pair key."""
        b, nl = self.bodies, self.neighbors
        if self.dim == 3:  # the step's rotation update is unit only to O((w dt)^4)
            b.rot /= np.linalg.norm(b.rot, axis=1, keepdims=True)
        if self.cell is not None:  # a sheared cell takes its least skewed basis
            self.cell.reduce()
        old = (nl.pairs, getattr(nl, "wall_pairs", None), getattr(self, "pair_state", None),
               getattr(self, "wall_state", None), getattr(self, "shape_state", None),
               getattr(self, "shape_wall_state", None))
        nl.build(b)
        if self.shaped and self._has_parts:
            self._expand_parts()
        if self.cell is not None:
            self._cellref[:] = np.linalg.inv(self.cell.h)
        counts = self._row_counts()
        ps = self.pair_state = PairState.zeros(counts, self.dim)
        ws = self.wall_state = WallState.zeros(counts, self.dim)
        if old[0] is not None and old[2] is not None:
            carry_history(old[0], old[2].hist, nl.pairs, ps.hist)
            carry_history(old[1], old[3].whist, nl.wall_pairs, ws.whist)
        # a pair with history was touching; others are found by the next force pass
        ps.touch[:] = np.any(ps.hist != 0.0, axis=1)
        if self.shaped:
            self._shape_rebuild(old)
        else:
            self._index()
            self._mesh_rebuild()
        self._radius_ref = b.radius.copy()

    def _row_counts(self):
        """Rows of the state bundles: pairs, wall pairs and bodies."""
        nl = self.neighbors
        return {"pair": nl.pairs.shape[0], "wall": nl.wall_pairs.shape[0],
                "body": self.bodies.n, "hist": self.model.n_hist}

    def _index(self):
        n, nl = self.bodies.n, self.neighbors
        m = nl.pairs.shape[0]
        self._inc_start = np.zeros(n + 1, np.int64)  # made with the inner list
        self._slot = np.zeros((m, 2), np.int64)
        self._contrib = np.zeros((2 * m, self.dim + self.bodies.n_rot))
        self._wstart = np.zeros(n + 1, np.int64)
        self._blk_start = np.zeros(N_BLOCKS + 1, np.int64)
        self._inner = np.zeros(nl.pairs.shape[0], np.int64)
        # (total, internal) pair counts; made by the next force evaluation
        self._n_inner = np.full(2, -1, np.int64)
        self._pos_inner = self.bodies.pos.copy()
        incidence(nl.wall_pairs, n, 0, self._wstart,
                  np.zeros(nl.wall_pairs.shape[0], np.int64))

    def _restore_inner(self, n_inner, n_internal, inner, pos_inner):
        """Set the inner contact list (checkpoint restart); -1 remakes it next step."""
        self._n_inner[:] = n_inner, n_internal
        if n_inner >= 0:
            self._inner[:n_inner] = inner
            self._pos_inner[:] = pos_inner
            inner_index(self.neighbors.pairs, self._inner, self._n_inner, self._blk_start,
                        self._inc_start, self._slot)

    def _call(self, n_steps, prime, resume=False):
        kernel, args = self._loop_args(n_steps, prime, resume)
        if kernel is not self._prepared:  # first call, or the thread count changed
            prepare(kernel, args, "shape" if self.shaped else "sphere")
            self._prepared = kernel
        return kernel(*args)

    def _loop_args(self, n_steps, prime, resume):
        """The time loop of this scene and its arguments."""
        if self.shaped:
            return self._shape_kernel, self._shape_args(n_steps, prime, resume)
        nl = self.neighbors
        return stepper(**self._loop_key, serial=self.threads == 1), (
            n_steps, prime, resume, self._settings(),
            self._body_arrays(), self._cell_arrays(),
            NeighborArrays(nl.pairs, nl.img, nl.wall_pairs, nl.pos_ref), self.pair_state,
            self.wall_state, InnerIndex(self._contrib, self._slot, self._inc_start,
                                        self._blk_start, self._inner, self._n_inner,
                                        self._pos_inner, self._wstart),
            self._params_pp, self._params_pw, self._status, self.wall_work,
            self._mesh_loop(), self._check)

    def _settings(self):
        return StepSettings(self.dt, self.gravity, self.damping, self.neighbors.skin,
                            self.overlap_limit, INNER_SKIN * self.neighbors.skin,
                            self._grow())

    def _body_arrays(self):
        b = self.bodies
        return BodyArrays(b.pos, b.vel, b.rot, b.ang_vel, b.force, b.torque, b.radius,
                          b.mass, self._inv_mass, self._inv_inertia, self._fixed, b.normal,
                          b.mat_id)

    def _cell_arrays(self):
        return CellArrays(self._hmat, self._lgrad, self._cellref, self.cell is not None)

    def prime(self):
        """Build the neighbour lists and the forces of the current state (idempotent)."""
        if not self._primed:
            self._refresh_tables()
            if self.neighbors.pairs is None or self._radius_ref.shape[0] != self.bodies.n:
                self._rebuild()  # first build, or bodies added (dem.insertion)
            elif not self.shaped:
                self._index()
            self._call(0, True)
            if self._status[0] == REBUILD:  # bodies moved past the skin since its build
                self._rebuild()
                self._call(0, True)
            self._check_status(None)
            self._primed = True

    def invalidate(self):
        """Say that the bodies' table or the contact model changed outside :meth:`run`
        (a friction change, a moved wall): the next step or measure rebuilds the
        parameter tables and forces first. Contact state is kept."""
        self._primed = False

    # ------------------------------------------------------------------ public views
    @property
    def image_matrix(self):
        """(d, d) [m]: the periodic cell's matrix H (columns: edge vectors; zero on
        non-periodic axes), by which a pair's integer image offsets ``img`` become the
        shift ``img @ image_matrix.T`` of its second body. Zeros without a box. The
        array is the one the step loop updates (not a copy)."""
        self.prime()
        return self._hmat

    def parameter_table(self, bucket):
        """The contact law's parameter table in use, ``"pp"`` (body-body) or ``"pw"``
        (body-wall): one row per material pair (:meth:`dem.ContactModel.table`)."""
        if not self._primed:  # the tables prime() would build, without its first step
            self._refresh_tables()
        if bucket not in ("pp", "pw"):
            raise ValueError(f"bucket must be 'pp' or 'pw', got {bucket!r}")
        return self._params_pp if bucket == "pp" else self._params_pw

    # ------------------------------------------------------------------ running
    def run(self, n_steps, progress=None):
        """Advance ``n_steps`` time steps.

        Per step, in this order: controllers whose trigger fires on the current step;
        half kick and drift of the bodies; contact and body forces; second half kick
        (velocity Verlet, see :mod:`dem.contact.loops`); state objects advanced by RK2;
        ``step += 1``; then every observer whose trigger fires on the new step. Steps
        between events run as one compiled chunk; a chunk stops early when the
        neighbour list must be rebuilt, which happens and the chunk resumes.

        Parameters
        ----------
        n_steps : int
        progress : bool, optional
            Show a progress bar (default: when stderr is a terminal and the run is long).
        """
        n_steps = int(n_steps)
        if n_steps < 0:
            raise ValueError("n_steps must be >= 0")
        self._steps(n_steps, progress)

    def _steps(self, n_steps, progress):
        """:meth:`run`'s loop; returns the status that ended it early (``RELAXED`` or
        ``CAME_APART`` of a relaxation check, :meth:`relax`), else ``OK``."""
        code = OK
        threads_before = numba.get_num_threads()
        numba.set_num_threads(self.threads)
        self.prime()
        end = self.step + n_steps
        bar = progress_bar(n_steps, progress)
        try:
            while self.step < end:
                for c in self.controllers:
                    if c.trigger(self.step):
                        c(self)
                        self._primed = False
                if not self._primed:
                    self.prime()
                stop = end
                for o in self.observers + self.controllers:
                    stop = min(stop, o.trigger.next_after(self.step))
                if self.state_objects:
                    stop = self.step + 1
                start = self.step
                code = self._advance(stop - self.step)
                if self.state_objects:
                    self._advance_state_objects()
                if bar is not None:
                    bar.update(self.step - start)
                for o in self.observers:
                    if o.trigger(self.step):
                        o(self)
                if code != OK:
                    break
        finally:
            numba.set_num_threads(threads_before)
            if bar is not None:
                bar.close()
        return code

    def _advance(self, n):
        resume = False
        snapshot = None
        while n > 0:
            if not resume:  # a chunk resumed mid-step keeps the snapshot of its start
                snapshot = self._snapshot_bodies()
            done = self._call(n, False, resume)
            if self.has_mesh:
                self._mesh_sync()
            self.n_inner_refreshes += int(self._status[3])
            self.step += done
            self.time = self.step * self.dt
            n -= done
            code = self._status[0]
            if self._check.every > 0 and code in (RELAXED, CAME_APART, NOT_RELAXED):
                return int(code)  # a check stopped the run
            resume = code == REBUILD  # stopped mid-step, after the drift
            if resume:
                self._rebuild()
                continue
            self._check_status(snapshot)
        return OK

    def _check_status(self, snapshot):
        code = int(self._status[0])
        if code == OK:
            return
        i, j = int(self._status[1]), int(self._status[2])
        if code == OVERLAP and j < 0:
            msg = (f"overlap between body {i} and mesh wall {-1 - j} exceeds "
                   f"{self.overlap_limit:g} x its radius at step {self.step}")
        elif code == OVERLAP:
            msg = (f"overlap between bodies {i} and {j} exceeds {self.overlap_limit:g} x the "
                   f"smaller radius at step {self.step}: dt = {self.dt:.4g} s may be too "
                   f"large or the bodies too fast (critical step {self.dt_crit:.4g} s)")
        elif code == NOCONVERGE:
            msg = (f"contact detection between bodies {i} and {j} did not converge in "
                   f"{self.admm_max_iter} ADMM iterations, warm or cold, at step "
                   f"{self.step} (tolerance {self.admm_tol:g}): raise admm_max_iter or "
                   f"admm_tol, or check the shapes' SDFs")
        elif code == NONFINITE:
            where = f" on body {i}" if i >= 0 else ""
            msg = (f"non-finite position, velocity or force{where} at step {self.step + 1}: "
                   f"the run blew up (dt = {self.dt:.4g} s, critical step "
                   f"{self.dt_crit:.4g} s)")
        else:
            msg = f"kernel status {code} at step {self.step}"
        for hook in self._failure_hooks:
            hook(self, snapshot)
        raise SimulationError(msg)

    def on_failure(self, hook):
        """Register ``hook(sim, last_good_bodies)``, called before a SimulationError."""
        self._failure_hooks.append(hook)

    def _snapshot_bodies(self):
        return self.bodies.copy() if self._failure_hooks else None

    def _grow(self):
        """Largest radius growth [m] since the neighbour build (state objects)."""
        if not self.state_objects or self.bodies.n == 0:
            return 0.0
        return max(0.0, float(np.max(self.bodies.radius - self._radius_ref)))

    def _advance_state_objects(self):
        for so in self.state_objects:
            so.advance(self, self.time - self.dt, self.dt)
        self._refresh_tables()
        # the list holds while 2 (displacement + growth) < skin; the kernel checks both
        # after each drift, this catches growth alone
        if 2.0 * self._grow() > 0.5 * self.neighbors.skin:
            self._rebuild()

    # ------------------------------------------------------------------ state copies
    #: the contact-state bundles: attribute name and class (:mod:`dem.state`); the last
    #: two exist in scenes with non-spherical shapes only
    BUNDLES = (("pair_state", PairState), ("wall_state", WallState),
               ("shape_state", ShapePairState), ("shape_wall_state", ShapeWallState))

    def state_bundles(self):
        """The contact state, ``{attribute name: bundle}``: one row per row of the
        neighbour lists (:meth:`prime` first). Snapshots, restores and checkpoints
        iterate it: the fields of the bundles are the whole per-contact state."""
        self.prime()
        return {name: getattr(self, name) for name, _ in self.BUNDLES[:4 if self.shaped
                                                                       else 2]}

    def state_arrays(self):
        """The whole dynamic state as a dict of the arrays themselves (not copies):
        bodies (``b.`` + :attr:`Bodies.ARRAYS`), neighbour lists (``nl.``), contact
        state (:meth:`state_bundles`, by field name), the radii at the last build, the
        clock, the inner list and the cell. :meth:`snapshot` copies it; checkpoints
        write it."""
        b, nl = self.bodies, self.neighbors
        src = {}
        for bundle in self.state_bundles().values():
            src.update(bundle._asdict())
        src.update({"b." + k: getattr(b, k) for k in Bodies.ARRAYS})
        src.update({"nl." + k: getattr(nl, k) for k in ("pairs", "img", "wall_pairs",
                                                         "pos_ref")})
        src["radius_ref"] = self._radius_ref
        src["clock"] = np.array([self.step, nl.n_builds, nl.capacity], np.int64)
        src["wall_work"] = self.wall_work
        src.update(self._mesh_state_arrays())
        if not self.shaped:
            src.update(n_inner=self._n_inner, inner=self._inner, pos_inner=self._pos_inner)
        if self.cell is not None:
            src.update(cell_h=self.cell.h, cell_lgrad=self.cell.lgrad,
                       cellref=self._cellref,
                       cell_n=np.array([self.cell.n_reductions], np.int64))
        return src

    def snapshot(self, into=None):
        """A copy of :meth:`state_arrays`; :meth:`restore` brings it back bit for bit.

        ``into``, a previous snapshot, has its arrays overwritten in place where the
        shapes still fit (no allocation in the common case of an unchanged list).
        """
        snap = {} if into is None else into
        for k, v in self.state_arrays().items():
            old = snap.get(k)
            if old is not None and old.shape == v.shape and old.dtype == v.dtype:
                np.copyto(old, v)
            else:
                snap[k] = v.copy()
        return snap

    def restore(self, snap):
        """Set the state saved by :meth:`snapshot` (the same scene: same bodies and
        model). Copies in place; running on repeats the original run bit for bit.
        Checkpoints restart through it too (:func:`dem.io.load_checkpoint`)."""
        b, nl = self.bodies, self.neighbors

        def put(obj, name, v):
            cur = getattr(obj, name, None)
            if cur is not None and cur.shape == v.shape and cur.dtype == v.dtype:
                np.copyto(cur, v)
            else:
                setattr(obj, name, v.copy())

        if snap["b.pos"].shape != b.pos.shape:
            raise ValueError("snapshot of another scene: body count or dimension differs")
        for k in Bodies.ARRAYS:
            put(b, k, snap["b." + k])
        for k in ("pairs", "img", "wall_pairs", "pos_ref"):
            put(nl, k, snap["nl." + k])
        counts = self._row_counts()
        for name, cls in self.BUNDLES[:4 if self.shaped else 2]:
            cur = getattr(self, name, None)
            new = cls.checked(snap, counts, self.dim, "snapshot: ")
            if cur is not None and all(x.shape == y.shape for x, y in zip(cur, new,
                                                                            strict=True)):
                for x, y in zip(cur, new, strict=True):
                    np.copyto(x, y)
            else:
                setattr(self, name, cls(*(x.copy() for x in new)))
        put(self, "_radius_ref", snap["radius_ref"])
        self.step, nl.n_builds, nl.capacity = (int(x) for x in snap["clock"])
        self.time = self.step * self.dt
        np.copyto(self.wall_work, snap["wall_work"])
        self._mesh_restore(snap)
        if self.cell is not None:
            np.copyto(self.cell.h, snap["cell_h"])
            np.copyto(self.cell.lgrad, snap["cell_lgrad"])
            np.copyto(self._cellref, snap["cellref"])
            self.cell.n_reductions = int(snap["cell_n"][0])
        inner = None
        if not self.shaped:
            n_inner, n_internal = (int(x) for x in snap["n_inner"])
            inner = (n_inner, n_internal, snap["inner"][:max(n_inner, 0)],
                     snap["pos_inner"])
        self._reindex(inner)

    def _reindex(self, inner):
        """After lists and contact arrays were set from saved state: tables, the
        per-body indexes and the inner list ``(n_inner, n_internal, inner,
        pos_inner)`` of the sphere loop; the state counts as primed."""
        self._refresh_tables()
        if self.shaped:
            self._shape_index()
        else:
            self._index()
            self._restore_inner(*inner)
        self._primed = True
