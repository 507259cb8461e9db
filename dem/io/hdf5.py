"""Time series of a simulation in HDF5 (h5py), with XDMF side files for ParaView and
meshio (:mod:`dem.io.xdmf`).

:class:`H5Writer` is an observer: whenever its trigger fires it appends one frame.

File layout (one group per frame, because the number of contacts changes from frame
to frame; frame groups are numbered ``000000, 000001, ...`` in the order written).
A frame holds every *particle*: every body that is not a wall (spheres and level-set
shapes alike), in body order::

    /                       attrs: format = "dem.h5writer", version, software,
                                   config (when given), dim, n_frames
    /frames/000000/         attrs: step, time [s], dt [s], dim, n_particles,
                                   n_spheres (particles of kind SPHERE), n_walls,
                                   n_contacts, n_surface_cells
        id       (n,)    int32    body index of each particle in ``sim.bodies``
        kind     (n,)    int32    :class:`~dem.shapes.Shape` code of each particle
        pos      (n, d)  float64  [m], centre of mass
        vel      (n, d)  float64  [m/s]
        rot      (n, 4) or (n, 1) float64  quaternion (w, x, y, z) in 3D,
                                           angle [rad] in 2D
        ang_vel  (n, 3) or (n, 1) float64  [rad/s]
        radius   (n,)    float64  [m], the radius of spheres, the bounding radius of
                                  other shapes
        force    (n, d)  float64  [N], total force of the last step
        walls/   id (nw,) int32, pos (nw, d) [m] (a point of the plane), normal (nw, d)
        meshes/    (only in scenes with mesh walls) points (nv, 3) [m], cells (nf, 3)
                   int64 triangles, wall (nf,) int32 (index in ``walls``), normal
                   (nf, 3): every mesh wall where it is at this frame
        surface/   (only in frames holding boxes, polygons or polyhedra)
            points   (np, 3)  float64  [m], world-frame vertices (z = 0 in 2D), body
                                       after body, each in its shape-table order
            cells    (nt, 3)  int32    triangles (rows of ``points``): the boundary
                                       triangles of 3D shapes (counter-clockwise seen
                                       from outside), a fan over each 2D polygon
                                       (counter-clockwise seen from +z)
            body     (nt,)    int32    body index of each triangle
            vel      (nt, 3)  float64  [m/s], velocity of the triangle's body (centre
                                       of mass; z = 0 in 2D)
        contacts/  (only when ``contacts=True``; touching contacts only)
            i, j     (nc,)   int32  body indices (``j`` is a wall when ``is_wall``)
            normal   (nc, d) float64 unit normal from i to j
            overlap  (nc,)   float64 [m], > 0
            force    (nc, d) float64 force on j [N]
            normal_force      (nc,)   float64 [N], ``force . normal``: > 0 pushes
                                       the two apart
            tangential_force  (nc, d) float64 [N], ``force - normal_force * normal``
            x1, x2   (nc, d) float64 [m], points of i and j deepest into the other
            is_wall  (nc,)   bool
            xdmf/    the contact network as line cells, one line per contact from
                     the centre of i to the centre of j (its periodic image) or,
                     for a wall contact, to the contact point:
                points (2 nc, 3) float64 [m] (rows 2k, 2k + 1: the ends of line k),
                lines (nc, 2) int32; 2D: force, normal, tangential_force (nc, 3)
                padded with a zero z component
        xdmf/      what the XDMF files read besides the datasets above:
            vertex   (n, 1)  int32    0, 1, ..., n - 1: the particles as vertex cells
            pos, vel, force (n, 3) float64, 2D only: padded with z = 0
            quat     (n, 4)  float64, 2D only: the angle as a quaternion about z
                                      (w, x, y, z), for glyph orientation
        walls/xdmf/  the wall planes drawn as finite patches: points (4 nw, 3) [m] and
                     cells (nw, 4) int32 (3D quadrilaterals), or points (2 nw, 3)
                     and cells (nw, 2) (2D segments); centred on the particles'
                     centroid projected onto the plane, as wide as the particles'
                     extent (plus two radii) in every direction of the plane;
                     normal (nw, 3)

Every dataset carries ``unit`` (and ``sign`` where it matters; :data:`UNITS`, listed in
``docs/conventions.md``); :func:`dem.io.read_frames` reads the frames back as arrays.

Custom shapes (a user SDF) have no vertices: they appear as particles only (a glyph at
``pos`` of size ``radius`` in ParaView), never in ``surface/``.

Crash safety: frames are written to ``path + ".tmp"`` (flushed after every frame) and
the file is renamed to ``path`` with :func:`os.replace` only by :meth:`H5Writer.close`,
so a killed run never leaves a truncated file at ``path``; ``path.tmp`` may remain and
usually holds the frames flushed before the crash. A write the disk refuses (full,
read-only) removes ``path.tmp`` and raises :class:`~dem.io.files.OutputError`, one
line naming ``path`` (:mod:`dem.io.files`).
"""

import logging
import os
import re
import sys
from pathlib import Path

import h5py
import numpy as np

from ..observers import Periodic
from ..shapes import Shape
from .geometry import angle_quaternion, pad3, shape_surfaces, wall_patches
from .files import H5Output, OutputError, publish, remove_quietly, write_bytes_atomic
from .meta import COMPRESSION, ONE, label, rules, stamp
from .xdmf import FORMAT, write_xdmf, xdmf_files

log = logging.getLogger(__name__)

VERSION = 4  # 2: frames hold every particle (kind, surface/), not spheres only;
#               3: padded 3-vectors and cells for XDMF 3 in each frame (xdmf/ groups);
#               4: unit (and sign) on every dataset, software and config at the root

#: unit and sign of every dataset of a frame, by its path in the frame group
#: (:func:`dem.io.meta.label`); ``rot`` depends on the dimension (:func:`frame_units`)
UNITS = (
    (r"(walls/)?id|kind|(xdmf/)?vertex|surface/(cells|body)|walls/xdmf/cells"
     r"|contacts/(i|j|is_wall)|contacts/xdmf/lines", ONE, None),
    (r"(xdmf/)?pos|walls/pos|surface/points|(walls|contacts)/xdmf/points"
     r"|contacts/x\d", "m", None),
    (r"(xdmf/)?vel|surface/vel", "m/s", None),
    (r"xdmf/quat", ONE, "(w, x, y, z), rotation body to world"),
    (r"ang_vel", "rad/s", "counter-clockwise positive (right-handed about each axis)"),
    (r"radius", "m", None),
    (r"(xdmf/)?force", "N", "total force on the body"),
    (r"walls/(xdmf/)?normal", ONE, "towards the particles' side"),
    (r"meshes/points", "m", None),
    (r"meshes/(cells|wall|normal)", ONE, None),
    (r"contacts/(xdmf/)?normal", ONE, "from i to j"),
    (r"contacts/overlap", "m", "positive in contact"),
    (r"contacts/(xdmf/)?force", "N", "force on j"),
    (r"contacts/normal_force", "N", COMPRESSION + " (pushes the two apart)"),
    (r"contacts/(xdmf/)?tangential_force", "N", "force on j minus its normal part"),
)


def frame_units(dim, fields=None):
    """The unit rules of a frame of dimension ``dim``, with the units of the extra
    per-body ``fields`` (``{name: unit}``)."""
    rot = (r"rot", "rad", "counter-clockwise positive") if dim == 2 else \
        (r"rot", ONE, "(w, x, y, z), rotation body to world")
    # paths are looked up with their numbers as 0 (dem.io.meta.label): so are names
    extra = [(f"fields/{re.escape(re.sub(r'[0-9]+', '0', k))}", u, None)
             for k, u in (fields or {}).items()]
    return rules(*UNITS, rot, *extra)


#: the most a stored dataset may inflate when read: deflate's limit is about 1032:1
MAX_INFLATION = 1100


def read_bounded(dataset, name=None):
    """The data of an h5py ``dataset``, refused (ValueError, one line) before anything
    is read or allocated when it declares more bytes than its file can hold.

    A truncated or crafted file (a header claiming 10^12 elements) is caught here:
    uncompressed data cannot exceed the file, compressed data ``MAX_INFLATION`` times
    the file.
    """
    if not isinstance(dataset, h5py.Dataset):
        raise ValueError(f"{dataset.file.filename}: {name or dataset.name} is not a "
                         f"dataset")
    path = dataset.file.filename
    declared = int(dataset.size or 0) * dataset.dtype.itemsize
    filtered = dataset.chunks is not None and \
        dataset.id.get_create_plist().get_nfilters() > 0
    limit = os.path.getsize(path) * (MAX_INFLATION if filtered else 1)
    if declared > limit:
        raise ValueError(f"{path}: {name or dataset.name} declares {dataset.shape} "
                         f"{dataset.dtype} ({declared} bytes), more than the file can "
                         f"hold: a truncated or corrupt file")
    return dataset[()]


#: the format tag and version of the project's PNG figures (in their text chunks)
FIGURE_FORMAT, FIGURE_VERSION = "femxdem.figure", 1


def save_figure(fig, path, dpi=120, data=None):
    """Write a matplotlib figure as PNG atomically (a ``.tmp`` file, then
    :func:`publish`): a reader never sees half a picture, and a figure that cannot
    be written is an :class:`~dem.io.files.OutputError` with no ``.tmp`` left.

    The PNG's text chunks carry ``format`` (:data:`FIGURE_FORMAT`), ``version``,
    ``Software`` (the project and its version) and, when given, ``data``: the file
    (and place in it) that holds the numbers drawn, e.g. ``"fields.h5:/curve"``.
    """
    from .meta import software

    path = Path(path)
    meta = {"format": FIGURE_FORMAT, "version": str(FIGURE_VERSION),
            "Software": software()}
    if data is not None:
        meta["data"] = str(data)
    write_bytes_atomic(path, lambda fh: fig.savefig(fh, format="png", dpi=dpi,
                                                    metadata=meta))
    return path


def figure_path(name, out_dir, docs_dir, argv=None):
    """Where a script writes its figure ``name``: into its output folder ``out_dir``,
    or into ``docs_dir`` (the documentation's figures) when it was run with
    ``--docs`` (``argv``: the script's arguments, default ``sys.argv[1:]``).

    >>> figure_path("a.png", "output/ex", "docs/figures", argv=[]).as_posix()
    'output/ex/a.png'
    >>> figure_path("a.png", "output/ex", "docs/figures", argv=["--docs"]).as_posix()
    'docs/figures/a.png'
    """
    argv = sys.argv[1:] if argv is None else argv
    return Path(docs_dir if "--docs" in argv else out_dir) / name


def _copy(src, dst):
    """Copy ``src`` to ``dst`` (its writer's ``.tmp``); an OutputError naming ``src``
    when the disk refuses."""
    import shutil

    try:
        shutil.copyfile(src, dst)
    except OSError as err:
        remove_quietly(dst)
        raise OutputError(src, err) from None


def _write_meshes(g, walls):
    """The mesh walls of a frame, as one set of triangles (``meshes/``)."""
    if not walls:
        return
    offsets = np.cumsum([0] + [w.vertices.shape[0] for w in walls])
    m = g.create_group("meshes")
    m.create_dataset("points", data=np.concatenate([w.vertices for w in walls]))
    m.create_dataset("cells", data=np.concatenate(
        [w.faces + o for w, o in zip(walls, offsets, strict=False)]).astype(np.int64))
    m.create_dataset("wall", data=np.concatenate(
        [np.full(w.n_faces, k, np.int32) for k, w in enumerate(walls)]))
    m.create_dataset("normal", data=np.concatenate([w.face_normal for w in walls]))


def frame_name(index):
    """Group name of frame ``index``: six digits, zero padded.

    >>> frame_name(7)
    '000007'
    """
    return f"{int(index):06d}"


class H5Writer:
    """Observer writing particle frames (and contacts) to an HDF5 file.

    Every body but the walls is a particle; boxes, polygons and polyhedra also get
    their world-frame surfaces as triangles (:func:`shape_surfaces`), shown by their
    own XDMF file (``<stem>_shapes.xdmf``), as are the contacts (``_contacts``) and
    the walls (``_walls``); see :mod:`dem.io.xdmf`.

    Parameters
    ----------
    path : str or os.PathLike
        The HDF5 file; written as ``path + ".tmp"`` until :meth:`close`. The XDMF file
        of the particles is ``path`` with the suffix ``.xdmf``
        (:attr:`xdmf_path`); :attr:`xdmf_paths` lists every XDMF file written.
    every : int or trigger
        Write a frame every ``every`` steps (or when a trigger with ``next_after``
        fires). The simulation calls observers after steps only: call the writer
        once yourself (``writer(sim)``) for a frame of the initial state.
    contacts : bool
        Also write the touching contacts of every frame.
    fields : dict, optional
        Extra per-body scalars, ``{name: fn(sim) -> (n,) array}`` or ``{name: (fn,
        unit)}``, written with every frame (with their ``unit``; ``"unknown"`` when
        not given) and shown by the particles' XDMF file as attributes (e.g.
        peridynamic damage, ``(fn, "1")``).
    config : str or dict, optional
        The configuration that made the run (a scene file's text, or settings stored
        as JSON): the file's ``config`` attribute.
    resume_step : int, optional
        Continue an existing ``path`` (a run restarted from a checkpoint at this
        step): its frames up to this step are kept, later ones dropped, and new ones
        follow. Without the file a new one is started.

    Examples
    --------
    >>> import tempfile, dem
    >>> from dem.io import H5Writer
    >>> b = dem.Bodies.spheres([[0.0, 0.0], [0.05, 0.0]], radius=0.01, density=2500.0)
    >>> sim = dem.Simulation(b, dem.LinearSpring(kn=1e4), dt=1e-5)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     with H5Writer(tmp + "/run.h5", every=10) as out:
    ...         sim.observers.append(out)
    ...         sim.run(20)
    >>> out.n_frames
    2
    """

    def __init__(self, path, every=100, contacts=True, fields=None, config=None,
                 resume_step=None):
        fields = dict(fields or {})
        self.fields = {k: v[0] if isinstance(v, tuple) else v for k, v in fields.items()}
        self._field_units = {k: v[1] for k, v in fields.items() if isinstance(v, tuple)}
        self.path = os.fspath(path)
        self.tmp_path = self.path + ".tmp"
        self.xdmf_path = os.fspath(Path(self.path).with_suffix(".xdmf"))
        self.trigger = every if hasattr(every, "next_after") else Periodic(every)
        self.contacts = bool(contacts)
        self.n_frames = 0
        #: the XDMF files written by :meth:`close` (particles first)
        self.xdmf_paths = []
        self._dim = None
        self._file = None
        parent = os.path.dirname(os.path.abspath(self.path))
        try:
            os.makedirs(parent, exist_ok=True)
        except OSError as err:
            raise OutputError(self.path, err) from None
        resume = resume_step is not None and os.path.exists(self.path)
        if resume:
            _copy(self.path, self.tmp_path)
        self._out = H5Output(self.tmp_path, "a" if resume else "w", name=self.path)
        self._file = self._out.h5
        with self._guard():
            if resume:
                self._keep_frames(int(resume_step))
            else:
                stamp(self._file, FORMAT, VERSION, config)
                self._frames = self._file.create_group("frames")

    def _keep_frames(self, step):
        """Drop the frames after ``step`` of a file being continued."""
        f = self._file
        if f.attrs.get("format") != FORMAT or "frames" not in f:
            self._out.abandon()
            remove_quietly(self.tmp_path)
            raise ValueError(f"{self.path} is not a particle file of dem.io.H5Writer; "
                             f"cannot continue it")
        self._frames = f["frames"]
        names = sorted(self._frames)
        keep = [n for n in names if int(self._frames[n].attrs["step"]) <= step]
        for n in names[len(keep):]:
            del self._frames[n]
        self.n_frames = len(keep)
        if "dim" in f.attrs:
            self._dim = int(f.attrs["dim"])

    def _guard(self):
        """A failed write ends the file: it is closed, its ``.tmp`` removed, and the
        OutputError naming :attr:`path` raised."""
        return self._out.guard(self._abandoned)

    def _abandoned(self):
        self._file = None
        remove_quietly(self.tmp_path)

    # ------------------------------------------------------------------ observer
    def __call__(self, sim):
        """Append one frame of ``sim`` (step, time, bodies and contacts)."""
        if self._file is None:
            raise ValueError(f"H5Writer for {self.path} is closed")
        with self._guard():
            self._append(sim)

    def _append(self, sim):
        b = sim.bodies
        if self._dim is None:
            self._dim = int(b.dim)
            self._file.attrs["dim"] = self._dim
        elif b.dim != self._dim:
            raise ValueError(f"frame is {b.dim}D but {self.path} holds "
                             f"{self._dim}D frames")
        g = self._frames.create_group(frame_name(self.n_frames))
        par = np.flatnonzero(b.kind != Shape.PLANE)
        wal = np.flatnonzero(b.kind == Shape.PLANE)
        g.attrs["step"] = int(sim.step)
        g.attrs["time"] = float(sim.time)
        g.attrs["dt"] = float(sim.dt)
        g.attrs["dim"] = int(b.dim)
        g.attrs["n_particles"] = par.size
        g.attrs["n_spheres"] = int(np.count_nonzero(b.kind == Shape.SPHERE))
        g.attrs["n_walls"] = wal.size
        g.create_dataset("id", data=par.astype(np.int32))
        g.create_dataset("kind", data=b.kind[par].astype(np.int32))
        for name in ("pos", "vel", "rot", "ang_vel", "radius", "force"):
            g.create_dataset(name, data=getattr(b, name)[par])
        if self.fields:
            extra = g.create_group("fields")
            for name, fn in self.fields.items():
                value = np.asarray(fn(sim), dtype=np.float64)
                if value.shape != (b.n,):
                    raise ValueError(f"field {name!r} must give one number per body, "
                                     f"got shape {value.shape}")
                extra.create_dataset(name, data=value[par])
        w = g.create_group("walls")
        w.create_dataset("id", data=wal.astype(np.int32))
        w.create_dataset("pos", data=b.pos[wal])
        w.create_dataset("normal", data=b.normal[wal])
        self._write_viewer_data(g, b, par, wal)
        surf = shape_surfaces(b)
        if surf["cells"].shape[0]:
            s = g.create_group("surface")
            for name, data in surf.items():
                s.create_dataset(name, data=data)
        g.attrs["n_surface_cells"] = surf["cells"].shape[0]
        _write_meshes(g, getattr(sim, "mesh_walls", ()))
        n_c = 0
        if self.contacts:
            n_c = self._write_contacts(g.create_group("contacts"), sim.contacts(), b)
        g.attrs["n_contacts"] = n_c
        label(g, frame_units(self._dim, self._field_units))
        self.n_frames += 1
        self._file.flush()

    @staticmethod
    def _write_viewer_data(g, b, par, wal):
        """The ``xdmf/`` groups of frame ``g``: vertex cells, 3-vectors (2D) and the
        walls as patches."""
        x = g.create_group("xdmf")
        x.create_dataset("vertex", data=np.arange(par.size, dtype=np.int32)[:, None])
        if b.dim == 2:
            for name in ("pos", "vel", "force"):
                x.create_dataset(name, data=pad3(getattr(b, name)[par]))
            x.create_dataset("quat", data=angle_quaternion(b.rot[par]))
        if not wal.size:
            return
        if par.size:
            centre = b.pos[par].mean(axis=0)
            half = 0.5 * np.ptp(b.pos[par], axis=0).max() + 2.0 * b.radius[par].max()
        else:  # no particles to frame: the walls' own extent, or a metre
            centre = b.pos[wal].mean(axis=0)
            half = 0.5 * np.ptp(b.pos[wal], axis=0).max() or 1.0
        points, cells = wall_patches(b.pos[wal], b.normal[wal], centre, half)
        w = g["walls"].create_group("xdmf")
        w.create_dataset("points", data=points)
        w.create_dataset("cells", data=cells)
        w.create_dataset("normal", data=pad3(b.normal[wal]))

    @staticmethod
    def _write_contacts(g, c, b):
        i = np.asarray(c["i"], dtype=np.int32)
        is_wall = np.asarray(c["is_wall"], dtype=bool)
        g.create_dataset("i", data=i)
        g.create_dataset("j", data=np.asarray(c["j"], dtype=np.int32))
        for name in ("normal", "overlap", "force", "x1", "x2"):
            g.create_dataset(name, data=np.asarray(c[name], dtype=np.float64))
        g.create_dataset("is_wall", data=is_wall)
        normal = np.asarray(c["normal"], dtype=np.float64).reshape(i.size, b.dim)
        force = np.asarray(c["force"], dtype=np.float64).reshape(i.size, b.dim)
        fn = np.einsum("kd,kd->k", force, normal)
        ft = force - fn[:, None] * normal
        g.create_dataset("normal_force", data=fn)
        g.create_dataset("tangential_force", data=ft)
        x = g.create_group("xdmf")  # lines i -> j (a wall: i -> the contact point)
        start = b.pos[i]
        reach = np.where(is_wall, 0.5, 1.0)[:, None]  # a wall's branch is 2 arms
        end = start + reach * np.asarray(c["branch"], dtype=np.float64).reshape(start.shape)
        x.create_dataset("points", data=pad3(np.stack([start, end], axis=1)
                                             .reshape(2 * i.size, b.dim)))
        x.create_dataset("lines", data=np.arange(2 * i.size, dtype=np.int32)
                         .reshape(i.size, 2))
        if b.dim == 2:
            for name, data in (("force", force), ("normal", normal),
                               ("tangential_force", ft)):
                x.create_dataset(name, data=pad3(data))
        return int(i.size)

    # ------------------------------------------------------------------ closing
    def close(self):
        """Finish the file: rename ``path.tmp`` to ``path`` and write the XDMF file.

        Idempotent. Returns the path of the HDF5 file.
        """
        if self._file is None:
            return self.path
        try:
            with self._guard():
                self._file.attrs["n_frames"] = self.n_frames
            self._file = None
            self._out.close(sync=True)
            publish(self.tmp_path, self.path)
        finally:
            self._file = None
            self._out.abandon()
            remove_quietly(self.tmp_path)
        write_xdmf(self.path, self.xdmf_path)
        self.xdmf_paths = [p for p in xdmf_files(self.xdmf_path).values()
                           if os.path.exists(p)]
        log.info("wrote %d frames to %s (+ %s)", self.n_frames, self.path,
                 ", ".join(self.xdmf_paths))
        return self.path

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        self.close()
        return False


def read_frame(path, index):
    """One frame (``index`` 0, 1, ...; negative counts from the end) as a dict.

    Keys: the frame's attributes (``step``, ``time``, ``dt``, ...), its particle
    datasets (``id``, ``kind``, ``pos``, ``vel``, ...), ``walls``, ``xdmf`` and, when
    written, ``surface`` and ``contacts`` (dicts of arrays, a subgroup a nested dict;
    see the module docstring).
    """
    with h5py.File(path, "r") as f:
        if f.attrs.get("format") != FORMAT:
            raise ValueError(f"{path} is not a {FORMAT} file")
        frames = f["frames"]
        if index < 0:  # count from the end, like a list
            index += len(frames)
        if not 0 <= index < len(frames):
            raise IndexError(f"{path} has {len(frames)} frames, no frame {index}")
        g = frames[frame_name(index)]
        out = {k: v.item() if hasattr(v, "item") else v for k, v in g.attrs.items()}
        out.update(_read_group(g))
    return out


def _read_group(g):
    """Datasets of group ``g`` as arrays, its subgroups as nested dicts."""
    return {k: _read_group(v) if isinstance(v, h5py.Group) else v[()]
            for k, v in g.items()}
