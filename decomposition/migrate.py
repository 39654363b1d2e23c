"""Moving records (particles) to the rank that owns their new position.

Records are a dict of equal-length numpy arrays (one per field; any trailing shape; float or
integer values below 2**53, which float64 carries exactly). Records bound for another rank are
packed field after field into one float64 row each and sent in one message per peer; every peer
gets a message, empty or not, so a receiver learns the count from the message itself (``Probe``)
and nothing waits on a handshake. Kept records come first in their old order, then received ones
in ascending peer order — the caller re-sorts into its canonical (patch, id) order anyway.
"""
from __future__ import annotations

import numpy as np

from decomposition.comm import is_parallel

TAG_MIGRATE = 103


def _width(a: np.ndarray) -> int:
    return int(np.prod(a.shape[1:], dtype=np.int64))


def pack(records: dict[str, np.ndarray], sel: np.ndarray) -> np.ndarray:
    """(len(sel), W) float64 rows holding every field of the selected records."""
    W = sum(_width(a) for a in records.values())
    out = np.empty((sel.size, W))
    col = 0
    for a in records.values():
        w = _width(a)
        out[:, col:col + w] = a[sel].reshape(sel.size, w)
        col += w
    return out


def unpack(rows: np.ndarray, like: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Inverse of :func:`pack`: arrays shaped and typed like ``like``'s."""
    out, col = {}, 0
    for name, a in like.items():
        w = _width(a)
        out[name] = rows[:, col:col + w].reshape((rows.shape[0],) + a.shape[1:]).astype(a.dtype)
        col += w
    return out


def migrate(records: dict[str, np.ndarray], dest: np.ndarray, comm, peers) -> dict[str, np.ndarray]:
    """Send each record to rank ``dest[i]``; return the records this rank now holds (the same
    dict object when nothing left or arrived). See :func:`exchange` for ``peers``."""
    keep, received = exchange(records, dest, comm, peers)
    if received is None and keep is None:
        return records
    out = {name: (a if keep is None else a[keep]) for name, a in records.items()}
    if received is not None:
        out = {name: np.concatenate([out[name], received[name]]) for name in records}
    return out


def exchange(records: dict[str, np.ndarray], dest: np.ndarray | None, comm, peers):
    """Send each record to rank ``dest[i]``; return ``(keep, received)``: the indices of the
    records that stay here (None: all of them), and the arrived records (a dict like
    ``records``, or None). ``dest=None`` says every record stays (the caller knows none moved);
    the peers still get their (empty) messages. Callers that re-sort anyway build their new
    arrays from both in one pass (no intermediate copies). ``peers`` are the ranks that may
    exchange records with this one (the relation must be symmetric); a ``dest`` outside ``peers``
    and this rank is a ValueError raised *before* anything is sent, so the caller decides how all
    ranks stop. ``peers=None`` means every rank. Only the leaving records are sorted and packed:
    a step in which few particles change rank costs one pass over ``dest``.
    """
    if not is_parallel(comm):
        if dest is not None and np.any(np.asarray(dest) != 0):
            raise ValueError("records addressed to another rank in a one-rank run")
        return None, None
    from mpi4py import MPI
    me, size = comm.Get_rank(), comm.Get_size()
    peers = np.array([r for r in range(size) if r != me] if peers is None else peers, np.int64)
    if dest is None:
        leaving = np.zeros(0, np.int64)
    else:
        dest = np.asarray(dest, dtype=np.int64)
        leaving = np.flatnonzero(dest != me)
    to = dest[leaving] if leaving.size else np.zeros(0, np.int64)
    allowed = np.zeros(size, bool)
    allowed[peers] = True
    if np.any(~allowed[to]):
        bad = int(to[~allowed[to]][0])
        raise ValueError(f"record addressed to rank {bad}, which is not a neighbour of rank {me}")
    order = np.argsort(to, kind="stable")
    to, leaving = to[order], leaving[order]
    bounds = np.searchsorted(to, peers, side="left")
    ends = np.searchsorted(to, peers, side="right")
    sends = []
    reqs = []
    for i, r in enumerate(peers):
        buf = pack(records, leaving[bounds[i]:ends[i]])
        sends.append(buf)
        reqs.append(comm.Isend([buf, MPI.DOUBLE], dest=int(r), tag=TAG_MIGRATE))
    W = sum(_width(a) for a in records.values())
    received = []
    status = MPI.Status()
    for r in peers:
        comm.Probe(source=int(r), tag=TAG_MIGRATE, status=status)
        n = status.Get_count(MPI.DOUBLE)
        buf = np.empty(n)
        comm.Recv([buf, MPI.DOUBLE], source=int(r), tag=TAG_MIGRATE)
        if n:
            received.append(buf.reshape(-1, W))
    MPI.Request.Waitall(reqs)
    keep = np.flatnonzero(dest == me) if leaving.size else None
    return keep, (unpack(np.concatenate(received), records) if received else None)
