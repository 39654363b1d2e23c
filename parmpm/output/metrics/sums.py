"""Sums in a fixed order: per-patch sums of per-particle addends, and numpy's sum of values in
global-id order without gathering them.

The run driver sums a metric's (or the energy balance's) per-particle addends patch by patch,
each patch's particles strictly in storage order, and then the patches in id order
(:func:`decomposition.ordered_sum`): the same rounding on any number of ranks.

:func:`gid_order_sum` gives, on every rank, ``np.sum`` of the values every rank holds arranged
in global-id order — bit for bit what one process holding them all computes — from the values'
runs (a body's masses are one value): :func:`pairwise_runs` replays numpy's pairwise summation
on a run-length encoded sequence.
"""
from __future__ import annotations

import numpy as np

from decomposition import is_parallel
from parmpm.core.jit import kernel

#: numpy's pairwise summation: sequential below 8 values, 8 accumulators up to this many
_PW_BLOCK = 128


def patch_sums(start, values, order=None):
    """(patches, k) sums of ``values`` rows over each patch's particles, strictly in canonical
    order: rows ``order[start[p]:start[p + 1]]`` (:meth:`parmpm.particles.store.Particles.order`;
    default: the rows as they lie)."""
    if order is None:
        order = np.arange(values.shape[0], dtype=np.uint64)
    return _patch_sums(start, values, order)


@kernel
def _patch_sums(start, values, order):
    out = np.zeros((start.size - 1, values.shape[1]))
    for p in range(start.size - 1):
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):
            i = order[kk]
            for c in range(values.shape[1]):
                out[p, c] += values[i, c]
    return out


def _pairwise(a: list[float]) -> float:
    """numpy's ``pairwise_sum`` (``numpy/_core/src/umath/loops_utils.h.src``) of at most
    :data:`_PW_BLOCK` values."""
    n = len(a)
    if n < 8:
        res = -0.0
        for x in a:
            res += x
        return res
    r = list(a[:8])
    i = 8
    while i < n - n % 8:
        for j in range(8):
            r[j] += a[i + j]
        i += 8
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    for x in a[i:]:
        res += x
    return res


def pairwise_runs(values, counts) -> float:
    """``np.sum(np.repeat(values, counts))`` without making the sequence: numpy's pairwise
    summation (halves rounded down to a multiple of 8, blocks of at most 128 summed with eight
    accumulators) replayed on the runs; a stretch inside one run is summed once per length."""
    values = [float(v) for v in values]
    ends = np.cumsum(np.asarray(counts, np.int64))
    n = int(ends[-1]) if ends.size else 0
    if n == 0:
        return 0.0
    memo: dict = {}

    def run_of(a: int) -> int:
        return int(np.searchsorted(ends, a, side="right"))

    def total(a: int, m: int) -> float:
        j = run_of(a)
        if a + m <= ends[j]:  # one run: depends only on its value and the length
            key = (np.float64(values[j]).tobytes(), m)
            if key not in memo:
                memo[key] = (_pairwise([values[j]] * m) if m <= _PW_BLOCK
                             else _split(a, m))
            return memo[key]
        if m <= _PW_BLOCK:
            seq = []
            while len(seq) < m:
                j = run_of(a + len(seq))
                seq += [values[j]] * int(min(ends[j] - a - len(seq), m - len(seq)))
            return _pairwise(seq)
        return _split(a, m)

    def _split(a: int, m: int) -> float:
        m2 = m // 2
        m2 -= m2 % 8
        return total(a, m2) + total(a + m2, m - m2)

    return 0.0 + total(0, n)  # the reduction starts from the identity, 0.0


def gid_order_sum(comm, gid, values) -> float:
    """``np.sum`` of every rank's ``values`` arranged in global-id order (``gid``: this rank's
    ids), bit for bit, on every rank. Each rank sends its runs — consecutive ids of one value
    — and adjacent runs of one value are joined; exchanges O(runs), not the values."""
    gid = np.asarray(gid, np.int64)
    values = np.asarray(values, np.float64)
    order = np.argsort(gid, kind="stable")
    gid, values = gid[order], values[order]
    if not is_parallel(comm):
        return float(np.sum(values))
    bits = values.view(np.int64)  # one value: the same bits (0.0 and -0.0 differ)
    cut = np.flatnonzero((np.diff(gid) != 1) | (np.diff(bits) != 0)) + 1
    first = (np.concatenate([[0], cut]) if gid.size else cut).astype(np.int64)
    runs = (gid[first], np.diff(np.concatenate([first, [gid.size]])), values[first])
    parts = comm.allgather(runs)
    starts = np.concatenate([p[0] for p in parts])
    counts = np.concatenate([p[1] for p in parts]).astype(np.int64)
    vals = np.concatenate([p[2] for p in parts])
    order = np.argsort(starts, kind="stable")
    counts, vals = counts[order], vals[order]
    if vals.size == 0:
        return 0.0
    new = np.concatenate([[True], vals[1:].view(np.int64) != vals[:-1].view(np.int64)])
    return pairwise_runs(vals[new], np.add.reduceat(counts, np.flatnonzero(new)))


__all__ = ["patch_sums", "pairwise_runs", "gid_order_sum"]
