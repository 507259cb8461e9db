"""What an RVE test (``hmm rve``) writes: ``rve_test.h5`` and ``rve_test.png``.

The units and sign conventions of the curves and the summary (:data:`UNITS`,
:data:`SIGNS`, :data:`SUMMARY_UNITS`, shared with ``batch.h5``), the HDF5 writer and the
figure of each kind of test.
"""

import json
import math

import numpy as np

__all__ = ["FORMAT", "SIGNS", "SUMMARY_UNITS", "UNITS", "VERSION", "curve_attrs",
           "write_figure", "write_h5"]

#: unit of each curve that has one (the others are dimensionless, unit "1")
UNITS = {"stress": "Pa", "p": "Pa", "q": "Pa", "friction_angle": "deg",
         "excess_pore_pressure": "Pa", "shear_stress": "Pa", "normal_stress": "Pa"}
#: the sign convention of each curve whose sign matters (geomechanics: strains,
#: ``p`` and the normal stress compression positive; the stress tensor tension
#: positive)
SIGNS = {"stress": "tension positive", "p": "compression positive",
         "q": "non-negative", "excess_pore_pressure": "compression positive",
         "shear_stress": "tension positive (the stress component)",
         "normal_stress": "compression positive",
         "axial_strain": "compression positive (shortening)",
         "normal_strain": "compression positive (shortening)",
         "volumetric_strain": "compression positive (contraction)"}
#: the format tag and version of ``rve_test.h5``
FORMAT, VERSION = "hmm.rve_test", 1


def curve_attrs(name):
    """The ``unit`` (and ``sign``) attributes of the curve ``name`` of an RVE test
    (``rve_test.h5``, ``batch.h5``)."""
    out = {"unit": UNITS.get(name, "1")}
    if name in SIGNS:
        out["sign"] = SIGNS[name]
    return out


#: unit of each summary value that has one
SUMMARY_UNITS = {"confining": "Pa", "peak_friction_angle": "deg",
                  "dilatancy_angle": "deg", "critical_friction_angle": "deg",
                  "critical_dilatancy_angle": "deg", "wall_time": "s",
                  "peak_deviator": "Pa", "peak_mean_stress": "Pa",
                  "phase_transformation_mean_stress": "Pa",
                  "phase_transformation_deviator": "Pa",
                  "max_excess_pore_pressure": "Pa", "final_excess_pore_pressure": "Pa",
                  "final_mean_stress": "Pa", "final_deviator": "Pa",
                  "final_friction_angle": "deg", "final_axial_stress": "Pa",
                  "constrained_modulus": "Pa"}


def write_h5(path, result):
    """Write the curves and summary of ``result`` (a :class:`~hmm.experiment.CompressionResult`)
    to ``path`` (``rve_test.h5``), atomically."""
    from dem.io.files import write_h5_atomic
    from dem.io.meta import stamp

    def fill(f):
        for name, values in result.curves.items():
            f.create_dataset(name, data=values).attrs.update(curve_attrs(name))
        for name, value in result.summary.items():
            f.attrs[name] = value
        stamp(f, FORMAT, VERSION, result.config)
        f.attrs["units"] = json.dumps(SUMMARY_UNITS)
        f.attrs["config"] = json.dumps(result.config)
        f.attrs["conventions"] = ("compression positive for strains, p, q; stress "
                                  "dataset tension positive; engineering strains")

    write_h5_atomic(path, fill)


def write_figure(path, result):
    """Draw the curves of ``result`` to the PNG ``path`` (``rve_test.png``)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from dem.io.hdf5 import save_figure

    c, s = result.curves, result.summary
    if s.get("kind", "drained") != "drained":
        panels = {"undrained": _undrained_panels, "oedometric": _oedometric_panels,
                  "isotropic": _isotropic_panels, "simple_shear": _shear_panels,
                  "cyclic": _cyclic_panels}[s["kind"]]
        fig = Figure(figsize=(12.0, 3.6), layout="constrained")
        FigureCanvasAgg(fig)
        panels(fig.subplots(1, 3), c, s)
        test = "biaxial" if s["dim"] == 2 else "triaxial"
        what = {"undrained": f"undrained {test}", "oedometric": "oedometric",
                "isotropic": "isotropic compression and unloading",
                "simple_shear": "simple shear",
                "cyclic": f"cyclic undrained {test}"}[s["kind"]]
        fig.suptitle(f"{what} test, {s['n_particles']} {s['particles']}, from "
                     f"{s['confining']:.4g} Pa, e0 = {s['initial_void_ratio']:.3f}")
        save_figure(fig, path, dpi=120, data="rve_test.h5")
        return
    ea = 100.0 * c["axial_strain"]
    fig = Figure(figsize=(9.0, 3.6), layout="constrained")
    FigureCanvasAgg(fig)
    ax1, ax2 = fig.subplots(1, 2)
    ax1.plot(ea, c["stress_ratio"], "k-")
    ax1.plot([100.0 * s["peak_axial_strain"]], [s["peak_stress_ratio"]], "ro",
             label=f"peak, φ = {s['peak_friction_angle']:.1f}°")
    ax1.axhline(s["critical_stress_ratio"], color="b", ls="--",
                label=f"last 20 %, φ = {s['critical_friction_angle']:.1f}°")
    ax1.set(xlabel="axial strain [%]", ylabel="stress ratio q/p")
    ax1.legend(loc="lower right")
    ax2.plot(ea, 100.0 * c["volumetric_strain"], "k-")
    ax2.axhline(0.0, color="0.6", lw=0.8)
    ax2.set(xlabel="axial strain [%]",
            ylabel="volumetric strain [%] (contraction > 0)")
    test = "biaxial" if s["dim"] == 2 else "triaxial"
    fig.suptitle(f"drained {test} test, {s['n_particles']} {s['particles']}, confining "
                 f"{s['confining']:.4g} Pa, e0 = {s['initial_void_ratio']:.3f}")
    save_figure(fig, path, dpi=120, data="rve_test.h5")


def _undrained_panels(axs, c, s):
    ea = 100.0 * c["axial_strain"]
    axs[0].plot(ea, 1e-3 * c["q"], "k-")
    axs[0].set(xlabel="axial strain [%]", ylabel="deviator q [kPa]")
    axs[1].plot(1e-3 * c["p"], 1e-3 * c["q"], "k-", label="effective stress path")
    if np.isfinite(s["phase_transformation_mean_stress"]):
        axs[1].plot([1e-3 * s["phase_transformation_mean_stress"]],
                    [1e-3 * s["phase_transformation_deviator"]], "bs",
                    label="phase transformation")
    axs[1].plot([1e-3 * s["peak_mean_stress"]], [1e-3 * s["peak_deviator"]], "ro",
                label="peak q")
    axs[1].set(xlabel="mean effective stress p' [kPa]", ylabel="deviator q [kPa]")
    axs[1].legend(loc="best", fontsize=8)
    axs[2].plot(ea, 1e-3 * c["excess_pore_pressure"], "k-")
    axs[2].axhline(0.0, color="0.6", lw=0.8)
    axs[2].set(xlabel="axial strain [%]", ylabel="excess pore pressure [kPa]")
    for ax in axs:
        ax.grid(alpha=0.3)


def _oedometric_panels(axs, c, s):
    ea = 100.0 * c["axial_strain"]
    d = s["dim"]
    sig_a = -c["stress"][:, d - 1, d - 1]
    axs[0].plot(ea, 1e-3 * sig_a, "k-")
    axs[0].set(xlabel="axial strain [%]", ylabel="axial effective stress [kPa]")
    axs[1].semilogx(1e-3 * sig_a, c["void_ratio"], "k-")
    axs[1].set(xlabel="axial effective stress [kPa]", ylabel="void ratio e")
    axs[2].plot(ea[1:], c["k0"][1:], "k-")
    axs[2].axhline(s["k0"], color="b", ls="--", label=f"K0 = {s['k0']:.3f}")
    axs[2].set(xlabel="axial strain [%]", ylabel="K0 = lateral / axial stress")
    axs[2].legend(loc="best", fontsize=8)
    for ax in axs:
        ax.grid(alpha=0.3)


def _isotropic_panels(axs, c, s):
    p = 1e-3 * c["p"]
    axs[0].semilogx(p, c["void_ratio"], "ko-", ms=3)
    axs[0].set(xlabel="mean stress p [kPa]", ylabel="void ratio e",
               title=f"λ = {s['compression_index']:.2e}, κ = {s['swelling_index']:.2e}")
    axs[1].plot(p, 100.0 * c["volumetric_strain"], "ko-", ms=3)
    axs[1].set(xlabel="mean stress p [kPa]",
               ylabel="volumetric strain [%] (contraction > 0)")
    axs[2].plot(np.arange(len(p)), p, "ko-", ms=3)
    axs[2].set(xlabel="increment", ylabel="mean stress p [kPa]")
    for ax in axs:
        ax.grid(alpha=0.3)


def _shear_panels(axs, c, s):
    g = 100.0 * c["shear_strain"]
    sn = np.where(c["normal_stress"] > 0.0, c["normal_stress"], np.nan)
    axs[0].plot(g, c["shear_stress"] / sn, "k-")
    axs[0].set(xlabel="shear strain γ [%]", ylabel="τ / σ_n",
               title=f"peak φ = {s['peak_friction_angle']:.1f}°")
    axs[1].plot(g, 100.0 * c["normal_strain"], "k-")
    axs[1].axhline(0.0, color="0.6", lw=0.8)
    axs[1].set(xlabel="shear strain γ [%]",
               ylabel="normal strain [%] (contraction > 0)")
    axs[2].plot(g, c["void_ratio"], "k-")
    axs[2].set(xlabel="shear strain γ [%]", ylabel="void ratio e")
    for ax in axs:
        ax.grid(alpha=0.3)


def _cyclic_panels(axs, c, s):
    ea = 100.0 * c["axial_strain"]
    axs[0].plot(ea, 1e-3 * c["q"] * np.sign(c["stress"][:, 0, 0] - c["stress"][:, -1, -1]),
                "k-", lw=0.8)
    axs[0].set(xlabel="axial strain [%]", ylabel="deviator [kPa] (compression > 0)")
    axs[1].plot(1e-3 * c["p"], 1e-3 * c["q"], "k-", lw=0.8)
    axs[1].set(xlabel="mean effective stress p' [kPa]", ylabel="q [kPa]")
    per_cycle = 4 * math.ceil(s["strain_amplitude"] / s["strain_increment"] - 1e-9)
    n = np.arange(len(ea)) / per_cycle
    axs[2].plot(n, c["excess_pore_pressure"] / s["confining"], "k-")
    axs[2].set(xlabel="cycles", ylabel="r_u = excess pore pressure / σ'_0")
    for ax in axs:
        ax.grid(alpha=0.3)
