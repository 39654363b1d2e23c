"""The live decomposition: which patches exist, which rank owns each, and the halo plan.

All ranks hold the same global picture (existing patch ids and their owners; small: one entry per
patch) and change it only together, at step boundaries, from globally gathered facts — so every
rank computes the same answer with no further negotiation:

* :meth:`PatchSet.update` — records moved: patches that became occupied pull their halo
  neighbourhood into existence, patches no longer within reach of any record are dropped. A new
  patch goes to the owner of the first occupied patch found in the fixed neighbour-offset order
  (deterministic, and local to the records that caused it).
* :meth:`PatchSet.rebalance` — when ``max/mean − 1`` of records per rank passes the threshold,
  the Morton partition is recomputed from the current counts and adopted if it is clearly better
  (otherwise the check rests for ``cooldown`` steps, so an unfixable imbalance — one patch
  heavier than a rank's share — costs nothing per step). Whole patches change owner; the caller
  then migrates their records.
"""
from __future__ import annotations

import numpy as np

from decomposition.comm import is_parallel
from decomposition.halo import HaloPlan
from decomposition.layout import PatchLayout
from decomposition.partition import (active_patches, adjacency_offsets, assign, imbalance,
                                     rank_loads, shift_patches)


class PatchSet:
    """Existing patches, their owners, this rank's slots and the halo plan between them."""

    def __init__(self, layout: PatchLayout, comm, counts: np.ndarray, threshold: float = 0.1,
                 cooldown: int = 50):
        self.layout, self.comm = layout, comm
        self.rank, self.size = comm.Get_rank(), comm.Get_size()
        self.threshold, self.cooldown = float(threshold), int(cooldown)
        self.rebalances, self.rebuilds, self._rest = 0, 0, 0
        counts = np.asarray(counts, dtype=np.int64)
        ids = active_patches(layout, np.flatnonzero(counts))
        self._build(ids, assign(layout, ids, counts[ids], self.size))

    def _build(self, ids: np.ndarray, owner: np.ndarray) -> None:
        self.plan = HaloPlan(self.layout, ids, owner, self.comm if is_parallel(self.comm) else None)
        p = self.plan
        self.ids, self.owner, self.rank_of, self.slot_of = p.ids, p.owner, p.rank_of, p.slot_of
        self.local_ids = p.local_ids
        # ranks that records can move to in one step: owners of every patch within reach
        near = set(int(r) for r in p.peers)
        for off in adjacency_offsets(self.layout):
            q, ok = shift_patches(self.layout, self.local_ids, off)
            near.update(int(r) for r in np.unique(self.rank_of[q[ok]]))
        near.discard(self.rank)
        near.discard(-1)
        self.peers = np.array(sorted(near), np.int64)

    @property
    def n_local(self) -> int:
        return int(self.local_ids.size)

    # --- global facts ------------------------------------------------------------------------
    def gather_counts(self, local_counts: np.ndarray) -> np.ndarray:
        """Dense per-patch record counts, from each rank's counts of its own patches."""
        counts = np.zeros(self.layout.n_patches, np.int64)
        parts = self.comm.allgather((self.local_ids, np.asarray(local_counts, np.int64)))
        for ids, c in parts:
            counts[ids] = c
        return counts

    def loads(self, counts: np.ndarray) -> np.ndarray:
        return rank_loads(self.owner, counts[self.ids], self.size)

    # --- changes (collective: every rank calls them with the same arguments) ------------------
    def update(self, counts: np.ndarray) -> bool:
        """Re-derive the existing patches from dense ``counts``; True if the set changed."""
        occupied = np.flatnonzero(counts)
        if np.any(self.rank_of[occupied] < 0):
            raise ValueError("records reached a patch that did not exist (moved > 1 patch)")
        ids = active_patches(self.layout, occupied)
        if np.array_equal(ids, self.ids):
            return False
        rank_of = self.rank_of.copy()
        new = ids[rank_of[ids] < 0]
        occ = np.zeros(self.layout.n_patches, bool)
        occ[occupied] = True
        for off in adjacency_offsets(self.layout):
            if new.size == 0:
                break
            q, ok = shift_patches(self.layout, new, off)
            hit = ok & occ[q]
            rank_of[new[hit]] = rank_of[q[hit]]
            new = new[~hit]
        if new.size:  # cannot happen: every active patch is within reach of an occupied one
            raise RuntimeError("a new patch has no occupied neighbour")
        self._build(ids, rank_of[ids])
        self.rebuilds += 1
        return True

    def ready_to_rebalance(self) -> bool:
        """False while the check rests after a re-partition that would not have helped."""
        if self.size == 1:
            return False
        if self._rest > 0:
            self._rest -= 1
            return False
        return True

    def rebalance(self, counts: np.ndarray) -> np.ndarray | None:
        """If the load imbalance passes the threshold and a Morton re-partition clearly helps,
        adopt it and return the previous dense ``rank_of`` (so the caller can move records);
        else None (and the check rests for ``cooldown`` calls of :meth:`ready_to_rebalance`)."""
        if self.size == 1:
            return None
        now = imbalance(self.loads(counts))
        if now <= self.threshold:
            return None
        owner = assign(self.layout, self.ids, counts[self.ids], self.size)
        new = imbalance(rank_loads(owner, counts[self.ids], self.size))
        if not (new <= self.threshold or new < 0.8 * now):
            self._rest = self.cooldown
            return None
        old = self.rank_of.copy()
        self._build(self.ids, owner)
        self.rebalances += 1
        return old
