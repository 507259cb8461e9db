"""The ``hmm`` command: multiscale runs and standalone RVE tests.

``hmm demo``
    The embedded demonstration problem (a 2D biaxial compression with DEM RVEs at
    its Gauss points); no file needed.
``hmm run problem.toml``
    A multiscale run described by a problem file (:mod:`hmm.problem`).
``hmm rve rve.toml``
    A standalone drained biaxial (2D) or triaxial (3D) test of one RVE.
``hmm batch sweep.toml``
    Many RVE tests (a grid or list of variations) through a dynamic queue over MPI
    ranks; resumable.

Exit status: 0 on success, 1 when the run fails (no convergence, a micro model that
cannot relax), 2 on bad input (invalid file, existing output, bad arguments). Errors
are one line on stderr, ``hmm <command>: error: ...``, never a traceback.
"""

import logging
import sys
from pathlib import Path

from dem.cli import Parser, UsageError

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2

log = logging.getLogger(__name__)


def _parser():
    p = Parser(prog="hmm", description="Multiscale FEM x DEM runs.")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    common = Parser(add_help=False)
    common.add_argument("-o", "--output", type=Path, metavar="DIR",
                        help="output directory (overrides [output] dir)")
    common.add_argument("--overwrite", action="store_true",
                        help="replace existing output files")
    common.add_argument("--no-progress", action="store_true", help="no progress bar")
    common.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log messages (-vv for debug)")
    demo = sub.add_parser("demo", parents=[common], help="run the demonstration problem",
                          description="A 2D biaxial compression: 8 elements, 32 Gauss "
                                      "points, each a periodic DEM RVE of 60 disks.")
    demo.set_defaults(func=_cmd_demo)
    run = sub.add_parser("run", parents=[common], help="run a problem file",
                         description="Validate a TOML problem file and run it.",
                         epilog="The format is documented in docs/multiscale.md.")
    run.add_argument("file", type=Path, help="the problem file (TOML)")
    run.add_argument("--dry-run", action="store_true",
                     help="validate and build the macro problem, then stop")
    run.add_argument("--restart", action="store_true",
                     help="continue from the output directory's checkpoint.h5")
    run.add_argument("--stop-after", type=int, metavar="STEP",
                     help="stop after this load step, writing a checkpoint (to split "
                          "a long run into jobs)")
    run.set_defaults(func=_cmd_run)
    rve = sub.add_parser("rve", parents=[common], help="run a standalone RVE test",
                         description="Consolidate a periodic packing, then compress it "
                                     "(biaxial in 2D, triaxial in 3D).")
    rve.add_argument("file", type=Path, help="the RVE test file (TOML)")
    rve.set_defaults(func=_cmd_rve)
    batch = sub.add_parser("batch", parents=[common], help="run a sweep of RVE tests",
                           description="Many standalone RVE tests from one sweep file, "
                                       "over MPI ranks with a dynamic queue when started "
                                       "by mpiexec; resumable.")
    batch.add_argument("file", type=Path, help="the sweep file (TOML)")
    batch.set_defaults(func=_cmd_batch)
    return p


def main(argv=None):
    """Entry point of the ``hmm`` console script and of ``python -m hmm``."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("hmm: %(levelname)s: %(message)s"))
    roots = [logging.getLogger("hmm"), logging.getLogger("dem")]
    for r in roots:
        r.addHandler(handler)
    try:
        try:
            args = _parser().parse_args(argv)
        except UsageError as exc:
            code = _error("hmm", str(exc), EXIT_USAGE)
        else:
            if args.command is None:
                code = _error("hmm", "a command is required (see 'hmm --help')",
                              EXIT_USAGE)
            else:
                level = (logging.DEBUG if args.verbose > 1 else
                         logging.INFO if args.verbose else logging.WARNING)
                for r in roots:
                    r.setLevel(level)
                code = args.func(args)
    finally:
        for r in roots:
            r.removeHandler(handler)
    raise SystemExit(code)


def _error(prog, msg, code):
    import os

    if os.environ.get("PMI_RANK", "0") == "0":  # under mpiexec every rank fails alike
        print(f"{prog}: error: " + " ".join(str(msg).split()), file=sys.stderr)
    return code


def _cmd_demo(args):
    from .run import demo_problem

    return _solve(demo_problem(), args, "hmm demo")


def _cmd_run(args):
    from dem.io.scene import SceneError

    from .problem import build_macro, load_problem

    try:
        problem = load_problem(args.file)
        if args.dry_run:
            macro = build_macro(problem)
            print(f"{args.file}: valid; {macro.n_elems} elements, {macro.n_gp} Gauss "
                  f"points, {problem['load']['steps']} load steps")
            return EXIT_OK
    except SceneError as err:
        return _error("hmm run", err, EXIT_USAGE)
    return _solve(problem, args, "hmm run")


def _solve(problem, args, prog):
    from dem.io.scene import SceneError
    from dem.simulation import SimulationError

    from .coupling import SolverError
    from .farm import mpi_world
    from .run import run_problem

    stem = Path(problem["source"]).stem if not problem["source"].startswith("<") \
        else "demo"
    directory = args.output or Path(problem["output"]["dir"] or f"output/{stem}")
    _, comm = mpi_world()
    if comm is not None:
        _share_cores(comm.Get_size())
    try:
        summary = run_problem(problem, directory, overwrite=args.overwrite,
                              progress=False if args.no_progress else None, echo=print,
                              restart=getattr(args, "restart", False),
                              stop_after=getattr(args, "stop_after", None))
    except (SceneError, FileExistsError, FileNotFoundError, ValueError) as err:
        return _error(prog, err, EXIT_USAGE)
    except (SolverError, SimulationError) as err:
        return _error(prog, err, EXIT_FAILED)
    except Exception as err:
        if comm is None:
            raise
        # a bug on one rank must not leave the others waiting: end the whole job
        print(f"{prog}: error: rank {comm.Get_rank()}: {type(err).__name__}: "
              + " ".join(str(err).split()), file=sys.stderr, flush=True)
        comm.Abort(EXIT_FAILED)
    if summary is None:  # a worker rank: rank 0 reports
        return EXIT_OK
    its = summary["iterations"]
    print(f"{summary['steps']} load steps, {sum(its)} Newton iterations "
          f"({min(its)}-{max(its)} per step), {summary['cuts']} step cuts, "
          f"{summary['trials']} farm trials; solved in {summary['solve_time']:.1f} s")
    print(f"Gauss points that ran DEM: {summary['dem_points']} of "
          f"{summary['gauss_points']}")
    for name, f in summary["reactions"].items():
        print(f"reaction on {name}: " + ", ".join(f"{x:.4g}" for x in f) + " N")
    print("output:")
    for f in summary["files"]:
        if Path(f).exists():
            print(f"  {f}")
    return EXIT_OK


def _share_cores(n_ranks):
    """Numba threads per rank that leave the cores not oversubscribed, unless
    ``NUMBA_NUM_THREADS`` was set for the ranks."""
    import os

    import numba

    if "NUMBA_NUM_THREADS" not in os.environ:
        numba.set_num_threads(max(1, min(numba.config.NUMBA_NUM_THREADS,
                                         (os.cpu_count() or 1) // n_ranks)))


def _cmd_rve(args):
    from .experiment import cmd_rve

    return cmd_rve(args)


def _cmd_batch(args):
    from .batch import cmd_batch
    from .farm import mpi_world

    _, comm = mpi_world()
    if comm is not None:
        _share_cores(comm.Get_size())
    return cmd_batch(args)
