"""The rows of a checkpoint in rank order: which fields are stored, this rank's rows sorted by
(patch, id), and where every rank's rows and every patch's rows start in the file."""
from __future__ import annotations

import numpy as np

from parmpm.io.checkpoint.format import FIELDS
from parmpm.io.checkpoint.parts import rank_rows
from parmpm.particles.store import OPTIONAL_FIELDS, Particles

#: rows per message from a member to its lead (and per read of a version 1–3 file): bounds the
#: extra memory a rank holds
BLOCK = 1 << 18


def stored(P: Particles) -> list[str]:
    """The fields a checkpoint of ``P`` holds: :data:`FIELDS` but the optional fields ``P``
    does not carry (the same on every rank: the scene decides)."""
    return [k for k in FIELDS if k not in OPTIONAL_FIELDS or k in P.optional]


def rank_order(comm, P: Particles, n_patches: int):
    """(this rank's rows in file order, every rank's (patch ids, row counts), the first row of
    each rank, ``patch_rows``): collective."""
    order = np.lexsort((P.gid, P.patch))
    pids, pcounts = np.unique(P.patch[order], return_counts=True)
    all_patches = comm.allgather((pids, pcounts))
    first, index = rank_rows(all_patches, n_patches)
    return order, all_patches, first, index
