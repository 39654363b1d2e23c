"""Particle-file bodies on several ranks: rank 0 reads the file, every rank holds its share.

A body's particles per patch need every particle's position, so one rank has to see the whole
file; rather than every rank reading it (each holding and scanning all N rows), rank 0 alone does
(the scene's check already did: the other ranks took its resolved scene,
:func:`parmpm.scene.agreement.load_shared_scene`). At set-up rank 0 counts every body's particles
per patch and broadcasts the counts (:func:`counted_by_root`); once the patches are dealt out it
finds each listed particle's rank and sends each rank the rows of its own particles, one rank
after another (:func:`share_listed`, :func:`decomposition.deal_from_root`). Every rank then
builds its particles from its :class:`parmpm.particles.seeding.listed.Share` as before: the same
global ids, the same bits, on any number of ranks. Rank 0's peak stays O(N) (the file, its patch
ids, the rows it sends one rank at a time); every other rank's is O(N/P). A mesh body's particles
are not read but made from its elements, and those are made P ways
(:mod:`parmpm.driver.mesh_slices`), its seeds awaiting their rows on every rank here.
"""
from __future__ import annotations

import numpy as np

from decomposition import deal_from_root, is_parallel
from parmpm.core.errors import ParmpmError
from parmpm.particles.seeding import Seeds, seed_bodies
from parmpm.particles.seeding.listed import Listed, Share
from parmpm.scene.recorded_files import LISTED_SHAPES


def shared_listing(comm, bodies) -> bool:
    """Whether rank 0 reads the listed bodies for every rank: several ranks, a mesh or particle
    body (known from the scene, before any file is read)."""
    return is_parallel(comm) and any(b.shape in LISTED_SHAPES for b in bodies)


def seeded_by_root(comm, grid, bodies, material_rows: dict) -> Seeds:
    """:func:`parmpm.particles.seeding.seed_bodies`, the particle files read on rank 0 only (the
    others' seeds await their rows; a mesh's seeds await theirs on every rank:
    :mod:`parmpm.driver.mesh_slices`); a problem on any rank is raised on every rank
    (collective)."""
    seeds, problem, kind = None, None, ParmpmError
    try:
        seeds = seed_bodies(grid, bodies, material_rows,
                            read_listed=("particles",) if comm.Get_rank() == 0 else ())
    except ParmpmError as exc:
        problem, kind = str(exc), type(exc)
    raise_lowest(comm, problem, kind)
    return seeds


def counted_by_root(comm, seeds: Seeds, disc) -> np.ndarray:
    """Particles per patch (:meth:`parmpm.particles.seeding.Seeds.patch_counts`), counted by
    rank 0, which holds every body's seeds, and broadcast; a particle outside the grid is rank
    0's one line on every rank (collective)."""
    counts, problem, kind = None, None, ParmpmError
    if comm.Get_rank() == 0:
        try:
            counts = seeds.patch_counts(disc)
        except ParmpmError as exc:
            problem, kind = str(exc), type(exc)
    counts, problem, kind = comm.bcast((counts, problem, kind), root=0)
    if problem:
        raise kind(problem)
    return counts


def share_listed(comm, seeds: Seeds, disc, rank_of: np.ndarray) -> None:
    """Replace every listed body's seeds by this rank's :class:`Share`: rank 0 finds each
    particle's patch, hence its rank (``rank_of``: per flat patch id), and sends every rank the
    rows of its own particles, one rank after another, so that rank 0 holds one rank's rows
    at a time besides the file (collective)."""
    rank, size = comm.Get_rank(), comm.Get_size()
    for k, (src, body, *rest) in enumerate(seeds.chunks):
        if body.shape != "particles":  # a mesh's: parmpm.driver.mesh_slices
            continue
        order = edges = None
        if rank == 0:
            owner = rank_of[seeds.patches_of(k, disc)]
            order = np.argsort(owner, kind="stable")  # by rank, ids increasing within each
            edges = np.searchsorted(owner[order], np.arange(size + 1))
            del owner
        mine = deal_from_root(comm, _rank_rows(src, order, edges), root=0)
        seeds.chunks[k] = (Share(len(src), *mine), body, *rest)


def _rank_rows(src: Listed, order, edges):
    """Rank ``r``'s rows, made when asked for (rank 0; ``order``: the seeds by rank, ``edges``:
    where each rank's begin)."""
    return lambda r: _rows(src, order[edges[r]:edges[r + 1]])


def _rows(src: Listed, ids: np.ndarray) -> tuple:
    """(ids, x, vol, velocity, material rows, F) of the seeds ``ids`` of ``src``."""
    pick = [None if a is None else a[ids] for a in (src.velocity, src.rows, src.F)]
    return (ids, src.x[ids], src.vol[ids], *pick)


def raise_lowest(comm, problem: str | None, kind: type) -> None:
    """Raise the lowest rank's problem, as its own class, on every rank."""
    found = [(p, k) for p, k in comm.allgather((problem, kind)) if p]
    if found:
        raise found[0][1](found[0][0])
