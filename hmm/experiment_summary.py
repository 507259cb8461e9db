"""The measures and the summary of an RVE test (``hmm rve``).

Stress invariants, mobilised friction and dilatancy angles (the conventions are those of
:mod:`hmm.experiment`: compression positive, the DEM stress itself positive in tension),
and :func:`summarize`, which reduces the curves of one test to the numbers of its kind,
and :func:`report`, the lines ``hmm rve`` prints of them.
"""

import math

import numpy as np

__all__ = ["dilatancy_angle", "friction_angle", "grains", "report", "stress_invariants",
           "summarize"]


def stress_invariants(stress):
    """Mean stress ``p`` and deviator ``q`` [Pa], compression positive.

    Parameters
    ----------
    stress : (..., d, d) array_like
        Cauchy stress [Pa], tension positive (as the DEM reports it).

    Returns
    -------
    p, q : (...) ndarray
        2D: ``(s1 + s2) / 2`` and ``(s1 - s2) / 2``; 3D: ``(s1 + s2 + s3) / 3`` and
        ``sqrt(3 J2)``, with ``s_i`` the principal values of ``-stress``.

    Examples
    --------
    >>> p, q = stress_invariants([[-3.0, 0.0], [0.0, -1.0]])
    >>> float(p), float(q)
    (2.0, 1.0)
    >>> p, q = stress_invariants(np.diag([-1.0, -1.0, -4.0]))
    >>> float(p), float(q)
    (2.0, 3.0)
    """
    s = np.sort(np.linalg.eigvalsh(-np.asarray(stress, dtype=np.float64)), axis=-1)
    if s.shape[-1] == 2:
        return 0.5 * (s[..., 1] + s[..., 0]), 0.5 * (s[..., 1] - s[..., 0])
    p = s.mean(axis=-1)
    dev = s - p[..., None]
    return p, np.sqrt(1.5 * np.einsum("...i,...i->...", dev, dev))


def friction_angle(ratio, dim):
    """Mobilised friction angle [deg] of stress ratios ``q / p`` (see the module).

    >>> round(float(friction_angle(0.5, 2)), 6), round(float(friction_angle(1.2, 3)), 4)
    (30.0, 30.0)
    """
    ratio = np.asarray(ratio, dtype=np.float64)
    sin = ratio if dim == 2 else 3.0 * ratio / (6.0 + ratio)
    return np.degrees(np.arcsin(np.clip(sin, -1.0, 1.0)))


def dilatancy_angle(axial_strain, volumetric_strain):
    """Dilatancy angle [deg] of a stretch of the test, positive when dilating.

    ``sin psi = -d eps_v / (2 d eps_a - d eps_v)``, the slope ``d eps_v / d eps_a``
    of a straight line fitted to the logarithmic strains. Arguments are engineering
    strains (compression positive), (n,) with n >= 2; NaN for a shorter stretch.

    >>> round(dilatancy_angle([0.0, 1e-6], [0.0, -1e-6]), 2)   # sin psi = 1/3
    19.47
    >>> dilatancy_angle([0.0, 0.05], [0.0, 0.0])                # isochoric
    0.0
    """
    ea = -np.log1p(-np.asarray(axial_strain, dtype=np.float64))
    ev = -np.log1p(-np.asarray(volumetric_strain, dtype=np.float64))
    if ea.size < 2 or np.ptp(ea) == 0.0:
        return math.nan
    slope = np.polyfit(ea, ev, 1)[0]
    sin = np.clip(-slope / (2.0 - slope), -1.0, 1.0)
    return float(np.degrees(np.arcsin(sin))) + 0.0  # no "-0.0"


def grains(bodies):
    """What the particles are, in words: disks, spheres, polygons, squares, ...
    (:func:`dem.shapes.registry.grain_name`), or "particles" for a mix."""
    from dem.shapes.registry import grain_name

    kinds = np.unique(bodies.kind).tolist()
    name = grain_name(kinds[0], bodies.dim) if len(kinds) == 1 else None
    return name or "particles"


def summarize(kind, curves, rve, confining, increment):
    """The summary of a test of ``[test] kind`` from its ``curves`` (the packing ``rve``
    at the end of the test, the ``confining`` pressure [Pa], the strain ``increment``).

    ``curves`` comes from :func:`hmm.experiment.compress`; a cyclic test's
    ``"amplitude"`` entry is taken out of it into the summary.
    """
    return _SUMMARIES[kind](curves, rve, confining, increment)


def _test_summary(c, rve, confining):
    """What every test's summary opens with: the packing and its start."""
    return {"dim": rve.dim, "n_particles": int(rve.bodies.n),
            "particles": grains(rve.bodies), "confining": confining,
            "initial_void_ratio": float(c["void_ratio"][0])}


def _summarize(c, rve, confining, increment):
    d = rve.dim
    ratio, ea, ev = c["stress_ratio"], c["axial_strain"], c["volumetric_strain"]
    k = int(np.argmax(ratio))
    near = np.abs(ea - ea[k]) <= max(0.01, 2.0 * increment) + 1e-12
    late = ea >= 0.8 * ea[-1] - 1e-12
    cs_ratio = float(ratio[late].mean())
    return {**_test_summary(c, rve, confining),
            "peak_stress_ratio": float(ratio[k]), "peak_axial_strain": float(ea[k]),
            "peak_friction_angle": float(friction_angle(ratio[k], d)),
            "dilatancy_angle": dilatancy_angle(ea[near], ev[near]),
            "critical_stress_ratio": cs_ratio,
            "critical_friction_angle": float(friction_angle(cs_ratio, d)),
            "critical_dilatancy_angle": dilatancy_angle(ea[late], ev[late]),
            "final_volumetric_strain": float(ev[-1]),
            "final_void_ratio": float(c["void_ratio"][-1])}


def _summarize_undrained(c, rve, confining, increment):
    """Peak deviator, phase transformation (the largest excess pore pressure before
    the end, where the packing turns from contraction to dilation; NaN when the
    pressure rises to the end or never rises), excess pore pressures and the
    softening after the peak (q at the end over the peak q; static liquefaction
    drives it towards 0)."""
    p, q, ea, u = c["p"], c["q"], c["axial_strain"], c["excess_pore_pressure"]
    k = int(np.argmax(q))
    m = int(np.argmax(u))
    turn = 0 < m < len(u) - 1
    # liquefied: the packing came apart (the test stopped), or its mean effective
    # stress fell below 1 % of the start
    liquefied = bool(p[-1] < 0.01 * p[0])
    nan = float("nan")
    return {**_test_summary(c, rve, confining),
            "peak_deviator": float(q[k]), "peak_axial_strain": float(ea[k]),
            "peak_mean_stress": float(p[k]),
            "phase_transformation_mean_stress": float(p[m]) if turn else nan,
            "phase_transformation_deviator": float(q[m]) if turn else nan,
            "phase_transformation_axial_strain": float(ea[m]) if turn else nan,
            "max_excess_pore_pressure": float(u.max()),
            "final_excess_pore_pressure": float(u[-1]),
            "final_mean_stress": float(p[-1]), "final_deviator": float(q[-1]),
            "softening": float(q[-1] / q[k]) if q[k] > 0.0 else nan,
            "final_friction_angle": float(c["friction_angle"][-1]),
            "liquefied": liquefied,
            "liquefaction_axial_strain": float(ea[-1]) if liquefied else nan,
            "final_axial_strain": float(ea[-1])}


def _summarize_oedometric(c, rve, confining, increment):
    """K0 (the mean over the second half of the increments, and at the end) and the
    constrained modulus of the last increment."""
    d = rve.dim
    sig_a = -c["stress"][:, d - 1, d - 1]
    half = c["k0"][1:][len(c["k0"][1:]) // 2:]
    ea = c["axial_strain"]
    return {**_test_summary(c, rve, confining),
            "k0": float(half.mean()), "final_k0": float(c["k0"][-1]),
            "final_axial_stress": float(sig_a[-1]),
            "constrained_modulus": float((sig_a[-1] - sig_a[-2]) / (ea[-1] - ea[-2])),
            "final_void_ratio": float(c["void_ratio"][-1])}


def _summarize_isotropic(c, rve, confining, increment):
    """Compression and swelling indices (slopes of e against ln p on the way up and
    down), the initial bulk modulus and the volumetric strain left after unloading."""
    p, e, ev = c["p"], c["void_ratio"], c["volumetric_strain"]
    top = int(np.argmax(p))
    up, down = slice(0, top + 1), slice(top, None)
    return {**_test_summary(c, rve, confining), "p_max": float(p[top]),
            "compression_index": float(-np.polyfit(np.log(p[up]), e[up], 1)[0]),
            "swelling_index": float(-np.polyfit(np.log(p[down]), e[down], 1)[0]),
            "bulk_modulus": float((p[1] - p[0]) / (ev[1] - ev[0])),
            "final_volumetric_strain": float(ev[-1]),
            "final_void_ratio": float(e[-1])}


def _summarize_shear(c, rve, confining, increment):
    """Peak and late (last 20 %) stress ratios tau / sigma_n with their friction
    angles, and the dilation angle at the peak (atan of -d eps_n / d gamma)."""
    g, tau, sn, en = (c["shear_strain"], c["shear_stress"], c["normal_stress"],
                      c["normal_strain"])
    ratio = np.divide(tau, sn, out=np.zeros_like(tau), where=sn > 0.0)
    k = int(np.argmax(ratio))
    near = np.abs(g - g[k]) <= max(0.01, 2.0 * increment) + 1e-12
    late = g >= 0.8 * g[-1] - 1e-12
    slope = np.polyfit(g[near], en[near], 1)[0] if near.sum() > 1 else float("nan")
    late_ratio = float(ratio[late].mean())
    return {**_test_summary(c, rve, confining),
            "peak_stress_ratio": float(ratio[k]), "peak_shear_strain": float(g[k]),
            "peak_friction_angle": float(np.degrees(np.arctan(ratio[k]))),
            "dilation_angle": float(np.degrees(np.arctan(-slope))),
            "critical_stress_ratio": late_ratio,
            "critical_friction_angle": float(np.degrees(np.arctan(late_ratio))),
            "final_normal_strain": float(en[-1]),
            "final_void_ratio": float(c["void_ratio"][-1])}


def _summarize_cyclic(c, rve, confining, increment):
    """Excess pore pressure ratios r_u = du / sigma'_0 and the cycles to liquefaction
    (p' below 1 % of the start, or the packing apart; NaN if it held)."""
    p, u, amp = c["p"], c["excess_pore_pressure"], c.pop("amplitude")
    per_cycle = 4 * math.ceil(amp / increment - 1e-9)
    liquefied = bool(p[-1] < 0.01 * p[0])
    done = (len(p) - 1) / per_cycle
    return {**_test_summary(c, rve, confining),
            "strain_amplitude": float(amp), "strain_increment": float(increment),
            "cycles_run": float(done),
            "liquefied": liquefied,
            "cycles_to_liquefaction": float(done) if liquefied else float("nan"),
            "max_pore_pressure_ratio": float(u.max() / confining),
            "final_pore_pressure_ratio": float(u[-1] / confining),
            "final_mean_stress": float(p[-1])}


#: the summary of each ``[test] kind``
_SUMMARIES = {"drained": _summarize, "undrained": _summarize_undrained,
              "oedometric": _summarize_oedometric, "isotropic": _summarize_isotropic,
              "simple_shear": _summarize_shear, "cyclic": _summarize_cyclic}


# ------------------------------------------------------------------ the printed report
def report(path, summary, files, final_axial_strain):
    """The lines ``hmm rve`` prints for a test of ``path`` ended with ``summary``
    (:func:`summarize`'s, with the test's ``kind``, ``dim`` and wall time), its output
    ``files`` and the last axial strain of its curves."""
    s = summary
    head = f"hmm rve {path}: "
    tail = (f"  wall time                {s['wall_time']:.3g} s\n"
            f"  output                   {', '.join(str(p) for p in files)}")
    lines = _REPORTS.get(s["kind"])
    if lines is None:  # a drained test
        return head + _drained_lines(s, final_axial_strain) + tail
    return head + lines(s) + tail


def _test_name(s):
    return "biaxial" if s["dim"] == 2 else "triaxial"


def _undrained_lines(s):
    pt = s["phase_transformation_mean_stress"]
    return (f"undrained {_test_name(s)} test (constant volume), "
            f"{s['n_particles']} {s['particles']}, from {s['confining']:.4g} Pa\n"
            f"  initial void ratio       {s['initial_void_ratio']:.4f}\n"
            f"  peak deviator            {s['peak_deviator']:.4g} Pa at axial strain "
            f"{100 * s['peak_axial_strain']:.2f} % (p' = {s['peak_mean_stress']:.4g} "
            f"Pa)\n"
            + (f"  phase transformation     p' = {pt:.4g} Pa, q = "
               f"{s['phase_transformation_deviator']:.4g} Pa at axial strain "
               f"{100 * s['phase_transformation_axial_strain']:.2f} %\n"
               if math.isfinite(pt) else
               "  phase transformation     none (the excess pore pressure rises to the "
               "end)\n")
            + f"  excess pore pressure     {s['final_excess_pore_pressure']:.4g} Pa "
            f"at the end (largest {s['max_excess_pore_pressure']:.4g} Pa)\n"
            + (f"  liquefied                at axial strain "
               f"{100 * s['liquefaction_axial_strain']:.2f} % (no effective stress "
               f"left; the test stopped there)\n" if s["liquefied"] else "")
            + f"  q at the end / peak q    {s['softening']:.3f}\n")


def _isotropic_lines(s):
    return (f"isotropic compression to {s['p_max']:.4g} Pa and unloading, "
            f"{s['n_particles']} {s['particles']}\n"
            f"  initial void ratio       {s['initial_void_ratio']:.4f}\n"
            f"  compression index        {s['compression_index']:.4g} (-de/dln p, "
            f"loading)\n"
            f"  swelling index           {s['swelling_index']:.4g} (unloading)\n"
            f"  initial bulk modulus     {s['bulk_modulus']:.4g} Pa\n"
            f"  volumetric strain        {100 * s['final_volumetric_strain']:.4f} % "
            f"left after unloading\n")


def _shear_lines(s):
    return (f"simple shear at {s['confining']:.4g} Pa normal stress, "
            f"{s['n_particles']} {s['particles']}\n"
            f"  initial void ratio       {s['initial_void_ratio']:.4f}\n"
            f"  peak friction angle      {s['peak_friction_angle']:.2f} deg "
            f"(tau/sigma_n = {s['peak_stress_ratio']:.4f} at shear strain "
            f"{100 * s['peak_shear_strain']:.2f} %)\n"
            f"  dilation angle at peak   {s['dilation_angle']:.2f} deg\n"
            f"  late friction angle      {s['critical_friction_angle']:.2f} deg "
            f"(last 20 %)\n")


def _cyclic_lines(s):
    liq = (f"liquefied after {s['cycles_to_liquefaction']:.2f} cycles"
           if s["liquefied"] else f"not liquefied in {s['cycles_run']:.2f} cycles")
    return (f"cyclic undrained {_test_name(s)} test, strain amplitude "
            f"{100 * s['strain_amplitude']:.3g} %, {s['n_particles']} "
            f"{s['particles']}, from {s['confining']:.4g} Pa\n"
            f"  initial void ratio       {s['initial_void_ratio']:.4f}\n"
            f"  pore pressure ratio r_u  {s['final_pore_pressure_ratio']:.3f} at the "
            f"end (largest {s['max_pore_pressure_ratio']:.3f})\n"
            f"  {liq}\n")


def _oedometric_lines(s):
    return (f"oedometric test, {s['n_particles']} {s['particles']}, from "
            f"{s['confining']:.4g} Pa\n"
            f"  initial void ratio       {s['initial_void_ratio']:.4f}\n"
            f"  K0                       {s['k0']:.4f} (second half; "
            f"{s['final_k0']:.4f} at the end)\n"
            f"  axial stress at the end  {s['final_axial_stress']:.4g} Pa\n"
            f"  constrained modulus      {s['constrained_modulus']:.4g} Pa (last "
            f"increment)\n")


def _drained_lines(s, final_axial_strain):
    lo = 0.8 * final_axial_strain
    return (f"drained {_test_name(s)} test, {s['n_particles']} {s['particles']}, "
            f"confining {s['confining']:.4g} Pa\n"
            f"  initial void ratio       {s['initial_void_ratio']:.4f}\n"
            f"  peak friction angle      {s['peak_friction_angle']:.2f} deg "
            f"(q/p = {s['peak_stress_ratio']:.4f} at axial strain "
            f"{100 * s['peak_axial_strain']:.2f} %)\n"
            f"  dilatancy angle at peak  {s['dilatancy_angle']:.2f} deg\n"
            f"  critical friction angle  {s['critical_friction_angle']:.2f} deg "
            f"(mean over axial strain >= {100 * lo:.2f} %)\n"
            f"  volumetric strain        {100 * s['final_volumetric_strain']:.3f} % "
            f"at the end (contraction > 0)\n")


_REPORTS = {"undrained": _undrained_lines, "isotropic": _isotropic_lines,
            "simple_shear": _shear_lines, "cyclic": _cyclic_lines,
            "oedometric": _oedometric_lines}
