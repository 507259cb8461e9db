"""Many standalone RVE tests over MPI ranks: ``mpiexec -n N hmm batch sweep.toml``.

A sweep file holds a ``[base]`` experiment (the sections of an ``hmm rve`` file:
``packing``, ``contact``, ``test``) and a ``[sweep]`` of variations of it: a ``grid``
(key path -> values, the Cartesian product) or a ``list`` of override tables. Every
experiment is validated against :data:`hmm.experiment.RVE_SCHEMA` before anything
runs and gets a stable id, its index and a hash of its overrides (``003-1a2b3c4d``).

Execution (:func:`run_batch`, collective over the ranks):

* rank 0, the master, keeps the queue: it hands one experiment to each idle worker
  (``send``/``recv`` with tags; the messages are small), records every reply in one
  HDF5 file (flushed after each) and runs experiments itself between replies,
  answering the workers after every increment of its own experiment; with one rank it
  runs them all, through the same code;
* a worker runs what it is given and replies with the summary and the curves, or
  with the error; it checks for a stop message after every increment.

Faults: a :class:`dem.rve.RelaxationError` (the packing did not relax) is recorded as
a failed experiment and the batch goes on; any other exception is a bug or unusable
input: rank 0 tells every rank to stop (a rank busy with an experiment stops after
its current increment) and the batch ends with a message naming the experiment.
Every path through :func:`run_batch` ends with all workers stopped and a broadcast
from rank 0, so no rank is left waiting.

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
import sys
import time
import traceback
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dem.io.scene import Key, SceneError, Section, read_toml, validate

from .experiment import (
    _SUMMARY_UNITS,
    _UNITS,
    RVE_SCHEMA,
    _compress,
    _packing,
    _summarize,
    validate_config,
)
from .farm import mpi_world

log = logging.getLogger(__name__)

__all__ = ["BATCH_SCHEMA", "BatchReport", "Experiment", "RankFailure", "Sweep",
           "cmd_batch", "expand", "experiment_id", "load_sweep", "read_batch",
           "run_batch", "run_one"]

FORMAT, VERSION = "hmm.batch", 1
OUTPUTS = ("batch.h5", "summary.csv", "summary.png")
#: group attributes that describe the run, not the experiment (they may differ)
RUN_METADATA = ("wall_time", "rank")
#: the sections of [base] a sweep may vary
SWEPT_SECTIONS = ("packing", "contact", "test")

TAG_TASK, TAG_STOP, TAG_DONE, TAG_FAILED, TAG_ABANDONED = range(11, 16)
_POLL_S = 0.002  # sleep between probes while waiting (a blocking recv spins a core)


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
    dem.io.scene.SceneError: <sweep>: [sweep] grid: ... (did you mean 'test.confining'?)
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
        canon = _canonical(overrides)
        if canon in seen:
            raise SceneError(f"{source}: experiments {seen[canon]} and {exp_id} have "
                             f"the same overrides {canon}")
        seen[canon] = exp_id
        experiments.append(Experiment(exp_id, index, overrides, cfg))
    return Sweep(source, experiments, parameters, out_dir)


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
        return [dict(zip(paths, combo)) for combo in itertools.product(*grid.values())]
    entries = sweep["list"]
    if not isinstance(entries, list) or not entries or not all(
            isinstance(e, dict) for e in entries):
        raise SceneError(f"{where} list must be a non-empty array of tables "
                         f"([[sweep.list]])")
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


# --------------------------------------------------------------------------- one run
class _Stopped(Exception):
    """Rank 0 asked this rank to stop: the experiment under way is abandoned."""


class _Hook:
    """Calls ``poll`` after every increment (the progress-bar slot of _compress)."""

    def __init__(self, poll):
        self.poll = poll

    def update(self, n=1):
        self.poll()


def run_one(cfg, poll=None):
    """Run the test of a validated config in memory: ``(curves, summary)``.

    The procedure and the results are those of
    :func:`hmm.experiment.run_experiment`, which writes files; this writes nothing.
    ``poll()`` is called between the phases and after every increment; it may raise
    to abandon the test. ``summary["wall_time"]`` [s] is added.
    """
    t0 = time.perf_counter()
    poll = poll or (lambda: None)
    rve, confining, _ = _packing(cfg)
    poll()
    rve.consolidate(confining)
    poll()
    t = cfg["test"]
    n_inc = math.ceil(t["axial_strain"] / t["increment"] - 1e-9)
    targets = np.minimum(np.arange(1, n_inc + 1) * t["increment"], t["axial_strain"])
    curves = _compress(rve, confining, targets, _Hook(poll))
    summary = _summarize(curves, rve, confining, t["increment"])
    summary["wall_time"] = time.perf_counter() - t0
    return curves, summary


def _attempt(exp_id, cfg, poll):
    """Run one experiment: ``(tag, payload)`` for the reply to rank 0."""
    from dem.rve import RelaxationError

    try:
        curves, summary = run_one(cfg, poll)
    except _Stopped:
        return TAG_ABANDONED, exp_id
    except Exception as exc:  # noqa: BLE001 - reported to rank 0, which decides
        message = " ".join(f"{type(exc).__name__}: {exc}".split())
        return TAG_FAILED, (exp_id, isinstance(exc, RelaxationError), message,
                            traceback.format_exc())
    return TAG_DONE, (exp_id, curves, summary)


# --------------------------------------------------------------------------- the file
class _Store:
    """``batch.h5``: a group per experiment, written by rank 0 only."""

    def __init__(self, path, sweep, overwrite):
        import h5py

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
        self.f = h5py.File(self.path, "a")
        for name in list(self.f):
            if "status" not in self.f[name].attrs:  # cut short while being written
                del self.f[name]
        self.f.attrs.update(format=FORMAT, version=VERSION, source=sweep.source,
                            units=json.dumps({**_SUMMARY_UNITS, **_UNITS}),
                            conventions="compression positive for strains, p, q; "
                                        "stress dataset tension positive")
        self.f.flush()
        self.stored = {name: str(g.attrs["status"]) for name, g in self.f.items()}

    def _check(self, f, sweep):
        """Refuse a file that is not a batch of this sweep."""
        if f.attrs.get("format", FORMAT) != FORMAT:
            self._refuse("is not a batch file")
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
        g = self._group(e, rank)
        for name, values in curves.items():
            g.create_dataset(name, data=values).attrs["unit"] = _UNITS.get(name, "-")
        g.attrs.update(summary)
        self._finish(g, "done")

    def failed(self, e, message, rank):
        g = self._group(e, rank)
        g.attrs["message"] = message
        self._finish(g, "failed")

    def _finish(self, g, status):
        g.attrs["status"] = status  # last: a group without it is incomplete
        self.f.flush()
        self.stored[g.name.lstrip("/")] = status

    def close(self):
        self.f.close()


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


# --------------------------------------------------------------------------- ranks
@dataclass
class BatchReport:
    """What a batch did; the same object on every rank."""

    n_total: int
    n_skipped: int = 0  # already in batch.h5
    n_done: int = 0  # status "done" in batch.h5 at the end (resumed ones included)
    n_failed: int = 0  # status "failed" (RelaxationError)
    aborted: str = None  # the one-line reason the batch stopped early
    files: list = field(default_factory=list)
    wall_time: float = 0.0
    ranks: int = 1



class RankFailure(RuntimeError):
    """Raised on the workers when rank 0 failed; ``code`` is its exit status."""

    def __init__(self, code):
        super().__init__(f"the batch failed on rank 0 (exit status {code})")
        self.code = int(code)


class _Master:
    """Rank 0: the queue, the replies, the file; runs experiments itself too.

    Every worker always holds exactly one task or has been sent a stop. Rank 0
    answers a reply with the next task or the stop as soon as it sees it: at once
    when idle, else after its current increment (or packing phase).
    """

    def __init__(self, MPI, comm):
        self.MPI, self.comm = MPI, comm
        self.workers = range(1, comm.size) if comm is not None else range(0)
        self.busy, self.stopped = {}, set()
        self.store, self.bar, self.queue, self.by_id = None, None, deque(), {}
        self.abort = None

    # -- workers
    def _send_next(self, rank):
        if self.queue and self.abort is None:
            e = self.queue.popleft()
            self.comm.send((e.id, e.config), dest=rank, tag=TAG_TASK)
            self.busy[rank] = e
        else:
            self.stop(rank)

    def stop(self, rank):
        if rank not in self.stopped:
            self.comm.send(None, dest=rank, tag=TAG_STOP)
            self.stopped.add(rank)

    def service(self, block=False):
        """Take every reply that has arrived (with ``block``: wait for one)."""
        if self.comm is None:
            return
        status = self.MPI.Status()
        while True:
            if not self.comm.Iprobe(source=self.MPI.ANY_SOURCE,
                                    tag=self.MPI.ANY_TAG, status=status):
                if not block:
                    return
                time.sleep(_POLL_S)
                continue
            rank, tag = status.Get_source(), status.Get_tag()
            payload = self.comm.recv(source=rank, tag=tag)
            self.busy.pop(rank, None)
            if self.store is not None:  # None while shutting down after a failure
                if tag == TAG_DONE:
                    self._record_done(self.by_id[payload[0]], *payload[1:], rank)
                elif tag == TAG_FAILED:
                    self._record_failure(self.by_id[payload[0]], *payload[1:], rank)
            if rank not in self.stopped:
                self._send_next(rank)
            block = False

    def shutdown(self, reason):
        """Stop every worker and take their last replies (after a failure)."""
        self.store, self.abort = None, self.abort or reason
        for rank in self.workers:
            self.stop(rank)
        deadline = time.monotonic() + 60.0
        while self.busy and time.monotonic() < deadline:
            self.service()
            time.sleep(_POLL_S)

    # -- results
    def _record_done(self, e, curves, summary, rank):
        self.store.done(e, curves, summary, rank)
        log.info("experiment %s done on rank %d in %.1f s", e.id, rank,
                 summary["wall_time"])
        self._tick()

    def _record_failure(self, e, is_relaxation, message, tb, rank):
        if is_relaxation:
            self.store.failed(e, message, rank)
            log.warning("experiment %s failed on rank %d: %s", e.id, rank, message)
            self._tick()
            return
        log.debug("experiment %s on rank %d:\n%s", e.id, rank, tb)
        if self.abort is None:
            self.abort = f"experiment {e.id} raised {message} (rank {rank})"
            for r in list(self.busy):  # they stop after their current increment
                self.stop(r)

    def _tick(self):
        if self.bar is not None:
            self.bar.update(1)

    # -- the loop
    def _poll(self):
        self.service()
        if self.abort is not None:
            raise _Stopped

    def run(self, store, todo, bar):
        """Hand out, run, record until the queue is empty; every worker stopped."""
        self.store, self.bar = store, bar
        self.queue, self.by_id = deque(todo), {e.id: e for e in todo}
        for rank in self.workers:
            self._send_next(rank)
        while self.abort is None:
            self.service()
            if not self.queue or self.abort is not None:
                break
            e = self.queue.popleft()
            tag, payload = _attempt(e.id, e.config, self._poll)
            if tag == TAG_DONE:
                self._record_done(e, *payload[1:], 0)
            elif tag == TAG_FAILED:
                self._record_failure(e, *payload[1:], 0)
        while self.busy:
            self.service(block=True)
        for rank in self.workers:
            self.stop(rank)


def run_batch(sweep, out_dir=None, overwrite=False, progress=None, world=None):
    """Run the experiments of a sweep; collective over the ranks of ``world``.

    Parameters
    ----------
    sweep : Sweep
        From :func:`load_sweep` (used on rank 0; other ranks may pass None).
    out_dir : str or Path, optional
        Output directory (default the sweep's ``[output] dir``).
    overwrite : bool
        Replace an existing ``batch.h5`` instead of resuming it.
    progress : bool, optional
        A progress bar over the experiments on rank 0 (default: stderr is a terminal).
    world : (MPI, comm), optional
        Default :func:`hmm.farm.mpi_world`; ``(None, None)`` runs in this process.

    Returns
    -------
    BatchReport
        On every rank. ``aborted`` is set when an experiment raised anything but a
        RelaxationError; the experiments finished before it are kept.

    Raises
    ------
    SceneError
        On every rank, before anything ran: ``batch.h5`` holds another sweep.
    """
    MPI, comm = mpi_world() if world is None else world
    if comm is not None and comm.rank != 0:
        _serve(MPI, comm)
        outcome = comm.bcast(None, root=0)
        if isinstance(outcome, str):
            raise SceneError(outcome)
        if isinstance(outcome, int):
            raise RankFailure(outcome)
        return outcome
    master = _Master(MPI, comm)
    try:
        report = _lead(sweep, out_dir, overwrite, progress, master)
    except SceneError as exc:
        master.shutdown(str(exc))
        _bcast(comm, str(exc))
        raise
    except BaseException as exc:
        master.shutdown("rank 0 failed")
        _bcast(comm, 130 if isinstance(exc, KeyboardInterrupt) else 1)
        raise
    _bcast(comm, report)
    return report


def _bcast(comm, value):
    if comm is not None:
        comm.bcast(value, root=0)


def _lead(sweep, out_dir, overwrite, progress, master):
    t0 = time.perf_counter()
    out = Path(sweep.out_dir if out_dir is None else out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = [out / name for name in OUTPUTS]
    store = _Store(files[0], sweep, overwrite)
    try:
        todo = [e for e in sweep.experiments if e.id not in store.stored]
        n = len(sweep.experiments)
        report = BatchReport(n, n - len(todo), files=[str(f) for f in files],
                             ranks=1 if master.comm is None else master.comm.size)
        bar = None
        if (sys.stderr.isatty() if progress is None else progress) and todo:
            from tqdm import tqdm

            bar = tqdm(total=n, initial=report.n_skipped, unit="experiment",
                       leave=False)
        try:
            master.run(store, todo, bar)
        finally:
            if bar is not None:
                bar.close()
        report.aborted = master.abort
        statuses = list(store.stored.values())
    finally:
        store.close()
    report.n_done, report.n_failed = statuses.count("done"), statuses.count("failed")
    _write_summaries(files[0], sweep, files[1], files[2])
    report.wall_time = time.perf_counter() - t0
    return report


def _serve(MPI, comm):
    """A worker: run what rank 0 sends until it says stop."""
    status = MPI.Status()

    def poll():
        if comm.Iprobe(source=0, tag=TAG_STOP):
            raise _Stopped

    while True:
        while not comm.Iprobe(source=0, tag=MPI.ANY_TAG, status=status):
            time.sleep(_POLL_S)
        tag = status.Get_tag()
        payload = comm.recv(source=0, tag=tag)
        if tag == TAG_STOP:
            return
        reply_tag, reply = _attempt(*payload, poll)
        comm.send(reply, dest=0, tag=reply_tag)


# --------------------------------------------------------------------------- summaries
#: summary.csv columns after id, status and the swept key paths
CSV_COLUMNS = (("e0", "initial_void_ratio"), ("peak_friction_angle",) * 2,
               ("critical_friction_angle",) * 2, ("dilatancy_angle",) * 2)


def _cell(value):
    if isinstance(value, float):
        return repr(value)
    return value if isinstance(value, (int, str)) else json.dumps(value)


def _write_summaries(h5, sweep, csv_path, png_path):
    """summary.csv (a row per experiment) and summary.png from ``batch.h5``."""
    from dem.io.hdf5 import publish

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
    tmp = csv_path.with_name(csv_path.name + ".tmp")
    tmp.write_text(text.getvalue())
    publish(tmp, csv_path)
    try:
        _write_figure(png_path, sweep, rows)
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

    from dem.io.hdf5 import publish

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
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        fig.savefig(fh, format="png", dpi=110)
    publish(tmp, path)


# --------------------------------------------------------------------------- CLI
def cmd_batch(args):
    """``hmm batch FILE``: run a sweep of RVE tests; call it on every rank.

    ``args`` has ``file`` (the TOML), ``output`` (directory or None) and
    ``overwrite``; optional ``no_progress``. Returns the exit status on every
    rank: 0 every experiment done, 1 some failed or the batch stopped early, 2 bad
    input (nothing ran), 130 interrupted. Only rank 0 prints.
    """
    MPI, comm = mpi_world()
    rank = 0 if comm is None else comm.rank
    sweep = error = None
    if rank == 0:
        try:
            sweep = load_sweep(args.file)
        except SceneError as exc:
            error = str(exc)
    if comm is not None:
        error = comm.bcast(error, root=0)
    if error is not None:
        return _error(error, 2) if rank == 0 else 2
    try:
        report = run_batch(sweep, getattr(args, "output", None),
                           overwrite=getattr(args, "overwrite", False),
                           progress=not getattr(args, "no_progress", False)
                           and sys.stderr.isatty(), world=(MPI, comm))
    except (SceneError, OSError) as exc:
        return _error(exc, 2) if rank == 0 else 2
    except KeyboardInterrupt:
        return _error("interrupted; rerun the same command to resume", 130) \
            if rank == 0 else 130
    except RankFailure as exc:  # a worker: rank 0 reports its own failure
        return exc.code
    if rank != 0:
        return _status(report)
    r = report
    ran = r.n_total - r.n_skipped
    if r.aborted:
        return _error(f"{r.aborted}; the batch stopped ({r.n_done} of {r.n_total} "
                      f"experiments done, in {r.files[0]})", 1)
    print(f"hmm batch {args.file}: {r.n_total} experiments ({ran} run, "
          f"{r.n_skipped} already in {Path(r.files[0]).name}) on {r.ranks} "
          f"rank{'s' * (r.ranks > 1)} in {r.wall_time:.1f} s: {r.n_done} done, "
          f"{r.n_failed} failed (did not relax)\n"
          f"  output: {', '.join(r.files)}")
    return _status(report)


def _status(report):
    return 1 if report.aborted or report.n_failed else 0


def _error(msg, code):
    print("hmm batch: error: " + " ".join(str(msg).split()), file=sys.stderr)
    return code
