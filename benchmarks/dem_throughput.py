"""DEM throughput: particle-steps per second on the shared scene, ours against peers.

The scene is the shared one (``../shared/bench/dem_throughput``, or ``DEM_BENCH_SCENE``):
16,250 spheres settled in a box of walls, linear spring-dashpot contacts with a tangential
history spring and Coulomb friction. Scene "static" is the bed under gravity; "compress"
adds a top wall moving down at 0.25 m/s. Every run does NPRE untimed steps, then NSTEPS
timed ones; the figure is ``N * NSTEPS / wall time of the timed loop``.

Our engine runs each configuration in a fresh process with ``NUMBA_NUM_THREADS`` set to
the thread count. The peers (LAMMPS ``lmp``, LIGGGHTS ``liggghts``, YADE ``yade``) run
the shared input files exactly as the scene's ``run_all.sh`` does, on 1 MPI rank and on
2 ranks (Open MPI ``mpirun``), and are timed by their own "Loop time" of the second run.
Codes are interleaved within each repetition, so machine noise hits all of them alike;
figures are medians over the repetitions.

usage::

    python benchmarks/dem_throughput.py              # run, write results/dem_throughput.json
    python benchmarks/dem_throughput.py --markdown   # print the docs table from the JSON

environment: NSTEPS (2000) NPRE (500) REPS (3) THREADS ("1 2") SCENES ("static compress")
CODES ("dem lammps liggghts yade") DEM_BENCH_SCENE (scene directory).

``BASE=<git revision>`` adds our engine at that revision as one more code, ``dem_base``
(its sources exported into ``benchmarks/work/trees``, run by the same worker), timed
interleaved with the others; the figures are ``ratio_base`` (this checkout's
particle-steps per second over the revision's, one thread) and ``ratio_base_2`` (two),
and the run writes ``results/dem_throughput_base.json`` instead, so that the peers'
record stays. ``BASE=a7808d7 CODES=dem python benchmarks/dem_throughput.py`` measures
the engine against the revision before rolling resistance.
"""

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "dem_throughput.json"
KNOWN_CODES = ("dem", "lammps", "liggghts", "yade")
BINARIES = {"lammps": "lmp", "liggghts": "liggghts", "yade": "yade"}
PEER_TIMEOUT = 3600


# --------------------------------------------------------------------------- our engine
def worker(scene, threads):
    """Run one configuration of our engine in this (fresh) process; print RESULT."""
    import numba

    sdir, why = C.scene_dir()
    if sdir is None:
        raise SystemExit(why)
    nsteps, npre = C.env_int("NSTEPS", 2000), C.env_int("NPRE", 500)
    t0 = time.perf_counter()
    sim, info = C.build_scene(sdir, scene)
    sim.prime()  # compiles the step kernel (or loads it from the cache)
    t1 = time.perf_counter()
    sim.run(npre)
    t2 = time.perf_counter()
    builds0 = sim.neighbors.n_builds
    c0, w0 = time.process_time(), time.perf_counter()
    sim.run(nsteps)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    state = C.scene_state(sim)
    C.emit_result({
        **info, **state, "scene": scene, "threads_requested": int(threads),
        "threads": getattr(sim, "threads", numba.get_num_threads()),
        "threading_layer": numba.threading_layer(),
        "nsteps": nsteps, "npre": npre, "wall_s": wall, "cpu_s": cpu,
        "pps": info["N"] * nsteps / wall, "setup_s": t1 - t0, "pre_s": t2 - t1,
        "neighbor_builds": sim.neighbors.n_builds - builds0})


def run_dem(scene, threads, tree=None):
    r = C.run_worker(Path(__file__), [scene, threads], threads, tree=tree)
    if r.get("ok"):  # per thread, as LAMMPS reports it per rank: 100 = cores fully used
        r["cpu_percent"] = 100.0 * r["cpu_s"] / r["wall_s"] / threads
    return r


# --------------------------------------------------------------------------- peers
def find_openmpi_mpirun():
    """``(path, version)`` of an Open MPI ``mpirun`` on PATH, or ``(None, reason)``.

    The venv's MPICH ``mpirun`` (first on PATH in an activated venv) cannot launch the
    Debian peers, which are built against Open MPI.
    """
    seen = set()
    for d in os.environ.get("PATH", "").split(os.pathsep):
        p = Path(d or ".") / "mpirun"
        if not (p.is_file() and os.access(p, os.X_OK)) or p.resolve() in seen:
            continue
        seen.add(p.resolve())
        try:
            v = subprocess.run([str(p), "--version"], capture_output=True, text=True,
                               timeout=30, stdin=subprocess.DEVNULL)
        except (OSError, subprocess.SubprocessError):
            continue
        text = v.stdout + v.stderr
        if "Open MPI" in text:
            return str(p), text.strip().splitlines()[0]
    return None, "no Open MPI mpirun on PATH (a venv's MPICH mpirun cannot launch the Debian peers)"


def peer_command(code, scene, par, sdir, nsteps, npre, binary, mpirun):
    """Command line and extra environment of one peer run (as in ``run_all.sh``)."""
    common = ["-var", "nsteps", str(nsteps), "-var", "npre", str(npre), "-log", "none",
              "-var", "scene", scene]
    if code == "lammps":
        cmd = [binary, "-in", str(sdir / "lammps" / "in.bench"),
               "-var", "data", str(sdir / "packing.data"), *common]
    elif code == "liggghts":
        cmd = [binary, "-in", str(sdir / "liggghts" / "in.bench"),
               "-var", "data", str(sdir / "packing.data"),
               "-var", "incdir", str(sdir / "liggghts"),
               "-var", "stl", str(sdir / "liggghts" / "top.stl"), *common]
    else:  # yade: threads, not ranks
        env = {"SCENE": scene, "NSTEPS": str(nsteps), "NPRE": str(npre),
               "PACKING": str(sdir / "packing.txt")}
        return [binary, "-n", "-x", f"-j{par}", str(sdir / "yade" / "bench.py")], env
    if par > 1:
        cmd = [mpirun, "--allow-run-as-root", "-np", str(par), *cmd]
    return cmd, {}


def parse_peer(code, text):
    """Loop wall time, steps, N, Z and KE at the end, from a peer's output."""
    if code in ("lammps", "liggghts"):
        loops = re.findall(r"Loop time of (\S+) on (\d+) procs for (\d+) steps with (\d+) atoms",
                           text)
        if len(loops) < 2:
            return None
        wall, procs, steps, n = loops[-1]
        thermo = [ln.split() for ln in text.splitlines()
                  if re.match(r"^\s+\d+\s+\S+\s+\d+\s+\S+\s+\S+\s+\S+\s+\S+\s*$", ln)]
        out = {"wall_s": float(wall), "procs": int(procs), "nsteps": int(steps),
               "N": int(n), "ke": float(thermo[-1][3]) if thermo else None,
               "Z": float(thermo[-1][4]) if thermo else None,
               "zmax": float(thermo[-1][5]) if thermo else None}
        cpu = re.findall(r"(\S+)% CPU use", text)
        if cpu:
            out["cpu_percent"] = float(cpu[-1])
        builds = re.findall(r"Neighbor list builds = (\d+)", text)
        if builds:
            out["neighbor_builds"] = int(builds[-1])
        head = text.lstrip().splitlines()[0] if text.strip() else ""
        out["version"] = head.strip()
        return out
    m = re.search(r"RESULT .*N=(\d+) steps=(\d+) wall_s=(\S+) cpu_s=(\S+) Z_start=(\S+) "
                  r"Z_end=(\S+)", text)
    if not m:
        return None
    post = re.search(r"POST step \d+ ke (\S+)", text)
    wall = float(m.group(3))
    return {"wall_s": wall, "nsteps": int(m.group(2)), "N": int(m.group(1)),
            "Z": float(m.group(6)), "ke": float(post.group(1)) if post else None,
            "cpu_percent": 100.0 * float(m.group(4)) / wall}


def run_peer(code, scene, par, sdir, nsteps, npre, binary, mpirun, tag):
    cmd, extra = peer_command(code, scene, par, sdir, nsteps, npre, binary, mpirun)
    env = dict(os.environ, OMP_NUM_THREADS="1", **extra)
    logs = C.WORK / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, env=env, cwd=C.WORK, stdin=subprocess.DEVNULL,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                           errors="replace", timeout=PEER_TIMEOUT)
        text, rc = p.stdout, p.returncode
    except subprocess.TimeoutExpired as e:
        out = e.stdout or ""
        text = out.decode(errors="replace") if isinstance(out, bytes) else out
        rc = f"timeout after {PEER_TIMEOUT} s"
    elapsed = time.perf_counter() - t0
    (logs / f"{tag}.out").write_text(text)
    r = parse_peer(code, text)
    if r is None:
        tail = " | ".join(text.strip().splitlines()[-5:])
        return {"ok": False, "error": f"rc={rc}: no loop time found: {tail}",
                "log": C.display_path(logs / f"{tag}.out")}
    if code == "yade" and "cpu_percent" in r:  # YADE's is summed over its threads
        r["cpu_percent"] /= par
    r.update(ok=True, rc=rc, process_elapsed_s=elapsed, pps=r["N"] * r["nsteps"] / r["wall_s"],
             log=C.display_path(logs / f"{tag}.out"))
    return r


def _yade_version(binary):
    try:
        v = subprocess.run([binary, "--version"], capture_output=True, text=True, timeout=60,
                           stdin=subprocess.DEVNULL)
    except (OSError, subprocess.SubprocessError):
        return None
    lines = (v.stdout + v.stderr).strip().splitlines()
    return lines[0].strip() if lines else None


# --------------------------------------------------------------------------- driver
def aggregate(runs, scenes, codes, pars):
    results, per_scene = {}, {}
    for scene in scenes:
        results[scene] = {}
        for code in codes:
            for p in pars.get(code, []):
                rs = [r for r in runs if r["scene"] == scene and r["code"] == code
                      and r["par"] == p]
                ok = [r for r in rs if r.get("ok")]
                if not rs:
                    continue
                results[scene].setdefault(code, {})[str(p)] = {
                    "parallelism": ("threads" if code in ("dem", "dem_base", "yade")
                                    else "MPI ranks"),
                    "pps": [r["pps"] for r in ok], "wall_s": [r["wall_s"] for r in ok],
                    "median_pps": C.median(r["pps"] for r in ok),
                    "median_wall_s": C.median(r["wall_s"] for r in ok),
                    "Z": C.median(r.get("Z") for r in ok),
                    "ke": C.median(r.get("ke") for r in ok),
                    "cpu_percent": C.median(r.get("cpu_percent") for r in ok),
                    "n_ok": len(ok), "n_failed": len(rs) - len(ok)}

        def med(code, p, scene=scene):
            return results[scene].get(code, {}).get(str(p), {}).get("median_pps")

        per_scene[scene] = {
            "ratio_lammps": C.ratio(med("dem", 1), med("lammps", 1)),
            "ratio_liggghts": C.ratio(med("dem", 1), med("liggghts", 1)),
            "ratio_yade": C.ratio(med("dem", 1), med("yade", 1)),
            "ratio_lammps_2": C.ratio(med("dem", 2), med("lammps", 2)),
            "ratio_liggghts_2": C.ratio(med("dem", 2), med("liggghts", 2)),
            "speedup_2_threads": C.ratio(med("dem", 2), med("dem", 1)),
            "speedup_lammps_2_ranks": C.ratio(med("lammps", 2), med("lammps", 1)),
            "speedup_liggghts_2_ranks": C.ratio(med("liggghts", 2), med("liggghts", 1)),
            "ratio_base": C.ratio(med("dem", 1), med("dem_base", 1)),
            "ratio_base_2": C.ratio(med("dem", 2), med("dem_base", 2)),
        }
    return results, per_scene


def print_table(data):
    print()
    hdr = f"{'scene':9} {'code':9} {'parallelism':15} {'runs':>4} {'median p-steps/s':>17} " \
          f"{'loop wall per run [s]':24} {'CPU %':>6} {'Z end':>7} {'KE end [J]':>11}"
    print(hdr)
    print("-" * len(hdr))
    for scene, codes in data["results"].items():
        for code, pars in codes.items():
            for p, r in pars.items():
                walls = ", ".join(f"{w:.2f}" for w in r["wall_s"])
                mp = f"{r['median_pps']:.4g}" if r["median_pps"] else "failed"
                z = f"{r['Z']:.3f}" if r["Z"] is not None else "-"
                ke = f"{r['ke']:.4g}" if r["ke"] is not None else "-"
                cpu = f"{r['cpu_percent']:.0f}" if r["cpu_percent"] is not None else "-"
                print(f"{scene:9} {code:9} {C._par_label(code, p):15} {r['n_ok']:>4} {mp:>17} "
                      f"{walls:24} {cpu:>6} {z:>7} {ke:>11}")
    print()
    for scene, r in data["per_scene"].items():
        parts = [f"{k} = {v:.3f}" for k, v in r.items() if v is not None]
        print(f"{scene}: " + ", ".join(parts))
    for s in data["skipped"]:
        print(f"skipped {s.get('code', 'all')}: {s['reason']}")
    busy = [r for r in data["runs"] if r.get("ok") and r.get("cpu_percent") is not None
            and r["cpu_percent"] < 90.0]
    if busy:
        print(f"warning: {len(busy)} of {len(data['runs'])} runs got less than 90% of their "
              f"cores (machine busy?): timings are noisy")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worker", nargs=2, metavar=("SCENE", "THREADS"), help=argparse.SUPPRESS)
    ap.add_argument("--markdown", nargs="?", const=str(OUT), metavar="JSON",
                    help="print the results table of JSON (default results/dem_throughput.json)")
    args = ap.parse_args(argv)
    if args.worker:
        worker(args.worker[0], int(args.worker[1]))
        return 0
    if args.markdown:
        print(C.throughput_markdown(json.loads(Path(args.markdown).read_text())))
        return 0

    sdir, why = C.scene_dir()
    base = {"benchmark": "dem_throughput", "date": C.now(), "machine": C.machine_info()}
    if sdir is None:
        print(f"dem_throughput: skipped: {why}")
        C.write_json(OUT, {"benchmark": "dem_throughput", "status": "skipped",
                           "skipped": [{"code": "all", "reason": why}], **base})
        return 0

    nsteps, npre, reps = C.env_int("NSTEPS", 2000), C.env_int("NPRE", 500), C.env_int("REPS", 3)
    threads = [int(t) for t in C.env_list("THREADS", "1 2")]
    scenes = C.env_list("SCENES", "static compress")
    codes = C.env_list("CODES", " ".join(KNOWN_CODES))
    bad = [c for c in codes if c not in KNOWN_CODES] + [
        s for s in scenes if s not in ("static", "compress")]
    if bad:
        print(f"dem_throughput: unknown code or scene {bad}", file=sys.stderr)
        return 2
    P = C.load_params(sdir)
    skipped, binaries, pars = [], {}, {}
    out = OUT
    base_rev = os.environ.get("BASE", "").strip()
    tree = None
    if base_rev:  # our engine at another revision: one more code, its own JSON
        tree = C.source_tree(base_rev)
        codes = [*codes, "dem_base"]
        pars["dem_base"] = threads
        out = C.RESULTS / "dem_throughput_base.json"
    mpirun, mpirun_version, yade_version = None, None, None
    if any(c in ("lammps", "liggghts") for c in codes) and max(threads) > 1:
        mpirun, mpirun_version = find_openmpi_mpirun()
        if mpirun is None:
            skipped.append({"code": "lammps/liggghts", "reason": f"> 1 rank: {mpirun_version}"})
            mpirun_version = None
    for code in codes:
        if code in ("dem", "dem_base"):
            pars[code] = threads
            continue
        binary = shutil.which(BINARIES[code])
        if binary is None:
            skipped.append({"code": code, "reason": f"'{BINARIES[code]}' not installed "
                            f"(Debian package {code}; apt-get install {code})"})
            continue
        binaries[code] = binary
        if code == "yade":
            yade_version = _yade_version(binary)
        pars[code] = [p for p in threads if p == 1 or code == "yade" or mpirun]
    active = [c for c in codes if c in pars]
    usable = base["machine"]["usable_cpus"] or 1
    if max(threads) > usable:
        print(f"warning: {max(threads)} threads/ranks on {usable} usable CPUs (oversubscribed)")

    data = {**base, "status": "partial", "scene_dir": C.display_path(sdir),
            "config": {"N": None, "nsteps": nsteps, "npre": npre, "reps": reps,
                       "threads": threads, "scenes": scenes, "codes": codes,
                       "dt": P["DT"], "skin": P["SKIN"], "kn": P["KN"], "kt": P["KT"],
                       "mu": P["MU"], "e_rest": P["E_REST"], "gamma_n": P["GAMMA_N"],
                       "v_top": P["V_TOP"]},
            "versions": {"ours": C.our_versions(), "mpirun": mpirun_version,
                         **({"base": base_rev} if base_rev else {}),
                         **({"yade": yade_version} if yade_version else {})},
            "skipped": skipped, "runs": []}
    for s in skipped:
        print(f"skipped {s['code']}: {s['reason']}")
    runs = data["runs"]
    for rep in range(1, reps + 1):
        for scene in scenes:
            for code in active:
                for p in pars[code]:
                    tag = f"{code}_{p}_{scene}_r{rep}"
                    load = C.loadavg()
                    if code in ("dem", "dem_base"):
                        r = run_dem(scene, p, tree if code == "dem_base" else None)
                    else:
                        r = run_peer(code, scene, p, sdir, nsteps, npre, binaries[code],
                                     mpirun, tag)
                        if r.get("version"):
                            data["versions"][code] = r.pop("version")
                    r.update(code=code, scene=scene, par=p, rep=rep, loadavg_before=load)
                    runs.append(r)
                    if r.get("ok"):
                        data["config"]["N"] = data["config"]["N"] or r.get("N")
                        print(f"rep {rep} {scene:8} {code:8} {C._par_label(code, p):15} "
                              f"{r['pps']:.4g} particle-steps/s  wall {r['wall_s']:.2f} s  "
                              f"Z {r.get('Z') or float('nan'):.3f}  "
                              f"KE {r.get('ke') or float('nan'):.4g}"
                              f"  load {load[0] if load else '?'}", flush=True)
                    else:
                        print(f"rep {rep} {scene:8} {code:8} {C._par_label(code, p):15} "
                              f"FAILED: {r['error']}", flush=True)
                    C.write_json(out, data)

    results, per_scene = aggregate(runs, scenes, active, pars)
    static = per_scene.get("static", {})
    data.update(status="ok", results=results, per_scene=per_scene,
                ratio_lammps=static.get("ratio_lammps"),
                ratio_liggghts=static.get("ratio_liggghts"),
                speedup_2_threads=static.get("speedup_2_threads"),
                loadavg_after=C.loadavg())
    if base_rev:
        data.update(ratio_base=static.get("ratio_base"),
                    ratio_base_2=static.get("ratio_base_2"))
    # keep the headline numbers near the top of the file
    order = ["benchmark", "status", "date", "ratio_lammps", "ratio_liggghts",
             "speedup_2_threads", "ratio_base", "ratio_base_2", "per_scene", "results",
             "skipped", "config", "versions", "machine", "scene_dir", "loadavg_after",
             "runs"]
    data = {k: data[k] for k in order if k in data}
    C.write_json(out, data)
    print_table(data)
    print(f"\nwrote {C.display_path(out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
