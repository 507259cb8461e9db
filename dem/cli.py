"""The ``dem`` command; ``dem run scene.toml`` runs a TOML scene (:mod:`dem.io.scene`).

Exit status: 0 on success, 1 when the simulation fails (:class:`dem.SimulationError`),
2 on bad input (invalid scene, unreadable file, existing output, bad arguments) or an
output the disk refuses (full, read-only: :class:`dem.io.files.OutputError`). Errors
are one line on stderr, ``dem: error: ...``, never a traceback.
"""

import argparse
import logging
import sys
import time
from pathlib import Path

log = logging.getLogger(__name__)

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2


class Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line, ``PROG: error: ...`` (the
    ``dem`` and ``hmm`` commands share it)."""

    def error(self, message):
        raise UsageError(f"{message} (see '{self.prog} --help')")


class UsageError(Exception):
    """A bad command line; the message is one line."""


def version_line(prog):
    """``PROG VERSION``: the version of the installed ``femxdem`` distribution (the
    package metadata), as ``--version`` prints it."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return f"{prog} {version('femxdem')}"
    except PackageNotFoundError:
        return f"{prog} (femxdem not installed: version unknown)"


def refuse_existing(paths, overwrite):
    """Raise FileExistsError naming the first of ``paths`` that exists, unless
    ``overwrite``: the rule of every command that writes files."""
    existing = [p for p in paths if Path(p).exists()]
    if existing and not overwrite:
        raise FileExistsError(f"output file {existing[0]} exists; pass --overwrite to "
                              f"replace it or choose another directory with --output")
    return existing


def _parser():
    parser = Parser(prog="dem", description="DEM simulations from TOML scene files.")
    parser.add_argument("--version", action="version", version=version_line("dem"),
                        help="print the version and exit")
    parser.add_argument("-v", "--verbose", action="count", default=argparse.SUPPRESS,
                        help="more log messages (-vv for debug)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    run = sub.add_parser(
        "run", help="run a scene file",
        description="Validate, build and run a TOML scene; write HDF5 output.",
        epilog="The scene format is documented in dem.io.scene (SCHEMA). Exit status: "
               "0 done, 1 the simulation failed, 2 bad input or an output the disk "
               "refuses.")
    run.add_argument("scene", type=Path, help="the scene file (TOML)")
    run.add_argument("-o", "--output", type=Path, metavar="DIR",
                     help="output directory (overrides [output] dir)")
    run.add_argument("--overwrite", action="store_true",
                     help="replace existing output files")
    run.add_argument("--steps", type=int, metavar="N",
                     help="number of steps (overrides [simulation] steps)")
    run.add_argument("--restart", action="store_true",
                     help="continue from the checkpoint.h5 beside the particle file (see "
                          "[output] checkpoint_every) to the scene's step count")
    run.add_argument("--dry-run", action="store_true",
                     help="validate and build the scene, check the output, print the "
                          "plan, then stop; nothing is written")
    run.add_argument("--no-progress", action="store_true", help="no progress bar")
    run.add_argument("-v", "--verbose", action="count", default=argparse.SUPPRESS,
                     help="more log messages (-vv for debug)")
    run.set_defaults(func=_cmd_run)
    return parser


def main(argv=None):
    """Entry point of the ``dem`` console script and of ``python -m dem``.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name (default ``sys.argv[1:]``).

    Raises
    ------
    SystemExit
        Always, with the exit status (0 ok, 1 simulation failure, 2 bad input).
    """
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("dem: %(levelname)s: %(message)s"))
    root = logging.getLogger("dem")
    old_level = root.level
    root.addHandler(handler)
    try:
        try:
            args = _parser().parse_args(argv)
        except UsageError as exc:
            code = _error(str(exc), EXIT_USAGE)
        else:
            verbose = getattr(args, "verbose", 0)
            root.setLevel(logging.DEBUG if verbose > 1 else logging.INFO if verbose
                          else logging.WARNING)
            if args.command is None:
                code = _error("a command is required (see 'dem --help')", EXIT_USAGE)
            else:
                code = args.func(args)
    finally:
        root.removeHandler(handler)
        root.setLevel(old_level)
    raise SystemExit(code)


def _error(msg, code):
    print("dem: error: " + " ".join(str(msg).split()), file=sys.stderr)
    return code


def _prepare(args):
    """The scene, its simulation (continued from the checkpoint on ``--restart``) and
    the :class:`_Run`; or the exit status of a refused input."""
    from .io.restart import load_scene_checkpoint
    from .io.scene import SceneError, build_simulation, load_scene

    try:
        scene = load_scene(args.scene)
        if args.steps is not None:
            from .limits import INT64_MAX

            if not 0 <= args.steps <= INT64_MAX:
                raise SceneError(f"--steps must be in [0, {INT64_MAX}] (a 64-bit "
                                 f"integer), got {args.steps}")
            scene["simulation"]["steps"] = args.steps
        sim, output = build_simulation(scene)
    except SceneError as exc:
        return _error(exc, EXIT_USAGE)
    out_file = output.file if args.output is None else args.output / output.file.name
    run = _Run(scene, out_file, output, args.scene.read_text(errors="replace"))
    if args.restart:
        try:
            sim = load_scene_checkpoint(run.checkpoint, scene, sim)
        except (ValueError, OSError) as exc:
            return _error(exc, EXIT_USAGE)
        if sim.step > run.n_steps:
            return _error(f"--restart: {run.checkpoint} holds step {sim.step}, past the "
                          f"scene's {run.n_steps} steps (raise --steps)", EXIT_USAGE)
    return scene, sim, run


def _cmd_run(args):
    from .io.files import OutputError
    from .simulation import SimulationError

    prepared = _prepare(args)
    if isinstance(prepared, int):
        return prepared
    scene, sim, run = prepared
    output, out_file, n_steps = run.output, run.out_file, run.n_steps
    if args.dry_run:
        inserted = scene["insert"]["count"] if scene["insert"] else 0
        return _dry_run(args, sim, run, n_steps - sim.step, inserted)
    try:
        writer = _open_writer(out_file, output, args.overwrite, config=run.config,
                              resume_step=sim.step if args.restart else None)
    except OSError as exc:  # existing output, or the directory cannot be made
        return _error(exc, EXIT_USAGE)
    if writer is not None:
        sim.observers.append(writer)
    progress = sys.stderr.isatty() and not args.no_progress and n_steps > sim.step
    t_start = time.perf_counter()
    start_step = sim.step
    try:
        sim.prime()  # neighbour lists and first forces; compiles the loop on first use
        if writer is not None and not args.restart:
            writer(sim)  # the initial frame; the run adds one every `every` steps
        t0 = time.perf_counter()
        with _Signals() as signals:
            rest = run.steps(sim, n_steps - sim.step, progress, writer, signals)
        if writer is not None:
            writer.close()
    except OutputError as exc:  # the disk refused a write: the file is removed
        return _error(exc, EXIT_USAGE)
    except SimulationError as exc:
        return _error(f"simulation failed: {exc}", EXIT_FAILED)
    except _Stopped as exc:
        return _error(f"{exc}; {run.checkpoint_note()}", 128 + exc.signum)
    except KeyboardInterrupt:
        return _error(f"interrupted at step {sim.step}; {run.checkpoint_note()}", 130)
    finally:
        if writer is not None:
            _close_quietly(writer)
    wall = time.perf_counter() - t0
    done = sim.step - start_step
    rate = f" ({done / wall:.3g} steps/s)" if wall > 0 and done else ""
    since = f" (from the checkpoint at step {start_step})" if args.restart else ""
    print(f"dem run {args.scene}: {_bodies_line(sim)}\n"
          f"  steps      {sim.step} x dt = {sim.dt:.4g} s = {sim.time:.4g} s simulated"
          f"{since}{rest}\n"
          f"  wall time  {wall:.3g} s{rate} + {t0 - t_start:.3g} s start-up\n"
          f"  output     {out_file if writer is not None else 'none (no HDF5 writer)'}")
    if writer is not None and writer.xdmf_paths:  # what ParaView and meshio open
        print("  xdmf       " + ", ".join(Path(p).name for p in writer.xdmf_paths))
    if output.checkpoint_every:
        print(f"  checkpoint {run.checkpoint} (step {sim.step})")
    return EXIT_OK


class _Stopped(Exception):
    """SIGINT or SIGTERM stopped the run at a step boundary."""

    def __init__(self, signum, step):
        import signal

        self.signum = int(signum)
        super().__init__(f"interrupted by {signal.Signals(signum).name} at step {step}")


class _Signals:
    """While open, SIGINT and SIGTERM only note themselves (:attr:`signum`): the run
    stops at the end of its chunk, where the state is whole and can be saved."""

    def __init__(self):
        self.signum = None
        self._old = {}

    def __enter__(self):
        import signal
        import threading

        if threading.current_thread() is threading.main_thread():
            for s in (signal.SIGINT, signal.SIGTERM):
                if signal.getsignal(s) is not signal.SIG_IGN:
                    self._old[s] = signal.signal(s, self._note)
        return self

    def _note(self, signum, frame):
        if self.signum is None:
            self.signum = signum

    def __exit__(self, *exc):
        import signal

        for s, handler in self._old.items():
            signal.signal(s, handler)
        self._old = {}


class _Run:
    """The steps of a scene run: chunks, rest checks, checkpoints, signals."""

    def __init__(self, scene, out_file, output, config):
        from .io.restart import CHECKPOINT

        self.scene, self.output, self.config = scene, output, config
        self.out_file = out_file
        self.n_steps = scene["simulation"]["steps"]
        self.checkpoint = out_file.parent / CHECKPOINT
        self.rest_speed = scene["simulation"]["rest_speed"]
        self.saved_at = None

    def save(self, sim):
        from .io.restart import save_scene_checkpoint

        if self.output.checkpoint_every and self.saved_at != sim.step:
            save_scene_checkpoint(sim, self.checkpoint, self.scene, config=self.config)
            self.saved_at = sim.step

    def checkpoint_note(self):
        """Where a stopped run can continue from, in a few words."""
        from .io.restart import checkpoint_step

        step = checkpoint_step(self.checkpoint) if self.output.checkpoint_every else None
        if step is None:
            return ("no checkpoint (set [output] checkpoint_every to continue a stopped "
                    "run with --restart)")
        return f"{self.checkpoint} holds step {step} (continue with --restart)"

    def steps(self, sim, n_steps, progress, writer, signals):
        """Run the remaining ``n_steps`` (or until rest); the words the summary adds."""
        from .observers import Periodic
        from .rest import run_chunked

        every = self.output.checkpoint_every
        marks = [Periodic(every)] if every else []

        def after(sim):
            if every and sim.step % every == 0:
                self.save(sim)
            if signals.signum is not None:
                self.save(sim)
                raise _Stopped(signals.signum, sim.step)

        speed = self.rest_speed
        _, at_rest = run_chunked(sim, n_steps, speed, progress=progress, marks=marks,
                                 after=after)
        if speed is not None and writer is not None and not writer.trigger(sim.step):
            writer(sim)  # the state at rest is the last frame
        self.save(sim)
        if speed is None:
            return ""
        return (f", at rest (below {speed:g} m/s)" if at_rest
                else f", not at rest (still above {speed:g} m/s)")


def _close_quietly(writer):
    """Close ``writer`` after another error, which is the one reported: its own
    OutputError would be a second line."""
    from .io.files import OutputError

    try:
        writer.close()
    except OutputError as exc:
        log.debug("%s", exc)


def _dry_run(args, sim, run, n_steps, inserted=0):
    """Check the outputs as the run would (nothing is written) and print the plan."""
    from .cost import run_seconds, time_line
    from .io.plan import check_new_files, work_line
    from .limits import memory_estimate
    from .shapes import Shape

    out_file = run.out_file
    if not args.restart:
        try:
            check_new_files([out_file, out_file.with_suffix(".xdmf"), run.checkpoint],
                            args.overwrite)
        except OSError as exc:
            return _error(exc, EXIT_USAGE)
    n_particles = sim.bodies.n - len(sim.bodies.ids(Shape.PLANE)) + inserted
    replaced = (" (continued)" if args.restart and out_file.exists() else
                " (replaced)" if args.overwrite and out_file.exists() else "")
    since = f" from the checkpoint at step {sim.step}" if args.restart else ""
    print(f"{args.scene}: valid; {_bodies_line(sim)}; {n_steps} steps{since} of "
          f"dt = {sim.dt:.4g} s; output {out_file}{replaced}; memory "
          f"{memory_estimate(n_particles)}; {work_line(n_particles, n_steps)}; "
          f"{time_line(run_seconds(n_particles, n_steps, sim.dim, sim.shaped))}")
    return EXIT_OK


def _bodies_line(sim):
    from .shapes import Shape

    b = sim.bodies
    n_sph, n_wall = len(b.ids(Shape.SPHERE)), len(b.ids(Shape.PLANE))
    meshes = f", {len(sim.mesh_walls)} mesh walls" if sim.mesh_walls else ""
    return (f"{n_sph} {'spheres' if b.dim == 3 else 'disks'}, {n_wall} walls{meshes} "
            f"({b.dim}D)")


def _open_writer(path, output, overwrite, config=None, resume_step=None):
    """The HDF5 observer writing to ``path``, or None where no writer is available;
    ``config`` (the scene file's text) is stored in the file.

    Refuses (FileExistsError) to replace an existing HDF5 or XDMF file (the
    particles' or a companion, :func:`dem.io.xdmf.xdmf_files`) or a checkpoint unless
    ``overwrite``. With ``resume_step`` (a restart) the particle file is continued
    from that step instead.
    """
    from .io.restart import CHECKPOINT

    try:
        from .io.hdf5 import H5Writer
        from .io.xdmf import xdmf_files
    except ImportError as exc:
        log.warning("HDF5 output disabled, the writer is not available: %s", exc)
        return None
    existing = []
    if resume_step is None:
        xdmf = [Path(p) for p in xdmf_files(path.with_suffix(".xdmf")).values()]
        existing = refuse_existing((path, *xdmf, path.parent / CHECKPOINT), overwrite)
    from .io.files import OutputError

    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(path.parent, err) from None
    for p in existing:
        try:
            p.unlink()
        except OSError as err:
            raise OutputError(p, err) from None
    return H5Writer(path, every=output.every, contacts=output.contacts, config=config,
                    resume_step=resume_step)
