"""``parmpm compile``: fill numba's cache for the cases named on the command line, on rank 0
while the other ranks of a launch wait (the work itself: :func:`parmpm.driver.warm_up.compile_kernels`)."""
from __future__ import annotations

import argparse
import time

from parmpm.core.errors import ParmpmError
from parmpm.core.log import get_logger
from parmpm.driver.warm_up import (COMPILED_UPDATES, DIMS, METHODS, compile_kernels,
                                   transfers_of, wait_for_all)
from parmpm.transfer.affine import TRANSFERS

log = get_logger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--dim", type=int, nargs="+", choices=DIMS, default=list(DIMS),
                        help="dimensions (default: 1 2 3)")
    parser.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS),
                        metavar="METHOD",
                        help=f"interpolators (default: all: {' '.join(METHODS)})")
    parser.add_argument("--update", nargs="+", choices=COMPILED_UPDATES,
                        default=list(COMPILED_UPDATES), help="USL, MUSL or both (default both)")
    parser.add_argument("--transfer", nargs="+", choices=TRANSFERS, default=list(TRANSFERS),
                        help="transfers, where the method takes them (default all: FLIP for "
                             "every method, APIC and MLS for bspline)")
    parser.add_argument("-q", "--quiet", action="store_true", help="no info messages")
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="debug messages (every kernel compiled, and its time)")
    parser.add_argument("--log-file", type=str, default=None, metavar="PATH",
                        help="also write rank 0's messages to PATH")


def run_compile(args: argparse.Namespace, comm) -> int:
    """``parmpm compile``: rank 0 compiles, the other ranks (if launched under MPI) wait."""
    transfers = getattr(args, "transfer", TRANSFERS)
    if not any(t in transfers_of(m) for m in args.methods for t in transfers):
        raise ParmpmError(f"compile: --transfer {' '.join(transfers)} applies to none of "
                          f"--methods {' '.join(args.methods)} (APIC and MLS: bspline only)")
    rank = comm.Get_rank() if comm is not None else 0
    try:
        if rank == 0:
            t0 = time.perf_counter()
            rows = compile_kernels(args.dim, args.methods, args.update, transfers)
            compiled = sum(r["compiled"] for r in rows)
            log.info("%d cases in %.0f s: %s", len(rows), time.perf_counter() - t0,
                     f"{compiled} kernels compiled" if compiled else "every kernel was cached")
    finally:
        if comm is not None and comm.Get_size() > 1:
            wait_for_all(comm)
    return 0
