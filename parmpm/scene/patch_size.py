"""``grid.patch_size = "auto"`` (the default): a patch size chosen from the scene alone, and the
start-up warning about ranks left without work.

The patch, not the rank, is the unit of computation and of summation order, which is why a run
gives the same bits on any number of ranks; so the patch size must never depend on the rank
count. But a scene smaller than one default patch (:data:`parmpm.scene.schema.DEFAULT_PATCH_SIZE`:
64 cells per axis in 1D and 2D, 16 in 3D) holds all its particles in one patch, and every rank
but one would idle. :func:`auto_patch_size` therefore starts from the default and halves it while
the bodies cover fewer than :data:`TARGET_PATCHES` patches, down to :func:`floor_size`.

Why these numbers (``parmpm bench`` and direct runs, one rank, ns per particle-step, best of 3;
``g``: ghost cells; the minimal scene of docs/reference/scenes.md at 64 and 32 is one 20 x 32 patch):

==============================  =====  =====  =====  =====  =====
case                               64     32     16      8      4
==============================  =====  =====  =====  =====  =====
2D cpdi, 1e5 particles, g 2       108    107    107    110    141
2D cpdi, 1e4 particles, g 2       112    112    116    118    131
2D cpdi, 3e4, ppc 3, g 2          102    102    105    106    110
2D cpdi, 1e5, l_cr 4dx, g 4       110    108    114    132      -
2D mpm, 1e5 particles, g 0         69     70     74     79     95
3D cpdi, 1e5 particles, g 2         -      -    451    428    472
1D cpdi, 1e4 particles, g 2        92     91     93    114    146
minimal scene, 400 particles        -    196    207    215    247
==============================  =====  =====  =====  =====  =====

Patches of 8 cells cost at most 5 % more than 64 in 2D and 3D (mpm: 14 %), 4 cells 10-60 %, and
a ghost layer of ``g`` cells costs little while ``P >= 4g`` (``g = 4``: 16 cells +5 %, 8 cells
+20 %); 1D patches of 8 cells hold too few particles (+24 %). Hence the floor ``max(16 in 1D,
8 in 2D/3D; 4·ghost)``. Sixteen occupied patches spread over 2-6 ranks within 25 % of an even
split (``⌈16/P⌉/(16/P) − 1``), where eight would leave 6 ranks 50 % apart. The bodies' patches
are counted from their particle lattices (unturned boxes: exact, the same coordinates and patch
formula as :mod:`parmpm.particles.seeding`) or their bounding boxes (disks, spheres, turned boxes,
polygons, cylinders, CSG bodies: an upper bound), with no particle made; a halving that would index more than :data:`MAX_DENSE_PATCHES`
patches of the bounding grid (a small body in a huge grid; every rank indexes them all) stops.
"""
from __future__ import annotations

import itertools
import math

import numpy as np

from decomposition.boxes import patch_of_coordinate
from decomposition.layout import PatchLayout
from decomposition.partition import active_patches, assign, rank_loads
from parmpm.scene.records import SceneSpec
from parmpm.scene.schema import DEFAULT_PATCH_SIZE

#: occupied patches the automatic size aims for (halving stops once the bodies cover this many)
TARGET_PATCHES = 16
#: the smallest automatic patch per dimension (measured above; raised to 4·ghost)
MIN_PATCH = {1: 16, 2: 8, 3: 8}
#: a halving that would index more patches of the bounding grid than this is not taken
#: (``parmpm.driver.footprint``: 256 B each on every rank, i.e. 8 MB)
MAX_DENSE_PATCHES = 2 ** 15


def floor_size(dim: int, ghost: int) -> int:
    """The smallest patch the automatic size and the idle-rank advice go to: a ghost layer of
    ``ghost`` cells around it adds at most half its width on each side."""
    return max(MIN_PATCH[dim], 4 * int(ghost))


def _clip(size: int, cells) -> list[int]:
    return [min(int(size), int(n)) for n in cells]


def _grid_frame(spec: SceneSpec, exterior):
    """(cells, origin, 1/h) of the computational grid: the user's widened by the exterior layer
    (as :meth:`parmpm.transfer.discretisation.Discretisation.from_grid` lays it out)."""
    grid = spec.grid
    lo, hi = (np.zeros(spec.dim, np.int64),) * 2 if exterior is None else exterior
    h = np.asarray(grid.cell_size, float)
    cells = np.asarray(grid.cells, np.int64) + lo + hi
    origin = np.asarray(grid.origin, float) - lo * h
    return cells, origin, 1.0 / h


def _body_extents(spec: SceneSpec) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per body, the lowest and highest coordinate its particles can have per axis: the first and
    last lattice point of an unturned box (seeding's formula, so the same floats), else the
    bounding box."""
    h = np.asarray(spec.grid.cell_size, float)
    out = []
    for body in spec.bodies:
        if body.shape == "box" and not body.angle:
            lo, hi = np.asarray(body.min, float), np.asarray(body.max, float)
            count = np.maximum(1, np.round((hi - lo) / h * np.asarray(body.ppc, float))).astype(int)
            spacing = (hi - lo) / count
            ends = [lo[k] + (np.array([0, count[k] - 1]) + 0.5) * spacing[k]
                    for k in range(spec.dim)]
            out.append((np.array([e[0] for e in ends]), np.array([e[1] for e in ends])))
        else:
            bmin, bmax = body.bounds()
            out.append((np.asarray(bmin, float), np.asarray(bmax, float)))
    return out


def covered_patches(spec: SceneSpec, size: int, exterior=None, stop: int | None = None) -> int:
    """Patches of ``size`` cells (clipped to the grid per axis) that the bodies' particles can lie
    in (:func:`_body_extents`); counting ends at ``stop`` when given."""
    cells, origin, inv_h = _grid_frame(spec, exterior)
    psize = _clip(size, spec.grid.cells)
    seen: set = set()
    for bmin, bmax in _body_extents(spec):
        ranges = []
        for k in range(spec.dim):
            ends = []
            for x in (bmin[k], bmax[k]):
                u = min(max((float(x) - origin[k]) * inv_h[k], 0.0), float(cells[k] - 1))
                ends.append(patch_of_coordinate(u, int(cells[k]), psize[k], 1.0 / psize[k]))
            ranges.append(range(ends[0], ends[1] + 1))
        for key in itertools.product(*ranges):
            seen.add(key)
            if stop is not None and len(seen) >= stop:
                return len(seen)
    return len(seen)


def dense_patches(spec: SceneSpec, size: int, exterior=None) -> int:
    """Patches of ``size`` cells in the whole computational grid."""
    cells, _, _ = _grid_frame(spec, exterior)
    return math.prod(-(-int(n) // p) for n, p in zip(cells, _clip(size, spec.grid.cells)))


def auto_patch_size(spec: SceneSpec, ghost: int, exterior=None) -> list[int]:
    """The patch size of a resolved scene whose ``grid.patch_size`` is ``"auto"``, per axis: the
    default, halved while the bodies cover fewer than :data:`TARGET_PATCHES` patches and the
    half stays at or above :func:`floor_size` and indexes at most :data:`MAX_DENSE_PATCHES`;
    clipped to the cell count as an explicit size is. ``exterior``: the exterior layer's cells
    ``(lo, hi)`` (:func:`parmpm.transfer.discretisation.exterior_cells`). Depends on the scene only, never
    on the number of ranks."""
    size, floor = DEFAULT_PATCH_SIZE[spec.dim], floor_size(spec.dim, ghost)
    while (size // 2 >= floor
           and covered_patches(spec, size, exterior, stop=TARGET_PATCHES) < TARGET_PATCHES
           and dense_patches(spec, size // 2, exterior) <= MAX_DENSE_PATCHES):
        size //= 2
    return _clip(size, spec.grid.cells)


# ---------------------------------------------------------------- ranks without work


def _rank_list(ranks) -> str:
    """``[1, 2, 3, 5]`` -> ``"1-3, 5"``."""
    parts, ranks = [], sorted(int(r) for r in ranks)
    start = prev = ranks[0]
    for r in ranks[1:] + [None]:
        if r is not None and r == prev + 1:
            prev = r
            continue
        parts.append(f"{start}" if start == prev else f"{start}-{prev}")
        if r is not None:
            start = prev = r
    return ", ".join(parts)


def rank_loads_at(layout: PatchLayout, counts: np.ndarray, ranks: int) -> np.ndarray:
    """Particles per rank when the patches of ``layout`` holding ``counts`` (dense, per patch)
    are dealt out to ``ranks`` ranks as a run starts (:class:`decomposition.PatchSet`)."""
    counts = np.asarray(counts, np.int64)
    ids = active_patches(layout, np.flatnonzero(counts))
    return rank_loads(assign(layout, ids, counts[ids], ranks), counts[ids], ranks)


def busy_ranks(layout: PatchLayout, counts: np.ndarray, ranks: int) -> int:
    """The most ranks, up to ``ranks``, that all start with particles on ``layout``."""
    return max((r for r in range(ranks, 0, -1) if np.all(rank_loads_at(layout, counts, r) > 0)),
               default=1)


def idle_ranks_warning(layout: PatchLayout, counts: np.ndarray, ranks: int, dim: int,
                       count_at) -> str | None:
    """One line naming the ranks that start without particles and the fix, or None when every
    rank has some. ``counts``: particles per patch of ``layout`` (dense); ``count_at(size)``:
    ``(layout, counts)`` of the same run with ``grid.patch_size = size``. The advice is computed:
    the largest halving of the patch size (down to :func:`floor_size`) that gives every rank
    work, else the fewest ranks and largest patch size that keep the most ranks busy."""
    counts = np.asarray(counts, np.int64)
    idle = np.flatnonzero(rank_loads_at(layout, counts, ranks) == 0)
    if idle.size == 0:
        return None
    n = int(np.count_nonzero(counts))
    who = (f"rank {_rank_list(idle)} has" if idle.size == 1 else f"ranks {_rank_list(idle)} have")
    head = (f"{ranks} ranks and {n} patch{'es' if n != 1 else ''} holding particles: {who} no "
            "work")
    size, floor = max(layout.patch_size), floor_size(dim, layout.ghost)
    most, advice = busy_ranks(layout, counts, ranks), None
    while size // 2 >= floor:
        size //= 2
        lay, there = count_at(size)
        m = int(np.count_nonzero(there))
        busy = busy_ranks(lay, np.asarray(there, np.int64), ranks)
        if busy == ranks:
            return f"{head}; set grid.patch_size = {size} (gives {m} patches)"
        if busy > most:
            most, advice = busy, f" with grid.patch_size = {size} ({m} patches)"
    plural = "s" if most != 1 else ""
    working = ranks - idle.size
    if working > most:  # "at most 3" alone reads wrong when 4 ranks have work now
        return (f"{head} ({working} of {ranks} do); every rank has work on {most} "
                f"rank{plural}{advice or ''}")
    return f"{head}; run on at most {most} rank{plural}{advice or ''}"
