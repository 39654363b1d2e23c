"""Communication constants of the cost model: point-to-point latency and bandwidth (α, β) and
the cost of a small Allreduce (α_r), measured by an MPI micro-benchmark.

Physics-free (it imports only :mod:`decomposition`); it measures the two kinds of communication
the time step makes, for the cost model in ``run_scripts/models/cost_model.py`` (``scaling.py`` runs it
and fits the model to it):

* **ping-pong** between ranks 0 and 1 (the others wait): blocking ``Send``/``Recv`` of numpy
  byte buffers of 8 B … 4 MiB (powers of two); the one-way time of a size is half a round trip,
  the mean over a batch of round trips, the fastest of several batches (a shared machine only
  ever adds time). Fitted by ``t(n) = α + n/β``.
* **Allreduce** of 5 doubles with ``MAX`` on every rank — exactly the end-of-step reduction of
  the stepper (``decomposition.comm.allreduce_max``) — mean per call over a batch, fastest batch,
  the slowest rank's value. Modelled as ``α_r·⌈log2 P⌉``.

Expected on one node with MPICH's shared-memory transport: α of a few µs (mpi4py's per-call
overhead included), β of a few GB/s at MiB sizes (memcpy bandwidth), an Allreduce of a few µs
per stage. Oversubscribed ranks (more ranks than cores) wait for the scheduler instead: times
of milliseconds, flagged ``oversubscribed`` in the result. Runtime: ~2 s (``--quick``: ~0.3 s).

    mpirun -n 2 python run_scripts/benchmarks/comm_constants.py --json probe.json
    mpirun -n 4 python run_scripts/benchmarks/comm_constants.py --json probe_4.json --no-pingpong  # Allreduce only
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from decomposition.comm import world

TAG_PING = 201
SIZES = tuple(8 * 2 ** k for k in range(20))  # 8 B .. 4 MiB
REDUCE_DOUBLES = 5


def _batches(comm, one, budget: float, batches: int) -> float:
    """Fastest batch mean of ``one()`` (collective among the ranks that call it; rank 0 of
    ``comm`` picks the batch length from a trial so that all batches take ≈ ``budget`` s)."""
    one()  # warm-up (first-touch of buffers, connection set-up)
    t0 = time.perf_counter()
    one()
    trial = max(time.perf_counter() - t0, 1e-7)
    reps = int(comm.bcast(max(1, min(100_000, int(budget / batches / trial))), root=0))
    best = float("inf")
    for _ in range(batches):
        t0 = time.perf_counter()
        for _ in range(reps):
            one()
        best = min(best, (time.perf_counter() - t0) / reps)
    return best


def pingpong(comm, sizes=SIZES, budget: float = 0.05, batches: int = 5) -> list[float] | None:
    """One-way seconds per message size between ranks 0 and 1 (rank 0's list; None elsewhere,
    and on one rank). Every rank must call it; ranks above 1 only wait at the barrier."""
    from mpi4py import MPI

    rank, size = comm.Get_rank(), comm.Get_size()
    if size < 2:
        return None
    pair = comm.Split(0 if rank < 2 else MPI.UNDEFINED, rank)
    times = []
    if pair != MPI.COMM_NULL:
        peer = 1 - rank
        for n in sizes:
            buf = np.zeros(n, np.uint8)

            def one(buf=buf):
                if rank == 0:
                    pair.Send([buf, MPI.BYTE], dest=peer, tag=TAG_PING)
                    pair.Recv([buf, MPI.BYTE], source=peer, tag=TAG_PING)
                else:
                    pair.Recv([buf, MPI.BYTE], source=peer, tag=TAG_PING)
                    pair.Send([buf, MPI.BYTE], dest=peer, tag=TAG_PING)

            times.append(_batches(pair, one, budget, batches) / 2.0)
        pair.Free()
    comm.Barrier()
    return times if rank == 0 else None


def allreduce(comm, budget: float = 0.1, batches: int = 5) -> float:
    """Seconds per ``Allreduce`` of 5 doubles (MAX), the slowest rank's fastest batch mean."""
    from mpi4py import MPI

    send = np.arange(REDUCE_DOUBLES, dtype=np.float64) + comm.Get_rank()
    recv = np.empty_like(send)

    def one():
        comm.Allreduce(send, recv, op=MPI.MAX)

    comm.Barrier()
    t = _batches(comm, one, budget, batches)
    return float(comm.allreduce(t, op=MPI.MAX))


def probe(comm, sizes=SIZES, budget: float = 0.05, do_pingpong: bool = True) -> dict | None:
    """Both measurements (collective); the result dict on rank 0, None elsewhere."""
    from mpi4py import MPI

    size = comm.Get_size()
    t_pp = pingpong(comm, sizes, budget) if do_pingpong else None
    t_ar = allreduce(comm, 2 * budget)
    if comm.Get_rank() != 0:
        return None
    cores = os.cpu_count() or 1
    return {
        "ranks": size, "cpu_count": cores, "oversubscribed": size > cores,
        "mpi_library": MPI.Get_library_version().strip().splitlines()[0],
        "pingpong": None if t_pp is None else {"bytes": list(sizes), "seconds": t_pp},
        "allreduce": {"doubles": REDUCE_DOUBLES, "op": "MAX", "seconds": t_ar},
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--json", type=Path, default=None, help="write the result here (rank 0)")
    p.add_argument("--quick", action="store_true", help="short batches (~0.3 s in all)")
    p.add_argument("--no-pingpong", action="store_true", help="the Allreduce timing only")
    args = p.parse_args(argv)
    comm = world()
    result = probe(comm, budget=0.005 if args.quick else 0.05, do_pingpong=not args.no_pingpong)
    if result is not None:
        pp = result["pingpong"]
        if pp:
            for n, t in zip(pp["bytes"], pp["seconds"]):
                print(f"  ping-pong {n:>8d} B  {t * 1e6:10.2f} µs  {n / t / 1e9:8.3f} GB/s")
        print(f"  Allreduce of {REDUCE_DOUBLES} doubles on {result['ranks']} rank(s): "
              f"{result['allreduce']['seconds'] * 1e6:.2f} µs"
              + ("  (oversubscribed)" if result["oversubscribed"] else ""), flush=True)
        if args.json is not None:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
