"""The decomposition alone (no MPM) under ``mpirun -n P``; prints ``OK`` when every check holds.

* accumulate then fill over ranks: every rank's patches hold exactly (bit for bit) what the
  one-rank exchange of the same fields gives — the global sum on every copy of every node, added
  in the same order — for random patch-to-rank assignments and sparse patch sets; sums and
  maxima in one message give what two exchanges give on one rank;
* migrate: records sent to random ranks arrive exactly once with every field intact, through the
  all-ranks path and the neighbours-only path;
* PatchSet: every rank derives the same patch set and owners after updates and re-balancing;
* a step's closing collective (:func:`decomposition.max_and_patch_sum`): the maximum over the
  ranks, and per-patch rows summed in patch order bit for bit as one rank sums them (and as
  :func:`decomposition.ordered_sum` does), also with ranks that own no patch.
"""

import sys
from pathlib import Path

import numpy as np

from decomposition import (HaloPlan, PatchLayout, PatchSet, accumulate, accumulate_max, fill,
                           max_and_patch_sum, migrate, ordered_sum, world)
from decomposition.partition import active_patches

LAYOUTS = [((10,), (3,), 1), ((9,), (2,), 2), ((7, 5), (3, 2), 1), ((6, 4), (2, 2), 3),
           ((5, 3), (2, 2), 0), ((8, 8), (2, 2), 2), ((5, 4, 3), (2, 3, 2), 1),
           ((4, 4, 4), (2, 2, 2), 2), ((5, 3, 4), (2, 2, 3), 0)]


def check_halo(comm, rng_seed: int) -> None:
    rank, size = comm.Get_rank(), comm.Get_size()
    for li, (cells, psize, ghost) in enumerate(LAYOUTS):
        lay = PatchLayout(cells, psize, ghost)
        for trial in range(3):
            rng = np.random.default_rng([rng_seed, li, trial])  # same on every rank
            ids = np.arange(lay.n_patches)
            if trial == 2:  # a sparse patch set
                ids = active_patches(lay, rng.choice(lay.n_patches, max(1, lay.n_patches // 4),
                                                     replace=False))
            owner = rng.integers(0, size, ids.size)
            f = rng.standard_normal((ids.size, lay.n_local_nodes, 3))
            f *= np.exp(rng.uniform(-20, 20, (ids.size, lay.n_local_nodes, 1)))
            g = rng.standard_normal((ids.size, lay.n_local_nodes, 1))
            serial = HaloPlan(lay, ids)
            fs, gs = f.copy(), g.copy()
            accumulate(serial, fs, gs)
            fill(serial, fs, gs)
            plan = HaloPlan(lay, ids, owner, comm)
            mine = np.searchsorted(ids, plan.local_ids)
            fl, gl = f[mine].copy(), g[mine].copy()
            accumulate(plan, fl, gl)
            fill(plan, fl, gl)
            assert np.array_equal(fl, fs[mine]) and np.array_equal(gl, gs[mine]), \
                f"rank {rank}: halo differs from one rank for layout {cells}/{psize}/{ghost} trial {trial}"
            # sums and maxima in one message: each as its own exchange gives it on one rank
            fs, gs = f.copy(), g.copy()
            accumulate(serial, fs)
            accumulate_max(serial, gs)
            fl, gl = f[mine].copy(), g[mine].copy()
            accumulate(plan, fl, maxima=(gl,))
            assert np.array_equal(fl, fs[mine]) and np.array_equal(gl, gs[mine]), \
                f"rank {rank}: sums with maxima differ for layout {cells}/{psize}/{ghost} trial {trial}"


def check_migrate(comm) -> None:
    rank, size = comm.Get_rank(), comm.Get_size()
    rng = np.random.default_rng([7, rank])
    n = int(rng.integers(0, 200))
    gid = rank * 1000 + np.arange(n)
    recs = {"gid": gid, "x": gid[:, None] * np.array([1.5, -2.0]),
            "F": gid[:, None, None] * np.ones((1, 2, 2)) + np.eye(2), "tag": (gid % 7).astype(np.int64)}
    total = comm.allreduce(n)
    for peers in (None, [(rank - 1) % size, (rank + 1) % size]):
        n = recs["gid"].size
        if peers is not None:
            peers = sorted(set(peers) - {rank})
            dest = rng.choice(peers + [rank], n) if peers else np.full(n, rank)
        else:
            dest = rng.integers(0, size, n)
        out = migrate(recs, dest, comm, peers)
        got = np.concatenate(comm.allgather(out["gid"]))
        assert got.size == total and np.unique(got).size == total, "a record was lost or doubled"
        g = out["gid"]
        assert np.array_equal(out["x"], g[:, None] * np.array([1.5, -2.0]))
        assert np.array_equal(out["F"], g[:, None, None] * np.ones((1, 2, 2)) + np.eye(2))
        assert np.array_equal(out["tag"], g % 7) and out["tag"].dtype == np.int64
        assert np.all(np.isin(dest[dest == rank], [rank]))  # kept ones stay
        recs = out


def check_patchset(comm) -> None:
    lay = PatchLayout((40, 24), (4, 4), 2)
    rng = np.random.default_rng(11)  # same on every rank
    counts = np.zeros(lay.n_patches, np.int64)
    counts[rng.choice(lay.n_patches, 12, replace=False)] = rng.integers(1, 500, 12)
    ps = PatchSet(lay, comm, counts, threshold=0.1)
    for step in range(6):
        # occupancy drifts: some patches empty, neighbours of occupied ones fill
        occ = np.flatnonzero(counts)
        near = active_patches(lay, occ)
        new = counts.copy()
        new[rng.choice(occ, 2, replace=False)] = 0
        new[rng.choice(near, 3, replace=False)] += rng.integers(1, 400, 3)
        if np.count_nonzero(new) == 0:
            continue
        counts = new
        ps.update(counts)
        ps.rebalance(counts)
        views = comm.allgather((ps.ids, ps.rank_of))
        for ids, rank_of in views:
            assert np.array_equal(ids, ps.ids) and np.array_equal(rank_of, ps.rank_of), \
                "ranks disagree on the patch set"
        assert np.array_equal(ps.ids, active_patches(lay, np.flatnonzero(counts)))


def check_step_collective(comm) -> None:
    lay = PatchLayout((40, 24), (4, 4), 2)
    rank, size = comm.Get_rank(), comm.Get_size()
    for seed, occupied in ((3, 12), (4, 2)):  # two occupied patches: idle ranks on 3 and 4
        rng = np.random.default_rng(seed)  # same on every rank
        counts = np.zeros(lay.n_patches, np.int64)
        counts[rng.choice(lay.n_patches, occupied, replace=False)] = rng.integers(1, 500, occupied)
        ps = PatchSet(lay, comm, counts)
        # rows of widely different magnitudes: a sum in another order rounds differently
        rows = rng.standard_normal((lay.n_patches, 7)) * 10.0 ** rng.integers(-8, 9, (lay.n_patches, 1))
        maxima = rng.standard_normal((size, 5))
        top, sums = max_and_patch_sum(comm, maxima[rank], rows[ps.local_ids], ps.owner)
        assert np.array_equal(top, maxima.max(axis=0)), "maximum differs"
        one_rank = np.cumsum(rows[ps.ids], axis=0)[-1]
        assert np.array_equal(sums, one_rank), "patch sums differ from one rank's"
        assert np.array_equal(sums, ordered_sum(comm, ps.local_ids, rows[ps.local_ids]))


def main() -> None:
    comm = world()
    check_halo(comm, 5)
    check_migrate(comm)
    check_patchset(comm)
    check_step_collective(comm)
    comm.Barrier()
    if comm.Get_rank() == 0:
        print("OK", flush=True)


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "harness"))
    from mpi_script import run_or_abort

    run_or_abort(main)
