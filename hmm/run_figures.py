"""The figures of a multiscale run, drawn from its closed ``fields.h5`` by
:meth:`hmm.io.Output.close` (the figures themselves are built in :mod:`hmm.plots`)."""

import h5py
import numpy as np
from skfem import MeshHex, MeshTri

from dem.io.hdf5 import save_figure

#: skfem's hexahedron vertex order -> VTK/XDMF order (the XDMF file's cells too)
HEX_ORDER = [0, 3, 6, 2, 1, 5, 7, 4]


def _second_panel(dem, void):
    """What the right half of deviatoric_strain.png shows: (values, title, cmap, limits).

    Where every Gauss point ran its RVE the share running DEM is 1 everywhere and
    says nothing; the void ratio (the dilation inside a band) says more.
    """
    if np.all(dem >= 1.0) and np.all(np.isfinite(void)):
        return void, "void ratio [-]", "magma", (None, None)
    return dem, "share of Gauss points running DEM [-]", "Greys", (0.0, 1.0)


def write_figures(out):
    """The figures of a closed run (:class:`hmm.io.Output`): ``load_displacement.png``,
    ``deviatoric_strain.png`` (2D: on the mesh; 3D: :func:`_slices`) and a saturated
    run's ``pore_pressure.png``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .plots import fields_figure, load_displacement_figure

    c = {k: np.asarray(v) for k, v in out.curve.items()}
    d = out.macro.dim
    save_figure(load_displacement_figure(c, out.driven, d),
                out.dir / "load_displacement.png", data="fields.h5:/curve")
    if out.porous is not None:
        _pressure_plot(out, plt, c)
    if not out.frames:
        return
    if d == 3:
        _slices(out)
        return
    with h5py.File(out.path, "r") as f:
        name = out.frames[-1][0]
        disp = f[name]["displacement"][:, :2]
        dev = f[name]["deviatoric_strain"][()]
        dem = f[name]["dem_fraction"][()]
        void = f[name]["void_ratio"][()]
    mesh = out.macro.mesh
    scale = 1.0
    span = np.ptp(mesh.p, axis=1).max()
    if np.abs(disp).max() > 0.0 and not out.macro.finite:  # finite: the true shape
        scale = min(10.0, 0.1 * span / np.abs(disp).max())
    fig = fields_figure(
        mesh.p.T + scale * disp, mesh.t.T,
        [(dev, "deviatoric strain [-]", "viridis", (None, None)),
         _second_panel(dem, void)],
        "last step, on the deformed mesh" if out.macro.finite else
        f"last step, displacements x {scale:.3g}")
    save_figure(fig, out.dir / "deviatoric_strain.png",
                data=f"fields.h5:/{out.frames[-1][0]}")

def _slices(out):
    """``deviatoric_strain.png`` of a 3D run: the last frame's deviatoric strain on
    three mid-planes (:func:`hmm.plots.slices_figure`)."""
    from .plots import slices_figure

    name = out.frames[-1][0]
    mesh = out.macro.mesh
    with h5py.File(out.path, "r") as f:
        dev = f[name]["deviatoric_strain"][()]
        pts = f[name]["points"][()] if out.macro.finite else \
            mesh.p.T + f[name]["displacement"][()]
    cells = mesh.t[HEX_ORDER].T if isinstance(mesh, MeshHex) else mesh.t[:4].T
    fig = slices_figure(pts, cells, dev, "deviatoric strain [-]",
                        "last step, on the deformed mesh" if out.macro.finite
                        else "last step, displacements x 1")
    save_figure(fig, out.dir / "deviatoric_strain.png", data=f"fields.h5:/{name}")

def _pressure_plot(out, plt, c):
    """``pore_pressure.png``: the pore pressure over time (maximum and mean over
    the nodes), in 2D its field on the mesh at the frame where it is largest, and
    the platens' settlement over time."""
    import matplotlib.tri as mtri

    d = out.macro.dim
    field = d == 2 and bool(out.frames)
    moving = [b for b in out.platens if f"displacement/{b}" in c]
    panels = 1 + int(field) + int(bool(moving))
    fig, axs = plt.subplots(1, panels, figsize=(5.0 * panels, 4), squeeze=False)
    ax = axs[0, 0]
    t = np.asarray(c["time"])
    log_time = t.size > 1 and t[t > 0].size and t.max() / t[t > 0].min() > 100.0
    for key, style, label in (("pore_pressure/max", "o-", "largest"),
                              ("pore_pressure/mean", "s--", "mean over the nodes")):
        ax.plot(t, 1e-3 * np.asarray(c[key]), style, ms=3, label=label)
    if log_time:
        ax.set_xscale("log")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("pore pressure [kPa]")
    ax.grid(alpha=0.3)
    ax.legend()
    if moving:
        ax = axs[0, panels - 1]
        for b in moving:  # settlement: down along the last axis, positive
            ax.plot(t, -1e3 * np.asarray(c[f"displacement/{b}"])[:, d - 1], "o-",
                    ms=3, label=b)
        if log_time:
            ax.set_xscale("log")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("settlement [mm]")
        ax.set_title("platens", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend()
    if field:  # the frame of the largest pore pressure: the most to see
        with h5py.File(out.path, "r") as f:
            name = max((fr[0] for fr in out.frames),
                       key=lambda n: np.abs(f[n]["pore_pressure"][()]).max())
            pn = f[name]["pore_pressure"][()]
            when = float(f[name].attrs["time"])
        mesh = out.macro.mesh
        xy = mesh.p.T  # small kinematics: the mesh does not move
        corners = mesh.t[:3].T if isinstance(mesh, MeshTri) else mesh.t[:4].T
        tris = corners if corners.shape[1] == 3 else np.vstack(
            [corners[:, [0, 1, 2]], corners[:, [0, 2, 3]]])
        ax = axs[0, 1]
        tri = mtri.Triangulation(1e3 * xy[:, 0], 1e3 * xy[:, 1], tris)
        art = ax.tripcolor(tri, 1e-3 * pn, shading="gouraud", cmap="Blues")
        ax.set_aspect("equal")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_title(f"pore pressure at t = {when:.4g} s", fontsize=10)
        fig.colorbar(art, ax=ax, shrink=0.8, label="pore pressure [kPa]")
    fig.tight_layout()
    save_figure(fig, out.dir / "pore_pressure.png", data="fields.h5")
    plt.close(fig)
