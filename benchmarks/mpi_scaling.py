"""MPI scaling of the multiscale solver: the demo problem on 1 and 2 ranks, and a cost
model for large runs.

Timed runs: ``hmm demo`` (32 Gauss points, each a periodic RVE of 60 disks) as its own
process, once per rank count per repetition, rank counts interleaved so that machine
noise hits both alike; ``NUMBA_NUM_THREADS=1`` per rank. The figure is the solve time the
run reports (set-up and output excluded, both are serial), median over repetitions;
``efficiency_2_ranks = T1 / (2 T2)``. The results must be bit for bit equal: the script
checks it on the displacement field.

Cost model (measured in the same run, on rank 0): per Newton iteration the farm sends
one broadcast command, a ``Scatterv`` of ``n_gp d^2`` doubles and ``Gatherv``s of
``n_gp (d^2 + d^4 + 2)`` doubles, i.e. ``8 n_gp (2 d^2 + d^4 + 2)`` bytes; rank 0
also assembles ``K`` and ``r`` and solves. With ``t_gp`` the mean cost of one Gauss
point's trial, ``t_asm(n_gp)`` rank 0's assembly and solve time, and ``P`` ranks, one
iteration takes about ``n_gp t_gp / P + t_asm + t_msg``: rank 0 becomes the bottleneck
when ``t_asm`` reaches ``n_gp t_gp / P``, i.e. at ``P* = n_gp t_gp / t_asm`` ranks.
``t_asm`` is measured on structured quadrilateral meshes of growing size with random
symmetric tangents.

usage::

    python benchmarks/mpi_scaling.py            # writes benchmarks/results/mpi_scaling.json
    python benchmarks/mpi_scaling.py --markdown # the docs table from the JSON

environment: REPS (3).
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "mpi_scaling.json"
VENV_BIN = Path(sys.executable).parent


def run_demo(ranks, workdir):
    env = C.worker_env(1)
    cmd = [str(VENV_BIN / "python"), "-m", "hmm", "demo", "--no-progress", "--overwrite",
           "-o", str(workdir)]
    if ranks > 1:
        cmd = [str(VENV_BIN / "mpiexec"), "-n", str(ranks)] + cmd
    t0 = time.perf_counter()
    p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=3600,
                       check=False)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise RuntimeError(f"{ranks} ranks failed: {p.stderr.strip()[-500:]}")
    m = re.search(r"solved in ([0-9.]+) s", p.stdout)
    trials = int(re.search(r"([0-9]+) farm trials", p.stdout).group(1))
    return {"solve_time": float(m.group(1)), "wall": wall, "trials": trials}


def displacement(workdir):
    import h5py

    with h5py.File(Path(workdir) / "fields.h5") as f:
        last = max(f["steps"])
        return f["steps"][last]["displacement"][()]


def assembly_cost(sizes, reps=5):
    """Rank 0's assembly + solve time [s] per Newton iteration on n x 2n quad meshes."""
    import numpy as np
    from skfem import condense, solve

    from hmm.macro import Macro, structured_mesh

    rng = np.random.default_rng(0)
    out = []
    for n in sizes:
        macro = Macro(structured_mesh("quad1", [1.0, 2.0], [n, 2 * n]), "quad1")
        a = rng.normal(size=(macro.n_gp, 3, 3))
        c = np.zeros((macro.n_gp, 2, 2, 2, 2))
        idx = [(0, 0), (1, 1), (0, 1)]
        spd = np.einsum("gij,gkj->gik", a, a) + 3 * np.eye(3)
        for p, (i, j) in enumerate(idx):
            for q, (k, m) in enumerate(idx):
                for ii, jj in {(i, j), (j, i)}:
                    for kk, ll in {(k, m), (m, k)}:
                        c[:, ii, jj, kk, ll] = spd[:, p, q]
        sig = rng.normal(size=(macro.n_gp, 2, 2))
        sig = 0.5 * (sig + sig.transpose(0, 2, 1))
        fixed = macro.dofs("bottom", 1)
        times = []
        for _ in range(reps):
            t0 = time.perf_counter()
            k = macro.stiffness(c)
            r = macro.internal_force(sig)
            solve(*condense(k, -r, D=fixed))
            times.append(time.perf_counter() - t0)
        out.append({"elements": int(macro.n_elems), "gauss_points": int(macro.n_gp),
                    "dofs": int(macro.n_dofs), "t_asm": float(C.median(times))})
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--markdown", action="store_true")
    args = ap.parse_args()
    if args.markdown:
        print(markdown(json.loads(OUT.read_text())))
        return
    reps = C.env_int("REPS", 3)
    runs = {1: [], 2: []}
    with tempfile.TemporaryDirectory() as tmp:
        run_demo(1, Path(tmp) / "warm")  # compile the kernels once, untimed
        for _ in range(reps):
            for ranks in (1, 2):
                runs[ranks].append(run_demo(ranks, Path(tmp) / f"r{ranks}"))
        import numpy as np

        same = bool(np.array_equal(displacement(Path(tmp) / "r1"),
                                   displacement(Path(tmp) / "r2")))
    t1 = C.median([r["solve_time"] for r in runs[1]])
    t2 = C.median([r["solve_time"] for r in runs[2]])
    trials = runs[1][0]["trials"]
    n_gp, d = 32, 2
    t_gp = t1 / (trials * n_gp)
    asm = assembly_cost([4, 8, 16, 32, 64])
    for row in asm:
        row["bytes_per_iteration"] = 8 * row["gauss_points"] * (2 * d * d + d**4 + 2)
        row["messages_per_iteration"] = "1 bcast + 1 Scatterv + 3 Gatherv + 1 gather"
        row["ranks_before_rank0_bottleneck"] = row["gauss_points"] * t_gp / row["t_asm"]
    data = {"benchmark": "mpi_scaling", "date": C.now(), "machine": C.machine_info(),
            "versions": C.our_versions(), "revision": C.git_revision(),
            "loadavg": C.loadavg(), "reps": reps,
            "problem": "hmm demo: 8 quad1 elements, 32 Gauss points, RVEs of 60 disks",
            "solve_time_1_rank": t1, "solve_time_2_ranks": t2,
            "speedup_2_ranks": t1 / t2, "efficiency_2_ranks": t1 / (2 * t2),
            "bit_identical": same, "farm_trials": trials,
            "t_gauss_point_trial": t_gp, "runs": {str(k): v for k, v in runs.items()},
            "assembly": asm}
    C.write_json(OUT, data)
    print(markdown(data))


def markdown(data):
    head = (f"Demo problem, median of {data['reps']} runs: solve time "
            f"{data['solve_time_1_rank']:.1f} s on 1 rank, "
            f"{data['solve_time_2_ranks']:.1f} s on 2 ranks: speedup "
            f"{data['speedup_2_ranks']:.2f}, efficiency "
            f"{data['efficiency_2_ranks']:.2f}; results bit-identical: "
            f"{data['bit_identical']}. One Gauss-point trial costs "
            f"{1e3 * data['t_gauss_point_trial']:.1f} ms on average.")
    cols = ("| elements | Gauss points | dofs | rank 0 assembly + solve [ms] | "
            "bytes per iteration | ranks before rank 0 limits |")
    lines = [head, "", cols, "|---|---|---|---|---|---|"]
    for r in data["assembly"]:
        lines.append(f"| {r['elements']} | {r['gauss_points']} | {r['dofs']} | "
                     f"{1e3 * r['t_asm']:.1f} | {r['bytes_per_iteration']:,} | "
                     f"{r['ranks_before_rank0_bottleneck']:,.0f} |")
    return "\n".join(lines)


if __name__ == "__main__":
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    main()
