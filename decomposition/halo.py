"""Ghost-layer exchange between patches: ``accumulate`` (ghost → owner sum) and ``fill``
(owner → ghost copy), on one rank or many.

A :class:`HaloPlan` is built from the *global* list of halo pairs: for every existing owner patch
``p`` (ascending id) and every other existing patch ``q`` in the layout's fixed neighbour-offset
order, the box of nodes that ``p`` owns and ``q`` holds as ghosts. Each rank keeps the rows that
concern its own patches:

* owner rows (``p`` here): ``accumulate`` adds ``q``'s partial sums into ``p`` *in global row
  order*, reading ``q`` from local memory when ``q`` is here and from the receive buffer when it
  is not — so every node's total is ``own + Σ_{offsets in fixed order} neighbour``, the same
  floating-point sum whichever rank hosts which patch (the key to rank-count-independent
  results); ``fill`` copies ``p``'s owned box to ``q`` (locally, or into the send buffer);
* ghost rows (``q`` here, ``p`` elsewhere): ``accumulate`` packs ``q``'s ghost box for ``p``'s
  rank; ``fill`` unpacks the owner's values into it.

Between ranks, each peer pair exchanges one message per operation, packed field after field,
rows in global order on both sides (so offsets agree without any handshake), with non-blocking
``Isend``/``Irecv`` on numpy buffers.
"""
from __future__ import annotations

import copy

import numpy as np
from numba import njit

from decomposition.comm import is_parallel
from decomposition.layout import PatchLayout
from decomposition.partition import shift_patches

TAG_ACCUMULATE, TAG_FILL = 101, 102
#: the plans :meth:`HaloPlan.among` keeps
AMONG_KEPT = 16


def halo_pairs(layout: PatchLayout, ids: np.ndarray) -> np.ndarray:
    """(n, 11) global halo rows: owner id p, other id q, p-local offset (3), q-local offset (3),
    size (3); ordered by p ascending, then by the fixed neighbour-offset order."""
    ids = np.unique(np.asarray(ids, dtype=np.int64))
    present = np.zeros(layout.n_patches, bool)
    present[ids] = True
    all_coords = layout.patch_coords()
    coords = all_coords[ids]
    own_lo, own_hi = layout.owned_box(coords)
    p_base = layout.local_base(coords)
    parts, keys = [], []
    for oi, off in enumerate(layout.neighbour_offsets()):
        qid, ok = shift_patches(layout, ids, off)
        ok &= present[qid]
        q_lo, q_hi = layout.local_box(all_coords[qid])
        lo, hi = np.maximum(own_lo, q_lo), np.minimum(own_hi, q_hi)
        ok &= np.all(hi > lo, axis=1)
        rows = np.concatenate([ids[:, None], qid[:, None], lo - p_base, lo - q_lo, hi - lo], axis=1)
        parts.append(rows[ok])
        keys.append(np.stack([np.flatnonzero(ok), np.full(ok.sum(), oi)], axis=1))
    if not parts:
        return np.zeros((0, 11), np.int64)
    rows, key = np.concatenate(parts), np.concatenate(keys)
    return rows[np.lexsort((key[:, 1], key[:, 0]))].astype(np.int64)


class HaloPlan:
    """This rank's share of the halo pairs between the existing patches ``patch_ids``.

    ``owner`` gives the rank of each of ``patch_ids`` (default: all on rank 0). Local patch
    ``s`` (slot ``s`` of every field array) is ``local_ids[s]``; slots follow ascending id.
    """

    def __init__(self, layout: PatchLayout, patch_ids=None, owner=None, comm=None):
        self.layout = layout
        self.comm = comm
        self.rank = comm.Get_rank() if comm is not None else 0
        ids = np.arange(layout.n_patches) if patch_ids is None else np.asarray(patch_ids, np.int64)
        owner = np.zeros(ids.size, np.int64) if owner is None else np.asarray(owner, np.int64)
        order = np.argsort(ids, kind="stable")
        self.ids, self.owner = ids[order], owner[order]
        self.rank_of = np.full(layout.n_patches, -1, np.int64)
        self.rank_of[self.ids] = self.owner
        self.local_ids = self.ids[self.owner == self.rank]
        self.slot_of = np.full(layout.n_patches, -1, np.int64)
        self.slot_of[self.local_ids] = np.arange(self.local_ids.size)
        self.local_nodes3 = layout.local_nodes3

        rows = halo_pairs(layout, self.ids)
        rp, rq = self.rank_of[rows[:, 0]], self.rank_of[rows[:, 1]]
        me = self.rank
        own, ghost = rows[rp == me], rows[(rq == me) & (rp != me)]
        own_peer = rq[rp == me]
        ghost_peer = rp[(rq == me) & (rp != me)]
        self.peers = np.unique(np.concatenate([own_peer[own_peer != me], ghost_peer]))
        seg_of = {int(r): i for i, r in enumerate(self.peers)}

        def segments(rows_, peer):
            size = np.prod(rows_[:, 8:11], axis=1)
            seg = np.array([seg_of.get(int(r), -1) for r in peer], np.int64)
            node_off = np.zeros(rows_.shape[0], np.int64)
            nodes = np.zeros(self.peers.size, np.int64)
            for i in range(rows_.shape[0]):  # per halo pair, at plan time only
                if seg[i] >= 0:
                    node_off[i] = nodes[seg[i]]
                    nodes[seg[i]] += size[i]
            return seg, node_off, nodes

        oseg, ooff, self.own_seg_nodes = segments(own, own_peer)
        q_slot = np.where(own_peer == me, self.slot_of[own[:, 1]], -1)
        #: owner rows: p slot, q slot (-1: remote), p offset 3, q offset 3, size 3, segment, node offset
        self.own_rows = np.concatenate([self.slot_of[own[:, :1]], q_slot[:, None], own[:, 2:11],
                                        oseg[:, None], ooff[:, None]], axis=1).astype(np.int64)
        gseg, goff, self.ghost_seg_nodes = segments(ghost, ghost_peer)
        #: ghost rows: q slot, q offset 3, size 3, segment, node offset
        self.ghost_rows = np.concatenate([self.slot_of[ghost[:, 1:2]], ghost[:, 5:11],
                                          gseg[:, None], goff[:, None]], axis=1).astype(np.int64)
        self._bufs: dict[int, tuple] = {}
        self._among: dict[bytes, HaloPlan] = {}  # among()'s plans by their slots

    def among(self, holding: np.ndarray) -> HaloPlan:
        """This plan with only the pairs whose ghost copy lies in a slot of this rank that
        ``holding`` (a bool per slot) marks; every pair with another rank's patch kept, so that
        each rank's messages stay what its peers expect. For fields whose ghost copies are zero
        or unread elsewhere: a contact field's sums and velocities outside the slots holding
        its particles, contact's normals and extents outside the slots with a node where fields
        meet. An exchange then costs those slots' pairs, not the grid's. The plans made are kept
        (the last few ``holding``s: a step asks for the same ones again)."""
        key = np.asarray(holding, bool).tobytes()
        sub = self._among.get(key)
        if sub is None:
            if len(self._among) >= AMONG_KEPT:
                self._among.clear()
            rows = self.own_rows
            q = rows[:, 1]
            keep = (q < 0) | np.asarray(holding, bool)[np.maximum(q, 0)]
            sub = copy.copy(self)  # the same buffers and remote rows
            sub.own_rows = np.ascontiguousarray(rows[keep])
            sub._among = {}
            #: the slots whose owned nodes a kept pair reaches, or that hold the ghosts: where
            #: such a field can be nonzero at all
            sub.reached = np.array(holding, bool)
            sub.reached[sub.own_rows[:, 0]] = True
            self._among[key] = sub
        return sub

    @property
    def n_local(self) -> int:
        return int(self.local_ids.size)

    @property
    def ghost_nodes_per_exchange(self) -> int:
        """Nodes this rank copies or sends in one accumulate (or fill) of a 1-component field."""
        size = lambda r, cols: int(np.prod(r[:, cols], axis=1).sum()) if len(r) else 0  # noqa: E731
        return size(self.own_rows, slice(8, 11)) + size(self.ghost_rows, slice(4, 7))

    def _buffers(self, k_total: int):
        if k_total not in self._bufs:
            ob = np.concatenate([[0], np.cumsum(self.own_seg_nodes * k_total)]).astype(np.int64)
            gb = np.concatenate([[0], np.cumsum(self.ghost_seg_nodes * k_total)]).astype(np.int64)
            self._bufs[k_total] = (ob, np.zeros(ob[-1]), gb, np.zeros(gb[-1]))
        return self._bufs[k_total]


# --- kernels ---------------------------------------------------------------------------------
@njit(cache=True)
def _owner_rows(field, rows, L, buf, base, seg_nodes, kbefore, mode):
    """Owner rows in global order. ``mode`` 1: sum the other patch's ghost copy (local, or from
    ``buf``) into the owned box (accumulate); 2: keep the larger of the two (accumulate_max);
    0: copy the owned box to it (fill; a remote ghost copy is packed into ``buf``)."""
    k = field.shape[2]
    for r in range(rows.shape[0]):
        p, q = rows[r, 0], rows[r, 1]
        pos = 0
        if q < 0:
            s = rows[r, 11]
            pos = base[s] + kbefore * seg_nodes[s] + rows[r, 12] * k
        for k2 in range(rows[r, 10]):
            for k1 in range(rows[r, 9]):
                np0 = rows[r, 2] + L[0] * (rows[r, 3] + k1 + L[1] * (rows[r, 4] + k2))
                nq0 = rows[r, 5] + L[0] * (rows[r, 6] + k1 + L[1] * (rows[r, 7] + k2))
                for k0 in range(rows[r, 8]):
                    for c in range(k):
                        if q >= 0:
                            if mode == 1:
                                field[p, np0 + k0, c] += field[q, nq0 + k0, c]
                            elif mode == 2:
                                field[p, np0 + k0, c] = max(field[p, np0 + k0, c],
                                                            field[q, nq0 + k0, c])
                            else:
                                field[q, nq0 + k0, c] = field[p, np0 + k0, c]
                        else:
                            if mode == 1:
                                field[p, np0 + k0, c] += buf[pos]
                            elif mode == 2:
                                field[p, np0 + k0, c] = max(field[p, np0 + k0, c], buf[pos])
                            else:
                                buf[pos] = field[p, np0 + k0, c]
                            pos += 1


@njit(cache=True)
def _ghost_copy(field, rows, L, buf, base, seg_nodes, kbefore, unpack):
    """Pack a ghost box into the buffer (``unpack`` False) or write the buffer into it."""
    k = field.shape[2]
    for r in range(rows.shape[0]):
        q, s = rows[r, 0], rows[r, 7]
        pos = base[s] + kbefore * seg_nodes[s] + rows[r, 8] * k
        for k2 in range(rows[r, 6]):
            for k1 in range(rows[r, 5]):
                nq0 = rows[r, 1] + L[0] * (rows[r, 2] + k1 + L[1] * (rows[r, 3] + k2))
                for k0 in range(rows[r, 4]):
                    for c in range(k):
                        if unpack:
                            field[q, nq0 + k0, c] = buf[pos]
                        else:
                            buf[pos] = field[q, nq0 + k0, c]
                        pos += 1


# --- operations --------------------------------------------------------------------------------
def _exchange(plan: HaloPlan, send, sbase, snodes, recv, rbase, rnodes, tag):
    """Post receives and sends for every peer; returns (recv requests, send requests)."""
    if not is_parallel(plan.comm) or plan.peers.size == 0:
        return [], []
    from mpi4py import MPI

    comm = plan.comm
    rreq = [comm.Irecv([recv[rbase[i]:rbase[i + 1]], MPI.DOUBLE], source=int(r), tag=tag)
            for i, r in enumerate(plan.peers) if rnodes[i]]
    sreq = [comm.Isend([send[sbase[i]:sbase[i + 1]], MPI.DOUBLE], dest=int(r), tag=tag)
            for i, r in enumerate(plan.peers) if snodes[i]]
    return rreq, sreq


def _waitall(reqs) -> None:
    if reqs:
        from mpi4py import MPI

        MPI.Request.Waitall(reqs)


def accumulate(plan: HaloPlan, *fields: np.ndarray, maxima: tuple = ()) -> None:
    """Add every ghost copy's partial sum into the owning node; fields are (slots, nodes, k).
    ``maxima``: more fields combined as :func:`accumulate_max` combines them, in the same
    message (one exchange with each peer for both)."""
    _gather(plan, fields + tuple(maxima), (1,) * len(fields) + (2,) * len(maxima))


def accumulate_max(plan: HaloPlan, *fields: np.ndarray) -> None:
    """Keep at every owning node the largest of its ghost copies' values (a per-node maximum
    over the particles of every patch: the same on any number of ranks, whatever the order)."""
    _gather(plan, fields, (2,) * len(fields))


def _gather(plan: HaloPlan, fields, modes) -> None:
    """Bring every ghost copy to its owner and combine each field by its ``modes`` entry
    (``mode`` of :func:`_owner_rows`)."""
    k_total = sum(f.shape[2] for f in fields)
    ob, obuf, gb, gbuf = plan._buffers(k_total)
    L = plan.local_nodes3
    kb = 0
    for f in fields:  # pack what other ranks own
        _ghost_copy(f, plan.ghost_rows, L, gbuf, gb, plan.ghost_seg_nodes, kb, False)
        kb += f.shape[2]
    rreq, sreq = _exchange(plan, gbuf, gb, plan.ghost_seg_nodes, obuf, ob, plan.own_seg_nodes,
                           TAG_ACCUMULATE)
    _waitall(rreq)
    kb = 0
    for f, mode in zip(fields, modes):
        _owner_rows(f, plan.own_rows, L, obuf, ob, plan.own_seg_nodes, kb, mode)
        kb += f.shape[2]
    _waitall(sreq)


def fill(plan: HaloPlan, *fields: np.ndarray) -> None:
    """Copy every owned node's value into all of its ghost copies, on this rank and others."""
    k_total = sum(f.shape[2] for f in fields)
    ob, obuf, gb, gbuf = plan._buffers(k_total)
    L = plan.local_nodes3
    kb = 0
    for f in fields:  # local copies, and pack what other ranks hold as ghosts
        _owner_rows(f, plan.own_rows, L, obuf, ob, plan.own_seg_nodes, kb, 0)
        kb += f.shape[2]
    rreq, sreq = _exchange(plan, obuf, ob, plan.own_seg_nodes, gbuf, gb, plan.ghost_seg_nodes,
                           TAG_FILL)
    _waitall(rreq)
    kb = 0
    for f in fields:
        _ghost_copy(f, plan.ghost_rows, L, gbuf, gb, plan.ghost_seg_nodes, kb, True)
        kb += f.shape[2]
    _waitall(sreq)
