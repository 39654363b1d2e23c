"""Reading a large particle CSV: wall time and peak memory of ``parmpm show`` of a scene whose
one body is a particle file of N rows (issue 41, item 12).

What it measures: a 2D table ``x, y, volume`` of N particles (random positions in a 1 m square,
each value its shortest round-trip repr, 17 significant digits at most, as ``repr``/``np.savetxt``
write them) under a scene with a grid around it; ``parmpm show`` of that scene runs in a fresh
process, its wall time, CPU time and peak resident memory (the child's own ``ru_maxrss``)
recorded; a 1000-row file first, not shown, so that compiling the reader (once per source tree)
is not counted. On a shared machine the CPU time is the steadier number. ``show`` reads the file once (its bounds, count and checks), as every rank
of a run does at scene load. The goal: 10⁷ rows in ≤ 10 s and ≤ 1.5 GB.

Measured on two cores shared with other jobs (load average 5-6, so the wall time is about three
times the CPU time); before: the row-by-row reader (every row a Python string), after: the
compiled pass (:mod:`parmpm.io.particle_file.scan`):

    rows    MB     before: wall   CPU     peak RSS     after: wall   CPU    peak RSS
    10^5     4.4           1.6 s   0.6 s     89 MB             1.9 s  0.7 s   150 MB
    10^6    44             11 s    4.6 s    588 MB             3.4 s  1.5 s   211 MB
    10^7   444            238 s   53 s     5487 MB             14 s   6.4 s   816 MB

(after, 10^5: the compiled reader's ~0.5 s of loading numba and its cached code.)

    python run_scripts/benchmarks/particle_csv.py                    # 1e5, 1e6, 1e7 rows
    python run_scripts/benchmarks/particle_csv.py --rows 1e5 1e6
    python run_scripts/benchmarks/particle_csv.py --source /path/to/old/checkout   # "before"

Output: a table on stdout and ``particle_csv.csv`` in ``--out`` (default
``run_scripts/out/particle_csv``); the CSV files are written there once and reused.
"""
from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
SCENE = """dim = 2
[grid]
origin = [-0.1, -0.1]
cell_size = 0.01
cells = [120, 120]
[materials.rock]
model = "linear_elastic"
density = 2000.0
youngs_modulus = 1e7
poisson_ratio = 0.3
[[bodies]]
shape = "particles"
material = "rock"
file = "{file}"
[time]
steps = 1
"""


def write_table(path: Path, n: int, seed: int = 41) -> None:
    """N rows ``x, y, volume``, written block by block (the writer's memory stays small)."""
    rng = np.random.default_rng(seed)
    with open(path, "w") as f:
        f.write("x, y, volume\n")
        for k in range(0, n, 1_000_000):
            m = min(1_000_000, n - k)
            a = np.column_stack([rng.uniform(0.0, 1.0, (m, 2)), np.full(m, 1.0 / n)])
            f.write("".join(f"{r[0]!r}, {r[1]!r}, {r[2]!r}\n" for r in a.tolist()))


#: the child: ``parmpm show`` of argv[1] (stdout discarded), then its own CPU seconds and peak
#: resident memory (``ru_maxrss``, kB on Linux) as one line on stderr
CHILD = """
import os, resource, sys
from parmpm.cli.main import main
sys.stdout = open(os.devnull, "w")
rc = main(["show", sys.argv[1]])
r = resource.getrusage(resource.RUSAGE_SELF)
print("RUSAGE", r.ru_utime + r.ru_stime, r.ru_maxrss, file=sys.stderr)
sys.exit(rc)
"""


def show(scene: Path, source: Path) -> tuple[float, float, float, int]:
    """(wall s, CPU s, peak RSS MB, return code) of ``parmpm show`` of ``scene`` in a child,
    the parmpm of the tree ``source``."""
    t = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", CHILD, str(scene)], cwd=source,
                          stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - t
    line = [s for s in done.stderr.splitlines() if s.startswith("RUSAGE")]
    if not line:
        sys.stderr.write(done.stderr)
        return wall, float("nan"), float("nan"), done.returncode
    _, cpu, peak = line[-1].split()
    return wall, float(cpu), int(peak) / 1024.0, done.returncode


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", nargs="+", type=lambda s: int(float(s)), default=[10**5, 10**6, 10**7])
    ap.add_argument("--out", type=Path, default=ROOT / "run_scripts" / "out" / "particle_csv")
    ap.add_argument("--source", type=Path, default=ROOT,
                    help="the tree whose parmpm runs (another checkout: the code before a change)")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    print(f"{'rows':>10}  {'MB on disk':>10}  {'wall s':>8}  {'CPU s':>8}  {'peak RSS MB':>11}  rc")
    for n in [1000] + sorted(args.rows):  # 1000 rows first: compiles (if not cached), not shown
        table = args.out / f"particles_{n}.csv"
        if not table.exists():
            write_table(table, n)
        scene = args.out / f"scene_{n}.toml"
        scene.write_text(SCENE.format(file=table))
        wall, cpu, peak, rc = show(scene, args.source)
        if n == 1000 and n not in args.rows:
            continue
        size = table.stat().st_size / 2**20
        rows.append({"rows": n, "file_mb": round(size, 1), "wall_s": round(wall, 2),
                     "cpu_s": round(cpu, 2), "peak_rss_mb": round(peak, 1), "rc": rc})
        print(f"{n:>10}  {size:>10.1f}  {wall:>8.2f}  {cpu:>8.2f}  {peak:>11.1f}  {rc}",
              flush=True)
    with open(args.out / "particle_csv.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
