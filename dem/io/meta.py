"""What every HDF5 file the project writes says about itself.

The root of each file carries

- ``format``: what kind of file it is (``"dem.h5writer"``, ``"dem.checkpoint"``,
  ``"hmm.fields"``, ...), and ``version``, the version of that layout (an integer);
- ``software``: the project and its version, ``"femxdem 0.1.0"``
  (:func:`software`, what ``dem --version`` prints);
- ``config``: the configuration that made it (the input TOML file's text, or the
  run's settings as JSON), where there is one.

Every dataset carries ``unit`` (an SI unit string, ``"1"`` for a dimensionless
number, an index or a flag) and, where a sign matters, ``sign`` (e.g. ``"tension
positive"``). ``docs/conventions.md`` lists them file by file.

:func:`label` puts units on the datasets of a group from a table of rules;
:func:`check_format` is how readers refuse a file of another kind. :data:`STATE_UNITS`
and :func:`state_units` are the rules of a simulation's state arrays (checkpoints,
snapshots, an RVE's state inside an hmm checkpoint).
"""

import json
import re

import h5py
import numpy as np

#: the sign conventions, spelled the same everywhere
TENSION = "tension positive"
COMPRESSION = "compression positive"
EXTENSION = "extension positive"
#: a unit for data without one: indices, counts, flags, codes
ONE = "1"


def project_version():
    """The version of the installed ``femxdem`` distribution, or ``"unknown"``.

    >>> isinstance(project_version(), str)
    True
    """
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("femxdem")
    except PackageNotFoundError:
        return "unknown"


def software():
    """``"femxdem VERSION"``: the ``software`` attribute of every file."""
    return f"femxdem {project_version()}"


def stamp(f, fmt, version, config=None):
    """Tag the root of an open h5py file ``f``: ``format``, ``version``,
    ``software`` and, when given, ``config`` (a str is stored as it is, anything
    else as JSON)."""
    f.attrs["format"] = fmt
    f.attrs["version"] = int(version)
    f.attrs["software"] = software()
    if config is not None:
        f.attrs["config"] = config if isinstance(config, str) else \
            json.dumps(config, sort_keys=True, default=str)


def text(value):
    """An attribute as str (h5py gives bytes for some strings), other values as
    they are."""
    return value.decode(errors="replace") if isinstance(value, bytes) else value


def tag(f):
    """The ``format`` tag of an open file, or None."""
    value = text(f.attrs.get("format"))
    return value if isinstance(value, str) else None


def check_format(f, path, fmt, versions):
    """Refuse (ValueError, one line) an open file ``f`` that is not a ``fmt`` file of
    one of ``versions``; returns its version."""
    found = tag(f)
    if found != fmt:
        what = f"a {found!r} file" if found is not None else \
            "an HDF5 file without a format tag"
        raise ValueError(f"{path} is {what}, not a {fmt!r} file")
    version = text(f.attrs.get("version"))
    if isinstance(version, np.integer):
        version = int(version)
    if not isinstance(version, int) or version not in versions:
        shown = version if isinstance(version, (int, str)) or version is None \
            else np.asarray(version).tolist()
        raise ValueError(f"{path}: {fmt} version {shown!r} is not one this "
                         f"reader knows ({', '.join(map(str, versions))})")
    return version


_DIGITS = re.compile(r"\d+")


def rules(*table):
    """A list of compiled rules ``(pattern, unit, sign)``: ``pattern`` is a regular
    expression matched against a dataset's path inside the labelled group (the
    whole path, ``re.fullmatch``); the first rule that matches gives the unit.
    A rule must not tell one number from another (``\\d+``, never ``7``): numbers
    in a path are all looked up as ``0``."""
    return [(re.compile(p), unit, sign) for p, unit, sign in table]


def unit_of(path, table):
    """``(unit, sign)`` of the dataset at ``path`` by the first matching rule of
    ``table``, or None.

    >>> unit_of("steps/00001/stress_xx", rules((r".*stress_\\w+", "Pa", TENSION)))
    ('Pa', 'tension positive')
    """
    for pattern, unit, sign in table:
        if pattern.fullmatch(path):
            return unit, sign
    return None


def label(group, table, prefix=""):
    """Set ``unit`` (and ``sign``) on every dataset under ``group`` that has none,
    by ``table`` (:func:`rules`) matched against ``prefix`` + the dataset's path
    relative to ``group``. A dataset no rule matches gets ``unit = "unknown"``
    (tests look for those)."""
    seen = {}  # the rules do not tell numbers apart: one lookup per path shape

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset) and "unit" not in obj.attrs:
            shape = _DIGITS.sub("0", prefix + name)
            if shape not in seen:
                seen[shape] = unit_of(shape, table)
            found = seen[shape]
            unit, sign = found if found is not None else ("unknown", None)
            obj.attrs["unit"] = unit
            if sign:
                obj.attrs["sign"] = sign

    group.visititems(visit)


# --------------------------------------------------------------------------- state
#: any path prefix: a group (``bodies/``) or a snapshot key's (``b.``, ``cell_``)
_ANY = r"(?:.*[/._])?"
#: units of the arrays of a simulation's state, by name (a checkpoint's datasets,
#: a snapshot's keys, an RVE's state inside an hmm checkpoint)
STATE_UNITS = (
    (r"(?:.*/)?meshes/(vertices|vert_ref|center|mpoint)", "m", None),
    (r"(?:.*/)?meshes/mhist", "m", "tangential spring of the law's history"),
    (r"(?:.*/)?meshes/velocity", "m/s", None),
    (r"(?:.*/)?meshes/ang_vel", "rad/s", "right-handed"),
    (r"(?:.*/)?meshes/mforce", "N", "on the sphere"),
    (r"(?:.*/)?meshes/mtorque", "N m", "on the sphere"),
    (r"(?:.*/)?meshes/mpower", "W", "of the wall's force on the sphere"),
    (r"(?:.*/)?meshes/(faces|face_normal|mrows|mtouch|mstart|vert_wall|face_wall"
     r"|mat_id)", ONE, None),
    (_ANY + r"(pos|pos_ref|pos_inner|radius|radius_ref|brad|part_off|part_rad|verts"
     r"|lo|hi|origin|h|param)", "m", None),
    (_ANY + r"(hist|whist)", "m", "tangential spring of the law's history"),
    (_ANY + r"ang_vel", "rad/s", "counter-clockwise positive (right-handed)"),
    (_ANY + r"vel", "m/s", None),
    (_ANY + r"(force|fpair|wforce)", "N", None),
    (_ANY + r"(torque|wtorque|tpair)", "N m", None),
    (_ANY + r"mass", "kg", None),
    (_ANY + r"inertia", "kg m^2", None),
    (_ANY + r"density", "kg/m^3", None),
    (_ANY + r"gravity", "m/s^2", None),
    (_ANY + r"wall_work", "J", None),
    (_ANY + r"lgrad", "1/s", None),
    (_ANY + r"cellref", "1/m", "inverse cell matrices"),
    (_ANY + r"(kind|mat_id|is_fixed|shape|normal|pairs|img|wall_pairs|touch|iters"
     r"|witers|inner|n_inner|clock|n|vstart|fstart|tstart|tris|cstart|part_kind"
     r"|part_row|part_rot|scale|periodic|deformation|iterations|pending|active"
     r"|strain)", ONE, None),
    (_ANY + r"(pgeom|wgeom)", "mixed", "columns: overlap [m] (positive in contact), "
                                       "contact point [m], normal [1]"),
    (_ANY + r"(warm|wwarm)", "mixed", "warm start of the ADMM contact solver"),
    (_ANY + r"xform", "mixed", "rotation [1] (9) and offset [m] (3)"),
    (_ANY + r"faces", "mixed", "outward normal [1] (3) and offset [m] (1)"),
    (_ANY + r"params_p[pw]", "mixed", "the contact law's parameters, SI"),
    (_ANY + r"(stress|sigma)", "Pa", TENSION),
    (_ANY + r"(tangent|c_elastic)", "Pa", None),
)


def state_units(dim):
    """The unit rules (:func:`dem.io.meta.rules`) of a ``dim``-dimensional state:
    :data:`STATE_UNITS` with the orientation ``rot`` (an angle [rad] in 2D, a
    quaternion in 3D)."""
    where = r"(?:.*[/.])?rot"  # a body's, not a compound part's (part_rot)
    rot = (where, "rad", "counter-clockwise positive") if dim == 2 else \
        (where, ONE, "(w, x, y, z), rotation body to world")
    return rules(*STATE_UNITS, rot)
