"""Problem files: the TOML description of a multiscale run, validated, and what it builds.

Layout (SI units; ``d`` is ``[mesh] dim``)::

    [mesh]
    dim = 2                        # 2 (plane strain) or 3
    element = "quad1"              # 2D: quad1 quad2 quad8 tri1 tri2
                                   # 3D: hex1 hex20 hex27 tet1 tet10
    integration = "reduced"        # quad2 quad8 hex20 hex27: 2 (or "full": 3) points/axis
    size = [0.05, 0.1]             # [m] rectangle / box [0, size]
    cells = [2, 4]                 # elements per axis
    file = "mesh.msh"              # instead of size/cells: any mesh scikit-fem reads
    x = [0.0, 0.03, 0.05]          # instead of size/cells: the element edges [m] along
    y = [0.0, 0.02, 0.06, 0.1]     # every axis, a graded mesh

    [[boundary]]                   # a named part of a boundary (optional, any number)
    name = "footing"
    of = "top"                     # the facets of "top" with midpoints in [lo, hi]
    lo = [0.0, 0.1]                # [m]
    hi = [0.02, 0.1]

    [[dirichlet]]                  # prescribed displacement, ramped over the schedule
    boundary = "bottom"            # a named boundary of the mesh
    component = "y"                # x, y or z
    value = 0.0                    # [m] at the end of the schedule

    [[dirichlet]]                  # or at one vertex of the mesh: a point support
    point = [0.025, 0.0]           # [m]
    component = "x"

    [[dirichlet]]                  # an affine displacement u = G (x - origin),
    boundary = "top"               # ramped: every component (or only `component`)
    gradient = [[0.0, 0.01], [0.0, 0.0]]
    origin = [0.0, 0.0]            # [m] optional, default 0

    [[periodic]]                   # opposite boundaries tied: u(x + L) = u(x) + G L
    boundary = "left"              # for each node x of boundary and its image
    image = "right"                # x + L on image (hold one node by a point)

    [[platen]]                     # a rigid frictionless platen: the boundary's
    boundary = "top"               # component moves as one, pushed by its loads
    component = "y"

    [[pressure]]                   # normal pressure (compression positive)
    boundary = "left"
    value = 1e5                    # [Pa]
    ramp = false                   # false: present from the start (balances the RVEs'
                                   # initial stress); true: grows with the load factor
    follower = true                # finite kinematics: normal to the deformed
                                   # boundary (false: a dead load on the initial one)

    [[traction]]                   # traction vector, ramped
    boundary = "top"
    value = [0.0, -1e4]            # [Pa]
    per = "reference"              # finite kinematics: per unit initial area, or
                                   # "current" area

    [body_force]
    value = [0.0, 0.0]             # [N/m^3], ramped
    per = "reference"              # per unit initial volume (gravity: rho_0 g), or
                                   # "current" volume

    [load]
    steps = 10                     # load steps (each may be cut and retried)
    gradient = [[0.0, 0.01], [0.0, 0.0]]  # G of the [[periodic]] pairs, ramped

    [fluid]                        # a saturated problem (Biot u-p, optional)
    permeability = 1e-12           # [m^2] a number or a d x d tensor
    viscosity = 1e-3               # [Pa s]
    bulk_modulus = 2.2e9           # [Pa] of the fluid
    porosity = 0.4
    initial_pressure = 0.0         # [Pa]

    [[drainage]]                   # hydraulic boundaries (others impermeable)
    boundary = "top"
    pressure = 0.0                 # [Pa] drained (or flux = inflow [m/s])

    [time]                         # a saturated problem's clock: [load] steps reach end
    end = 3600.0                   # [s]
    first = 1.0                    # [s] optional: steps growing geometrically
    ramp = 0.0                     # [s] the load's rise time (0: at once)

    [micro]
    model = "dem"                  # dem | adaptive | linear_elastic | hyperbolic |
                                   # hypoelastic | neo_hookean
    ... (see MICRO keys below)

    [[imperfection]]               # a weak spot (optional, any number; dem/adaptive)
    center = [0.01, 0.03]          # [m] Gauss points within radius of it start
    radius = 0.004                 # from their own packing: consolidated at this
    consolidation_friction = 0.3   # friction (looser), and/or with contact friction mu

    [solver]
    kinematics = "finite"          # "small" (fixed mesh) or "finite" (updated
                                   # Lagrangian); default finite, small for the
                                   # small-strain laws linear_elastic and hyperbolic
    tol_residual = 1e-3
    tol_displacement = 1e-3
    max_iterations = 10
    min_step = 0.015625

    [output]
    dir = "output/problem"         # default output/<file stem>
    every = 1                      # load steps between field frames
    checkpoint_every = 0           # load steps between checkpoints (0: none)

Any problem is a :class:`~dem.io.scene.SceneError` whose message is one line naming
the file and the key. :data:`SCHEMA` and :func:`~hmm.problem_schema.schema_markdown`
(the reference of every key) are in :mod:`hmm.problem_schema`; what a validated problem
builds (:func:`build_macro`, :func:`build_loads`, :func:`build_farm`, ...) is in
:mod:`hmm.problem_build`.
"""

import math
from pathlib import Path

import numpy as np

from dem.io.schema import read_toml, validate
from dem.limits import PARTICLES, LimitError, check_particle_scales

from .problem_build import build_farm, build_loads, build_macro
from .problem_schema import (
    COMPONENTS,
    ELEMENTS_2D,
    LOAD_STEPS,
    MESH_ELEMENTS,
    QUADRATURE_CHOICE,
    SCHEMA,
    SMALL_ONLY,
)

__all__ = ["SCHEMA", "build_farm", "build_loads", "build_macro", "load_problem",
           "validate_problem"]



def load_problem(path):
    """Read and validate a problem file (a :class:`SceneError` on any problem)."""
    path = Path(path)
    return validate_problem(read_toml(path, "problem"), str(path), path.parent)


def _check_edges(ctx, m, edges):
    """A graded mesh: element edges along every axis, and neither size, cells nor a
    file."""
    axes = "xyz"[:m["dim"]]
    if m["file"] is not None or m["size"] is not None or m["cells"] is not None:
        ctx.fail(f"takes the element edges {', '.join(edges)}, or size and cells, or a "
                 "mesh file: one of them", "[mesh]")
    if edges != list(axes):
        ctx.fail(f"needs the element edges along every axis ({', '.join(axes)}) in "
                 f"{m['dim']}D, got {', '.join(edges)}", "[mesh]")
    try:
        MESH_ELEMENTS.check(math.prod(len(m[a]) - 1 for a in axes), "edges: elements")
    except LimitError as exc:
        ctx.fail(str(exc), "[mesh]")


def validate_problem(data, source="<problem>", base_dir="."):
    """Check parsed TOML against :data:`SCHEMA`; defaults filled, paths resolved.

    Examples
    --------
    >>> p = validate_problem({"mesh": {"size": [1.0, 2.0], "cells": [1, 2]},
    ...                       "dirichlet": [{"boundary": "bottom", "component": "y"}],
    ...                       "micro": {"model": "linear_elastic", "young": 1e6,
    ...                                 "poisson": 0.3}})
    >>> p["load"]["steps"], p["micro"]["stress0"]
    (10, 0.0)
    >>> validate_problem({"mesh": {"size": [1.0, 2.0], "cells": [1, 2]},
    ...                   "micro": {"model": "dem", "young": 1e6}})
    Traceback (most recent call last):
    ...
    dem.io.schema.SceneError: <problem>: [micro] young is not used with model = "dem" (only with "linear_elastic", "hyperbolic", "hypoelastic" or "neo_hookean")
    """
    out, ctx = validate(data, SCHEMA, source, base_dir, dim_key=("mesh", "dim"))
    m = out["mesh"]
    edges = [a for a in "xyz" if m[a] is not None]
    if edges:
        _check_edges(ctx, m, edges)
    elif m["file"] is None:
        if m["size"] is None or m["cells"] is None:
            ctx.fail("needs size and cells, the element edges (x, y, z), or a mesh file",
                     "[mesh]")
        if any(c != int(c) for c in m["cells"]):
            ctx.fail(f"cells must be integers, got {m['cells']}", "[mesh]")
        try:
            MESH_ELEMENTS.check(math.prod(int(c) for c in m["cells"]),
                           f"cells = {[int(c) for c in m['cells']]}: elements")
        except LimitError as exc:
            ctx.fail(str(exc), "[mesh]")
    elif m["size"] is not None or m["cells"] is not None:
        ctx.fail("takes a mesh file or size and cells, not both", "[mesh]")
    if (m["element"] in ELEMENTS_2D) != (m["dim"] == 2):
        ctx.fail(f"element \"{m['element']}\" does not fit dim = {m['dim']}", "[mesh]")
    if m["integration"] is not None and m["element"] not in QUADRATURE_CHOICE:
        ctx.fail(f"integration applies to {', '.join(QUADRATURE_CHOICE)}, not to "
                 f"element \"{m['element']}\"", "[mesh]")
    for i, c in enumerate(out["dirichlet"]):
        _check_dirichlet(ctx, c, data["dirichlet"][i], m["dim"], f"[[dirichlet]] #{i + 1}")
    for i, c in enumerate(out["platen"]):
        if COMPONENTS.index(c["component"]) >= m["dim"]:
            ctx.fail(f"component \"{c['component']}\" does not exist in {m['dim']}D",
                     f"[[platen]] #{i + 1}")
    if not out["dirichlet"]:
        ctx.fail("a quasi-static problem needs supports: add [[dirichlet]] conditions")
    _check_periodic(ctx, out, data)
    if out["imperfection"] and out["micro"]["model"] not in ("dem", "adaptive"):
        ctx.fail(f"needs [micro] model = \"dem\" or \"adaptive\", not "
                 f"\"{out['micro']['model']}\"", "[[imperfection]] #1")
    kin = out["solver"]["kinematics"]
    if kin is None:
        kin = "small" if out["micro"]["model"] in SMALL_ONLY else "finite"
        out["solver"]["kinematics"] = kin
    elif kin == "finite" and out["micro"]["model"] in SMALL_ONLY:
        ctx.fail(f"kinematics = \"finite\" needs an objective micro model; "
                 f"\"{out['micro']['model']}\" is a small-strain law (use "
                 f"\"hypoelastic\" or \"neo_hookean\", or kinematics = \"small\")",
                 "[solver]")
    try:
        LOAD_STEPS.check(out["load"]["steps"], "steps")
    except LimitError as exc:
        ctx.fail(str(exc), "[load]")
    _check_fluid(ctx, out, data)
    if out["micro"]["model"] in ("dem", "adaptive"):
        from .experiment_config import check_shape
        from .micro import PERTURBATION_NEEDS_RELAX

        check_shape(ctx, out["micro"], m["dim"], "[micro]", ("[micro]", out["micro"]))
        _check_micro_sizes(ctx, out, m["dim"])
        if out["micro"]["tangent"] == "perturbation" and not out["micro"]["relax"]:
            ctx.fail(f"tangent = \"perturbation\" with relax = false: "
                     f"{PERTURBATION_NEEDS_RELAX}", "[micro]")
    return out


def _check_dirichlet(ctx, c, raw, dim, where):
    """One [[dirichlet]]: a boundary or a point; a component that exists; a value or
    a gradient; an origin with a gradient only."""
    if (c["boundary"] is None) == (c["point"] is None):
        ctx.fail("needs a boundary or a point (one of them)", where)
    if c["gradient"] is None:
        if c["component"] is None:
            ctx.fail("needs a component (x, y or z) with a value, or a gradient", where)
        if c["origin"] is not None:
            ctx.fail("origin applies to an affine displacement: add a gradient", where)
    elif "value" in raw:
        ctx.fail("takes a value or a gradient, not both", where)
    if c["component"] is not None and COMPONENTS.index(c["component"]) >= dim:
        ctx.fail(f"component \"{c['component']}\" does not exist in {dim}D", where)


def _check_periodic(ctx, out, data):
    """[[periodic]] pairs name two different boundaries, each in one pair; [load]
    gradient needs them; no saturated problem."""
    seen = {}
    for i, c in enumerate(out["periodic"]):
        where = f"[[periodic]] #{i + 1}"
        if c["boundary"] == c["image"]:
            ctx.fail(f"boundary and image are both \"{c['boundary']}\"", where)
        for name in (c["boundary"], c["image"]):
            if name in seen:
                ctx.fail(f"\"{name}\" is in [[periodic]] #{seen[name] + 1} already", where)
            seen[name] = i
    if out["load"]["gradient"] is not None and not out["periodic"]:
        ctx.fail("gradient applies to [[periodic]] boundaries: add them (an affine "
                 "displacement of a boundary is a [[dirichlet]] gradient)", "[load]")
    if out["periodic"] and data.get("fluid") is not None:
        ctx.fail("a saturated problem takes no periodic boundaries", "[[periodic]] #1")


def _check_micro_sizes(ctx, out, dim):
    """Generated packings: their particle count and scales; packing files: not a
    directory."""
    mc = out["micro"]
    if mc["packing"] is None:
        try:
            PARTICLES.check(mc["count"], "count")
            check_particle_scales(mc["radius"], mc["density"], dim)
        except LimitError as exc:
            ctx.fail(str(exc), "[micro]")
    spots = [(f"[[imperfection]] #{i + 1}", s) for i, s in enumerate(out["imperfection"])]
    for where, section in [("[micro]", mc), *spots]:
        if section["packing"] is not None and Path(section["packing"]).is_dir():
            ctx.fail(f"packing {section['packing']} is a directory, not a packing file",
                     where)


def _check_fluid(ctx, out, data):
    """A saturated problem has [fluid] and [time]; a dry one neither, nor drainage.
    An absent [fluid] or [time] becomes None."""
    if data.get("fluid") is None:
        for name in ("time", "drainage"):
            if data.get(name) is not None:
                ctx.fail("applies to a saturated problem only: add a [fluid] section",
                         f"[{name}]" if name == "time" else "[[drainage]] #1")
        if out["solver"]["coupling"] is not None:
            ctx.fail("coupling applies to a saturated problem only: add a [fluid] "
                     "section", "[solver]")
        out["fluid"] = out["time"] = None
        return
    if out["solver"]["coupling"] is None:
        out["solver"]["coupling"] = "monolithic"
    if out["solver"]["predictor"] != "tangent":
        ctx.fail("predictor = \"extrapolated\" is for dry problems: a saturated "
                 "problem's first guess is the committed tangents'", "[solver]")
    fl, tm = out["fluid"], out["time"]
    if fl["permeability"] is None:
        ctx.fail("missing required key 'permeability' (number or dim x dim array, "
                 "m^2)", "[fluid]")
    k = np.asarray(fl["permeability"], dtype=np.float64)
    if k.ndim == 2 and not (np.allclose(k, k.T) and np.all(np.linalg.eigvalsh(k) > 0)):
        ctx.fail(f"permeability must be symmetric positive definite, got "
                 f"{fl['permeability']}", "[fluid]")
    if not fl["porosity"] <= fl["biot"]:
        ctx.fail(f"biot must be in [porosity, 1] = [{fl['porosity']:g}, 1], got "
                 f"{fl['biot']:g}", "[fluid]")
    if data.get("time") is None or tm["end"] is None:
        ctx.fail("a saturated problem needs [time] end (seconds): the time its "
                 "[load] steps reach", "[time]")
    if tm["first"] is not None and tm["first"] > tm["end"] / out["load"]["steps"]:
        ctx.fail(f"first = {tm['first']:g} s is longer than an equal step, end / "
                 f"steps = {tm['end'] / out['load']['steps']:g} s", "[time]")
    for i, c in enumerate(out["drainage"]):
        if (c["pressure"] is None) == (c["flux"] is None):
            ctx.fail("needs a pressure or a flux (one of them)", f"[[drainage]] #{i + 1}")
    from .porous import PAIRS

    if out["mesh"]["element"] not in PAIRS:
        ctx.fail(f"a saturated problem needs a quadratic element ({', '.join(PAIRS)}) "
                 f"to pair with linear pore pressures, not \"{out['mesh']['element']}\"",
                 "[mesh]")
    if data.get("solver", {}).get("kinematics") is None:
        # small by default: the closed forms of saturated problems (Terzaghi, Mandel)
        # are small-strain theories; finite on request
        out["solver"]["kinematics"] = "small"
