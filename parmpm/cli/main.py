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
another run, or files parmpm did not write, is refused unless ``--overwrite`` is given; a folder
where the run would delete or replace a file it reads (its scene, its bodies' files, a restart's
checkpoint) is refused either way.

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
import sys
import time
import traceback

from parmpm.cli import commands
from parmpm.cli.launch import all_ranks_here as _all_ranks_here
from parmpm.cli.launch import launcher_rank as _launcher_rank
from parmpm.cli.launch import launcher_size as _launcher_size
from parmpm.cli.launch import world as _world
from parmpm.cli.parser import build_parser, check_out, default_command
from parmpm.core.errors import ParmpmError, RunInterrupted


def _one_line(message: str) -> str:
    return " ".join(part.strip() for part in str(message).splitlines() if part.strip())


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
        _abort(comm, code)
        return code  # pragma: no cover (Abort does not return)

    try:
        _setup_logging(args, rank, size, comm)
        check_out(args)
        command = {"bench": commands.cmd_bench, "restart": commands.cmd_restart,
                   "compile": commands.cmd_compile}.get(args.command, commands.cmd_run)
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

    text = traceback.format_exc()
    to_file_only(log, text.rstrip(), logging.ERROR)
    sys.stderr.write(text)  # one write: the launcher forwards it whole or not at all
    sys.stderr.flush()
    if size > 1:
        _abort(comm, 1)
    return 1


#: how long a failing rank waits between its last words and the abort (seconds)
ABORT_GRACE_S = 0.5


def _abort(comm, code: int) -> None:
    """Abort the job, ``ABORT_GRACE_S`` after this rank's message: the launcher tears every
    process down at the abort and drops what it has not yet forwarded from their pipes (MPICH's
    hydra lost a failing rank's traceback, or all of its one line, about one time in six)."""
    sys.stdout.flush()
    sys.stderr.flush()
    time.sleep(ABORT_GRACE_S)
    comm.Abort(code)



def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` (default ``sys.argv[1:]``), run the command and return the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(default_command(argv))
    if args.command in ("scenes", "show"):  # no MPI, no solver
        try:
            return (commands.cmd_scenes() if args.command == "scenes"
                    else commands.cmd_show(args))
        except ParmpmError as exc:
            print(f"parmpm: error: {_one_line(exc)}", file=sys.stderr)
            return 2
    return _run_guarded(args)


