"""Time steps of explicit DEM: the two-body critical step, the stability limit of a
close packing per family of contact modes, and the reductions for dashpots and local
damping (docs/stability.md)."""

import math

import numpy as np

from .contact.model import ContactModel
from .shapes import Shape

#: default time step as a fraction of the critical step, from the speed-accuracy chart
#: (docs/performance.md): the largest factor whose binary-collision errors, averaged
#: over where in a step contacts start, stay below 1% (about 22 steps per contact)
DT_FACTOR = 0.07
#: steps above this fraction of a close packing's stability limit
#: (:func:`packing_stability` x the two-body critical step) are refused
STABLE_FACTOR = 0.9


#: a close-packed assembly's highest frequency over the two-body one: 1 / the
#: measured blow-up factor 0.5 of normal springs (docs/stability.md). Its dashpots add
#: up as its springs do, so its damping ratio is this multiple of the two-body one too
PACKING_FREQUENCY_RATIO = 2.0
#: the same ratio per family of contact modes and dimension. Normal springs: 2 (fcc
#: spheres; the hexagonal disks' sqrt(3) is taken as 2 too). Tangential springs with
#: their rotational coupling: every body spinning the same way about one axis slips all
#: its contacts at once, sqrt(40/7) in 3D (fcc: 16 kt r^2 against I = 0.4 m r^2, where
#: the pair has 7 kt / m) and 2 in 2D (hexagonal: 12 kt r^2 against 0.5 m r^2 and
#: 6 kt / m); the lattices' stiffness matrices give the same (tests/test_stability.py)
#: Rolling springs (:mod:`dem.contact.rolling`) act on relative rotations only: a body
#: turning against all its z neighbours loads z springs at twice the pair's rate,
#: sqrt(z) times the pair's frequency at most (z = 12 fcc, 6 hexagonal)
PACKING_RATIOS = {"normal": {2: PACKING_FREQUENCY_RATIO, 3: PACKING_FREQUENCY_RATIO},
                  "tangential": {2: 2.0, 3: math.sqrt(40.0 / 7.0)},
                  "rolling": {2: math.sqrt(6.0), 3: math.sqrt(12.0)}}


def damped_stability(zeta, local_damping=0.0):
    """The reduction of an RVE's default step (:func:`quasi_static_dt`) for
    contact damping ratio ``zeta`` and Cundall local damping ``local_damping``.

    Explicit dashpots (velocity Verlet with the half-step velocity) are stable for
    ``omega dt < 2 (sqrt(1 + z^2) - z)``; here ``z`` =
    :data:`PACKING_FREQUENCY_RATIO` x ``zeta``, and local damping divides by
    ``sqrt(1 + a)``. 1 with neither. (The refusal threshold of a step is
    :func:`packing_stability`, which also raises ``z`` by ``sqrt(1 + a)`` and tells
    the families of modes apart.)

    >>> round(damped_stability(0.0), 2), round(damped_stability(0.73), 2)
    (1.0, 0.31)
    >>> round(damped_stability(0.0, local_damping=0.5), 3)
    0.816
    """
    z = PACKING_FREQUENCY_RATIO * zeta
    return (math.sqrt(1.0 + z * z) - z) / math.sqrt(1.0 + local_damping)


def packing_stability(modes, dim, local_damping=0.0):
    """Stability limit of a close packing, as a fraction of the two-body critical step
    ``sqrt(2 m_min / k_max)``.

    ``modes`` are ``(family, k, zeta)`` (:meth:`dem.ContactModel.modes`). A family's
    fastest packing mode has :data:`PACKING_RATIOS` ``R`` times the two-body frequency
    (``2 sqrt(k / k_max)`` over the critical step) and damping ratio. Explicit dashpots
    (velocity Verlet with the half-step velocity) are stable for ``omega dt < 2
    (sqrt(1 + z^2) - z)``. Cundall local damping ``a`` scales the force, spring and
    dashpot alike, by up to ``1 + a`` while it opposes the velocity: ``omega`` and
    ``z`` grow by ``sqrt(1 + a)``. The limit is the smallest over the modes.

    >>> round(packing_stability([("normal", 1.0, 0.0)], 3), 3)
    0.5
    >>> round(packing_stability([("normal", 1.0, 0.0), ("tangential", 1.0, 0.0)], 3), 3)
    0.418
    """
    k_max = max(k for _, k, _ in modes)
    scale = math.sqrt(1.0 + local_damping)
    limit = math.inf
    for family, k, zeta in modes:
        if k <= 0.0:
            continue
        ratio = PACKING_RATIOS[family][dim]
        z = ratio * zeta * scale
        limit = min(limit, (math.sqrt(1.0 + z * z) - z)
                    / (ratio * scale * math.sqrt(k / k_max)))
    return limit


def stable_time_step(bodies, model, local_damping=0.0):
    """The largest step a scene accepts, ``STABLE_FACTOR`` x :func:`packing_stability`
    x ``dt_crit`` [s] (infinite without free bodies). Returns ``(dt_stable, fraction,
    dt_crit, m_min, k_max)``, ``fraction`` the close packing's limit over ``dt_crit``."""
    dt_crit, m_min, k_max = critical_time_step(bodies, model)
    if not math.isfinite(dt_crit):
        return math.inf, 0.5, dt_crit, m_min, k_max
    fraction = packing_stability(model.modes(bodies, m_min), bodies.dim, local_damping)
    return STABLE_FACTOR * fraction * dt_crit, fraction, dt_crit, m_min, k_max


def critical_time_step(bodies, model):
    """Critical time step [s] from the lightest body and the stiffest contact.

    ``dt_crit = sqrt(2 m_min / k_max)``: the velocity Verlet stability limit
    (``dt < 2 / omega``) of two of the lightest bodies joined by the stiffest spring,
    where a tangential spring counts with its rotational coupling ``1 + m r^2 / I``.
    For non-spherical bodies the normal spring acts off-centre too: both count with
    ``1 + m r^2 / I_min`` (``r`` the bounding radius), the largest over the bodies.
    Returns ``(dt_crit, m_min, k_max)``.
    """
    if not isinstance(model, ContactModel):
        model = ContactModel(model)
    free = (~bodies.is_fixed) & (bodies.kind != Shape.PLANE)
    if not free.any():
        return math.inf, math.inf, 0.0
    m_min = float(bodies.mass[free].min())
    k_max = model.max_stiffness(bodies)
    shaped = free & (bodies.kind != Shape.SPHERE)
    if shaped.any():
        arm = bodies.mass[shaped] * bodies.radius[shaped] ** 2
        k_max *= 1.0 + float(np.max(arm / bodies.inertia[shaped].min(axis=1)))
    return math.sqrt(2.0 * m_min / k_max), m_min, k_max


#: default time step of an RVE as a fraction of the critical step, before the
#: reductions for dashpots and local damping (:func:`quasi_static_dt`). A quasi-static
#: cell needs no resolved collisions (the engine's DT_FACTOR of 0.07 is set by binary
#: impacts); its relaxation takes a fixed physical time, so its steps shrink with a
#: larger dt, and a strain cap per step is then a slower load in units of the
#: packing's own response time (benchmarks/rve_size_accuracy.py, docs/performance.md).
#: The worst case is a close packing: hexagonal close packed spheres under the default
#: local damping of 0.5 stop relaxing from 0.4 x dt_crit without dashpots and from 0.09
#: x with the paper's viscoelastic ones (benchmarks/rve_step_limit.py, on the box of
#: examples/ex05_box_vs_periodic.py; docs/stability.md); 0.25 x the reductions gives
#: 0.20 and 0.063 there
QUASI_STATIC_FACTOR = 0.25


def quasi_static_dt(bodies, model, dt=None, damping=0.0):
    """``dt`` [s], or by default ``QUASI_STATIC_FACTOR`` x the critical step of the scene, times
    :func:`~dem.timestep.damped_stability` of its most damped contact mode and the
    local damping ``damping``."""
    if dt is not None:
        return dt
    if not isinstance(model, ContactModel):
        model = ContactModel(model)
    dt_crit, m_min, _ = critical_time_step(bodies, model)
    zeta = model.max_damping_ratio(bodies, m_min)
    return QUASI_STATIC_FACTOR * damped_stability(zeta, damping) * dt_crit
