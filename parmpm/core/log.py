"""Rank-aware logging for parmpm (after Dedalus' ``dedalus/tools/logging.py``).

Library modules never ``print``; they log::

    from parmpm.core.log import get_logger
    logger = get_logger(__name__)
    logger.info("step %d, t = %.4g", step, t)

The entry point (the CLI, a run script) calls :func:`setup_logging` once with its MPI rank and
size: rank 0 then logs at INFO (DEBUG with ``verbose``, WARNING when ``quiet``), every other rank
at WARNING, so a message that all ranks emit appears once, while a warning from a single rank is
still seen. With more than one rank each record carries ``[rank/size]``. The rank is passed in:
this module does not import mpi4py.

``log_file`` (the CLI's ``--log-file``) also writes **rank 0's** records to a file, at INFO (DEBUG
with ``verbose``) whatever ``quiet`` says, with dates, plus the progress lines and the line the
run ends with. Rank 0's only: it tells the run's story (every collective error is raised on rank 0
too), one writer needs no locking on a shared filesystem, and a warning of another rank still
reaches stderr, the job's own log.
"""

from __future__ import annotations

import contextlib
import logging
import sys
from typing import TextIO

from parmpm.core.errors import ParmpmError

ROOT = "parmpm"
_DATEFMT = "%H:%M:%S"


def get_logger(name: str) -> logging.Logger:
    """Return the logger ``name`` under the ``parmpm`` hierarchy.

    ``parmpm.*`` names (``__name__`` inside the package) are used as they are; any other name
    (a run script's ``__main__``, say) is placed under ``parmpm.`` so that :func:`setup_logging`
    configures it too.
    """
    if name != ROOT and not name.startswith(ROOT + "."):
        name = f"{ROOT}.{name}"
    return logging.getLogger(name)


class _ParmpmHandler(logging.StreamHandler):
    """The console handler installed by :func:`setup_logging` (a marker class, so a repeat call
    replaces it). ``around`` (set by a progress bar) wraps each write, so that a record is
    printed above the bar instead of through it."""

    around = None

    def emit(self, record: logging.LogRecord) -> None:
        around = type(self).around
        with around() if around is not None else contextlib.nullcontext():
            super().emit(record)


class _ParmpmFileHandler(logging.FileHandler):
    """The ``--log-file`` handler (a marker class, like the console's)."""


def console_writes_around(factory) -> None:
    """``factory()``: a context manager every console record is written inside (None: none)."""
    _ParmpmHandler.around = factory


def setup_logging(rank: int, size: int, quiet: bool = False, stream: TextIO | None = None,
                  verbose: bool = False, log_file=None) -> logging.Logger:
    """Configure the ``parmpm`` logger for one MPI rank and return it.

    Rank 0 logs at INFO (DEBUG when ``verbose``, WARNING when ``quiet``), every other rank at
    WARNING. Records go to ``stream`` (default: ``sys.stderr``, so that stdout holds only the run
    summary), formatted ``HH:MM:SS LEVEL name: message``, prefixed with ``[rank/size]`` when
    ``size > 1``; on rank 0 also to ``log_file`` (appended; a file that cannot be opened is a
    :class:`ParmpmError`). Calling it again replaces the previous configuration.
    """
    logger = logging.getLogger(ROOT)
    for handler in [h for h in logger.handlers
                    if isinstance(h, (_ParmpmHandler, _ParmpmFileHandler))]:
        logger.removeHandler(handler)
        handler.close()

    prefix = f"[{rank}/{size}] " if size > 1 else ""
    console = _ParmpmHandler(sys.stderr if stream is None else stream)
    console.setFormatter(logging.Formatter(f"{prefix}%(asctime)s %(levelname)s %(name)s: "
                                           "%(message)s", _DATEFMT))
    level = logging.WARNING
    if rank == 0 and not quiet:
        level = logging.DEBUG if verbose else logging.INFO
    console.setLevel(level)
    logger.addHandler(console)
    if log_file is not None and rank == 0:
        try:
            file = _ParmpmFileHandler(log_file, mode="a", encoding="utf-8")
        except OSError as exc:
            raise ParmpmError(f"cannot write log file '{log_file}': "
                              f"{exc.strerror or exc}") from None
        file.setFormatter(logging.Formatter(f"{prefix}%(asctime)s %(levelname)s %(name)s: "
                                            "%(message)s", "%Y-%m-%d %H:%M:%S"))
        file.setLevel(logging.DEBUG if verbose else logging.INFO)
        logger.addHandler(file)
        level = min(level, file.level)
    logger.setLevel(level)
    logger.propagate = False  # the root logger may have handlers of its own: print each record once
    return logger


def to_file_only(logger: logging.Logger, message: str, level: int = logging.INFO) -> None:
    """Write ``message`` to the ``--log-file`` only (e.g. what the console shows otherwise:
    the progress bar's state, the error line the CLI prints)."""
    files = [h for h in logging.getLogger(ROOT).handlers if isinstance(h, _ParmpmFileHandler)]
    if not files or not logger.isEnabledFor(level):
        return
    record = logger.makeRecord(logger.name, level, "(parmpm)", 0, message, (), None)
    for handler in files:
        if record.levelno >= handler.level:
            handler.handle(record)


def close_log_file() -> None:
    """Flush and close the ``--log-file`` (at exit; the console handler stays)."""
    logger = logging.getLogger(ROOT)
    for handler in [h for h in logger.handlers if isinstance(h, _ParmpmFileHandler)]:
        logger.removeHandler(handler)
        handler.close()
