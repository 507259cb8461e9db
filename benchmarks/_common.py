"""Helpers shared by the benchmark scripts.

Locating the shared scene, building it for our engine, running a worker in a fresh
process, medians, machine and version information, JSON writing and the markdown
tables that ``docs/performance.md`` shows. Nothing here imports ``dem`` (or numba) at
module level: the driver processes stay light, and only the workers compile kernels.
"""

import datetime
import importlib.metadata
import json
import math
import os
import platform
import re
import runpy
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "benchmarks" / "results"
WORK = REPO / "benchmarks" / "work"  # scratch (git-ignored): peer logs, cwd of peer runs

#: where the shared DEM throughput scene lives unless ``DEM_BENCH_SCENE`` says otherwise
DEFAULT_SCENE = REPO.parent / "shared" / "bench" / "dem_throughput"

GRAVITY = (0.0, 0.0, -9.81)


# --------------------------------------------------------------------------- environment
def env_int(name, default):
    """Integer from the environment variable ``name`` (``default`` when unset or empty)."""
    v = os.environ.get(name, "").strip()
    return int(v) if v else int(default)


def env_list(name, default):
    """Whitespace- or comma-separated list from the environment (``default``: a string)."""
    v = os.environ.get(name, "").strip() or default
    return [x for x in re.split(r"[\s,]+", v) if x]


def worker_env(threads):
    """Environment for a worker process running our engine on ``threads`` threads."""
    env = dict(os.environ)
    env["NUMBA_NUM_THREADS"] = str(int(threads))
    env["OMP_NUM_THREADS"] = str(int(threads))
    env.setdefault("NUMBA_THREADING_LAYER", "omp")  # as the Makefile: never TBB
    env.setdefault("NUMBA_CACHE_DIR", str(REPO / ".numba_cache"))
    env.setdefault("MPLBACKEND", "Agg")
    return env


def run_worker(script, args, threads, timeout=3600, tree=None):
    """Run ``python script --worker *args`` in a fresh process; return its RESULT dict.

    The worker prints one line ``RESULT {json}``. On failure the dict has ``ok: False``
    and the tail of the worker's stderr under ``error``. ``tree``: a source tree (see
    :func:`source_tree`) whose packages the worker imports instead of this checkout's.
    """
    cmd = [sys.executable, str(script), "--worker", *[str(a) for a in args]]
    env = worker_env(threads)
    if tree is not None:
        env["PYTHONPATH"] = str(tree) + os.pathsep + env.get("PYTHONPATH", "")
    try:
        p = subprocess.run(cmd, env=env, cwd=REPO, capture_output=True,
                           text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"ok": False, "error": f"timed out after {timeout} s"}
    for line in p.stdout.splitlines():
        if line.startswith("RESULT "):
            out = json.loads(line[len("RESULT "):])
            out["ok"] = True
            return out
    tail = (p.stderr or p.stdout or "").strip().splitlines()[-8:]
    return {"ok": False, "error": f"rc={p.returncode}: " + " | ".join(tail)}


def worker_command(script, args, procs=1):
    """The command of ``python script --worker *args``; on ``procs`` > 1 ranks under
    the venv's ``mpiexec``, through ``python -m mpi4py`` (a rank's exception ends the
    job instead of hanging it). For :func:`run_result`."""
    cmd = [sys.executable, str(Path(script).resolve()), "--worker", *[str(a) for a in args]]
    if procs > 1:
        cmd = [str(Path(sys.executable).parent / "mpiexec"), "-n", str(procs),
               sys.executable, "-m", "mpi4py"] + cmd[1:]
    return cmd


def launch(script, args, procs=1, timeout=3600):
    """Run ``script``'s worker of ``args`` on ``procs`` ranks (one thread each,
    :func:`worker_command`); its result with the load average at the start, or
    RuntimeError naming the worker and why it failed."""
    load = loadavg()
    r = run_result(worker_command(script, args, procs), worker_env(1), REPO, timeout)
    if not r.get("ok"):
        raise RuntimeError(f"{' '.join(map(str, args))} failed: {r['error']}")
    r.pop("ok")
    return dict(r, loadavg=load)


def run_result(cmd, env, cwd, timeout=3600):
    """Run ``cmd``; the dict of its ``RESULT {json}`` line, or ``ok: False`` with why."""
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, env=env, cwd=cwd, stdin=subprocess.DEVNULL,
                           capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        return {"ok": False, "error": f"timed out after {timeout} s"}
    for line in p.stdout.splitlines():
        if line.startswith("RESULT "):
            out = json.loads(line[len("RESULT "):])
            out.update(ok=True, process_time=time.perf_counter() - t0)
            return out
    tail = (p.stderr or p.stdout or "").strip().splitlines()[-8:]
    return {"ok": False, "error": f"rc={p.returncode}: " + " | ".join(tail)}


def source_tree(revision):
    """The sources of git ``revision`` of this repository, exported once into
    ``WORK/trees/<revision>`` (``git archive``): a tree to run a worker on."""
    tree = WORK / "trees" / revision
    if not (tree / "dem" / "__init__.py").exists():
        tree.mkdir(parents=True, exist_ok=True)
        archive = subprocess.run(["git", "archive", revision], cwd=REPO, check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(tree)], input=archive, check=True)
    return tree


def emit_result(result):
    """Print a worker's result as the one line :func:`run_worker` parses."""
    print("RESULT " + json.dumps(result), flush=True)


def entry(main, worker):
    """A benchmark script's ``__main__``: ``worker(args)`` when started by
    :func:`run_worker` (``--worker args...``), else ``main()``; one numba thread
    unless the environment says otherwise."""
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        worker(sys.argv[2:])
    else:
        main()


# --------------------------------------------------------------------------- the shared scene
def scene_dir():
    """``(path, reason)``: the shared scene directory, or ``(None, why it is unusable)``."""
    d = Path(os.environ.get("DEM_BENCH_SCENE") or DEFAULT_SCENE).expanduser()
    if not d.is_dir():
        return None, f"scene directory {d} not found (set DEM_BENCH_SCENE=<dir>)"
    for name in ("packing.txt", "params.py"):
        if not (d / name).is_file():
            return None, f"{d / name} not found (set DEM_BENCH_SCENE=<dir>)"
    return d, ""


def display_path(p):
    """``p`` relative to the repository root (keeps machine paths out of the JSON)."""
    p = Path(p).resolve()
    try:
        return os.path.relpath(p, REPO)
    except ValueError:
        return str(p)


def load_params(sdir):
    """The scene parameters (``params.py`` of the scene directory) as a dict of floats."""
    g = runpy.run_path(str(Path(sdir) / "params.py"))
    return {k: v for k, v in g.items() if k.isupper() and isinstance(v, (int, float))}


def load_packing(sdir):
    """``(pos (n, 3), radius (n,))`` [m] from ``packing.txt`` (x y z r per line)."""
    import numpy as np

    data = np.loadtxt(Path(sdir) / "packing.txt", comments="#", ndmin=2)
    return np.ascontiguousarray(data[:, :3]), np.ascontiguousarray(data[:, 3])


def build_scene(sdir, scene, dt=None, dt_factor=None):
    """Our engine on the shared scene, with the physics of ``lammps/in.bench``.

    Parameters
    ----------
    sdir : path of the scene directory
    scene : {"static", "compress"}
    dt : float, optional
        Time step [s]; default the scene's ``DT`` (0.1 x the contact duration).
    dt_factor : float, optional
        Time step as a fraction of the engine's critical step (overrides ``dt``).

    Returns
    -------
    sim : dem.Simulation
    info : dict (N, ztop0 [m], dt [s], dt / dt_crit)
    """
    import dem

    if scene not in ("static", "compress"):
        raise ValueError(f"scene must be 'static' or 'compress', got {scene!r}")
    P = load_params(sdir)
    pos, radius = load_packing(sdir)
    n = pos.shape[0]
    bodies = dem.Bodies.spheres(pos, radius=radius, density=P["RHO"])
    # spatial order in memory, as LAMMPS and LIGGGHTS sort their atoms by default
    bodies.sort_spatially()
    lx, ly = P["LX"], P["LY"]
    bodies.add_plane([0.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    bodies.add_plane([lx, 0.0, 0.0], [-1.0, 0.0, 0.0])
    bodies.add_plane([0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    bodies.add_plane([0.0, ly, 0.0], [0.0, -1.0, 0.0])
    bodies.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    ztop0 = float((pos[:, 2] + radius).max())  # top of the bed: max z + R (1.15512 m)
    if scene == "compress":
        bodies.add_plane([0.0, 0.0, ztop0], [0.0, 0.0, -1.0], velocity=[0.0, 0.0, -P["V_TOP"]])
    # sphere-sphere: damping ratio from e (= LAMMPS' m_eff * gamma_n with m_eff = m/2);
    # sphere-wall: LAMMPS' wall m_eff is m, so a fixed dashpot m * gamma_n
    pp = dem.LinearSpring(kn=P["KN"], kt=P["KT"], mu=P["MU"], restitution=P["E_REST"])
    pw = dem.LinearSpring(kn=P["KN"], kt=P["KT"], mu=P["MU"], gamma_n=P["MASS"] * P["GAMMA_N"])
    model = dem.ContactModel(pp, wall_law=pw)
    if dt_factor is not None:
        dt = float(dt_factor) * dem.critical_time_step(bodies, model)[0]
    elif dt is None:
        dt = P["DT"]
    sim = dem.Simulation(bodies, model, dt=dt, gravity=list(GRAVITY), skin=P["SKIN"],
                         allow_unstable_dt=dt_factor is not None and dt_factor >= 1.0)
    info = {"N": int(n), "ztop0": ztop0, "dt": float(sim.dt),
            "dt_over_dt_crit": float(sim.dt / sim.dt_crit)}
    return sim, info


def scene_state(sim):
    """Z (sphere-sphere contacts per sphere, both ends counted), KE, max z of the spheres."""
    import dem
    import numpy as np

    b = sim.bodies
    sph = ~b.is_fixed
    c = sim.contacts()
    n_pp = int(np.count_nonzero(~c["is_wall"]))
    n_pw = int(np.count_nonzero(c["is_wall"]))
    ke_t, ke_r = dem.kinetic_energy(b)
    return {"Z": 2.0 * n_pp / int(sph.sum()), "wall_contacts": n_pw, "ke": ke_t,
            "ke_rot": ke_r, "zmax": float(b.pos[sph, 2].max())}


# --------------------------------------------------------------------------- statistics, I/O
def median(xs):
    """Median of the finite values of ``xs`` (None when there are none)."""
    v = [float(x) for x in xs if x is not None and math.isfinite(float(x))]
    return statistics.median(v) if v else None


def time_rve_calls(rve, snap, deps, reps, **call):
    """``reps`` Gauss-point calls ``rve.apply_strain(deps, tangent=True, **call)``, each
    from the state ``snap`` (restored before it), after one warm-up: their wall times
    [s] and the median of their DEM steps. The RVE is left at ``snap``."""
    import time

    times, steps = [], []
    for _ in range(reps + 1):
        rve.restore(snap)
        s0 = rve.sim.step
        t0 = time.perf_counter()
        rve.apply_strain(deps, tangent=True, **call)
        times.append(time.perf_counter() - t0)
        steps.append(rve.sim.step - s0)
    rve.restore(snap)
    return times[1:], median(steps[1:])


def ratio(a, b):
    return a / b if a is not None and b else None


def loadavg():
    """The 1-, 5- and 15-minute load averages (None where unavailable)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def write_json(path, data):
    """Write ``data`` as indented JSON, atomically (temporary file, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=False) + "\n")
    os.replace(tmp, path)


def now():
    return datetime.datetime.now().astimezone().isoformat(timespec="seconds")


def _cpu_model():
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _mem_gib():
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal"):
                return round(int(line.split()[1]) / 2**20, 1)
    except OSError:
        pass
    return None


def machine_info():
    """CPU, core counts, memory, OS and load of this machine."""
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    return {"cpu": _cpu_model(), "cpu_count": os.cpu_count(), "usable_cpus": usable,
            "mem_gib": _mem_gib(), "os": platform.platform(), "loadavg": loadavg()}


def _version(dist):
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


def git_revision():
    """Short commit of the repository, with ``+dirty`` when the tree has changes."""
    git = shutil.which("git")
    if not git:
        return None
    try:
        rev = subprocess.run([git, "rev-parse", "--short", "HEAD"], cwd=REPO,
                             capture_output=True, text=True, timeout=10).stdout.strip()
        dirty = subprocess.run([git, "status", "--porcelain", "--untracked-files=no"],
                               cwd=REPO, capture_output=True, text=True, timeout=10).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    return (rev + ("+dirty" if dirty.strip() else "")) or None


def our_versions():
    """Versions of our engine's stack (no import of numba needed)."""
    return {"dem": _version("femxdem"), "git": git_revision(),
            "python": platform.python_version(), "numpy": _version("numpy"),
            "numba": _version("numba")}


# --------------------------------------------------------------------------- markdown
def _fmt(x, spec):
    return "to be measured" if x is None else format(x, spec)


def _par_label(code, p):
    p = int(p)
    if code in ("dem", "dem_base"):
        return f"{p} thread" + ("s" if p > 1 else "")
    if code == "yade":
        return f"{p} thread" + ("s" if p > 1 else "") + f" (-j{p})"
    return f"{p} MPI rank" + ("s" if p > 1 else "")


def throughput_markdown(data):
    """Markdown tables of a ``dem_throughput.json`` (the docs' results table)."""
    lines = []
    cfg = data.get("config", {})
    if data.get("status") == "skipped":
        return "Throughput benchmark skipped: " + "; ".join(
            s["reason"] for s in data.get("skipped", []))
    lines.append(f"N = {cfg.get('N')} spheres, {cfg.get('nsteps')} timed steps after "
                 f"{cfg.get('npre')} untimed, {cfg.get('reps')} repetitions (median); "
                 f"{data.get('date', '')}; {data.get('machine', {}).get('cpu', '')}.")
    lines.append("")
    lines.append("| scene | code | parallelism | runs | median particle-steps/s | "
                 "loop wall per run [s] | CPU % | Z (end) | KE (end) [J] | "
                 "ours (same count) / this |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|")
    for scene, codes in data.get("results", {}).items():
        ours = codes.get("dem", {})
        for code, pars in codes.items():
            for p, r in pars.items():
                walls = ", ".join(f"{w:.2f}" for w in r.get("wall_s", []))
                rel = "" if code == "dem" else _fmt(
                    ratio(ours.get(p, {}).get("median_pps"), r.get("median_pps")), ".2f")
                cpu = r.get("cpu_percent")
                lines.append(
                    f"| {scene} | {code} | {_par_label(code, p)} | {len(r.get('wall_s', []))} "
                    f"| {_fmt(r.get('median_pps'), '.3g')} | {walls} | "
                    f"{'' if cpu is None else format(cpu, '.0f')} | "
                    f"{_fmt(r.get('Z'), '.3f')} | {_fmt(r.get('ke'), '.3g')} | {rel} |")
    lines.append("")
    lines.append("| scene | ours 1 thread / LAMMPS 1 rank | ours 1 thread / LIGGGHTS 1 rank | "
                 "ours 2 threads / ours 1 thread |")
    lines.append("|---|---|---|---|")
    for scene, r in data.get("per_scene", {}).items():
        lines.append(f"| {scene} | {_fmt(r.get('ratio_lammps'), '.2f')} | "
                     f"{_fmt(r.get('ratio_liggghts'), '.2f')} | "
                     f"{_fmt(r.get('speedup_2_threads'), '.2f')} |")
    if data.get("skipped"):
        lines.append("")
        lines.append("Skipped: " + "; ".join(f"{s.get('code', 'all')}: {s['reason']}"
                                               for s in data["skipped"]) + ".")
    return "\n".join(lines)


def _cost(c):
    if c is None:
        return ""
    if c.get("wall_per_sim_s") is None:
        return "to be measured"
    return f"{c['wall_per_sim_s']:.3g} ({c.get('cpu_per_sim_s') or float('nan'):.3g})"


def dt_markdown(data):
    """Markdown table of a ``dt_speed_accuracy.json``."""
    cost = {round(c["dt_factor"], 6): c for c in data.get("cost", [])}
    lines = ["Relative errors of a head-on binary collision: worst over the entry phases "
             "(phase-averaged in brackets).", "",
             "| dt / dt_crit | steps per contact | contact duration (elastic) | "
             "restitution (e = 0.5) | energy (elastic) | wall (CPU) s per simulated s, 1 thread |",
             "|---|---|---|---|---|---|"]
    for r in data.get("accuracy", []):
        c = cost.get(round(r["dt_factor"], 6))
        lines.append(
            f"| {r['dt_factor']:.3g} | {r['steps_per_contact']:.1f} | "
            f"{r['err_duration']:.1e} ({r['bias_duration']:.1e}) | "
            f"{r['err_restitution']:.1e} ({r['bias_restitution']:.1e}) | "
            f"{r['err_energy']:.1e} ({r['bias_energy']:.1e}) | "
            f"{_cost(c)} |")
    tol = data.get("tolerance", 0.01)
    lines.append("")
    lines.append(
        f"Largest factor with every error below {tol:.0%}: "
        f"{_fmt(data.get('recommended_dt_factor'), '.3g')} (worst phase), "
        f"{_fmt(data.get('recommended_dt_factor_phase_mean'), '.3g')} (phase-averaged). "
        f"Engine default DT_FACTOR = {data.get('dt_factor_default')}: "
        f"{'supported' if data.get('default_supported') else 'not supported'} on worst-phase "
        f"errors, {'supported' if data.get('default_supported_phase_mean') else 'not supported'}"
        f" on phase-averaged errors.")
    return "\n".join(lines)
