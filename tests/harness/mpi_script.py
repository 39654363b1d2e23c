"""The end of every script the tests launch under ``mpirun``: run ``main`` and, should it raise
on one rank only, print the traceback and abort the job, so no other rank is left waiting in a
collective (the test then sees a non-zero exit instead of a hang)."""
from __future__ import annotations

import sys
import traceback


def run_or_abort(main) -> None:
    try:
        main()
    except BaseException:  # one rank failing alone must not leave the others waiting
        traceback.print_exc()
        sys.stderr.flush()
        from decomposition import world

        world().Abort(1)
