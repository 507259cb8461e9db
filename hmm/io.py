"""Output of a multiscale run: HDF5 fields with an XDMF file for ParaView, and plots.

``fields.h5``::

    /            attrs: format = "hmm.fields", version, software, config (the
                 problem as JSON), kinematics ("small" or "finite")
    /mesh/points (n_vertices, 3) [m], /mesh/cells (n_elems, k) int64 (initial mesh)
    /gauss/points (n_gp, d) [m], /gauss/weights (n_gp,) [m^d] (initial)
    /steps/NNNNN/  attrs: step, load_factor, iterations
        displacement (n_vertices, 3) [m]
        points (n_vertices, 3) [m] -- finite kinematics: the deformed mesh
        element data, (n_elems,) each -- Gauss-point means:
            stress_xx ... [Pa] (Cauchy), strain_xx ... [-] (small: sym grad u;
            finite: logarithmic, ln V), strain_increment_xx ... [-] (the last
            step's sym G), deviatoric_strain [-], pressure p = -tr(sigma)/d [Pa]
            (compression positive, named for its sign; ``mean_stress`` in files
            of version 1), stress_ratio q/p [-], void_ratio, coordination,
            dem_fraction (share of points that ran DEM), fabric_xx ... [-] (the
            contact fabric <n (x) n>), anisotropy [-] (its second-order Fourier
            amplitude, :func:`dem.observers.fabric_anisotropy`; NaN for analytic
            laws); with rolling resistance, couple_stress_zx, _zy (2D) or _xx ...
            _zz (3D; moment component, then the plane's normal) [N/m]
        gauss/stress (n_gp, d, d), gauss/strain (n_gp, d, d),
        gauss/increment (n_gp, d, d) (what the micro models got: G, not
        symmetrised, under finite kinematics), gauss/ran_dem (n_gp,),
        gauss/fabric (n_gp, d, d), gauss/couple_stress (n_gp, r, d) (rolling only),
        gauss/points (n_gp, d) [m] -- finite kinematics: current positions
    /curve/  load_factor, displacement, force (per supported boundary, per step;
             forces on the current boundary); iterations, dem_points; the work of
             each step: work/rve_calls, work/rve_seconds (summed over the points),
             work/dem_steps

A saturated problem (:mod:`hmm.porous`) adds, per step (attrs: time [s]):
``pore_pressure`` (n_vertices,) [Pa] (compression positive) on the nodes; element
means ``darcy_flux_x`` ... [m/s] and ``total_stress_xx`` ... [Pa] (the total stress
``sigma' - alpha p I``; ``stress_*`` and ``pressure`` are then the effective
ones); ``gauss/pore_pressure``, ``gauss/darcy_flux``, ``gauss/total_stress``; and
the curve ``time`` [s], ``pore_pressure/max`` and ``pore_pressure/mean`` [Pa]
(``pore_pressure.png`` shows them, the field where it is largest and the
platens' settlements).

Every dataset carries ``unit`` and, where it matters, ``sign`` (:func:`field_units`;
stresses and strains tension positive, pressures compression positive).
:func:`hmm.read_fields` reads the file back.

``fields.xdmf`` references it (a temporal collection, one grid per written step; under
finite kinematics each grid is the deformed mesh, so ParaView shows the real shape);
``load_displacement.png`` and ``deviatoric_strain.png`` show the run; written at
:meth:`Output.close`.
"""

import contextlib
import logging
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import numpy as np
from skfem import MeshHex, MeshQuad, MeshTet, MeshTri

from dem.io.files import (
    H5Output,
    OutputError,
    readable_h5,
    remove_quietly,
    write_bytes_atomic,
)
from dem.io import meta
from dem.io.meta import COMPRESSION, EXTENSION, ONE, TENSION, check_format, rules, stamp

from .run_figures import HEX_ORDER as _HEX_ORDER
from .run_figures import write_figures
from .signals import held

log = logging.getLogger(__name__)

#: the format tag and version of ``fields.h5`` (files of earlier runs carry none;
#: version 1 named the pressure ``mean_stress`` and had no units)
FORMAT, VERSION = "hmm.fields", 2
#: the versions a restart continues (an older file is brought up to date) and
#: :func:`hmm.read_fields` reads
VERSIONS = (1, 2)
#: dataset names of version 1 -> their names now (the values are the same)
RENAMED = {"mean_stress": "pressure"}


def field_units(dim):
    """The unit rules (:func:`dem.io.meta.rules`) of the datasets of ``fields.h5``,
    by their path in the file, for a ``dim``-dimensional problem."""
    step = r"steps/\d+/"
    force = "N/m" if dim == 2 else "N"
    return rules(
        (r"mesh/points|gauss/points", "m", None),
        (r"mesh/cells", ONE, None),
        (r"gauss/weights", f"m^{dim}", None),
        (step + r"(displacement|points|gauss/points)", "m", None),
        (step + r"(total_)?stress_[xyz]{2}|" + step + r"gauss/(total_)?stress", "Pa",
         TENSION),
        (step + r"strain(_increment)?_[xyz]{2}|" + step + r"gauss/strain", ONE,
         EXTENSION),
        (step + r"gauss/increment", ONE, EXTENSION + " (the increment's gradient G)"),
        (step + r"deviatoric_strain", ONE, "non-negative"),
        (step + r"(gauss/)?(pressure|pore_pressure)", "Pa", COMPRESSION),
        (step + r"stress_ratio", ONE, "q/p, non-negative where p > 0"),
        (step + r"(void_ratio|coordination|dem_fraction|gauss/ran_dem)", ONE, None),
        (step + r"(fabric_[xyz]{2}|gauss/fabric)", ONE, "<n (x) n> of the contact normals"),
        (step + r"anisotropy", ONE, "of the fabric, 0 when isotropic"),
        (step + r"(couple_stress_[xyz]{2}|gauss/couple_stress)", "N/m",
         "moment component, then the plane's normal"),
        (step + r"(darcy_flux_[xyz]|gauss/darcy_flux)", "m/s", None),
        (r"curve/(load_factor|iterations|dem_points|work/rve_calls|work/dem_steps)", ONE,
         None),
        (r"curve/work/rve_seconds", "s", "summed over the Gauss points"),
        (r"curve/displacement/.+", "m", None),
        (r"curve/force/.+", force, "force the support exerts on the body"),
        (r"curve/time", "s", None),
        (r"curve/pore_pressure/(max|mean)", "Pa", COMPRESSION),
    )

#: the work of each load step in the curve: RVE (micro model) calls, their seconds summed
#: over the Gauss points (every rank's), and DEM steps; failed tries and cut steps count
WORK_CURVES = ("work/rve_calls", "work/rve_seconds", "work/dem_steps")

#: XDMF topology of each mesh kind (its corner vertices, whatever the element order)
_TOPOLOGY = ((MeshQuad, "Quadrilateral"), (MeshTri, "Triangle"), (MeshHex, "Hexahedron"),
             (MeshTet, "Tetrahedron"))
_AXES = "xyz"


def _components(d):
    return [(a, b) for a in range(d) for b in range(a, d)]


def _p_q(sig):
    """Mean stress p (compression positive) and q/p per row of (n, d, d)."""
    d = sig.shape[1]
    p = -np.trace(sig, axis1=1, axis2=2) / d
    s = sig + p[:, None, None] * np.eye(d)
    q = np.sqrt((0.5 if d == 2 else 1.5) * np.einsum("nij,nij->n", s, s))
    with np.errstate(divide="ignore", invalid="ignore"):
        return p, np.where(p > 0.0, q / p, np.nan)


class Output:
    """Writes the steps of a run into ``directory``.

    Parameters
    ----------
    directory : path
    macro : Macro
    boundaries : sequence of str
        Supported boundaries whose reaction forces make the load-displacement curve.
    every : int
        Steps between field frames (the curve gets every step).
    overwrite : bool
        Replace an existing ``fields.h5``; otherwise refuse (FileExistsError).
    driven : sequence of (boundary, component)
        The curves of ``load_displacement.png``.
    restart : (step, curve), optional
        Continue the existing file from a checkpoint's step and curve.
    porous : PorousMacro, optional
        The pressure field of a saturated problem.
    platens : sequence of str
        Boundaries that move as rigid platens: their displacement is recorded
        (``displacement/<name>``; no reaction, nothing holds them).
    config : dict or str, optional
        The problem that made the run: the file's ``config`` attribute (as JSON).
    """

    def __init__(self, directory, macro, boundaries, every=1, overwrite=False,
                 driven=(), restart=None, porous=None, platens=(), config=None):
        self.dir = Path(directory)
        self.macro = macro
        self.porous = porous
        self.platens = tuple(platens)
        self.boundaries = tuple(boundaries)
        #: (boundary, component) pairs whose displacement is prescribed non-zero:
        #: the load-displacement curves
        self.driven = tuple(driven)
        self.every = int(every)
        self.path = self.dir / "fields.h5"
        self.frames = []  # (group name, load factor)
        self.curve = {k: [] for k in self.curve_names(self.boundaries,
                                                      porous is not None, self.platens)}
        self.f, self._kept, self._closed, self._out = None, None, False, None
        self._config, self._units = config, field_units(macro.dim)
        self._work = np.zeros(3)  # the farm's work (measures["work"]) at the last write
        self._old_version = None
        if restart is not None:
            self._reopen(*restart)
            return
        if self.path.exists() and not overwrite:
            raise FileExistsError(f"{self.path} exists (pass --overwrite to replace it)")
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise OutputError(self.dir, err) from None
        self._made_dir = not any(self.dir.iterdir())
        self._out = H5Output(self.path, "w")
        self.f = self._out.h5
        with self._guard():
            self._head(macro, porous)

    def _head(self, macro, porous):
        """The parts of a new file that do not change: mesh, Gauss points, tags."""
        mesh = macro.mesh
        pts = np.zeros((mesh.p.shape[1], 3))
        pts[:, :macro.dim] = mesh.p.T
        cells = mesh.t.T.astype(np.int64)
        if macro.element.startswith("hex"):  # the vertices, in VTK's order
            cells = cells[:, _HEX_ORDER]
        self.f.create_dataset("mesh/points", data=pts)
        self.f.create_dataset("mesh/cells", data=cells)
        self.f.create_dataset("gauss/points", data=macro.gauss_points())
        self.f.create_dataset("gauss/weights", data=macro.weights())
        stamp(self.f, FORMAT, VERSION, self._config)
        self.f.attrs["kinematics"] = macro.kinematics
        if porous is not None:
            self.f.attrs["pressure_element"] = porous.p_element
        meta.label(self.f, self._units)

    @contextlib.contextmanager
    def _guard(self):
        """A write the disk refuses ends the output: the file is closed as it was at
        its last flush (every frame is flushed) and the OutputError naming it is
        raised. A new file is removed if it holds no frame or cannot be read; a
        restarted one is left to the user. SIGINT and SIGTERM wait for the write to
        end (:func:`hmm.signals.held`)."""
        with held(), self._out.guard(self._abandoned):
            yield

    def _abandoned(self):
        self.f, self._closed = None, True
        if self._kept is None and not (self.frames and readable_h5(self.path)):
            remove_quietly(self.path)

    @staticmethod
    def curve_names(boundaries, saturated=False, platens=()):
        """The series of the load-displacement curve (``/curve/`` of ``fields.h5``),
        the platens' displacements, and a saturated problem's clock and pore
        pressures."""
        return ["load_factor", "iterations", "dem_points", *WORK_CURVES] + [
            f"{kind}/{b}" for b in boundaries for kind in ("displacement", "force")] \
            + [f"displacement/{b}" for b in platens if b not in boundaries] \
            + (["time", "pore_pressure/max", "pore_pressure/mean"] if saturated else [])

    def _reopen(self, step, curve):
        """Continue the file of an interrupted run from its checkpoint at ``step``:
        frames written after it are dropped, the curve is the checkpoint's. The file
        is checked here (ValueError if it is not this run's) and changed only by the
        first :meth:`write` or :meth:`close`."""
        if not self.path.exists():
            raise FileNotFoundError(f"{self.path} is missing: cannot restart its run")
        try:
            with h5py.File(self.path, "r") as f:
                try:
                    version = check_format(f, self.path, FORMAT, VERSIONS)
                except ValueError as err:  # another program's file: not ours to change
                    raise FileExistsError(
                        f"{err}; a restart continues only its own run's file: remove "
                        f"it, or run without --restart and with --overwrite to "
                        f"replace it") from None
                frames = {name: float(f["steps"][name].attrs["load_factor"])
                          for name in f["steps"] if int(name) <= step}
        except (OSError, KeyError, TypeError, ValueError, AttributeError) as err:
            if isinstance(err, FileExistsError):
                raise
            raise ValueError(f"{self.path} is not the output of this run, cannot "
                             f"restart it ({' '.join(str(err).split())})") from None
        self._old_version = version if version != VERSION else None
        self._kept = frames
        self.frames = [(f"steps/{name}", frames[name]) for name in sorted(frames)]
        for k in self.curve:
            self.curve[k] = list(curve[k])

    def _file(self):
        """The open HDF5 file; a restarted one loses its later frames and its curve
        on first use."""
        if self.f is None:
            self._out = H5Output(self.path, "a")
            self.f = self._out.h5
            with self._guard():
                for name in list(self.f["steps"]):
                    if name not in self._kept:
                        del self.f["steps"][name]
                if "curve" in self.f:
                    del self.f["curve"]
                if self._old_version is not None:
                    self._upgrade(self.f)
        return self.f

    def _upgrade(self, f):
        """Bring the file of an earlier version up to this one, in place: the
        datasets renamed since (:data:`RENAMED`), the tags and units."""
        for name in f["steps"]:
            g = f["steps"][name]
            for old, new in RENAMED.items():
                if old in g and new not in g:
                    g.move(old, new)
        stamp(f, FORMAT, VERSION, self._config)
        meta.label(f, self._units)
        self._old_version = None

    def discard(self):
        """End a run that never started (a failed set-up): a new ``fields.h5`` is
        removed (with its directory if that was empty), a restarted one is left as
        it was."""
        if self._closed:
            return
        self._closed = True
        if self.f is not None:
            self._out.abandon()
            self.f = None
        if self._kept is None:
            self.path.unlink(missing_ok=True)
            if self._made_dir:
                with contextlib.suppress(OSError):
                    self.dir.rmdir()

    def write(self, step, solver, measures, iterations, force_frame=False):
        """Record step ``step`` of ``solver`` (committed state) and ``measures`` (the
        farm's per-point arrays)."""
        macro, d = self.macro, self.macro.dim
        u = solver.u
        reactions = solver.reactions()
        if self.porous is None:
            self.curve["load_factor"].append(solver.t)
        else:
            self.curve["load_factor"].append(solver.schedule.load_factor(solver.t))
            self.curve["time"].append(solver.t)
            pn = self.porous.nodal_pressure(solver.p)
            self.curve["pore_pressure/max"].append(float(pn.max()))
            self.curve["pore_pressure/mean"].append(float(pn.mean()))
        self.curve["iterations"].append(iterations)
        self.curve["dem_points"].append(int(np.sum(measures["ran_dem"] > 0)))
        work = np.asarray(measures.get("work", np.full(3, np.nan)), dtype=np.float64)
        for name, done in zip(WORK_CURVES, work - self._work, strict=True):
            self.curve[name].append(done)
        self._work = work
        for b in self.boundaries:
            disp = np.array([u[macro.dofs(b, c)].mean() for c in range(d)])
            self.curve[f"displacement/{b}"].append(disp)
            self.curve[f"force/{b}"].append(reactions[b])
        for b in self.platens:
            if b not in self.boundaries:
                self.curve[f"displacement/{b}"].append(
                    np.array([u[macro.dofs(b, c)].mean() for c in range(d)]))
        if force_frame or step % self.every == 0:
            self._frame(step, solver, measures, iterations)

    def stopped(self, step, solver, measures, iterations, message, partial=False):
        """Record that the run stopped at ``solver``'s committed state, which is step
        ``step``, or part of it (``partial``: cut sub-steps converged before the stop;
        the curve gets that state too). Its field frame is written if the output
        interval skipped it; the file's attributes ``stopped`` (the message),
        ``last_converged_step`` and ``last_converged_load_factor`` say so."""
        if partial:
            self.write(step, solver, measures, iterations, force_frame=True)
        elif not self.frames or self.frames[-1][0] != f"steps/{step:05d}":
            self._frame(step, solver, measures, iterations)
        f = self._file()
        with self._guard():
            f.attrs["stopped"] = message
            f.attrs["last_converged_step"] = int(step)
            f.attrs["last_converged_load_factor"] = float(solver.t)
            f.flush()

    def _frame(self, step, solver, measures, iterations):
        f = self._file()
        with self._guard():
            self._write_frame(f, step, solver, measures, iterations)

    def _write_frame(self, f, step, solver, measures, iterations):
        macro, d = self.macro, self.macro.dim
        u = solver.u
        name = f"steps/{step:05d}"
        g = f.create_group(name)
        g.attrs["step"] = step
        g.attrs["load_factor"] = solver.t if self.porous is None \
            else solver.schedule.load_factor(solver.t)
        if self.porous is not None:
            g.attrs["time"] = solver.t
        g.attrs["iterations"] = iterations
        disp = np.zeros((macro.mesh.p.shape[1], 3))
        disp[:, :d] = macro.nodal_displacement(u)
        g.create_dataset("displacement", data=disp)
        if macro.finite:
            pts = np.zeros_like(disp)
            pts[:, :d] = macro.current_points(u)
            g.create_dataset("points", data=pts)
        sig = solver.sigma
        eps = macro.total_strain(u)
        inc = solver.increment
        inc_sym = 0.5 * (inc + np.swapaxes(inc, 1, 2))
        ne, nq = macro.n_elems, macro.n_qp

        def emean(a):
            return a.reshape(ne, nq, *a.shape[1:]).mean(axis=1)

        for a, b in _components(d):
            g.create_dataset(f"stress_{_AXES[a]}{_AXES[b]}", data=emean(sig[:, a, b]))
            g.create_dataset(f"strain_{_AXES[a]}{_AXES[b]}", data=emean(eps[:, a, b]))
            g.create_dataset(f"strain_increment_{_AXES[a]}{_AXES[b]}",
                             data=emean(inc_sym[:, a, b]))
        dev = eps - np.trace(eps, axis1=1, axis2=2)[:, None, None] / d * np.eye(d)
        g.create_dataset("deviatoric_strain",
                         data=emean(np.sqrt(2.0 / 3.0 * np.einsum("nij,nij->n", dev, dev))))
        p, ratio = _p_q(sig)
        g.create_dataset("pressure", data=emean(p))
        g.create_dataset("stress_ratio", data=emean(ratio))
        for k in ("void_ratio", "coordination", "anisotropy"):
            g.create_dataset(k, data=emean(np.asarray(measures[k], float)))
        fabric = np.asarray(measures["fabric"], float)
        for a, b in _components(d):
            g.create_dataset(f"fabric_{_AXES[a]}{_AXES[b]}", data=emean(fabric[:, a, b]))
        g.create_dataset("gauss/fabric", data=fabric)
        couple = np.asarray(measures["couple_stress"], float)
        if np.isfinite(couple).any():  # a law with rolling resistance (else NaN)
            moments = "z" if d == 2 else _AXES
            for a, m in enumerate(moments):
                for b in range(d):
                    g.create_dataset(f"couple_stress_{m}{_AXES[b]}",
                                     data=emean(couple[:, a, b]))
            g.create_dataset("gauss/couple_stress", data=couple)
        g.create_dataset("dem_fraction", data=emean(np.asarray(measures["ran_dem"], float)))
        g.create_dataset("gauss/stress", data=sig)
        g.create_dataset("gauss/strain", data=eps)
        g.create_dataset("gauss/increment", data=inc)
        g.create_dataset("gauss/ran_dem", data=np.asarray(measures["ran_dem"], bool))
        if macro.finite:
            g.create_dataset("gauss/points", data=macro.gauss_points(u))
        if self.porous is not None:
            self._saturated(g, solver, emean)
        meta.label(g, self._units, prefix=name + "/")
        self.f.flush()
        self.frames.append((name, solver.t))

    def _saturated(self, g, solver, emean):
        """A saturated problem's fields in frame group ``g``."""
        por, d = self.porous, self.macro.dim
        g.create_dataset("pore_pressure", data=por.nodal_pressure(solver.p))
        flux = por.darcy_flux(solver.p, solver.u)
        total = solver.total_stress()
        for a in range(d):
            g.create_dataset(f"darcy_flux_{_AXES[a]}", data=emean(flux[:, a]))
        for a, b in _components(d):
            g.create_dataset(f"total_stress_{_AXES[a]}{_AXES[b]}",
                             data=emean(total[:, a, b]))
        g.create_dataset("gauss/pore_pressure", data=por.gauss_pressure(solver.p))
        g.create_dataset("gauss/darcy_flux", data=flux)
        g.create_dataset("gauss/total_stress", data=total)

    def close(self, plots=True):
        """Write the curve, the XDMF file and (unless ``plots`` is False, e.g. after an
        interrupt: drawing takes seconds) the plots; close the HDF5 file."""
        if self._closed:
            return
        f = self._file()
        with self._guard():
            for k, v in self.curve.items():
                f.create_dataset(f"curve/{k}", data=np.asarray(v, dtype=np.float64))
            meta.label(f, self._units)
            keys = [k for k in f[self.frames[0][0]]
                    if isinstance(f[self.frames[0][0]][k], h5py.Dataset)] \
                if self.frames else []
            self._closed = True
            self.f = None
            self._out.close()
        self._xdmf(keys)
        if not plots:
            return
        try:
            write_figures(self)
        except OutputError:
            raise  # the disk refused it: an error, like any output that cannot be written
        except Exception as err:  # noqa: BLE001 - a plot must not lose a finished run
            log.warning("plots not written: %s", err)

    def _xdmf(self, keys):
        macro = self.macro
        n_pts = macro.mesh.p.shape[1]
        cells = macro.mesh.t.shape
        h5 = self.path.name
        root = ET.Element("Xdmf", {"Version": "3.0"})
        dom = ET.SubElement(root, "Domain")
        coll = ET.SubElement(dom, "Grid", {"Name": "steps", "GridType": "Collection",
                                           "CollectionType": "Temporal"})

        def item(parent, ref, shape, kind="Float", prec=8):
            it = ET.SubElement(parent, "DataItem", {
                "Dimensions": " ".join(map(str, shape)), "NumberType": kind,
                "Precision": str(prec), "Format": "HDF"})
            it.text = f"{h5}:/{ref}"

        topology = next(kind for cls, kind in _TOPOLOGY if isinstance(macro.mesh, cls))
        for name, t in self.frames:
            grid = ET.SubElement(coll, "Grid", {"Name": name, "GridType": "Uniform"})
            ET.SubElement(grid, "Time", {"Value": repr(float(t))})
            topo = ET.SubElement(grid, "Topology", {
                "TopologyType": topology,
                "NumberOfElements": str(cells[1])})
            item(topo, "mesh/cells", (cells[1], cells[0]), "Int")
            geo = ET.SubElement(grid, "Geometry", {"GeometryType": "XYZ"})
            item(geo, f"{name}/points" if macro.finite else "mesh/points", (n_pts, 3))
            att = ET.SubElement(grid, "Attribute", {"Name": "displacement",
                                                     "AttributeType": "Vector",
                                                     "Center": "Node"})
            item(att, f"{name}/displacement", (n_pts, 3))
            if "pore_pressure" in keys:
                att = ET.SubElement(grid, "Attribute", {"Name": "pore_pressure",
                                                         "AttributeType": "Scalar",
                                                         "Center": "Node"})
                item(att, f"{name}/pore_pressure", (n_pts,))
            for k in keys:
                if k in ("displacement", "points", "pore_pressure"):
                    continue
                att = ET.SubElement(grid, "Attribute", {"Name": k, "AttributeType":
                                                         "Scalar", "Center": "Cell"})
                item(att, f"{name}/{k}", (cells[1],))
        write_bytes_atomic(self.dir / "fields.xdmf",
                           lambda fh: ET.ElementTree(root).write(
                               fh, xml_declaration=True, encoding="utf-8"))
