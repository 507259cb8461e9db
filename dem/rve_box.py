"""The wall-bounded RVE: disks or spheres in an orthogonal box of moving planar walls.

A :class:`BoxRVE` is the paper's compression box: two walls per axis, loaded the
way a laboratory biaxial or triaxial cell is, with the interface of the periodic
:class:`~dem.rve.RVE`:

* **strain control** -- :meth:`BoxRVE.apply_strain` takes the diagonal of an
  increment ``deps`` (d, d) and moves each pair of opposite walls apart (or
  together) at a constant speed over ``n_s`` steps, ``n_s`` chosen so that no step
  strains the box by more than ``max_step_strain``; the box's edge ``L_i`` ends at
  ``(1 + deps_ii) L_i`` and the walls are then held while the packing relaxes. The
  box has no shear mode: a non-zero off-diagonal component is refused;
* **stress and mixed control** -- :meth:`BoxRVE.load` drives the normal stresses
  named in ``mask`` to their targets by a servo on the walls' speeds (drained biaxial
  or triaxial tests: axial strain, constant lateral stress);
* **relaxation** -- as the periodic RVE: steps go on until the unbalanced-force ratio
  is below ``tol`` and every servo is within ``stress_tol`` of its target; past
  ``max_relax_steps`` a :class:`~dem.rve.RelaxationError` says how far it got.

Two stresses are measured (tension positive; in 2D per unit thickness, [Pa] for disks
of unit thickness):

* the **wall stress** -- the boundary average over the wall contacts,
  ``sigma = -(1/V) sum_c sym(F_c (x) (x_c - x_0))`` (``F_c`` the force on the wall,
  ``x_c`` the contact point, ``x_0`` the box centre): its diagonal is, for each axis
  ``i``, the normal force on the two walls normal to ``i`` over their area
  ``A_i = V / L_i``, averaged over the pair; its off-diagonal terms are the couples
  of the normal forces (and the tangential forces of rough walls), which the walls
  cannot control;
* the **Love-Weber stress** over particle-particle contacts (branch vectors) and
  particle-wall contacts (the particle's centre-to-contact arm), plus the kinetic
  part, over the box volume.

:meth:`BoxRVE.stress` and ``response()["stress"]`` are the wall stress: it is what
the servo controls and what a laboratory cell reports. In equilibrium both agree to
within the unbalanced-force ratio (``response()["stress_love"]`` gives the other).
The contact tangent is eq 29 over every contact (a wall contact's lever is its arm)
divided by the box volume.

Packings come from :func:`generate_box`: a random loose cloud in a box, consolidated
isotropically to ``p0`` by the wall servo (friction optionally lowered meanwhile).
"""

import json
import logging
import math
import time

import numpy as np

from .contact.laws import Law, law_from_spec
from .contact.model import ContactModel
from .observers import contact_summary
from .packings import cloud_lengths, particle_radii, random_addition, solid_volume
from .rve import RelaxationError
from .rve_settings import check_settings, scale_masses, store_settings, warn_contact_scale
from .shapes import Shape
from .simulation import Simulation
from .state import Bodies
from .timestep import quasi_static_dt

log = logging.getLogger(__name__)

__all__ = ["BoxRVE", "RelaxationError", "box_cloud", "generate_box"]

NO_SHEAR = "a box RVE has no shear mode"


class BoxRVE:
    """A wall-bounded representative volume element of disks or spheres.

    Parameters
    ----------
    bodies : Bodies
        Disks (2D) or spheres (3D) with centres inside the box; nothing else. The
        ``2 d`` walls are appended to it (rows ``walls``).
    law : Law
        Particle-particle contact law.
    lo, hi : (d,) array_like
        Opposite corners of the box [m].
    wall_law : Law, optional
        Particle-wall law, of the same kind as ``law`` (default: ``law`` without
        friction: smooth walls, with no tangential traction, so the packing slides
        along them and the box deforms homogeneously).
    damping, dt, mass_scale, max_step_strain, tol, stress_tol, max_relax_steps, \
check_every, threads
        As for :class:`~dem.rve.RVE`.

    Attributes
    ----------
    walls : (d, 2) int array, body rows of the lower and upper wall of each axis
    deformation : (d, d) float64, ``diag(L / L_ref)``: the box's stretch since its
        creation (a property, read from the walls' positions)
    """

    #: servo time constant, in checks (chunks of ``check_every`` steps)
    SERVO_CHUNKS = 4.0

    #: settings stored with a saved box RVE
    _SETTINGS = ("mass_scale", "max_step_strain", "tol", "stress_tol", "max_relax_steps",
                 "check_every")

    def __init__(self, bodies, law, lo, hi, wall_law=None, damping=0.5, dt=None,
                 mass_scale=1.0, max_step_strain=1e-5, tol=1e-3, stress_tol=1e-3,
                 max_relax_steps=200_000, check_every=50, threads=1):
        if not isinstance(law, Law):
            raise TypeError("law must be a contact Law (LinearSpring, HertzMindlin)")
        wall_law = law.with_friction(0.0) if wall_law is None else wall_law
        if type(wall_law) is not type(law):
            raise TypeError("wall_law must be a contact Law of the same kind as law")
        d = bodies.dim
        lo = np.asarray(lo, dtype=np.float64)
        hi = np.asarray(hi, dtype=np.float64)
        if lo.shape != (d,) or hi.shape != (d,) or not np.all(np.isfinite(lo)) \
                or not np.all(np.isfinite(hi)) or not np.all(hi > lo):
            raise ValueError(f"box corners lo, hi must be finite ({d},) arrays, hi > lo")
        if bodies.has_shapes or np.any(bodies.kind != Shape.SPHERE):
            raise ValueError("a box RVE holds disks or spheres only (it adds the walls)")
        if np.any(bodies.pos < lo) or np.any(bodies.pos > hi):
            raise ValueError("every particle centre must lie inside the box")
        check_settings(mass_scale, max_step_strain, tol, stress_tol, max_relax_steps,
                       check_every)
        scale_masses(bodies, mass_scale)
        walls = np.zeros((d, 2), np.int64)
        for a in range(d):
            e = np.eye(d)[a]
            walls[a, 0] = bodies.add_plane(lo, e)
            walls[a, 1] = bodies.add_plane(hi, -e)
        model = ContactModel(law, wall_law)
        sim = Simulation(bodies, model, dt=quasi_static_dt(bodies, model, dt, damping),
                         damping=damping, threads=threads)
        self._setup(sim, law, wall_law, walls, hi - lo, mass_scale, max_step_strain, tol,
                    stress_tol, max_relax_steps, check_every)

    def _setup(self, sim, law, wall_law, walls, length_ref, mass_scale, max_step_strain,
               tol, stress_tol, max_relax_steps, check_every):
        self.sim = sim
        self.law = law
        self.wall_law = wall_law
        self.dim = sim.dim
        self.walls = np.asarray(walls, np.int64)
        self.length_ref = np.array(length_ref, np.float64)
        self.particles = np.flatnonzero(sim.bodies.kind != Shape.PLANE)
        store_settings(self, mass_scale, max_step_strain, tol, stress_tol,
                       max_relax_steps, check_every)
        #: steps of the last load or relaxation
        self.last_relax_steps = 0
        #: every step loads and relaxations have run (not reset by :meth:`restore`)
        self.steps_run = 0

    # ------------------------------------------------------------------ state
    @property
    def bodies(self):
        return self.sim.bodies

    def lengths(self):
        """Edge lengths of the box [m], (d,): distances between opposite walls."""
        p = self.bodies.pos
        ax = np.arange(self.dim)
        return p[self.walls[:, 1], ax] - p[self.walls[:, 0], ax]

    @property
    def volume(self):
        """Box volume [m^3] (area [m^2] in 2D)."""
        return float(np.prod(self.lengths()))

    @property
    def deformation(self):
        """``diag(L / L_ref)`` (d, d): the box's stretch since its creation."""
        return np.diag(self.lengths() / self.length_ref)

    def snapshot(self, into=None):
        """Copy of the full state (reusing ``into``'s arrays): see :meth:`restore`."""
        return self.sim.snapshot(into)

    def restore(self, snap):
        """Return to a :meth:`snapshot`; runs from it repeat bit for bit."""
        self.sim.restore(snap)

    def set_friction(self, mu):
        """Change the particle-particle friction coefficient (the walls keep theirs)."""
        self.law = self.law.with_friction(mu)
        self.sim.model = ContactModel(self.law, self.wall_law)
        self.sim.invalidate()

    def _set_wall_speeds(self, speed):
        """Walls of axis ``i`` move apart at ``speed[i]`` [m/s] (d,), centre fixed."""
        v = self.bodies.vel
        for a in range(self.dim):
            v[self.walls[a, 0], a] = -0.5 * speed[a]
            v[self.walls[a, 1], a] = 0.5 * speed[a]

    # ------------------------------------------------------------------ response
    def wall_stress(self):
        """Stress from the wall forces (d, d) [Pa], tension positive.

        ``sigma = -(1/V) sum_c sym(F_c (x) (x_c - x_0))`` over the wall contacts, with
        ``F_c`` the force on the wall, ``x_c`` the contact point on it and ``x_0`` the
        box centre. Its diagonal is, for each axis ``i``, the mean normal force on the
        two walls normal to ``i`` over their area ``A_i = V / L_i``; its off-diagonal
        terms are couples of the normal forces (and the tangential forces of rough
        walls), which the walls cannot control: a box RVE has no shear mode.
        """
        sim = self.sim
        sim.prime()
        b = sim.bodies
        wp = sim.neighbors.wall_pairs
        i, w = wp[:, 0], wp[:, 1]
        nw = b.normal[w]
        gap = np.einsum("ij,ij->i", b.pos[i] - b.pos[w], nw)
        x_c = b.pos[i] - gap[:, None] * nw  # the particle centre projected on the wall
        ax = np.arange(self.dim)
        centre = 0.5 * (b.pos[self.walls[:, 0], ax] + b.pos[self.walls[:, 1], ax])
        sig = np.einsum("ca,cb->ab", sim.wall_state.wforce, x_c - centre)  # wforce: on the particle
        return 0.5 * (sig + sig.T) / self.volume

    def response(self, tangent=True):
        """Wall stress (d, d) [Pa], contact tangent (d, d, d, d) [Pa] or None, and the
        measures of the packing, from the current state (a dict).

        Keys as :meth:`dem.rve.RVE.response` (``stress``, ``tangent``, ``n_contacts``,
        ``unbalanced``, ``fabric``, ``coordination``, ``rattlers``, ``void_ratio``),
        plus ``stress_love`` (Love-Weber, kinetic part included) and ``n_wall_contacts``.
        Contacts and the fabric count wall contacts too; the coordination number is
        contacts per particle, a wall contact counting once.
        """
        sim = self.sim
        sim.prime()
        b = sim.bodies
        c = contact_summary(sim)
        v = self.volume
        f, n, is_wall = c["force"], c["normal"], c["is_wall"]
        # lever of a contact: branch vector (particles), centre-to-contact arm (walls)
        lever = np.where(is_wall[:, None], c["arm_i"], c["branch"])
        p = self.particles
        sig = -np.einsum("ca,cb->ab", f, lever)
        sig -= np.einsum("p,pa,pb->ab", b.mass[p], b.vel[p], b.vel[p])
        n_wall = int(np.count_nonzero(is_wall))
        out = {"stress": self.wall_stress(), "stress_love": 0.5 * (sig + sig.T) / v,
               "n_contacts": int(f.shape[0]), "n_wall_contacts": n_wall}
        net = np.zeros((b.n, self.dim))
        np.add.at(net, c["i"], -f)
        np.add.at(net, c["j"][~is_wall], f[~is_wall])
        fmean = float(np.linalg.norm(f, axis=1).mean()) if f.shape[0] else 0.0
        out["unbalanced"] = (float(np.linalg.norm(net[p], axis=1).mean()) / fmean
                             if fmean > 0.0 else math.inf)
        out["fabric"] = (np.einsum("ci,cj->ij", n, n) / n.shape[0] if n.shape[0]
                         else np.zeros((self.dim, self.dim)))
        deg = np.bincount(np.concatenate([c["i"], c["j"][~is_wall]]), minlength=b.n)[p]
        out["coordination"] = float(deg.sum()) / p.size
        out["rattlers"] = int(np.count_nonzero(deg < 2))
        vs = solid_volume(b)
        out["void_ratio"] = (v - vs) / vs
        if tangent:
            kn, kt = c["kn"], c["kt"]
            eye = np.eye(self.dim)
            cn = np.einsum("c,ci,cj,ck,cl->ijkl", kn, n, lever, n, lever)
            proj = eye[None] - np.einsum("ci,ck->cik", n, n)
            ct = np.einsum("c,cik,cj,cl->ijkl", kt, proj, lever, lever)
            out["tangent"] = (cn + ct) / v
        return out

    def stress(self):
        """Wall stress (d, d) [Pa], tension positive (see :meth:`wall_stress`)."""
        return self.wall_stress()

    def tangent(self, method="contact", probe=1e-5, direction=None):
        """Tangent operator ``C_ijkl = d sigma_ij / d eps_kl`` (d, d, d, d) [Pa].

        ``"contact"``: eq 29 over every contact (affine, all components).
        ``"perturbation"``: an axial probe ``probe`` per axis from the current state,
        relaxed, the wall-stress difference divided by it, the state restored after
        each; the box has no shear mode, so only the columns ``C_ijkk`` are measured
        and ``C_ijkl`` with ``k != l`` is zero. ``direction`` (d, d) gives each probe the
        sign of its diagonal component (the loading branch), as for
        :meth:`dem.rve.RVE.tangent`.
        """
        if method == "contact":
            return self.response(tangent=True)["tangent"]
        if method != "perturbation":
            raise ValueError(f"tangent method must be 'contact' or 'perturbation', "
                             f"got {method!r}")
        d = self.dim
        base = self.snapshot()
        s0 = self.stress()
        c = np.zeros((d, d, d, d))
        for k in range(d):
            h = -probe if direction is not None and direction[k, k] < 0.0 else probe
            de = np.zeros((d, d))
            de[k, k] = h
            self.apply_strain(de)
            c[:, :, k, k] = (self.stress() - s0) / h
            self.restore(base)
        return c

    # ------------------------------------------------------------------ loading
    def apply_strain(self, deps):
        """Impose the axial strain increment ``diag(deps)`` (d, d), then relax.

        Returns the relaxed wall stress (d, d) [Pa]. A non-zero off-diagonal
        component raises ValueError: a box RVE has no shear mode.
        """
        return self.load(deps)

    def load(self, deps=None, stress=None, mask=None, progress=None):
        """Mixed control: axial strain on some axes, normal stress on the others.

        Parameters
        ----------
        deps : (d, d) array_like, optional
            Strain increment, diagonal (off-diagonal entries must be zero); entries
            of stress-controlled axes are ignored.
        stress : (d,) or (d, d) array_like, optional
            Target normal stresses [Pa] (tension positive) of the axes in ``mask``.
        mask : (d,) or (d, d) bool array_like, optional
            Axes under stress control (a diagonal mask).
        progress : callable, optional
            ``progress(steps_done)`` after each check.

        Returns the relaxed wall stress (d, d) [Pa].
        """
        d = self.dim
        deps = np.zeros((d, d)) if deps is None else np.array(deps, dtype=np.float64)
        if deps.shape != (d, d) or not np.all(np.isfinite(deps)):
            raise ValueError(f"strain increment must be a finite ({d}, {d}) array")
        off = ~np.eye(d, dtype=bool)
        if np.any(deps[off] != 0.0):
            raise ValueError(f"{NO_SHEAR}: its walls only stretch or compress the axes, "
                             f"so the off-diagonal components of the strain increment "
                             f"must be zero, got {deps[off].tolist()}")
        mask = np.zeros(d, bool) if mask is None else np.asarray(mask, dtype=bool)
        target = np.zeros(d) if stress is None else np.asarray(stress, dtype=np.float64)
        if mask.shape == (d, d):
            if np.any(mask[off]):
                raise ValueError(f"{NO_SHEAR}: only normal stresses can be controlled")
            mask = np.diag(mask).copy()
        if target.shape == (d, d):
            if np.any(target[off] != 0.0):
                raise ValueError(f"{NO_SHEAR}: shear stress targets must be zero")
            target = np.diag(target).copy()
        if mask.shape != (d,) or target.shape != (d,) or not np.all(np.isfinite(target)):
            raise ValueError(f"stress targets and mask must be finite ({d},) or "
                             f"({d}, {d}) arrays")
        eps = np.diag(deps).copy()
        eps[mask] = 0.0
        return self._drive(eps, target, mask, progress)

    def consolidate(self, p0, friction=None, max_step_strain=1e-4, progress=None):
        """Isotropic consolidation to ``sigma = -p0 I`` [Pa] by the wall servo.

        With ``friction`` the consolidation first runs at that particle friction
        coefficient (lower than the law's for a denser packing), then the law's
        friction is restored for the final relaxation at the same pressure. It is
        restored also when the first stage raises.
        """
        if not (math.isfinite(p0) and p0 > 0.0):
            raise ValueError(f"p0 must be positive and finite, got {p0}")
        working = self.law.mu
        saved = self.max_step_strain
        self.max_step_strain = float(max_step_strain)
        target = np.full(self.dim, -float(p0))
        full = np.ones(self.dim, bool)
        zero = np.zeros(self.dim)
        try:
            if friction is not None:
                self.set_friction(friction)
                try:
                    self._drive(zero, target, full, progress)
                finally:
                    self.set_friction(working)
            return self._drive(zero, target, full, progress)
        finally:
            self.max_step_strain = saved

    def _drive(self, eps, target, mask, progress):
        """Axial strains ``eps`` (d,) on the unmasked axes, stress ``target`` (d,) [Pa]
        on the masked ones; then relax."""
        sim, d = self.sim, self.dim
        dt = sim.dt
        n_load = math.ceil(np.abs(eps).max() / self.max_step_strain) if eps.any() else 0
        # constant wall speeds: after n_load steps each edge is exactly (1 + eps) L
        speed_load = eps * self.lengths() / (n_load * dt) if n_load else np.zeros(d)
        rate_max = self.max_step_strain / dt
        tau = self.SERVO_CHUNKS * self.check_every * dt  # servo time constant
        start = sim.step
        done_load = 0
        r = self.response(tangent=bool(mask.any()))
        try:
            while True:
                servo_ok = True
                speed = np.zeros(d)
                length = self.lengths()
                for a in np.flatnonzero(mask):
                    err = target[a] - r["stress"][a, a]
                    if target[a] != 0.0:
                        servo_ok &= abs(err) <= self.stress_tol * abs(target[a])
                    else:  # a zero target: judged against the mean stress
                        scale = max(abs(np.trace(r["stress"])) / d, 1e-300)
                        servo_ok &= abs(err) <= self.stress_tol * scale
                    m = r["tangent"][a, a, a, a]
                    rate = err / (m * tau) if m > 0.0 else math.copysign(rate_max, err)
                    speed[a] = max(-rate_max, min(rate_max, rate)) * length[a]
                n_chunk = self.check_every
                if done_load < n_load:
                    n_chunk = min(n_chunk, n_load - done_load)
                    speed += speed_load
                elif servo_ok and r["unbalanced"] < self.tol:
                    break
                if sim.step - start - n_load >= self.max_relax_steps:
                    raise RelaxationError(
                        f"box RVE did not relax within {self.max_relax_steps} steps: "
                        f"unbalanced force ratio {r['unbalanced']:.3g} (tolerance "
                        f"{self.tol:g}), wall stress "
                        f"{np.round(np.diag(r['stress']), 1).tolist()} Pa (targets "
                        f"{target[mask].tolist()} on axes {np.flatnonzero(mask).tolist()}"
                        f"); lower the strain increment, raise damping or "
                        f"max_relax_steps")
                self._set_wall_speeds(speed)
                sim.run(n_chunk, progress=False)
                self.steps_run += n_chunk
                self._set_wall_speeds(np.zeros(d))
                if done_load < n_load:
                    done_load += n_chunk
                r = self.response(tangent=bool(mask.any()))
                if progress is not None:
                    progress(sim.step - start)
        finally:
            self._set_wall_speeds(np.zeros(d))
        self.last_relax_steps = sim.step - start
        return r["stress"]

    # ------------------------------------------------------------------ files
    def save(self, path, **attrs):
        """Write the box RVE (state, laws, settings) to an HDF5 file, atomically."""
        from .io.checkpoint import save_checkpoint

        def extra(f):
            g = f.create_group("box_rve")
            g.attrs["law"] = json.dumps(self.law.spec())
            g.attrs["wall_law"] = json.dumps(self.wall_law.spec())
            for k in self._SETTINGS:
                g.attrs[k] = getattr(self, k)
            g.create_dataset("walls", data=self.walls)
            g.create_dataset("length_ref", data=self.length_ref)
            for k, v in attrs.items():
                g.attrs[k] = v

        return save_checkpoint(self.sim, path, extra=extra)

    @classmethod
    def load_file(cls, path, **overrides):
        """Read a box RVE written by :meth:`save` (``overrides`` replace settings)."""
        from .io.checkpoint import load_checkpoint, read_group

        g = read_group(path, "box_rve")
        try:
            law = law_from_spec(json.loads(g["attrs"]["law"]))
            wall_law = law_from_spec(json.loads(g["attrs"]["wall_law"]))
            opts = {k: g["attrs"][k] for k in cls._SETTINGS}
            walls = np.asarray(g["data"]["walls"], np.int64)
            length_ref = np.asarray(g["data"]["length_ref"], np.float64)
        except (KeyError, ValueError, TypeError) as err:
            raise ValueError(f"{path}: malformed box RVE file ({err})") from None
        unknown = set(overrides) - set(cls._SETTINGS)
        if unknown:
            raise TypeError(f"unknown RVE settings: {', '.join(sorted(unknown))}")
        opts.update(overrides)
        sim = load_checkpoint(path, ContactModel(law, wall_law))
        d = sim.dim
        if walls.shape != (d, 2) or length_ref.shape != (d,) or walls.min() < 0 \
                or walls.max() >= sim.bodies.n \
                or np.any(sim.bodies.kind[walls] != Shape.PLANE):
            raise ValueError(f"{path}: not a box RVE (walls)")
        rve = cls.__new__(cls)
        rve._setup(sim, law, wall_law, walls, length_ref, **opts)
        return rve


# --------------------------------------------------------------------------- packings
def box_cloud(dim, radii, solid_fraction, seed=0, aspect=None):
    """A box and non-overlapping random positions for ``radii`` inside it.

    Random sequential addition, largest first, of particles wholly inside a box sized
    for ``solid_fraction`` (at most 0.5 in 2D, 0.35 in 3D); ``aspect`` (d,) sets the
    edge ratios (default a cube). Returns ``(lo, hi, pos)`` [m], ``lo`` the origin.

    Examples
    --------
    >>> lo, hi, pos = box_cloud(2, [1.0, 1.0, 1.0], 0.3)
    >>> bool(np.all(pos - 1.0 >= lo) and np.all(pos + 1.0 <= hi))
    True
    """
    radii = np.asarray(radii, dtype=np.float64)
    lengths = cloud_lengths(dim, radii, solid_fraction, aspect, "a box: an edge")
    pos = random_addition(radii, lengths, solid_fraction, seed, periodic=False)
    return np.zeros(dim), lengths, pos


def generate_box(dim, n, radius, law, p0, density=2650.0, fractions=None, seed=0,
                 friction=None, solid_fraction=None, aspect=None, wall_law=None,
                 progress=None, **rve_options):
    """A box packing consolidated to ``p0`` [Pa] by its walls, ready to load.

    Arguments as :func:`dem.rve.generate`, plus ``aspect`` (d,), the box's initial
    edge ratios, and ``wall_law`` (see :class:`BoxRVE`). ``**rve_options`` go to
    :class:`BoxRVE`. Reproducible: a function of the seed and the arguments.
    """
    radii = particle_radii(n, radius, fractions, seed)
    warn_contact_scale(law, p0, float(np.mean(radii)), dim)
    phi = solid_fraction or (0.4 if dim == 2 else 0.25)
    lo, hi, pos = box_cloud(dim, radii, phi, seed, aspect)
    bodies = Bodies.spheres(pos, radius=radii, density=density)
    rve = BoxRVE(bodies, law, lo, hi, wall_law=wall_law, **rve_options)
    t0 = time.perf_counter()
    rve.consolidate(p0, friction=friction, progress=progress)
    log.info("box packing of %d particles consolidated to %.4g Pa in %d steps (%.1f s)",
             n, p0, rve.sim.step, time.perf_counter() - t0)
    return rve
