"""The lazy canonical order (parmpm.particles.order): after particles change patch, leave the rank
or arrive, the store's order, offsets and fields equal a full (slot, gid) sort of the rows that
remain, whether or not the fields were copied into order; reading a field from outside the step
sees the canonical order."""
import numpy as np
import pytest

import parmpm.particles.store as particles_module
from parmpm.particles.store import Particles

SLOTS = 7


def _store(rng, n, dim=2):
    P = Particles(dim, n)
    P.gid = rng.permutation(10 * n)[:n].astype(np.int64)
    P.x = rng.random((n, dim))
    P.F = rng.random((n, dim, dim))
    P.mass = rng.random(n)
    P.patch = rng.integers(0, SLOTS, n).astype(np.int64)
    P.group_by_patch(P.patch, np.arange(SLOTS), SLOTS, force=True)
    return P


def _reference(rows: dict, slot_of):
    """Every field of ``rows`` in (slot, gid) order, and the CSR offsets."""
    slot = slot_of[rows["patch"]]
    order = np.lexsort((rows["gid"], slot))
    counts = np.bincount(slot, minlength=SLOTS)
    return ({k: v[order] for k, v in rows.items()},
            np.concatenate([[0], np.cumsum(counts)]))


def _canonical_view(P):
    """The fields as the kernels see them: physical rows visited in P.order()."""
    order = P.order().astype(np.int64)
    return {k: P.rows.__getattr__(k)[order] for k in ("gid", "patch", "x", "F", "mass")}


@pytest.mark.parametrize("seed", range(6))
def test_moves_exchanges_and_arrivals_equal_a_full_sort(seed, monkeypatch):
    monkeypatch.setattr(particles_module, "COMPACT_FRACTION", 1e9)  # stay lazy
    rng = np.random.default_rng(seed)
    n = int(rng.integers(50, 400))
    P = _store(rng, n)
    slot_of = np.arange(SLOTS)
    next_gid = 10 * n
    for step in range(8):
        n = P.n
        R = P.rows
        new = R.patch.copy()
        movers = rng.random(n) < 0.2
        new[movers] = rng.integers(0, SLOTS, int(movers.sum()))
        exchange = step % 2 == 1
        keep = received = None
        if exchange:
            keep = np.flatnonzero(rng.random(n) > 0.15)
            r = int(rng.integers(0, 40))
            received = {"gid": np.arange(next_gid, next_gid + r, dtype=np.int64),
                        "patch": rng.integers(0, SLOTS, r).astype(np.int64),
                        "x": rng.random((r, 2)), "F": rng.random((r, 2, 2)),
                        "mass": rng.random(r)}
            next_gid += r
            for k in P.names():
                if k not in received:
                    received[k] = np.zeros((r,) + R.__getattr__(k).shape[1:],
                                           R.__getattr__(k).dtype)
        kept = np.arange(n) if keep is None else keep
        rows = {k: R.__getattr__(k)[kept].copy() for k in ("gid", "x", "F", "mass")}
        rows["patch"] = new[kept].copy()
        if received is not None:
            rows = {k: np.concatenate([v, received[k]]) for k, v in rows.items()}
        want, start = _reference(rows, slot_of)
        P.group_by_patch(new, slot_of, SLOTS, keep=keep, received=received,
                         moved=int(np.count_nonzero(new != R.patch)) if not exchange else -1)
        np.testing.assert_array_equal(P.start, start)
        got = _canonical_view(P)  # lazy: no copy of the fields
        for k, v in want.items():
            np.testing.assert_array_equal(got[k], v, err_msg=f"step {step}, field {k}")
    assert P._order is not None  # the fields were never copied
    for k, v in want.items():  # reading a field copies them into canonical order
        np.testing.assert_array_equal(getattr(P, k), v)
    assert P._order is None
    np.testing.assert_array_equal(P.order(), np.arange(P.n))


def test_compaction_past_the_threshold_keeps_the_order(monkeypatch):
    monkeypatch.setattr(particles_module, "COMPACT_FRACTION", 0.1)
    rng = np.random.default_rng(7)
    P = _store(rng, 300)
    slot_of = np.arange(SLOTS)
    compacted = 0
    for _ in range(10):
        new = P.rows.patch.copy()
        new[rng.integers(0, P.n, 12)] = rng.integers(0, SLOTS, 12)
        rows = {k: P.rows.__getattr__(k).copy() for k in ("gid", "x", "F", "mass")}
        rows["patch"] = new.copy()
        want, start = _reference(rows, slot_of)
        P.group_by_patch(new, slot_of, SLOTS)
        compacted += P._order is None
        got = _canonical_view(P)
        for k, v in want.items():
            np.testing.assert_array_equal(got[k], v)
    assert compacted >= 2  # 12 of 300 rows move per step: a copy every ~3 steps


def test_a_changed_patch_set_moves_index_runs_only(monkeypatch):
    """Slots renumbered (patches gained or lost elsewhere): the same as a full sort, and no
    field is copied while every particle's patch stays local."""
    monkeypatch.setattr(particles_module, "COMPACT_FRACTION", 1e9)
    rng = np.random.default_rng(3)
    P = _store(rng, 200)
    new = P.rows.patch.copy()
    new[:30] = (new[:30] + 1) % SLOTS
    P.group_by_patch(new, np.arange(SLOTS), SLOTS)  # lazy now
    x_before = P.rows.x
    slot_of = np.array([4, 0, 6, 2, 1, 5, 3, -1, -1])  # 7 patches in new slots, room for 9
    rows = {k: P.rows.__getattr__(k).copy() for k in ("gid", "x", "F", "mass", "patch")}
    want, start = _reference(rows, slot_of[:SLOTS])
    P.group_by_patch(P.rows.patch, slot_of, SLOTS, force=True)
    assert P.rows.x is x_before  # index runs moved, the rows did not
    np.testing.assert_array_equal(P.start, start)
    got = _canonical_view(P)
    for k, v in want.items():
        np.testing.assert_array_equal(got[k], v)


def test_an_exchange_needs_grouped_rows():
    P = Particles(2, 5)
    with pytest.raises(ValueError, match="grouped"):
        P.group_by_patch(P.rows.patch, np.arange(1), 1, keep=np.arange(3))


@pytest.mark.parametrize("seed", range(6))
def test_slot_subsets_are_the_numpy_selections(seed):
    """The compiled slot bookkeeping of the contact and crack passes gives what numpy's
    selections give: the kept slots' runs of the order (empty slots and none kept included),
    the slots holding a positive value, the slots with a nonzero crack normal."""
    from parmpm.grid.crack import slots_with_crack
    from parmpm.particles.order import slot_subset, slots_holding_positive

    rng = np.random.default_rng(seed)
    slots = int(rng.integers(1, 9))
    counts = rng.integers(0, 5, slots)
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    order = rng.permutation(start[-1]).astype(np.uint64)
    for keep in (rng.random(slots) < 0.5, np.zeros(slots, bool), np.ones(slots, bool)):
        kept, sub = slot_subset(start, order, keep)
        want = np.zeros_like(start)
        np.cumsum(counts * keep, out=want[1:])
        np.testing.assert_array_equal(kept, want)
        assert sub.dtype == order.dtype
        np.testing.assert_array_equal(sub, order[np.repeat(keep, counts)])
    values = np.where(rng.random(start[-1]) < 0.2, rng.random(start[-1]), 0.0)
    values[rng.random(start[-1]) < 0.1] = -1.0
    want = np.zeros(slots, bool)
    want[np.repeat(np.arange(slots), counts)[values[order] > 0.0]] = True
    np.testing.assert_array_equal(slots_holding_positive(start, order, values), want)
    normal = np.where(rng.random((slots + 2, 3, 11)) < 0.05, rng.standard_normal((slots + 2, 3, 11)), 0.0)
    normal[-2:] = 1.0  # spare slots past the patches' are not looked at
    normal[:, :, 9:] = np.where(rng.random((slots + 2, 3, 2)) < 0.5, 1.0, 0.0)  # nor the stride's tail
    want = np.any(normal[:slots, :, :9] != 0.0, axis=(1, 2))
    np.testing.assert_array_equal(slots_with_crack(normal, slots, 9), want)
