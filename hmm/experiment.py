"""The standalone RVE compression test: ``hmm rve rve.toml``.

A periodic packing (generated and consolidated, or read from a file) is brought
isotropically to the confining pressure, then compressed along its last axis (y in
2D, z in 3D) in equal increments of axial strain while a servo holds the lateral
stresses at the confining pressure: a drained biaxial test in 2D, a drained triaxial
test in 3D. After every increment the cell relaxes to quasi-static equilibrium
(:meth:`dem.rve.RVE.load`) and the state is recorded.

Conventions (soil mechanics, compression positive; the DEM stress itself is positive
in tension):

* axial strain ``eps_a = 1 - F_aa`` and volumetric strain ``eps_v = 1 - det F``
  (engineering strains, ``F`` the deformation gradient of the cell since the start of
  the compression): ``eps_v > 0`` is contraction, ``eps_v < 0`` dilation;
* principal stresses ``s1 >= s2 (>= s3)`` of ``-sigma``; 2D: ``p = (s1 + s2) / 2``,
  ``q = (s1 - s2) / 2``, mobilised friction ``sin phi = q / p``; 3D: ``p`` the mean
  stress, ``q = sqrt(3 J2)`` (``(s1 + 2 s3) / 3`` and ``s1 - s3`` when ``s2 = s3``),
  ``sin phi = 3 M / (6 + M)`` with ``M = q / p``;
* dilatancy ``sin psi = -d eps_v / (2 d eps_a - d eps_v)`` from logarithmic strain
  rates: in 2D ``-d eps_v / d gamma`` with ``gamma = eps_1 - eps_2``; in 3D the
  triaxial form of the Mohr-Coulomb flow rule. Positive ``psi`` is dilation.

The file format is :data:`RVE_SCHEMA` (validated by :func:`dem.io.scene.validate`);
``docs/rve.md`` holds its reference. The test is in four modules: this one runs it;
:mod:`hmm.experiment_config` holds the schema and the validation,
:mod:`hmm.experiment_summary` the measures and the summary of each kind of test,
:mod:`hmm.experiment_output` the files written. The names of ``__all__`` are all
importable from here.
"""

import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dem.io.schema import SceneError

from .experiment_config import RVE_SCHEMA, load_config, shape_maker, validate_config
from .experiment_output import SUMMARY_UNITS, UNITS, write_figure, write_h5
from .experiment_summary import dilatancy_angle, friction_angle, stress_invariants, summarize

log = logging.getLogger(__name__)

__all__ = ["RVE_SCHEMA", "SUMMARY_UNITS", "UNITS", "CompressionResult", "compress",
           "dilatancy_angle", "friction_angle", "load_config", "make_packing",
           "output_paths", "run_experiment", "stress_invariants", "validate_config"]

#: written by a test: curves and summary, figure, and (generated packings) the packing
OUTPUTS = ("rve_test.h5", "rve_test.png", "packing.h5")


# --------------------------------------------------------------------------- packing
def _law(c):
    from dem.contact.laws import law_class
    from dem.io.materials import rolling_spec

    return law_class(c["law"]).from_table(c, rolling=rolling_spec(c))


def make_packing(cfg):
    """The packing of a validated config, ready for :func:`compress`.

    Returns ``(rve, confining, generated)``: the :class:`dem.rve.RVE`, generated and
    consolidated at ``[packing] p0`` [Pa] or read from ``[packing] file``; the
    confining pressure [Pa] of the test; whether the packing was generated. Raises
    :class:`~dem.io.scene.SceneError` (one line) for unusable input.
    """
    from dem import rve as rve_mod
    from dem.io.checkpoint import read_group

    p, t = cfg["packing"], cfg["test"]
    settings = {k: t[k] for k in ("tol", "stress_tol", "max_step_strain",
                                  "max_relax_steps")}
    where = f"{cfg['source']}: [packing]"
    if p["file"] is None:
        try:
            law = _law(cfg["contact"])
            rve = rve_mod.generate(p["dim"], p["count"], p["radius"], law, p["p0"],
                                   density=p["density"], seed=p["seed"],
                                   friction=p["consolidation_friction"],
                                   damping=t["damping"], shape=shape_maker(p),
                                   **settings)
        except ValueError as exc:
            raise SceneError(f"{where} {exc}") from None
        return rve, t["confining"], True
    try:
        rve = rve_mod.RVE.load_file(p["file"], **settings)
        stored = read_group(p["file"], "rve")["attrs"].get("p0")
    except (OSError, ValueError) as exc:
        raise SceneError(f"{where} cannot use file {p['file']}: {exc}") from None
    rve.sim.damping = t["damping"]
    confining = t["confining"] if t["confining"] is not None else stored
    if confining is None:
        raise SceneError(f"{cfg['source']}: [test] confining is required: "
                         f"{p['file']} does not record its consolidation pressure")
    return rve, float(confining), False

# --------------------------------------------------------------------------- the test
@dataclass
class CompressionResult:
    """Curves (one row per recorded state, row 0 the start) and summary of a test."""

    curves: dict
    summary: dict
    config: dict
    generated: bool
    files: list = field(default_factory=list)


def output_paths(cfg, out_dir=None):
    """The files a test of ``cfg`` writes, in ``out_dir`` (default ``[output] dir``)."""
    out = Path(cfg["output"]["dir"] if out_dir is None else out_dir)
    names = OUTPUTS if cfg["packing"]["file"] is None else OUTPUTS[:2]
    return [out / n for n in names]


def run_experiment(cfg, out_dir=None, overwrite=False, progress=None):
    """Build or load the packing, compress it, write the results.

    Parameters
    ----------
    cfg : dict
        A validated configuration (:func:`load_config`).
    out_dir : str or Path, optional
        Output directory (default ``[output] dir``); made if missing.
    overwrite : bool
        Replace existing output files (else FileExistsError before anything runs).
    progress : bool, optional
        A progress bar over the increments (default: when stderr is a terminal).

    Returns
    -------
    CompressionResult

    Raises
    ------
    SceneError
        Unusable packing parameters or packing file.
    FileExistsError
        An output file exists and ``overwrite`` is False.
    OSError
        An output is a directory, or the output directory cannot be made or
        written into (checked first).
    dem.rve.RelaxationError
        An increment did not relax; nothing is written.
    """
    from dem.progress import progress_bar

    from dem.io.plan import check_new_files

    paths = output_paths(cfg, out_dir)
    # an existing output, a directory in its place, a directory that cannot be made:
    # refused before the test runs, not after
    check_new_files(paths, overwrite)
    t0 = time.perf_counter()
    packing = make_packing(cfg)
    rve, generated = packing[0], packing[2]
    consolidated = rve.snapshot() if generated else None
    bar = progress_bar(len(_increments(cfg["test"], 2, 1.0)), progress, min_steps=1,
                       unit="increment")
    shown = None if bar is None else (lambda k: bar.update(k - bar.n))  # bar at k
    try:
        result = compress(cfg, shown, packing)
    finally:
        if bar is not None:
            bar.close()
    result.summary["wall_time"] = time.perf_counter() - t0
    result.files = paths
    paths[0].parent.mkdir(parents=True, exist_ok=True)
    write_h5(paths[0], result)
    write_figure(paths[1], result)
    if generated:
        rve.restore(consolidated)
        p = cfg["packing"]
        rve.save(paths[2], config={"packing": p, "contact": cfg["contact"]},
                 p0=p["p0"], seed=p["seed"],
                 consolidation_friction=p["consolidation_friction"])
    return result


def compress(cfg, on_increment=None, packing=None):
    """Run the test of a validated config in memory; nothing is written.

    The packing is consolidated isotropically at the confining pressure, then
    compressed in increments of axial strain (see the module), as by
    :func:`run_experiment`, with the same results.

    Parameters
    ----------
    cfg : dict
        A validated configuration (:func:`load_config`).
    on_increment : callable, optional
        ``on_increment(k)`` is called with ``k = 0`` once the packing is consolidated
        at the confining pressure, then with ``k = 1, ..., n`` after increment ``k``.
        It may raise to abandon the test.
    packing : tuple, optional
        ``(rve, confining, generated)`` from :func:`make_packing` (default: made
        here). The RVE is left in the state at the end of the test.

    Returns
    -------
    CompressionResult
        Without ``files``; ``summary["wall_time"]`` [s] is the time of this call.

    Raises
    ------
    SceneError
        Unusable packing parameters or packing file.
    dem.rve.RelaxationError
        An increment did not relax.
    """
    t0 = time.perf_counter()
    rve, confining, generated = make_packing(cfg) if packing is None else packing
    rve.consolidate(confining)  # isotropic, at the working friction
    if on_increment is not None:
        on_increment(0)
    t = cfg["test"]
    curves = _curves(rve, confining, _increments(t, rve.dim, confining), on_increment,
                     t["kind"])
    summary = summarize(t["kind"], curves, rve, confining, t["increment"])
    summary["kind"] = t["kind"]
    summary["wall_time"] = time.perf_counter() - t0
    return CompressionResult(curves, summary, cfg, generated)


def _targets(t):
    """The engineering axial strains at the end of the increments of ``[test]``."""
    n_inc = math.ceil(t["axial_strain"] / t["increment"] - 1e-9)
    return np.minimum(np.arange(1, n_inc + 1) * t["increment"], t["axial_strain"])


def _increments(t, d, confining):
    """What each increment of a ``[test]`` does: ``(kind, value)`` pairs, ``value``
    the engineering axial strain (drained, undrained, oedometric, cyclic), the shear
    strain (simple_shear) or the mean stress [Pa] (isotropic) at its end."""
    kind = t["kind"]
    if kind == "isotropic":
        top = t["p_max"] if t["p_max"] is not None else 4.0 * confining
        up = confining * (top / confining) ** (np.arange(1, t["steps"] + 1) / t["steps"])
        return [(kind, p) for p in np.concatenate([up, up[-2::-1], [confining]])]
    if kind == "cyclic":  # a triangle wave 0 -> A -> -A -> A ... -> 0
        amp, n = t["axial_strain"], math.ceil(t["axial_strain"] / t["increment"] - 1e-9)
        quarter = amp * np.arange(1, n + 1) / n
        cycle = np.concatenate([quarter, amp - quarter, -quarter, -amp + quarter])
        return [(kind, e) for e in np.tile(cycle, t["cycles"])]
    return [(kind, e) for e in _targets(t)]


def _curves(rve, confining, increments, on_increment, kind="drained"):
    """Run the ``increments`` (:func:`_increments`), the lateral sides held as
    ``kind`` says; the curves."""
    from dem.rve import PackingApart

    d = rve.dim
    axial = d - 1
    lateral_axes = np.arange(d) != axial
    f0_inv = np.linalg.inv(rve.deformation)
    rows = [_record(rve, rve.stress(), f0_inv, 0)]
    for k, (_, value) in enumerate(increments, 1):
        f_rel = rve.deformation @ f0_inv
        deps, target, mask = _increment(kind, value, f_rel, confining, d)
        try:
            stress = rve.load(deps, stress=target, mask=mask)
        except PackingApart:
            if kind not in ("undrained", "cyclic"):
                raise
            # liquefied: no effective stress left; the test ends at this state
            rows.append(_record(rve, rve.stress(), f0_inv, rve.last_relax_steps))
            break
        rows.append(_record(rve, stress, f0_inv, rve.last_relax_steps))
        if on_increment is not None:
            on_increment(k)
    curves = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    p, q = stress_invariants(curves["stress"])
    curves.update(p=p, q=q, stress_ratio=q / p,
                  friction_angle=friction_angle(q / p, d))
    sig = -curves["stress"]  # compression positive
    lat = np.mean([sig[:, i, i] for i in np.flatnonzero(lateral_axes)], axis=0)
    if kind in ("undrained", "cyclic"):  # the cell pressure holds the total lateral
        curves["excess_pore_pressure"] = confining - lat
    elif kind == "oedometric":
        curves["k0"] = lat / sig[:, axial, axial]
    elif kind == "simple_shear":
        curves["shear_strain"] = np.array([r["shear"] for r in rows])
        curves["shear_stress"] = curves["stress"][:, 0, axial]
        curves["normal_stress"] = sig[:, axial, axial]
        curves["normal_strain"] = curves["axial_strain"]
    curves.pop("shear")
    if kind == "cyclic":
        curves["amplitude"] = float(max(abs(v) for _, v in increments))
    return curves


def _increment(kind, value, f_rel, confining, d):
    """``(deps, stress target, mask)`` of one increment to ``value``."""
    axial = d - 1
    deps = np.zeros((d, d))
    if kind == "isotropic":
        return deps, np.full(d, -value), np.ones(d, bool)
    lateral = np.flatnonzero(np.arange(d) != axial)
    if kind == "simple_shear":  # shear x along the last axis, normal stress held
        deps[0, axial] = (value - f_rel[0, axial]) / f_rel[axial, axial]
        mask = np.zeros(d, bool)
        mask[axial] = True
        return deps, np.where(mask, -confining, 0.0), mask
    deps[axial, axial] = (1.0 - value) / f_rel[axial, axial] - 1.0
    if kind == "drained":
        return deps, np.full(d, -confining), np.arange(d) != axial
    # strain control: no lateral strain, or the lateral strain of no volume
    stretch = 1.0 if kind == "oedometric" else (1.0 - value) ** (-1.0 / (d - 1))
    for i in lateral:
        deps[i, i] = stretch / f_rel[i, i] - 1.0
    return deps, None, None


def _record(rve, stress, f0_inv, steps):
    r = rve.response(tangent=False)
    f_rel = rve.deformation @ f0_inv
    return {"axial_strain": 1.0 - f_rel[-1, -1], "shear": f_rel[0, -1],
            "volumetric_strain": 1.0 - np.linalg.det(f_rel),
            "stress": np.array(stress), "void_ratio": r["void_ratio"],
            "coordination": r["coordination"], "n_contacts": r["n_contacts"],
            "unbalanced": r["unbalanced"], "relax_steps": steps}

