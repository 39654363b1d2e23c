"""One core against the yardstick: parmpm's full 2D step beside a bare numba MPM step, same run.

What it measures: ``python -m parmpm bench --dim 2 --method M --update U --particles N`` (the
whole step: patches, ghost layers, sorting, boundary conditions, the CFL reduction) and the
yardstick ``--yardstick PATH`` (an external script, not part of parmpm, run from where it lies:
``PATH --method cpdi|hat --n N`` takes one plain numba USL step, no patches, no MPI, and prints a
``RESULT`` line) alternately, ``--repeat`` times each,
keeping each one's fastest. Cases: 2D cpdi (USL, its default), 2D mpm with USL (the yardstick's
algorithm), 2D mpm with MUSL (parmpm's default for mpm: a second P2G/G2P pass, so ~1.5× the
work), and 2D bspline with APIC and with MLS (USL) against the yardstick's C ``mls`` case (``ref_step.c`` beside the script), a
quadratic B-spline MLS-MPM step in C (compiled here with ``gcc -O3 -march=native``; skipped without
gcc). The C case fuses the stress into the affine matrix and uses ``C_p`` as the velocity gradient
(MLS-MPM): parmpm's ``transfer = "mls"`` is that algorithm, its APIC keeps the force field and the
gradient weights. And 2D cpdi2 (USL) beside
the numba CPDI1 yardstick (CPDI2 interpolates the same way from tracked corners). The ratio ``parmpm / yardstick`` of particle-steps per second is what the performance
issue asks about (≥ 0.7, goal 1.0); the figure stacks parmpm's phases in ns per particle-step
beside the yardstick's total.

Expected: ratio ≈ 0.8–1.0 for cpdi and mpm-USL at 1e6 particles on one quiet core. Runtime: ~2
minutes at 1e6 with --repeat 3; ``--quick`` (2e4 particles, one repeat, no yardstick unless it is
found): ~20 s.

    python run_scripts/benchmarks/throughput.py --particles 1e6 --repeat 3
    python run_scripts/benchmarks/throughput.py --quick
    python run_scripts/benchmarks/throughput.py --dt 5e-5 ...   # parmpm at the yardsticks' fixed step

Output: ``throughput.csv`` and ``throughput.png`` (``throughput_fixed_dt.*`` with ``--dt``) in ``--out`` (default
``run_scripts/out/throughput``; ``--figures docs/figures`` for the documentation's figure).
Without ``--yardstick PATH`` (or with ``none``) parmpm runs alone."""
from __future__ import annotations

import json
import math
import shutil
import re
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py, the groups
import study

#: (method, update, yardstick method, transfer); "mls" is the C yardstick's quadratic B-spline
#: APIC/MLS case (``ref_step.c``, compiled here with gcc when it is found)
CASES = (("cpdi", "usl", "cpdi", "flip"), ("mpm", "usl", "hat", "flip"),
         ("mpm", "musl", "hat", "flip"), ("bspline", "usl", "mls", "apic"),
         ("bspline", "usl", "mls", "mls"), ("cpdi2", "usl", "cpdi", "flip"))
PHASE_ORDER = ("p2g", "accumulate", "grid", "fill", "g2p", "migrate", "sort", "reduce")


def parmpm_bench(method: str, update: str, particles: float, steps: int,
                 transfer: str = "flip", dt: float | None = None) -> dict:
    """One ``parmpm bench`` run in a fresh process (``dt``: a fixed step, as the yardsticks
    take); its JSON result."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "bench.json"
        cmd = [sys.executable, "-m", "parmpm", "bench", "--quiet", "--dim", "2", "--method", method,
               "--update", update, "--particles", f"{particles:g}", "--steps", str(steps),
               "--transfer", transfer, "--json", str(out)] + ([] if dt is None else ["--dt", f"{dt!r}"])
        proc = subprocess.run(cmd, cwd=study.ROOT, capture_output=True, text=True, timeout=1800)
        if proc.returncode != 0:
            raise SystemExit(f"throughput: parmpm bench failed:\n{proc.stderr}")
        return json.loads(out.read_text(encoding="utf-8"))


def compile_c(path: Path) -> Path | None:
    """``ref_step.c`` beside the numba yardstick, built with ``gcc -O3 -march=native`` into a
    temporary folder (None without gcc or the source)."""
    src = path.with_suffix(".c")
    gcc = shutil.which("gcc")
    if gcc is None or not src.is_file():
        return None
    exe = Path(tempfile.mkdtemp(prefix="ref_step_")) / "ref_step"
    proc = subprocess.run([gcc, "-O3", "-march=native", "-o", str(exe), str(src), "-lm"],
                          capture_output=True, text=True)
    return exe if proc.returncode == 0 else None


def yardstick(path: Path, method: str, particles: float, c_exe: Path | None = None) -> float:
    """Median particle-steps per second of one yardstick run (its ``RESULT`` line); the C one
    (``c_exe``) for ``mls``."""
    cmd = [sys.executable, str(path), "--method", method, "--n", f"{particles:g}"]
    if method == "mls":
        if c_exe is None:
            return math.nan
        cmd = [str(c_exe), "mls", str(int(particles)), "10", "5"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
    found = re.search(r"^RESULT .*median=(\S+)", proc.stdout, re.M)
    if proc.returncode != 0 or not found:
        raise SystemExit(f"throughput: yardstick {path} failed:\n{proc.stdout}\n{proc.stderr}")
    return float(found.group(1))


def measure(args) -> list[dict]:
    rows = []
    c_exe = compile_c(args.yardstick) if args.yardstick else None
    for method, update, ymethod, transfer in CASES:
        best, ybest = None, math.nan
        for _ in range(args.repeat):
            r = parmpm_bench(method, update, args.particles, args.steps, transfer, args.dt)
            if best is None or r["particle_steps_per_second"] > best["particle_steps_per_second"]:
                best = r
            if args.yardstick:
                y = yardstick(args.yardstick, ymethod, args.particles, c_exe)
                ybest = max(y, ybest if math.isfinite(ybest) else 0.0) if math.isfinite(y) else ybest
        n = best["particles"]
        row = {"method": method, "update": update, "transfer": transfer,
               "yardstick": "C (gcc)" if ymethod == "mls" else "numba", "particles": n,
               "fixed_dt": args.dt if args.dt is not None else math.nan,
               "parmpm_particle_steps_per_second": best["particle_steps_per_second"],
               "yardstick_particle_steps_per_second": ybest,
               "ratio": best["particle_steps_per_second"] / ybest if math.isfinite(ybest) else math.nan,
               "parmpm_ns_per_particle_step": best["ns_per_particle_step"],
               "yardstick_ns_per_particle_step": 1e9 / ybest if math.isfinite(ybest) else math.nan,
               "bytes_per_particle": best["bytes_per_particle"],
               "jit_warmup_seconds": best["jit_warmup_seconds"]}
        for k in PHASE_ORDER:
            row[f"{k}_ns"] = 1e9 * best["phase_seconds_per_step"].get(k, 0.0) / n
        row["stress_in_g2p_ns"] = 1e9 * best["stress_in_g2p_seconds_per_step"] / n
        rows.append(row)
        print(f"{method:>7} {update:<4} {transfer:<4} parmpm {row['parmpm_particle_steps_per_second']:.3e} p-steps/s, "
              f"yardstick {ybest:.3e}, ratio {row['ratio']:.2f}", flush=True)
    return rows


def plot(rows: list[dict], path: Path) -> Path:
    fig, axes = study.figure(1, 1, size=(7.0, 4.2))
    ax = axes[0, 0]
    colors = dict(zip(PHASE_ORDER, ("#1f77b4", "#aec7e8", "#ff7f0e", "#ffbb78", "#2ca02c",
                                    "#98df8a", "#d62728", "#9467bd")))
    labels = []
    for i, r in enumerate(rows):
        bottom = 0.0
        for k in PHASE_ORDER:
            h = r[f"{k}_ns"]
            ax.bar(2 * i, h, bottom=bottom, color=colors[k], width=0.8,
                   label=k if i == 0 else None)
            bottom += h
        ax.text(2 * i, bottom, f"{r['parmpm_ns_per_particle_step']:.0f}", ha="center", va="bottom",
                fontsize=8)
        y = r["yardstick_ns_per_particle_step"]
        if math.isfinite(y):
            ax.bar(2 * i + 0.9, y, color="0.6", width=0.8, label="yardstick" if i == 0 else None)
            ax.text(2 * i + 0.9, y, f"{y:.0f}\n×{r['ratio']:.2f}", ha="center", va="bottom", fontsize=8)
        labels.append(f"{r['method']}\n{r['update'].upper()}"  # stacked: no label runs into the next
                      + (f" {r['transfer'].upper()}\n(vs C mls)" if r["transfer"] != "flip"
                         else ""))
    ax.set_xticks([2 * i + 0.45 for i in range(len(rows))], labels)
    ax.set_ylabel("ns per particle-step (one core)")
    fixed = rows[0]["fixed_dt"]
    ax.set_title(f"2D, {rows[0]['particles']:,} particles: parmpm phases vs the numba yardstick"
                 + (f" (fixed Δt = {fixed:g} s)" if math.isfinite(fixed) else ""), fontsize=10)
    ax.legend(fontsize=7, ncol=3)
    ax.set_ylim(0, 1.25 * max(max(r["parmpm_ns_per_particle_step"], r["yardstick_ns_per_particle_step"]
                                  if math.isfinite(r["yardstick_ns_per_particle_step"]) else 0)
                              for r in rows))
    return study.save(fig, path)


def main(argv=None) -> int:
    p = study.parser(__doc__)
    p.add_argument("--particles", type=float, default=1e6)
    p.add_argument("--steps", type=int, default=10)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--dt", type=float, default=None,
                   help="a fixed step for parmpm (time.dt, s; the yardsticks' is 5e-5), whose G2P "
                        "leaves out the wave speed (default: the CFL step)")
    p.add_argument("--yardstick", default="none",
                   help="path of the yardstick script, or 'none' (the default)")
    args = p.parse_args(argv)
    if args.quick:
        args.particles, args.steps, args.repeat = 2e4, 4, 1
    y = None if args.yardstick == "none" else Path(args.yardstick)
    if y is not None and not y.is_file():
        print(f"throughput: no yardstick at {y}; parmpm only", flush=True)
        y = None
    args.yardstick = y
    out, figs = study.folders(args, "throughput")
    rows = measure(args)
    name = "throughput" if args.dt is None else "throughput_fixed_dt"
    study.write_csv(out / f"{name}.csv", rows)
    print(study.wrote(out / f"{name}.csv"))
    print(study.wrote(plot(rows, figs / f"{name}.png")))
    return 0


if __name__ == "__main__":
    sys.exit(main())
