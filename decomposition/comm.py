"""The communicator seen by the decomposition: an mpi4py communicator, or a one-rank stand-in.

A serial run is the parallel run with one rank, so the same code calls the same methods; only
the handful used here are provided by :class:`SerialComm`. Collective helpers that need MPI
constants (``MAX``) live here so that no other module has to branch on the communicator type.
"""
from __future__ import annotations

import numpy as np


class SerialComm:
    """The subset of ``mpi4py.MPI.Comm`` used by parmpm, for one process without MPI."""

    def Get_rank(self) -> int:
        return 0

    def Get_size(self) -> int:
        return 1

    def allgather(self, obj):
        return [obj]

    def gather(self, obj, root=0):
        return [obj]

    def bcast(self, obj, root=0):
        return obj

    def Barrier(self) -> None:
        pass


def world(use_mpi: bool = True):
    """``MPI.COMM_WORLD`` when mpi4py imports, else a :class:`SerialComm` (also when mpi4py is
    installed without an MPI library: its import then raises ``RuntimeError``)."""
    if use_mpi:
        try:
            from mpi4py import MPI
        except (ImportError, RuntimeError):
            return SerialComm()
        return MPI.COMM_WORLD
    return SerialComm()


def is_parallel(comm) -> bool:
    return comm is not None and comm.Get_size() > 1


def ranks_on_this_node(comm) -> int:
    """How many ranks of ``comm`` share this node's memory (collective under MPI)."""
    if not is_parallel(comm):
        return 1
    from mpi4py import MPI

    node = comm.Split_type(MPI.COMM_TYPE_SHARED)
    try:
        return node.Get_size()
    finally:
        node.Free()


def allreduce_max(comm, values: np.ndarray) -> np.ndarray:
    """Element-wise maximum of a float64 vector over all ranks (exact: max has no rounding)."""
    values = np.ascontiguousarray(values, dtype=np.float64)
    if not is_parallel(comm):
        return values.copy()
    from mpi4py import MPI

    out = np.empty_like(values)
    comm.Allreduce(values, out, op=MPI.MAX)
    return out


def ordered_sum(comm, keys: np.ndarray, partials: np.ndarray) -> np.ndarray:
    """Σ of per-item partial sums over all ranks, added in ascending ``keys`` order.

    Each rank passes the partial sums of the items (patches) it holds; every rank gets the same
    total, rounded the same way whichever rank held which item: the foundation of rank-count
    independent reductions (energies, metrics).
    """
    keys = np.asarray(keys, dtype=np.int64)
    partials = np.asarray(partials, dtype=np.float64)
    if partials.ndim != 2 or partials.shape[0] != keys.size:
        raise ValueError(f"partials must be (len(keys), k), got {partials.shape} for {keys.size} keys")
    if is_parallel(comm):
        parts = comm.allgather((keys, partials))
        keys = np.concatenate([k for k, _ in parts])
        partials = np.concatenate([p for _, p in parts])
    if keys.size == 0:
        return np.zeros(partials.shape[1])
    order = np.argsort(keys, kind="stable")
    # cumsum adds strictly in sequence (np.sum's pairwise blocking is not an order we control)
    return np.cumsum(partials[order], axis=0)[-1]


def max_and_patch_sum(comm, maxima: np.ndarray, partials: np.ndarray, owner: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """One collective for what a time step's end agrees on: the element-wise maximum of
    ``maxima`` over all ranks (as :func:`allreduce_max`), and the sum of every existing patch's
    row of ``partials`` added in ascending patch id (as :func:`ordered_sum`: the same bits on any
    number of ranks).

    ``partials`` is this rank's (own patches, k) rows in slot order (ascending id); ``owner`` the
    rank of every existing patch in ascending id (:attr:`decomposition.PatchSet.owner`, the same
    on every rank), from which every rank knows how many rows every other sends: one
    ``Allgatherv`` of plain buffers, where an ``Allreduce`` and an ``allgather`` of pickled
    arrays were two synchronisations per step.
    """
    maxima = np.ascontiguousarray(maxima, dtype=np.float64)
    partials = np.asarray(partials, dtype=np.float64)
    m, k = maxima.size, partials.shape[1]
    if not is_parallel(comm):
        rows = partials
        top = maxima.copy()
    else:
        from mpi4py import MPI

        counts = np.bincount(owner, minlength=comm.Get_size()) * k + m
        send = np.concatenate([maxima, partials.ravel()])
        if send.size != counts[comm.Get_rank()]:
            raise ValueError(f"partials must be (own patches, k), got {partials.shape} for "
                             f"{(counts[comm.Get_rank()] - m) // max(k, 1)} own patches")
        recv = np.empty(int(counts.sum()))
        displs = np.concatenate([[0], np.cumsum(counts)[:-1]])
        comm.Allgatherv(send, [recv, counts, displs, MPI.DOUBLE])
        top = recv[displs[:, None] + np.arange(m)].max(axis=0)
        blocks = np.delete(recv, (displs[:, None] + np.arange(m)).ravel()).reshape(-1, k)
        # the blocks come rank after rank, each in ascending id: put the rows in id order
        rows = np.empty_like(blocks)
        rows[np.argsort(owner, kind="stable")] = blocks
    if rows.shape[0] == 0:
        return top, np.zeros(k)
    # cumsum adds strictly in sequence, as ordered_sum does
    return top, np.cumsum(rows, axis=0)[-1]


#: the tag of :func:`deal_from_root`'s messages
TAG_DEAL = 107


def deal_from_root(comm, part_for, root: int = 0):
    """This rank's part, dealt out by ``root``: it makes each other rank's with ``part_for(rank)``
    (e.g. a tuple of numpy arrays) and sends it before making the next, so that it never holds
    more than one other rank's part at a time (a scatter holds them all); the other ranks
    receive theirs. Collective."""
    if comm.Get_rank() != root:
        return comm.recv(source=root, tag=TAG_DEAL)
    for r in range(comm.Get_size()):
        if r != root:
            comm.send(part_for(r), dest=r, tag=TAG_DEAL)
    return part_for(root)
