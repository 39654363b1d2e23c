"""Checkpoint write and restart cost per rank count: seconds, MB/s and the bytes each rank reads.

    python run_scripts/benchmarks/checkpoint_io.py --particles 4e6
    mpirun -n 4 python run_scripts/benchmarks/checkpoint_io.py --particles 4e6

Runs the benchmark block (``parmpm bench``'s translating neo-Hookean block, 2D by default) for two
steps, then for each ``--ranks-per-file`` setting (default: ``auto``, one part file per rank,
and the rank count, one writer gathering everything as before version 4) writes one checkpoint
and restarts from it. Prints, from rank 0: the checkpoint's size, the write time and rate, the
restart set-up time (opening, dealing the patches out, reading, building the stepper) and rate,
the share of run time a checkpoint every ``--every`` steps costs; then per rank the particle
rows and bytes it read (the reader's count) and the bytes its process read from files meanwhile
(``rchar`` of /proc/self/io: every byte HDF5 read, cached or not). Expected: with one part per
rank each rank reads its own rows only (about N/P rows, 232 bytes each in 2D), and the write
time falls with P while the disk keeps up. Runtime: about a minute for 4·10⁶ particles on one
rank (the two steps dominate), more when oversubscribed. ``--json FILE``: rank 0 also writes
the numbers there (one record per ``--ranks-per-file`` setting; ``run_scripts/benchmarks/io_scaling.py``
reads it).
"""
import argparse
import dataclasses
import json
import shutil
import tempfile
import time
from pathlib import Path

import parmpm.driver.restart as rank_state  # where a restart opens its checkpoint
from decomposition import world
from parmpm.cli.bench import build_bench_scene
from parmpm.io.checkpoint import DTYPES, parts_folder, remove_checkpoint
from parmpm.core.log import setup_logging
from parmpm.driver.simulation import Simulation

#: a finished run's checkpoint is refused unless the restart is given steps to run: one more
#: (only the read is timed; the continued run is never stepped)
MORE = ("time.steps=3",)

_readers = []


class _CountingReader(rank_state.CheckpointReader):
    """The restart's reader, kept so that its row count can be reported after it is closed."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        _readers.append(self)


rank_state.CheckpointReader = _CountingReader


def _rchar() -> int:
    """Bytes this process has read through read()/pread() (Linux; 0 elsewhere)."""
    try:
        for line in Path("/proc/self/io").read_text().splitlines():
            if line.startswith("rchar:"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


def _size(path: Path) -> int:
    parts = parts_folder(path)
    return path.stat().st_size + sum(p.stat().st_size for p in parts.glob("*.h5"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--particles", type=float, default=1e6)
    ap.add_argument("--dim", type=int, default=2)
    ap.add_argument("--every", type=int, default=1000, help="checkpoint cadence for the share")
    ap.add_argument("--ranks-per-file", nargs="+", default=["auto", "all"],
                    help='settings to compare: "auto", an integer, or "all" (one writer)')
    ap.add_argument("--out", type=Path, default=None, help="folder (default: a temporary one)")
    ap.add_argument("--json", type=Path, default=None, help="also write the numbers here (rank 0)")
    args = ap.parse_args()
    comm = world()
    rank, size = comm.Get_rank(), comm.Get_size()
    setup_logging(rank, size, quiet=True)
    out = args.out or Path(tempfile.gettempdir())
    out = Path(comm.bcast(tempfile.mkdtemp(prefix="parmpm-ckio-", dir=out) if rank == 0 else None))
    scene = build_bench_scene(args.dim, "cpdi", int(args.particles), 2, steps=2)
    sim = Simulation(scene, out / "run", quiet=True, comm=comm)
    summary = sim.run()
    step = summary["particles"] / summary["particle_steps_per_second"]
    record = {"ranks": size, "particles": int(summary["particles"]), "dim": args.dim,
              "step_seconds": step, "settings": []}
    if rank == 0:
        print(f"{size} rank(s), {summary['particles']:,} particles, {args.dim}D, step {step:.3f} s")
    for k, setting in enumerate(args.ranks_per_file):
        rpf = size if setting == "all" else (setting if setting == "auto" else int(setting))
        scene = sim.state.scene  # the writer reads the typed scene (parmpm.scene.records)
        scene.spec = dataclasses.replace(
            scene.spec, checkpoint=dataclasses.replace(scene.spec.checkpoint, ranks_per_file=rpf))
        comm.Barrier()
        t0 = time.perf_counter()
        path = sim.write_checkpoint()
        comm.Barrier()
        t_write = time.perf_counter() - t0
        _readers.clear()
        r0 = _rchar()
        t0 = time.perf_counter()
        Simulation.from_checkpoint(path, MORE, out_dir=out / f"restart{k}", quiet=True, comm=comm)
        comm.Barrier()
        t_read = time.perf_counter() - t0
        rchar = _rchar() - r0
        reader = _readers[0]
        dim = args.dim
        per_row = {n: DTYPES[n].itemsize * (dim if n in ("x", "v", "x0", "lh0") else
                                            dim * dim if n in ("F", "stress", "r0", "rf") else 1)
                   for n in DTYPES}
        got = sum(per_row[n] * c for n, c in reader.rows_read.items())
        rows = max(reader.rows_read.values(), default=0)
        per_rank = comm.gather((rows, got, rchar), root=0)
        if rank == 0:
            mb = _size(path) / 1e6
            files = 1 + len(list(parts_folder(path).glob("*.h5")))
            print(f"ranks_per_file = {setting} ({files} file(s), {mb:.1f} MB): write "
                  f"{t_write:.2f} s ({mb / t_write:.0f} MB/s); restart set-up incl. read "
                  f"{t_read:.2f} s ({mb / t_read:.0f} MB/s); a checkpoint every {args.every} "
                  f"steps costs {100 * t_write / (t_write + args.every * step):.2f} % of run time")
            for r, (n_rows, b, rc) in enumerate(per_rank):
                print(f"  rank {r}: read {n_rows:,} rows, {b / 1e6:.1f} MB of particle data; "
                      f"{rc / 1e6:.1f} MB read from files")
            record["settings"].append({
                "ranks_per_file": setting, "files": files, "bytes": _size(path),
                "write_seconds": t_write, "restart_seconds": t_read,
                "per_rank": [{"rank": r, "rows": n_rows, "bytes_read": b, "rchar": rc}
                             for r, (n_rows, b, rc) in enumerate(per_rank)]})
            remove_checkpoint(path)
        comm.Barrier()
    if rank == 0:
        shutil.rmtree(out, ignore_errors=True)
        if args.json is not None:
            args.json.write_text(json.dumps(record), encoding="utf-8")


if __name__ == "__main__":
    main()
