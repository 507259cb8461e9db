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
:func:`check_format` is how readers refuse a file of another kind.
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
