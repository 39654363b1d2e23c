"""Which patches exist and which rank owns each: the sparse active set and SFC partitioning.

* :func:`active_patches` — "model no more than a scene needs": the patches that hold records
  (particles) plus every patch within halo reach of them (their ghost contributions land there
  and records may move there in one step). Nothing else is allocated.
* :func:`morton_order` / :func:`split_contiguous` / :func:`assign` — patches ordered along a
  Morton (Z-order) space-filling curve and cut into contiguous pieces of near-equal weight
  (weight = records + 1, so empty patches, which still carry grid work, spread too). Contiguous
  pieces of an SFC keep each rank's patches compact, so most halo pairs stay on one rank.
* :func:`imbalance` — ``max / mean − 1`` of the per-rank loads.
"""
from __future__ import annotations

import numpy as np

from decomposition.boxes import flat_patch_id
from decomposition.layout import PatchLayout


def adjacency_offsets(layout: PatchLayout) -> np.ndarray:
    """(k, 3) offsets of all patches within halo reach (and at least the 3^d − 1 adjacent)."""
    offs = layout.neighbour_offsets()
    return np.array(offs, dtype=np.int64).reshape(-1, 3)


def shift_patches(layout: PatchLayout, ids: np.ndarray, off) -> tuple[np.ndarray, np.ndarray]:
    """Flat ids of the patches at ``coords(ids) + off`` and a mask of those inside the layout."""
    n = layout.patches_per_axis
    c = layout.patch_coords()[ids] + np.asarray(off, dtype=np.int64)
    ok = np.all((c >= 0) & (c < n), axis=1)
    c = np.where(ok[:, None], c, 0)
    return flat_patch_id(c, n), ok


def active_patches(layout: PatchLayout, occupied: np.ndarray) -> np.ndarray:
    """Sorted flat ids of the occupied patches and every patch within halo reach of one."""
    occupied = np.unique(np.asarray(occupied, dtype=np.int64))
    mark = np.zeros(layout.n_patches, bool)
    mark[occupied] = True
    for off in adjacency_offsets(layout):
        ids, ok = shift_patches(layout, occupied, off)
        mark[ids[ok]] = True
    return np.flatnonzero(mark).astype(np.int64)


def morton_keys(coords: np.ndarray) -> np.ndarray:
    """Z-order keys of (n, 3) non-negative integer coordinates (21 bits per axis)."""
    c = np.asarray(coords, dtype=np.uint64)
    key = np.zeros(c.shape[0], dtype=np.uint64)
    for bit in range(21):
        for a in range(3):
            key |= ((c[:, a] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + a)
    return key


def morton_order(layout: PatchLayout, ids: np.ndarray) -> np.ndarray:
    """``ids`` sorted along the Morton curve of their patch coordinates."""
    ids = np.asarray(ids, dtype=np.int64)
    keys = morton_keys(layout.patch_coords()[ids])
    return ids[np.argsort(keys, kind="stable")]


def split_contiguous(weights: np.ndarray, n_parts: int) -> np.ndarray:
    """Part index (0..n_parts-1, non-decreasing) of each item so that consecutive items form
    pieces of near-equal total weight: an item goes to the part its weight midpoint falls in."""
    w = np.asarray(weights, dtype=np.float64)
    if w.size == 0:
        return np.zeros(0, np.int64)
    total = float(w.sum())
    mid = np.cumsum(w) - 0.5 * w
    part = np.floor(mid / total * n_parts).astype(np.int64) if total > 0 else \
        (np.arange(w.size) * n_parts) // w.size
    return np.clip(part, 0, n_parts - 1)


def assign(layout: PatchLayout, ids: np.ndarray, counts: np.ndarray, n_ranks: int) -> np.ndarray:
    """Owner rank of each of ``ids`` (aligned with ``ids``): contiguous Morton pieces weighted by
    ``counts + 1``."""
    ids = np.asarray(ids, dtype=np.int64)
    counts = np.asarray(counts, dtype=np.float64)
    order = np.argsort(morton_keys(layout.patch_coords()[ids]), kind="stable")
    owner = np.empty(ids.size, np.int64)
    owner[order] = split_contiguous(counts[order] + 1.0, n_ranks)
    return owner


def rank_loads(owner: np.ndarray, counts: np.ndarray, n_ranks: int) -> np.ndarray:
    """Records per rank."""
    return np.bincount(owner, weights=counts, minlength=n_ranks)


def imbalance(loads: np.ndarray) -> float:
    """``max / mean − 1`` (0 = perfectly balanced)."""
    loads = np.asarray(loads, dtype=np.float64)
    mean = loads.mean() if loads.size else 0.0
    return float(loads.max() / mean - 1.0) if mean > 0 else 0.0
