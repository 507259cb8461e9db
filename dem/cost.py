"""The cost model: how long a run will take, from its work and measured rates.

The time of a DEM run is proportional to its particle-steps; the rate depends on the
dimension and on the particles' kind (spheres and disks, or level-set shapes). An RVE
call (one strain increment of a periodic cell) is its load steps, one per
``max_step_strain`` of strain, plus the steps of the relaxation that follows; a
generated RVE packing costs a consolidation. The rates are medians measured on one
core of the reference machine of ``docs/performance.md`` with warm kernels
(``benchmarks/rve_call.py``, ``benchmarks/dem_throughput.py``,
``benchmarks/shape_throughput.py``); ``benchmarks/cost_model.py`` compares the
estimates with real runs of the examples. Another machine scales them, and the
relaxation of a test depends on its packing: read an estimate as within a factor of
about three. The dry runs (``--dry-run``) print it.
"""

import logging
import math

log = logging.getLogger(__name__)

__all__ = ["SECONDS_PER_PARTICLE_STEP", "STEP_S", "RELAX_STEPS", "RELAX_SERVO_STEPS",
           "CONSOLIDATION_S", "CALLS_PER_STEP", "CALLS_PER_STEP_EXTRAPOLATED", "RVE_CALL_S",
           "STARTUP_S", "run_seconds", "rve_call_steps", "rve_seconds", "rve_test_seconds",
           "fe2_seconds", "duration", "time_line"]

#: seconds per particle-step on one core, by (kind, dimension): spheres and disks from
#: the periodic RVE calls of benchmarks/rve_call.py (400 disks, 1000 spheres) and the
#: 16,250-sphere scene of benchmarks/dem_throughput.py; shapes from the 5,000-body
#: scenes of benchmarks/shape_throughput.py
SECONDS_PER_PARTICLE_STEP = {("sphere", 2): 5.8e-8, ("sphere", 3): 1.3e-7,
                             ("shape", 2): 2.7e-6, ("shape", 3): 2.7e-5}

#: seconds of a time step of a periodic RVE besides its particles, by dimension: the
#: checks of the relaxation every 50 steps, the calls, the neighbour rebuilds
STEP_S = {2: 1.0e-5, 3: 1.0e-5}

#: steps of the relaxation after the load steps of a strain-controlled RVE call
#: (median of benchmarks/rve_call.py: 110 steps for a 1e-4 increment at 1e-5 a step)
RELAX_STEPS = 100

#: steps of the relaxation of an increment with a stress servo (a drained, isotropic
#: or simple shear test of ``hmm rve``): 4,400 to 6,000 in the examples of 60 and 200
#: disks
RELAX_SERVO_STEPS = 5000

#: seconds per particle to generate and consolidate an RVE packing, by dimension
#: (benchmarks/rve_call.py: 2.3 s for 400 disks, 10.4 s for 1000 spheres)
CONSOLIDATION_S = {2: 5.7e-3, 3: 1.04e-2}

#: RVE calls at each Gauss point in a load step of a multiscale run with DEM micro
#: models: its Newton iterations and the retries of its step cuts (16.8 in
#: examples/biaxial.toml: 73 iterations and 6 cuts in 8 steps, 134 farm trials)
CALLS_PER_STEP = 10

#: the same with ``predictor = "extrapolated"`` (the last step's displacements, scaled,
#: as the first guess): 2.03 in examples/triaxial_3d.toml (10,368 calls of 128 points in
#: 40 steps, 80 Newton iterations; benchmarks/triaxial_3d.py)
CALLS_PER_STEP_EXTRAPOLATED = 2

#: seconds of an RVE call besides its steps: restoring the state, the contact
#: tangent, the farm (examples/biaxial.toml: 2.5 ms a call of 60 disks, 1.5 ms of it
#: stepping)
RVE_CALL_S = 1.0e-3

#: seconds a command takes to start (imports, reading its input)
STARTUP_S = 2.0


def _rate(dim, shaped):
    return SECONDS_PER_PARTICLE_STEP[("shape" if shaped else "sphere", int(dim))]


def run_seconds(n_particles, n_steps, dim, shaped=False):
    """Seconds of ``n_steps`` steps of ``n_particles`` on one core.

    >>> round(run_seconds(16250, 2000, 3), 1)
    4.2
    """
    return n_particles * n_steps * _rate(dim, shaped)


def rve_call_steps(increment, max_step_strain, servo=False, relax=True):
    """Time steps of one RVE call: load steps for a strain ``increment`` at
    ``max_step_strain`` a step, plus :data:`RELAX_STEPS` (:data:`RELAX_SERVO_STEPS`
    with a stress servo); ``relax=False`` (a micro model's ``relax = false``, YADE
    FEMxDEM's call) stops at the load steps.

    >>> rve_call_steps(1e-4, 1e-5), rve_call_steps(1e-3, 1e-5, servo=True)
    (110, 5100)
    >>> rve_call_steps(1e-4, 1e-5, relax=False)
    10
    """
    load = math.ceil(abs(increment) / max_step_strain)
    if not relax:
        return load
    return load + (RELAX_SERVO_STEPS if servo else RELAX_STEPS)


def rve_seconds(n_particles, n_steps, dim, shaped=False):
    """Seconds of ``n_steps`` steps of one periodic RVE on one core, its per-step
    overhead :data:`STEP_S` included."""
    return n_steps * STEP_S[int(dim)] + run_seconds(n_particles, n_steps, dim, shaped)


def rve_test_seconds(n_particles, dim, n_increments, increment, max_step_strain,
                     servo=False, generated=True, shaped=False):
    """Seconds of a standalone RVE test (``hmm rve``) on one core: its consolidation
    if the packing is generated, then ``n_increments`` RVE calls."""
    steps = n_increments * rve_call_steps(increment, max_step_strain, servo)
    gen = n_particles * CONSOLIDATION_S[int(dim)] if generated else 0.0
    return gen + n_increments * RVE_CALL_S + rve_seconds(n_particles, steps, dim, shaped)


def fe2_seconds(n_particles, dim, n_points, n_load_steps, max_step_strain,
                increment=1e-4, generated=True, shaped=False, relax=True,
                predictor="tangent"):
    """Seconds of a multiscale run with DEM micro models on one core:
    :data:`CALLS_PER_STEP` RVE calls per Gauss point and load step
    (:data:`CALLS_PER_STEP_EXTRAPOLATED` with ``predictor="extrapolated"``), each of a
    strain ``increment`` (a typical macro strain increment, 1e-4 by default), relaxed
    unless ``relax=False``, and :data:`RVE_CALL_S` besides, and one consolidation if
    the packing is generated (the Gauss points take copies)."""
    per_step = CALLS_PER_STEP_EXTRAPOLATED if predictor == "extrapolated" else CALLS_PER_STEP
    calls = n_points * n_load_steps * per_step
    steps = calls * rve_call_steps(increment, max_step_strain, relax=relax)
    gen = n_particles * CONSOLIDATION_S[int(dim)] if generated else 0.0
    return gen + calls * RVE_CALL_S + rve_seconds(n_particles, steps, dim, shaped)


def duration(seconds):
    """A duration rounded for a person to read.

    >>> duration(42.0), duration(754.0), duration(4 * 3600.0), duration(3e6)
    ('42 s', '13 min', '4.0 h', '35 days')
    """
    s = float(seconds)
    if s < 1.0:
        return "under 1 s"
    if s < 99.5:
        return f"{s:.2g} s"
    if s < 5970.0:
        return f"{round(s / 60.0):d} min"
    if s < 2 * 86400.0:
        return f"{s / 3600.0:.1f} h"
    return f"{round(s / 86400.0):d} days"


def time_line(seconds, at_most=False):
    """The plan's time estimate of a run of ``seconds``, the command's start-up
    :data:`STARTUP_S` added, e.g. ``time about 13 min on one core (cost model, warm
    kernels)``; ``at_most`` for a bound. The estimate in seconds is logged (``-v``).

    >>> time_line(752.0)
    'time about 13 min on one core (cost model, warm kernels)'
    >>> time_line(5.0, at_most=True)
    'time at most 7 s on one core (cost model, warm kernels)'
    """
    seconds = seconds + STARTUP_S
    log.info("cost model: %.4g s on one core", seconds)
    text = duration(seconds)
    if not text.startswith("under"):  # "under 1 s" is a bound already
        text = ("at most " if at_most else "about ") + text
    return f"time {text} on one core (cost model, warm kernels)"
