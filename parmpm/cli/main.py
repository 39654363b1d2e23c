"""The ``parmpm`` command line: ``python -m parmpm`` or the ``parmpm`` console script.

    mpirun -n 2 python -m parmpm                                  # the default scene (hanging_bar)
    mpirun -n 4 python -m parmpm run vibrating_bar --set method.interpolator=mpm
    python -m parmpm run my_scene.toml --out results/ --quiet
    python -m parmpm scenes                                       # the built-in scenes
    python -m parmpm run hanging_bar --set checkpoint.every_steps=200 --out runs/bar
    mpirun -n 3 python -m parmpm restart runs/bar/checkpoint_00000200.h5 --set time.end=0.5
    python -m parmpm show hanging_bar --set time.end=0.1 > my.toml    # a scene file to edit
    python -m parmpm compile --dim 2 3                            # fill numba's cache (a job's first step)

Exit codes: 0 success; 2 a user error (bad scene, bad ``--set``, a run that cannot go on:
every ``ParmpmError``), printed as one line ``parmpm: error: <message>`` without a traceback;
130 interrupted (SIGINT, SIGTERM or SIGHUP: inside the time loop after writing a checkpoint,
named in the message; before it, at once); 1 a bug (full traceback; under MPI the job is aborted so that no
rank hangs). Options before any command mean ``run``: ``parmpm --quiet`` runs the default scene.

Output folders are never taken from another run (:mod:`parmpm.io.run_folder`): the default
``parmpm-out/<scene>`` becomes ``<scene>_2``, ``_3``, … when taken; an explicit ``--out`` that holds
another run is refused unless ``--overwrite`` is given.

Under MPI a user error that every rank raises (a bad scene is read by every rank) is printed once,
by rank 0, and every rank exits with 2. An error raised by some ranks only is printed by each of
them, and the job is aborted, since the other ranks may be waiting on them in a collective.
The two cases are told apart by a non-blocking barrier on a private communicator, given a few
seconds to complete.

MPI is optional (:mod:`parmpm.cli.launch`): without an MPI library mpi4py can load, parmpm runs on
one rank; started by a launcher as several ranks it stops instead, with one line on how to get it.
"""

from __future__ import annotations

import argparse
import os
import sys
import traceback
from pathlib import Path

from parmpm.core.errors import ParmpmError, RunInterrupted
from parmpm.cli.launch import all_ranks_here as _all_ranks_here
from parmpm.cli.launch import launcher_rank as _launcher_rank
from parmpm.cli.launch import launcher_size as _launcher_size
from parmpm.cli.launch import world as _world
from parmpm.shapes import interpolator_names

DEFAULT_SCENE = "hanging_bar"
DEFAULT_OUT = Path("parmpm-out")

_EPILOG = """\
examples:
  mpirun -n 2 python -m parmpm                       the default scene (2D hanging bar, cpdi, l_cr = 2dx)
  python -m parmpm scenes                            list the built-in scenes
  mpirun -n 4 python -m parmpm run hanging_bar --set method.interpolator=mpm --set time.end=0.1
  python -m parmpm run path/to/scene.toml --out results/
  python -m parmpm show hanging_bar > my.toml        the resolved scene, a file to edit and run
  python -m parmpm compile --dim 2 3                 fill numba's cache (all cases: ~1 min, once)

Without a command, parmpm runs the built-in scene 'hanging_bar'.
"""

_RUN_EPILOG = """\
--set takes a dotted scene key and a TOML value (a bare word is read as a string), e.g.
  --set method.interpolator=ugimp    --set method.lcr=1.5dx     --set grid.cells=[40,60]
  --set time.end=0.1                 --set bodies.0.ppc=3       --set gravity.g=[0,-9.81]
The scene keys are listed in the README (Scene reference) and in parmpm/scene/load.py.
"""


def _version() -> str:
    try:
        from importlib.metadata import PackageNotFoundError, version
    except ImportError:  # pragma: no cover
        return "unknown"
    try:
        return version("parmpm")
    except PackageNotFoundError:
        return "unknown (not installed)"


class _Parser(argparse.ArgumentParser):
    """argparse that prints (usage, errors, help) on rank 0 only: under ``mpirun -n 4`` a
    mistyped option is reported once; every rank still exits with code 2."""

    def _print_message(self, message, file=None):
        if _launcher_rank() == 0:
            super()._print_message(message, file)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="parmpm",
        description=f"MPI-parallel explicit Material Point Method solver ({interpolator_names()} "
        "with CPDI domain scaling). Run it under mpirun for several ranks.",
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    commands = parser.add_subparsers(dest="command", title="commands", metavar="COMMAND")

    run = commands.add_parser(
        "run",
        help="run a scene (the default command)",
        description="Run a scene on all MPI ranks; write snapshots, figures and summary.json to the "
        "output folder and print a summary.",
        epilog=_RUN_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    run.add_argument("scene", metavar="SCENE", nargs="?", default=DEFAULT_SCENE,
                     help="a built-in scene name (see 'parmpm scenes') or the path to a TOML scene "
                     f"file (default: {DEFAULT_SCENE})")
    run.add_argument("-s", "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                     help="override a scene value (repeatable; applied after the scene file)")
    run.add_argument("-o", "--out", type=_out_folder, default=None, metavar="DIR",
                     help=f"output folder (default: {DEFAULT_OUT}/<scene name>/)")
    run.add_argument("-q", "--quiet", action="store_true",
                     help="no progress bar, no info messages (warnings and errors still show)")
    run.add_argument("--overwrite", action="store_true",
                     help="if the --out folder holds another run, delete that run's results and "
                     "write there (without it such a folder is refused)")
    _logging_arguments(run)

    restart = commands.add_parser(
        "restart", help="continue a run from a checkpoint (any number of ranks)",
        description="Continue the run saved in CHECKPOINT (checkpoint_<step>.h5) bit for bit, on "
        "any number of ranks. --set changes the stored scene (e.g. time.end=0.5).",
        epilog=_RUN_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    restart.add_argument("checkpoint", metavar="CHECKPOINT", type=Path,
                         help="a checkpoint_<step>.h5 written by a run")
    restart.add_argument("-s", "--set", dest="overrides", action="append", default=[],
                         metavar="KEY=VALUE", help="override a value of the stored scene (repeatable)")
    restart.add_argument("-o", "--out", type=_out_folder, default=None, metavar="DIR",
                         help="output folder (default: restart_<step>/ beside the checkpoint)")
    restart.add_argument("-q", "--quiet", action="store_true",
                         help="no progress bar, no info messages (warnings and errors still show)")
    restart.add_argument("--overwrite", action="store_true",
                         help="if the --out folder holds another run, delete that run's results")
    _logging_arguments(restart)

    show = commands.add_parser(
        "show", help="print a scene, resolved, as TOML (a scene file to start from)",
        description="Print the scene with every default filled in and the --set overrides "
        "applied, as TOML: 'parmpm show hanging_bar > my.toml; parmpm run my.toml' runs the "
        "same scene.", epilog=_RUN_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    show.add_argument("scene", metavar="SCENE", nargs="?", default=DEFAULT_SCENE,
                      help=f"a built-in scene name or a TOML scene file (default: {DEFAULT_SCENE})")
    show.add_argument("-s", "--set", dest="overrides", action="append", default=[],
                      metavar="KEY=VALUE", help="override a scene value (repeatable)")

    commands.add_parser("scenes", help="list the built-in scenes",
                        description="List the built-in scenes: name and one-line description.")

    bench = commands.add_parser(
        "bench", help="time steps of a synthetic block (time per step, phases, halo share)",
        description="Benchmark the time-step loop on a translating neo-Hookean block of about "
        "--particles particles; print time per step and its phases (rank 0). Run under mpirun "
        "for several ranks; run_scripts/scaling.py compares rank counts.")
    from parmpm.cli.bench import add_arguments  # light: the solver is imported only when it runs
    add_arguments(bench)

    compile_ = commands.add_parser(
        "compile", help="compile the kernels into numba's cache (before a batch job's runs)",
        description="Run a tiny scene of each dimension, interpolator and update (USL, MUSL) "
        "for two steps, so that numba's cache holds every kernel a run uses and later runs "
        "start at once. The cache is the __pycache__ beside the installed sources, or "
        "NUMBA_CACHE_DIR (set it on a shared filesystem when the install is read-only).")
    from parmpm.cli.compile import add_arguments as add_compile_arguments
    add_compile_arguments(compile_)
    return parser


def _out_folder(text: str):
    """``--out``: a Path; an empty one stays "" so that the run refuses it (it would otherwise
    mean the current folder, written into without a word)."""
    return Path(text) if text else ""


def _check_out(args: argparse.Namespace) -> None:
    if getattr(args, "out", None) == "":
        raise ParmpmError("--out is empty: name the output folder (e.g. --out results; "
                          "'--out .' is the current folder)")


def _logging_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="debug messages (rank 0): set-up details, every kernel compiled")
    parser.add_argument("--log-file", type=str, default=None, metavar="PATH",
                        help="also write rank 0's messages (info, or debug with -v, even with "
                        "--quiet), the progress lines and the closing error to PATH (appended)")


def _one_line(message: str) -> str:
    return " ".join(part.strip() for part in str(message).splitlines() if part.strip())


def _cmd_scenes() -> int:
    from parmpm.scene.load import builtin_scenes

    scenes = builtin_scenes()
    width = max((len(name) for name in scenes), default=0)
    try:
        for name, description in scenes.items():
            print(f"{name:<{width}}  {description}".rstrip(), flush=True)
    except BrokenPipeError:  # `parmpm scenes | head -1`: the reader left; say nothing more
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0


def _cmd_show(args: argparse.Namespace) -> int:
    """The resolved scene as TOML on stdout: ``parmpm run`` of it runs the same scene."""
    from parmpm.scene.load import load_scene

    text = load_scene(args.scene, overrides=args.overrides).to_toml()
    try:
        sys.stdout.write(text)
        sys.stdout.flush()
    except BrokenPipeError:  # `parmpm show | head`: the reader left; say nothing more
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0


def _cmd_run(args: argparse.Namespace, rank: int, comm) -> int:
    from parmpm.scene.agreement import load_shared_scene

    # read once by rank 0, shared, compared on every rank (parmpm.scene.agreement); before the
    # heavy imports below
    scene = load_shared_scene(comm, args.scene, overrides=args.overrides)

    from parmpm.driver.simulation import Simulation
    from parmpm.driver.warm_up import compile_first, compile_notice
    from parmpm.io.summary import format_summary

    with compile_notice():
        summary = Simulation(scene, args.out, quiet=args.quiet or rank != 0, comm=comm,
                             overwrite=args.overwrite, warm_up=compile_first).run()
    if rank == 0:
        print(format_summary(summary), flush=True)
    return 0


def _cmd_restart(args: argparse.Namespace, rank: int, comm) -> int:
    from parmpm.driver.simulation import Simulation
    from parmpm.driver.warm_up import compile_first, compile_notice
    from parmpm.io.summary import format_summary

    with compile_notice():
        sim = Simulation.from_checkpoint(args.checkpoint, args.overrides, args.out,
                                         quiet=args.quiet or rank != 0, comm=comm,
                                         overwrite=args.overwrite, warm_up=compile_first)
        summary = sim.run()
    if rank == 0:
        print(format_summary(summary), flush=True)
    return 0


def _cmd_bench(args: argparse.Namespace, rank: int, comm) -> int:
    from parmpm.cli.bench import run_benches
    from parmpm.driver.warm_up import compile_notice

    with compile_notice():
        run_benches(args, comm)  # rank 0 prints the tables
    return 0


def _cmd_compile(args: argparse.Namespace, rank: int, comm) -> int:
    from parmpm.cli.compile import run_compile

    return run_compile(args, comm)


def _interrupt_on_sigterm() -> None:
    """SIGTERM (a batch system's time limit, ``timeout``, ``kill``) and SIGHUP (a closed terminal,
    unless ``nohup``) stop parmpm like Ctrl-C: outside a running time loop, as KeyboardInterrupt
    (nothing is lost: there is nothing to save yet, or the run has finished), exit code 130 and
    one line; inside it, the run's own handler takes over and writes a checkpoint first
    (:meth:`parmpm.driver.simulation.Simulation.run`; :mod:`parmpm.driver.signals`)."""
    import signal
    import threading

    from parmpm.driver.signals import is_hangup, silence_hung_up_terminal, to_handle

    def interrupt(signum, frame):
        if is_hangup(signum):  # a closed terminal: later writes to it must not fail
            silence_hung_up_terminal()
        raise KeyboardInterrupt

    if threading.current_thread() is threading.main_thread():
        for sig in to_handle():
            if sig != signal.SIGINT:  # Ctrl-C raises KeyboardInterrupt already
                signal.signal(sig, interrupt)


def _setup_logging(args: argparse.Namespace, rank: int, size: int, comm) -> None:
    """The logging of the module docstring; a log file rank 0 cannot open fails on every rank."""
    import logging

    from parmpm.core.log import setup_logging

    problem = None
    try:
        setup_logging(rank, size, quiet=args.quiet, verbose=getattr(args, "verbose", False),
                      log_file=getattr(args, "log_file", None))
    except ParmpmError as exc:
        setup_logging(rank, size, quiet=args.quiet)
        problem = str(exc)
    if comm is not None and size > 1:
        from parmpm.core.collective import agree

        agree(comm, problem)
    elif problem:
        raise ParmpmError(problem)
    if rank == 0:
        from parmpm.io.summary import parmpm_version

        logging.getLogger("parmpm").debug("parmpm %s on %d rank(s): %s", parmpm_version(), size,
                                          " ".join(sys.argv))


def _run_guarded(args: argparse.Namespace) -> int:
    """``run`` with MPI set up and the error policy of the module docstring applied."""
    import logging

    from parmpm.core.log import close_log_file, get_logger, setup_logging, to_file_only

    _interrupt_on_sigterm()
    try:
        # `parmpm compile` outside a launcher needs no MPI (a batch shell may not start it)
        solo = args.command == "compile" and _launcher_size() == 1
        rank, size, comm = (0, 1, None) if solo else _world()
    except ParmpmError as exc:  # several ranks, no MPI: each process is alone, rank 0 says it
        if _launcher_rank() == 0:
            print(f"parmpm: error: {_one_line(exc)}", file=sys.stderr, flush=True)
        return 2
    _interrupt_on_sigterm()  # again: MPI's start-up puts a SIGHUP handler of its own in place
    setup_logging(rank, size, quiet=args.quiet)
    # A private communicator for the error handshake, so that it can never match a collective
    # that other ranks are blocked in on COMM_WORLD. (Dup is collective: every rank is here.)
    err_comm = comm.Dup() if comm is not None and size > 1 else None
    log = get_logger(__name__)

    def fail(message: str, code: int) -> int:
        to_file_only(log, message, logging.ERROR)
        if _all_ranks_here(err_comm):
            if rank == 0:
                print(message, file=sys.stderr, flush=True)
            return code
        print(message, file=sys.stderr, flush=True)
        comm.Abort(code)
        return code  # pragma: no cover (Abort does not return)

    try:
        _setup_logging(args, rank, size, comm)
        _check_out(args)
        command = {"bench": _cmd_bench, "restart": _cmd_restart,
                   "compile": _cmd_compile}.get(args.command, _cmd_run)
        return command(args, rank, comm)
    except RunInterrupted as exc:
        return fail(f"parmpm: {_one_line(exc)}", 130)
    except ParmpmError as exc:
        return fail(f"parmpm: error: {_one_line(exc)}", 2)
    except KeyboardInterrupt:
        return fail("parmpm: interrupted", 130)
    except RuntimeError as exc:
        if "no locator available" not in str(exc):  # numba's: no folder it can cache into
            return _bug(log, size, comm)
        return fail(f"parmpm: error: numba cannot cache the kernels: {_one_line(exc)} (no "
                    "writable __pycache__ beside the sources, nor ~/.cache/numba); set "
                    "NUMBA_CACHE_DIR to a writable folder (on a cluster: one every node sees)", 2)
    except Exception:
        return _bug(log, size, comm)
    finally:
        close_log_file()


def _bug(log, size: int, comm) -> int:
    """An exception no user caused: the traceback (also into the log file), exit code 1; under
    MPI the job is aborted, since other ranks may be waiting for this one."""
    import logging

    from parmpm.core.log import to_file_only

    to_file_only(log, traceback.format_exc().rstrip(), logging.ERROR)
    traceback.print_exc()
    sys.stderr.flush()
    if size > 1:
        comm.Abort(1)
    return 1


def _default_command(argv: list[str]) -> list[str]:
    """``run`` is the default command: ``parmpm``, ``parmpm --quiet`` and ``parmpm --set k=v``
    mean ``parmpm run hanging_bar ...`` (the top-level --help and --version stay)."""
    if not argv or (argv[0].startswith("-") and argv[0] not in ("-h", "--help", "--version")):
        return ["run", *argv]
    return argv


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` (default ``sys.argv[1:]``), run the command and return the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(_default_command(argv))
    if args.command in ("scenes", "show"):  # no MPI, no solver
        try:
            return _cmd_scenes() if args.command == "scenes" else _cmd_show(args)
        except ParmpmError as exc:
            print(f"parmpm: error: {_one_line(exc)}", file=sys.stderr)
            return 2
    return _run_guarded(args)

