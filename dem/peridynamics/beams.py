"""Bonded beams: Euler-Bernoulli beams between rigid bodies (paper section 5.5).

A beam ``k`` joins the centres of bodies ``i`` and ``j``. At the reference (bonding)
configuration it has length ``L0`` and an orthonormal frame: the axis ``a`` (from i to
j) and, in 3D, two section axes ``b`` (local y) and ``c`` (local z). The frame is stored
in each end body's own frame, so it turns with the body: ``a_i = R_i a_i^0`` and so on.
With ``e = (x_j - x_i) / L`` the current chord, the beam's energy is

    U = EA/(2 L0) (L - L0)^2
        + sum_{s = y, z} 2 E I_s / L0 (psi_is^2 + psi_is psi_js + psi_js^2)
        + GJ/(2 L0) tau^2,

    psi_i = e x a_i  (the end's bending rotation relative to the chord; a scalar in 2D)
    psi_iy = psi_i . b_i,  psi_iz = psi_i . c_i,  tau = (c_i . b_j - b_i . c_j) / 2.

Linearised about the reference this is exactly the Euler-Bernoulli element in the
co-rotated frame: axial ``EA/L``, shear ``12 EI/L^3``, coupling ``6 EI/L^2``, end
moments ``4 EI/L`` and ``2 EI/L``, torsion ``GJ/L``. Rotations are measured by their
sines, so the element is meant for small rotations of one beam relative to its chord
(large rigid motions of the whole beam are exact). ``U`` depends on dot and cross
products of vectors that turn with the bodies only, so it is objective, forces and
moments are its exact gradient, and they conserve linear and angular momentum.

In 2D (the x-y plane) a body's orientation is one angle, bending is about z with
``I_z`` and there is no torsion. The parameter table ``params`` (n_bonds, 5) holds
``(L0 [m], EA [N], E I_y [N m^2], E I_z [N m^2], G J [N m^2])`` per beam.

The compiled kernels are in :mod:`dem.peridynamics.beam_kernels`; this module holds the
beams' tables (:class:`BeamBonds`), their time loop with its relaxation
(:class:`BeamStructure`) and the cantilever that checks them against beam theory.
"""

import logging
import math

import numpy as np

from .beam_kernels import beam_forces_2d, beam_forces_3d, integrate_beams_2d, integrate_beams_3d

log = logging.getLogger(__name__)

#: default time step as a fraction of :meth:`BeamBonds.critical_time_step`
DT_FACTOR = 0.8


# ------------------------------------------------------------------ API
def _rotations(dim, rot):
    """Body-to-world rotation matrices (n, d, d) of ``Bodies.rot``."""
    if dim == 2:
        c, s = np.cos(rot[:, 0]), np.sin(rot[:, 0])
        return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
    w, x, y, z = rot.T
    rows = [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]
    return np.stack([np.stack(row, -1) for row in rows], -2)


def _per_bond(value, n_bonds, name, shape=()):
    out = np.broadcast_to(np.asarray(value, dtype=np.float64), (n_bonds, *shape)).copy()
    if not np.all(np.isfinite(out)) or not np.all(out > 0.0):
        raise ValueError(f"{name} must be positive and finite")
    return out


class BeamBonds:
    """Euler-Bernoulli beams between pairs of rigid bodies (see the module docstring).

    The configuration of ``bodies`` when the beams are made is their unstressed one.

    Parameters
    ----------
    bodies : dem.Bodies
        2D or 3D body table; its ``pos`` and ``rot`` give the reference configuration.
    pairs : (n_bonds, 2) array_like of int
        Body indices ``(i, j)`` of each beam, ``i != j``, at distinct positions.
    E : float or (n_bonds,) array_like
        Young's modulus [Pa].
    area : float or (n_bonds,) array_like
        Section area [m^2].
    moments : float or array_like
        Second moments of area [m^4]: in 2D ``I_z`` (bending in the plane), float or
        (n_bonds,); in 3D ``(I_y, I_z, J)``, (3,) or (n_bonds, 3), about the section
        axes ``b`` and ``c`` and the torsion constant ``J``.
    G : float or (n_bonds,) array_like, optional
        Shear modulus [Pa]; required in 3D (torsion ``G J / L``).
    up : (3,) or (n_bonds, 3) array_like, optional
        3D only: direction of the section axis ``b`` (local y), made perpendicular to
        the beam; default: the world axis most perpendicular to it.

    Examples
    --------
    >>> import dem
    >>> b = dem.Bodies.spheres([[0.0, 0.0], [0.1, 0.0]], radius=0.01, density=1000.0)
    >>> beams = BeamBonds(b, [[0, 1]], E=1e9, area=1e-4, moments=1e-9)
    >>> b.pos[1, 1] = 1e-4                      # tip moved sideways by 0.1 mm
    >>> force, torque, energy = beams.forces(b)
    >>> # -12 E I v / L^3 on the moved end, 6 E I v / L^2 on the other
    >>> round(float(force[1, 1]), 3), round(float(torque[0, 0]), 4)
    (-1.2, 0.06)
    """

    def __init__(self, bodies, pairs, E, area, moments, G=None, up=None):
        dim = bodies.dim
        pairs = np.atleast_2d(np.asarray(pairs))
        if pairs.ndim != 2 or pairs.shape[1] != 2 or not np.issubdtype(pairs.dtype,
                                                                         np.integer):
            raise ValueError(
                f"pairs must be an (n_bonds, 2) integer array, got {pairs.shape}")
        if pairs.size and (pairs.min() < 0 or pairs.max() >= bodies.n
                           or np.any(pairs[:, 0] == pairs[:, 1])):
            raise ValueError(
                f"pairs must join two different bodies of 0..{bodies.n - 1}")
        nb = pairs.shape[0]
        self.dim = dim
        self.pairs = np.ascontiguousarray(pairs, dtype=np.int32)
        r = bodies.pos[self.pairs[:, 1]] - bodies.pos[self.pairs[:, 0]]
        length = np.linalg.norm(r, axis=1)
        if not np.all(length > 0.0):
            raise ValueError("a beam joins two bodies at the same position")
        axis = r / length[:, None]
        E, area = _per_bond(E, nb, "E"), _per_bond(area, nb, "area")
        self.params = np.zeros((nb, 5))
        self.params[:, 0], self.params[:, 1] = length, E * area
        rots = _rotations(dim, bodies.rot)
        if dim == 2:
            self.params[:, 3] = E * _per_bond(moments, nb, "moments")
            world = axis[:, None, :]  # (nb, 1, 2): the axis only
        else:
            if G is None:
                raise ValueError("a 3D beam needs the shear modulus G (torsion)")
            mom = _per_bond(moments, nb, "moments", (3,))
            self.params[:, 2:4] = E[:, None] * mom[:, :2]
            self.params[:, 4] = _per_bond(G, nb, "G") * mom[:, 2]
            if up is None:
                up = np.eye(3)[np.argmin(np.abs(axis), axis=1)]
            up = np.broadcast_to(np.asarray(up, dtype=np.float64), (nb, 3))
            b = up - np.sum(up * axis, axis=1)[:, None] * axis
            norm = np.linalg.norm(b, axis=1)
            if not np.all(norm > 1e-8 * np.linalg.norm(up, axis=1)):
                raise ValueError("up must not be parallel to a beam")
            b /= norm[:, None]
            world = np.stack([axis, b, np.cross(axis, b)], axis=1)  # (nb, 3, 3) rows
        # v_body = R^T v_world, per end; rows of ``world`` are vectors
        frames = np.stack([np.einsum("kvw,kwc->kvc", world, rots[self.pairs[:, e]])
                           for e in (0, 1)], axis=1)
        self.frames = np.ascontiguousarray(frames[:, :, 0, :] if dim == 2 else frames)

    @property
    def n_bonds(self):
        return self.pairs.shape[0]

    def forces(self, bodies):
        """Beam forces ``(n, d)`` [N], moments ``(n, 1 or 3)`` [N m] (world frame) and
        energies ``(n_bonds,)`` [J] in the current configuration of ``bodies``."""
        force, torque = np.zeros_like(bodies.force), np.zeros_like(bodies.torque)
        energy = np.zeros(self.n_bonds)
        loop = beam_forces_2d if self.dim == 2 else beam_forces_3d
        loop(self.pairs, self.params, self.frames, bodies.pos, bodies.rot, force,
             torque, energy)
        return force, torque, energy

    def critical_time_step(self, bodies):
        """Velocity Verlet stability limit ``2 / omega_max`` [s].

        ``omega_max^2`` is bounded by Gershgorin's theorem on the mass-scaled stiffness
        of the linearised beams: per body and per degree of freedom, the sum over its
        beams of ``|K_rc| / sqrt(M_r M_c)`` in each beam's frame (axial ``EA/L``, shear
        ``12 EI/L^3``, coupling ``6 EI/L^2``, bending ``4 EI/L`` and ``2 EI/L``,
        torsion ``GJ/L``), with the smallest principal moment of inertia of a body for
        its rotations. Fixed bodies count as infinitely heavy. For a straight beam this
        is Gershgorin's bound itself, so the true limit is larger; for beams meeting at
        an angle it is an estimate of the same kind.
        """
        fixed = bodies.is_fixed
        mass = np.where(fixed, np.inf, bodies.mass)
        inertia = np.where(fixed, np.inf, bodies.inertia.min(axis=1))
        length, ea, eiy, eiz, gj = self.params.T
        rows_t, rows_r = np.zeros(bodies.n), np.zeros(bodies.n)
        i, j = self.pairs[:, 0], self.pairs[:, 1]
        bending = (eiz,) if self.dim == 2 else (eiy, eiz)
        for p, q in ((i, j), (j, i)):
            mp, mq, jp, jq = mass[p], mass[q], inertia[p], inertia[q]
            tt = 1.0 / mp + 1.0 / np.sqrt(mp * mq)
            tr = 1.0 / np.sqrt(mp * jp) + 1.0 / np.sqrt(mp * jq)
            rt = 1.0 / np.sqrt(jp * mp) + 1.0 / np.sqrt(jp * mq)
            trans = ea / length * tt
            turn = gj / length * (1.0 / jp + 1.0 / np.sqrt(jp * jq))
            for ei in bending:
                trans = np.maximum(trans, 12 * ei / length**3 * tt
                                   + 6 * ei / length**2 * tr)
                turn = np.maximum(turn, 4 * ei / length / jp + 2 * ei / length
                                  / np.sqrt(jp * jq) + 6 * ei / length**2 * rt)
            np.add.at(rows_t, p, trans)
            np.add.at(rows_r, p, turn)
        free = ~fixed
        omega2 = float(np.maximum(rows_t, rows_r)[free].max()) if free.any() else 0.0
        return 2.0 / math.sqrt(omega2) if omega2 > 0.0 else math.inf


class BeamStructure:
    """Bodies joined by :class:`BeamBonds`, advanced by velocity Verlet.

    One step of :meth:`run`, in this order: half kick of the free bodies with the last
    step's force and moment, Cundall-damped against their velocity; drift (``x += dt
    v``; the angle, or the quaternion by the exact exponential map, turned by ``ang_vel
    dt``); beam forces and moments; ``mass * accel`` added on free bodies; second half
    kick. Fixed bodies never move and keep the beam reaction as their force. In 3D the
    kicks act on the angular momentum and the drift keeps it, so a free structure
    conserves linear and angular momentum to round-off.

    Parameters
    ----------
    bodies : dem.Bodies
        Modified in place (``pos``, ``vel``, ``rot``, ``ang_vel``, ``force``,
        ``torque``); ``mass`` [kg], principal ``inertia`` [kg m^2] and ``is_fixed``
        are read.
    bonds : BeamBonds
    accel : (d,) array_like, optional
        Uniform body acceleration (gravity) [m/s^2] on free bodies.
    damping : float
        Cundall local damping coefficient in [0, 1), 0 for none.
    dt : float, optional
        Time step [s]; default ``DT_FACTOR * dt_crit``. A step above the critical step
        is refused unless ``allow_unstable_dt=True``.
    """

    def __init__(self, bodies, bonds, accel=None, damping=0.0, dt=None,
                 allow_unstable_dt=False):
        if bonds.dim != bodies.dim:
            raise ValueError(f"{bonds.dim}D beams on a {bodies.dim}D body table")
        free = ~bodies.is_fixed
        if not (np.all(bodies.mass[free] > 0.0) and np.all(bodies.inertia[free] > 0.0)
                and np.all(np.isfinite(bodies.mass[free]))
                and np.all(np.isfinite(bodies.inertia[free]))):
            raise ValueError("free bodies need positive, finite mass and inertia")
        self.bodies, self.bonds, self.dim = bodies, bonds, bodies.dim
        a = np.zeros(self.dim) if accel is None else np.asarray(accel, dtype=np.float64)
        if a.shape != (self.dim,) or not np.all(np.isfinite(a)):
            raise ValueError(f"accel must be {self.dim} finite components, got {a}")
        self.accel = a
        if not 0.0 <= damping < 1.0:
            raise ValueError(f"damping must be in [0, 1), got {damping}")
        self.damping = float(damping)
        self.dt_crit = bonds.critical_time_step(bodies)
        if dt is None:
            if not math.isfinite(self.dt_crit):
                raise ValueError("dt must be given for a structure without free beams")
            dt = DT_FACTOR * self.dt_crit
        dt = float(dt)
        if not (dt > 0.0 and math.isfinite(dt)):
            raise ValueError(f"dt must be positive and finite, got {dt}")
        if dt > self.dt_crit and not allow_unstable_dt:
            raise ValueError(
                f"dt = {dt:.4g} s exceeds the critical time step "
                f"{self.dt_crit:.4g} s of the stiffest beam on the lightest body; "
                f"pass allow_unstable_dt=True to run anyway")
        self.dt = dt
        self.step = 0
        self.energy = np.zeros(bonds.n_bonds)  # [J] per beam, at the last evaluation
        self._loop = integrate_beams_2d if self.dim == 2 else integrate_beams_3d
        self._forces = beam_forces_2d if self.dim == 2 else beam_forces_3d
        self._update_forces()

    def _update_forces(self):
        b, k = self.bodies, self.bonds
        self._forces(k.pairs, k.params, k.frames, b.pos, b.rot, b.force, b.torque,
                     self.energy)
        free = ~b.is_fixed
        b.force[free] += b.mass[free, None] * self.accel

    def run(self, n_steps):
        """Advance ``n_steps`` steps (see the class docstring for one step's order)."""
        b, k = self.bodies, self.bonds
        self._update_forces()  # the state may have been changed since the last run
        self._loop(int(n_steps), self.dt, self.accel, self.damping, k.pairs, k.params,
                   k.frames, b.pos, b.vel, b.rot, b.ang_vel, b.force, b.torque, b.mass,
                   b.inertia, b.is_fixed, self.energy)
        self.step += int(n_steps)
        if not (np.all(np.isfinite(b.pos)) and np.all(np.isfinite(b.rot))):
            raise FloatingPointError(
                f"the beam structure blew up by step {self.step} "
                f"(dt = {self.dt:.4g} s, dt_crit = {self.dt_crit:.4g} s)")

    def residual(self):
        """Unbalanced-force ratio of the free bodies: ``max |F| / max |m a|`` and
        ``max |M| / (max |m a| L_mean)`` (the larger), with ``F``, ``M`` the undamped
        totals of the last step and ``L_mean`` the mean beam length."""
        b = self.bodies
        free = ~b.is_fixed
        ref = float(np.max(b.mass[free], initial=0.0) * np.linalg.norm(self.accel))
        if ref == 0.0:
            raise ValueError("the residual needs a body acceleration on free bodies")
        arm = self.bonds.params[:, 0].mean()
        f = np.linalg.norm(b.force[free], axis=1).max() / ref
        m = np.linalg.norm(b.torque[free], axis=1).max() / (ref * arm)
        return float(max(f, m))

    def relax(self, tol=1e-6, max_steps=1_000_000, check_every=2000):
        """Run until :meth:`residual` falls below ``tol``; returns the steps run.

        Raises ``RuntimeError`` if it has not after ``max_steps`` steps.
        """
        start = self.step
        while self.step - start < max_steps:
            self.run(check_every)
            if self.residual() < tol:
                return self.step - start
        raise RuntimeError(f"no static equilibrium after {max_steps} steps: residual "
                           f"{self.residual():.3g} > {tol:g} (try more damping)")

    def kinetic_energy(self):
        """Translational plus rotational kinetic energy [J] of the free bodies."""
        b = self.bodies
        free = ~b.is_fixed
        e = 0.5 * np.sum(b.mass[free, None] * b.vel[free] ** 2)
        w = b.ang_vel[free]
        if self.dim == 3:
            rots = _rotations(3, b.rot[free])
            w = np.einsum("nji,nj->ni", rots, w)  # body frame
        return float(e + 0.5 * np.sum(b.inertia[free] * w**2))

    def momentum(self):
        """Linear momentum (d,) [kg m/s] and angular momentum about the origin
        ((1,) in 2D, (3,) in 3D) [kg m^2/s] of the free bodies."""
        b = self.bodies
        free = ~b.is_fixed
        m, x, v, w = b.mass[free], b.pos[free], b.vel[free], b.ang_vel[free]
        p = m[:, None] * v
        if self.dim == 2:
            spin = b.inertia[free, 0] * w[:, 0]
            return p.sum(axis=0), np.array([np.sum(x[:, 0] * p[:, 1] - x[:, 1] * p[:, 0]
                                                   + spin)])
        rots = _rotations(3, b.rot[free])
        wb = np.einsum("nji,nj->ni", rots, w)
        spin = np.einsum("nij,nj->ni", rots, b.inertia[free] * wb)
        return p.sum(axis=0), np.sum(np.cross(x, p) + spin, axis=0)


# ------------------------------------------------------------------ cantilever
def rectangle_torsion_constant(height, width):
    """Saint-Venant torsion constant [m^4] of a solid ``height x width`` rectangle
    (Roark's approximation, within 0.5 %)."""
    a, b = max(height, width), min(height, width)
    return a * b**3 * (1.0 / 3.0 - 0.21 * b / a * (1.0 - b**4 / (12.0 * a**4)))


def cantilever(dim, n, length, height, E, density, width=None, G=None, poisson=0.3):
    """A straight cantilever along +x clamped at x = 0: ``n`` bodies, ``n - 1`` beams.

    Body ``k`` sits at ``x = k l``, ``l = length / (n - 1)``, and is the rigid piece of
    beam it carries: length ``l``, or ``l / 2`` for the two end bodies, so the masses
    are the lumped masses of the beam and add up to ``density * length * area``. The
    section is ``height`` (along y in 2D, z in 3D) by ``width`` (out of the plane in
    2D, along y in 3D); ``I = width height^3 / 12`` resists a load along -y (2D) or
    -z (3D). Body 0 is fixed: the clamp.

    Parameters
    ----------
    dim : {2, 3}
    n : int, >= 2
    length, height : float [m]
    E : float [Pa]
    density : float [kg/m^3]
    width : float [m], optional; default ``height`` (a square section)
    G : float [Pa], optional; default ``E / (2 (1 + poisson))``

    Returns
    -------
    bodies : dem.Bodies
    bonds : BeamBonds
    """
    from ..shapes import Box
    from ..state import Bodies

    if dim not in (2, 3):
        raise ValueError(f"dimension must be 2 or 3, got {dim}")
    if int(n) < 2:
        raise ValueError(f"a cantilever needs at least 2 bodies, got {n}")
    n = int(n)
    width = height if width is None else width
    G = E / (2.0 * (1.0 + poisson)) if G is None else G
    seg = length / (n - 1)
    pos = np.zeros((n, dim))
    pos[:, 0] = np.arange(n) * seg
    bodies = Bodies.empty(dim)
    rho = density * width if dim == 2 else density  # 2D: mass per unit area
    for rows, piece in ((np.arange(1, n - 1), seg), (np.array([0, n - 1]), 0.5 * seg)):
        half = [0.5 * piece, 0.5 * height] if dim == 2 else [0.5 * piece, 0.5 * width,
                                                             0.5 * height]
        if rows.size:
            bodies.add_shapes(Box(half), pos[rows], density=rho)
    order = np.argsort(np.concatenate([np.arange(1, n - 1), [0, n - 1]]), kind="stable")
    for name in bodies.ARRAYS:  # put the bodies back in x order
        setattr(bodies, name, np.ascontiguousarray(getattr(bodies, name)[order]))
    bodies.fix([0])
    area = width * height
    i_y, i_z = width * height**3 / 12.0, height * width**3 / 12.0
    pairs = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1)
    if dim == 2:
        return bodies, BeamBonds(bodies, pairs, E=E, area=area, moments=i_y)
    moments = (i_y, i_z, rectangle_torsion_constant(height, width))
    return bodies, BeamBonds(bodies, pairs, E=E, area=area, moments=moments, G=G,
                             up=(0.0, 1.0, 0.0))


def cantilever_theory(length, height, E, density, accel, n=None):
    """Tip deflection [m] of a cantilever under its own weight ``q = rho A a``.

    ``w = q L^4 / (8 E I) = M a L^3 / (8 E I)`` (Euler-Bernoulli); for a rectangular
    section of ``height`` h along the load, ``I / A = h^2 / 12`` whatever its width.
    With ``n``, the exact tip deflection of the lumped model of :func:`cantilever`
    instead: its beams are exact for nodal loads, and lumping the load at the bodies
    adds the trapezoidal-rule error ``w (l / L)^2 / 3``, i.e. ``w (1 + 1 / (3 (n -
    1)^2))``. Lengths in m, E in Pa, density in kg/m^3, accel in m/s^2.

    >>> round(cantilever_theory(1.0, 0.05, 1e9, 1000.0, 1.0) * 1e3, 4)
    0.6
    """
    w = density * accel * length**4 * 12.0 / (8.0 * E * height**2)
    return w if n is None else w * (1.0 + 1.0 / (3.0 * (n - 1) ** 2))


def cantilever_deflection(dim, n, length, height, E, density, accel, width=None,
                          G=None, damping=0.7, tol=1e-6):
    """Static tip deflection [m] of :func:`cantilever` under a body acceleration
    ``accel`` [m/s^2] across it (along -y in 2D, -z in 3D), found by dynamic relaxation
    with Cundall damping. Returns ``(deflection, structure)``; the deflection is
    positive along the load."""
    bodies, bonds = cantilever(dim, n, length, height, E, density, width=width, G=G)
    a = np.zeros(dim)
    a[-1] = -accel
    sim = BeamStructure(bodies, bonds, accel=a, damping=damping)
    sim.relax(tol=tol)
    log.info("cantilever %dD n=%d E=%.3g: %d steps", dim, n, E, sim.step)
    return float(-bodies.pos[-1, -1]), sim
