"""Hostile input files: every file a user hands in ends in a valid run or a one-line
error with exit status 2.

Property-based (hypothesis, derandomized): the example scene, problem, RVE test and
sweep files are mutated (a key dropped or added, a value replaced by a wrong type,
NaN, an infinity, a negative, zero, huge or empty value, the text cut short or
garbled) and fed to the command line in this process. Crafted HDF5 packings and
checkpoints (wrong dtypes and shapes, missing parts, a dataset declaring 10^12
elements, truncated or non-HDF5 files) must be refused before any large allocation.
Nothing here runs a simulation: a valid file stops where its run would start
(``--dry-run``, or the step that starts the run replaced by :class:`_Stop`).
``docs/hostile_inputs.md`` lists the cases and their number.
"""

import contextlib
import copy
import io
import json
import math
import os
import re
import shutil
import tempfile
import tracemalloc
from pathlib import Path
from unittest import mock

import h5py
import numpy as np
import pytest
import tomllib
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"

#: generated cases per property (docs/hostile_inputs.md states the total)
N_TOML = 80
N_PACKING_TEXT = 60
N_HDF5 = 100
N_CHECKPOINT = 25


def cases(n):
    """Deterministic hypothesis settings with ``n`` generated cases."""
    return settings(max_examples=n, derandomize=True, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow,
                                           HealthCheck.function_scoped_fixture])


@pytest.fixture(scope="session", autouse=True)
def warm_kernels():
    """Nothing here runs a compiled loop: skip the shared warm-up (tests/conftest.py)."""


# --------------------------------------------------------------------------- TOML
def _toml_key(key):
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else json.dumps(key)


def toml_value(v):
    """A value as inline TOML (tables inline, so any nesting round-trips)."""
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_toml_key(k)} = {toml_value(x)}"
                               for k, x in v.items()) + "}"
    raise TypeError(type(v))


def to_toml(data):
    """A parsed TOML document written back: one ``key = inline value`` per line."""
    return "\n".join(f"{_toml_key(k)} = {toml_value(v)}" for k, v in data.items()) + "\n"


def _load_example(name, **edits):
    data = tomllib.loads((EXAMPLES / name).read_text())
    for path, value in edits.items():
        table = data
        *parents, key = path.split("/")
        for p in parents:
            table = table[p]
        table[key] = value
    assert tomllib.loads(to_toml(data)) == data
    return data


#: the example files; the scene's particle count is cut to keep its build quick
BASES = {
    "scene": _load_example("scenes/pour.toml", **{"particles/count": 30,
                                                  "simulation/steps": 100}),
    "problem": _load_example("biaxial.toml"),
    "rve": _load_example("rve_biaxial.toml"),
    "sweep": _load_example("sweep.toml"),
}

HOSTILE_VALUES = [
    "", "text", "dem", True, False, 0, 1, -1, 2, 3, 0.0, -0.0, -1.0, 1e-300, 0.5,
    float("nan"), float("inf"), float("-inf"), 1e300, -1e300, 10**18, -(10**18),
    2**63 - 1, [], [0.0], [1.0, 2.0], [float("nan"), 1.0], [0.0, 0.0, 0.0],
    [-1.0, -1.0, -1.0], [1e300, 1e300, 1e300], ["a", "b"], [[]], [1, "a"], {},
    {"a": 1}, [{}], list(range(50)),
]
UNKNOWN_KEYS = ["unknown", "Dim", "steps ", "", "x.y", "ünïcödé", "base", "seed"]


def _nodes(data, path=()):
    """Every (path, value) below ``data``: tables, arrays and leaves."""
    out = []
    items = data.items() if isinstance(data, dict) else enumerate(data) \
        if isinstance(data, list) else ()
    for k, v in items:
        out.append((path + (k,), v))
        out += _nodes(v, path + (k,))
    return out


def _tables(data, path=()):
    out = [path] if isinstance(data, dict) else []
    items = data.items() if isinstance(data, dict) else enumerate(data) \
        if isinstance(data, list) else ()
    for k, v in items:
        out += _tables(v, path + (k,))
    return out


def _get(data, path):
    for k in path:
        data = data[k]
    return data


@st.composite
def mutated(draw, base):
    """``(TOML text, description)``: ``base`` with one to three hostile edits."""
    data = tomllib.loads(to_toml(base))  # a fresh copy, whatever happened before
    edits = []
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["drop", "unknown", "replace", "replace", "scale"]))
        nodes = _nodes(data)
        if kind == "unknown" or not nodes:
            path = draw(st.sampled_from(_tables(data)))
            key = draw(st.sampled_from(UNKNOWN_KEYS))
            value = copy.deepcopy(draw(st.sampled_from(HOSTILE_VALUES)))
            _get(data, path)[key] = value
            edits.append(f"add {path + (key,)} = {value!r}")
            continue
        path, old = draw(st.sampled_from(nodes))
        parent = _get(data, path[:-1])
        if kind == "drop":
            del parent[path[-1]]
            edits.append(f"drop {path}")
        elif kind == "scale" and isinstance(old, (int, float)) \
                and not isinstance(old, bool):
            factor = draw(st.sampled_from([-1, 0, 1e-12, 1e12, 0.5, 2]))
            parent[path[-1]] = type(old)(old * factor) if isinstance(old, float) \
                else int(old * factor)
            edits.append(f"{path} x {factor}")
        else:
            value = copy.deepcopy(draw(st.sampled_from(HOSTILE_VALUES)))
            parent[path[-1]] = value
            edits.append(f"{path} = {value!r}")
    text = to_toml(data)
    cut = draw(st.sampled_from([None] * 6 + ["truncate", "garble"]))
    if cut == "truncate":
        text = text[:draw(st.integers(0, len(text)))]
        edits.append("truncated")
    elif cut == "garble":
        at = draw(st.integers(0, len(text)))
        text = text[:at] + draw(st.sampled_from(["\x00", "[", "=", "\ufffd", '"']))\
            + text[at:]
        edits.append("garbled")
    return text, "; ".join(edits)


# --------------------------------------------------------------------------- running
class _Stop(Exception):
    """Raised where a valid file's run would start: validation passed."""


def _stop(*args, **kwargs):
    raise _Stop


def run_cli(prog, argv, cwd):
    """``prog`` (``dem`` or ``hmm``) with ``argv`` in this process, from ``cwd``:
    ``(exit status, stdout, stderr)``; status 0 where :class:`_Stop` was raised."""
    if prog == "dem":
        from dem.cli import main
    else:
        from hmm.cli import main
    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                main([str(a) for a in argv])
            except SystemExit as exc:
                code = exc.code
            except _Stop:
                code = 0
    finally:
        os.chdir(here)
    return code, out.getvalue(), err.getvalue()


def listing(root):
    """Every file below ``root`` with its bytes."""
    root = Path(root)
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


def assert_clean_outcome(code, err, prog, note):
    assert code in (0, 2), f"exit status {code} for {note}:\n{err}"
    assert "Traceback" not in err, f"{note}:\n{err}"
    if code == 2:
        lines = err.splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"{prog}: error: "), \
            f"{note}:\n{err}"


#: per file kind: the command, where a valid file is stopped before its run (a patch,
#: or --dry-run), and the output file it must not overwrite
KINDS = {
    "scene": ("dem", ["run"], ["--dry-run"], None, None, "scene.h5", "dem"),
    "problem": ("hmm", ["run"], ["--dry-run"], None, None, "fields.h5", "hmm run"),
    "rve": ("hmm", ["rve"], [], "hmm.experiment.make_packing",
            "hmm.experiment.make_packing", "rve_test.h5", "hmm rve"),
    "sweep": ("hmm", ["batch"], [], "hmm.queue.run_batch", "hmm.queue._Master.run",
              "batch.h5", "hmm batch"),
}


def check_file(kind, text, note):
    """Validate ``text`` as a ``kind`` file twice: into a missing output directory
    (nothing may appear in the working directory), then into one whose output file
    exists (it must be refused, the file left as it was)."""
    prog, command, dry, patch, patch2, existing, label = KINDS[kind]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        path = tmp / f"{kind}.toml"
        path.write_bytes(text.encode("utf-8", "surrogatepass"))
        before = listing(tmp)
        with mock.patch(patch, _stop) if patch else contextlib.nullcontext():
            code, _, err = run_cli(prog, [*command, path, "-o", tmp / "out", *dry], tmp)
        assert_clean_outcome(code, err, label, note)
        assert listing(tmp) == before, f"files written for {note}"
        out = tmp / "out"
        out.mkdir()
        (out / existing).write_bytes(b"an earlier result")
        before = listing(tmp)
        with mock.patch(patch2, _stop) if patch2 else contextlib.nullcontext():
            code2, _, err2 = run_cli(prog, [*command, path, "-o", out], tmp)
        assert code2 == 2, f"{note}: exit {code2}\n{err2}"
        assert_clean_outcome(code2, err2, label, note)
        assert listing(tmp) == before, f"output changed for {note}"
        return code


def test_the_unmutated_examples_are_valid():
    for kind, base in BASES.items():
        assert check_file(kind, to_toml(base), kind) == 0, kind


@pytest.mark.parametrize("kind", sorted(BASES))
def test_mutated_input_files_end_in_a_run_or_one_line(kind):
    @cases(N_TOML)
    @given(mutated(BASES[kind]))
    def prop(case):
        check_file(kind, *case)

    prop()


@pytest.mark.parametrize("kind, edits, message", [
    ("scene", {"particles/count": 10**12}, "exceeds the limit of 10000000 particles"),
    ("scene", {"particles/count": 100000}, "random placement stops"),
    ("scene", {"particles/generator": "lattice", "particles/count": 10**12},
     "exceeds the limit of 10000000 particles"),
    ("scene", {"particles/generator": "lattice", "particles/hi": [1e300] * 3},
     "overlaps the wall"),
    ("problem", {"mesh/cells": [10**9, 10**9]}, "exceeds the limit of 1000000 elements"),
])
def test_huge_sizes_are_refused_before_allocation(kind, edits, message):
    data = copy.deepcopy(BASES[kind])
    for path, value in edits.items():
        section, key = path.split("/")
        data[section][key] = value
    prog, command, dry, *_ = KINDS[kind]
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "f.toml").write_text(to_toml(data))
        with bounded_memory():
            code, _, err = run_cli(prog, [*command, "f.toml", *dry], tmp)
    assert code == 2 and message in err and err.count("\n") == 1, err


# --------------------------------------------------------------------------- particle files
SCENE_FROM_FILE = {
    "simulation": {"dim": 2, "steps": 10},
    "particles": {"generator": "file", "file": "packing.txt", "density": 2500.0},
    "walls": [{"point": [0.0, 0.0], "normal": [0.0, 1.0]}],
    "contact": {"law": "linear", "kn": 1e4, "mu": 0.5},
}

_numbers = st.one_of(st.floats(-1.0, 1.0), st.sampled_from(
    [0.0, -0.0, 1e-300, 1e300, -1e300, float("nan"), float("inf"), float("-inf")]))


@st.composite
def packing_texts(draw):
    """Rows ``x y r`` with hostile numbers, wrong column counts, overlaps, junk."""
    rows = draw(st.lists(st.lists(_numbers, min_size=1, max_size=4), max_size=6))
    lines = [" ".join(repr(x) for x in row) for row in rows]
    extra = draw(st.sampled_from(["", "# a comment", "x y r", "1,2,3", "\x00\x01",
                                  "0.0 0.0 0.1\n0.0 0.0 0.1", "0.5 0.5 0.1"]))
    lines.insert(draw(st.integers(0, len(lines))), extra)
    return "\n".join(lines)


def test_particle_files_end_in_a_run_or_one_line():
    @cases(N_PACKING_TEXT)
    @given(packing_texts(), st.booleans())
    def prop(text, binary):
        with tempfile.TemporaryDirectory() as tmp:
            tmp = Path(tmp)
            (tmp / "packing.txt").write_bytes(text.encode() + (b"\xff\xfe" if binary
                                                               else b""))
            (tmp / "scene.toml").write_text(to_toml(SCENE_FROM_FILE))
            before = listing(tmp)
            code, _, err = run_cli("dem", ["run", "scene.toml", "--dry-run"], tmp)
            assert_clean_outcome(code, err, "dem", repr(text))
            assert listing(tmp) == before

    prop()


def test_overlapping_and_empty_particle_files_are_refused(tmp_path):
    (tmp_path / "scene.toml").write_text(to_toml(SCENE_FROM_FILE))
    for text, message in (("0.5 0.5 0.1\n0.6 0.5 0.1\n", "overlap by"),
                          ("# nothing\n", "holds no particles"),
                          ("0.5 0.05 0.1\n", "overlaps the wall")):
        (tmp_path / "packing.txt").write_text(text)
        code, _, err = run_cli("dem", ["run", "scene.toml", "--dry-run"], tmp_path)
        assert code == 2 and message in err and err.count("\n") == 1, err


# --------------------------------------------------------------------------- HDF5
def write_rve_packing(path, d=2):
    """A valid RVE packing file (the layout of ``RVE.save``): two disks at rest in a
    periodic cell, written directly so that no compiled loop runs."""
    n = 2
    r = np.full(n, 1e-3)
    m = 2650.0 * np.pi * r**2
    with h5py.File(path, "w") as f:
        f.attrs.update(format="dem.checkpoint", version=1, dim=d, step=0, time=0.0,
                       dt=1e-7, damping=0.5, overlap_limit=0.5, skin=4e-4,
                       backend="cell", n_builds=1, capacity=0, has_box=True,
                       detection="auto", admm_tol=1e-8, admm_max_iter=200)
        f["gravity"] = np.zeros(d)
        f["wall_work"] = np.zeros(1)
        b = f.create_group("bodies")
        b.attrs["dim"] = d
        arrays = {"pos": np.array([[1e-3, 1e-3], [3.5e-3, 3.5e-3]]),
                  "vel": np.zeros((n, d)), "rot": np.zeros((n, 1)),
                  "ang_vel": np.zeros((n, 1)), "force": np.zeros((n, d)),
                  "torque": np.zeros((n, 1)), "radius": r, "mass": m,
                  "inertia": (0.5 * m * r**2)[:, None], "kind": np.zeros(n, np.int32),
                  "mat_id": np.zeros(n, np.int32), "is_fixed": np.zeros(n, bool),
                  "normal": np.zeros((n, d)), "density": np.full(n, 2650.0),
                  "shape": np.full(n, -1, np.int32)}
        for k, v in arrays.items():
            b[k] = v
        g = f.create_group("neighbors")
        g["pairs"] = np.zeros((0, 2), np.int32)
        g["img"] = np.zeros((0, d), np.int32)
        g["wall_pairs"] = np.zeros((0, 2), np.int32)
        g["pos_ref"] = arrays["pos"]
        c = f.create_group("cell")
        c.attrs["n_reductions"] = 0
        c["h"] = np.eye(d) * 5e-3
        c["lgrad"] = np.zeros((d, d))
        c["origin"] = np.zeros(d)
        c["cellref"] = np.zeros((2, d, d))
        g = f.create_group("contacts")
        g.attrs.update(n_inner=-1, n_internal=-1)
        g["hist"] = np.zeros((0, 3))
        g["touch"] = np.zeros(0, np.uint8)
        g["fpair"] = np.zeros((0, d))
        g["whist"] = np.zeros((0, 3))
        g["wforce"] = np.zeros((0, d))
        g["wtorque"] = np.zeros((0, 1))
        g["radius_ref"] = r
        g = f.create_group("rve")
        g.attrs.update(law=json.dumps({"law": "LinearSpring", "kn": 1e8, "kt": 5e7,
                                       "mu": 0.5}),
                       mass_scale=1.0, max_step_strain=1e-5, tol=1e-3, stress_tol=1e-3,
                       max_relax_steps=1000, check_every=50, p0=1e5)
        g["deformation"] = np.eye(d)


def _h5_items(path):
    """(datasets, (object, attribute) pairs) of a file."""
    datasets, attrs = [], []
    with h5py.File(path, "r") as f:
        attrs += [("/", k) for k in f.attrs]

        def visit(name, obj):
            attrs.extend((name, k) for k in obj.attrs)
            if isinstance(obj, h5py.Dataset):
                datasets.append(name)

        f.visititems(visit)
    return datasets, attrs


HUGE = 10**12


def _mutate_dataset(f, name, how):
    ds = f[name]
    attrs = dict(ds.attrs)
    data = ds[()] if ds.size <= 10**6 else np.zeros([min(n, 4) for n in ds.shape],
                                                    ds.dtype)
    shape = data.shape
    del f[name]
    if how == "delete":
        return
    if how == "group":
        f.create_group(name)
        return
    if how == "huge":  # declared, never written: the file stays small
        new = (HUGE,) + shape[1:] if shape else (HUGE,)
        f.create_dataset(name, shape=new, maxshape=(None,) + new[1:],
                         dtype=data.dtype, chunks=(1024,) + new[1:])
        return
    if how == "huge_rows":
        f.create_dataset(name, shape=(4,) + (HUGE,), dtype=data.dtype, chunks=(1, 1024))
        return
    if how == "dtype_float":
        new = np.asarray(data, np.float32)
    elif how == "dtype_int":
        new = np.zeros(shape, np.int64)
    elif how == "dtype_str":
        new = np.full(shape, b"x", dtype="S1")
    elif how == "extra_row":
        new = np.concatenate([data, data[:1]]) if shape and shape[0] else np.zeros(
            (1,) + shape[1:], data.dtype)
    elif how == "scalar":
        new = np.zeros((), data.dtype)
    elif how == "transpose":
        new = np.ascontiguousarray(np.atleast_2d(data).T)
    elif how == "nan":
        new = np.full(shape, np.nan) if data.dtype.kind == "f" else data
    else:  # "negative"
        new = -np.ones(shape, data.dtype) if data.dtype.kind in "fi" else data
    f.create_dataset(name, data=new)
    for k, v in attrs.items():
        f[name].attrs[k] = v


def _mutate_attr(f, obj, key, how):
    attrs = f[obj].attrs
    if how == "delete":
        del attrs[key]
    else:
        attrs[key] = {"string": "seven", "array": np.arange(3.0), "nan": np.nan,
                      "negative": -1, "huge": 2**62, "zero": 0,
                      "json": "{\"law\": [1, 2]}"}[how]


DATASET_EDITS = ["delete", "group", "huge", "huge_rows", "dtype_float", "dtype_int",
                 "dtype_str", "extra_row", "scalar", "transpose", "nan", "negative"]
ATTR_EDITS = ["delete", "string", "array", "nan", "negative", "huge", "zero", "json"]
FILE_EDITS = ["truncate", "garbage", "empty", "text"]


@st.composite
def hdf5_edits(draw, template):
    """A list of edits of the file ``template``: datasets, attributes, bytes."""
    datasets, attrs = _h5_items(template)
    edits = []
    for _ in range(draw(st.integers(1, 2))):
        kind = draw(st.sampled_from(["dataset", "dataset", "attr", "file"]))
        if kind == "dataset":
            edits.append(("dataset", draw(st.sampled_from(datasets)),
                          draw(st.sampled_from(DATASET_EDITS))))
        elif kind == "attr":
            obj, key = draw(st.sampled_from(attrs))
            edits.append(("attr", (obj, key), draw(st.sampled_from(ATTR_EDITS))))
        else:
            edits.append(("file", draw(st.floats(0.0, 1.0)),
                          draw(st.sampled_from(FILE_EDITS))))
    return edits


def apply_edits(path, edits):
    for kind, where, how in edits:
        if kind == "dataset":
            with h5py.File(path, "a") as f:
                if where in f and isinstance(f[where], h5py.Dataset):
                    _mutate_dataset(f, where, how)
        elif kind == "attr":
            with h5py.File(path, "a") as f:
                obj, key = where
                if obj in f and key in f[obj].attrs:
                    _mutate_attr(f, obj, key, how)
        else:
            data = Path(path).read_bytes()
            Path(path).write_bytes({
                "truncate": data[:int(where * len(data))],
                "garbage": bytes(range(256)) * 8,
                "empty": b"",
                "text": b"x y r\n0 0 1\n"}[how])
            return  # not HDF5 any more: later edits cannot apply


@contextlib.contextmanager
def bounded_memory(limit=64 * 2**20):
    """Fail if the block allocates more than ``limit`` bytes of traced memory."""
    tracemalloc.start()
    try:
        yield
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < limit, f"{peak / 2**20:.0f} MiB allocated"


RVE_FROM_FILE = {"packing": {"file": "packing.h5"},
                 "test": {"axial_strain": 0.01, "increment": 0.005}}


def check_rve_packing(tmp, edits):
    """``hmm rve`` with a crafted ``[packing] file``: stopped after the packing is
    read (``compress`` patched), from ``tmp``."""
    (tmp / "rve.toml").write_text(to_toml(RVE_FROM_FILE))
    before = listing(tmp)
    with mock.patch("hmm.experiment.compress", _stop), bounded_memory():
        code, _, err = run_cli("hmm", ["rve", "rve.toml", "-o", "out"], tmp)
    assert_clean_outcome(code, err, "hmm rve", repr(edits))
    assert listing(tmp) == before, f"files written for {edits!r}"
    return code, err


def test_the_crafted_rve_packing_is_valid(tmp_path):
    write_rve_packing(tmp_path / "packing.h5")
    assert check_rve_packing(tmp_path, [])[0] == 0


def test_crafted_rve_packings_end_in_a_run_or_one_line(tmp_path_factory):
    template = tmp_path_factory.mktemp("template") / "packing.h5"
    write_rve_packing(template)

    @cases(N_HDF5)
    @given(hdf5_edits(template))
    def prop(edits):
        with tempfile.TemporaryDirectory() as tmp:
            tmp = Path(tmp)
            shutil.copy(template, tmp / "packing.h5")
            apply_edits(tmp / "packing.h5", edits)
            check_rve_packing(tmp, edits)

    prop()


@pytest.mark.parametrize("where", ["bodies/pos", "bodies/radius", "neighbors/pairs",
                                   "contacts/hist", "rve/deformation", "gravity",
                                   "cell/h"])
def test_a_declared_huge_dataset_is_refused_before_reading(tmp_path, where):
    path = tmp_path / "packing.h5"
    write_rve_packing(path)
    apply_edits(path, [("dataset", where, "huge")])
    assert path.stat().st_size < 10**6
    code, err = check_rve_packing(tmp_path, where)
    assert code == 2 and "packing.h5" in err, err


def test_checkpoint_readers_refuse_huge_and_malformed_files(tmp_path):
    from dem import LinearSpring
    from dem.io.checkpoint import load_checkpoint, read_bodies, read_group

    path = tmp_path / "packing.h5"
    law = LinearSpring(kn=1e8, kt=5e7, mu=0.5)
    for edits in ([("dataset", "bodies/pos", "huge")],
                  [("dataset", "bodies/mass", "huge_rows")],
                  [("dataset", "contacts/radius_ref", "huge")],
                  [("dataset", "model/params_pp", "huge")],
                  [("attr", ("/", "dim"), "array")],
                  [("dataset", "bodies/pos", "group")],
                  [("file", 0.5, "truncate")]):
        write_rve_packing(path)
        with h5py.File(path, "a") as f:
            f.create_group("model")["params_pp"] = np.zeros((1, 1, 4))
        apply_edits(path, edits)
        with bounded_memory():
            for read in (lambda: load_checkpoint(path, law),
                         lambda: read_group(path, "rve"),
                         lambda: read_group(path, "bodies")):
                try:
                    read()
                except ValueError as exc:
                    assert "\n" not in str(exc)
    # a bodies file (write_bodies' format) is checked the same way
    write_rve_packing(path)
    with h5py.File(path, "a") as f:
        f.attrs["format"] = "dem.bodies"
    apply_edits(path, [("dataset", "bodies/pos", "huge")])
    with bounded_memory(), pytest.raises(ValueError, match="bodies/pos"):
        read_bodies(path)
    apply_edits(path, [("file", 0.3, "truncate")])
    with pytest.raises(ValueError):
        read_bodies(path)


# --------------------------------------------------------------------------- hmm run
ELASTIC = {
    "mesh": {"size": [1.0, 2.0], "cells": [1, 2]},
    "dirichlet": [{"boundary": "bottom", "component": "y"},
                  {"boundary": "top", "component": "y", "value": -0.01},
                  {"boundary": "left", "component": "x"}],
    "micro": {"model": "linear_elastic", "young": 1e6, "poisson": 0.3},
    "load": {"steps": 2},
    "output": {"checkpoint_every": 1},
}


def test_a_bad_micro_packing_leaves_no_output(tmp_path):
    """The packing is read after the output is opened: a refusal removes it."""
    problem = copy.deepcopy(BASES["problem"])
    problem["micro"] = {"model": "dem", "packing": "packing.h5"}
    (tmp_path / "problem.toml").write_text(to_toml(problem))
    for edits in ([("file", 0.5, "truncate")], [("dataset", "bodies/pos", "huge")],
                  [("attr", ("rve", "law"), "json")]):
        write_rve_packing(tmp_path / "packing.h5")
        apply_edits(tmp_path / "packing.h5", edits)
        before = listing(tmp_path)
        code, _, err = run_cli("hmm", ["run", "problem.toml", "-o", "out"], tmp_path)
        assert code == 2 and "packing" in err and err.count("\n") == 1, err
        assert listing(tmp_path) == before
        assert not (tmp_path / "out").exists()


@pytest.fixture(scope="module")
def stopped_run(tmp_path_factory):
    """An elastic problem stopped after load step 1: its directory, checkpoint in it."""
    tmp = tmp_path_factory.mktemp("stopped")
    (tmp / "problem.toml").write_text(to_toml(ELASTIC))
    code, _, err = run_cli("hmm", ["run", "problem.toml", "-o", "out", "--stop-after",
                                   "1", "--no-progress"], tmp)
    assert code == 0, err
    assert (tmp / "out" / "checkpoint.h5").exists()
    return tmp


def test_crafted_checkpoints_end_in_a_run_or_one_line(stopped_run):
    template = stopped_run / "out" / "checkpoint.h5"

    @cases(N_CHECKPOINT)
    @given(hdf5_edits(template))
    def prop(edits):
        with tempfile.TemporaryDirectory() as tmp:
            tmp = Path(tmp)
            shutil.copytree(stopped_run, tmp, dirs_exist_ok=True)
            apply_edits(tmp / "out" / "checkpoint.h5", edits)
            fields = (tmp / "out" / "fields.h5").read_bytes()
            with bounded_memory(), mock.patch("hmm.io.write_figures"):
                code, _, err = run_cli("hmm", ["run", "problem.toml", "-o", "out",
                                               "--restart", "--stop-after", "1",
                                               "--no-progress"], tmp)
            assert_clean_outcome(code, err, "hmm run", repr(edits))
            if code == 2:
                assert (tmp / "out" / "fields.h5").read_bytes() == fields, \
                    f"fields.h5 changed by a refused restart {edits!r}"

    prop()


# --------------------------------------------------------------------------- code
UNSAFE = re.compile(r"\bpickle\b|\bcloudpickle\b|\bmarshal\b|\bshelve\b|\beval\(|"
                    r"\bexec\(|allow_pickle\s*=\s*True|yaml\.load\(|np\.load\(")


#: the one pickle of the package, line by line: dem._jit.prepare hands a compilation
#: (a factory's name and arguments, numba types) to its own child process through a
#: pipe; the child reads that pipe, never a file
TRUSTED = {("dem/_jit.py", "import pickle"),
           ("dem/_jit.py", "input=pickle.dumps((numba.config.CACHE_DIR, made, sig)),"),
           ("dem/_jit.py", "numba.config.CACHE_DIR, (module, name, args, kwargs), sig = "
                           "pickle.load(sys.stdin.buffer)"),
           # the law dispatch: source written from integer codes and identifiers the
           # package's own law classes give (checked there), nothing read from a file
           ("dem/_jit.py", 'exec(compile("\\n".join(lines), f"<dem._jit.branch_on {name}>", '
                           '"exec"), scope, namespace)')}


def test_input_files_cannot_run_code():
    """No deserialiser that runs code on anything read from a file."""
    hits = [f"{p.relative_to(ROOT)}:{i}: {line.strip()}"
            for pkg in ("dem", "hmm") for p in sorted((ROOT / pkg).rglob("*.py"))
            for i, line in enumerate(p.read_text().splitlines(), 1)
            if UNSAFE.search(line)
            and (str(p.relative_to(ROOT)), line.strip()) not in TRUSTED]
    assert not hits, "\n".join(hits)


# --------------------------------------------------------------------------- edges
# Issue 32: sizes and derived values, parsing limits, tracebacks, time-step wording.
# Every case must end in exit status 2 and one line naming the key or the file.
def refused(prog, argv, cwd, *needles, patch=None, label=None):
    """Run ``prog argv`` from ``cwd`` (``patch``: a function replaced by a stop, where
    the real work would start) and assert a one-line refusal holding ``needles``,
    starting ``label: error:`` (default ``dem`` or ``hmm COMMAND``); returns stdout."""
    with mock.patch(patch, _stop) if patch else contextlib.nullcontext():
        code, out, err = run_cli(prog, argv, cwd)
    label = label or (prog if prog == "dem" else f"hmm {argv[0]}")
    assert code == 2, f"exit {code}:\n{err}"
    assert_clean_outcome(code, err, label, " ".join(map(str, argv)))
    for needle in needles:
        assert needle in err, f"{needle!r} not in {err!r}"
    return out


def write_case(tmp, kind, edits=(), name=None):
    """The base file of ``kind`` with ``edits`` ({"section/key": value}, nested with
    "/"; None drops the key) written into ``tmp``; its name."""
    data = copy.deepcopy(BASES[kind])
    for path, value in dict(edits).items():
        *parents, key = path.split("/")
        table = data
        for p in parents:
            table = table.setdefault(p, {})
        if value is None:
            table.pop(key, None)
        else:
            table[key] = value
    name = name or f"{kind}.toml"
    (Path(tmp) / name).write_text(to_toml(data))
    return name


#: the command of each file kind, stopped where its run would start
STOPPED = {"scene": ("dem", ["run"], ["--dry-run"], None),
           "problem": ("hmm", ["run"], ["--dry-run"], None),
           "rve": ("hmm", ["rve"], [], "hmm.experiment.make_packing"),
           "sweep": ("hmm", ["batch"], [], "hmm.queue.run_batch")}


def refused_file(tmp, kind, edits, *needles):
    name = write_case(tmp, kind, edits)
    prog, command, dry, patch = STOPPED[kind]
    with bounded_memory():
        return refused(prog, [*command, name, "-o", "out", *dry], tmp, name, *needles,
                       patch=patch)


@pytest.mark.parametrize("kind, edits, needles", [
    ("rve", {"packing/count": 10**9}, ["[packing] count = 1000000000", "DEM_MAX_PARTICLES"]),
    ("problem", {"micro/count": 10**9}, ["[micro] count = 1000000000",
                                         "DEM_MAX_PARTICLES"]),
    ("problem", {"micro/count": 400_000}, ["[micro] count x Gauss points = 400000 x 32",
                                           "DEM_MAX_PARTICLES"]),
    ("sweep", {"base/packing/count": 10**9}, ["[packing] count = 1000000000",
                                              "DEM_MAX_PARTICLES"]),
    ("problem", {"load/steps": 10**15}, ["[load] steps", "HMM_MAX_LOAD_STEPS"]),
    ("rve", {"test/increment": 1e-300}, ["[test] axial_strain / increment",
                                         "HMM_MAX_INCREMENTS"]),
    ("scene", {"simulation/steps": 2**63}, ["[simulation] steps", "64-bit"]),
    ("rve", {"packing/seed": 10**20}, ["[packing] seed", "64-bit"]),
])
def test_huge_sizes_name_the_limit_and_how_to_raise_it(tmp_path, kind, edits, needles):
    refused_file(tmp_path, kind, edits, *needles)


@pytest.mark.parametrize("kind, edits, needles", [
    ("scene", {"particles/radius": 1e300}, ["[particles] radius = 1e+300 m"]),
    ("scene", {"particles/density": 1e-300}, ["[particles]", "density = 1e-300",
                                              "particle mass"]),
    ("rve", {"packing/radius": 1e300}, ["[packing] radius = 1e+300 m"]),
    ("rve", {"packing/density": 1e-300}, ["[packing]", "density = 1e-300"]),
    ("problem", {"micro/radius": [1e-3, 1e300]}, ["[micro] radius = 1e+300 m"]),
    ("sweep", {"base/packing/radius": 1e300}, ["[packing] radius = 1e+300 m"]),
])
def test_values_that_overflow_derived_quantities_are_refused(tmp_path, kind, edits,
                                                             needles):
    refused_file(tmp_path, kind, edits, *needles)


def test_a_limit_is_raised_or_lowered_by_its_environment_variable(tmp_path, monkeypatch):
    name = write_case(tmp_path, "scene")  # 30 particles
    monkeypatch.setenv("DEM_MAX_PARTICLES", "10")
    refused("dem", ["run", name, "--dry-run"], tmp_path,
            "count = 30 exceeds the limit of 10 particles", "DEM_MAX_PARTICLES")
    monkeypatch.setenv("HMM_MAX_EXPERIMENTS", "4")  # the sweep has 8
    sweep = write_case(tmp_path, "sweep")
    refused("hmm", ["batch", sweep], tmp_path, "[sweep] grid", "HMM_MAX_EXPERIMENTS",
            patch="hmm.queue.run_batch")
    monkeypatch.setenv("DEM_MAX_PARTICLES", "100")
    code, out, err = run_cli("dem", ["run", name, "--dry-run"], tmp_path)
    assert code == 0 and "valid" in out, err


def test_the_python_api_refuses_huge_packings_before_allocation(monkeypatch):
    from dem.limits import LimitError
    from dem.rve import particle_radii

    monkeypatch.setenv("DEM_MAX_PARTICLES", "1000")
    with pytest.raises(LimitError, match="DEM_MAX_PARTICLES"):
        particle_radii(1001, [1e-3, 2e-3])
    assert particle_radii(1000, [1e-3, 2e-3]).shape == (1000,)


@pytest.mark.parametrize("kind", sorted(STOPPED))
@pytest.mark.parametrize("depth", [40, 5000])
def test_deeply_nested_files_are_refused_in_one_line(tmp_path, kind, depth):
    name = write_case(tmp_path, kind)
    path = tmp_path / name
    path.write_text(path.read_text() + "deep = " + "[" * depth + "]" * depth + "\n")
    prog, command, dry, patch = STOPPED[kind]
    refused(prog, [*command, name, *dry], tmp_path, name, "nested more than 32 levels",
            patch=patch)


def test_an_oversized_file_is_refused_in_one_line(tmp_path):
    name = write_case(tmp_path, "scene")
    with open(tmp_path / name, "a") as f:
        f.write(("# padding " + "x" * 1000 + "\n") * (17 * 1024))
    refused("dem", ["run", name, "--dry-run"], tmp_path, name, "larger than 16 MiB")


@pytest.mark.parametrize("text", [b"junk text\n", bytes(range(256)) * 4])
def test_a_garbage_mesh_file_is_one_line_not_meshio_exit(tmp_path, text):
    (tmp_path / "mesh.msh").write_bytes(text)
    problem = copy.deepcopy(ELASTIC)
    problem["mesh"] = {"file": "mesh.msh"}
    (tmp_path / "p.toml").write_text(to_toml(problem))
    out = refused("hmm", ["run", "p.toml", "--dry-run"], tmp_path,
                  "[mesh] cannot read mesh file", "mesh.msh")
    assert out == ""  # meshio's own print is captured


@pytest.mark.parametrize("step", ["0", "-1"])
def test_stop_after_must_be_a_load_step(tmp_path, step):
    (tmp_path / "p.toml").write_text(to_toml(ELASTIC))
    refused("hmm", ["run", "p.toml", "-o", "out", f"--stop-after={step}"], tmp_path,
            "argument --stop-after: must be a load step >= 1", label="hmm")
    assert not (tmp_path / "out").exists()


def test_a_restart_must_stop_after_its_checkpoint(stopped_run, tmp_path):
    shutil.copytree(stopped_run, tmp_path, dirs_exist_ok=True)
    before = listing(tmp_path)
    refused("hmm", ["run", "problem.toml", "-o", "out", "--restart", "--stop-after", "1",
                    "--no-progress"], tmp_path, "--stop-after 1", "checkpoint.h5")
    assert listing(tmp_path) == before


def test_overwrite_cannot_replace_a_directory_named_like_an_output(tmp_path):
    (tmp_path / "p.toml").write_text(to_toml(ELASTIC))
    (tmp_path / "out" / "fields.h5").mkdir(parents=True)
    refused("hmm", ["run", "p.toml", "-o", "out", "--overwrite", "--no-progress"],
            tmp_path, "fields.h5 is a directory")


def test_a_directory_given_as_a_packing_file_is_named_so(tmp_path):
    (tmp_path / "packing.h5").mkdir()
    name = write_case(tmp_path, "rve", {"packing": {"file": "packing.h5"}, "contact": None})
    refused("hmm", ["rve", name, "-o", "out"], tmp_path, "[packing] file",
            "packing.h5 is a directory", patch="hmm.experiment.make_packing")
    name = write_case(tmp_path, "problem", {"micro/packing": "packing.h5",
                                            "micro/count": None})
    refused("hmm", ["run", name, "--dry-run"], tmp_path, "[micro] packing",
            "packing.h5 is a directory")


def test_a_scene_names_the_stable_time_step_and_takes_allow_unstable_dt(tmp_path):
    """One name for the threshold: the message, the scene reference and the guides."""
    name = write_case(tmp_path, "scene", {"simulation/dt": 1.0})
    refused("dem", ["run", name, "--dry-run"], tmp_path,
            "[simulation] dt = 1 s exceeds the stable time step dt_stable",
            "allow_unstable_dt = true")
    name = write_case(tmp_path, "scene", {"simulation/dt": 1.0,
                                          "simulation/allow_unstable_dt": True})
    code, out, err = run_cli("dem", ["run", name, "--dry-run"], tmp_path)
    assert code == 0 and "dt = 1 s" in out, err
    for page in ("quickstart.md", "stability.md", "theory.md", "scene_reference.md"):
        text = " ".join((ROOT / "docs" / page).read_text().split())
        assert "stable time step" in text and "allow_unstable_dt" in text, page
    assert "a larger step than `sim.dt_crit` is refused" not in \
        (ROOT / "docs" / "quickstart.md").read_text()


def test_dry_runs_print_a_memory_estimate(tmp_path):
    """1 kB a particle (dem.limits.BYTES_PER_PARTICLE), 20 kB an RVE besides."""
    name = write_case(tmp_path, "scene")  # 30 particles
    code, out, err = run_cli("dem", ["run", name, "--dry-run"], tmp_path)
    assert code == 0 and "memory about 30 kB for 30 particles" in out, err
    name = write_case(tmp_path, "problem")  # 60 disks at each of 32 Gauss points
    code, out, err = run_cli("hmm", ["run", name, "--dry-run"], tmp_path)
    assert code == 0 and "memory about 2.6 MB for 1920 particles in 32 RVEs" in out, err


def test_steps_on_the_command_line_are_a_64_bit_integer(tmp_path):
    name = write_case(tmp_path, "scene")
    refused("dem", ["run", name, "--dry-run", "--steps", str(2**63)], tmp_path,
            "--steps must be in [0, 9223372036854775807]")


def test_a_particle_file_is_counted_against_the_limit_before_it_is_parsed(tmp_path,
                                                                           monkeypatch):
    (tmp_path / "packing.txt").write_text("# x y z r\n" + "".join(
        f"{0.02 * i} 0.04 0.04 0.004\n" for i in range(1, 4)))
    name = write_case(tmp_path, "scene", {"particles": {
        "generator": "file", "file": "packing.txt", "density": 2500.0}})
    monkeypatch.setenv("DEM_MAX_PARTICLES", "2")
    refused("dem", ["run", name, "--dry-run"], tmp_path,
            "packing.txt holds more than 2 particles", "DEM_MAX_PARTICLES")
    monkeypatch.setenv("DEM_MAX_PARTICLES", "3")
    code, out, err = run_cli("dem", ["run", name, "--dry-run"], tmp_path)
    assert code == 0 and "3 spheres" in out, err
