"""Bodies that overlap: the space two ``[[bodies]]`` share is seeded by both, so the scene holds
that material twice (two boxes overlapping by a third: 1722 kg where their union weighs 1554;
issue 28). Said once, on rank 0, before the first step, naming the bodies, the volume seeded
twice and its mass.

Why a warning and not an error: the scene runs as written (every particle is a valid particle),
and a scene that means its bodies to overlap says so by making them one body, their ``union``
(:mod:`parmpm.scene.parts`), seeded once; the warning gives the numbers to judge it by.

What is measured is what was seeded twice: for bodies ``i < j`` whose bounds meet, the particles
of the later body ``j`` whose reference position lies inside body ``i`` (strictly: a particle on
``i``'s surface is not counted, so bodies that only touch are silent). Their count, times
body ``j``'s particle volume and mass, is the overlap's volume (to the particle spacing: exact for
boxes whose lattices align with the overlap, ``O(Δx)`` of its surface otherwise; a CSG body's
inside test is :func:`parmpm.geometry.csg.inside`) and the extra
mass (a mesh or particle body ``j``: the sum of those particles' own volumes and masses; a mesh or
particle body has no inside test, so as body ``i`` it is not checked). Each rank counts its own particles (``O(N/P)``: a body's particles are a range of global
ids, and the test is elementwise) and the counts are summed over the ranks, integers, so the
message is the same on any number of ranks.
"""
from __future__ import annotations

import numpy as np

from decomposition import is_parallel
from parmpm.core.log import get_logger

log = get_logger(__name__)

#: volume units by dimension
UNITS = {1: "m", 2: "m²", 3: "m³"}
#: bodies listed point by point: no inside test, each particle its own volume
LISTED = ("mesh", "particles")


def candidate_pairs(bodies, dim: int) -> list[tuple[int, int]]:
    """Pairs ``(i, j)``, ``i < j``, whose bounds overlap with positive volume (``bodies``:
    their records, :class:`parmpm.scene.records.Body`); body ``i`` has an inside test."""
    bounds = [tuple(np.asarray(v, float) for v in b.bounds()) for b in bodies]
    pairs = []
    for j in range(len(bodies)):
        for i in range(j):
            if bodies[i].shape in LISTED:
                continue
            lo = np.maximum(bounds[i][0], bounds[j][0])
            hi = np.minimum(bounds[i][1], bounds[j][1])
            if np.all(hi > lo):
                pairs.append((i, j))
    return pairs


def local_counts(bodies, dim: int, pairs, first: np.ndarray, gid: np.ndarray,
                 x0: np.ndarray) -> np.ndarray:
    """Per pair ``(i, j)``: how many of these particles (global ids ``gid``, increasing, at
    reference positions ``x0``) are body ``j``'s (ids ``first[j] ≤ gid < first[j + 1]``) and
    lie inside body ``i``."""
    out = np.zeros(len(pairs), np.int64)
    gid = np.asarray(gid, np.int64)
    for k, (i, j) in enumerate(pairs):
        a, b = np.searchsorted(gid, [first[j], first[j + 1]])
        if b > a:
            out[k] = int(np.count_nonzero(bodies[i].inside(dim, x0[a:b])))
    return out


def seeded_twice(comm, spec, seeds, gid: np.ndarray, x0: np.ndarray) -> list[dict]:
    """The pairs of bodies with particles seeded twice, summed over every rank (collective:
    every rank calls it with its own particles, global ids ``gid`` at reference positions
    ``x0``; ``seeds``: the :class:`parmpm.particles.seeding.Seeds` they came from): for each, ``bodies``
    ``(i, j)``, ``particles`` (body ``j``'s inside body ``i``), their ``volume`` and ``mass``.
    The same on every rank. ``spec``: the scene (:class:`parmpm.scene.records.SceneSpec`)."""
    dim, bodies = spec.dim, spec.bodies
    pairs = candidate_pairs(bodies, dim)
    if not pairs:
        return []
    first = np.concatenate([[0], np.cumsum([len(c[0]) for c in seeds.chunks])]).astype(np.int64)
    gid, x0 = np.asarray(gid, np.int64), np.asarray(x0, float).reshape(-1, dim)
    if np.any(np.diff(gid) < 0):
        order = np.argsort(gid, kind="stable")
        gid, x0 = gid[order], x0[order]
    counts = local_counts(bodies, dim, pairs, first, gid, x0)
    sums = _listed_sums(spec, seeds, pairs, first, gid, x0)
    if is_parallel(comm):
        counts = np.sum(comm.allgather(counts), axis=0)
        sums = np.sum(comm.allgather(sums), axis=0)
    out = []
    for k, ((i, j), n) in enumerate(zip(pairs, counts)):
        if n > 0 and bodies[j].shape in LISTED:
            out.append({"bodies": (i, j), "particles": int(n), "volume": float(sums[k, 0]),
                        "mass": float(sums[k, 1])})
        elif n > 0:
            volume = float(n) * float(np.prod(seeds.chunks[j][2]))
            density = float(spec.materials[bodies[j].material].density)
            out.append({"bodies": (i, j), "particles": int(n), "volume": volume,
                        "mass": density * volume})
    return out


def _listed_sums(spec, seeds, pairs, first: np.ndarray, gid: np.ndarray,
                 x0: np.ndarray) -> np.ndarray:
    """Per pair whose body ``j`` is listed, the volume and mass of its particles inside body
    ``i`` (these particles' share), from the seeds this rank holds of body ``j`` (on several
    ranks only its own rows: :class:`parmpm.particles.seeding.listed.Share`)."""
    dim, bodies = spec.dim, spec.bodies
    names_of = {row: name for name, row in seeds.material_rows.items()}
    out = np.zeros((len(pairs), 2))
    for k, (i, j) in enumerate(pairs):
        if bodies[j].shape not in LISTED:
            continue
        a, b = np.searchsorted(gid, [first[j], first[j + 1]])
        ids = gid[a:b] - first[j]
        src = seeds.chunks[j][0]
        inside = np.asarray(bodies[i].inside(dim, x0[a:b]), bool)
        vol = src.vol[src.local(ids)][inside]
        names = (np.full(len(vol), bodies[j].material) if src.rows is None
                 else [names_of[int(r)] for r in src.material_rows(ids, -1)[inside]])
        rho = np.array([spec.materials[str(m)].density for m in names], float)
        out[k] = vol.sum(), (rho * vol).sum()
    return out


def message(overlap: dict, dim: int) -> str:
    """The warning's line for one :func:`seeded_twice` pair."""
    (i, j), n = overlap["bodies"], overlap["particles"]
    return (f"bodies.{i} and bodies.{j} overlap: {overlap['volume']:.4g} {UNITS[dim]} of "
            f"bodies.{j} ({n} particles, {overlap['mass']:.4g} kg) lies inside bodies.{i} and "
            "is seeded twice (the scene holds that material twice; make the bodies touch, not "
            "overlap)")


def check_overlaps(comm, spec, seeds, gid: np.ndarray, x0: np.ndarray) -> list[str]:
    """:func:`seeded_twice`, as warnings logged once, by rank 0 (collective). Returns the lines
    (the same on every rank)."""
    lines = [message(o, spec.dim) for o in seeded_twice(comm, spec, seeds, gid, x0)]
    if comm is None or comm.Get_rank() == 0:
        for line in lines:
            log.warning("%s", line)
    return lines
