"""The relaxation settings every RVE boundary type shares (:class:`dem.rve.RVE` and
:class:`dem.rve_box.BoxRVE`): their checks, density scaling and storage; and the check
of a packing's contact stiffness against its pressure."""

import logging
import math

log = logging.getLogger("dem.rve")  # its warnings are about the packing dem.rve makes


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


def warn_contact_scale(law, p0, r, dim):
    """Log a warning when the contacts of ``law`` are too soft or too stiff for a
    packing of mean radius ``r`` [m] at ``p0`` [Pa]; returns the ratio judged.

    A linear law's ``kn / (p0 r^(d-2))`` should lie in [1e2, 1e5]. Another law (whose
    stiffness grows with the overlap, as Hertz's) is judged by its stiffness at its
    reference overlap (:meth:`Law.critical_stiffness`, 5 % of the radius for Hertz),
    and only for softness: below 1e2 its overlaps at ``p0`` pass that overlap (in 2D
    the forces are per metre of thickness, so a modulus that suits spheres is far too
    soft for disks)."""
    scale = p0 * r ** (dim - 2)
    kn = getattr(law, "kn", None)
    if kn is None:
        kappa = law.critical_stiffness(r) / scale
        if kappa < 1e2:
            log.warning("the contact stiffness at the reference overlap over p0 r^%d = %.3g "
                        "is below 1e2: overlaps will be large (soft contacts); a stiffer "
                        "material suits this p0", dim - 2, kappa)
        return kappa
    kappa = kn / scale  # contact stiffness against the confinement's force per contact
    if not 1e2 <= kappa <= 1e5:
        log.warning(
            "kn / (p0 r^%d) = %.3g is outside [1e2, 1e5]: %s", dim - 2, kappa,
            "overlaps will be large (soft contacts)" if kappa < 1e2 else
            "the relaxation will need very many steps (stiff contacts); about "
            f"{1e3 * scale:.3g} N/m suits this p0")
    return kappa
