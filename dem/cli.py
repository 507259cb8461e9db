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


def _cmd_run(args):
    from .io.files import OutputError
    from .io.scene import SceneError, build_simulation, load_scene
    from .simulation import SimulationError

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
    n_steps = scene["simulation"]["steps"]
    if args.dry_run:
        inserted = scene["insert"]["count"] if scene["insert"] else 0
        return _dry_run(args, sim, out_file, n_steps, inserted)
    try:
        writer = _open_writer(out_file, output, args.overwrite,
                              config=args.scene.read_text(errors="replace"))
    except OSError as exc:  # existing output, or the directory cannot be made
        return _error(exc, EXIT_USAGE)
    if writer is not None:
        sim.observers.append(writer)
    progress = sys.stderr.isatty() and not args.no_progress and n_steps > 0
    t_start = time.perf_counter()
    try:
        sim.prime()  # neighbour lists and first forces; compiles the loop on first use
        if writer is not None:
            writer(sim)  # the initial frame; the run adds one every `every` steps
        t0 = time.perf_counter()
        rest = _run(sim, n_steps, scene["simulation"]["rest_speed"], progress, writer)
        if writer is not None:
            writer.close()
    except OutputError as exc:  # the disk refused a write: the file is removed
        return _error(exc, EXIT_USAGE)
    except SimulationError as exc:
        return _error(f"simulation failed: {exc}", EXIT_FAILED)
    except KeyboardInterrupt:
        return _error(f"interrupted at step {sim.step}", 130)
    finally:
        if writer is not None:
            _close_quietly(writer)
    wall = time.perf_counter() - t0
    n_steps = sim.step
    rate = f" ({n_steps / wall:.3g} steps/s)" if wall > 0 and n_steps else ""
    print(f"dem run {args.scene}: {_bodies_line(sim)}\n"
          f"  steps      {n_steps} x dt = {sim.dt:.4g} s = {sim.time:.4g} s simulated{rest}\n"
          f"  wall time  {wall:.3g} s{rate} + {t0 - t_start:.3g} s start-up\n"
          f"  output     {out_file if writer is not None else 'none (no HDF5 writer)'}")
    if writer is not None and writer.xdmf_paths:  # what ParaView and meshio open
        print("  xdmf       " + ", ".join(Path(p).name for p in writer.xdmf_paths))
    return EXIT_OK


def _run(sim, n_steps, rest_speed, progress, writer):
    """Run the scene's steps, or until rest (the state at rest is the last frame);
    the words the summary adds."""
    if rest_speed is None:
        sim.run(n_steps, progress=progress)
        return ""
    from .rest import run_until_rest

    _, at_rest = run_until_rest(sim, n_steps, rest_speed, progress=progress)
    if writer is not None and not writer.trigger(sim.step):
        writer(sim)
    return (f", at rest (below {rest_speed:g} m/s)" if at_rest
            else f", not at rest (still above {rest_speed:g} m/s)")


def _close_quietly(writer):
    """Close ``writer`` after another error, which is the one reported: its own
    OutputError would be a second line."""
    from .io.files import OutputError

    try:
        writer.close()
    except OutputError as exc:
        log.debug("%s", exc)


def _dry_run(args, sim, out_file, n_steps, inserted=0):
    """Check the outputs as the run would (nothing is written) and print the plan."""
    from .cost import run_seconds, time_line
    from .io.plan import check_new_files, work_line
    from .limits import memory_estimate
    from .shapes import Shape

    try:
        check_new_files([out_file, out_file.with_suffix(".xdmf")], args.overwrite)
    except OSError as exc:
        return _error(exc, EXIT_USAGE)
    n_particles = sim.bodies.n - len(sim.bodies.ids(Shape.PLANE)) + inserted
    replaced = " (replaced)" if args.overwrite and out_file.exists() else ""
    print(f"{args.scene}: valid; {_bodies_line(sim)}; {n_steps} steps of "
          f"dt = {sim.dt:.4g} s; output {out_file}{replaced}; memory "
          f"{memory_estimate(n_particles)}; {work_line(n_particles, n_steps)}; "
          f"{time_line(run_seconds(n_particles, n_steps, sim.dim, sim.shaped))}")
    return EXIT_OK


def _bodies_line(sim):
    from .shapes import Shape

    b = sim.bodies
    n_sph, n_wall = len(b.ids(Shape.SPHERE)), len(b.ids(Shape.PLANE))
    return (f"{n_sph} {'spheres' if b.dim == 3 else 'disks'}, {n_wall} walls "
            f"({b.dim}D)")


def _open_writer(path, output, overwrite, config=None):
    """The HDF5 observer writing to ``path``, or None where no writer is available;
    ``config`` (the scene file's text) is stored in the file.

    Refuses (FileExistsError) to replace an existing HDF5 or XDMF file (the
    particles' or a companion, :func:`dem.io.xdmf.xdmf_files`) unless ``overwrite``.
    """
    refuse_existing((path, path.with_suffix(".xdmf")), overwrite)
    try:
        from .io.hdf5 import H5Writer
        from .io.xdmf import xdmf_files
    except ImportError as exc:
        log.warning("HDF5 output disabled, the writer is not available: %s", exc)
        return None
    xdmf = [Path(p) for p in xdmf_files(path.with_suffix(".xdmf")).values()]
    existing = refuse_existing((path, *xdmf), overwrite)
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
    return H5Writer(path, every=output.every, contacts=output.contacts, config=config)
