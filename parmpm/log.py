"""Rank-aware logging for parmpm (after Dedalus' ``dedalus/tools/logging.py``).

Library modules never ``print``; they log::

    from parmpm.log import get_logger
    logger = get_logger(__name__)
    logger.info("step %d, t = %.4g", step, t)

The entry point (the CLI, a run script) calls :func:`setup_logging` once with its MPI rank and
size: rank 0 then logs at INFO, every other rank at WARNING, so a message that all ranks emit
appears once, while a warning from a single rank is still seen. With more than one rank each
record carries ``[rank/size]``. The rank is passed in: this module does not import mpi4py.
"""

from __future__ import annotations

import logging
import sys
from typing import TextIO

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
    """The handler installed by :func:`setup_logging` (a marker class, so a repeat call replaces it)."""


def setup_logging(rank: int, size: int, quiet: bool = False, stream: TextIO | None = None) -> logging.Logger:
    """Configure the ``parmpm`` logger for one MPI rank and return it.

    Rank 0 logs at INFO (WARNING when ``quiet``), every other rank at WARNING. Records go to
    ``stream`` (default: ``sys.stderr``, so that stdout holds only the run summary), formatted
    ``HH:MM:SS LEVEL name: message``, prefixed with ``[rank/size]`` when ``size > 1``.
    Calling it again replaces the previous configuration.
    """
    logger = logging.getLogger(ROOT)
    for handler in [h for h in logger.handlers if isinstance(h, _ParmpmHandler)]:
        logger.removeHandler(handler)
        handler.close()

    prefix = f"[{rank}/{size}] " if size > 1 else ""
    handler = _ParmpmHandler(sys.stderr if stream is None else stream)
    handler.setFormatter(logging.Formatter(f"{prefix}%(asctime)s %(levelname)s %(name)s: %(message)s", _DATEFMT))
    logger.addHandler(handler)
    logger.setLevel(logging.INFO if rank == 0 and not quiet else logging.WARNING)
    logger.propagate = False  # the root logger may have handlers of its own: print each record once
    return logger
