"""Strong scaling of the time step: ``parmpm bench`` at several rank counts, one table.

What it measures: the same synthetic problem (a translating neo-Hookean block, see
``parmpm/bench.py``; default 2D, cpdi, ~1e6 particles, ppc 2, 10 steps of which the first, JIT
compilation, is not timed) run as ``mpirun -n P python -m parmpm bench --json ...`` for each P
in ``--ranks``. For each P it reports the time per step T_P, particle-steps per second, the
parallel efficiency E(P) = T_1 / (P · T_P) (relative to the smallest P when 1 is not in the
list), the share of the step spent in halo exchange (accumulate + fill) and in migration, and
the particle imbalance between ranks.

Expected: E close to 1 while each rank holds many patches (halo traffic grows like a patch
surface, work like its volume) and there are as many cores as ranks; E falls when P exceeds the
physical cores. Runtime: ~1M particles, 2 ranks: a minute or two on a laptop; ``--quick``
(2e4 particles, 5 steps): seconds.

    python run_scripts/mpi_scaling.py --ranks 1,2 --particles 1e6 --steps 10
    python run_scripts/mpi_scaling.py --quick                      # the smoke test's mode

Each run is the command ``mpirun -n P python -m parmpm bench --dim 2 --method cpdi
--particles 1e6 --ppc 2 --steps 10 --json run_scripts/out/mpi_scaling_P.json``; the table goes
to stdout and to ``--csv`` (default ``run_scripts/out/mpi_scaling.csv``), the per-run JSON next
to it. ``--repeat N`` keeps the fastest of N runs per rank count (timings on a shared machine
are noisy). ``mpirun`` is looked up next to this Python first (the venv's MPICH wheel), then on
PATH.
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DEFAULT_CSV = REPO / "run_scripts" / "out" / "mpi_scaling.csv"
COLUMNS = ("ranks", "particles", "seconds_per_step", "particle_steps_per_second", "efficiency",
           "halo_share", "migrate_share", "imbalance", "particles_migrated", "jit_warmup_seconds",
           "peak_rss_mb_per_rank", "halo_bytes_per_step")


def find_mpirun() -> str | None:
    """``mpirun`` next to ``sys.executable`` (a venv's MPICH wheel), else the one on PATH."""
    here = Path(sys.executable).parent / "mpirun"
    if here.is_file() and os.access(here, os.X_OK):
        return str(here)
    return shutil.which("mpirun")


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--ranks", default="1,2", help="comma-separated rank counts (default 1,2)")
    p.add_argument("--dim", type=int, default=2)
    p.add_argument("--method", default="cpdi")
    p.add_argument("--particles", default="1e6")
    p.add_argument("--ppc", type=int, default=2)
    p.add_argument("--steps", type=int, default=10)
    p.add_argument("--patch-size", type=int, default=None)
    p.add_argument("--speed", type=float, default=None)
    p.add_argument("--quick", action="store_true", help="smoke-test size: 2e4 particles, 5 steps")
    p.add_argument("--csv", type=Path, default=DEFAULT_CSV)
    p.add_argument("--repeat", type=int, default=1,
                   help="runs per rank count, the fastest kept (for a busy machine; default 1)")
    p.add_argument("--timeout", type=float, default=1800, help="seconds per mpirun (default 1800)")
    args = p.parse_args(argv)
    if args.quick:
        args.particles, args.steps = "2e4", 5
    args.ranks = [int(r) for r in args.ranks.split(",") if r.strip()]
    return args


def bench_once(mpirun: str, ranks: int, args: argparse.Namespace, json_path: Path) -> dict:
    """One ``mpirun -n ranks python -m parmpm bench`` run; its JSON result."""
    cmd = [mpirun, "-n", str(ranks), sys.executable, "-m", "parmpm", "bench", "--quiet",
           "--dim", str(args.dim), "--method", args.method, "--particles", str(args.particles),
           "--ppc", str(args.ppc), "--steps", str(args.steps), "--json", str(json_path)]
    if args.patch_size:
        cmd += ["--patch-size", str(args.patch_size)]
    if args.speed is not None:
        cmd += ["--speed", str(args.speed)]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))
    print("$ " + " ".join(cmd[:1] + ["-n", str(ranks), "python"] + cmd[4:]), flush=True)
    json_path.unlink(missing_ok=True)
    proc = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=args.timeout)
    print(proc.stdout.rstrip(), flush=True)
    if proc.returncode != 0 or not json_path.is_file():
        sys.exit(f"mpi_scaling: {ranks} rank(s) failed (exit {proc.returncode}):\n{proc.stderr}")
    return json.loads(json_path.read_text(encoding="utf-8"))


def table(results: list[dict]) -> list[dict]:
    """One row per run; efficiency E(P) = P0·T_P0 / (P·T_P), P0 the smallest rank count."""
    base = min(results, key=lambda r: r["ranks"])
    ref = base["ranks"] * base["seconds_per_step"]
    return [{
        "ranks": r["ranks"], "particles": r["particles"], "seconds_per_step": r["seconds_per_step"],
        "particle_steps_per_second": r["particle_steps_per_second"],
        "efficiency": ref / (r["ranks"] * r["seconds_per_step"]),
        "halo_share": r["halo_share"], "migrate_share": r["migrate_share"],
        "imbalance": r["decomposition"]["imbalance"], "particles_migrated": r["particles_migrated"],
        "jit_warmup_seconds": r["jit_warmup_seconds"], "peak_rss_mb_per_rank": r["peak_rss_mb_per_rank"],
        "halo_bytes_per_step": r["decomposition"]["halo_bytes_per_step"],
    } for r in results]


def format_table(rows: list[dict]) -> str:
    head = f"{'ranks':>5} {'s/step':>9} {'p-steps/s':>10} {'eff.':>6} {'halo':>7} {'migrate':>8} {'imbal.':>7}"
    lines = [head]
    for r in rows:
        lines.append(f"{r['ranks']:>5} {r['seconds_per_step']:>9.4f} {r['particle_steps_per_second']:>10.3e} "
                     f"{r['efficiency']:>6.2f} {100 * r['halo_share']:>6.1f}% "
                     f"{100 * r['migrate_share']:>7.1f}% {r['imbalance']:>7.3f}")
    return "\n".join(lines)


def main(argv=None) -> int:
    args = parse_args(argv)
    mpirun = find_mpirun()
    if mpirun is None:
        sys.exit("mpi_scaling: no mpirun next to this Python nor on PATH (pip install mpich)")
    args.csv.parent.mkdir(parents=True, exist_ok=True)
    results = []
    for p in args.ranks:
        path = args.csv.with_name(f"{args.csv.stem}_{p}.json")
        runs = [bench_once(mpirun, p, args, path) for _ in range(max(1, args.repeat))]
        results.append(min(runs, key=lambda r: r["seconds_per_step"]))
        path.write_text(json.dumps(results[-1], indent=2) + "\n", encoding="utf-8")
    rows = table(results)
    first = results[0]
    print(f"\nstrong scaling: {first['dim']}D {first['method']}, {first['particles']:,} particles, "
          f"{first['timed_steps']} timed steps")
    print(format_table(rows))
    with args.csv.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {args.csv}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
