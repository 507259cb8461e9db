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
cannot relax), 2 on bad input (invalid file, existing output, bad arguments) or an
output the disk refuses (full, read-only: :class:`dem.io.files.OutputError`), 130 on
SIGINT (Ctrl-C) and 143 on SIGTERM, on any rank under ``mpiexec``. Errors are one line
on stderr, ``hmm <command>: error: ...``, never a traceback.

The commands live here and import the modules that do the work (:mod:`hmm.run`,
:mod:`hmm.experiment`, :mod:`hmm.batch`, :mod:`hmm.queue`) when they run; none of those
imports this module.
"""

import logging
import signal
import sys
from pathlib import Path

from dem.cli import Parser, UsageError, version_line

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2

log = logging.getLogger(__name__)


def _parser():
    p = Parser(prog="hmm", description="Multiscale FEM x DEM runs.")
    p.add_argument("--version", action="version", version=version_line("hmm"),
                   help="print the version and exit")
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
                     help="read and check every input (packings, mesh, checkpoint) "
                          "and the outputs, print the plan, then stop; nothing is "
                          "written")
    run.add_argument("--restart", action="store_true",
                     help="continue from the output directory's checkpoint.h5")
    run.add_argument("--stop-after", type=_positive_int, metavar="STEP",
                     help="stop after this load step, writing a checkpoint (to split "
                          "a long run into jobs)")
    run.set_defaults(func=_cmd_run)
    rve = sub.add_parser("rve", parents=[common], help="run a standalone RVE test",
                         description="Consolidate a periodic packing, then compress it "
                                     "(biaxial in 2D, triaxial in 3D).")
    rve.add_argument("file", type=Path, help="the RVE test file (TOML)")
    rve.add_argument("--dry-run", action="store_true",
                     help="read and check the file, its packing and the outputs, print "
                          "the plan, then stop; nothing is written")
    rve.set_defaults(func=cmd_rve)
    batch = sub.add_parser("batch", parents=[common], help="run a sweep of RVE tests",
                           description="Many standalone RVE tests from one sweep file, "
                                       "over MPI ranks with a dynamic queue when started "
                                       "by mpiexec; resumable.")
    batch.add_argument("file", type=Path, help="the sweep file (TOML)")
    batch.add_argument("--dry-run", action="store_true",
                       help="read and check the sweep, its packings and an existing "
                            "batch file, print the plan, then stop; nothing is written")
    batch.set_defaults(func=_cmd_batch)
    return p


def _positive_int(text):
    """An argument that must be an integer >= 1 (argparse names the option)."""
    import argparse

    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a load step >= 1, got {value}")
    return value


def main(argv=None):
    """Entry point of the ``hmm`` console script and of ``python -m hmm``."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("hmm: %(levelname)s: %(message)s"))
    roots = [logging.getLogger("hmm"), logging.getLogger("dem")]
    for r in roots:
        r.addHandler(handler)
    handlers = _on_signals()
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
                code = _interruptible(args)
    finally:
        for r in roots:
            r.removeHandler(handler)
        for s, h in handlers.items():
            signal.signal(s, h)
        if _hooks:
            sys.unraisablehook = _hooks.pop()
    raise SystemExit(code)


def _on_signals():
    """SIGINT and SIGTERM (unless ignored) raise :class:`hmm.signals.Interrupted` (an MPI
    farm or batch defers them to its own checks); returns the previous handlers."""
    import threading

    from .signals import interrupt

    old = {}
    if threading.current_thread() is threading.main_thread():
        for s in (signal.SIGINT, signal.SIGTERM):
            if signal.getsignal(s) is not signal.SIG_IGN:
                old[s] = signal.signal(s, interrupt)
        _hooks.append(sys.unraisablehook)
        sys.unraisablehook = _unraisable
    return old


_hooks = []  # the unraisable hooks _on_signals replaced (restored by main)


def _unraisable(info):
    """An :class:`hmm.signals.Interrupted` raised inside a weakref callback or a
    ``__del__`` is dropped by Python, which would print it: it is raised again at the
    next check (:func:`hmm.signals.raise_pending`), so it is not printed. Anything
    else goes to Python's own hook."""
    from .signals import Interrupted

    if not isinstance(info.exc_value, Interrupted):
        (_hooks[-1] if _hooks else sys.__unraisablehook__)(info)


def _interruptible(args):
    """Run the command; a signal outside its own handling is one line too."""
    from .signals import Interrupted, reported

    try:
        return args.func(args)
    except KeyboardInterrupt:
        return _error(f"hmm {args.command}", "interrupted by SIGINT", 130)
    except Interrupted as err:
        return _error(f"hmm {args.command}", err, err.code)
    finally:
        reported()


def _error(prog, msg, code):
    import os

    if os.environ.get("PMI_RANK", "0") == "0":  # under mpiexec every rank fails alike
        _report(prog, msg, code)
    return code


def _report(prog, msg, code):
    """Print ``prog: error: msg`` as one line on stderr; return ``code``."""
    print(f"{prog}: error: " + " ".join(str(msg).split()), file=sys.stderr)
    return code


def _cmd_demo(args):
    from .run import demo_problem

    return _solve(demo_problem(), args, "hmm demo")


def _cmd_run(args):
    from dem.io.schema import SceneError

    from .problem import load_problem

    try:
        problem = load_problem(args.file)
        if args.dry_run:
            from .dryrun import plan_run

            print(plan_run(problem, _directory(problem, args), args.overwrite,
                           args.restart, args.stop_after))
            return EXIT_OK
    except (SceneError, OSError, ValueError) as err:
        return _error("hmm run", err, EXIT_USAGE)
    return _solve(problem, args, "hmm run")


def _directory(problem, args):
    """The output directory of a run: ``-o``, else ``[output] dir``, else
    ``output/<file stem>``."""
    stem = Path(problem["source"]).stem if not problem["source"].startswith("<") \
        else "demo"
    return args.output or Path(problem["output"]["dir"] or f"output/{stem}")


def _solve(problem, args, prog):
    from dem.io.files import OutputError
    from dem.io.schema import SceneError
    from dem.simulation import SimulationError

    from .coupling import SolverError
    from .farm import mpi_world
    from .signals import Interrupted
    from .run import run_problem

    directory = _directory(problem, args)
    _, comm = mpi_world()
    if comm is not None:
        _share_cores(comm.Get_size())
    try:
        summary = run_problem(problem, directory, overwrite=args.overwrite,
                              progress=False if args.no_progress else None, echo=print,
                              restart=getattr(args, "restart", False),
                              stop_after=getattr(args, "stop_after", None))
    except OutputError as err:  # the disk refused a file; say where a restart starts
        note = _checkpoint_note(directory)
        return _error(prog, err if note.startswith("no ") else f"{err}; {note}",
                      EXIT_USAGE)
    except (SceneError, OSError, ValueError) as err:
        return _error(prog, err, EXIT_USAGE)
    except (SolverError, SimulationError) as err:
        return _error(prog, err, EXIT_FAILED)
    except KeyboardInterrupt:
        return _interrupted(prog, Interrupted(signal.SIGINT), directory, comm)
    except Interrupted as err:
        return _interrupted(prog, err, directory, comm)
    except Exception as err:
        if comm is None:
            raise
        # a bug on one rank must not leave the others waiting: end the whole job
        print(f"{prog}: error: rank {comm.Get_rank()}: {type(err).__name__}: "
              + " ".join(str(err).split()), file=sys.stderr, flush=True)
        comm.Abort(EXIT_FAILED)
    if summary is None:  # a worker rank: rank 0 reports
        return EXIT_OK
    for line in run_lines(problem, summary):
        print(line)
    for line in reaction_lines(summary):
        print(line)
    print("output:")
    for f in summary["files"]:
        if Path(f).exists():
            print(f"  {f}")
    return EXIT_OK


def run_lines(problem, summary):
    """The lines ``hmm run`` prints of a finished run's ``summary``: the solver's
    work, where the DEM ran and what the RVE calls cost, a saturated run's clock and
    pressures."""
    its = summary["iterations"] or [0]
    out = [f"{summary['steps']} load steps, {sum(its)} Newton iterations "
           f"({min(its)}-{max(its)} per step), {summary['cuts']} step cuts, "
           f"{summary['trials']} farm trials; solved in {summary['solve_time']:.1f} s"]
    if problem["micro"]["model"] in ("dem", "adaptive"):  # analytic models never run DEM
        out.append(f"Gauss points that ran DEM: {summary['dem_points']} of "
                   f"{summary['gauss_points']}")
        calls, seconds, steps = (summary["work"][k] for k in
                                 ("rve_calls", "rve_seconds", "dem_steps"))
        if calls > 0:
            out.append(f"RVE calls: {calls:.0f}, on average {1e3 * seconds / calls:.3g} ms "
                       f"and {steps / calls:.0f} DEM steps each")
    if "p" in summary:  # a saturated problem
        out.append(f"time {summary['time']:.6g} s, pore pressure {summary['p'].min():.4g} "
                   f"to {summary['p'].max():.4g} Pa")
    return out


def reaction_lines(summary):
    """``reaction on NAME: x = ..., y = ... UNIT``, one line per support of a run's
    ``summary``: the components the support holds, in N/m in 2D (plane strain, per
    unit thickness) and N in 3D."""
    unit = "N/m" if summary.get("dim", 3) == 2 else "N"
    held = summary.get("held", {})
    lines = []
    for name, f in summary["reactions"].items():
        comps = held.get(name, range(len(f)))
        lines.append(f"reaction on {name}: "
                     + ", ".join(f"{'xyz'[c]} = {f[c]:.4g}" for c in comps) + f" {unit}")
    return lines


def _interrupted(prog, err, directory, comm):
    """One line from rank 0 (the outputs are closed by then); ``comm.Abort`` when a
    rank did not answer in time, the last resort."""
    if comm is None or comm.Get_rank() == 0:
        _report(prog, f"{err}; {_checkpoint_note(directory)}", err.code)
    if comm is not None and not err.settled:
        sys.stderr.flush()
        comm.Abort(err.code)
    return err.code


def _checkpoint_note(directory):
    """Where a stopped run can continue from, in a few words."""
    import h5py

    path = Path(directory) / "checkpoint.h5"
    try:
        with h5py.File(path, "r") as f:
            step = int(f.attrs["step"])
    except (OSError, KeyError, TypeError, ValueError):
        return f"no checkpoint in {directory}"
    return f"{path} holds load step {step} (continue with --restart)"


def _share_cores(n_ranks):
    """Numba threads per rank that leave the cores not oversubscribed, unless
    ``NUMBA_NUM_THREADS`` was set for the ranks."""
    import os

    import numba

    if "NUMBA_NUM_THREADS" not in os.environ:
        numba.set_num_threads(max(1, min(numba.config.NUMBA_NUM_THREADS,
                                         (os.cpu_count() or 1) // n_ranks)))


def cmd_rve(args):
    """``hmm rve FILE``: run an RVE compression test and print its summary.

    ``args`` has ``file`` (the TOML), ``output`` (directory or None) and
    ``overwrite``; optional ``no_progress``. Returns the exit status: 0 done, 1 the
    packing did not relax, 2 bad input (invalid file, existing output).
    """
    from dem.io.schema import SceneError
    from dem.simulation import SimulationError

    from .experiment import load_config, run_experiment
    from .experiment_summary import report

    try:
        cfg = load_config(args.file)
        if getattr(args, "dry_run", False):
            from .dryrun import plan_rve

            print(plan_rve(cfg, getattr(args, "output", None),
                           getattr(args, "overwrite", False)))
            return 0
        result = run_experiment(cfg, getattr(args, "output", None),
                                overwrite=getattr(args, "overwrite", False),
                                progress=not getattr(args, "no_progress", False)
                                and sys.stderr.isatty())
    except (SceneError, OSError) as exc:  # FileExistsError is an OSError
        return _report("hmm rve", exc, 2)
    except SimulationError as exc:
        return _report("hmm rve", f"the test failed: {exc}", 1)
    except KeyboardInterrupt:
        return _report("hmm rve", "interrupted", 130)
    print(report(args.file, result.summary, result.files,
                 result.curves["axial_strain"][-1]))
    return 0


def _cmd_batch(args):
    from .farm import mpi_world

    _, comm = mpi_world()
    if comm is not None:
        _share_cores(comm.Get_size())
    return cmd_batch(args)


def cmd_batch(args):
    """``hmm batch FILE``: run a sweep of RVE tests; call it on every rank.

    ``args`` has ``file`` (the TOML), ``output`` (directory or None) and
    ``overwrite``; optional ``no_progress``. Returns the exit status on every
    rank: 0 every experiment done, 1 some failed or the batch stopped early, 2 bad
    input (nothing ran), 130 interrupted. Only rank 0 prints.
    """
    from dem.io.schema import SceneError

    from .batch import load_sweep
    from .farm import mpi_world
    from .signals import Interrupted
    from .queue import RankFailure, run_batch

    MPI, comm = mpi_world()
    rank = 0 if comm is None else comm.rank
    sweep = err = None
    if rank == 0:
        try:
            sweep = load_sweep(args.file)
        except SceneError as exc:
            err = str(exc)
    if comm is not None:
        err = comm.bcast(err, root=0)
    if err is not None:
        return _report("hmm batch", err, 2) if rank == 0 else 2
    if getattr(args, "dry_run", False):
        return _dry_batch(sweep, args) if rank == 0 else 0
    try:
        report = run_batch(sweep, getattr(args, "output", None),
                           overwrite=getattr(args, "overwrite", False),
                           progress=not getattr(args, "no_progress", False)
                           and sys.stderr.isatty(), world=(MPI, comm))
    except (SceneError, OSError) as exc:
        return _report("hmm batch", exc, 2) if rank == 0 else 2
    except KeyboardInterrupt:
        return _report("hmm batch", "interrupted by SIGINT; rerun the same command to "
                       "resume", 130) if rank == 0 else 130
    except Interrupted as exc:
        if rank == 0:
            _report("hmm batch", f"{exc}; rerun the same command to resume", exc.code)
        if comm is not None and not exc.settled:
            sys.stderr.flush()
            comm.Abort(exc.code)
        return exc.code
    except RankFailure as exc:  # a worker: rank 0 reports its own failure
        return exc.code
    if rank != 0:
        return _batch_status(report)
    r = report
    ran = r.n_total - r.n_skipped
    if r.aborted:
        return _report("hmm batch", f"{r.aborted}; the batch stopped ({r.n_done} of "
                       f"{r.n_total} experiments done, in {r.files[0]})", 1)
    print(f"hmm batch {args.file}: {r.n_total} experiments ({ran} run, "
          f"{r.n_skipped} already in {Path(r.files[0]).name}) on {r.ranks} "
          f"rank{'s' * (r.ranks > 1)} in {r.wall_time:.1f} s: {r.n_done} done, "
          f"{r.n_failed} failed (did not relax)\n"
          f"  output: {', '.join(r.files)}")
    return _batch_status(report)


def _dry_batch(sweep, args):
    """``hmm batch --dry-run``: the checks of :func:`hmm.dryrun.plan_batch`, its plan."""
    from dem.io.schema import SceneError

    from .dryrun import plan_batch

    try:
        print(plan_batch(sweep, getattr(args, "output", None),
                         getattr(args, "overwrite", False)))
    except (SceneError, OSError) as exc:
        return _report("hmm batch", exc, 2)
    return 0


def _batch_status(report):
    return 1 if report.aborted or report.n_failed else 0
