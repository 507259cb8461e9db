"""Size limits checked before anything is allocated, and the range of derived values.

A file that asks for a billion particles, or a radius whose volume overflows, is
refused in one line that names the limit and how to raise it, before memory is
committed. Each :class:`Limit` has a default and an environment variable that raises
(or lowers) it for one run, e.g. ``DEM_MAX_PARTICLES=50000000 dem run big.toml``.

:data:`PARTICLES` is the limit of the particle engine (every generated packing: scene
files, RVE packings, :func:`dem.rve.generate`); :mod:`hmm` defines its own (elements,
load steps, test increments, experiments) with the same class. Parsed TOML files are
held to :data:`MAX_FILE_BYTES` and :data:`MAX_DEPTH` (:func:`dem.io.scene.read_toml`).

:func:`check_particle_scales` refuses radii and densities whose derived values (volume,
mass, moment of inertia) leave :data:`MAGNITUDE`, the range within which the products of
two of them stay finite and normal double-precision numbers.
"""

import math
import os
from dataclasses import dataclass

__all__ = ["BYTES_PER_PARTICLE", "BYTES_PER_RVE", "INT64_MAX", "MAGNITUDE", "MAX_DEPTH",
           "MAX_FILE_BYTES", "PARTICLES", "Limit", "LimitError", "check_particle_scales",
           "memory_estimate"]

#: the largest integer a key may hold (steps, counts, seeds are int64 in the engine)
INT64_MAX = 2**63 - 1
#: decimal exponents that derived values must stay within: products of two stay finite
MAGNITUDE = (-150, 150)
#: largest TOML input file [bytes] (scene, problem, RVE test, sweep)
MAX_FILE_BYTES = 16 * 2**20
#: deepest nesting of arrays and tables in a TOML input file
MAX_DEPTH = 32
#: memory of one particle of a run [bytes]: its row of the body table, its neighbour
#: and contact rows (measured: 0.7 kB in a 3D lattice scene of 2e3 to 2e5 spheres by
#: peak RSS, 0.93 kB in 2D RVEs of 60 to 600 disks by tracemalloc; rounded up)
BYTES_PER_PARTICLE = 1000
#: memory of one RVE besides its particles [bytes] (cell, settings, buffers; 20 kB
#: measured)
BYTES_PER_RVE = 20_000


class LimitError(ValueError):
    """A size beyond a :class:`Limit`, or a derived value out of range; one line."""


@dataclass(frozen=True)
class Limit:
    """The most ``unit`` a run may ask for: ``default``, or the integer in the
    environment variable ``env`` when that is set.

    >>> lim = Limit(100, "DEM_EXAMPLE_LIMIT", "particles")
    >>> lim.check(50, "count")
    >>> lim.check(500, "count")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    dem.limits.LimitError: count = 500 exceeds the limit of 100 particles; set the ...
    """

    default: int
    env: str
    unit: str

    def value(self):
        """The limit in force (read from the environment on every call)."""
        raw = os.environ.get(self.env)
        if raw is None or raw.strip() == "":
            return self.default
        try:
            value = int(float(raw.strip()))
        except (ValueError, OverflowError):
            value = 0
        if value < 1:
            raise LimitError(f"the environment variable {self.env} must be a positive "
                             f"integer ({self.unit}), got {raw!r}")
        return value

    def check(self, n, what):
        """Raise :class:`LimitError` if ``n`` (asked for by ``what``, e.g.
        ``"count"``) exceeds the limit."""
        limit = self.value()
        if n > limit:
            shown = f"{n:d}" if isinstance(n, int) and n < 10**12 else f"{float(n):.4g}"
            raise LimitError(f"{what} = {shown} exceeds the limit of {limit} {self.unit}; "
                             f"set the environment variable {self.env} to raise it")


#: particles of one generated packing (scene files, RVE packings, dem.rve.generate)
PARTICLES = Limit(10**7, "DEM_MAX_PARTICLES", "particles")


def check_particle_scales(radius, density, dim):
    """Refuse (:class:`LimitError`) particles whose volume, mass or moment of inertia
    falls outside ``10**MAGNITUDE``: a radius [m] of 1e300 overflows its volume, a
    density [kg/m^3] of 1e-300 underflows its mass and makes the time step meaningless.

    ``radius`` is a number or ``[min, max]``; both ends are checked.

    >>> check_particle_scales([1e-3, 2e-3], 2650.0, 3)
    >>> check_particle_scales(1e100, 2650.0, 3)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    dem.limits.LimitError: radius = 1e+100 m gives a particle volume of about 1e+301 m^3, ...
    """
    lo, hi = MAGNITUDE
    radii = radius if isinstance(radius, (list, tuple)) else [radius]
    if not (density > 0.0 and all(r > 0.0 for r in radii)):
        raise LimitError(f"radius = {radius} m and density = {density} kg/m^3 must be "
                         f"positive")
    log_rho = math.log10(density)
    for r in radii:
        log_r = math.log10(r)
        log_vol = math.log10(math.pi if dim == 2 else 4.0 * math.pi / 3.0) + dim * log_r
        log_mass = log_vol + log_rho
        log_inertia = log_mass + math.log10(0.5 if dim == 2 else 0.4) + 2.0 * log_r
        for name, unit, e, keys in (
                ("radius", "m", log_r, f"radius = {r:g} m"),
                ("volume", "m^3" if dim == 3 else "m^2", log_vol, f"radius = {r:g} m"),
                ("mass", "kg", log_mass, f"radius = {r:g} m and density = {density:g} "
                                         f"kg/m^3"),
                ("moment of inertia", "kg m^2", log_inertia,
                 f"radius = {r:g} m and density = {density:g} kg/m^3")):
            if not lo <= e <= hi:
                verb = "gives" if name in ("radius", "volume") else "give"
                what = "is" if name == "radius" else f"{verb} a particle {name} of about"
                shown = "" if name == "radius" else f" 1e{e:+.0f} {unit},"
                raise LimitError(f"{keys} {what}{shown} outside 1e{lo} to 1e+{hi} "
                                 f"(products of such numbers overflow); use SI units of a "
                                 f"real material")


def memory_estimate(n_particles, n_rves=0):
    """About how much memory the particle state of a run takes, in words: ``n_particles``
    in all, in ``n_rves`` RVEs (0: one scene). The process itself (Python, numba,
    compiled loops) adds about 0.2 to 0.3 GB.

    >>> memory_estimate(300)
    'about 300 kB for 300 particles'
    >>> memory_estimate(1920, 32)
    'about 2.6 MB for 1920 particles in 32 RVEs'
    """
    n_bytes = n_particles * BYTES_PER_PARTICLE + n_rves * BYTES_PER_RVE
    for unit, size in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n_bytes >= size:
            value = n_bytes / size
            shown = f"{value:.2g} {unit}" if value < 100 else f"{value:.0f} {unit}"
            break
    else:
        shown = f"{n_bytes} B"
    where = f" in {n_rves} RVEs" if n_rves else ""
    return f"about {shown} for {n_particles} particles{where}"
