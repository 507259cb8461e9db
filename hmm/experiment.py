"""The standalone RVE compression test: ``hmm rve rve.toml``.

A periodic packing (generated and consolidated, or read from a file) is brought
isotropically to the confining pressure, then compressed along its last axis (y in
2D, z in 3D) in equal increments of axial strain while a servo holds the lateral
stresses at the confining pressure: a drained biaxial test in 2D, a drained triaxial
test in 3D. After every increment the cell relaxes to quasi-static equilibrium
(:meth:`dem.rve.RVE.load`) and the state is recorded.

Conventions (soil mechanics, compression positive; the DEM stress itself is positive
in tension):

* axial strain ``eps_a = 1 - F_aa`` and volumetric strain ``eps_v = 1 - det F``
  (engineering strains, ``F`` the deformation gradient of the cell since the start of
  the compression): ``eps_v > 0`` is contraction, ``eps_v < 0`` dilation;
* principal stresses ``s1 >= s2 (>= s3)`` of ``-sigma``; 2D: ``p = (s1 + s2) / 2``,
  ``q = (s1 - s2) / 2``, mobilised friction ``sin phi = q / p``; 3D: ``p`` the mean
  stress, ``q = sqrt(3 J2)`` (``(s1 + 2 s3) / 3`` and ``s1 - s3`` when ``s2 = s3``),
  ``sin phi = 3 M / (6 + M)`` with ``M = q / p``;
* dilatancy ``sin psi = -d eps_v / (2 d eps_a - d eps_v)`` from logarithmic strain
  rates: in 2D ``-d eps_v / d gamma`` with ``gamma = eps_1 - eps_2``; in 3D the
  triaxial form of the Mohr-Coulomb flow rule. Positive ``psi`` is dilation.

The file format is :data:`RVE_SCHEMA` (validated by :func:`dem.io.scene.validate`);
``docs/rve.md`` holds its reference.
"""

import json
import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dem.io.scene import REQUIRED, Key, Range, SceneError, Section, read_toml, validate
from dem.io.scene import SCHEMA as SCENE_SCHEMA
from dem.io.text import fmt as _fmt
from dem.limits import PARTICLES, Limit, LimitError, check_particle_scales

log = logging.getLogger(__name__)

__all__ = ["RVE_SCHEMA", "SUMMARY_UNITS", "UNITS", "CompressionResult", "compress",
           "dilatancy_angle", "friction_angle", "load_config", "make_packing",
           "output_paths", "run_experiment", "stress_invariants", "validate_config"]

#: recorded increments of one test (each a relaxation of the packing)
INCREMENTS = Limit(10**6, "HMM_MAX_INCREMENTS", "increments")

#: the tests of ``[test] kind``
KINDS = ("drained", "undrained", "oedometric", "isotropic", "simple_shear", "cyclic")

_POSITIVE = Range(0.0, lo_closed=False)
_NONNEGATIVE = Range(0.0)

_CONTACT_KEYS = dict(SCENE_SCHEMA["contact"].keys)
_CONTACT_KEYS["kt"] = Key("float", "N/m", default=REQUIRED, range=_NONNEGATIVE,
                          only=("linear",),
                          doc="Tangential stiffness (friction acts through it).")

RVE_SCHEMA = {
    "packing": Section(doc="The periodic packing: generated and consolidated "
                           "isotropically, or read from a file.", required=True, keys={
        "dim": Key("int", default=2, choices=(2, 3),
                   doc="2: disks, biaxial test; 3: spheres, triaxial test."),
        "count": Key("int", range=Range(2.0),
                     doc="Number of particles; required unless file."),
        "radius": Key("radius", "m", range=_POSITIVE,
                      doc="Radius, or [min, max] for radii uniform in that range; "
                          "required unless file."),
        "density": Key("float", "kg/m^3", default=2650.0, range=_POSITIVE,
                       doc="Particle density (per unit thickness in 2D)."),
        "seed": Key("int", default=0, range=_NONNEGATIVE,
                    doc="Seed of the random packing (same seed, same packing)."),
        "p0": Key("float", "Pa", range=_POSITIVE,
                  doc="Isotropic consolidation pressure; required unless file."),
        "consolidation_friction": Key(
            "float", default=0.0, range=_NONNEGATIVE,
            doc="Friction coefficient while consolidating (0: densest packing); "
                "[contact] mu applies after."),
        "shape": Key("str", default="sphere", choices=("sphere", "polygon", "box"),
                     doc="Particle shape: sphere (a disk in 2D), polygon (2D: regular, "
                         "circumradius the radius) or box (a square or cube, "
                         "half-diagonal the radius); polygons and boxes at random "
                         "orientations from the seed."),
        "sides": Key("int", range=Range(3.0, 64.0),
                     doc="Corners of each polygon, or the fewest with sides_max; "
                         "shape = polygon only (default 6)."),
        "sides_max": Key("int", range=Range(3.0, 64.0),
                         doc="Optional: the most corners; each polygon draws its count "
                             "uniformly from sides to sides_max."),
        "file": Key("path", doc="Optional: a packing.h5 of an earlier run to start "
                                "from instead (it holds the law, size and p0)."),
    }),
    "contact": Section(doc="The contact law; required unless [packing] file (which "
                           "holds its law), and then an error.", variant="law",
                       keys=_CONTACT_KEYS),
    "test": Section(doc="The compression: axial strain in increments, the lateral "
                        "sides as `kind` says.", keys={
        "kind": Key("str", default="drained", choices=KINDS,
                    doc="drained: the lateral stress held at confining; undrained: "
                        "constant volume (saturated, no drainage, water and grains "
                        "far stiffer than the packing), the excess pore pressure read "
                        "from the stress path at a constant total lateral stress "
                        "(confining minus the lateral effective stress); oedometric: "
                        "no lateral strain (K0 compression); isotropic: the mean "
                        "stress up to p_max and back; simple_shear: shear strain at a "
                        "constant normal stress and no lateral strain; cyclic: "
                        "undrained axial strain cycles of amplitude axial_strain."),
        "p_max": Key("float", "Pa", range=_POSITIVE,
                     doc="isotropic: the largest mean stress (default 4 x confining)."),
        "steps": Key("int", default=10, range=Range(1.0),
                     doc="isotropic: stress increments each way (geometric)."),
        "cycles": Key("int", default=5, range=Range(1.0),
                      doc="cyclic: number of strain cycles."),
        "axial_strain": Key("float", default=0.1, range=Range(0.0, 0.5, False),
                            doc="Total axial compressive strain (engineering); "
                                "simple_shear: the total shear strain; cyclic: the "
                                "strain amplitude."),
        "increment": Key("float", default=1e-3, range=_POSITIVE,
                         doc="Axial strain per recorded increment."),
        "confining": Key("float", "Pa", range=_POSITIVE,
                         doc="Lateral (confining) pressure; default [packing] p0."),
        "damping": Key("float", default=0.5, range=Range(0.0, 1.0, hi_closed=False),
                       doc="Cundall local damping coefficient."),
        "tol": Key("float", default=1e-3, range=_POSITIVE,
                   doc="Unbalanced-force ratio that ends a relaxation "
                       "(consolidation included)."),
        "stress_tol": Key("float", default=1e-3, range=_POSITIVE,
                          doc="Relative tolerance of the lateral stress servo."),
        "max_step_strain": Key("float", default=1e-5, range=_POSITIVE,
                               doc="Largest strain of the cell in one time step."),
        "max_relax_steps": Key("int", default=200_000, range=Range(1.0),
                               doc="Step cap of one relaxation (then the test fails)."),
    }),
    "output": Section(doc="Files written by `hmm rve`.", keys={
        "dir": Key("str", doc="Output directory; default output/<file stem>."),
    }),
}

#: [packing] keys that describe a packing to generate (not used with ``file``)
_GENERATION_KEYS = ("dim", "count", "radius", "density", "seed", "p0",
                    "consolidation_friction", "shape", "sides", "sides_max")

#: written by a test: curves and summary, figure, and (generated packings) the packing
OUTPUTS = ("rve_test.h5", "rve_test.png", "packing.h5")


# --------------------------------------------------------------------------- input
def load_config(path):
    """Read and validate an RVE test file; returns as :func:`validate_config`.

    Raises :class:`~dem.io.scene.SceneError` (one line) for an unreadable file,
    invalid TOML or a value outside :data:`RVE_SCHEMA`.
    """
    path = Path(path)
    return validate_config(read_toml(path, "RVE test"), str(path), path.parent)


def validate_config(data, source="<rve>", base_dir="."):
    """Check parsed TOML ``data`` against :data:`RVE_SCHEMA`.

    Returns ``{section: {key: value}}`` with defaults filled, ``[packing] file``
    resolved against ``base_dir``, ``[output] dir`` defaulted to
    ``output/<source stem>`` and ``"source"``. Without ``file``, ``count``,
    ``radius`` and ``p0`` are required; with it, they and ``[contact]`` are errors.

    Examples
    --------
    >>> c = validate_config({"packing": {"count": 50, "radius": 1e-3, "p0": 1e5},
    ...                      "contact": {"law": "linear", "kn": 1e8, "kt": 5e7,
    ...                                  "mu": 0.5}}, "rve.toml")
    >>> c["test"]["confining"], c["output"]["dir"]
    (100000.0, 'output/rve')
    >>> validate_config({"packing": {"count": 50, "radius": 1e-3, "p0": -1}})
    Traceback (most recent call last):
    ...
    dem.io.scene.SceneError: <rve>: [packing] p0 must be > 0, got -1
    """
    packing = data.get("packing") if isinstance(data, dict) else None
    from_file = isinstance(packing, dict) and "file" in packing
    schema = RVE_SCHEMA
    if from_file:
        for key in _GENERATION_KEYS:
            if key in packing:
                raise SceneError(f"{source}: [packing] {key} is not used with file "
                                 f"(the packing, its size and law come from the file)")
        if "contact" in data:
            raise SceneError(f"{source}: [contact] is not used with [packing] file "
                             f"(the law is stored in the packing file)")
        schema = {k: v for k, v in RVE_SCHEMA.items() if k != "contact"}
    cfg, ctx = validate(data, schema, source, base_dir, dim=2)
    p, t = cfg["packing"], cfg["test"]
    if from_file:
        if Path(p["file"]).is_dir():
            ctx.fail(f"file {p['file']} is a directory, not a packing file", "[packing]")
        if not Path(p["file"]).is_file():
            ctx.fail(f"file {p['file']} does not exist", "[packing]")
        for key in _GENERATION_KEYS:
            p[key] = None
    else:
        _check_generated(ctx, p, t)
    _check_kind(ctx, data, t)
    if t["increment"] > t["axial_strain"]:
        ctx.fail(f"increment = {_fmt(t['increment'])} must not exceed axial_strain = "
                 f"{_fmt(t['axial_strain'])}", "[test]")
    try:
        INCREMENTS.check(n_increments(t), _increments_asked(t))
    except LimitError as exc:
        ctx.fail(str(exc), "[test]")
    if cfg["output"]["dir"] is None:
        stem = Path(source).stem.strip("<>") or "rve"
        cfg["output"]["dir"] = str(Path("output") / stem)
    return cfg


def _check_generated(ctx, p, t):
    """A packing to generate: its required keys, shape, size and particle scales."""
    for key, kind in (("count", "integer"), ("radius", "number or [min, max], m"),
                      ("p0", "number, Pa")):
        if p[key] is None:
            ctx.fail(f"missing required key '{key}' ({kind}; or give file)", "[packing]")
    if t["confining"] is None:
        t["confining"] = p["p0"]
    check_shape(ctx, p, p["dim"])
    try:
        PARTICLES.check(p["count"], "count")
        check_particle_scales(p["radius"], p["density"], p["dim"])
    except LimitError as exc:
        ctx.fail(str(exc), "[packing]")


def n_increments(t):
    """The number of increments a validated ``[test]`` records (computed without
    building them: a tiny ``increment`` must not allocate)."""
    if t["kind"] == "isotropic":
        return 2 * t["steps"]
    ratio = t["axial_strain"] / t["increment"]
    n = math.ceil(ratio - 1e-9) if ratio < 1e15 else ratio  # (may be inf)
    return 4 * n * t["cycles"] if t["kind"] == "cyclic" else n


def _increments_asked(t):
    """What sets the number of increments, in words, for a refusal."""
    if t["kind"] == "isotropic":
        return f"2 x steps = 2 x {t['steps']}"
    ratio = f"axial_strain / increment = {_fmt(t['axial_strain'])} / {_fmt(t['increment'])}"
    return f"4 x cycles x {ratio}" if t["kind"] == "cyclic" else ratio


def _check_kind(ctx, data, t):
    """The keys of one kind of test are not given to another; p_max exceeds the
    confining pressure."""
    raw_test = data.get("test") if isinstance(data.get("test"), dict) else {}
    for key, kind in (("p_max", "isotropic"), ("steps", "isotropic"),
                      ("cycles", "cyclic")):
        if key in raw_test and t["kind"] != kind:
            ctx.fail(f"{key} applies to kind = \"{kind}\", not \"{t['kind']}\"", "[test]")
    if t["kind"] == "isotropic" and t["p_max"] is not None and t["confining"] is not None \
            and t["p_max"] <= t["confining"]:
        ctx.fail(f"p_max = {_fmt(t['p_max'])} Pa must exceed the confining pressure "
                 f"{_fmt(t['confining'])} Pa", "[test]")


def check_shape(ctx, p, dim, where="[packing]"):
    """The shape keys ``shape``, ``sides``, ``sides_max`` of a section ``p`` agree with
    each other and with ``dim`` (``sides`` defaults to 6 for polygons)."""
    if p["shape"] != "polygon":
        for key in ("sides", "sides_max"):
            if p[key] is not None:
                ctx.fail(f"{key} is for shape = \"polygon\", not {p['shape']!r}", where)
        return
    if dim != 2:
        ctx.fail('shape = "polygon" needs dim = 2 (in 3D use "box")', where)
    if p["sides"] is None:
        p["sides"] = 6
    if p["sides_max"] is not None and p["sides_max"] < p["sides"]:
        ctx.fail(f"sides_max = {p['sides_max']} must be at least sides = {p['sides']}",
                 where)


def shape_maker(p, dim=None):
    """The ``shape(r, rng)`` of :func:`dem.rve.generate` for the validated shape keys
    of a section ``p`` (None for spheres); ``dim`` defaults to ``p["dim"]``."""
    from dem.shapes import Box, ConvexPolygon

    if p["shape"] == "sphere":
        return None
    if p["shape"] == "box":
        d = p["dim"] if dim is None else dim
        return lambda r, rng: Box([r / math.sqrt(d)] * d)
    lo = p["sides"]
    hi = lo if p["sides_max"] is None else p["sides_max"]
    return lambda r, rng: ConvexPolygon.regular(int(rng.integers(lo, hi + 1)), r)


def grains(bodies):
    """What the particles are, in words: disks, spheres, polygons, squares, ..."""
    from dem.shapes import Shape

    kinds = set(np.unique(bodies.kind).tolist())
    names = {Shape.SPHERE: ("disks", "spheres"), Shape.BOX: ("squares", "cubes"),
             Shape.POLYGON: ("polygons", "polygons"),
             Shape.POLYHEDRON: ("polyhedra", "polyhedra")}
    if len(kinds) == 1 and kinds <= set(names):
        return names[kinds.pop()][bodies.dim - 2]
    return "particles"


def _law(c):
    from dem import HertzMindlin, LinearSpring

    if c["law"] == "linear":
        return LinearSpring(kn=c["kn"], kt=c["kt"], mu=c["mu"], gamma_n=c["gamma_n"],
                            gamma_t=c["gamma_t"], restitution=c["restitution"])
    return HertzMindlin(young=c["young"], poisson=c["poisson"],
                        restitution=c["restitution"], mu=c["mu"])


def make_packing(cfg):
    """The packing of a validated config, ready for :func:`compress`.

    Returns ``(rve, confining, generated)``: the :class:`dem.rve.RVE`, generated and
    consolidated at ``[packing] p0`` [Pa] or read from ``[packing] file``; the
    confining pressure [Pa] of the test; whether the packing was generated. Raises
    :class:`~dem.io.scene.SceneError` (one line) for unusable input.
    """
    from dem import rve as rve_mod
    from dem.io.checkpoint import read_group

    p, t = cfg["packing"], cfg["test"]
    settings = {k: t[k] for k in ("tol", "stress_tol", "max_step_strain",
                                  "max_relax_steps")}
    where = f"{cfg['source']}: [packing]"
    if p["file"] is None:
        try:
            law = _law(cfg["contact"])
            rve = rve_mod.generate(p["dim"], p["count"], p["radius"], law, p["p0"],
                                   density=p["density"], seed=p["seed"],
                                   friction=p["consolidation_friction"],
                                   damping=t["damping"], shape=shape_maker(p),
                                   **settings)
        except ValueError as exc:
            raise SceneError(f"{where} {exc}") from None
        return rve, t["confining"], True
    try:
        rve = rve_mod.RVE.load_file(p["file"], **settings)
        stored = read_group(p["file"], "rve")["attrs"].get("p0")
    except (OSError, ValueError) as exc:
        raise SceneError(f"{where} cannot use file {p['file']}: {exc}") from None
    rve.sim.damping = t["damping"]
    confining = t["confining"] if t["confining"] is not None else stored
    if confining is None:
        raise SceneError(f"{cfg['source']}: [test] confining is required: "
                         f"{p['file']} does not record its consolidation pressure")
    return rve, float(confining), False


# --------------------------------------------------------------------------- measures
def stress_invariants(stress):
    """Mean stress ``p`` and deviator ``q`` [Pa], compression positive.

    Parameters
    ----------
    stress : (..., d, d) array_like
        Cauchy stress [Pa], tension positive (as the DEM reports it).

    Returns
    -------
    p, q : (...) ndarray
        2D: ``(s1 + s2) / 2`` and ``(s1 - s2) / 2``; 3D: ``(s1 + s2 + s3) / 3`` and
        ``sqrt(3 J2)``, with ``s_i`` the principal values of ``-stress``.

    Examples
    --------
    >>> p, q = stress_invariants([[-3.0, 0.0], [0.0, -1.0]])
    >>> float(p), float(q)
    (2.0, 1.0)
    >>> p, q = stress_invariants(np.diag([-1.0, -1.0, -4.0]))
    >>> float(p), float(q)
    (2.0, 3.0)
    """
    s = np.sort(np.linalg.eigvalsh(-np.asarray(stress, dtype=np.float64)), axis=-1)
    if s.shape[-1] == 2:
        return 0.5 * (s[..., 1] + s[..., 0]), 0.5 * (s[..., 1] - s[..., 0])
    p = s.mean(axis=-1)
    dev = s - p[..., None]
    return p, np.sqrt(1.5 * np.einsum("...i,...i->...", dev, dev))


def friction_angle(ratio, dim):
    """Mobilised friction angle [deg] of stress ratios ``q / p`` (see the module).

    >>> round(float(friction_angle(0.5, 2)), 6), round(float(friction_angle(1.2, 3)), 4)
    (30.0, 30.0)
    """
    ratio = np.asarray(ratio, dtype=np.float64)
    sin = ratio if dim == 2 else 3.0 * ratio / (6.0 + ratio)
    return np.degrees(np.arcsin(np.clip(sin, -1.0, 1.0)))


def dilatancy_angle(axial_strain, volumetric_strain):
    """Dilatancy angle [deg] of a stretch of the test, positive when dilating.

    ``sin psi = -d eps_v / (2 d eps_a - d eps_v)``, the slope ``d eps_v / d eps_a``
    of a straight line fitted to the logarithmic strains. Arguments are engineering
    strains (compression positive), (n,) with n >= 2; NaN for a shorter stretch.

    >>> round(dilatancy_angle([0.0, 1e-6], [0.0, -1e-6]), 2)   # sin psi = 1/3
    19.47
    >>> dilatancy_angle([0.0, 0.05], [0.0, 0.0])                # isochoric
    0.0
    """
    ea = -np.log1p(-np.asarray(axial_strain, dtype=np.float64))
    ev = -np.log1p(-np.asarray(volumetric_strain, dtype=np.float64))
    if ea.size < 2 or np.ptp(ea) == 0.0:
        return math.nan
    slope = np.polyfit(ea, ev, 1)[0]
    sin = np.clip(-slope / (2.0 - slope), -1.0, 1.0)
    return float(np.degrees(np.arcsin(sin))) + 0.0  # no "-0.0"


# --------------------------------------------------------------------------- the test
@dataclass
class CompressionResult:
    """Curves (one row per recorded state, row 0 the start) and summary of a test."""

    curves: dict
    summary: dict
    config: dict
    generated: bool
    files: list = field(default_factory=list)


def output_paths(cfg, out_dir=None):
    """The files a test of ``cfg`` writes, in ``out_dir`` (default ``[output] dir``)."""
    out = Path(cfg["output"]["dir"] if out_dir is None else out_dir)
    names = OUTPUTS if cfg["packing"]["file"] is None else OUTPUTS[:2]
    return [out / n for n in names]


def run_experiment(cfg, out_dir=None, overwrite=False, progress=None):
    """Build or load the packing, compress it, write the results.

    Parameters
    ----------
    cfg : dict
        A validated configuration (:func:`load_config`).
    out_dir : str or Path, optional
        Output directory (default ``[output] dir``); made if missing.
    overwrite : bool
        Replace existing output files (else FileExistsError before anything runs).
    progress : bool, optional
        A progress bar over the increments (default: when stderr is a terminal).

    Returns
    -------
    CompressionResult

    Raises
    ------
    SceneError
        Unusable packing parameters or packing file.
    FileExistsError
        An output file exists and ``overwrite`` is False.
    OSError
        An output is a directory, or the output directory cannot be made or
        written into (checked first).
    dem.rve.RelaxationError
        An increment did not relax; nothing is written.
    """
    from dem.simulation import progress_bar

    from dem.io.plan import check_new_files

    paths = output_paths(cfg, out_dir)
    # an existing output, a directory in its place, a directory that cannot be made:
    # refused before the test runs, not after
    check_new_files(paths, overwrite)
    t0 = time.perf_counter()
    packing = make_packing(cfg)
    rve, generated = packing[0], packing[2]
    consolidated = rve.snapshot() if generated else None
    bar = progress_bar(len(_increments(cfg["test"], 2, 1.0)), progress, min_steps=1,
                       unit="increment")
    shown = None if bar is None else (lambda k: bar.update(k - bar.n))  # bar at k
    try:
        result = compress(cfg, shown, packing)
    finally:
        if bar is not None:
            bar.close()
    result.summary["wall_time"] = time.perf_counter() - t0
    result.files = paths
    paths[0].parent.mkdir(parents=True, exist_ok=True)
    _write_h5(paths[0], result)
    _write_figure(paths[1], result)
    if generated:
        rve.restore(consolidated)
        p = cfg["packing"]
        rve.save(paths[2], config={"packing": p, "contact": cfg["contact"]},
                 p0=p["p0"], seed=p["seed"],
                 consolidation_friction=p["consolidation_friction"])
    return result


def compress(cfg, on_increment=None, packing=None):
    """Run the test of a validated config in memory; nothing is written.

    The packing is consolidated isotropically at the confining pressure, then
    compressed in increments of axial strain (see the module), as by
    :func:`run_experiment`, with the same results.

    Parameters
    ----------
    cfg : dict
        A validated configuration (:func:`load_config`).
    on_increment : callable, optional
        ``on_increment(k)`` is called with ``k = 0`` once the packing is consolidated
        at the confining pressure, then with ``k = 1, ..., n`` after increment ``k``.
        It may raise to abandon the test.
    packing : tuple, optional
        ``(rve, confining, generated)`` from :func:`make_packing` (default: made
        here). The RVE is left in the state at the end of the test.

    Returns
    -------
    CompressionResult
        Without ``files``; ``summary["wall_time"]`` [s] is the time of this call.

    Raises
    ------
    SceneError
        Unusable packing parameters or packing file.
    dem.rve.RelaxationError
        An increment did not relax.
    """
    t0 = time.perf_counter()
    rve, confining, generated = make_packing(cfg) if packing is None else packing
    rve.consolidate(confining)  # isotropic, at the working friction
    if on_increment is not None:
        on_increment(0)
    t = cfg["test"]
    curves = _curves(rve, confining, _increments(t, rve.dim, confining), on_increment,
                     t["kind"])
    summarize = {"drained": _summarize, "undrained": _summarize_undrained,
                 "oedometric": _summarize_oedometric, "isotropic": _summarize_isotropic,
                 "simple_shear": _summarize_shear, "cyclic": _summarize_cyclic}[t["kind"]]
    summary = summarize(curves, rve, confining, t["increment"])
    summary["kind"] = t["kind"]
    summary["wall_time"] = time.perf_counter() - t0
    return CompressionResult(curves, summary, cfg, generated)


def _targets(t):
    """The engineering axial strains at the end of the increments of ``[test]``."""
    n_inc = math.ceil(t["axial_strain"] / t["increment"] - 1e-9)
    return np.minimum(np.arange(1, n_inc + 1) * t["increment"], t["axial_strain"])


def _increments(t, d, confining):
    """What each increment of a ``[test]`` does: ``(kind, value)`` pairs, ``value``
    the engineering axial strain (drained, undrained, oedometric, cyclic), the shear
    strain (simple_shear) or the mean stress [Pa] (isotropic) at its end."""
    kind = t["kind"]
    if kind == "isotropic":
        top = t["p_max"] if t["p_max"] is not None else 4.0 * confining
        up = confining * (top / confining) ** (np.arange(1, t["steps"] + 1) / t["steps"])
        return [(kind, p) for p in np.concatenate([up, up[-2::-1], [confining]])]
    if kind == "cyclic":  # a triangle wave 0 -> A -> -A -> A ... -> 0
        amp, n = t["axial_strain"], math.ceil(t["axial_strain"] / t["increment"] - 1e-9)
        quarter = amp * np.arange(1, n + 1) / n
        cycle = np.concatenate([quarter, amp - quarter, -quarter, -amp + quarter])
        return [(kind, e) for e in np.tile(cycle, t["cycles"])]
    return [(kind, e) for e in _targets(t)]


def _curves(rve, confining, increments, on_increment, kind="drained"):
    """Run the ``increments`` (:func:`_increments`), the lateral sides held as
    ``kind`` says; the curves."""
    from dem.rve import PackingApart

    d = rve.dim
    axial = d - 1
    lateral_axes = np.arange(d) != axial
    f0_inv = np.linalg.inv(rve.deformation)
    rows = [_record(rve, rve.stress(), f0_inv, 0)]
    for k, (_, value) in enumerate(increments, 1):
        f_rel = rve.deformation @ f0_inv
        deps, target, mask = _increment(kind, value, f_rel, confining, d)
        try:
            stress = rve.load(deps, stress=target, mask=mask)
        except PackingApart:
            if kind not in ("undrained", "cyclic"):
                raise
            # liquefied: no effective stress left; the test ends at this state
            rows.append(_record(rve, rve.stress(), f0_inv, rve.last_relax_steps))
            break
        rows.append(_record(rve, stress, f0_inv, rve.last_relax_steps))
        if on_increment is not None:
            on_increment(k)
    curves = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    p, q = stress_invariants(curves["stress"])
    curves.update(p=p, q=q, stress_ratio=q / p,
                  friction_angle=friction_angle(q / p, d))
    sig = -curves["stress"]  # compression positive
    lat = np.mean([sig[:, i, i] for i in np.flatnonzero(lateral_axes)], axis=0)
    if kind in ("undrained", "cyclic"):  # the cell pressure holds the total lateral
        curves["excess_pore_pressure"] = confining - lat
    elif kind == "oedometric":
        curves["k0"] = lat / sig[:, axial, axial]
    elif kind == "simple_shear":
        curves["shear_strain"] = np.array([r["shear"] for r in rows])
        curves["shear_stress"] = curves["stress"][:, 0, axial]
        curves["normal_stress"] = sig[:, axial, axial]
        curves["normal_strain"] = curves["axial_strain"]
    curves.pop("shear")
    if kind == "cyclic":
        curves["amplitude"] = float(max(abs(v) for _, v in increments))
    return curves


def _increment(kind, value, f_rel, confining, d):
    """``(deps, stress target, mask)`` of one increment to ``value``."""
    axial = d - 1
    deps = np.zeros((d, d))
    if kind == "isotropic":
        return deps, np.full(d, -value), np.ones(d, bool)
    lateral = np.flatnonzero(np.arange(d) != axial)
    if kind == "simple_shear":  # shear x along the last axis, normal stress held
        deps[0, axial] = (value - f_rel[0, axial]) / f_rel[axial, axial]
        mask = np.zeros(d, bool)
        mask[axial] = True
        return deps, np.where(mask, -confining, 0.0), mask
    deps[axial, axial] = (1.0 - value) / f_rel[axial, axial] - 1.0
    if kind == "drained":
        return deps, np.full(d, -confining), np.arange(d) != axial
    # strain control: no lateral strain, or the lateral strain of no volume
    stretch = 1.0 if kind == "oedometric" else (1.0 - value) ** (-1.0 / (d - 1))
    for i in lateral:
        deps[i, i] = stretch / f_rel[i, i] - 1.0
    return deps, None, None


def _record(rve, stress, f0_inv, steps):
    r = rve.response(tangent=False)
    f_rel = rve.deformation @ f0_inv
    return {"axial_strain": 1.0 - f_rel[-1, -1], "shear": f_rel[0, -1],
            "volumetric_strain": 1.0 - np.linalg.det(f_rel),
            "stress": np.array(stress), "void_ratio": r["void_ratio"],
            "coordination": r["coordination"], "n_contacts": r["n_contacts"],
            "unbalanced": r["unbalanced"], "relax_steps": steps}


def _test_summary(c, rve, confining):
    """What every test's summary opens with: the packing and its start."""
    return {"dim": rve.dim, "n_particles": int(rve.bodies.n),
            "particles": grains(rve.bodies), "confining": confining,
            "initial_void_ratio": float(c["void_ratio"][0])}


def _summarize(c, rve, confining, increment):
    d = rve.dim
    ratio, ea, ev = c["stress_ratio"], c["axial_strain"], c["volumetric_strain"]
    k = int(np.argmax(ratio))
    near = np.abs(ea - ea[k]) <= max(0.01, 2.0 * increment) + 1e-12
    late = ea >= 0.8 * ea[-1] - 1e-12
    cs_ratio = float(ratio[late].mean())
    return {**_test_summary(c, rve, confining),
            "peak_stress_ratio": float(ratio[k]), "peak_axial_strain": float(ea[k]),
            "peak_friction_angle": float(friction_angle(ratio[k], d)),
            "dilatancy_angle": dilatancy_angle(ea[near], ev[near]),
            "critical_stress_ratio": cs_ratio,
            "critical_friction_angle": float(friction_angle(cs_ratio, d)),
            "critical_dilatancy_angle": dilatancy_angle(ea[late], ev[late]),
            "final_volumetric_strain": float(ev[-1]),
            "final_void_ratio": float(c["void_ratio"][-1])}


def _summarize_undrained(c, rve, confining, increment):
    """Peak deviator, phase transformation (the largest excess pore pressure before
    the end, where the packing turns from contraction to dilation; NaN when the
    pressure rises to the end or never rises), excess pore pressures and the
    softening after the peak (q at the end over the peak q; static liquefaction
    drives it towards 0)."""
    p, q, ea, u = c["p"], c["q"], c["axial_strain"], c["excess_pore_pressure"]
    k = int(np.argmax(q))
    m = int(np.argmax(u))
    turn = 0 < m < len(u) - 1
    # liquefied: the packing came apart (the test stopped), or its mean effective
    # stress fell below 1 % of the start
    liquefied = bool(p[-1] < 0.01 * p[0])
    nan = float("nan")
    return {**_test_summary(c, rve, confining),
            "peak_deviator": float(q[k]), "peak_axial_strain": float(ea[k]),
            "peak_mean_stress": float(p[k]),
            "phase_transformation_mean_stress": float(p[m]) if turn else nan,
            "phase_transformation_deviator": float(q[m]) if turn else nan,
            "phase_transformation_axial_strain": float(ea[m]) if turn else nan,
            "max_excess_pore_pressure": float(u.max()),
            "final_excess_pore_pressure": float(u[-1]),
            "final_mean_stress": float(p[-1]), "final_deviator": float(q[-1]),
            "softening": float(q[-1] / q[k]) if q[k] > 0.0 else nan,
            "final_friction_angle": float(c["friction_angle"][-1]),
            "liquefied": liquefied,
            "liquefaction_axial_strain": float(ea[-1]) if liquefied else nan,
            "final_axial_strain": float(ea[-1])}


def _summarize_oedometric(c, rve, confining, increment):
    """K0 (the mean over the second half of the increments, and at the end) and the
    constrained modulus of the last increment."""
    d = rve.dim
    sig_a = -c["stress"][:, d - 1, d - 1]
    half = c["k0"][1:][len(c["k0"][1:]) // 2:]
    ea = c["axial_strain"]
    return {**_test_summary(c, rve, confining),
            "k0": float(half.mean()), "final_k0": float(c["k0"][-1]),
            "final_axial_stress": float(sig_a[-1]),
            "constrained_modulus": float((sig_a[-1] - sig_a[-2]) / (ea[-1] - ea[-2])),
            "final_void_ratio": float(c["void_ratio"][-1])}


def _summarize_isotropic(c, rve, confining, increment):
    """Compression and swelling indices (slopes of e against ln p on the way up and
    down), the initial bulk modulus and the volumetric strain left after unloading."""
    p, e, ev = c["p"], c["void_ratio"], c["volumetric_strain"]
    top = int(np.argmax(p))
    up, down = slice(0, top + 1), slice(top, None)
    return {**_test_summary(c, rve, confining), "p_max": float(p[top]),
            "compression_index": float(-np.polyfit(np.log(p[up]), e[up], 1)[0]),
            "swelling_index": float(-np.polyfit(np.log(p[down]), e[down], 1)[0]),
            "bulk_modulus": float((p[1] - p[0]) / (ev[1] - ev[0])),
            "final_volumetric_strain": float(ev[-1]),
            "final_void_ratio": float(e[-1])}


def _summarize_shear(c, rve, confining, increment):
    """Peak and late (last 20 %) stress ratios tau / sigma_n with their friction
    angles, and the dilation angle at the peak (atan of -d eps_n / d gamma)."""
    g, tau, sn, en = (c["shear_strain"], c["shear_stress"], c["normal_stress"],
                      c["normal_strain"])
    ratio = np.divide(tau, sn, out=np.zeros_like(tau), where=sn > 0.0)
    k = int(np.argmax(ratio))
    near = np.abs(g - g[k]) <= max(0.01, 2.0 * increment) + 1e-12
    late = g >= 0.8 * g[-1] - 1e-12
    slope = np.polyfit(g[near], en[near], 1)[0] if near.sum() > 1 else float("nan")
    late_ratio = float(ratio[late].mean())
    return {**_test_summary(c, rve, confining),
            "peak_stress_ratio": float(ratio[k]), "peak_shear_strain": float(g[k]),
            "peak_friction_angle": float(np.degrees(np.arctan(ratio[k]))),
            "dilation_angle": float(np.degrees(np.arctan(-slope))),
            "critical_stress_ratio": late_ratio,
            "critical_friction_angle": float(np.degrees(np.arctan(late_ratio))),
            "final_normal_strain": float(en[-1]),
            "final_void_ratio": float(c["void_ratio"][-1])}


def _summarize_cyclic(c, rve, confining, increment):
    """Excess pore pressure ratios r_u = du / sigma'_0 and the cycles to liquefaction
    (p' below 1 % of the start, or the packing apart; NaN if it held)."""
    p, u, amp = c["p"], c["excess_pore_pressure"], c.pop("amplitude")
    per_cycle = 4 * math.ceil(amp / increment - 1e-9)
    liquefied = bool(p[-1] < 0.01 * p[0])
    done = (len(p) - 1) / per_cycle
    return {**_test_summary(c, rve, confining),
            "strain_amplitude": float(amp), "strain_increment": float(increment),
            "cycles_run": float(done),
            "liquefied": liquefied,
            "cycles_to_liquefaction": float(done) if liquefied else float("nan"),
            "max_pore_pressure_ratio": float(u.max() / confining),
            "final_pore_pressure_ratio": float(u[-1] / confining),
            "final_mean_stress": float(p[-1])}


# --------------------------------------------------------------------------- output
#: unit of each curve that has one (the others are dimensionless, unit "1")
UNITS = {"stress": "Pa", "p": "Pa", "q": "Pa", "friction_angle": "deg",
         "excess_pore_pressure": "Pa", "shear_stress": "Pa", "normal_stress": "Pa"}
#: the sign convention of each curve whose sign matters (geomechanics: strains,
#: ``p`` and the normal stress compression positive; the stress tensor tension
#: positive)
SIGNS = {"stress": "tension positive", "p": "compression positive",
         "q": "non-negative", "excess_pore_pressure": "compression positive",
         "shear_stress": "tension positive (the stress component)",
         "normal_stress": "compression positive",
         "axial_strain": "compression positive (shortening)",
         "normal_strain": "compression positive (shortening)",
         "volumetric_strain": "compression positive (contraction)"}
#: the format tag and version of ``rve_test.h5``
FORMAT, VERSION = "hmm.rve_test", 1


def curve_attrs(name):
    """The ``unit`` (and ``sign``) attributes of the curve ``name`` of an RVE test
    (``rve_test.h5``, ``batch.h5``)."""
    out = {"unit": UNITS.get(name, "1")}
    if name in SIGNS:
        out["sign"] = SIGNS[name]
    return out
#: unit of each summary value that has one
SUMMARY_UNITS = {"confining": "Pa", "peak_friction_angle": "deg",
                  "dilatancy_angle": "deg", "critical_friction_angle": "deg",
                  "critical_dilatancy_angle": "deg", "wall_time": "s",
                  "peak_deviator": "Pa", "peak_mean_stress": "Pa",
                  "phase_transformation_mean_stress": "Pa",
                  "phase_transformation_deviator": "Pa",
                  "max_excess_pore_pressure": "Pa", "final_excess_pore_pressure": "Pa",
                  "final_mean_stress": "Pa", "final_deviator": "Pa",
                  "final_friction_angle": "deg", "final_axial_stress": "Pa",
                  "constrained_modulus": "Pa"}


def _write_h5(path, result):
    from dem.io.files import write_h5_atomic
    from dem.io.meta import stamp

    def fill(f):
        for name, values in result.curves.items():
            f.create_dataset(name, data=values).attrs.update(curve_attrs(name))
        for name, value in result.summary.items():
            f.attrs[name] = value
        stamp(f, FORMAT, VERSION, result.config)
        f.attrs["units"] = json.dumps(SUMMARY_UNITS)
        f.attrs["config"] = json.dumps(result.config)
        f.attrs["conventions"] = ("compression positive for strains, p, q; stress "
                                  "dataset tension positive; engineering strains")

    write_h5_atomic(path, fill)


def _write_figure(path, result):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from dem.io.hdf5 import save_figure

    c, s = result.curves, result.summary
    if s.get("kind", "drained") != "drained":
        panels = {"undrained": _undrained_panels, "oedometric": _oedometric_panels,
                  "isotropic": _isotropic_panels, "simple_shear": _shear_panels,
                  "cyclic": _cyclic_panels}[s["kind"]]
        fig = Figure(figsize=(12.0, 3.6), layout="constrained")
        FigureCanvasAgg(fig)
        panels(fig.subplots(1, 3), c, s)
        test = "biaxial" if s["dim"] == 2 else "triaxial"
        what = {"undrained": f"undrained {test}", "oedometric": "oedometric",
                "isotropic": "isotropic compression and unloading",
                "simple_shear": "simple shear",
                "cyclic": f"cyclic undrained {test}"}[s["kind"]]
        fig.suptitle(f"{what} test, {s['n_particles']} {s['particles']}, from "
                     f"{s['confining']:.4g} Pa, e0 = {s['initial_void_ratio']:.3f}")
        save_figure(fig, path, dpi=120, data="rve_test.h5")
        return
    ea = 100.0 * c["axial_strain"]
    fig = Figure(figsize=(9.0, 3.6), layout="constrained")
    FigureCanvasAgg(fig)
    ax1, ax2 = fig.subplots(1, 2)
    ax1.plot(ea, c["stress_ratio"], "k-")
    ax1.plot([100.0 * s["peak_axial_strain"]], [s["peak_stress_ratio"]], "ro",
             label=f"peak, φ = {s['peak_friction_angle']:.1f}°")
    ax1.axhline(s["critical_stress_ratio"], color="b", ls="--",
                label=f"last 20 %, φ = {s['critical_friction_angle']:.1f}°")
    ax1.set(xlabel="axial strain [%]", ylabel="stress ratio q/p")
    ax1.legend(loc="lower right")
    ax2.plot(ea, 100.0 * c["volumetric_strain"], "k-")
    ax2.axhline(0.0, color="0.6", lw=0.8)
    ax2.set(xlabel="axial strain [%]",
            ylabel="volumetric strain [%] (contraction > 0)")
    test = "biaxial" if s["dim"] == 2 else "triaxial"
    fig.suptitle(f"drained {test} test, {s['n_particles']} {s['particles']}, confining "
                 f"{s['confining']:.4g} Pa, e0 = {s['initial_void_ratio']:.3f}")
    save_figure(fig, path, dpi=120, data="rve_test.h5")


def _undrained_panels(axs, c, s):
    ea = 100.0 * c["axial_strain"]
    axs[0].plot(ea, 1e-3 * c["q"], "k-")
    axs[0].set(xlabel="axial strain [%]", ylabel="deviator q [kPa]")
    axs[1].plot(1e-3 * c["p"], 1e-3 * c["q"], "k-", label="effective stress path")
    if np.isfinite(s["phase_transformation_mean_stress"]):
        axs[1].plot([1e-3 * s["phase_transformation_mean_stress"]],
                    [1e-3 * s["phase_transformation_deviator"]], "bs",
                    label="phase transformation")
    axs[1].plot([1e-3 * s["peak_mean_stress"]], [1e-3 * s["peak_deviator"]], "ro",
                label="peak q")
    axs[1].set(xlabel="mean effective stress p' [kPa]", ylabel="deviator q [kPa]")
    axs[1].legend(loc="best", fontsize=8)
    axs[2].plot(ea, 1e-3 * c["excess_pore_pressure"], "k-")
    axs[2].axhline(0.0, color="0.6", lw=0.8)
    axs[2].set(xlabel="axial strain [%]", ylabel="excess pore pressure [kPa]")
    for ax in axs:
        ax.grid(alpha=0.3)


def _oedometric_panels(axs, c, s):
    ea = 100.0 * c["axial_strain"]
    d = s["dim"]
    sig_a = -c["stress"][:, d - 1, d - 1]
    axs[0].plot(ea, 1e-3 * sig_a, "k-")
    axs[0].set(xlabel="axial strain [%]", ylabel="axial effective stress [kPa]")
    axs[1].semilogx(1e-3 * sig_a, c["void_ratio"], "k-")
    axs[1].set(xlabel="axial effective stress [kPa]", ylabel="void ratio e")
    axs[2].plot(ea[1:], c["k0"][1:], "k-")
    axs[2].axhline(s["k0"], color="b", ls="--", label=f"K0 = {s['k0']:.3f}")
    axs[2].set(xlabel="axial strain [%]", ylabel="K0 = lateral / axial stress")
    axs[2].legend(loc="best", fontsize=8)
    for ax in axs:
        ax.grid(alpha=0.3)


def _isotropic_panels(axs, c, s):
    p = 1e-3 * c["p"]
    axs[0].semilogx(p, c["void_ratio"], "ko-", ms=3)
    axs[0].set(xlabel="mean stress p [kPa]", ylabel="void ratio e",
               title=f"λ = {s['compression_index']:.2e}, κ = {s['swelling_index']:.2e}")
    axs[1].plot(p, 100.0 * c["volumetric_strain"], "ko-", ms=3)
    axs[1].set(xlabel="mean stress p [kPa]",
               ylabel="volumetric strain [%] (contraction > 0)")
    axs[2].plot(np.arange(len(p)), p, "ko-", ms=3)
    axs[2].set(xlabel="increment", ylabel="mean stress p [kPa]")
    for ax in axs:
        ax.grid(alpha=0.3)


def _shear_panels(axs, c, s):
    g = 100.0 * c["shear_strain"]
    sn = np.where(c["normal_stress"] > 0.0, c["normal_stress"], np.nan)
    axs[0].plot(g, c["shear_stress"] / sn, "k-")
    axs[0].set(xlabel="shear strain γ [%]", ylabel="τ / σ_n",
               title=f"peak φ = {s['peak_friction_angle']:.1f}°")
    axs[1].plot(g, 100.0 * c["normal_strain"], "k-")
    axs[1].axhline(0.0, color="0.6", lw=0.8)
    axs[1].set(xlabel="shear strain γ [%]",
               ylabel="normal strain [%] (contraction > 0)")
    axs[2].plot(g, c["void_ratio"], "k-")
    axs[2].set(xlabel="shear strain γ [%]", ylabel="void ratio e")
    for ax in axs:
        ax.grid(alpha=0.3)


def _cyclic_panels(axs, c, s):
    ea = 100.0 * c["axial_strain"]
    axs[0].plot(ea, 1e-3 * c["q"] * np.sign(c["stress"][:, 0, 0] - c["stress"][:, -1, -1]),
                "k-", lw=0.8)
    axs[0].set(xlabel="axial strain [%]", ylabel="deviator [kPa] (compression > 0)")
    axs[1].plot(1e-3 * c["p"], 1e-3 * c["q"], "k-", lw=0.8)
    axs[1].set(xlabel="mean effective stress p' [kPa]", ylabel="q [kPa]")
    per_cycle = 4 * math.ceil(s["strain_amplitude"] / s["strain_increment"] - 1e-9)
    n = np.arange(len(ea)) / per_cycle
    axs[2].plot(n, c["excess_pore_pressure"] / s["confining"], "k-")
    axs[2].set(xlabel="cycles", ylabel="r_u = excess pore pressure / σ'_0")
    for ax in axs:
        ax.grid(alpha=0.3)
