"""Collective agreement on errors: a problem found on one rank is raised on every rank.

A rank that raises alone leaves the others waiting in their next collective, and ``mpirun``
prints the error once per rank (or not at all when the job is aborted). So every check that can
fail on some ranks only ends in :func:`agree`, which hands each rank the same one-line message
and raises it everywhere at once. The CLI then prints it once and exits with 2
(:mod:`parmpm.__main__`).
"""
from __future__ import annotations

from parmpm.core.errors import ParmpmError


def agree(comm, problem: str | None, root: int | None = 0, error: type = ParmpmError,
          key=None) -> None:
    """Raise ``error(message)`` on every rank when a rank has a ``problem`` (None: none).

    ``root`` given: only that rank knows (a writer's problem), one broadcast. ``root=None``: any
    rank may have one; the message raised is the one with the smallest ``key`` (default: the
    rank, so the lowest rank's), the same on every rank.
    """
    if root is not None:
        problem = comm.bcast(problem, root=root)
        if problem:
            raise error(problem)
        return
    rank = comm.Get_rank()
    found = [(k, p) for k, p in comm.allgather((rank if key is None else key, problem)) if p]
    if found:
        raise error(min(found, key=lambda kp: kp[0])[1])
