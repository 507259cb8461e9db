"""Representative volume elements: periodic DEM cells under strain, stress or mixed control.

An :class:`RVE` is a :class:`~dem.Simulation` of disks (2D) or spheres (3D) in a
deformable :class:`~dem.boundary.PeriodicCell`. It is loaded the way a finite element
Gauss point needs:

* **strain control** -- :meth:`RVE.apply_strain` imposes an increment ``deps`` (d, d)
  of the displacement gradient as a constant velocity gradient over ``n_s`` steps,
  ``n_s`` chosen so that no step strains the cell by more than ``max_step_strain``
  (1e-5 by default, as YADE's FEMxDEM; :func:`load_steps`: the stretch counts, a
  rotation does not), with ``L = ((I + deps)^(1/n_s) - I) / dt`` so that the
  steps' map ``(I + dt L)^n_s`` is exactly ``I + deps``; then it holds the cell and
  relaxes. ``deps`` need not be symmetric: its spin turns the packing with the cell
  (:mod:`dem.boundary`), and the stress with it;
* **stress and mixed control** -- :meth:`RVE.load` drives the diagonal components
  named in ``mask`` to target stresses with a servo on the cell while the others
  follow a strain increment (a drained biaxial or triaxial test: axial strain,
  constant lateral stress);
* **relaxation** -- steps go on until the unbalanced-force ratio (mean net force
  on a particle over mean contact force) is below ``tol`` and every servo has
  reached its target; past ``max_relax_steps`` a :class:`RelaxationError` says how
  far it got. The checks run inside the compiled step loop: under strain control
  those of :meth:`dem.Simulation.relax`, with a servo the drive's
  (:mod:`dem.contact.servo`, :mod:`dem.rve_servo`), which set the servo's rates.

The response is the Love-Weber stress over contacts with periodic branch vectors,
plus the kinetic part of the fluctuations (:func:`dem.observers.stress_and_tangent`,
paper eq 24), and a tangent: the contact-stiffness tangent (eq 29, the stiffness of
the contact network deformed affinely) or a perturbation tangent (finite strain probes
from the same state, each relaxed, the accurate alternative). Stress is positive in
tension; in 2D stresses are per unit thickness over the cell's area, i.e. [Pa] for
disks of unit thickness.

State handling is a copy into preallocated arrays (:meth:`RVE.snapshot`,
:meth:`RVE.restore`); :meth:`RVE.save` and :meth:`RVE.load_file` keep a packing in
HDF5 so that one consolidation serves every Gauss point.

Packings come from :func:`generate`: a random loose cloud of polydisperse
particles, consolidated isotropically to ``p0`` by the servo with friction lowered
(dense packings), then brought to the working friction at the same pressure.
"""

import logging
import math
import time

import numpy as np

from .boundary import PeriodicCell, cell_map, load_steps, matrix_root
from .contact.laws import Law, law_from_spec
from .rve_measure import measure_periodic
from .rve_servo import drive
from .limits import check_particle_scales
from .observers import couple_stress
from .rve_settings import check_settings, scale_masses, store_settings, warn_contact_scale
from .simulation import Simulation, SimulationError
from .timestep import quasi_static_dt
from .packings import loose_cloud, particle_radii, shape_bodies, solid_volume
from .shapes import Shape
from .shapes.registry import kinds_with
from .state import Bodies

log = logging.getLogger(__name__)

#: shape kinds an RVE holds besides spheres/disks
POLYTOPES = kinds_with("polytope")


class RelaxationError(SimulationError):
    """The RVE did not reach quasi-static equilibrium within its step cap."""


class PackingApart(RelaxationError):
    """Under strain control the packing lost its contacts (a gas in a fixed cell, which
    never relaxes): in an undrained test, liquefaction."""


# --------------------------------------------------------------------------- the RVE
class RVE:
    """A periodic representative volume element of disks or spheres.

    Parameters
    ----------
    bodies : Bodies
        Disks (2D) or spheres (3D) inside ``cell``; nothing else.
    law : Law
        Contact law (:class:`~dem.LinearSpring` or :class:`~dem.HertzMindlin`).
    cell : PeriodicCell
    damping : float
        Cundall local damping in [0, 1) (quasi-static runs: 0.2 to 0.7).
    dt : float, optional
        Time step [s]; default :data:`dem.timestep.QUASI_STATIC_FACTOR` (0.25) x the
        critical step, less for
        dashpots and local damping (:func:`quasi_static_dt`).
    mass_scale : float
        Density scaling factor (>= 1 speeds quasi-static runs up by sqrt of it; the
        masses, the kinetic stress and the time step are those of the scaled
        particles, and :attr:`mass_scale` reports it).
    max_step_strain : float
        Largest strain per time step under strain control.
    tol : float
        Unbalanced-force ratio at which a relaxation ends.
    stress_tol : float
        Relative tolerance of a stress-controlled component.
    max_relax_steps : int
        Step cap of one relaxation.
    check_every : int
        Steps between evaluations of stress and unbalanced force (servo updates).
    threads : int, optional
        Passed to :class:`~dem.Simulation` (default 1: an RVE is small, and a farm
        runs many at once).
    """

    def __init__(self, bodies, law, cell, damping=0.5, dt=None, mass_scale=1.0,
                 max_step_strain=1e-5, tol=1e-3, stress_tol=1e-3,
                 max_relax_steps=200_000, check_every=50, threads=1):
        if not isinstance(cell, PeriodicCell):
            raise TypeError("cell must be a PeriodicCell")
        if not isinstance(law, Law):
            raise TypeError("law must be a contact Law (LinearSpring, HertzMindlin)")
        if bodies.dim != cell.dim:
            raise ValueError(f"bodies are {bodies.dim}D, the cell {cell.dim}D")
        if np.any(~np.isin(bodies.kind, POLYTOPES + (Shape.SPHERE,))):
            raise ValueError("an RVE holds disks/spheres and polytopes (boxes, polygons, "
                             "polyhedra) only: no walls, no user-defined shapes")
        check_settings(mass_scale, max_step_strain, tol, stress_tol, max_relax_steps,
                       check_every)
        scale_masses(bodies, mass_scale)
        sim = Simulation(bodies, law, dt=quasi_static_dt(bodies, law, dt, damping),
                         damping=damping, box=cell, threads=threads)
        self._setup(sim, law, mass_scale, max_step_strain, tol, stress_tol,
                    max_relax_steps, check_every, np.eye(cell.dim))

    def _setup(self, sim, law, mass_scale, max_step_strain, tol, stress_tol,
               max_relax_steps, check_every, deformation):
        self.sim = sim
        self.law = law
        self.cell = sim.cell
        self.dim = sim.dim
        store_settings(self, mass_scale, max_step_strain, tol, stress_tol,
                       max_relax_steps, check_every)
        #: accumulated deformation gradient of the cell since its creation
        self.deformation = deformation
        #: steps of the last load or relaxation
        self.last_relax_steps = 0
        #: how often the last :meth:`load` (or :meth:`apply_strain`) or
        #: :meth:`consolidate` doubled a stalled servo's gain (:attr:`STALL_CHECKS`)
        self.servo_boosts = 0
        #: every step loads and relaxations have run, probes included (a work counter:
        #: :meth:`restore` does not reset it)
        self.steps_run = 0

    #: a servo on a shear (or zero) stress is done within this fraction of the mean
    #: stress: a small packing's shear stress jumps by about that much when a
    #: contact slips, and a tighter servo would keep stirring it
    SHEAR_TOL = 1e-2

    #: under strain control, a packing whose coordination number stays below this
    #: for :attr:`APART_CHECKS` checks after its increment has come apart: no
    #: jammed packing has fewer contacts than half its particles, and a gas in a
    #: fixed cell never relaxes, so the relaxation stops at once with a
    #: :class:`RelaxationError` instead of running to its step cap
    APART_COORDINATION = 1.0
    APART_CHECKS = 10

    #: a servo whose packing is at rest but off target, with its worst error not 10 %
    #: smaller than its best for this many checks, has stalled: a creeping packing
    #: relaxes stress as fast as a proportional servo (gain from the eq-29 tangent, an
    #: upper bound of the stiffness) restores it, and the offset stays. Once half of
    #: ``max_relax_steps`` is spent, a stalled servo's gain is doubled (halved again,
    #: to at least its own, on an overshoot). A load or consolidation that ends
    #: within half its step cap never sees this rescue: its path is unchanged.
    STALL_CHECKS = 20

    #: settings stored with a saved RVE
    _SETTINGS = ("mass_scale", "max_step_strain", "tol", "stress_tol", "max_relax_steps",
                 "check_every")

    # ------------------------------------------------------------------ state
    @property
    def bodies(self):
        return self.sim.bodies

    @property
    def volume(self):
        return self.cell.volume

    def snapshot(self, into=None):
        """Copy of the full state (reusing ``into``'s arrays): see :meth:`restore`."""
        snap = self.sim.snapshot(into)
        old = snap.get("rve_deformation")
        if old is None:
            snap["rve_deformation"] = self.deformation.copy()
        else:
            np.copyto(old, self.deformation)
        return snap

    def restore(self, snap):
        """Return to a :meth:`snapshot`; runs from it repeat bit for bit."""
        self.sim.restore(snap)
        np.copyto(self.deformation, snap["rve_deformation"])

    def set_friction(self, mu):
        """Change the friction coefficient of the contact law (existing contacts keep
        their tangential springs; a spring above the new Coulomb limit slips at the
        next step)."""
        self.law = self.law.with_friction(mu)
        self.sim.model = type(self.sim.model)(self.law)
        self.sim.invalidate()

    # ------------------------------------------------------------------ response
    def response(self, tangent=True):
        """Stress (d, d) [Pa], contact tangent (d, d, d, d) [Pa] or None, and the
        measures of the packing, from the current state (a dict).

        One compiled pass over the contacts (:func:`dem.rve_measure.measure_periodic`)
        into arrays kept with the RVE; the returned arrays are fresh copies. A law with
        rolling resistance adds ``couple_stress`` (r, d) [N/m]
        (:func:`dem.observers.couple_stress`).
        """
        sim = self.sim
        sim.prime()
        b = sim.bodies
        d = self.dim
        if getattr(self, "_scratch", None) is None or self._scratch[0].shape[0] != b.n:
            self._scratch = (np.zeros((b.n, d)), np.zeros(b.n, np.int64),
                             np.zeros((d, d)), np.zeros((d, d, d, d)), np.zeros((d, d)))
        net, degree, sig, cmat, fabric = self._scratch
        nl = sim.neighbors
        n_c, unbalanced = measure_periodic(
            sim.model.kind("pp").code, b.pos, b.vel, b.mass, b.radius, b.mat_id,
            nl.pairs, nl.img, sim.image_matrix, sim.pair_state.fpair, sim.shaped,
            sim.shape_state.pgeom if sim.shaped else _NO_GEOMETRY,
            sim.parameter_table("pp"), self.volume,
            bool(tangent), net, degree, sig, cmat, fabric)
        if getattr(self, "_solid", None) is None:  # the particles never change
            self._solid = solid_volume(b)
        vs = self._solid
        out = {"stress": sig.copy(), "n_contacts": int(n_c),
               "unbalanced": float(unbalanced), "fabric": fabric.copy(),
               "coordination": 2.0 * n_c / b.n,
               "rattlers": int(np.count_nonzero(degree < 2)),
               "void_ratio": (self.volume - vs) / vs}
        if tangent:
            out["tangent"] = cmat.copy()
        if sim.model.rolling:  # the contact moments' couple stress
            out["couple_stress"] = couple_stress(sim, self.volume)
        return out

    def stress(self):
        """Homogenised Cauchy stress (d, d) [Pa], tension positive."""
        return self.response(tangent=False)["stress"]

    def tangent(self, method="contact", probe=1e-5, direction=None):
        """Tangent operator ``C_ijkl = d sigma_ij / d eps_kl`` (d, d, d, d) [Pa].

        ``method="contact"``: eq 29 from the contact stiffnesses (affine, an upper
        bound of the relaxed stiffness). ``"perturbation"``: for each symmetric
        strain direction, a probe of ``probe`` is applied from the current state and
        relaxed, and the stress difference divided by it; the state is restored
        after each probe (the result is symmetric in kl by construction). A granular
        packing is stiffer unloading than loading: ``direction`` (d, d), e.g. the
        last strain increment, gives each probe the sign of its component, so the
        tangent is that of the loading branch (default: positive probes).
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
            for m in range(k, d):
                de = np.zeros((d, d))
                h = probe
                if direction is not None and direction[k, m] + direction[m, k] < 0.0:
                    h = -probe
                # a shear probe is an engineering strain: eps_km = eps_mk = h / 2
                de[k, m] = de[m, k] = h if k == m else 0.5 * h
                self.apply_strain(de)
                ds = (self.stress() - s0) / h
                if k == m:
                    c[:, :, k, k] = ds
                else:  # d sigma / d eps_km = d sigma / d eps_mk = ds (each half)
                    c[:, :, k, m] = c[:, :, m, k] = ds
                self.restore(base)
        return c

    # ------------------------------------------------------------------ loading
    def apply_strain(self, deps, relax=True, tangent=False):
        """Impose the displacement-gradient increment ``deps`` (d, d), then relax.

        Returns the stress (d, d) [Pa] of the relaxed state, and with ``tangent=True``
        the pair ``(stress, contact tangent)`` of that state from one measuring pass
        (a Gauss point's call). ``relax=False`` stops once the increment is imposed,
        as YADE's FEMxDEM calls its RVEs: the stress is that of the state the loading
        steps leave, not in equilibrium.

        The call is two compiled loops and a measure: the increment's steps in one
        run, then :meth:`dem.Simulation.relax`, whose loop checks the unbalanced
        force every :attr:`check_every` steps itself. Calls of :meth:`load` with a
        servo or a ``progress`` callback run the drive of :mod:`dem.rve_servo`, whose
        checks the loop makes too (polytope RVEs: between chunks of
        :attr:`check_every` steps); a strain-controlled call gives the same state
        either way, bit for bit.
        """
        sig = self.load(deps, relax=relax, tangent=tangent)
        return (sig, self._last["tangent"]) if tangent else sig

    def load(self, deps=None, stress=None, mask=None, progress=None, relax=True,
             tangent=False):
        """Mixed control: strain increment on some components, stress on others.

        Parameters
        ----------
        deps : (d, d) array_like, optional
            Displacement-gradient increment of the strain-controlled components
            (entries on stress-controlled components are ignored).
        stress : (d,) or (d, d) array_like, optional
            Target stresses [Pa] (tension positive) of the components in ``mask``:
            diagonal ones, or a full symmetric tensor.
        mask : (d,) or (d, d) bool array_like, optional
            Components under stress control: diagonal ones, or any symmetric set
            (a shear component is driven by a symmetric shear strain rate).
        progress : callable, optional
            ``progress(steps_done)`` after each check (for progress bars).
        relax : bool
            Relax after the increment (default); False ends the call once the
            increment is imposed (strain control only: a servo needs relaxation).
        tangent : bool
            Measure the contact tangent of the final state too (kept for
            :meth:`apply_strain`).

        Returns the relaxed stress (d, d) [Pa].
        """
        d = self.dim
        deps = np.zeros((d, d)) if deps is None else np.array(deps, dtype=np.float64)
        if deps.shape != (d, d) or not np.all(np.isfinite(deps)):
            raise ValueError(f"strain increment must be a finite ({d}, {d}) array")
        mask = np.zeros(d, bool) if mask is None else np.asarray(mask, dtype=bool)
        target = np.zeros(d) if stress is None else np.asarray(stress, dtype=np.float64)
        if mask.shape == (d,):
            mask = np.diag(mask)
        if target.shape == (d,):
            target = np.diag(target)
        if mask.shape != (d, d) or target.shape != (d, d) \
                or not np.all(np.isfinite(target)):
            raise ValueError(f"stress targets and mask must be finite ({d},) or "
                             f"({d}, {d}) arrays")
        mask = mask | mask.T
        if not relax and mask.any():
            raise ValueError("stress control needs relaxation: relax=False is for "
                             "strain-controlled increments only")
        deps[mask] = 0.0
        self.servo_boosts = 0
        if not mask.any() and progress is None and not self.sim.shaped:
            return self._strain_drive(deps, relax, tangent)
        sig = self._drive(deps, target, mask, progress, relax)
        if tangent and "tangent" not in self._last:
            self._last = self.response(tangent=True)
        return sig

    def consolidate(self, p0, friction=None, max_step_strain=1e-4, progress=None):
        """Isotropic consolidation to ``sigma = -p0 I`` [Pa] by the servo on every
        component of the cell (shear stresses driven towards zero while it relaxes,
        see :attr:`SHEAR_TOL`).

        With ``friction`` the consolidation first runs at that friction coefficient
        (lower than the law's for a denser packing) with the normal stresses alone
        servoed, then the law's friction is restored for the final relaxation. A first
        stage that does not settle within ``max_relax_steps`` (a small frictionless
        packing can creep under its locked shear stress faster than the servo corrects
        it) is logged and left where it stopped: the second, at the law's friction
        with every component servoed, finishes the consolidation or raises.
        """
        if not (math.isfinite(p0) and p0 > 0.0):
            raise ValueError(f"p0 must be positive and finite, got {p0}")
        working = self.law.mu
        saved = self.max_step_strain
        self.max_step_strain = float(max_step_strain)
        target = -float(p0) * np.eye(self.dim)  # shear stresses driven to zero too
        full = np.ones((self.dim, self.dim), bool)
        zero = np.zeros((self.dim, self.dim))
        self.servo_boosts = 0  # over both stages
        try:
            if friction is not None:  # a fragile frictionless packing: normal stresses
                self.set_friction(friction)
                try:
                    self._drive(zero, target, np.eye(self.dim, dtype=bool), progress)
                except PackingApart:
                    raise
                except RelaxationError as err:
                    log.warning("consolidation at friction %g did not settle, going on at "
                                "the law's: %s", friction, err)
                finally:
                    self.set_friction(working)
            return self._drive(zero, target, full, progress)
        finally:
            self.max_step_strain = saved

    def _load_gradient(self, deps):
        """Steps of the increment ``deps`` and the velocity gradient over them [1/s]:
        ``(I + dt L)^n_load = I + deps`` exactly, ``L`` from the matrix root."""
        d, dt = self.dim, self.sim.dt
        n_load = load_steps(deps, self.max_step_strain)
        if not n_load:
            return 0, np.zeros((d, d))
        return n_load, (matrix_root(np.eye(d) + deps, n_load) - np.eye(d)) / dt

    def _strain_drive(self, deps, relax, tangent):
        """Strain control in compiled loops: the increment in one run, then
        :meth:`dem.Simulation.relax` with this RVE's checks. The steps and the checks
        are those of :meth:`_drive` (a check after the increment, then one every
        :attr:`check_every` steps), and so is the state they leave, bit for bit."""
        sim, cell = self.sim, self.cell
        start = sim.step
        n_load, l_load = self._load_gradient(deps)
        if n_load:
            cell.lgrad[:] = l_load
            try:
                sim.run(n_load, progress=False)
            finally:
                cell.lgrad[:] = 0.0
            self.steps_run += n_load
            done = 0
            while done < n_load:  # the cell map composed as the chunked drive does
                chunk = min(self.check_every, n_load - done)
                self.deformation = cell_map(l_load, sim.dt, chunk) @ self.deformation
                done += chunk
        if relax:
            every = self.check_every
            rx = sim.relax(self.tol, -(-self.max_relax_steps // every) * every, every,
                           self.APART_COORDINATION, self.APART_CHECKS, progress=False)
            self.steps_run += rx.steps
            if rx.status != "relaxed":
                r = self.response(tangent=False)
                zero = np.zeros((self.dim, self.dim))
                if rx.status == "apart":
                    raise self._apart(r, self.APART_CHECKS)
                raise self._not_relaxed(r, zero, zero.astype(bool))
        r = self.response(tangent=tangent)
        self.last_relax_steps = sim.step - start
        self._last = r
        return r["stress"]

    def _apart(self, r, checks):
        """The error of a packing that came apart (``r``: its response)."""
        return PackingApart(
            f"the packing came apart: {r['n_contacts']} contacts among "
            f"{self.sim.bodies.n} particles (coordination "
            f"{r['coordination']:.2f}) {checks} checks after the strain "
            f"increment, mean stress {-np.trace(r['stress']) / self.dim:.4g} Pa; "
            f"it cannot relax (lower the strain increment)")

    def _not_relaxed(self, r, target, mask):
        """The error of a relaxation that reached its step cap."""
        return RelaxationError(
            f"RVE did not relax within {self.max_relax_steps} steps: unbalanced "
            f"force ratio {r['unbalanced']:.3g} (tolerance {self.tol:g}), stress "
            f"{np.round(r['stress'], 1).tolist()} Pa (targets "
            f"{target[mask].tolist()} on components "
            f"{[tuple(map(int, x)) for x in np.argwhere(mask)]}); lower the "
            f"strain increment, raise damping or max_relax_steps")

    def _drive(self, deps, target, mask, progress, relax=True):
        """Mixed control and progress reports: the drive of
        :func:`dem.rve_servo.drive`, its checks and servo compiled."""
        return drive(self, deps, target, mask, progress, relax)

    # ------------------------------------------------------------------ files
    def save(self, path, config=None, **attrs):
        """Write the RVE (state, law, settings) to an HDF5 file, atomically: a
        ``dem.checkpoint`` file (:func:`dem.io.save_checkpoint`) with an ``rve``
        group; ``config`` (the settings that made the packing, a str or JSON-able)
        becomes the file's ``config`` attribute, ``attrs`` the group's."""
        import json

        from .io.checkpoint import save_checkpoint

        def extra(f):
            g = f.create_group("rve")
            g.attrs["law"] = json.dumps(self.law.spec())
            for k in self._SETTINGS:
                g.attrs[k] = getattr(self, k)
            g.create_dataset("deformation", data=self.deformation)
            for k, v in attrs.items():
                g.attrs[k] = v

        return save_checkpoint(self.sim, path, extra=extra, config=config)

    @classmethod
    def load_file(cls, path, **overrides):
        """Read an RVE written by :meth:`save`; its law and settings come with it
        (``overrides`` replace settings, e.g. ``tol``)."""
        import json

        from .io.checkpoint import load_checkpoint, read_group

        g = read_group(path, "rve")
        try:
            law = law_from_spec(json.loads(g["attrs"]["law"]))
            opts = {k: g["attrs"][k] for k in cls._SETTINGS}
            deformation = g["data"]["deformation"]
        except (KeyError, ValueError, TypeError) as err:
            raise ValueError(f"{path}: malformed RVE file ({err})") from None
        sim = load_checkpoint(path, law)
        if sim.cell is None or np.asarray(deformation).shape != (sim.dim, sim.dim):
            raise ValueError(f"{path}: not a periodic-cell RVE")
        unknown = set(overrides) - set(cls._SETTINGS)
        if unknown:
            raise TypeError(f"unknown RVE settings: {', '.join(sorted(unknown))}")
        opts.update(overrides)
        rve = cls.__new__(cls)
        rve._setup(sim, law, deformation=np.array(deformation, np.float64), **opts)
        return rve


#: the contact geometry rows a sphere RVE passes (it has none)
_NO_GEOMETRY = np.zeros((0, 7))


def generate(dim, n, radius, law, p0, density=2650.0, fractions=None, seed=0,
             friction=None, solid_fraction=None, progress=None, shape=None,
             **rve_options):
    """A consolidated periodic packing, ready to load.

    Parameters
    ----------
    dim : 2 or 3
    n : int
        Number of particles.
    radius : float, (r_min, r_max) or radii
        Size distribution (see :func:`particle_radii`).
    law : Law
        The working contact law.
    p0 : float
        Consolidation pressure [Pa].
    density : float
        Particle density [kg/m^3] (per unit thickness in 2D).
    fractions : sequence, optional
        Solid-volume fractions of the size classes.
    seed : int
        The packing is a function of the seed (and the arguments): reproducible.
    friction : float, optional
        Friction during consolidation (default: the law's; 0 gives the densest).
    solid_fraction : float, optional
        Of the initial loose cloud (default 0.4 in 2D, 0.25 in 3D), counted with the
        particles' bounding radii.
    shape : callable, optional
        ``shape(r, rng)``: a polytope (``Box``, ``ConvexPolygon``, ``ConvexPolyhedron``)
        of bounding radius at most ``r`` [m], asked for each particle's radius with the
        packing's random generator; each goes in at a random orientation. Default:
        disks/spheres.
    **rve_options
        Passed to :class:`RVE`.

    Returns
    -------
    RVE
    """
    radii = particle_radii(n, radius, fractions, seed)
    check_particle_scales([float(radii.min()), float(radii.max())], density, dim)
    warn_contact_scale(law, p0, float(np.mean(radii)), dim)
    phi = solid_fraction or (0.4 if dim == 2 else 0.25)
    cell, pos = loose_cloud(dim, radii, phi, seed)
    if shape is None:
        bodies = Bodies.spheres(pos, radius=radii, density=density)
    else:
        bodies = shape_bodies(dim, pos, radii, shape, density, seed)
    rve = RVE(bodies, law, cell, **rve_options)
    t0 = time.perf_counter()
    rve.consolidate(p0, friction=friction, progress=progress)
    log.info("packing of %d particles consolidated to %.4g Pa in %d steps (%.1f s)",
             n, p0, rve.sim.step, time.perf_counter() - t0)
    return rve
