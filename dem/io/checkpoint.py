"""Checkpoint and restart that continue a run bit for bit; failure output.

A checkpoint is an HDF5 file holding the full state of a :class:`~dem.Simulation`::

    /            attrs: format = "dem.checkpoint", version, software, config (when
                        given), dim, step, time [s], dt [s], damping,
                        overlap_limit, skin [m], backend, n_builds, has_box
    /gravity     (d,) [m/s^2]          /wall_work (1,) [J]
    /bodies/     every array of Bodies.ARRAYS (attrs: dim)
    /neighbors/  pairs (m, 2) int32, img (m, d) int32, wall_pairs (mw, 2) int32,
                 pos_ref (n, d) [m]
    /box/        lo, hi (d,) [m], periodic (d,) bool (only if the scene has a box)
    /cell/       h, lgrad (d, d), origin (d,), cellref (2, d, d) (a PeriodicCell instead)
    /contacts/   per sphere pair: hist (m, 3), touch (m,) uint8, fpair (m, d);
                 per sphere-wall pair: whist (mw, 3), wforce (mw, d), wtorque;
                 radius_ref (n,), the radii at the last neighbour build;
                 inner (n_inner,) int64 and pos_inner (n, d): the pairs the step
                 loop evaluates and the positions they were chosen at (attr n_inner,
                 -1 when the list is due to be remade)
    /meshes/     mesh walls (only if the scene has some; :mod:`dem.mesh_scene`): the
                 combined mesh (vertices [m], faces, face_normal, the wall of each
                 vertex and face, vert_ref [m]), each wall's center [m], velocity
                 [m/s], ang_vel [rad/s] and mat_id, and the contact rows (mrows,
                 mstart, mhist, mtouch, mpoint, mforce, mtorque, mpower)
    /model/      params_pp, params_pw: the parameter tables in use (a restart with
                 other tables is allowed but logged as a warning)

Every dataset carries ``unit`` (and ``sign`` where it matters):
:func:`dem.io.meta.state_units`.

Observers, controllers and state objects are not saved: pass them again to
:func:`load_checkpoint`. The contact model is code, not data: pass it too.

A file written by :func:`write_last_good_state` holds only ``/bodies`` (format
``"dem.bodies"``); read it back with :func:`read_bodies`.
"""

import logging
import os

import h5py
import numpy as np

from ..boundary import PeriodicCell
from ..mesh_scene import walls_from_snapshot
from ..neighbors import Box
from ..shapes import Shape
from ..shapes.registry import kinds_with
from ..simulation import Simulation
from ..state import Bodies
from .files import OutputError, write_h5_atomic
from .hdf5 import read_bounded
from .meta import label, stamp, state_units

log = logging.getLogger(__name__)

FORMAT = "dem.checkpoint"
BODIES_FORMAT = "dem.bodies"
VERSION = 1

_F8, _I4 = np.dtype(np.float64), np.dtype(np.int32)

_B = np.dtype(bool)



def _body_spec(dim):
    nr = 1 if dim == 2 else 3
    return {"pos": ((dim,), _F8), "vel": ((dim,), _F8),
            "rot": ((4 if dim == 3 else 1,), _F8), "ang_vel": ((nr,), _F8),
            "force": ((dim,), _F8), "torque": ((nr,), _F8),
            "radius": ((), _F8), "mass": ((), _F8), "inertia": ((nr,), _F8),
            "kind": ((), _I4), "mat_id": ((), _I4), "is_fixed": ((), _B),
            "normal": ((dim,), _F8), "density": ((), _F8)}


_I8 = np.dtype(np.int64)
#: shape-table arrays: (name, trailing shape, dtype, length: "ns", "ns+1" or a pool)
_TABLE_SPEC = (("kind", (), _I8, "ns"), ("param", (4,), _F8, "ns"), ("scale", (), _F8, "ns"),
               ("brad", (), _F8, "ns"), ("xform", (12,), _F8, "ns"),
               ("vstart", (), _I8, "ns+1"), ("verts", (3,), _F8, "vstart"),
               ("fstart", (), _I8, "ns+1"), ("faces", (4,), _F8, "fstart"),
               ("tstart", (), _I8, "ns+1"), ("tris", (3,), _I8, "tstart"),
               ("cstart", (), _I8, "ns+1"), ("part_kind", (), _I8, "cstart"),
               ("part_row", (), _I8, "cstart"), ("part_off", (3,), _F8, "cstart"),
               ("part_rot", (4,), _F8, "cstart"), ("part_rad", (), _F8, "cstart"))
#: the compound part pool, absent from files written before compounds existed
_COMPOUND_NAMES = ("cstart", "part_kind", "part_row", "part_off", "part_rot", "part_rad")
#: shape-table kinds a file may hold (spheres and planes have no row; custom SDFs are code)
_STORABLE_KINDS = kinds_with("stored")


# ------------------------------------------------------------------ bodies
def _write_bodies(group, bodies):
    group.attrs["dim"] = int(bodies.dim)
    for name in Bodies.ARRAYS:
        group.create_dataset(name, data=getattr(bodies, name))
    t = bodies.table
    if t.n:
        if np.any(t.kind == Shape.CUSTOM):
            raise ValueError("bodies with a user-defined shape (CustomShape) cannot be "
                             "written: their signed distance function is code, not data")
        g = group.create_group("shape_table")
        for name, _, _, _ in _TABLE_SPEC:
            g.create_dataset(name, data=getattr(t, name))


def _read_table(path, group, n_bodies_shape):
    """The shape table from ``group`` (checked: dtypes, sizes, offsets, indices)."""
    from ..shapes.table import ShapeTable

    t = ShapeTable()
    if "kind" not in group:
        raise ValueError(f"{path}: bodies/shape_table/kind is missing")
    ns = group["kind"].shape[0] if group["kind"].ndim == 1 else -1
    if ns < 0:
        raise ValueError(f"{path}: bodies/shape_table/kind must be one-dimensional")
    for name, tail, dtype, length in _TABLE_SPEC:
        if name in _COMPOUND_NAMES and "cstart" not in group:
            if name == "cstart":
                t.cstart = np.zeros(ns + 1, np.int64)
            continue
        if name not in group:
            raise ValueError(f"{path}: bodies/shape_table/{name} is missing")
        if length == "ns":
            rows = ns
        elif length == "ns+1":
            rows = ns + 1
        else:
            start = getattr(t, length)
            if start[0] != 0 or np.any(np.diff(start) < 0):
                raise ValueError(f"{path}: bodies/shape_table/{length} is not a valid "
                                 f"offset array")
            rows = int(start[-1])
        setattr(t, name, _checked(path, f"bodies/shape_table/{name}", group[name],
                                  (rows, *tail), dtype))
    if np.any(~np.isin(t.kind, _STORABLE_KINDS)):
        raise ValueError(f"{path}: bodies/shape_table/kind holds an unknown or "
                         f"non-storable shape kind")
    parts = np.diff(t.cstart)
    row_kind = np.where(t.part_row >= 0, t.kind[np.clip(t.part_row, 0, max(ns - 1, 0))],
                        Shape.SPHERE)
    if (np.any((parts > 0) != (t.kind == Shape.COMPOUND)) or np.any(t.part_row >= ns)
            or np.any((t.part_row < 0) != (t.part_kind == Shape.SPHERE))
            or np.any(row_kind != t.part_kind) or np.any(t.part_kind == Shape.COMPOUND)
            or not (np.all(np.isfinite(t.part_off)) and np.all(np.isfinite(t.part_rot))
                    and np.all(t.part_rad > 0.0))):
        raise ValueError(f"{path}: bodies/shape_table holds an inconsistent compound "
                         f"part pool")
    for s in range(ns):
        nv = t.vstart[s + 1] - t.vstart[s]
        tri = t.tris[t.tstart[s]:t.tstart[s + 1]]
        if tri.size and (tri.min() < 0 or tri.max() >= nv):
            raise ValueError(f"{path}: bodies/shape_table/tris of row {s} index past "
                             f"its {nv} vertices")
    if not (np.all(np.isfinite(t.verts)) and np.all(np.isfinite(t.faces))
            and np.all(t.scale > 0.0) and np.all(t.brad > 0.0)):
        raise ValueError(f"{path}: bodies/shape_table holds non-finite or non-positive "
                         f"geometry")
    if n_bodies_shape.size and n_bodies_shape.max() >= ns:
        raise ValueError(f"{path}: bodies/shape points past the {ns} rows of the table")
    t.shapes = [None] * ns
    return t


def _read_bodies(path, group):
    """Bodies from ``group``, every array checked for shape and dtype."""
    if "dim" not in group.attrs or int(group.attrs["dim"]) not in (2, 3):
        raise ValueError(f"{path}: bodies need a dim attribute of 2 or 3")
    dim = int(group.attrs["dim"])
    if "pos" not in group:
        raise ValueError(f"{path}: bodies/pos is missing")
    if not isinstance(group["pos"], h5py.Dataset) or group["pos"].ndim != 2:
        raise ValueError(f"{path}: bodies/pos must be an (n, {dim}) dataset")
    n = group["pos"].shape[0]
    arrays = {}
    for name, (tail, dtype) in _body_spec(dim).items():
        if name not in group:
            raise ValueError(f"{path}: bodies/{name} is missing")
        arrays[name] = _checked(path, f"bodies/{name}", group[name], (n, *tail), dtype)
    table = None
    if "shape" in group:  # files written before shapes existed have none
        arrays["shape"] = _checked(path, "bodies/shape", group["shape"], (n,), _I4)
        if "shape_table" in group:
            table = _read_table(path, group["shape_table"], arrays["shape"])
        elif np.any(arrays["shape"] >= 0):
            raise ValueError(f"{path}: bodies/shape refers to a shape table that is missing")
    return Bodies(dim=dim, table=table, **arrays)


def _checked(path, name, dataset, shape, dtype):
    if not isinstance(dataset, h5py.Dataset):
        raise ValueError(f"{path}: {name} is not a dataset")
    if dataset.shape != tuple(shape) or dataset.dtype != dtype:
        raise ValueError(f"{path}: {name} is {dataset.dtype}{dataset.shape}, "
                         f"expected {dtype}{tuple(shape)}")
    return np.ascontiguousarray(read_bounded(dataset, name))


def _open(path, fmt):
    """Open an HDF5 file for reading, checking its format tag (ValueError if wrong)."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(path)
    try:
        f = h5py.File(path, "r")
    except OSError as err:
        raise ValueError(f"{path} is not a {fmt} file (not HDF5: {err})") from None
    try:
        tag = f.attrs.get("format")
        version = f.attrs.get("version")
    except (OSError, KeyError) as err:
        f.close()
        raise ValueError(f"{path} is not a readable {fmt} file ({err})") from None
    if isinstance(tag, bytes):
        tag = tag.decode()
    if not isinstance(tag, str) or tag != fmt:
        f.close()
        raise ValueError(f"{path} is not a {fmt} file (format tag {tag!r})")
    if not isinstance(version, (int, np.integer)) or version != VERSION:
        f.close()
        raise ValueError(f"{path}: {fmt} version {version} is not supported "
                         f"(need {VERSION})")
    return f


def _write_atomic(path, fill):
    """Write an HDF5 file with ``fill(h5file)`` into ``path.tmp``, then rename it
    (:func:`dem.io.files.write_h5_atomic`: a failed write is one OutputError)."""
    path = os.fspath(path)
    parent = os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(parent, exist_ok=True)
    except OSError as err:
        raise OutputError(path, err) from None
    return write_h5_atomic(path, fill)


# ------------------------------------------------------------------ checkpoint
def save_checkpoint(sim, path, extra=None, config=None):
    """Write the full state of ``sim`` to ``path`` (HDF5, atomically).

    An unprimed simulation is primed first (neighbour lists and forces of the current
    state), exactly as its next :meth:`~dem.Simulation.run` would.

    Parameters
    ----------
    sim : Simulation
    path : str or os.PathLike
        Written as ``path + ".tmp"`` and renamed into place: an interrupted save never
        leaves a partial file at ``path``.
    extra : callable, optional
        ``extra(h5file)`` adds groups of a caller (e.g. an RVE's settings) to the
        same atomic write.
    config : str or dict, optional
        The configuration that made the state (a file's text, or settings stored as
        JSON): the file's ``config`` attribute.

    Returns
    -------
    str
        ``path``.
    """
    # the state as a snapshot has it; the file keeps its own layout (module docstring)
    state = sim.state_arrays()
    nl = sim.neighbors

    def fill(f):
        stamp(f, FORMAT, VERSION, config)
        f.attrs["dim"] = int(sim.dim)
        f.attrs["step"] = int(sim.step)
        f.attrs["time"] = float(sim.time)
        f.attrs["dt"] = float(sim.dt)
        f.attrs["damping"] = float(sim.damping)
        f.attrs["overlap_limit"] = float(sim.overlap_limit)
        f.attrs["skin"] = float(nl.skin)
        f.attrs["backend"] = str(nl.backend)
        f.attrs["n_builds"] = int(nl.n_builds)
        f.attrs["capacity"] = int(nl.capacity)
        f.attrs["has_box"] = sim.box is not None
        f.attrs["detection"] = str(sim.detection)
        f.attrs["admm_tol"] = float(sim.admm_tol)
        f.attrs["admm_max_iter"] = int(sim.admm_max_iter)
        f.create_dataset("gravity", data=np.asarray(sim.gravity, dtype=np.float64))
        f.create_dataset("wall_work", data=np.asarray(sim.wall_work, dtype=np.float64))
        _write_bodies(f.create_group("bodies"), sim.bodies)
        g = f.create_group("neighbors")
        for name in ("pairs", "img", "wall_pairs", "pos_ref"):
            g.create_dataset(name, data=getattr(nl, name))
        if sim.cell is not None:
            g = f.create_group("cell")
            for name in ("h", "lgrad", "origin"):
                g.create_dataset(name, data=getattr(sim.cell, name))
            g.create_dataset("cellref", data=state["cellref"])
            g.attrs["n_reductions"] = int(sim.cell.n_reductions)
        elif sim.box is not None:
            g = f.create_group("box")
            g.create_dataset("lo", data=np.asarray(sim.box.lo, dtype=np.float64))
            g.create_dataset("hi", data=np.asarray(sim.box.hi, dtype=np.float64))
            g.create_dataset("periodic", data=np.asarray(sim.box.periodic, dtype=bool))
        g = f.create_group("contacts")
        for name in _CONTACT_KEYS:
            if name in state:
                g.create_dataset(name, data=state[name])
        if not sim.shaped:
            # the inner list decides when the Verlet list is rebuilt: part of the state
            n_inner, n_internal = (int(x) for x in state["n_inner"])
            g.attrs["n_inner"] = n_inner
            g.attrs["n_internal"] = n_internal
            g.create_dataset("inner", data=state["inner"][:max(n_inner, 0)])
            g.create_dataset("pos_inner", data=state["pos_inner"])
        meshes = {k[5:]: v for k, v in state.items() if k.startswith("mesh.")}
        if meshes:
            g = f.create_group("meshes")
            for name, v in meshes.items():
                g.create_dataset(name, data=v)
        g = f.create_group("model")
        for bucket in ("pp", "pw"):
            g.create_dataset("params_" + bucket, data=sim.parameter_table(bucket))
        if extra is not None:
            extra(f)
        label(f, state_units(sim.dim))

    _write_atomic(path, fill)
    log.info("checkpoint of step %d written to %s", sim.step, path)
    return os.fspath(path)


def load_checkpoint(path, model, observers=(), controllers=(), state_objects=()):
    """Rebuild the :class:`~dem.Simulation` saved by :func:`save_checkpoint`.

    Running the returned simulation continues the saved run bit for bit (same
    model, same machine and library build).

    Parameters
    ----------
    path : str or os.PathLike
    model : ContactModel or Law
        The contact model of the saved run (models are code and are not saved).
    observers, controllers, state_objects : sequences
        Passed to :class:`~dem.Simulation`.

    Returns
    -------
    Simulation
        Primed: its neighbour lists, contact history and forces are the saved ones.

    Raises
    ------
    ValueError
        If ``path`` is not a checkpoint or an array has the wrong shape or dtype.
    """
    path = os.fspath(path)
    with _open(path, FORMAT) as f:
        try:
            state = _read_checkpoint(path, f)
        except _MALFORMED as err:
            raise ValueError(f"{path}: malformed checkpoint ({err})") from None
    a = state["attrs"]
    box = state["box"]
    sim = Simulation(state["bodies"], model, dt=a["dt"], gravity=state["gravity"],
                     damping=a["damping"], skin=a["skin"], box=box,
                     neighbor_backend=a["backend"], overlap_limit=a["overlap_limit"],
                     observers=observers, controllers=controllers,
                     state_objects=state_objects, allow_unstable_dt=True,
                     detection=a["detection"], admm_tol=a["admm_tol"],
                     admm_max_iter=a["admm_max_iter"],
                     walls=walls_from_snapshot(state["meshes"]))
    sim.restore(_snapshot(state))
    for bucket in ("pp", "pw"):
        name = "params_" + bucket
        saved, now = state["model"].get(name), sim.parameter_table(bucket)
        if saved is not None and not (saved.shape == now.shape
                                      and np.array_equal(saved, now, equal_nan=True)):
            log.warning("%s: the contact model differs from the saved one (%s); the "
                        "restart will not repeat the original run", path, name)
    log.info("restarted from %s at step %d", path, sim.step)
    return sim


#: what h5py and numpy raise on a file whose layout is not the one written here
_MALFORMED = (KeyError, AttributeError, TypeError, IndexError, OSError)


def _read_checkpoint(path, f):
    attrs = {"dim": int(f.attrs["dim"]), "step": int(f.attrs["step"]),
             "time": float(f.attrs["time"]), "dt": float(f.attrs["dt"]),
             "damping": float(f.attrs["damping"]),
             "overlap_limit": float(f.attrs["overlap_limit"]),
             "skin": float(f.attrs["skin"]), "n_builds": int(f.attrs["n_builds"]),
             "capacity": int(f.attrs.get("capacity", 0)),
             "has_box": bool(f.attrs["has_box"]),
             "detection": str(f.attrs.get("detection", "auto")),
             "admm_tol": float(f.attrs.get("admm_tol", 1e-8)),
             "admm_max_iter": int(f.attrs.get("admm_max_iter", 200))}
    if isinstance(f.attrs.get("detection"), bytes):
        attrs["detection"] = f.attrs["detection"].decode()
    backend = f.attrs["backend"]
    attrs["backend"] = backend.decode() if isinstance(backend, bytes) else str(backend)
    d = attrs["dim"]
    bodies = _read_bodies(path, f["bodies"])
    if bodies.dim != d:
        raise ValueError(f"{path}: bodies are {bodies.dim}D, the checkpoint says {d}D")
    n = bodies.n
    gravity = _checked(path, "gravity", f["gravity"], (d,), _F8)
    wall_work = _checked(path, "wall_work", f["wall_work"], (1,), _F8)
    g = f["neighbors"]
    m = g["pairs"].shape[0]
    mw = g["wall_pairs"].shape[0]
    neighbors = {"pairs": _checked(path, "neighbors/pairs", g["pairs"], (m, 2), _I4),
                 "img": _checked(path, "neighbors/img", g["img"], (m, d), _I4),
                 "wall_pairs": _checked(path, "neighbors/wall_pairs", g["wall_pairs"],
                                        (mw, 2), _I4),
                 "pos_ref": _checked(path, "neighbors/pos_ref", g["pos_ref"], (n, d),
                                     _F8)}
    for name in ("pairs", "wall_pairs"):
        p = neighbors[name]
        if p.size and (p.min() < 0 or p.max() >= n):
            raise ValueError(f"{path}: neighbors/{name} refers to bodies outside "
                             f"0..{n - 1}")
    g = f["contacts"]
    contacts = {}
    counts = {"pair": m, "wall": mw, "body": n,
              "hist": g["hist"].shape[1] if "hist" in g and g["hist"].ndim == 2 else 3}
    for _, cls in Simulation.BUNDLES[:4 if bodies.has_shapes else 2]:
        for name, col in zip(cls._fields, cls.COLUMNS, strict=True):
            if name in g:
                contacts[name] = _checked(path, f"contacts/{name}", g[name],
                                          col.shape(counts, d), np.dtype(col.dtype))
            elif name == "touch":  # older files: a pair with history was touching
                contacts[name] = np.any(contacts["hist"] != 0.0, axis=1).astype(np.uint8)
            else:
                raise ValueError(f"{path}: contacts/{name} is missing")
    radius_ref = _checked(path, "contacts/radius_ref", g["radius_ref"], (n,), _F8)
    n_inner = int(g.attrs.get("n_inner", -1))
    n_internal = int(g.attrs.get("n_internal", -1))
    if not -1 <= n_inner <= m:
        raise ValueError(f"{path}: contacts/n_inner = {n_inner} is outside -1..{m}")
    if n_inner >= 0 and not 0 <= n_internal <= n_inner:
        raise ValueError(f"{path}: contacts/n_internal = {n_internal} is outside "
                         f"0..{n_inner}")
    inner = np.zeros(0, np.int64)
    pos_inner = None
    if n_inner >= 0:
        inner = _checked(path, "contacts/inner", g["inner"], (n_inner,), np.dtype(np.int64))
        pos_inner = _checked(path, "contacts/pos_inner", g["pos_inner"], (n, d), _F8)
        if inner.size and (inner.min() < 0 or inner.max() >= m):
            raise ValueError(f"{path}: contacts/inner refers to pairs outside 0..{m - 1}")
    box = None
    cellref = None
    if attrs["has_box"] and "cell" in f:
        g = f["cell"]
        box = PeriodicCell(_checked(path, "cell/h", g["h"], (d, d), _F8),
                           _checked(path, "cell/origin", g["origin"], (d,), _F8))
        box.lgrad[:] = _checked(path, "cell/lgrad", g["lgrad"], (d, d), _F8)
        box.n_reductions = int(g.attrs.get("n_reductions", 0))
        cellref = _checked(path, "cell/cellref", g["cellref"], (2, d, d), _F8)
    elif attrs["has_box"]:
        g = f["box"]
        box = Box(_checked(path, "box/lo", g["lo"], (d,), _F8),
                  _checked(path, "box/hi", g["hi"], (d,), _F8),
                  _checked(path, "box/periodic", g["periodic"], (d,), _B))
    model = {k: read_bounded(v, f"model/{k}") for k, v in f["model"].items()} \
        if "model" in f else {}
    meshes = {"mesh." + k: np.asarray(v[()]) for k, v in f["meshes"].items()} \
        if "meshes" in f else {}
    return {"attrs": attrs, "bodies": bodies, "gravity": gravity, "meshes": meshes,
            "wall_work": wall_work, "neighbors": neighbors, "contacts": contacts,
            "radius_ref": radius_ref, "box": box, "cellref": cellref, "model": model,
            "inner": (n_inner, n_internal, inner, pos_inner)}


#: the contact-state fields a checkpoint keeps under /contacts (:attr:`Simulation.BUNDLES`)
_CONTACT_KEYS = tuple(k for _, cls in Simulation.BUNDLES for k in cls._fields) \
    + ("radius_ref",)


def _snapshot(state):
    """The :meth:`Simulation.snapshot` of the state read from a checkpoint."""
    a, b, nl = state["attrs"], state["bodies"], state["neighbors"]
    snap = {"b." + k: getattr(b, k) for k in Bodies.ARRAYS}
    snap.update({"nl." + k: v for k, v in nl.items()})
    snap.update(state["contacts"])
    snap["radius_ref"] = state["radius_ref"]
    snap["clock"] = np.array([a["step"], a["n_builds"], a["capacity"]], np.int64)
    snap["wall_work"] = state["wall_work"]
    snap.update(state["meshes"])
    n_inner, n_internal, inner, pos_inner = state["inner"]
    snap["n_inner"] = np.array([n_inner, n_internal], np.int64)
    snap["inner"] = inner
    snap["pos_inner"] = pos_inner if pos_inner is not None else b.pos
    box = state["box"]
    if isinstance(box, PeriodicCell):
        snap.update(cell_h=box.h, cell_lgrad=box.lgrad, cellref=state["cellref"],
                    cell_n=np.array([box.n_reductions], np.int64))
    return snap


def read_group(path, name, max_elements=10**6):
    """Attributes and (small) datasets of group ``name`` of a checkpoint file:
    ``{"attrs": {...}, "data": {...}}``. A dataset larger than ``max_elements`` is
    refused before it is read."""
    with _open(path, FORMAT) as f:
        if name not in f or not isinstance(f[name], h5py.Group):
            raise ValueError(f"{path}: no /{name} group")
        g = f[name]
        attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in g.attrs.items()}
        data = {}
        for k, v in g.items():
            if not isinstance(v, h5py.Dataset) or v.size > max_elements:
                raise ValueError(f"{path}: /{name}/{k} is not a small dataset")
            data[k] = read_bounded(v, f"/{name}/{k}")
    return {"attrs": attrs, "data": data}


# ------------------------------------------------------------------ failure output
def write_bodies(bodies, path, **attrs):
    """Write a :class:`~dem.Bodies` table to ``path`` (HDF5, atomically).

    Extra keyword arguments become file attributes (e.g. ``step=...``).
    """

    def fill(f):
        stamp(f, BODIES_FORMAT, VERSION)
        for k, v in attrs.items():
            f.attrs[k] = v
        _write_bodies(f.create_group("bodies"), bodies)
        label(f, state_units(bodies.dim))

    return _write_atomic(path, fill)


def read_bodies(path):
    """The :class:`~dem.Bodies` table of a file written by :func:`write_bodies`."""
    path = os.fspath(path)
    with _open(path, BODIES_FORMAT) as f:
        if "bodies" not in f:
            raise ValueError(f"{path}: no bodies group")
        try:
            return _read_bodies(path, f["bodies"])
        except _MALFORMED as err:
            raise ValueError(f"{path}: malformed bodies file ({err})") from None


def write_last_good_state(path):
    """A :meth:`~dem.Simulation.on_failure` hook that saves the last good bodies.

    When a run stops on a physical failure, the hook writes the bodies as they were
    before the failing chunk of steps (``sim.step`` is then the step of the failure)
    to ``path``; read them back with :func:`read_bodies`. When no earlier state exists
    (failure while priming) the current bodies are written, with ``is_last_good``
    False. A write error is logged, never raised, so that it cannot hide the
    simulation's own error.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    callable
        ``hook(sim, last_good_bodies)``.
    """
    path = os.fspath(path)

    def hook(sim, last_good_bodies):
        bodies = sim.bodies if last_good_bodies is None else last_good_bodies
        try:
            write_bodies(bodies, path, failed_at_step=int(sim.step),
                         failed_at_time=float(sim.time), dt=float(sim.dt),
                         is_last_good=last_good_bodies is not None)
        except (OSError, ValueError, RuntimeError):
            log.exception("could not write the last good state to %s", path)
        else:
            log.warning("simulation failed at step %d: last good state written to %s",
                      sim.step, path)

    return hook
