"""``fields.h5`` (the output of ``hmm run``) read back as numpy arrays with units.

:func:`read_fields` returns a :class:`Fields`: the mesh as scikit-fem holds it
(``points`` (d, n_vertices), ``cells`` (k, n_elems)), the Gauss points, and every
field stacked over the written steps, with its unit and sign convention.
"""

import json
from dataclasses import dataclass, field

import h5py
import numpy as np

from dem.io.hdf5 import read_bounded
from dem.io.meta import check_format, text, unit_of


@dataclass
class Fields:
    """The written steps of a multiscale run.

    Attributes
    ----------
    path : str
    attrs : dict
        The file's root attributes: ``format``, ``version``, ``software``,
        ``kinematics`` ("small" or "finite"), ...
    config : dict or None
        The problem that made the run (the ``config`` attribute, parsed), if stored.
    dim : int
        2 or 3.
    points : (dim, n_vertices) float64
        [m], the initial mesh's vertices, as ``skfem.Mesh.p``.
    cells : (k, n_elems) int64
        The corner vertices of each element, as ``skfem.Mesh.t`` (the file keeps
        hexahedra in VTK's order for ParaView; here they are in scikit-fem's).
    gauss_points : (n_gp, dim) float64
        [m], initial positions of the Gauss points (element by element).
    gauss_weights : (n_gp,) float64
        [m^dim], quadrature weights times the Jacobian.
    step : (n_frames,) int64
        The load step of each written frame (0: the initial state).
    load_factor : (n_frames,) float64
        [1].
    fields : dict
        ``{name: (n_frames, ...) array}``: every dataset of the frames, by its path
        in a frame: ``"displacement"`` (n_frames, n_vertices, 3) [m],
        ``"stress_xx"`` ... (n_frames, n_elems) element means, ``"pressure"``,
        ``"gauss/stress"`` (n_frames, n_gp, d, d), ...
    curve : dict
        ``{name: array}``: the load-displacement curve (every step),
        ``"load_factor"``, ``"displacement/<boundary>"``, ``"force/<boundary>"``, ...
    units : dict
        ``{name: unit}`` of every name of ``fields``, of ``curve`` (as
        ``"curve/<name>"``) and of the mesh and Gauss points (as the file names them:
        ``"mesh/points"``, ``"gauss/weights"``, ...).
    signs : dict
        ``{name: sign convention}``, where it matters ("tension positive",
        "compression positive", ...).

    ``fields_obj["stress_yy"]`` is ``fields_obj.fields["stress_yy"]``.
    """

    path: str
    attrs: dict
    config: dict
    dim: int
    points: np.ndarray
    cells: np.ndarray
    gauss_points: np.ndarray
    gauss_weights: np.ndarray
    step: np.ndarray
    load_factor: np.ndarray
    fields: dict = field(default_factory=dict)
    curve: dict = field(default_factory=dict)
    units: dict = field(default_factory=dict)
    signs: dict = field(default_factory=dict)

    def __getitem__(self, name):
        return self.fields[name]

    def mesh(self):
        """The initial mesh as a linear scikit-fem mesh of the corner vertices
        (``MeshTri``, ``MeshQuad``, ``MeshTet`` or ``MeshHex``), on which the nodal
        fields (``displacement``) live."""
        from skfem import MeshHex, MeshQuad, MeshTet, MeshTri

        kinds = {(2, 3): MeshTri, (2, 4): MeshQuad, (3, 4): MeshTet, (3, 8): MeshHex}
        kind = kinds.get((self.dim, self.cells.shape[0]))
        if kind is None:
            raise ValueError(f"{self.path}: no scikit-fem mesh of {self.cells.shape[0]}-"
                             f"vertex cells in {self.dim}D")
        return kind(self.points, self.cells)

    def __len__(self):
        return len(self.step)


def read_fields(path):
    """Read ``fields.h5`` of ``hmm run`` (or ``hmm demo``).

    Files of version 1 (before units were stored) are read too: their
    ``mean_stress`` comes as ``pressure`` (the same numbers, compression positive)
    and their units are those the format defines.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Fields

    Raises
    ------
    ValueError
        ``path`` is not HDF5, another kind of file (its ``format`` tag, e.g. a
        ``batch.h5``), a version this reader does not know, misses a part, or a
        dataset declares more data than the file holds.
    """
    from .io import _HEX_ORDER, FORMAT, RENAMED, VERSIONS, field_units

    path = str(path)
    try:
        f = h5py.File(path, "r")
    except OSError as err:
        raise ValueError(f"{path} is not a readable HDF5 file "
                         f"({' '.join(str(err).split())})") from None
    with f:
        check_format(f, path, FORMAT, VERSIONS)
        try:
            out = _read(f, path, RENAMED, field_units)
        except (KeyError, TypeError, IndexError) as err:
            raise ValueError(f"{path}: not a complete fields file "
                             f"({' '.join(str(err).split())})") from None
    if out.dim == 3 and out.cells.shape[0] == 8:  # VTK's vertex order -> skfem's
        out.cells = out.cells[np.argsort(_HEX_ORDER)]
    return out


def _read(f, path, renamed, field_units):
    attrs = {k: _value(v) for k, v in f.attrs.items()}
    config = attrs.get("config")
    if isinstance(config, str):
        try:
            config = json.loads(config)
        except ValueError:
            pass  # stored as text
    gp = read_bounded(f["gauss/points"], "gauss/points")
    dim = int(gp.shape[1])
    rules = field_units(dim)
    out = Fields(path, attrs, config, dim,
                 read_bounded(f["mesh/points"], "mesh/points")[:, :dim].T.copy(),
                 read_bounded(f["mesh/cells"], "mesh/cells").T.copy(), gp,
                 read_bounded(f["gauss/weights"], "gauss/weights"),
                 np.zeros(0, np.int64), np.zeros(0))
    for key in ("mesh/points", "mesh/cells", "gauss/points", "gauss/weights"):
        _note(out, key, f[key], key, rules)
    names = sorted(f["steps"]) if "steps" in f else []
    frames = []
    for name in names:
        g = f["steps"][name]
        data = {}

        def visit(key, obj, g=g, data=data, name=name):
            if isinstance(obj, h5py.Dataset):
                new = renamed.get(key, key)
                data[new] = read_bounded(obj, f"steps/{name}/{key}")
                _note(out, new, obj, f"steps/{name}/{new}", rules)

        g.visititems(visit)
        frames.append(data)
    out.step = np.array([int(f["steps"][n].attrs["step"]) for n in names], np.int64)
    out.load_factor = np.array([float(f["steps"][n].attrs["load_factor"])
                                for n in names])
    common = set.intersection(*(set(d) for d in frames)) if frames else set()
    out.fields = {k: np.stack([d[k] for d in frames]) for k in sorted(common)}
    if isinstance(f.get("curve"), h5py.Group):
        def curve(key, obj):
            if isinstance(obj, h5py.Dataset):
                out.curve[key] = read_bounded(obj, f"curve/{key}")
                _note(out, f"curve/{key}", obj, f"curve/{key}", rules)

        f["curve"].visititems(curve)
    return out


def _note(out, name, obj, full, rules):
    """Record the unit and sign of dataset ``obj`` under ``name``: its attributes,
    or (a file of version 1) what the format defines for its path ``full``."""
    if "unit" in obj.attrs:
        out.units[name] = text(obj.attrs["unit"])
        if "sign" in obj.attrs:
            out.signs[name] = text(obj.attrs["sign"])
        return
    found = unit_of(full, rules)
    if found is not None:
        out.units[name] = found[0]
        if found[1]:
            out.signs[name] = found[1]


def _value(v):
    v = text(v)
    return v.item() if isinstance(v, np.generic) else v
