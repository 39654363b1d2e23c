"""The ``parmpm`` command line run inside the test process, as a user's shell would see it.

A ``python -m parmpm`` subprocess spends about 1.5 s before its first step (imports, and every
cached kernel loaded anew; measured 1.7-1.8 s for a one-step run of the 1D bar, 2-core machine,
2026-11-29); the same command inside a pytest worker whose kernels are loaded takes 0.05 s. So a
one-rank command runs here through :func:`parmpm.cli.main.main`, with what a process boundary
gives it put back by hand: its own working directory, stdout and stderr captured (the logging's
console handler is bound to them), ``sys.argv``, the signal handlers and the ``parmpm`` logger as
they were, and ``SystemExit`` (argparse's usage errors) turned into the exit code.

A launch under ``mpirun`` is always a subprocess (with a timeout, so a hang fails). Set
``PARMPM_TEST_CLI=subprocess`` to run every command as a subprocess too (the old way: slower,
and the check that nothing here hides a difference).
"""
from __future__ import annotations

import contextlib
import io
import logging
import os
import signal
import subprocess
import sys
from pathlib import Path

from mpi_launch import mpirun as find_mpirun

REPO = Path(__file__).resolve().parents[2]
#: a hang, not a timing: a loaded CI machine runs 3x slower
TIMEOUT_S = 600


def in_process() -> bool:
    return os.environ.get("PARMPM_TEST_CLI", "in-process") != "subprocess"


def parmpm_cli(*args: str, cwd: Path | str | None = None, ranks: int = 1, mpirun: str | None = None,
               timeout: float = TIMEOUT_S) -> subprocess.CompletedProcess:
    """``python -m parmpm ARGS`` in ``cwd`` (default: the current folder): in this process on one
    rank, under ``mpirun -n ranks`` (a subprocess) on more."""
    if ranks > 1 or not in_process():
        cmd = [sys.executable, "-m", "parmpm", *args]
        if ranks > 1:
            cmd = [mpirun or find_mpirun(), "-n", str(ranks), *cmd]
        path = os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))
        return subprocess.run(cmd, cwd=cwd, env=dict(os.environ, PYTHONPATH=path),
                              capture_output=True, text=True, timeout=timeout)
    return _run_here(list(args), cwd)


def _run_here(args: list[str], cwd) -> subprocess.CompletedProcess:
    from parmpm.cli.main import main

    out, err = io.StringIO(), io.StringIO()
    logger = logging.getLogger("parmpm")
    saved_handlers, saved_level, saved_propagate = list(logger.handlers), logger.level, logger.propagate
    saved_signals = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    saved_argv, here = sys.argv, os.getcwd()
    sys.argv = [str(REPO / "parmpm" / "__main__.py"), *args]
    try:
        if cwd is not None:
            os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(args)
            except SystemExit as exc:  # argparse: usage errors (2), --help and --version (0)
                if exc.code is None or isinstance(exc.code, int):
                    code = exc.code or 0
                else:  # sys.exit("message"): printed, exit 1, as the interpreter does
                    print(exc.code, file=sys.stderr)
                    code = 1
    finally:
        os.chdir(here)
        sys.argv = saved_argv
        for s, handler in saved_signals.items():
            signal.signal(s, handler)
        for h in logger.handlers:
            if h not in saved_handlers:  # the run's console handler, bound to `err`
                h.close()
        logger.handlers[:] = saved_handlers
        logger.setLevel(saved_level)
        logger.propagate = saved_propagate
    return subprocess.CompletedProcess(["parmpm", *args], code, out.getvalue(), err.getvalue())
