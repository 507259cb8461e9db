"""The relaxation settings every RVE boundary type shares (:class:`dem.rve.RVE` and
:class:`dem.rve_box.BoxRVE`): their checks, density scaling and storage."""

import math


def check_settings(mass_scale, max_step_strain, tol, stress_tol, max_relax_steps,
                   check_every):
    """Refuse RVE settings that are not physical (shared by every boundary type)."""
    for name, v in (("max_step_strain", max_step_strain), ("tol", tol),
                    ("stress_tol", stress_tol), ("mass_scale", mass_scale)):
        if not (math.isfinite(v) and v > 0.0):
            raise ValueError(f"{name} must be positive and finite, got {v}")
    if mass_scale < 1.0:
        raise ValueError(f"mass_scale must be >= 1, got {mass_scale}")
    if int(max_relax_steps) < 1 or int(check_every) < 1:
        raise ValueError("max_relax_steps and check_every must be >= 1")


def scale_masses(bodies, mass_scale):
    """Density scaling: masses, inertias and densities times ``mass_scale``."""
    if mass_scale != 1.0:
        bodies.mass *= mass_scale
        bodies.inertia *= mass_scale
        bodies.density *= mass_scale


def store_settings(rve, mass_scale, max_step_strain, tol, stress_tol, max_relax_steps,
                   check_every):
    """Set the relaxation settings on ``rve`` (the names of ``RVE._SETTINGS``)."""
    rve.mass_scale = float(mass_scale)
    rve.max_step_strain = float(max_step_strain)
    rve.tol = float(tol)
    rve.stress_tol = float(stress_tol)
    rve.max_relax_steps = int(max_relax_steps)
    rve.check_every = int(check_every)
