"""The configuration of an RVE test (``hmm rve``): its schema and validation.

:data:`RVE_SCHEMA` is the file format (validated by :func:`dem.io.scene.validate`;
``docs/rve.md`` holds its reference); :func:`load_config` and :func:`validate_config`
read and check a file; :func:`check_shape` and :func:`shape_maker` serve the packing
keys of an RVE test and of a problem file's ``[micro]`` alike.
"""

import math
from pathlib import Path

from dem.io.schema import REQUIRED, Key, Range, SceneError, Section, read_toml, validate
from dem.io.scene import SCHEMA as SCENE_SCHEMA
from dem.io.text import fmt as _fmt
from dem.shapes.registry import packing_shapes
from dem.limits import PARTICLES, Limit, LimitError, check_particle_scales

__all__ = ["INCREMENTS", "KINDS", "RVE_SCHEMA", "check_shape", "load_config",
           "n_increments", "shape_maker", "validate_config"]

#: recorded increments of one test (each a relaxation of the packing)
INCREMENTS = Limit(10**6, "HMM_MAX_INCREMENTS", "increments")

#: the tests of ``[test] kind``
KINDS = ("drained", "undrained", "oedometric", "isotropic", "simple_shear", "cyclic")

_POSITIVE = Range(0.0, lo_closed=False)
_NONNEGATIVE = Range(0.0)

_CONTACT_KEYS = dict(SCENE_SCHEMA["contact"].keys)
del _CONTACT_KEYS["pair"]  # an RVE has one group of particles and one law
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
        "shape": Key("str", default="sphere", choices=tuple(packing_shapes()),
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
    dem.io.schema.SceneError: <rve>: [packing] p0 must be > 0, got -1
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
        _check_generated(ctx, p, t, cfg["contact"])
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


def _check_generated(ctx, p, t, contact):
    """A packing to generate: its required keys, shape, size and particle scales."""
    for key, kind in (("count", "integer"), ("radius", "number or [min, max], m"),
                      ("p0", "number, Pa")):
        if p[key] is None:
            ctx.fail(f"missing required key '{key}' ({kind}; or give file)", "[packing]")
    if t["confining"] is None:
        t["confining"] = p["p0"]
    check_shape(ctx, p, p["dim"], rolling=("[contact]", contact))
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


def check_shape(ctx, p, dim, where="[packing]", rolling=None):
    """The shape keys ``shape``, ``sides``, ``sides_max`` of a section ``p`` agree with
    each other and with ``dim`` (``sides`` defaults to 6 for polygons); ``rolling``,
    the (section, table) holding ``mu_roll``, is for spheres and disks only."""
    if rolling is not None and p["shape"] != "sphere":
        for key in ("mu_roll", "mu_twist"):
            if rolling[1].get(key):
                ctx.fail(f"{key}: rolling resistance acts between spheres and disks, not "
                         f"with shape = {p['shape']!r}", rolling[0])
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
    of a section ``p`` (None for spheres), from the shape registry
    (:func:`dem.shapes.registry.packing_maker`); ``dim`` defaults to ``p["dim"]``."""
    from dem.shapes.registry import packing_maker

    return packing_maker(p["shape"], p, p["dim"] if dim is None else dim)
