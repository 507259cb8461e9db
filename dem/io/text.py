"""Formatting of values in one-line error messages (scene files, packings)."""


def fmt(x):
    """A number as ``%g``, anything else as ``str``; None as the empty string."""
    return "" if x is None else f"{x:g}" if isinstance(x, float) else str(x)


def tname(value):
    """The TOML name of a value's type."""
    names = {bool: "boolean", int: "integer", float: "float", str: "string",
             list: "array", dict: "table"}
    return names.get(type(value), type(value).__name__)


def show(value):
    """A value as a user wrote it, with its type where that helps.

    >>> show([1.0, "a"]), show(True)
    ('[1, "a"]', 'true (boolean)')
    """
    if isinstance(value, str):
        return f'"{value}" (string)'
    if isinstance(value, bool):
        return f"{str(value).lower()} (boolean)"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "[" + ", ".join(show(v).split(" (")[0] for v in value) + "]"
    if isinstance(value, (int, float)):
        return fmt(value)
    return f"{value} ({tname(value)})"


def reason(exc):
    """The short reason of an OS or parse error."""
    return getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
