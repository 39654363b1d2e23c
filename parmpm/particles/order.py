"""The canonical particle order as an index, kept up to date in O(n) without moving the fields.

A rank's particles are visited patch slot by patch slot, inside a patch in global-id order: that
order fixes the rounding of every P2G sum, so it is what makes a run bit-identical on any number
of ranks. Copying every field into that order after each step (what a sort does) costs a pass
over all of a particle's ~250 bytes, a third of a CPDI step when particles cross patches every
step. Here the order is an array ``order`` (canonical position → physical row) that the kernels
loop over; after a step only the particles that changed patch (or rank) move in it, merged into
the stayers' runs, which are still sorted. The fields themselves stay where they lie (rows that
left the rank are filled from the tail, received rows appended), until
:meth:`parmpm.particles.store.Particles.compact` copies them into order.
"""
from __future__ import annotations

import numpy as np

from parmpm.core.jit import kernel

MOVED, FILLER, LEFT = 1, 2, 4  # bits of ``flags`` (one byte per physical row, zero between calls)


@kernel
def _new_row(i, flags, fillers, holes):
    """Row ``i``'s index once the rows that left are filled from the tail."""
    if flags[i] & FILLER:
        return holes[np.searchsorted(fillers, i)]
    return i


@kernel
def merge_order(order, patch, new, slot_of, gid, start, counts, flags, fillers, holes,
                recv_slot, recv_gid, scratch, out):
    """The canonical order after a step's moves, into ``out`` (its length is the new count):
    slot by slot, the old order's rows that stayed in their patch (still in gid order) merged
    with the arrivals (rows that changed patch here and the ``recv_*`` received rows, appended
    after the kept ones) sorted by (slot, gid). ``flags``: a zeroed byte per row, with
    :data:`LEFT` set on the rows that left the rank (left zeroed again); ``fillers``/``holes``:
    the kept rows past the new end and the rows they fill (both increasing); ``scratch``:
    (4, ≥ rows + received) int64, only its first entries touched (a persistent buffer, so no
    step allocates). ``counts`` (per slot) is updated in place. Returns how many rows changed
    patch or left.

    Two passes over the rows: the movers are found in row order (sequential reads), then the
    merge reads a stayer's gid only while arrivals wait in its slot."""
    n = order.size
    n_keep = out.size - recv_slot.size
    for j in range(fillers.size):
        flags[fillers[j]] |= FILLER
    rows, aslot, agid = scratch[0], scratch[1], scratch[2]  # arrivals: new row, slot, gid
    marked = scratch[3]  # rows whose flags are cleared at the end
    m = 0
    n_marked = 0
    top = 0
    for i in range(n):
        f = flags[i]
        if f & LEFT or new[i] != patch[i]:
            flags[i] = f | MOVED
            counts[slot_of[patch[i]]] -= 1
            if not f & LEFT:
                s = slot_of[new[i]]
                counts[s] += 1
                rows[m] = _new_row(i, flags, fillers, holes)
                aslot[m] = s
                agid[m] = gid[i]
                top = max(top, gid[i])
                m += 1
        if flags[i]:
            marked[n_marked] = i
            n_marked += 1
    changed = n_marked - fillers.size
    for j in range(fillers.size):  # a filler that also moved is counted once
        if flags[fillers[j]] & (MOVED | LEFT):
            changed += 1
    for j in range(recv_slot.size):
        counts[recv_slot[j]] += 1
        rows[m] = n_keep + j
        aslot[m] = recv_slot[j]
        agid[m] = recv_gid[j]
        top = max(top, recv_gid[j])
        m += 1
    key = np.empty(m, np.int64)
    for j in range(m):
        key[j] = aslot[j] * (top + 1) + agid[j]
    srt = np.argsort(key)
    b = 0
    pos = 0
    for s in range(start.size - 1):
        k = start[s]
        end = start[s + 1]
        b_end = b  # arrivals into slot s: srt[b:b_end]
        while b_end < m and aslot[srt[b_end]] == s:
            b_end += 1
        while b < b_end:
            g = agid[srt[b]]
            while k < end:  # the stayers before the next arrival
                i = order[k]
                if flags[i] & MOVED == 0:
                    if gid[i] > g:
                        break
                    out[pos] = _new_row(i, flags, fillers, holes)
                    pos += 1
                k += 1
            out[pos] = rows[srt[b]]
            pos += 1
            b += 1
        while k < end:  # the rest of the slot's stayers: no gid needed
            i = order[k]
            if flags[i] & MOVED == 0:
                out[pos] = _new_row(i, flags, fillers, holes)
                pos += 1
            k += 1
    for j in range(n_marked):
        flags[marked[j]] = 0
    return changed


@kernel
def move_runs(order, src, size, dst, out):
    """``out[dst[r]:dst[r] + size[r]] = order[src[r]:src[r] + size[r]]`` for every run ``r``."""
    for r in range(src.size):
        for k in range(size[r]):
            out[dst[r] + k] = order[src[r] + k]


@kernel
def slot_subset(start, order, keep):
    """(start, order) of the slots ``keep`` marks, the others empty: ``order``'s runs of the kept
    slots in slot order (what ``order[np.repeat(keep, counts)]`` gives, without its n-long
    temporaries; a pass over the kept rows only)."""
    slots = start.size - 1
    kept = np.zeros_like(start)
    for p in range(slots):
        kept[p + 1] = kept[p] + (start[p + 1] - start[p] if keep[p] else 0)
    out = np.empty(kept[slots], order.dtype)
    for p in range(slots):
        if keep[p]:
            out[kept[p]:kept[p + 1]] = order[start[p]:start[p + 1]]
    return kept, out


@kernel
def slots_holding_positive(start, order, values):
    """Per slot: whether any of its rows has ``values > 0`` (stops at the first)."""
    slots = start.size - 1
    out = np.zeros(slots, np.bool_)
    for p in range(slots):
        for kk in range(start[p], start[p + 1]):
            if values[order[kk]] > 0.0:
                out[p] = True
                break
    return out
