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
the file and the key. :func:`schema_markdown` gives the reference of every key.
"""

import math
from pathlib import Path

import numpy as np

from dem.io.scene import REQUIRED, Key, Range, SceneError, Section, read_toml, validate
from dem.io.scene import schema_markdown as _markdown
from dem.limits import PARTICLES, Limit, LimitError, check_particle_scales

from .conditions import (
    BodyForce,
    ConditionError,
    Dirichlet,
    Periodic,
    Platen,
    Pressure,
    Traction,
    cut_boundary,
    external_forces,
    supports,
    vertex_at,
)

POSITIVE = Range(0.0, lo_closed=False)
NONNEGATIVE = Range(0.0)
COMPONENTS = ("x", "y", "z")
#: element names of 2D and 3D meshes (hmm.macro.ELEMENTS gives their classes)
ELEMENTS_2D = ("quad1", "quad2", "quad8", "tri1", "tri2")
ELEMENTS_3D = ("hex1", "hex20", "hex27", "tet1", "tet10")
#: elements whose Gauss rule [mesh] integration chooses (hmm.macro.INTEGRATION)
QUADRATURE_CHOICE = ("quad2", "quad8", "hex20", "hex27")
#: most elements of a mesh ([mesh] size and cells, or a file); each has Gauss points
MESH_ELEMENTS = Limit(10**6, "HMM_MAX_ELEMENTS", "elements")
#: most load steps of a run (the schedule is an array of that length)
LOAD_STEPS = Limit(10**6, "HMM_MAX_LOAD_STEPS", "load steps")
#: micro models of [micro] model; the analytic ones take young and poisson
MICRO_MODELS = ("dem", "adaptive", "linear_elastic", "hyperbolic", "hypoelastic",
                "neo_hookean")
ANALYTIC = ("linear_elastic", "hyperbolic", "hypoelastic", "neo_hookean")
#: the small-strain laws (not objective): small kinematics only
SMALL_ONLY = ("linear_elastic", "hyperbolic")
KINEMATICS = ("small", "finite")

SCHEMA = {
    "mesh": Section(doc="The macro domain and its finite elements.", required=True, keys={
        "dim": Key("int", default=2, choices=(2, 3), doc="2 (plane strain) or 3."),
        "element": Key("str", default="quad1",
                       choices=ELEMENTS_2D + ELEMENTS_3D,
                       doc="Element type (2D: quad1 quad2 quad8 tri1 tri2; 3D: hex1 "
                           "hex20 hex27 tet1 tet10)."),
        "integration": Key("str", choices=("reduced", "full"),
                           doc="Quadratic quadrilaterals and hexahedra (quad2 quad8 "
                               "hex20 hex27): 2 (reduced) or 3 (full) Gauss points per "
                               "axis; default reduced for quad8 and hex20, full for "
                               "quad2 and hex27."),
        "size": Key("vector", "m", range=POSITIVE,
                    doc="Edge lengths of the rectangle/box [0, size]."),
        "cells": Key("vector", range=Range(1.0), doc="Elements along each axis."),
        "file": Key("path", doc="A mesh file scikit-fem reads (instead of size/cells)."),
    }),
    "boundary": Section(doc="Named parts of the mesh's boundaries (a footing on the top "
                            "face, say): the facets of `of` whose midpoints lie in the "
                            "box [lo, hi].", array=True, keys={
        "name": Key("str", default=REQUIRED, doc="Name of the new boundary."),
        "of": Key("str", default=REQUIRED, doc="The boundary it is cut from."),
        "lo": Key("vector", "m", default=REQUIRED, doc="Lower corner of the box."),
        "hi": Key("vector", "m", default=REQUIRED, doc="Upper corner of the box."),
    }),
    "dirichlet": Section(doc="Prescribed displacements, ramped with the load factor: a "
                             "uniform `value` in one component, or an affine "
                             "displacement u = G (x - origin) (`gradient`), in every "
                             "component or in `component` only (x the initial "
                             "position of each node).", array=True, keys={
        "boundary": Key("str", doc="Named boundary of the mesh (this or `point`)."),
        "point": Key("vector", "m", doc="A vertex of the mesh (this or `boundary`): a "
                                         "point support, e.g. the middle of a smooth "
                                         "base held against rigid sliding."),
        "component": Key("str", choices=COMPONENTS,
                         doc="Displacement component (required with `value`; with "
                             "`gradient`, default every component)."),
        "value": Key("float", "m", default=0.0, doc="Value at the end of the schedule."),
        "gradient": Key("tensor", doc="The displacement gradient G of an affine "
                                      "displacement u = G (x - origin) at the end of "
                                      "the schedule, instead of `value`: d rows of d "
                                      "numbers (a number g: g I)."),
        "origin": Key("vector", "m", doc="The point an affine displacement leaves in "
                                         "place (default 0)."),
    }),
    "periodic": Section(doc="Periodic boundaries: `boundary` and its `image` (the same "
                            "nodes shifted by L) are tied node by node, u(x + L) = "
                            "u(x) + G L, with G the average displacement gradient "
                            "[load] gradient; a corner on two pairs is tied to all its "
                            "images. Hold one node against rigid translation with a "
                            "point [[dirichlet]] in every component.", array=True,
                        keys={
        "boundary": Key("str", default=REQUIRED, doc="Named boundary of the mesh."),
        "image": Key("str", default=REQUIRED,
                     doc="The opposite boundary, `boundary` shifted by L."),
    }),
    "platen": Section(doc="A rigid, frictionless platen: one displacement component "
                          "of a boundary is a single unknown, pushed by the loads on "
                          "the boundary (a pressure or a traction): the plates of "
                          "Mandel's problem, a rigid footing under a force.",
                      array=True, keys={
        "boundary": Key("str", default=REQUIRED, doc="Named boundary of the mesh."),
        "component": Key("str", default=REQUIRED, choices=COMPONENTS,
                         doc="The component that moves as one."),
    }),
    "pressure": Section(doc="Normal pressure on a boundary (compression positive).",
                        array=True, keys={
        "boundary": Key("str", default=REQUIRED, doc="Named boundary of the mesh."),
        "value": Key("float", "Pa", default=REQUIRED, doc="Pressure."),
        "ramp": Key("bool", default=False,
                    doc="Grow with the load factor (else present from the start)."),
        "follower": Key("bool", default=True,
                        doc="Under finite kinematics, act normal to the deformed "
                            "boundary, on its current area (false: a dead load on "
                            "the initial boundary)."),
    }),
    "traction": Section(doc="Traction vector on a boundary, ramped.", array=True, keys={
        "boundary": Key("str", default=REQUIRED, doc="Named boundary of the mesh."),
        "value": Key("vector", "Pa", default=REQUIRED, doc="Traction at load factor 1."),
        "per": Key("str", default="reference", choices=("reference", "current"),
                   doc="Under finite kinematics, per unit initial (reference) or "
                       "current area."),
    }),
    "body_force": Section(doc="Body force density, ramped.", keys={
        "value": Key("vector", "N/m^3", default=0.0, doc="Force per unit volume."),
        "per": Key("str", default="reference", choices=("reference", "current"),
                   doc="Under finite kinematics, per unit initial (reference) volume "
                       "(gravity: rho_0 g) or current volume."),
    }),
    "load": Section(doc="The load schedule.", keys={
        "steps": Key("int", default=10, range=Range(1.0), doc="Number of load steps."),
        "gradient": Key("tensor", doc="The average displacement gradient G of the "
                                      "[[periodic]] pairs at the end of the schedule, "
                                      "d rows of d numbers (a number g: g I; default "
                                      "0)."),
    }),
    "micro": Section(doc="The micro model at every Gauss point.", required=True,
                     variant="model", keys={
        "model": Key("str", default=REQUIRED, choices=MICRO_MODELS,
                     doc="dem: an RVE per point; adaptive: DEM only where needed; "
                         "linear_elastic / hyperbolic: small-strain analytic laws; "
                         "hypoelastic (Jaumann rate) / neo_hookean: objective "
                         "analytic laws."),
        "young": Key("float", "Pa", default=REQUIRED, range=POSITIVE,
                     only=ANALYTIC, doc="Young's modulus (small strain)."),
        "poisson": Key("float", default=REQUIRED, range=Range(-1.0, 0.5, False, False),
                       only=ANALYTIC, doc="Poisson's ratio (small strain)."),
        "gamma_ref": Key("float", default=REQUIRED, range=POSITIVE, only=("hyperbolic",),
                         doc="Reference shear strain of the hyperbolic law."),
        "stress0": Key("float", "Pa", default=0.0,
                       only=("linear_elastic", "hyperbolic", "hypoelastic"),
                       doc="Initial isotropic stress (tension positive)."),
        "packing": Key("path", only=("dem", "adaptive"),
                       doc="A packing saved by `hmm rve` or RVE.save (else generated)."),
        "packings": Key("int", default=1, range=Range(1.0), only=("dem", "adaptive"),
                        doc="Distinct generated packings (seeds seed..seed+n-1), "
                            "assigned to Gauss points in turn: material variability."),
        "count": Key("int", default=100, range=Range(4.0), only=("dem", "adaptive"),
                     doc="Particles per generated packing."),
        "radius": Key("radius", "m", default=[0.8e-3, 1.2e-3], range=POSITIVE,
                      only=("dem", "adaptive"), doc="Radius or [min, max]."),
        "density": Key("float", "kg/m^3", default=2650.0, range=POSITIVE,
                       only=("dem", "adaptive"), doc="Particle density."),
        "p0": Key("float", "Pa", default=1e5, range=POSITIVE, only=("dem", "adaptive"),
                  doc="Consolidation pressure of generated packings."),
        "seed": Key("int", default=0, range=NONNEGATIVE, only=("dem", "adaptive"),
                    doc="Seed of the first generated packing."),
        "consolidation_friction": Key("float", default=0.0, range=NONNEGATIVE,
                                      only=("dem", "adaptive"),
                                      doc="Friction while consolidating (lower: denser)."),
        "shape": Key("str", default="sphere", choices=("sphere", "polygon", "box"),
                     only=("dem", "adaptive"),
                     doc="Particle shape of generated packings, as [packing] shape of "
                         "`hmm rve` (polygon: 2D only)."),
        "sides": Key("int", range=Range(3.0, 64.0), only=("dem", "adaptive"),
                     doc="Corners of each polygon, or the fewest with sides_max "
                         "(default 6)."),
        "sides_max": Key("int", range=Range(3.0, 64.0), only=("dem", "adaptive"),
                         doc="Optional: the most corners of a polygon."),
        "kn": Key("float", "N/m", default=1e8, range=POSITIVE, only=("dem", "adaptive"),
                  doc="Normal contact stiffness (linear law)."),
        "kt": Key("float", "N/m", default=5e7, range=NONNEGATIVE, only=("dem", "adaptive"),
                  doc="Tangential contact stiffness."),
        "mu": Key("float", default=0.5, range=NONNEGATIVE, only=("dem", "adaptive"),
                  doc="Friction coefficient."),
        "damping": Key("float", default=0.5, range=Range(0.0, 1.0, True, False),
                       only=("dem", "adaptive"), doc="Local damping of the RVEs."),
        "tol": Key("float", default=1e-3, range=POSITIVE, only=("dem", "adaptive"),
                   doc="Unbalanced-force ratio that ends a relaxation."),
        "max_step_strain": Key("float", default=1e-5, range=POSITIVE,
                               only=("dem", "adaptive"), doc="Largest strain per step."),
        "max_relax_steps": Key("int", default=200000, range=Range(1.0),
                               only=("dem", "adaptive"), doc="Step cap of a relaxation."),
        "relax": Key("bool", default=True, only=("dem", "adaptive"),
                     doc="Relax each RVE call to tol; false: stop once the strain "
                         "increment is imposed (YADE FEMxDEM's call)."),
        "tangent": Key("str", default="contact", choices=("contact", "perturbation"),
                       only=("dem", "adaptive"), doc="Tangent operator of the RVEs "
                       "(perturbation: relaxed probes, so relax = true only)."),
        "strain_threshold": Key("float", default=1e-4, range=POSITIVE, only=("adaptive",),
                                doc="Strain after which a point runs its RVE."),
        "ratio_threshold": Key("float", default=0.3, range=POSITIVE, only=("adaptive",),
                               doc="Stress ratio q/p after which a point runs its RVE."),
    }),
    "imperfection": Section(doc="Weak spots: the Gauss points inside a disc (a ball in "
                                "3D) start from their own packing, so that localisation "
                                "has a place to begin.", array=True, keys={
        "center": Key("vector", "m", default=REQUIRED, doc="Centre of the spot."),
        "radius": Key("float", "m", default=REQUIRED, range=POSITIVE,
                      doc="Radius of the spot."),
        "consolidation_friction": Key("float", range=NONNEGATIVE,
                                      doc="Friction while consolidating the spot's "
                                          "packing (higher: looser); default as [micro]."),
        "mu": Key("float", range=NONNEGATIVE,
                  doc="Contact friction in the spot; default as [micro]."),
        "packing": Key("path", doc="A packing file for the spot (else generated)."),
    }),
    "solver": Section(doc="Kinematics, Newton iterations and step cutting.", keys={
        "kinematics": Key("str", choices=KINEMATICS,
                          doc="small: a fixed mesh and the symmetric strain "
                              "increment; finite: updated Lagrangian, the mesh moves "
                              "and the RVEs get the whole displacement gradient "
                              "(default: finite for dem, adaptive, hypoelastic and "
                              "neo_hookean; small for linear_elastic and "
                              "hyperbolic, which are small-strain laws)."),
        "tol_residual": Key("float", default=1e-3, range=POSITIVE,
                            doc="Free residual over internal force norm."),
        "tol_displacement": Key("float", default=1e-3, range=POSITIVE,
                                doc="Correction over step displacement norm."),
        "max_iterations": Key("int", default=10, range=Range(1.0),
                              doc="Newton iterations before a step is cut."),
        "min_step": Key("float", default=1.0 / 64.0, range=Range(0.0, 1.0, False, True),
                        doc="Smallest step, as a fraction of the nominal one."),
        "aitken": Key("bool", default=True,
                      doc="Aitken relaxation of successive Newton corrections (steadies "
                          "the DEM's approximate tangent; false: plain Newton, "
                          "quadratic with an exact tangent)."),
        "coupling": Key("str", choices=("monolithic", "fixed_stress"),
                        doc="A saturated problem: Newton on displacement and pore "
                            "pressure at once (monolithic, the default), or the "
                            "fixed-stress split (the flow, then the mechanics, in each "
                            "iteration; YADE FEMxDEM's msFEMup)."),
        "check_residual": Key("bool", default=True,
                              doc="Converge on residual and correction; false: on the "
                                  "correction over the step's displacement (YADE "
                                  "FEMxDEM's criterion; a cut step's scaled to the "
                                  "nominal step) or the residual, either."),
    }),
    "fluid": Section(doc="The pore fluid of a saturated problem (Biot's u-p "
                         "equations, hmm.porous): with it the micro models give the "
                         "effective stress, [time] sets the steps in seconds and "
                         "[[drainage]] the hydraulic boundaries. Needs a quadratic "
                         "element (quad8 quad2 tri2 hex20 hex27 tet10) and small "
                         "kinematics.", keys={
        "permeability": Key("tensor", "m^2", range=POSITIVE,
                            doc="Intrinsic permeability k (required): a number "
                                "(isotropic) or a d x d symmetric positive definite "
                                "tensor."),
        "viscosity": Key("float", "Pa s", default=1e-3, range=POSITIVE,
                         doc="Dynamic viscosity of the fluid (water: 1e-3)."),
        "bulk_modulus": Key("float", "Pa", default=2.2e9, range=POSITIVE,
                            doc="Bulk modulus of the fluid (water: 2.2e9)."),
        "porosity": Key("float", default=0.4, range=Range(0.0, 1.0, False, False),
                        doc="Porosity n, which weighs the fluid's compressibility in "
                            "the storage 1/M = n/K_f + (biot - n)/K_s."),
        "biot": Key("float", default=1.0, range=Range(0.0, 1.0, False, True),
                    doc="Biot's coefficient alpha, in [porosity, 1]."),
        "solid_bulk_modulus": Key("float", "Pa", range=POSITIVE,
                                  doc="Bulk modulus of the grains K_s (default: "
                                      "incompressible grains)."),
        "initial_pressure": Key("float", "Pa", default=0.0,
                                doc="Uniform pore pressure at the start."),
        "permeability_law": Key("str", default="constant",
                                choices=("constant", "kozeny_carman"),
                                doc="kozeny_carman: the permeability scales with n^3 / "
                                    "(1 - n)^2 from its value at porosity, n following "
                                    "the volumetric strain at each Gauss point."),
    }),
    "drainage": Section(doc="Hydraulic conditions of a saturated problem: every "
                            "boundary not named here is impermeable.", array=True,
                        keys={
        "boundary": Key("str", default=REQUIRED, doc="Named boundary of the mesh."),
        "pressure": Key("float", "Pa", doc="Drained: the pore pressure held on the "
                                           "boundary from the first step on (this or "
                                           "flux)."),
        "flux": Key("float", "m/s", doc="Fluid volume entering per unit area and time "
                                        "(negative: leaving); this or pressure."),
    }),
    "time": Section(doc="The time of a saturated problem: [load] steps steps reach "
                        "end.", keys={
        "end": Key("float", "s", range=POSITIVE, doc="End of the run (required)."),
        "first": Key("float", "s", range=POSITIVE,
                     doc="The first step; the later ones grow geometrically to reach "
                         "end (default: equal steps)."),
        "ramp": Key("float", "s", default=0.0, range=NONNEGATIVE,
                    doc="The load factor rises from 0 to 1 over this time (0: the whole "
                        "load in the first step, carried undrained at first)."),
    }),
    "output": Section(doc="Where results go.", keys={
        "dir": Key("str", doc="Output directory; default output/<file stem>."),
        "every": Key("int", default=1, range=Range(1.0),
                     doc="Load steps between field frames."),
        "checkpoint_every": Key("int", default=0, range=NONNEGATIVE,
                                doc="Load steps between checkpoints (0: none)."),
    }),
}


def schema_markdown():
    """The problem file reference (Markdown), generated from :data:`SCHEMA`."""
    return _markdown(SCHEMA)


def load_problem(path):
    """Read and validate a problem file (a :class:`SceneError` on any problem)."""
    path = Path(path)
    return validate_problem(read_toml(path, "problem"), str(path), path.parent)


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
    dem.io.scene.SceneError: <problem>: [micro] young is not used with model = "dem" (only with "linear_elastic", "hyperbolic", "hypoelastic" or "neo_hookean")
    """
    out, ctx = validate(data, SCHEMA, source, base_dir, dim_key=("mesh", "dim"))
    m = out["mesh"]
    if m["file"] is None:
        if m["size"] is None or m["cells"] is None:
            ctx.fail("needs size and cells, or a mesh file", "[mesh]")
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

        check_shape(ctx, out["micro"], m["dim"], "[micro]")
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
        out["solver"]["kinematics"] = "small"
    elif out["solver"]["kinematics"] != "small":
        ctx.fail("a saturated problem runs under kinematics = \"small\" for now",
                 "[solver]")


def build_macro(problem):
    """The :class:`~hmm.macro.Macro` of a validated problem; boundary names checked."""
    from .macro import ELEMENTS, Macro, structured_mesh

    src = problem["source"]
    m = problem["mesh"]
    if m["file"] is None:
        mesh = structured_mesh(m["element"], m["size"], [int(c) for c in m["cells"]])
    else:
        mesh = read_mesh(m["file"], f"{src}: [mesh]")
        if not isinstance(mesh, ELEMENTS[m["element"]][0]):
            raise SceneError(f"{src}: [mesh] file holds a {type(mesh).__name__}, "
                             f"element \"{m['element']}\" needs a "
                             f"{ELEMENTS[m['element']][0].__name__}")
    if mesh.t.shape[1] == 0:
        raise SceneError(f"{src}: [mesh] has no elements")
    try:
        if m["file"] is not None:
            MESH_ELEMENTS.check(mesh.t.shape[1], f"the elements of {m['file']}")
    except LimitError as exc:
        raise SceneError(f"{src}: [mesh] {exc}") from None
    mesh = _cut_boundaries(problem, mesh)
    known = set(mesh.boundaries or {})
    for kind in ("dirichlet", "pressure", "traction", "drainage", "platen", "periodic"):
        for i, c in enumerate(problem[kind]):
            if c.get("point") is not None:
                if vertex_at(mesh, c["point"]) is None:
                    raise SceneError(f"{src}: [[{kind}]] #{i + 1} point = "
                                     f"{list(c['point'])} is not a vertex of the mesh")
                continue
            if c["boundary"] not in known:
                raise SceneError(f"{src}: [[{kind}]] #{i + 1} boundary "
                                 f"\"{c['boundary']}\" is not a boundary of the mesh "
                                 f"(known: {', '.join(sorted(known)) or 'none'})")
    for i, c in enumerate(problem["periodic"]):
        if c["image"] not in known:
            raise SceneError(f"{src}: [[periodic]] #{i + 1} image \"{c['image']}\" is not "
                             f"a boundary of the mesh (known: "
                             f"{', '.join(sorted(known)) or 'none'})")
    macro = Macro(mesh, m["element"], problem["solver"]["kinematics"], m["integration"])
    mc = problem["micro"]
    if mc["model"] in ("dem", "adaptive") and mc["packing"] is None:
        try:  # every Gauss point holds a copy of its packing
            PARTICLES.check(mc["count"] * macro.n_gp, f"count x Gauss points = "
                            f"{mc['count']} x {macro.n_gp}")
        except LimitError as exc:
            raise SceneError(f"{src}: [micro] {exc}") from None
    return macro


def read_mesh(path, where=None):
    """A scikit-fem mesh (its named boundaries included: gmsh physical groups, the
    sets of a file skfem saved) from a file meshio reads; a :class:`SceneError`
    starting with ``where`` (if given) for anything else.

    meshio prints to stdout and calls ``sys.exit`` on a file it cannot parse: its
    output is captured and turned into the one-line error.
    """
    import contextlib
    import io

    from skfem import Mesh

    lead = "" if where is None else f"{where} "
    if Path(path).is_dir():
        raise SceneError(f"{lead}mesh file {path} is a directory")
    said = io.StringIO()
    try:
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
            return Mesh.load(path)
    except SystemExit:
        reason = " ".join(said.getvalue().split()).removeprefix("Error: ") or \
            "meshio gave up on it"
    except Exception as err:  # noqa: BLE001 - meshio raises many kinds
        reason = f"{type(err).__name__}: {err}"
    raise SceneError(f"{lead}cannot read mesh file {path}: {reason}")


def _cut_boundaries(problem, mesh):
    """The mesh with the ``[[boundary]]`` parts added to its named boundaries
    (:func:`hmm.conditions.cut_boundary`)."""
    for i, b in enumerate(problem["boundary"]):
        try:
            mesh = cut_boundary(mesh, b["name"], b["of"], b["lo"], b["hi"])
        except ValueError as err:
            raise SceneError(f"{problem['source']}: [[boundary]] #{i + 1} {err}") from None
    return mesh


def build_loads(problem, macro):
    """Supports, the constant and ramped external force vectors (dead loads), and the
    configuration-dependent loads of finite kinematics: the problem's conditions as
    the objects of :mod:`hmm.conditions`, through :func:`hmm.conditions.supports` and
    :func:`hmm.conditions.external_forces`."""
    dirichlet = [Dirichlet(c["boundary"], c["component"], c["value"], c["gradient"],
                           c["origin"], c["point"]) for c in problem["dirichlet"]]
    platens = [Platen(c["boundary"], c["component"]) for c in problem["platen"]]
    periodic = [Periodic(c["boundary"], c["image"]) for c in problem["periodic"]]
    try:
        sup = supports(macro, dirichlet, platens, periodic, problem["load"]["gradient"])
    except ConditionError as err:
        where = f"[[{err.kind}]]" + ("" if err.index is None else f" #{err.index + 1}")
        raise SceneError(f"{problem['source']}: {where} {err.reason}") from None
    loads = [Pressure(p["boundary"], p["value"], p["ramp"], p["follower"])
             for p in problem["pressure"]]
    loads += [Traction(t["boundary"], tuple(t["value"]), t["per"])
              for t in problem["traction"]]
    b = problem["body_force"]
    loads.append(BodyForce(tuple(b["value"]), b["per"]))
    return (sup, *external_forces(macro, loads))


def build_porous(problem, macro):
    """The pressure field and the time schedule of a saturated problem
    (:class:`~hmm.porous.PorousMacro`, :class:`~hmm.porous.TimeSchedule`), or
    ``(None, None)`` for a dry one."""
    if problem["fluid"] is None:
        return None, None
    from .porous import Fluid, PorousMacro, TimeSchedule

    fl = problem["fluid"]
    ks = fl["solid_bulk_modulus"]
    fluid = Fluid(permeability=fl["permeability"], viscosity=fl["viscosity"],
                  bulk_modulus=fl["bulk_modulus"], porosity=fl["porosity"],
                  biot=fl["biot"], solid_bulk_modulus=math.inf if ks is None else ks,
                  initial_pressure=fl["initial_pressure"],
                  permeability_law=fl["permeability_law"])
    drained = {c["boundary"]: c["pressure"] for c in problem["drainage"]
               if c["pressure"] is not None}
    inflow = {c["boundary"]: c["flux"] for c in problem["drainage"]
              if c["flux"] is not None}
    tm = problem["time"]
    schedule = TimeSchedule(end=tm["end"], steps=problem["load"]["steps"],
                            first=tm["first"], ramp=tm["ramp"])
    return PorousMacro(macro, fluid, drained, inflow), schedule


def build_farm(problem, macro, progress=None):
    """The micro model of every Gauss point in a farm: a :class:`~hmm.farm.MPIFarm`
    when this process is one of several MPI ranks (every rank must call this), else a
    :class:`~hmm.farm.SerialFarm`.

    DEM points share packings: each distinct packing is generated (or read) once per
    rank and copied into every point that uses it.
    """
    from .farm import make_farm

    return make_farm(macro.n_gp, macro.dim,
                     model_factory(problem, macro.dim, progress, macro.gauss_points()))


def build_models(problem, n, dim, progress=None, points=None):
    """The ``n`` micro models of a validated problem (``points``: the Gauss points'
    coordinates (n, d), needed with ``[[imperfection]]``)."""
    factory = model_factory(problem, dim, progress, points)
    return [factory(g) for g in range(n)]


def spot_of(problem, points):
    """For every Gauss point, the index of the first ``[[imperfection]]`` that holds
    it, or -1.

    Examples
    --------
    >>> p = {"imperfection": [{"center": [0.0, 0.0], "radius": 1.0}]}
    >>> spot_of(p, np.array([[0.5, 0.5], [1.0, 1.0]])).tolist()
    [0, -1]
    """
    points = np.asarray(points, dtype=np.float64)
    spot = np.full(len(points), -1, dtype=np.int64)
    for i, imp in reversed(list(enumerate(problem["imperfection"]))):
        inside = np.linalg.norm(points - np.asarray(imp["center"]), axis=1) <= imp["radius"]
        spot[inside] = i
    return spot


def model_factory(problem, dim, progress=None, points=None):
    """``factory(g)``: a fresh micro model for Gauss point ``g`` in its initial state.

    DEM packings are made once, here, and copied by every call; the packing of an
    ``[[imperfection]]`` is made on first use, so a rank that owns none of its points
    never builds it. ``points`` are the Gauss points' coordinates (n_gp, d).
    """
    from .micro import (Adaptive, DEMMicroModel, Hyperbolic, Hypoelastic, LinearElastic,
                        NeoHookean)

    mc = problem["micro"]
    kind = mc["model"]
    if kind == "linear_elastic":
        return lambda g: LinearElastic(mc["young"], mc["poisson"], dim, mc["stress0"])
    if kind == "hyperbolic":
        return lambda g: Hyperbolic(mc["young"], mc["poisson"], mc["gamma_ref"], dim,
                                    mc["stress0"])
    if kind == "hypoelastic":
        return lambda g: Hypoelastic(mc["young"], mc["poisson"], dim, mc["stress0"])
    if kind == "neo_hookean":
        return lambda g: NeoHookean(mc["young"], mc["poisson"], dim)
    finite = problem["solver"]["kinematics"] == "finite"
    packings = [_packing(problem, k, dim, progress) for k in range(mc["packings"])]
    if problem["imperfection"] and points is None:
        raise ValueError("[[imperfection]] needs the Gauss points' coordinates")
    spot = None if points is None else spot_of(problem, points)
    weak = {}

    def packing_of(g):
        if spot is None or spot[g] < 0:
            return packings[g % len(packings)]
        i = int(spot[g])
        if i not in weak:
            weak[i] = _packing(problem, 0, dim, progress, problem["imperfection"][i])
        return weak[i]

    def factory(g):
        m = DEMMicroModel(clone_rve(packing_of(g)), tangent=mc["tangent"],
                          relax=mc["relax"])
        if kind == "adaptive":
            m = Adaptive(m, mc["strain_threshold"], mc["ratio_threshold"], finite)
        return m

    return factory


def _packing(problem, k, dim, progress, spot=None):
    """Packing ``k`` of ``[micro]``, or the packing of an ``[[imperfection]]``
    (``spot``): the first packing with the spot's friction and consolidation."""
    from dem import LinearSpring
    from dem import rve as rvemod

    mc = dict(problem["micro"])
    src = problem["source"]
    where = "[micro]"
    if spot is not None:
        where = "[[imperfection]]"
        mc.update({key: spot[key] for key in ("consolidation_friction", "mu", "packing")
                   if spot[key] is not None})
    opts = {"damping": mc["damping"], "tol": mc["tol"],
            "max_step_strain": mc["max_step_strain"],
            "max_relax_steps": mc["max_relax_steps"]}
    if mc["packing"] is not None:
        try:
            rve = rvemod.RVE.load_file(mc["packing"], **{k_: v for k_, v in opts.items()
                                                         if k_ != "damping"})
        except (OSError, ValueError) as err:
            raise SceneError(f"{src}: {where} packing: {err}") from None
        if rve.dim != dim:
            raise SceneError(f"{src}: {where} packing is {rve.dim}D, the mesh {dim}D")
        if spot is not None and spot["mu"] is not None:
            rve.set_friction(spot["mu"])
        return rve
    from .experiment_config import shape_maker

    law = LinearSpring(kn=mc["kn"], kt=mc["kt"], mu=mc["mu"])
    return rvemod.generate(dim, mc["count"], mc["radius"], law, mc["p0"],
                           density=mc["density"], seed=mc["seed"] + k,
                           friction=mc["consolidation_friction"],
                           shape=shape_maker(mc, dim), **opts)


def clone_rve(rve):
    """An independent copy of an RVE in its current state (bit-identical runs)."""
    from dem import rve as rvemod

    snap = rve.snapshot()
    twin = rvemod.RVE(rve.bodies.copy(), rve.law, rve.cell.copy(),
                      damping=rve.sim.damping, dt=rve.sim.dt, threads=rve.sim.threads,
                      **{k: getattr(rve, k) for k in rve._SETTINGS if k != "mass_scale"})
    twin.mass_scale = rve.mass_scale
    twin.restore(snap)
    return twin


def initial_stress_check(problem, farm, tol=0.05):
    """Relative mismatch between constant pressures and the micro models' initial
    stress (a constant pressure should balance it); returned for the log."""
    sig = farm.stress()
    p_micro = -np.trace(sig, axis1=1, axis2=2).mean() / sig.shape[1]
    const = [p["value"] for p in problem["pressure"] if not p["ramp"]]
    if not const or not math.isfinite(p_micro) or p_micro == 0.0:
        return 0.0
    return abs(np.mean(const) - p_micro) / abs(p_micro)
