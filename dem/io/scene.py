"""TOML scene files: a schema written as data, validation, the Simulation they build.

A scene file is parsed with :mod:`tomllib`, checked against :data:`SCHEMA` and turned
into a :class:`dem.Simulation` by :func:`build_simulation`. Any problem is a
:class:`SceneError` whose message is one line naming the file and the full key path,
e.g. ``scene.toml: [particles] radius must be > 0, got -0.01``.

Layout (SI units throughout; ``d`` is ``[simulation] dim``)::

    [simulation]
    dim = 3                       # 2 or 3
    steps = 20000                 # required
    dt = 1e-5                     # [s], optional: default DT_FACTOR x critical step
    allow_unstable_dt = false     # true: run a dt above the stable time step anyway
    gravity = [0.0, 0.0, -9.81]   # [m/s^2], d components
    damping = 0.0                 # Cundall local damping in [0, 1)
    skin = 0.002                  # [m], optional Verlet skin
    neighbor_backend = "cell"     # or "kdtree"
    overlap_limit = 0.5           # stop when overlap > this x smaller radius

    [particles]
    generator = "random"          # required: "lattice" | "random" | "file"
    count = 300                   # random: required; lattice: optional (fill the box)
    lo = [0.0, 0.0, 0.0]          # [m] generation box (required: lattice, random)
    hi = [0.1, 0.1, 0.2]
    spacing = 0.011               # [m] lattice pitch (default 2.1 x largest radius)
    radius = [0.004, 0.005]       # [m] required: one value or [min, max] (uniform)
    density = 2500.0              # [kg/m^3], required
    seed = 0                      # random positions / polydisperse radii
    velocity = [0.0, 0.0, 0.0]    # [m/s] initial velocity of every particle
    file = "packing.txt"          # file: rows "x y z r" (3D) or "x y r" (2D)
    group = "particles"           # the group [[contact]] pair names

    [[walls]]                     # any number; the normal points to the free side
    point = [0.0, 0.0, 0.0]       # [m], required
    normal = [0.0, 0.0, 1.0]      # required
    velocity = [0.0, 0.0, 0.0]    # [m/s], optional
    rigid = true                  # optional: the wall's own material, the keys of the
    mu = 0.3                      # particle-wall law (dem.io.materials)

    [[meshes]]                    # any number (3D): triangle-mesh walls
    file = "hopper.stl"           # required, relative to the scene file
    scale = 0.001                 # optional factor on the file's coordinates
    velocity = [0.0, 0.0, 0.0]    # [m/s]; angular_velocity [rad/s] about center [m]
    mu = 0.3                      # optional: the wall's own material, as [[walls]]

    [contact]                     # or several [[contact]] with pair = ["a", "b"]
    law = "linear"                # required: a law of dem.contact.laws.LAWS (each
                                  # with its keys: docs/scene_reference.md)
    kn = 1e4                      # linear: [N/m], required
    kt = 5e3                      # linear: [N/m]
    gamma_n = 0.0                 # linear: [N s/m]
    gamma_t = 0.0                 # linear: [N s/m]
    young = 1e7                   # hertz_mindlin: [Pa], required
    poisson = 0.3                 # hertz_mindlin: in [0, 0.5), required
    mu = 0.5                      # every law: friction coefficient, required
    restitution = 0.5             # every law: in (0, 1], default 1

    [output]
    dir = "output/scene"          # relative to the working directory
    every = 1000                  # steps between frames
    contacts = true               # also write the contact network

Paths inside the scene (``[particles] file``) are relative to the scene file; the output
directory is relative to the current working directory and defaults to
``output/<scene file stem>``. Keys that belong to another generator or law (``file``
with ``generator = "lattice"``, ``young`` with ``law = "linear"``) are errors, as are
unknown keys. Walls are listed as ``[[walls]] #1``, ``#2``, ... (1-based) in messages.
:func:`schema_markdown` renders :data:`SCHEMA` (types, units, defaults, ranges) as a
reference page.
"""

import logging
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..contact.laws import contact_keys
from ..limits import PARTICLES, LimitError
from ..limits import check_particle_scales
from .packing import (
    check_random_fits,
    lattice_packing,
    radii,
    random_packing,
    read_packing,
)
from .schema import (
    NONNEGATIVE,
    POSITIVE,
    REQUIRED,
    Key,
    Range,
    SceneError,
    Section,
    _Context,
    read_toml,
    validate,
)
from .materials import (
    DEFAULT_GROUP,
    ROLLING_KEYS,
    WALL_MATERIAL_KEYS,
    check_materials,
    scene_materials,
)
from .schema import schema_markdown as _schema_markdown
from .text import fmt as _fmt
from .text import show as _show

log = logging.getLogger(__name__)

__all__ = ["REQUIRED", "SCHEMA", "Key", "OutputSettings", "Range", "SceneError", "Section",
           "build_bodies", "build_meshes", "build_simulation", "load_scene", "read_toml",
           "schema_markdown", "validate", "validate_scene"]


SCHEMA = {
    "simulation": Section(doc="Time stepping and body forces.", required=True, keys={
        "dim": Key("int", default=3, choices=(2, 3), doc="Dimension of the scene."),
        "steps": Key("int", default=REQUIRED, range=NONNEGATIVE,
                     doc="Number of time steps to run (with rest_speed: the most)."),
        "rest_speed": Key("float", "m/s", range=POSITIVE,
                          doc="Stop before steps once every particle is slower than "
                              "this, spin included (the surface speed omega r), "
                              "checked every 100 steps; default: run every step."),
        "dt": Key("float", "s", range=POSITIVE,
                  doc="Time step; default DT_FACTOR x the critical time step dt_crit "
                      "(or less with heavy dashpots). A dt above the stable time step "
                      "dt_stable (docs/stability.md) is refused."),
        "allow_unstable_dt": Key("bool", default=False,
                                 doc="Run a dt above the stable time step anyway (the "
                                     "run may blow up)."),
        "gravity": Key("vector", "m/s^2", default=0.0,
                       doc="Gravitational acceleration, dim components."),
        "damping": Key("float", default=0.0, range=Range(0.0, 1.0, hi_closed=False),
                       doc="Cundall local damping coefficient."),
        "skin": Key("float", "m", range=POSITIVE,
                    doc="Verlet skin; default 0.4 x the mean radius."),
        "neighbor_backend": Key("str", default="cell", choices=("cell", "kdtree"),
                                doc="Neighbour search."),
        "overlap_limit": Key("float", default=0.5, range=POSITIVE,
                             doc="Stop when an overlap exceeds this x smaller radius."),
    }),
    "particles": Section(doc="Spheres (disks in 2D).", required=True,
                         variant="generator", keys={
        "generator": Key("str", default=REQUIRED, choices=("lattice", "random", "file"),
                         doc="How positions are made."),
        "count": Key("int", range=Range(1.0), only=("lattice", "random"),
                     required_for=("random",),
                     doc="Number of particles (lattice: default fills the box)."),
        "lo": Key("vector", "m", default=REQUIRED, only=("lattice", "random"),
                  doc="Lower corner of the generation box."),
        "hi": Key("vector", "m", default=REQUIRED, only=("lattice", "random"),
                  doc="Upper corner of the generation box."),
        "spacing": Key("float", "m", range=POSITIVE, only=("lattice",),
                       doc="Lattice pitch; default 2.1 x the largest radius."),
        "radius": Key("radius", "m", default=REQUIRED, range=POSITIVE,
                      only=("lattice", "random"),
                      doc="Radius, or [min, max] for uniformly distributed radii."),
        "density": Key("float", "kg/m^3", default=REQUIRED, range=POSITIVE,
                       doc="Density (per unit thickness in 2D)."),
        "seed": Key("int", default=0, range=NONNEGATIVE, only=("lattice", "random"),
                    doc="Seed of the random generator."),
        "velocity": Key("vector", "m/s", default=0.0, doc="Initial velocity."),
        "file": Key("path", default=REQUIRED, only=("file",),
                    doc="Whitespace-separated rows x y [z] r, '#' comments."),
        "group": Key("str", default=DEFAULT_GROUP,
                     doc="Name of the particles' group, which [[contact]] pair names."),
    }),
    "domain": Section(doc="A periodic box: the axes along which the scene repeats and "
                          "its bounds on them (other axes stay open).", keys={
        "periodic": Key("axes", doc="The periodic axes, e.g. [\"x\", \"y\"]; required "
                                    "in a [domain]."),
        "lo": Key("vector", "m", doc="Lower corner of the box; required in a [domain]."),
        "hi": Key("vector", "m", doc="Upper corner of the box; required in a [domain]."),
    }),
    "insert": Section(doc="Particles inserted over time in a region (spheres, disks "
                          "in 2D), after the [particles] of the start.", keys={
        "count": Key("int", range=NONNEGATIVE,
                     doc="Particles to insert in all; required in an [insert]."),
        "rate": Key("float", "1/s", range=POSITIVE,
                    doc="Particles per second; required in an [insert]."),
        "lo": Key("vector", "m", doc="Lower corner of the region; required."),
        "hi": Key("vector", "m", doc="Upper corner of the region; required."),
        "radius": Key("radius", "m", range=POSITIVE,
                      doc="Radius, or [min, max]; required."),
        "density": Key("float", "kg/m^3", range=POSITIVE,
                       doc="Density; default that of [particles]."),
        "velocity": Key("vector", "m/s", default=0.0, doc="Initial velocity."),
        "every": Key("int", default=100, range=Range(1.0),
                     doc="Steps between insertions."),
        "seed": Key("int", default=0, range=NONNEGATIVE,
                    doc="Seed of the random positions and radii."),
        "group": Key("str", doc="Group of the inserted particles; default the "
                                "[particles] group."),
    }),
    "walls": Section(doc="Planes; particles live on the side the normal points to.",
                     array=True, keys={
        "point": Key("vector", "m", default=REQUIRED, doc="A point of the plane."),
        "normal": Key("vector", default=REQUIRED, doc="Normal towards the free side."),
        "velocity": Key("vector", "m/s", default=0.0, doc="Prescribed velocity."),
        **WALL_MATERIAL_KEYS,
    }),
    "meshes": Section(doc="Triangle-mesh walls (3D, spheres, no [domain]): the triangles "
                          "of a file meshio reads (STL, OBJ, PLY, VTK, ...), moved "
                          "rigidly by a prescribed velocity and angular velocity.",
                      array=True, keys={
        "file": Key("path", default=REQUIRED,
                    doc="The mesh file, relative to the scene file; its triangles are "
                        "the wall (corners shared by several triangles are merged)."),
        "scale": Key("float", default=1.0, range=POSITIVE,
                     doc="Factor on the file's coordinates (0.001 for millimetres)."),
        "shift": Key("vector", "m", default=0.0,
                     doc="Translation of the scaled coordinates."),
        "watertight": Key("bool", default=False,
                          doc="Require a closed surface (every edge shared by two "
                              "triangles)."),
        "velocity": Key("vector", "m/s", default=0.0, doc="Prescribed velocity."),
        "angular_velocity": Key("vector", "rad/s", default=0.0,
                                doc="Prescribed angular velocity about center."),
        "center": Key("vector", "m",
                      doc="The point the wall turns about (it moves with the wall); "
                          "default the centre of the wall's bounding box."),
        **WALL_MATERIAL_KEYS,
    }),
    "contact": Section(doc="The contact law: one [contact] table for every pair, or an "
                           "array of [[contact]] tables, each naming the pair of groups "
                           "it acts between (\"walls\": the walls' group).",
                       required=True, variant="law", keys={
        "pair": Key("pair", doc="The two groups, e.g. [\"sand\", \"walls\"]; required "
                                "in an array of [[contact]] tables; default: every pair."),
        **contact_keys(),
        **ROLLING_KEYS,
    }),
    "output": Section(doc="HDF5 output written by `dem run`.", keys={
        "dir": Key("str", doc="Output directory; default output/<scene stem>."),
        "every": Key("int", default=1000, range=Range(1.0),
                     doc="Steps between frames."),
        "contacts": Key("bool", default=True, doc="Also write contacts."),
        "checkpoint_every": Key("int", default=0, range=Range(0.0),
                                doc="Steps between checkpoints (checkpoint.h5 beside the "
                                    "particle file, also written at the end and when a "
                                    "signal stops the run; dem run --restart continues "
                                    "from it); 0: none."),
    }),
}


@dataclass(frozen=True)
class OutputSettings:
    """Where and how often ``dem run`` writes: ``file`` (HDF5) inside ``dir``."""

    dir: Path
    file: Path
    every: int
    contacts: bool
    checkpoint_every: int = 0


# --------------------------------------------------------------------------- loading
def load_scene(path):
    """Read, parse and validate a scene file.

    Parameters
    ----------
    path : str or Path
        The TOML scene file.

    Returns
    -------
    dict
        ``{section: {key: value}}`` with defaults filled (``walls`` a list of such
        dicts), ``particles.file`` resolved against the scene's directory, and
        ``"source"``: the path as given, used in later messages.

    Raises
    ------
    SceneError
        Unreadable file, invalid TOML or a value outside the schema.
    """
    path = Path(path)
    return validate_scene(read_toml(path), source=str(path), base_dir=path.parent)


def validate_scene(data, source="<scene>", base_dir="."):
    """Check parsed ``data`` against :data:`SCHEMA`; returns as :func:`load_scene`.

    Examples
    --------
    >>> s = validate_scene({"simulation": {"steps": 10},
    ...                     "particles": {"generator": "lattice", "lo": [0, 0, 0],
    ...                                   "hi": [1, 1, 1], "radius": 0.1, "density": 1},
    ...                     "contact": {"law": "linear", "kn": 1e3, "mu": 0.3}})
    >>> s["simulation"]["gravity"], s["contact"]["restitution"]
    ([0.0, 0.0, 0.0], 1.0)
    >>> validate_scene({"simulation": {"steps": -1}})
    Traceback (most recent call last):
    ...
    dem.io.schema.SceneError: <scene>: [simulation] steps must be >= 0, got -1
    """
    schema = SCHEMA
    if isinstance(data, dict) and isinstance(data.get("contact"), list):
        schema = {**SCHEMA, "contact": replace(SCHEMA["contact"], array=True)}
    out, ctx = validate(data, schema, source, base_dir, dim_key=("simulation", "dim"))
    _cross_checks(ctx, out)
    return out


def _cross_checks(ctx, scene):
    p = scene["particles"]
    if p["generator"] in ("lattice", "random"):
        for a, (lo, hi) in enumerate(zip(p["lo"], p["hi"], strict=True)):
            if not lo < hi:
                ctx.fail(f"needs lo < hi on every axis, got lo[{a}] = {_fmt(lo)}, "
                         f"hi[{a}] = {_fmt(hi)}", "[particles]")
        try:
            if p["count"] is not None:
                PARTICLES.check(p["count"], "count")
            check_particle_scales(p["radius"], p["density"], ctx.dim)
        except LimitError as exc:
            ctx.fail(str(exc), "[particles]")
    for i, w in enumerate(scene["walls"]):
        if not any(w["normal"]):
            ctx.fail("normal must be a non-zero vector", f"[[walls]] #{i + 1}")
    if scene["meshes"] and ctx.dim != 3:
        ctx.fail("mesh walls need a 3D scene ([simulation] dim = 3)", "[[meshes]] #1")
    _check_domain(ctx, scene)
    _check_insert(ctx, scene)
    check_materials(ctx, scene)


def _check_insert(ctx, scene):
    """An [insert] names its count, rate, region and radius; the region holds a
    particle, and its count is within the particle limit."""
    ins = scene["insert"]
    if ins["count"] is None and ins["rate"] is None and ins["lo"] is None:
        scene["insert"] = None
        return
    for key in ("count", "rate", "lo", "hi", "radius"):
        if ins[key] is None:
            ctx.fail(f"missing required key '{key}' of an insertion", "[insert]")
    r_max = max(ins["radius"]) if isinstance(ins["radius"], list) else ins["radius"]
    for a, (lo, hi) in enumerate(zip(ins["lo"], ins["hi"], strict=True)):
        if not hi - lo > 2.0 * r_max:
            ctx.fail(f"the region must be wider than a particle's diameter "
                     f"{_fmt(2.0 * r_max)} m along every axis, got lo[{a}] = {_fmt(lo)}, "
                     f"hi[{a}] = {_fmt(hi)}", "[insert]")
    try:
        PARTICLES.check(ins["count"], "[insert] count")
        check_particle_scales(ins["radius"], ins["density"] or scene["particles"]["density"],
                              ctx.dim)
    except LimitError as exc:
        ctx.fail(str(exc), "[insert]")


def _check_domain(ctx, scene):
    """A [domain] names its periodic axes and bounds them; the generation box lies
    inside it along them, and no wall cuts across one."""
    dom = scene["domain"]
    if all(v is None for v in dom.values()):
        return
    for key in ("periodic", "lo", "hi"):
        if dom[key] is None:
            ctx.fail(f"missing required key '{key}' of a periodic box", "[domain]")
    axes = ["xyz".index(a) for a in dom["periodic"]]
    for a in axes:
        if not dom["lo"][a] < dom["hi"][a]:
            ctx.fail(f"needs lo < hi along the periodic axis {'xyz'[a]}, got "
                     f"{_fmt(dom['lo'][a])} and {_fmt(dom['hi'][a])}", "[domain]")
    p = scene["particles"]
    if p["generator"] in ("lattice", "random"):
        for a in axes:
            if p["lo"][a] < dom["lo"][a] or p["hi"][a] > dom["hi"][a]:
                ctx.fail(f"the generation box lo..hi must lie inside the [domain] along "
                         f"its periodic axis {'xyz'[a]}: {_fmt(p['lo'][a])}.."
                         f"{_fmt(p['hi'][a])} is not inside {_fmt(dom['lo'][a])}.."
                         f"{_fmt(dom['hi'][a])}", "[particles]")
    if scene["meshes"]:
        ctx.fail("mesh walls do not work with a periodic [domain]", "[[meshes]] #1")
    for i, w in enumerate(scene["walls"]):
        if any(w["normal"][a] != 0.0 for a in axes):
            ctx.fail(f"a wall's normal must have no component along a periodic axis "
                     f"({', '.join(dom['periodic'])}), got {_show(w['normal'])}",
                     f"[[walls]] #{i + 1}")


def scene_domain(scene):
    """The :class:`dem.Domain` of a validated scene's ``[domain]``, or None."""
    dom = scene["domain"]
    if dom["periodic"] is None:
        return None
    from ..neighbors import Box

    periodic = [a in dom["periodic"] for a in "xyz"[:len(dom["lo"])]]
    return Box(dom["lo"], dom["hi"], periodic)


# --------------------------------------------------------------------------- building
def build_bodies(scene):
    """The :class:`dem.Bodies` of a validated scene: particles, then walls.

    Raises :class:`SceneError` for a box too small for the requested particles, a
    particle file that cannot be read or whose spheres overlap (naming the first pair),
    and a particle that overlaps a wall.
    """
    from ..state import Bodies

    ctx = _Context(scene.get("source", "<scene>"), Path("."))
    ctx.dim = scene["simulation"]["dim"]
    p = scene["particles"]
    gen = p["generator"]
    try:
        if gen == "file":
            pos, radius = read_packing(p["file"], ctx.dim)
            check_particle_scales([float(radius.min()), float(radius.max())],
                                  p["density"], ctx.dim)
        else:
            rng = np.random.default_rng(p["seed"])
            lo, hi = np.array(p["lo"]), np.array(p["hi"])
            n = p["count"]
            r = p["radius"]
            if gen == "lattice":
                pos, radius = lattice_packing(lo, hi, r, p["spacing"], n, rng)
            else:
                check_random_fits(lo, hi, r, n)
                radius = radii(r, n, rng)
                pos = random_packing(lo, hi, radius, rng)
    except ValueError as exc:
        ctx.fail(str(exc), "[particles]")
    domain = scene_domain(scene)
    if domain is not None:
        ax = domain.periodic
        out = np.flatnonzero(np.any((pos[:, ax] < domain.lo[ax])
                                    | (pos[:, ax] >= domain.hi[ax]), axis=1))
        if out.size:
            k = int(out[0])
            ctx.fail(f"particle {k} at {_show(pos[k].tolist())} lies outside the [domain] "
                     f"along a periodic axis", "[particles]")
    mats = scene_materials(ctx, scene)
    bodies = Bodies.spheres(pos, radius=radius, density=p["density"], vel=p["velocity"],
                            mat_id=mats.groups[p["group"]])
    for i, w in enumerate(scene["walls"]):
        point, normal = np.array(w["point"]), np.array(w["normal"])
        normal = normal / np.linalg.norm(normal)
        gap = (pos - point) @ normal - radius
        k = int(np.argmin(gap)) if len(gap) else 0
        if len(gap) and gap[k] < -1e-9 * radius[k]:
            ctx.fail(f"particle {k} at {_show(pos[k].tolist())} overlaps the wall by "
                     f"{_fmt(-gap[k])} m (is the normal pointing to the free side?)",
                     f"[[walls]] #{i + 1}")
        bodies.add_plane(point, normal, velocity=w["velocity"], mat_id=mats.walls[i])
    return bodies


def build_meshes(scene, bodies, mat_ids):
    """The :class:`dem.MeshWall` of each ``[[meshes]]`` table of a validated scene, with
    the material rows ``mat_ids``.

    Raises :class:`SceneError` naming the table for a file that is missing, unreadable,
    without triangles, with a degenerate triangle or (``watertight``) open, and for a
    particle of ``bodies`` that overlaps a wall.
    """
    from ..meshwall import MeshWall

    ctx = _Context(scene.get("source", "<scene>"), Path("."))
    out = []
    pos, radius = bodies.pos, bodies.radius
    for i, (m, mat) in enumerate(zip(scene["meshes"], mat_ids, strict=True)):
        where = f"[[meshes]] #{i + 1}"
        try:
            wall = MeshWall.from_file(m["file"], require_watertight=m["watertight"],
                                      scale=m["scale"], shift=m["shift"],
                                      velocity=m["velocity"],
                                      angular_velocity=m["angular_velocity"],
                                      center=m["center"], mat_id=mat)
        except ValueError as exc:
            ctx.fail(str(exc), where)
        ptr, _ = wall.faces_near(pos, radius)
        for k in np.flatnonzero(np.diff(ptr)):
            hit = wall.contacts(pos[k], radius[k])
            if hit.overlap.size and hit.overlap.max() > 1e-9 * radius[k]:
                ctx.fail(f"particle {int(k)} at {_show(pos[k].tolist())} overlaps the "
                         f"mesh wall by {_fmt(float(hit.overlap.max()))} m", where)
        out.append(wall)
    return out


def build_simulation(scene):
    """Build the :class:`dem.Simulation` of a validated scene (from :func:`load_scene`).

    Returns
    -------
    sim : Simulation
        Bodies, contact law, time step and forces of the scene; not yet run.
    output : OutputSettings
        The ``[output]`` section with the directory and HDF5 file resolved.
    """
    from ..simulation import Simulation
    from ..timestep import stable_time_step

    ctx = _Context(scene.get("source", "<scene>"), Path("."))
    bodies = build_bodies(scene)
    mats = scene_materials(ctx, scene)
    meshes = build_meshes(scene, bodies, mats.walls[len(scene["walls"]):])
    s = scene["simulation"]
    if s["dt"] is not None and not s["allow_unstable_dt"]:
        dt_max = stable_time_step(bodies, mats.model, s["damping"])[0]
        if s["dt"] > dt_max:
            ctx.fail(f"dt = {_fmt(s['dt'])} s exceeds the stable time step dt_stable = "
                     f"{dt_max:.4g} s of these particles and [contact] law; lower dt or "
                     f"set allow_unstable_dt = true", "[simulation]")
    try:
        sim = Simulation(bodies, mats.model, dt=s["dt"], gravity=s["gravity"],
                         damping=s["damping"], skin=s["skin"],
                         neighbor_backend=s["neighbor_backend"],
                         overlap_limit=s["overlap_limit"],
                         allow_unstable_dt=s["allow_unstable_dt"], box=scene_domain(scene),
                         walls=meshes)
    except ValueError as exc:
        ctx.fail(str(exc), "[simulation]")
    if scene["insert"] is not None:
        from ..insertion import Inserter

        ins = scene["insert"]
        try:
            inserter = Inserter(ins["lo"], ins["hi"], ins["count"], ins["rate"],
                                ins["radius"], ins["density"] or scene["particles"]["density"],
                                velocity=ins["velocity"], every=ins["every"], seed=ins["seed"],
                                mat_id=mats.groups[ins["group"] or scene["particles"]["group"]])
            inserter.check_mass(sim)
        except ValueError as exc:
            ctx.fail(str(exc), "[insert]")
        sim.controllers.append(inserter)
    o = scene["output"]
    stem = Path(ctx.source).stem.strip("<>") or "scene"
    out_dir = Path(o["dir"] if o["dir"] is not None else Path("output") / stem)
    output = OutputSettings(dir=out_dir, file=out_dir / f"{stem}.h5", every=o["every"],
                            contacts=o["contacts"], checkpoint_every=o["checkpoint_every"])
    log.info("scene %s: %d bodies, dt = %.4g s", ctx.source, bodies.n, sim.dt)
    return sim, output


# --------------------------------------------------------------------------- text


# --------------------------------------------------------------------------- text
def schema_markdown(schema=None):
    """A schema (default: the scene's) as a Markdown reference, a table per section.

    >>> print(schema_markdown().splitlines()[0])
    ## [simulation]
    """
    return _schema_markdown(SCHEMA if schema is None else schema)
