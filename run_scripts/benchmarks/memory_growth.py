"""Memory over a long run: does a run's resident memory stay flat however many steps it takes?

What it measures: the resident memory (``VmRSS`` of ``/proc/self/status``) of one process
running a tiny scene for many steps, sampled at every output time (``Simulation.observers``,
every ``--every`` steps), in three cases, each in a fresh interpreter:

* ``both``: a snapshot every ``--every`` steps and the scene's metrics (the vibrating bar's,
  sampled every step) — issue 28's test: 200,000 steps, a snapshot every 100;
* ``metrics``: the metrics, no snapshots;
* ``none``: neither (the floor: what the stepping itself does).

The scene is the ``vibrating_bar`` (1D, linear elastic, CPDI, 32 particles on 20 cells), run for
``--steps`` steps (``time.steps``; ``time.end`` out of reach), the history at its default
(200 rows per run). Tiny, so that 200,000 steps take a minute or two: what grows with the
steps and the snapshots is the record of them, not the particles.

Expected: flat. Before issue 28 three things grew: the snapshot writer kept the XDMF index as
an XML tree in memory (~12 kB per snapshot here, 50 kB with more fields), HDF5 cached the
series' metadata up to 2 MB on disk, ~50 MB in memory (~130 kB per snapshot until full), and
every metric kept a Python list per column (~0.1 kB per step for the vibrating bar, and the
whole list went into every checkpoint). Measured on two shared cores (CPU only), 200,000 steps,
a snapshot every 100 (2,000 snapshots); RSS in MB at steps 2,000 / 100,000 / 200,000, and the
slope over the second half:

    case      before (bbc2b48)                         after
    both      181.9 / 271.2 / 306.0, 347 kB/1000 steps   180.4 / 181.0 / 181.4, 2.1 kB/1000 steps
    metrics   165.1 / 176.9 / 188.4, 117 kB/1000 steps   165.2 / 165.4 / 165.6, 2.1 kB/1000 steps
    none      164.5 / 164.8 / 164.9, 2.0 kB/1000 steps   (flat; its runs' baselines included a
                                                          recompile of the kernels)

A run whose kernels compile during it starts higher (LLVM's memory) and can hide growth for a
while in what the compiler freed: run ``--quick`` once first to warm numba's cache.

Runtime: ~1–3 minutes per case at 200,000 steps on one core (``--quick``: 4,000 steps, a few
seconds per case).

    python run_scripts/benchmarks/memory_growth.py                          # the three cases, 200,000 steps
    python run_scripts/benchmarks/memory_growth.py --cases both --steps 50000
    nice python run_scripts/benchmarks/memory_growth.py --quick             # the smoke test's run

Output: a table on stdout and, in ``--out`` (default ``run_scripts/out/memory_growth``),
``memory_growth.csv`` (one row per case: RSS at the start, middle and end, the growth per 1,000
steps and per snapshot over the second half) and ``memory_growth_samples.csv`` (every sample:
case, step, RSS).
"""
from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[1] / "out" / "memory_growth"
CASES = ("both", "metrics", "none")

SCENE = """
description = "memory_growth.py: the vibrating bar, tiny, for many steps"
dim = 1
[grid]
origin = 0.0
cell_size = 1.5625
cells = 20
patch_size = 8
[materials.bar]
model = "linear_elastic"
density = 1.0
youngs_modulus = 100.0
poisson_ratio = 0.0
[[bodies]]
shape = "box"
min = 0.0
max = 25.0
material = "bar"
ppc = 2
[bodies.vibration]
amplitude = 0.1
mode = 1
axis = 0
[method]
interpolator = "cpdi"
[boundary]
x_min = "clamped"
[time]
end = 1e12
cfl = 0.4
steps = {steps}
[output]
every_steps = {every}
snapshots = {snapshots}
figure = false
[metrics]
kind = "{metrics}"
every_steps = 1
[checkpoint]
at_end = false
"""


def rss_mb() -> float:
    """This process's resident memory (MB) from /proc/self/status."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    raise RuntimeError("no VmRSS in /proc/self/status (Linux only)")


def worker(case: str, steps: int, every: int, folder: Path) -> list[tuple[int, float]]:
    """Run one case in this process; (step, RSS MB) at every output time."""
    import gc

    from parmpm import Simulation, load_scene

    text = SCENE.format(steps=steps, every=every, snapshots="true" if case == "both" else "false",
                        metrics="none" if case == "none" else "vibrating_bar")
    path = folder / f"{case}.toml"
    path.write_text(text)
    sim = Simulation(load_scene(path), folder / case, quiet=True)
    samples = []

    def sample(sim):
        gc.collect()
        samples.append((int(sim.nstep), rss_mb()))

    sim.observers.append(sample)
    sim.run()
    return samples


def at(samples, step: int) -> float:
    """RSS of the first sample at or after ``step``."""
    for s, r in samples:
        if s >= step:
            return r
    return samples[-1][1]


def summarise(case: str, samples, steps: int, every: int) -> dict:
    s = np.array([a for a, _ in samples], float)
    r = np.array([b for _, b in samples], float)
    half = s >= steps / 2
    slope = float(np.polyfit(s[half], r[half], 1)[0]) if half.sum() > 2 else float("nan")
    start_step = max(every, steps // 100)
    return {"case": case, "steps": steps, "every": every,
            "rss_start_mb": at(samples, start_step), "rss_middle_mb": at(samples, steps // 2),
            "rss_end_mb": r[-1], "start_step": start_step,
            "growth_kb_per_1000_steps": 1024.0 * 1000.0 * slope,
            "growth_kb_per_output": 1024.0 * every * slope}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200_000)
    ap.add_argument("--every", type=int, default=100, help="steps between outputs (snapshots)")
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--quick", action="store_true", help="4,000 steps")
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    steps = 4000 if args.quick else args.steps
    if args.worker:  # one case, in this fresh interpreter: its samples as JSON on stdout
        with tempfile.TemporaryDirectory(dir=args.out) as tmp:
            print(json.dumps(worker(args.worker, steps, args.every, Path(tmp))))
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    cases = [c for c in args.cases.split(",") if c]
    for c in cases:
        if c not in CASES:
            ap.error(f"--cases: unknown case {c!r} (known: {', '.join(CASES)})")
    rows, all_samples = [], []
    for case in cases:
        cmd = [sys.executable, __file__, "--worker", case, "--steps", str(steps),
               "--every", str(args.every), "--out", str(args.out)]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            print(proc.stdout[-2000:] + proc.stderr[-2000:], file=sys.stderr)
            return proc.returncode
        samples = json.loads(proc.stdout.strip().splitlines()[-1])
        rows.append(summarise(case, samples, steps, args.every))
        all_samples += [(case, s, r) for s, r in samples]
    print(f"{'case':8} {'steps':>8} {'RSS start':>10} {'middle':>8} {'end':>8} "
          f"{'kB/1000 steps':>14} {'kB/output':>10}")
    for r in rows:
        print(f"{r['case']:8} {r['steps']:>8} {r['rss_start_mb']:>10.1f} {r['rss_middle_mb']:>8.1f} "
              f"{r['rss_end_mb']:>8.1f} {r['growth_kb_per_1000_steps']:>14.2f} "
              f"{r['growth_kb_per_output']:>10.3f}")
    with open(args.out / "memory_growth.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    with open(args.out / "memory_growth_samples.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["case", "step", "rss_mb"])
        w.writerows(all_samples)
    return 0


if __name__ == "__main__":
    sys.exit(main())
