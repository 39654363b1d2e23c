"""Checkpoint write and read throughput (``parmpm bench``'s block; run under mpirun for ranks).

    python run_scripts/checkpoint_io.py --particles 1e6
    mpirun -n 2 python run_scripts/checkpoint_io.py --particles 1e6

Writes one checkpoint of the block after a step (rank 0 gathers blocks of 2^18 global ids and
writes them), then restarts from it, and prints file size, write and read seconds and MB/s, and
the share of run time a checkpoint every ``--every`` steps would cost at the measured step time.
"""
import argparse
import tempfile
import time
from pathlib import Path

from decomposition import world
from parmpm.bench import build_bench_scene
from parmpm.log import setup_logging
from parmpm.simulation import Simulation


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--particles", type=float, default=1e6)
    ap.add_argument("--dim", type=int, default=2)
    ap.add_argument("--every", type=int, default=1000, help="checkpoint cadence for the share")
    args = ap.parse_args()
    comm = world()
    setup_logging(comm.Get_rank(), comm.Get_size(), quiet=True)
    out = Path(comm.bcast(tempfile.mkdtemp(prefix="parmpm-ckio-") if comm.Get_rank() == 0 else None))
    scene = build_bench_scene(args.dim, "cpdi", int(args.particles), 2, steps=3)
    sim = Simulation(scene, out, quiet=True, comm=comm)
    summary = sim.run()
    step = 1.0 / summary["particle_steps_per_second"] * summary["particles"]
    comm.Barrier()
    t0 = time.perf_counter()
    path = sim.write_checkpoint()
    comm.Barrier()
    t_write = time.perf_counter() - t0
    t0 = time.perf_counter()
    Simulation.from_checkpoint(path, out_dir=out / "r", quiet=True, comm=comm)
    comm.Barrier()
    t_read = time.perf_counter() - t0
    if comm.Get_rank() == 0:
        mb = path.stat().st_size / 1e6
        print(f"{comm.Get_size()} rank(s), {summary['particles']:,} particles, {args.dim}D: "
              f"checkpoint {mb:.1f} MB; write {t_write:.2f} s ({mb / t_write:.0f} MB/s); "
              f"restart set-up incl. read {t_read:.2f} s ({mb / t_read:.0f} MB/s); "
              f"step {step:.3f} s; a checkpoint every {args.every} steps costs "
              f"{100 * t_write / (t_write + args.every * step):.2f} % of run time")


if __name__ == "__main__":
    main()
