"""Sweeps of standalone RVE tests: the file format, ``batch.h5`` and the summaries.

``mpiexec -n N hmm batch sweep.toml`` (:func:`hmm.cli.cmd_batch`). A sweep file holds a
``[base]`` experiment (the sections of an ``hmm rve`` file: ``packing``, ``contact``,
``test``) and a ``[sweep]`` of variations of it: a ``grid`` (key path -> values, the
Cartesian product) or a ``list`` of override tables. Every experiment is validated
against :data:`hmm.experiment_config.RVE_SCHEMA` before anything runs and gets a stable id,
its index and a hash of its overrides (``003-1a2b3c4d``).

The experiments run through the master-worker queue of :mod:`hmm.queue`, which
records each in ``batch.h5`` (:class:`Store`) as it ends and writes ``summary.csv``
and ``summary.png`` (:func:`write_summaries`) at the end.

Resume: a rerun into the same ``batch.h5`` skips the experiments stored there (done
or failed) after checking that their settings are those of the sweep; a changed sweep
is refused unless ``overwrite``. The stored numbers do not depend on the number of
ranks or on interruptions; only ``wall_time`` and ``rank`` (run metadata) do.

``docs/batch.md`` documents the format, the files and the command.
"""

import copy
import csv
import difflib
import hashlib
import io
import itertools
import json
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dem.io.meta import stamp
from dem.io.schema import Key, SceneError, Section, read_toml, validate
from dem.limits import Limit, LimitError

from .experiment_config import RVE_SCHEMA, validate_config
from .experiment_output import SUMMARY_UNITS, UNITS, curve_attrs

log = logging.getLogger(__name__)

__all__ = ["BATCH_SCHEMA", "Experiment", "Store", "Sweep", "expand", "experiment_id",
           "load_sweep", "read_batch", "write_summaries"]

FORMAT, VERSION = "hmm.batch", 1
OUTPUTS = ("batch.h5", "summary.csv", "summary.png")
#: group attributes that describe the run, not the experiment (they may differ)
RUN_METADATA = ("wall_time", "rank")
#: the sections of [base] a sweep may vary
SWEPT_SECTIONS = ("packing", "contact", "test")
#: experiments of one sweep (a grid's product is checked before it is built)
EXPERIMENTS = Limit(10**5, "HMM_MAX_EXPERIMENTS", "experiments")


class _Text:
    """A default shown verbatim in the generated reference."""

    def __init__(self, text):
        self.text = text

    def __str__(self):
        return self.text


BATCH_SCHEMA = {
    "sweep": Section(doc="The variations of [base]: exactly one of grid and list. "
                         "A key path is section.key of [base], e.g. "
                         "\"test.confining\" (quoted, or written as a dotted key).",
                     required=True, keys={
        "grid": Key("table", default=_Text("one of grid, list"),
                    doc="Key path = [values]: one experiment per combination (the "
                        "Cartesian product; the last path varies fastest)."),
        "list": Key("array of tables", default=_Text("one of grid, list"),
                    doc="[[sweep.list]] tables of key path = value: one experiment "
                        "each, in order."),
    }),
    "output": Section(doc="Files written by `hmm batch`.", keys={
        "dir": Key("str", doc="Output directory; default output/<file stem>."),
    }),
}


# --------------------------------------------------------------------------- input
@dataclass(frozen=True)
class Experiment:
    """One experiment of a sweep: ``config`` is a validated RVE test config."""

    id: str
    index: int
    overrides: dict
    config: dict = field(repr=False)

    @property
    def key(self):
        """The settings that decide its results, as canonical JSON."""
        return _canonical({k: v for k, v in self.config.items()
                           if k not in ("source", "output")})


@dataclass
class Sweep:
    """A validated sweep file: its experiments and where the output goes."""

    source: str
    experiments: list
    parameters: list  # swept key paths, in order of first appearance
    out_dir: str
    data: dict = None  # the parsed file: batch.h5's ``config`` attribute (as JSON)


def load_sweep(path):
    """Read and validate a sweep file (SceneError, one line, on any problem)."""
    path = Path(path)
    return expand(read_toml(path, "sweep"), str(path), path.parent)


def expand(data, source="<sweep>", base_dir="."):
    """The :class:`Sweep` of parsed TOML ``data``; every experiment validated.

    Examples
    --------
    >>> s = expand({"base": {"packing": {"count": 40, "radius": 1e-3, "p0": 1e5},
    ...                      "contact": {"law": "linear", "kn": 1e8, "kt": 5e7,
    ...                                  "mu": 0.5}},
    ...             "sweep": {"grid": {"test.confining": [5e4, 1e5],
    ...                                "packing": {"seed": [1, 2]}}}}, "s.toml")
    >>> [e.overrides["packing.seed"] for e in s.experiments], s.out_dir
    ([1, 2, 1, 2], 'output/s')
    >>> s.experiments[0].id
    '000-24e570fc'
    >>> expand({"base": {}, "sweep": {"grid": {"test.confining_pressure": [1]}}})
    ... # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    dem.io.schema.SceneError: <sweep>: [sweep] grid: ... (did you mean 'test.confining'?)
    """
    if not isinstance(data, dict):
        raise SceneError(f"{source}: the file must be a TOML table")
    for name in data:
        if name not in ("base", "sweep", "output"):
            close = difflib.get_close_matches(name, ["base", "sweep", "output"], 1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise SceneError(f"{source}: unknown section [{name}]{hint}")
    base = data.get("base")
    if not isinstance(base, dict):
        raise SceneError(f"{source}: missing section [base] (the experiment to vary)")
    if "output" in base:
        raise SceneError(f"{source}: [base] output is not used: the batch writes into "
                         f"the top-level [output] dir")
    out = validate({"output": data.get("output", {})},
                   {"output": BATCH_SCHEMA["output"]}, source)[0]["output"]
    out_dir = out["dir"] or str(Path("output") / (Path(source).stem.strip("<>")
                                                  or "sweep"))
    combos = _combinations(data.get("sweep"), source)
    parameters = list(dict.fromkeys(p for c in combos for p in c))
    experiments, seen = [], {}
    for index, overrides in enumerate(combos):
        exp_id = experiment_id(index, overrides)
        raw = copy.deepcopy(base)
        for path, value in overrides.items():
            section, key = path.split(".")
            if not isinstance(raw.setdefault(section, {}), dict):
                raise SceneError(f"{source}: [base] {section} must be a table")
            raw[section][key] = copy.deepcopy(value)
        cfg = validate_config(raw, f"{source} experiment {exp_id}", base_dir)
        if cfg["test"]["kind"] != "drained":
            raise SceneError(f"{source}: experiment {exp_id}: [test] kind = "
                             f"\"{cfg['test']['kind']}\": a batch sweeps drained tests "
                             f"(its summary is their friction and dilatancy angles)")
        canon = _canonical(overrides)
        if canon in seen:
            raise SceneError(f"{source}: experiments {seen[canon]} and {exp_id} have "
                             f"the same overrides {canon}")
        seen[canon] = exp_id
        experiments.append(Experiment(exp_id, index, overrides, cfg))
    return Sweep(source, experiments, parameters, out_dir, data)


def experiment_id(index, overrides):
    """``"<index>-<hash>"``: 3+ digits and 8 hex digits of the overrides' SHA-1.

    >>> experiment_id(7, {"packing.seed": 1})
    '007-28dd541c'
    """
    digest = hashlib.sha1(_canonical(overrides).encode()).hexdigest()[:8]
    return f"{index:03d}-{digest}"


def _canonical(value):
    return json.dumps(value, sort_keys=True, separators=(",", ":"))


def _combinations(sweep, source):
    """The override tables ({path: value}) of a [sweep], in order."""
    where = f"{source}: [sweep]"
    if not isinstance(sweep, dict):
        raise SceneError(f"{source}: missing section [sweep] (a grid or a list)")
    unknown = [k for k in sweep if k not in ("grid", "list")]
    if unknown or len(sweep) != 1:
        raise SceneError(f"{where} needs exactly one of grid and list"
                         + (f", got unknown key '{unknown[0]}'" if unknown else ""))
    if "grid" in sweep:
        grid = _paths(sweep["grid"], f"{where} grid")
        if not grid:
            raise SceneError(f"{where} grid is empty")
        for path, values in grid.items():
            if not isinstance(values, list) or not values:
                raise SceneError(f"{where} grid: '{path}' must be a non-empty array of "
                                 f"values")
        paths = list(grid)
        try:
            EXPERIMENTS.check(math.prod(len(v) for v in grid.values()),
                              "grid experiments = " + " x ".join(
                                  str(len(v)) for v in grid.values()))
        except LimitError as exc:
            raise SceneError(f"{where} {exc}") from None
        return [dict(zip(paths, combo, strict=True))
                for combo in itertools.product(*grid.values())]
    entries = sweep["list"]
    if not isinstance(entries, list) or not entries or not all(
            isinstance(e, dict) for e in entries):
        raise SceneError(f"{where} list must be a non-empty array of tables "
                         f"([[sweep.list]])")
    try:
        EXPERIMENTS.check(len(entries), "list experiments")
    except LimitError as exc:
        raise SceneError(f"{where} {exc}") from None
    return [_paths(e, f"{where} list #{i + 1}") for i, e in enumerate(entries)]


def _paths(table, where):
    """``{section: {key: v}}`` or ``{"section.key": v}`` -> ``{"section.key": v}``."""
    if not isinstance(table, dict):
        raise SceneError(f"{where} must be a table of key paths")
    flat = {}
    for name, value in table.items():
        items = ([(f"{name}.{k}", v) for k, v in value.items()]
                 if isinstance(value, dict) else [(name, value)])
        for path, v in items:
            _check_path(path, where)
            flat[path] = _normalised(path, v)
    return flat


def _check_path(path, where):
    valid = [f"{s}.{k}" for s in SWEPT_SECTIONS for k in RVE_SCHEMA[s].keys]
    if path not in valid:
        section = path.split(".")[0]
        same = [v for v in valid if v.split(".")[0] == section]  # a key of a section
        close = difflib.get_close_matches(path, same, 1, 0.5) or \
            difflib.get_close_matches(path, valid, 1)
        hint = f" (did you mean '{close[0]}'?)" if close else \
            " (a key path is section.key of [base]: packing, contact or test)"
        raise SceneError(f"{where}: unknown key path '{path}'{hint}")


def _normalised(path, value):
    """Integers written for float keys become floats (so 100000 and 1e5 match)."""
    section, key = path.split(".")
    if RVE_SCHEMA[section].keys[key].type not in ("float", "radius"):
        return value

    def f(v):
        if isinstance(v, list):
            return [f(x) for x in v]
        return float(v) if isinstance(v, int) and not isinstance(v, bool) else v

    return f(value)


# --------------------------------------------------------------------------- the file
class Store:
    """``batch.h5``: a group per experiment, written by rank 0 only.

    Opening an existing file resumes it: groups cut short while being written are
    dropped, and a file of another sweep is refused (SceneError) unless
    ``overwrite``. ``stored`` maps the id of every experiment in the file to its
    status.
    """

    def __init__(self, path, sweep, overwrite):
        import h5py

        from dem.io.files import H5Output

        self.path, self.sweep = Path(path), sweep
        if overwrite and self.path.exists():
            self.path.unlink()
        if self.path.exists():  # resume: check read-only first, change nothing
            try:
                with h5py.File(self.path, "r") as f:
                    self._check(f, sweep)
            except OSError as exc:
                raise SceneError(f"{self.path}: cannot read the batch file ({exc}); "
                                 f"pass --overwrite to start afresh") from None
        self._created = not self.path.exists()
        self.stored = {}
        self._out = H5Output(self.path, "a")
        self.f = self._out.h5
        with self._guard():
            for name in list(self.f):
                if "status" not in self.f[name].attrs:  # cut short while being written
                    del self.f[name]
            if self.f.attrs.get("format") != FORMAT:  # a new file (a resumed one is ours)
                stamp(self.f, FORMAT, VERSION, sweep.data)
            tags = dict(source=sweep.source, units=json.dumps({**SUMMARY_UNITS, **UNITS}),
                        conventions="compression positive for strains, p, q; "
                                    "stress dataset tension positive")
            for k, v in tags.items():  # a resumed file is only written where it must be
                if self.f.attrs.get(k) != v:
                    self.f.attrs[k] = v
            self.f.flush()
            self.stored = {name: str(g.attrs["status"]) for name, g in self.f.items()}

    def _guard(self):
        """A write the disk refuses closes the file, which keeps the experiments of
        its last flush (a rerun resumes it), and raises the OutputError naming it. A
        file this run made is removed if it holds no experiment or cannot be read; a
        resumed file is left to the user."""
        return self._out.guard(self._abandoned)

    def _abandoned(self):
        from dem.io.files import readable_h5, remove_quietly

        if self._created and not (readable_h5(self.path) and self.stored):
            remove_quietly(self.path)  # a read-only disk keeps it

    def _check(self, f, sweep):
        """Refuse a file that is not a batch of this sweep: another program's (its
        ``format`` tag is another, or it has none and holds something: an empty file
        is a batch cut short before its first write)."""
        tag = f.attrs.get("format")
        if isinstance(tag, bytes):
            tag = tag.decode(errors="replace")
        if tag != FORMAT and (tag is not None or len(f) or len(f.attrs)):
            what = f"a {tag!r} file" if tag is not None else "an HDF5 file without a format tag"
            self._refuse(f"is {what}, not a batch file ({FORMAT!r})")
        by_id = {e.id: e for e in sweep.experiments}
        for name, g in f.items():
            e = by_id.get(name)
            if "status" in g.attrs and (
                    e is None or g.attrs.get("config") != e.key
                    or g.attrs.get("overrides") != _canonical(e.overrides)):
                self._refuse(f"holds experiment {name}, which {sweep.source} does not "
                             f"define with the same settings (the sweep changed)")

    def _refuse(self, what):
        raise SceneError(f"{self.path} {what}; pass --overwrite to replace it or "
                         f"choose another --output")

    def _group(self, e, rank):
        g = self.f.create_group(e.id)
        g.attrs.update(index=e.index, overrides=_canonical(e.overrides), config=e.key,
                       rank=rank)
        return g

    def done(self, e, curves, summary, rank):
        with self._guard():
            g = self._group(e, rank)
            for name, values in curves.items():
                g.create_dataset(name, data=values).attrs.update(curve_attrs(name))
            g.attrs.update(summary)
            self._finish(g, "done")

    def failed(self, e, message, rank):
        with self._guard():
            g = self._group(e, rank)
            g.attrs["message"] = message
            self._finish(g, "failed")

    def _finish(self, g, status):
        g.attrs["status"] = status  # last: a group without it is incomplete
        self.f.flush()
        self.stored[g.name.lstrip("/")] = status

    def close(self):
        self._out.close()


def read_batch(path):
    """Every experiment of a ``batch.h5``: ``{id: {"attrs": {}, "curves": {}}}``."""
    import h5py

    out = {}
    with h5py.File(path, "r") as f:
        for name, g in f.items():
            attrs = {k: (v.item() if isinstance(v, np.generic) else v)
                     for k, v in g.attrs.items()}
            out[name] = {"attrs": attrs, "curves": {k: d[()] for k, d in g.items()}}
    return out


# --------------------------------------------------------------------------- summaries
#: summary.csv columns after id, status and the swept key paths
CSV_COLUMNS = (("e0", "initial_void_ratio"), ("peak_friction_angle",) * 2,
               ("critical_friction_angle",) * 2, ("dilatancy_angle",) * 2)


def _cell(value):
    if isinstance(value, float):
        return repr(value)
    return value if isinstance(value, (int, str)) else json.dumps(value)


def write_summaries(h5, sweep, csv_path, png_path):
    """summary.csv (a row per experiment) and summary.png from ``batch.h5``.

    Each is written to a temporary file, then renamed; a figure that cannot be drawn
    is a logged warning, a file the disk refuses an OutputError.
    """
    from dem.io.files import OutputError, write_text_atomic

    stored = read_batch(h5)
    rows = [(e, stored.get(e.id, {"attrs": {"status": "not run"}})["attrs"])
            for e in sweep.experiments]
    text = io.StringIO()
    w = csv.writer(text, lineterminator="\n")
    w.writerow(["id", "status", *sweep.parameters, *(c[0] for c in CSV_COLUMNS),
                "message"])
    for e, a in rows:
        w.writerow([e.id, a["status"], *(_cell(_value(e, p)) for p in sweep.parameters),
                    *(_cell(a[c[1]]) if c[1] in a else "" for c in CSV_COLUMNS),
                    a.get("message", "")])
    write_text_atomic(csv_path, text.getvalue())
    try:
        _write_figure(png_path, sweep, rows)
    except OutputError:
        raise  # the disk refused it: an error, like any output that cannot be written
    except Exception as exc:  # noqa: BLE001 - a plot must not lose a finished batch
        log.warning("%s not written: %s: %s", png_path, type(exc).__name__, exc)


def _value(e, path):
    """The value of a key path in an experiment (its override, else [base]'s or the
    default)."""
    section, key = path.split(".")
    return e.config[section][key]


def _write_figure(path, sweep, rows):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from dem.io.hdf5 import save_figure

    params = sweep.parameters
    first, second = params[0], (params[1] if len(params) > 1 else None)
    x_of = {e.id: _value(e, first) for e, _ in rows}
    line_of = {e.id: _cell(_value(e, second)) if second else "" for e, _ in rows}
    numeric = all(isinstance(x, (int, float)) and not isinstance(x, bool)
                  for x in x_of.values())
    if not numeric:  # categories, in order of first appearance
        names = list(dict.fromkeys(_cell(x) for x in x_of.values()))
        x_of = {k: names.index(_cell(x)) for k, x in x_of.items()}
    fig = Figure(figsize=(6.4, 4.2), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    done = [e.id for e, a in rows if a["status"] == "done"]
    attrs = {e.id: a for e, a in rows}
    for k, line in enumerate(dict.fromkeys(line_of.values())):
        for name, style in (("peak_friction_angle", "o-"),
                            ("critical_friction_angle", "s--")):
            points = {}
            for i in done:
                if line_of[i] == line:
                    points.setdefault(x_of[i], []).append(attrs[i][name])
            if points:
                x = sorted(points)
                y = [float(np.mean(points[v])) for v in x]  # over further parameters
                label = f"{second} = {line}" if second and style == "o-" else None
                ax.plot(x, y, style, color=f"C{k % 10}", label=label)
    ax.plot([], [], "ko-", label="peak")
    ax.plot([], [], "ks--", label="critical (last 20 %)")
    if not numeric:
        ax.set_xticks(range(len(names)), names)
    elif min(x_of.values()) > 0 and max(x_of.values()) >= 5 * min(x_of.values()):
        ax.set_xscale("log")  # a geometric series
    ax.set(xlabel=first, ylabel="friction angle [deg]")
    ax.legend(fontsize="small")
    ax.set_title(f"{Path(sweep.source).name}: {len(done)} of {len(rows)} "
                 f"experiments done", fontsize="medium")
    save_figure(fig, path, dpi=110, data="batch.h5")
