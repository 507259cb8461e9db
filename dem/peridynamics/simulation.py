"""PDSimulation: peridynamic solids, DEM spheres and walls in one particle table.

Material points are rows of a :class:`dem.Bodies` table (disks/spheres of radius
``dx / 2``, the mass of their lattice cell); the table may hold DEM spheres and walls
too. Points of one solid are joined by persistent bonds within the horizon; a pair that
is not joined by an intact bond (its bond broke, or it never had one) interacts by
contact through the ordinary contact laws (:mod:`.contact`), so fragments collide as
bodies, with friction if the law has it, and a sphere can strike a plate.
"""

import math

import numba
import numpy as np

from ..shapes import Shape
from ..progress import progress_bar
from ..simulation import PARALLEL_MIN_BODIES, SimulationError
from ..status import NONFINITE, REBUILD
from .contact import ContactState, contact_model, default_law
from .kernels import (
    Bonds,
    Loads,
    bond_pass,
    energy_density,
    forces,
    step_chunk,
    weighted_volume,
)
from .lattice import Family, pairs_within
from .materials import P_SCRIT, PMB_CODE

#: default time step as a fraction of the critical one (velocity Verlet's energy error
#: grows as (omega dt / 2)^2 in the stiffest mode: 0.4 keeps it a few percent there)
DT_FACTOR = 0.4


def add_points(bodies, pos, dx, density, thickness=1.0, vel=None):
    """Append material points at ``pos`` (n, d): each the cell of a lattice of spacing
    ``dx`` [m] (times ``thickness`` [m] in 2D) of the given ``density`` [kg/m^3].

    A point's contact radius is ``dx / 2``. Returns the new rows (int32 array).

    Examples
    --------
    >>> import dem
    >>> from dem.peridynamics import lattice
    >>> b = dem.Bodies.empty(2)
    >>> ids = add_points(b, lattice([0, 0], [1, 1], 0.5), 0.5, 1000.0, thickness=0.1)
    >>> len(ids), float(b.mass[0])
    (4, 25.0)
    """
    pos = np.atleast_2d(np.asarray(pos, dtype=np.float64))
    d = bodies.dim
    if not (dx > 0.0 and thickness > 0.0):
        raise ValueError(f"dx and thickness must be positive, got {dx}, {thickness}")
    ids = bodies.add_spheres(pos, 0.5 * dx, density, vel=vel)
    vol = dx**d * (thickness if d == 2 else 1.0)
    bodies.mass[ids] = density * vol
    bodies.inertia[ids] = (0.4 if d == 3 else 0.5) * density * vol * (0.5 * dx) ** 2
    return ids


class PDSimulation:
    """Peridynamic solids (and DEM spheres and walls) advanced by velocity Verlet.

    Parameters
    ----------
    bodies : Bodies
        Material points (see :func:`add_points`), DEM spheres and walls.
    material : LPS or PMB
        The material of every solid.
    points : int array or sequence of int arrays
        The rows that are material points; a sequence gives several solids, whose points
        bond only within their own solid.
    horizon : float [m]
        Peridynamic horizon (3 lattice spacings is the usual choice).
    cut : callable, optional
        Bonds to leave out in the reference configuration (a pre-crack, see
        :func:`~dem.peridynamics.crack`).
    dt : float, optional
        Time step [s]; default ``DT_FACTOR`` times the critical step. A larger step than
        the critical one is refused unless ``allow_unstable_dt``.
    damping : float
        Cundall local damping in [0, 1), for quasi-static problems.
    gravity : (d,) array_like [m/s^2], optional
    contact : Law or ContactModel, optional
        The contact between bodies not joined by an intact bond, and with walls: any
        law of :mod:`dem.contact.laws` (e.g. ``dem.LinearSpring(kn, kt, mu,
        restitution=...)`` or ``dem.HertzMindlin``), per material pair through a
        :class:`dem.ContactModel` (``wall_law`` for the walls), as in
        :class:`dem.Simulation` (:mod:`dem.peridynamics.contact`). Default: a
        frictionless, undamped linear spring of stiffness ``E V / (2 dx^2)``, half the
        stiffness of a lattice cell squeezed across its width, so that contact does not
        set the time step of a lattice scene.
    contact_kn : float [N/m], optional
        The default spring's stiffness instead (not with ``contact``).
    skin : float [m], optional
        Verlet skin of the contact list; default 0.3 dx.
    observers : sequence
        Called after steps when their trigger fires (as for :class:`dem.Simulation`).
    threads : int, optional
        Threads for the bond passes; default all of numba's for scenes of at least
        ``PARALLEL_MIN_BODIES`` bodies, else 1. Results do not depend on it.
    """

    def __init__(self, bodies, material, points, horizon, cut=None, dt=None, damping=0.0,
                 gravity=None, contact=None, contact_kn=None, skin=None, observers=(),
                 allow_unstable_dt=False, threads=None):
        self.bodies = b = bodies
        self.dim = d = b.dim
        self.material = material
        solids = [np.asarray(points, np.int64)] if np.ndim(points[0]) == 0 else [
            np.asarray(p, np.int64) for p in points]
        label = np.full(b.n, -1, np.int64)
        for s, ids in enumerate(solids):
            if ids.size == 0 or ids.min() < 0 or ids.max() >= b.n:
                raise ValueError(f"solid {s}: point indices must be rows of the table")
            if np.any(label[ids] >= 0):
                raise ValueError(f"solid {s} shares points with another solid")
            if np.any(b.kind[ids] != Shape.SPHERE):
                raise ValueError(f"solid {s}: material points must be sphere rows "
                                 "(see add_points)")
            label[ids] = s
        self.solid = label
        if not (horizon > 0.0 and math.isfinite(horizon)):
            raise ValueError(f"horizon must be positive and finite, got {horizon}")
        self.horizon = float(horizon)
        if not 0.0 <= damping < 1.0:
            raise ValueError(f"damping must be in [0, 1), got {damping}")
        self.damping = float(damping)
        g = np.zeros(d) if gravity is None else np.asarray(gravity, np.float64)
        if g.shape != (d,):
            raise ValueError(f"gravity must have {d} components, got {g.shape}")
        self.gravity = g
        pts = label >= 0
        self.dx = float(2.0 * b.radius[pts].mean())
        self.vol = np.where(pts, b.mass / b.density, 0.0)
        self.family = f = Family.build(b.pos, horizon, solid=label, cut=cut)
        if f.n_bonds == 0:
            raise ValueError(f"no bonds within the horizon {horizon:g} m: the horizon must "
                             f"exceed the lattice spacing {self.dx:g} m")
        self.omega = material.influence(f.length, horizon)
        self.mvol = np.zeros(b.n)
        weighted_volume(f.start, f.nbr, f.length, self.omega, self.vol, self.mvol)
        s_i = np.bincount(f.owner(), f.length * self.vol[f.nbr], minlength=b.n)
        s_bulk = float(s_i.max())
        lps_corr = material.code != PMB_CODE and material.surface_correction
        self.qw = f.dilation_weights(self.omega, self.vol, self.mvol, lps_corr)
        self.pw = np.divide(1.0, self.mvol, out=np.zeros(b.n), where=self.mvol > 0.0)[f.owner()]
        self.sdev = np.zeros(b.n)
        self.corr = np.ones(b.n)
        if material.code == PMB_CODE and material.surface_correction:
            has = s_i > 0.0
            self.corr[has] = s_bulk / s_i[has]
        self.params = material.params(d, self.horizon, s_bulk)
        self.theta = np.zeros(b.n)
        self.bforce = np.zeros((b.n, d))
        self._prof_t = np.zeros(0)
        self._prof_v = np.zeros(0)
        #: the contact laws (a :class:`dem.ContactModel`)
        self.contact = contact_model(contact, contact_kn, lambda: default_law(
            float(np.mean(self.vol[pts])), self.dx, material))
        self._contact = ContactState(self.contact, b)
        self.skin = 0.3 * self.dx if skin is None else float(skin)
        self.observers = list(observers)
        if threads is None:
            threads = numba.config.NUMBA_NUM_THREADS if b.n >= PARALLEL_MIN_BODIES else 1
        self.threads = max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS))
        self.step = 0
        self.time = 0.0
        self._status = np.zeros(2, np.int64)
        self._fixed = b.is_fixed.astype(np.uint8)
        self.x0 = b.pos.copy()  # the reference configuration
        self.dt_crit = self.critical_time_step()
        if dt is None:
            dt = DT_FACTOR * self.dt_crit
        dt = float(dt)
        if not (dt > 0.0 and math.isfinite(dt)):
            raise ValueError(f"dt must be positive and finite, got {dt}")
        if dt > self.dt_crit and not allow_unstable_dt:
            raise ValueError(f"dt = {dt:.4g} s exceeds the critical time step "
                             f"{self.dt_crit:.4g} s of the bonds and contacts; pass "
                             f"allow_unstable_dt=True to run anyway")
        self.dt = dt
        self._primed = False

    # ------------------------------------------------------------------ loads
    def add_body_force(self, ids, b):
        """Body force density ``b`` (d,) [N/m^3] on the points ``ids``, scaled by the
        time profile (see :meth:`set_profile`); adds to what is there."""
        b = np.asarray(b, np.float64)
        if b.shape != (self.dim,) or not np.all(np.isfinite(b)):
            raise ValueError(f"body force density must be {self.dim} finite numbers")
        ids = np.asarray(ids, np.int64)
        self.bforce[ids] += self.vol[ids, None] * b
        self._primed = False

    def set_profile(self, times, values):
        """The body forces' time profile: piecewise linear through ``(times, values)``,
        constant beyond the ends (times ascending)."""
        t = np.asarray(times, np.float64)
        v = np.asarray(values, np.float64)
        if t.ndim != 1 or t.shape != v.shape or t.size < 1 or np.any(np.diff(t) <= 0):
            raise ValueError("profile times must ascend, with one value per time")
        self._prof_t, self._prof_v = t, v
        self._primed = False

    # ------------------------------------------------------------------ stability
    def critical_time_step(self, iterations=400, seed=0):
        """Critical time step [s]: ``2 / omega_max`` of the bonds, by power iteration on
        the mass-scaled stiffness at the reference state (until its Rayleigh quotient
        changes by less than 1e-7, at most ``iterations``), and ``sqrt(2 m_min / kn)``
        of the contacts; the smaller."""
        b = self.bodies
        free = (~b.is_fixed) & (b.kind != Shape.PLANE)
        if not free.any():
            return math.inf
        m_min = float(b.mass[free].min())
        r_ref = float(b.radius[free].min())
        z = self.contact.max_damping_ratio(b, m_min)
        dt_c = math.sqrt(2.0 * m_min / self._contact.stiffness(r_ref)) * (
            math.sqrt(1.0 + z * z) - z)
        lam = self._largest_eigenvalue(free, iterations, seed)
        dt_b = 2.0 / math.sqrt(lam) if lam > 0.0 else math.inf
        return min(dt_b, dt_c)

    def _largest_eigenvalue(self, free, iterations, seed):
        b, f = self.bodies, self.family
        x0 = self.x0
        params = self.params.copy()
        params[P_SCRIT] = math.inf
        scale = np.where(free, 1.0 / np.sqrt(np.where(free, b.mass, 1.0)), 0.0)[:, None]
        eps = 1e-6 * self.dx
        v = np.random.default_rng(seed).standard_normal(x0.shape) * (scale > 0)
        out = np.zeros_like(x0)
        bonds = self._bonds(theta=np.zeros(b.n), sdev=np.zeros(b.n), params=params,
                            broken=np.zeros_like(f.broken))
        contacts = self._contact.empty(b)
        loads = Loads(np.zeros_like(x0), np.zeros(0), np.zeros(0), np.zeros(self.dim))
        lam = 0.0
        for _ in range(iterations):
            v /= np.abs(v).max()
            out[:] = 0.0
            forces(x0 + eps * scale * v, np.zeros_like(x0), b.radius, b.mass,
                   np.ones(b.n, np.uint8), bonds, contacts, loads, 0.0, 0.0, out)
            w = -scale * out / eps
            lam_old, lam = lam, float((w * v).sum() / (v * v).sum())
            v = w
            if abs(lam - lam_old) < 1e-7 * abs(lam):  # the Rayleigh quotient has settled
                break
        return lam

    # ------------------------------------------------------------------ running
    def _rebuild(self):
        b = self.bodies
        cand = np.flatnonzero((b.kind != Shape.PLANE) & (b.radius > 0.0))
        r = b.radius[cand]
        small = r <= 2.0 * np.median(r)
        lab = np.zeros(cand.size, np.int64)
        lab[~small] = -1
        pairs = cand[pairs_within(b.pos[cand], r * small, self.skin, lab)]
        big = cand[~small]
        extra = []
        for i in big:  # few large DEM bodies: brute force against every other body
            dist = np.sqrt(((b.pos[cand] - b.pos[i]) ** 2).sum(1))
            near = cand[(dist < b.radius[cand] + b.radius[i] + self.skin) & (cand != i)]
            extra.append(np.stack([np.minimum(near, i), np.maximum(near, i)], axis=1))
        if extra:
            pairs = np.unique(np.concatenate([pairs] + extra), axis=0)
        self._contact.set_pairs(pairs)
        self._pos_ref = b.pos.copy()

    def _bonds(self, **change):
        """The :class:`~dem.peridynamics.kernels.Bonds` of the current state, made
        afresh (fields in ``change`` replaced)."""
        f = self.family
        return Bonds(f.start, f.nbr, f.twin, f.length, self.omega, self.vol, self.qw,
                     self.pw, self.corr, self.theta, self.sdev, self.params,
                     f.broken)._replace(**change)

    def _contacts(self):
        return self._contact.bundle(self.bodies)

    def _loads(self):
        return Loads(self.bforce, self._prof_t, self._prof_v, self.gravity)

    def _forces(self):
        b = self.bodies
        scale = float(np.interp(self.time, self._prof_t, self._prof_v)) if \
            self._prof_t.size else 1.0
        forces(b.pos, b.vel, b.radius, b.mass, self._fixed, self._bonds(), self._contacts(),
               self._loads(), scale, 0.0, b.force)

    def prime(self):
        """Contact list and forces of the current state (idempotent)."""
        if not self._primed:
            self._fixed = self.bodies.is_fixed.astype(np.uint8)
            self._rebuild()
            self._forces()
            self._primed = True

    def run(self, n_steps, progress=None):
        """Advance ``n_steps`` time steps (see :func:`~dem.peridynamics.kernels.step_chunk`
        for the order within a step); observers whose trigger fires run after a step."""
        n_steps = int(n_steps)
        if n_steps < 0:
            raise ValueError("n_steps must be >= 0")
        threads_before = numba.get_num_threads()
        numba.set_num_threads(self.threads)
        self.prime()
        end = self.step + n_steps
        bar = progress_bar(n_steps, progress)
        b = self.bodies
        try:
            while self.step < end:
                stop = end
                for o in self.observers:
                    stop = min(stop, o.trigger.next_after(self.step))
                start = self.step
                while self.step < stop:
                    done = step_chunk(
                        stop - self.step, self.time, self.dt, self.damping, b.pos, b.vel,
                        b.radius, b.mass, self._fixed, self._bonds(), self._contacts(),
                        self._loads(), self._pos_ref, 0.5 * self.skin, b.force,
                        self._status)
                    self.step += done
                    self.time = self.step * self.dt
                    if self._status[0] == NONFINITE:
                        raise SimulationError(
                            f"non-finite or runaway motion of body {self._status[1]} (more "
                            f"than its radius in one step) at step {self.step}: the run "
                            f"blew up (dt = {self.dt:.4g} s, "
                            f"critical step {self.dt_crit:.4g} s)")
                    if self._status[0] == REBUILD:
                        self._rebuild()
                if bar is not None:
                    bar.update(self.step - start)
                for o in self.observers:
                    if o.trigger(self.step):
                        o(self)
        finally:
            numba.set_num_threads(threads_before)
            if bar is not None:
                bar.close()

    # ------------------------------------------------------------------ results
    def damage(self):
        """Broken fraction of each point's bonds, (n,) in [0, 1] (0 without bonds)."""
        f = self.family
        total = np.diff(f.start)
        broken = np.add.reduceat(f.broken.astype(np.int64), f.start[:-1]) if f.n_bonds else 0
        broken = np.where(total > 0, broken, 0)
        return np.where(total > 0, broken / np.maximum(total, 1), 0.0)

    def energy_density(self):
        """Strain-energy density [J/m^3] of every point at the current state."""
        b, f = self.bodies, self.family
        theta = self.dilation()
        out = np.zeros(b.n)
        energy_density(b.pos, f.start, f.nbr, f.length, self.omega, self.vol, self.pw,
                       self.corr, theta, self.params, f.broken, out)
        return out

    def dilation(self):
        """Dilation ``theta`` of every point at the current state (LPS; 0 for PMB)."""
        b, f = self.bodies, self.family
        theta = np.zeros(b.n)
        params = self.params.copy()
        params[P_SCRIT] = math.inf  # reading the state breaks nothing
        bond_pass(b.pos, f.start, f.nbr, f.length, self.omega, self.vol, self.qw, self.pw,
                  params, f.broken.copy(), theta, np.zeros(b.n))
        return theta

    def deformation_gradient(self):
        """Nonlocal deformation gradient of every point, (n, d, d): ``F_i = (sum_j w Y ⊗ xi
        V_j) K_i^-1`` with the shape tensor ``K_i = sum_j w xi ⊗ xi V_j``, over the point's
        intact bonds (post-processing; the identity where a point has too few bonds)."""
        b, f = self.bodies, self.family
        d = self.dim
        own = f.owner()
        keep = f.broken == 0
        wv = (self.omega * self.vol[f.nbr])[keep]
        xi = f.xi[keep]
        y = b.pos[f.nbr[keep]] - b.pos[own[keep]]
        shape = np.zeros((b.n, d, d))
        np.add.at(shape, own[keep], wv[:, None, None] * xi[:, :, None] * xi[:, None, :])
        moment = np.zeros((b.n, d, d))
        np.add.at(moment, own[keep], wv[:, None, None] * y[:, :, None] * xi[:, None, :])
        ok = np.linalg.cond(shape) < 1e8
        F = np.broadcast_to(np.eye(d), (b.n, d, d)).copy()
        F[ok] = moment[ok] @ np.linalg.inv(shape[ok])
        return F

    def stress(self):
        """Cauchy stress of every point, (n, d, d) [Pa], from the small strain
        ``sym(F) - I`` of :meth:`deformation_gradient` and the material's elastic
        constants (plane strain or stress in 2D): a post-processing estimate, the
        classical stress the local deformation would carry."""
        d = self.dim
        F = self.deformation_gradient()
        eps = 0.5 * (F + F.transpose(0, 2, 1)) - np.eye(d)
        mat = self.material
        mu = mat.E / (2.0 * (1.0 + mat.nu))
        lam = mat.kappa(d) - 2.0 * mu / d  # the dimension's own Lame constant
        tr = np.trace(eps, axis1=1, axis2=2)
        return lam * tr[:, None, None] * np.eye(d) + 2.0 * mu * eps

    def strain_energy(self):
        """Elastic energy of the bonds [J]."""
        return float((self.energy_density() * self.vol).sum())

    def kinetic_energy(self):
        """Kinetic energy of the free bodies [J]."""
        b = self.bodies
        free = ~b.is_fixed
        return float(0.5 * (b.mass[free] * (b.vel[free] ** 2).sum(1)).sum())

    def momentum(self):
        """Linear momentum (d,) [kg m/s] of the free bodies."""
        b = self.bodies
        free = ~b.is_fixed
        return (b.mass[free, None] * b.vel[free]).sum(0)

    def angular_momentum(self, origin=None):
        """Angular momentum about ``origin`` of the free bodies (translational part:
        points carry no spin): a scalar in 2D, (3,) in 3D [kg m^2/s]."""
        b = self.bodies
        free = ~b.is_fixed
        o = np.zeros(self.dim) if origin is None else np.asarray(origin, np.float64)
        r = b.pos[free] - o
        p = b.mass[free, None] * b.vel[free]
        if self.dim == 2:
            return float((r[:, 0] * p[:, 1] - r[:, 1] * p[:, 0]).sum())
        return np.cross(r, p).sum(0)
