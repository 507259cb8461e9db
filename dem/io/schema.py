"""Input files as data: a schema of sections and keys, and its validation.

A schema is ``{name: Section}``; a :class:`Section` holds :class:`Key` specs (type,
unit, default, :class:`Range`, choices, the variants a key belongs to). :func:`validate`
checks parsed TOML against a schema and fills defaults; every problem is a
:class:`SceneError` whose message is one line naming the file and the full key path.
:func:`read_toml` reads a file within the size and nesting limits, and
:func:`schema_markdown` renders a schema as a reference page. Scene files
(:mod:`dem.io.scene`), problem files, RVE tests and sweeps (``hmm``) are all written in
this form.
"""

import difflib
import math
from dataclasses import dataclass
from pathlib import Path

import tomllib

from ..limits import INT64_MAX, MAX_DEPTH, MAX_FILE_BYTES
from .text import fmt as _fmt
from .text import reason as _reason
from .text import show as _show
from .text import tname as _tname

__all__ = ["NONNEGATIVE", "POSITIVE", "REQUIRED", "UNIT_OPEN_CLOSED", "Key", "Range",
           "SceneError", "Section", "read_toml", "schema_markdown", "validate"]


class SceneError(ValueError):
    """An invalid scene; the message is one line naming the file and the key."""

    def __init__(self, msg):
        super().__init__(" ".join(str(msg).split()))


class _Required:
    def __repr__(self):
        return "required"


#: marks a key that has no default
REQUIRED = _Required()


@dataclass(frozen=True)
class Range:
    """The physical range of a number: ``lo``/``hi`` bounds, closed or open."""

    lo: float = None
    hi: float = None
    lo_closed: bool = True
    hi_closed: bool = True

    def __contains__(self, x):
        lo, hi = self.lo, self.hi
        above = lo is None or (x >= lo if self.lo_closed else x > lo)
        below = hi is None or (x <= hi if self.hi_closed else x < hi)
        return above and below

    def __str__(self):
        lo, hi = _fmt(self.lo), _fmt(self.hi)
        if self.lo is not None and self.hi is not None:
            left, right = "[(" [not self.lo_closed], "])" [not self.hi_closed]
            return f"in {left}{lo}, {hi}{right}"
        if self.lo is not None:
            return f"{'>=' if self.lo_closed else '>'} {lo}"
        if self.hi is not None:
            return f"{'<=' if self.hi_closed else '<'} {hi}"
        return "any value"


@dataclass(frozen=True)
class Key:
    """One key of a section.

    ``type`` is one of ``int``, ``float``, ``bool``, ``str``, ``vector`` (``dim``
    numbers), ``radius`` (a number or ``[min, max]``), ``tensor`` (a number or ``dim``
    rows of ``dim`` numbers; ``range`` applies to a number only), ``axes`` (distinct
    axis names among the first ``dim`` of x, y, z), ``pair`` (two non-empty names) and
    ``path`` (a file name relative to the scene). ``default`` is a value, ``None``
    (optional: computed when absent) or :data:`REQUIRED`. ``only`` lists the variants
    (generators, laws) the key belongs to (empty: all); ``required_for`` the variants
    for which it is required.
    """

    type: str
    unit: str = "-"
    default: object = None
    range: Range = None
    choices: tuple = ()
    only: tuple = ()
    required_for: tuple = ()
    doc: str = ""


@dataclass(frozen=True)
class Section:
    """A table (``[name]``) or an array of tables (``[[name]]``) of :class:`Key`."""

    keys: dict
    doc: str = ""
    required: bool = False
    array: bool = False
    variant: str = None  # the key whose value selects which keys apply


POSITIVE = Range(0.0, lo_closed=False)
NONNEGATIVE = Range(0.0)
UNIT_OPEN_CLOSED = Range(0.0, 1.0, lo_closed=False)


def read_toml(path, what="scene"):
    """Parse a TOML file; a :class:`SceneError` (one line) if unreadable or invalid.

    Files above :data:`dem.limits.MAX_FILE_BYTES` and arrays or tables nested deeper
    than :data:`dem.limits.MAX_DEPTH` are refused (no input file needs them, and
    the parser and the validation recurse into nested values).
    """
    path = Path(path)
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_FILE_BYTES + 1)
        if len(raw) > MAX_FILE_BYTES:
            raise SceneError(f"{path}: the {what} file is larger than "
                             f"{MAX_FILE_BYTES // 2**20} MiB, the most an input file "
                             f"may hold")
        text = raw.decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{path}: cannot read {what} file: {_reason(exc)}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: invalid TOML: {exc}") from None
    except RecursionError:
        data = None
    if data is None or _depth(data) > MAX_DEPTH:
        raise SceneError(f"{path}: arrays or tables are nested more than {MAX_DEPTH} "
                         f"levels deep, the most an input file may nest")
    return data


def _depth(value):
    """How deeply arrays and tables nest in ``value`` (a scalar: 0), without
    recursion."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        v, level = stack.pop()
        if isinstance(v, (dict, list)):
            level += 1
            deepest = max(deepest, level)
            if level <= MAX_DEPTH:  # one level beyond the limit is enough to refuse
                stack.extend((x, level) for x in (v.values() if isinstance(v, dict)
                                                  else v))
    return deepest


def validate(data, schema, source="<file>", base_dir=".", dim_key=None, dim=3):
    """Check parsed TOML ``data`` against a ``schema`` ({name: :class:`Section`}).

    ``dim_key`` = (section, key) names the integer that sets the length of vector
    keys (else ``dim``). Returns ``(validated, context)``: the context's ``fail``
    raises a :class:`SceneError` in the same one-line form, for cross checks.
    """
    ctx = _Context(source, Path(base_dir))
    ctx.dim = dim
    if not isinstance(data, dict):
        raise SceneError(f"{source}: the file must be a TOML table")
    for name in data:
        if name not in schema:
            what = "section" if isinstance(data[name], (dict, list)) else "key"
            shown = f"[{name}]" if what == "section" else f"'{name}'"
            ctx.fail(f"unknown {what} {shown}{_suggest(name, schema)}")
    if dim_key is not None:
        sec, key = dim_key
        raw = data.get(sec)
        if isinstance(raw, dict) and key in raw:  # vectors everywhere need dim first
            ctx.dim = _check_value(ctx, f"[{sec}]", key, schema[sec].keys[key], raw[key])
        elif schema[sec].keys[key].default not in (None, REQUIRED):
            ctx.dim = schema[sec].keys[key].default
    out = {}
    for name, section in schema.items():
        raw = data.get(name)
        if section.array:
            out[name] = _validate_array(ctx, name, section, raw)
        else:
            if raw is None:
                if section.required:
                    ctx.fail(f"missing required section [{name}]")
                raw = {}
            out[name] = _validate_table(ctx, f"[{name}]", section, raw)
    out["source"] = source
    return out, ctx


class _Context:
    def __init__(self, source, base_dir):
        self.source, self.base_dir, self.dim = source, base_dir, 3

    def fail(self, msg, where=None):
        prefix = f"{self.source}: " + (f"{where} " if where else "")
        raise SceneError(prefix + msg)


def _validate_array(ctx, name, section, raw):
    if raw is None:
        return []
    if isinstance(raw, dict):
        ctx.fail(f"[{name}] must be an array of tables: write [[{name}]]")
    if not isinstance(raw, list):
        ctx.fail(f"{name} must be an array of tables ([[{name}]]), got {_tname(raw)}")
    return [_validate_table(ctx, f"[[{name}]] #{i + 1}", section, item)
            for i, item in enumerate(raw)]


def _validate_table(ctx, where, section, raw):
    if not isinstance(raw, dict):
        ctx.fail(f"must be a table, got {_tname(raw)}", where)
    for key in raw:
        if key not in section.keys:
            ctx.fail(f"unknown key '{key}'{_suggest(key, section.keys)}", where)
    variant = None
    if section.variant is not None:
        name = section.variant
        variant = _check_value(ctx, where, name, section.keys[name],
                               raw.get(name, REQUIRED))
    out = {}
    for key, spec in section.keys.items():
        if spec.only and variant not in spec.only:
            if key in raw:
                ctx.fail(f"{key} is not used with {section.variant} = \"{variant}\" "
                         f"(only with {_alternatives(spec.only)})", where)
            continue
        if key in raw:
            value = raw[key]
        elif variant in spec.required_for:
            value = REQUIRED
        elif spec.type == "vector" and isinstance(spec.default, float):
            value = [spec.default] * ctx.dim  # a scalar default fills every component
        else:
            value = spec.default
        out[key] = _check_value(ctx, where, key, spec, value)
    return out


def _check_value(ctx, where, key, spec, value):
    if value is REQUIRED:
        ctx.fail(f"missing required key '{key}' ({_describe(spec)})", where)
    if value is None:
        return None
    t = spec.type
    if t == "vector":
        if not isinstance(value, list) or len(value) != ctx.dim:
            ctx.fail(f"{key} must be an array of {ctx.dim} numbers (dim = {ctx.dim}), "
                     f"got {_show(value)}", where)
        return [_number(ctx, where, f"{key}[{i}]", spec, v)
                for i, v in enumerate(value)]
    if t == "coordinates":
        if not isinstance(value, list) or len(value) < 2:
            ctx.fail(f"{key} must be an array of at least 2 increasing numbers, got "
                     f"{_show(value)}", where)
        xs = [_number(ctx, where, f"{key}[{i}]", spec, v) for i, v in enumerate(value)]
        if any(b <= a for a, b in zip(xs, xs[1:], strict=False)):
            ctx.fail(f"{key} must increase from each number to the next, got "
                     f"{_show(value)}", where)
        return xs
    if t == "tensor":
        if not isinstance(value, list):
            return _number(ctx, where, key, spec, value, f"a number or {ctx.dim} rows "
                           f"of {ctx.dim} numbers")
        if len(value) != ctx.dim or any(not isinstance(row, list) or len(row) != ctx.dim
                                        for row in value):
            ctx.fail(f"{key} must be a number or {ctx.dim} rows of {ctx.dim} numbers "
                     f"(dim = {ctx.dim}), got {_show(value)}", where)
        free = Key("float")
        return [[_number(ctx, where, f"{key}[{i}][{j}]", free, v)
                 for j, v in enumerate(row)] for i, row in enumerate(value)]
    if t == "axes":
        names = "xyz"[:ctx.dim]
        if (not isinstance(value, list) or not value
                or any(not isinstance(a, str) or a not in names for a in value)
                or len(set(value)) != len(value)):
            ctx.fail(f"{key} must be a list of distinct axes among "
                     f"{_show(list(names))}, got {_show(value)}", where)
        return list(value)
    if t == "pair":
        if (not isinstance(value, list) or len(value) != 2
                or any(not isinstance(v, str) or not v for v in value)):
            ctx.fail(f"{key} must be two names, e.g. [\"sand\", \"walls\"], got "
                     f"{_show(value)}", where)
        return list(value)
    if t == "radius":
        if isinstance(value, list):
            if len(value) != 2:
                ctx.fail(f"{key} must be a number or [min, max], got {_show(value)}",
                         where)
            lo, hi = (_number(ctx, where, f"{key}[{i}]", spec, v)
                      for i, v in enumerate(value))
            if lo > hi:
                ctx.fail(f"{key} = [min, max] needs min <= max, got {_show(value)}",
                         where)
            return [lo, hi]
        return _number(ctx, where, key, spec, value, "a number or [min, max]")
    if t in ("int", "float"):
        v = _number(ctx, where, key, spec, value)
    elif t == "bool":
        if not isinstance(value, bool):
            ctx.fail(f"{key} must be true or false, got {_show(value)}", where)
        v = value
    elif t in ("str", "path"):
        if not isinstance(value, str) or not value:
            ctx.fail(f"{key} must be a non-empty string, got {_show(value)}", where)
        v = value
        if t == "path":
            v = str(ctx.base_dir / value)
    else:  # pragma: no cover - schema bug
        raise TypeError(f"unknown schema type {t!r}")
    if spec.choices and v not in spec.choices:
        ctx.fail(f"{key} must be {_alternatives(spec.choices)}, got {_show(value)}",
                 where)
    return v


def _number(ctx, where, key, spec, value, expected=None):
    is_int = spec.type == "int"
    expected = expected or ("an integer" if is_int else "a number")
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        ctx.fail(f"{key} must be {expected}, got {_show(value)}", where)
    if isinstance(value, float) and not math.isfinite(value):
        ctx.fail(f"{key} must be finite, got {value}", where)
    if is_int and value != int(value):
        ctx.fail(f"{key} must be {expected}, got {value}", where)
    if is_int and not -INT64_MAX - 1 <= value <= INT64_MAX:
        ctx.fail(f"{key} must be a 64-bit integer (at most {INT64_MAX}), got {value}",
                 where)
    try:
        value = int(value) if is_int else float(value)
    except OverflowError:
        ctx.fail(f"{key} is out of range, got {value}", where)
    if spec.range is not None and value not in spec.range:
        ctx.fail(f"{key} must be {spec.range}, got {_fmt(value)}", where)
    return value


# --------------------------------------------------------------------------- text
def _toml(value):
    if isinstance(value, str):
        return f'"{value}"'
    return str(value).lower() if isinstance(value, bool) else str(value)


def _alternatives(options):
    q = [_toml(o) for o in options]
    return q[0] if len(q) == 1 else ", ".join(q[:-1]) + " or " + q[-1]


def _suggest(name, known):
    close = difflib.get_close_matches(name, list(known), n=1)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _describe(spec):
    kind = {"vector": "array of dim numbers", "radius": "number or [min, max]",
            "tensor": "number or dim x dim array",
            "coordinates": "array of increasing numbers",
            "path": "file name", "str": "string", "int": "integer", "float": "number",
            "bool": "boolean", "axes": "list of axis names",
            "pair": "two names"}[spec.type]
    return kind + (f", {spec.unit}" if spec.unit != "-" else "")


def schema_markdown(schema):
    """A schema ({name: :class:`Section`}) as a Markdown reference, a table per section.

    >>> print(schema_markdown({"run": Section({"steps": Key("int")})}).splitlines()[0])
    ## [run]
    """
    lines = []
    for name, sec in schema.items():
        head = f"[[{name}]]" if sec.array else f"[{name}]"
        doc = sec.doc + (" Required." if sec.required else "")
        lines += [f"## {head}", "", doc, "",
                  "| key | type | unit | default | range | applies to | description |",
                  "|---|---|---|---|---|---|---|"]
        for key, k in sec.keys.items():
            default = "required" if k.default is REQUIRED else (
                "computed" if k.default is None else _toml(k.default))
            if k.required_for:
                alts = _alternatives(k.required_for)
                default = f"required for {alts}, else {default}"
            rng = (_alternatives(k.choices) if k.choices
                   else str(k.range) if k.range else "")
            only = _alternatives(k.only) if k.only else "all"
            cells = (f"`{key}`", k.type, k.unit, default, rng, only, k.doc)
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)
