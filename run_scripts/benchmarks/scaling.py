"""Strong and weak scaling of the time step, and a cost model fitted to them (``cost_model.py``).

What it measures. ``parmpm bench`` (a translating neo-Hookean block, ``parmpm/cli/bench.py``; the
first step, JIT, untimed) run as ``mpirun -n P python -m parmpm bench --json ...`` for each P in
``--ranks`` (1 is always added: the reference):

* **strong scaling** — a fixed problem (default 2D cpdi, 1e6 particles, ppc 2, 10 steps):
  ``E(P) = T_1 / (P·T_P)``;
* **weak scaling** — a fixed load per rank (default 5e5 particles per rank):
  ``E(P) = T_1 / T_P`` (times ``N_P / (P·N_1)``, which corrects for the block's rounding of the
  particle count; 1 when ``N_P = P·N_1`` exactly);
* **t_p in 3D** — one 1-rank 3D cpdi bench (default 2e5 particles): the predictions are for 3D;
* **communication constants** — ``mpirun -n 2 python run_scripts/benchmarks/comm_constants.py``: one-way ping-pong
  times over 8 B … 4 MiB (fitted by ``t = α + n/β``) and an Allreduce of 5 doubles (``α_r`` per
  ``⌈log2 P⌉`` stage; also under ``-n P`` for every P > 2 in ``--ranks``, Allreduce only).

Then it fits the cost model (equations in ``cost_model.py``; fit, check and predictions in
``scaling_model.py``), checks its halo-byte formula against every multi-rank run's measured
``halo_bytes_per_step`` (the patch partition is rebuilt from the bench block with
``decomposition``'s own Morton assignment; the formula itself is independent of the halo code),
compares predicted with measured T and E at the measured rank counts, and predicts the
strong-scaling efficiency of 3D cubes of 1e8, 1e9 and 1e10 particles on 1e2 … 1e4 ranks of an
assumed cluster (α_net = 1.5 µs, β_net = 12.5 GB/s: 100 Gb/s InfiniBand).

Rank counts above ``os.cpu_count()`` run, but are flagged ``oversubscribed`` in both CSVs, drawn
hollow, and left out of the fits (t_p comes from 1 rank; α_r from the Allreduce timings of the
other rank counts; the ping-pong needs 2 ranks and is flagged in ``cost_model.json`` if 2 is
already too many).

Expected: strong E close to 1 while every rank holds many patches and has a core of its own (halo
traffic grows like a rank's surface, work like its volume), weak E ≈ 1; E falls once P exceeds
the cores, and on a machine busy with other work (the model, which assumes a core per rank, then
over-predicts E). The halo formula matches the measured bytes exactly while the patch set has not
changed during the run (the bench's default speed). Predicted 3D E stays above 0.97 while a rank
holds ≳ 30 patches and drops to ~0.76 at ~3 patches per rank, through whole-patch load imbalance:
with t_p ≈ 4 µs per 3D particle-step, communication is < 0.3 % of the step on the assumed
network (it scales like 1/t_p); 1e8 particles (~3 000 patches of 16³ cells) cannot use 5 000
ranks at all.

Outputs (``--out``, default ``run_scripts/out/scaling``): ``scaling.csv`` (one row per run, a
``kind`` column: strong / weak; every bench phase's share as ``share_<phase>``), ``cost_model.csv``
(predictions, and the check rows against the measurements), ``cost_model.json`` (the fitted and
the assumed constants, labelled), the bench and probe JSON of every run; ``scaling.png``
(efficiency and time per step against ranks, ideal lines, model check) and ``cost_model.png``
(predicted efficiency against ranks) in ``--out`` too (``make figures`` passes ``--figures
docs/figures``).

Runtime on 2 cores: full about a minute per ``--repeat`` (2D 1e6 on 1 and 2 ranks — the weak
2-rank run is the same run —, 5e5 on 1 rank, 3D 2e5 on 1 rank, the probe); ``--quick`` (2e4
particles, 2e4 per rank, 3D 8e3, 4 steps) ~10 s. It launches ``mpirun`` itself: run it with
plain ``python``, never under ``mpirun``::

    python run_scripts/benchmarks/scaling.py --ranks 1,2 --repeat 3              # the lead's full study
    python run_scripts/benchmarks/scaling.py --quick                             # the smoke test's mode
    python run_scripts/benchmarks/scaling.py --ranks 1,2,4 --kind strong --particles 4e6 --steps 6
    python run_scripts/benchmarks/scaling.py --dim 3 --particles 2e5 --per-rank 1e5 --out /tmp/sc3

Each run is ``mpirun -n P python -m parmpm bench --dim 2 --method cpdi --particles 1e6 --ppc 2
--steps 10 --json run_scripts/out/scaling/bench_2d_P1_N1000000.json`` (``--patch-size``,
``--speed`` passed through; the 3D run keeps the 3D default patch size, as the prediction does).
``--repeat N`` keeps the fastest of N runs of each (a shared machine only ever adds time).
``mpirun`` is the one next to this Python (the venv's MPICH wheel), else the one on PATH.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py, the groups
from models import cost_model as cm
import numpy as np
from models.scaling_model import model_study, partition_halo
from study import ROOT, compact_png, figure, folders, parser, save, write_csv, wrote

KINDS = ("strong", "weak")
QUICK = {"particles": 2e4, "per_rank": 2e4, "particles_3d": 8e3, "steps": 4}
ALPHA_NET = 1.5e-6     # s, assumed inter-node latency (100 Gb/s InfiniBand)
BETA_NET = 12.5e9      # bytes/s, assumed inter-node bandwidth (100 Gb/s)
PREDICT_PARTICLES = "1e8,1e9,1e10"
PREDICT_RANKS = "100,200,500,1000,2000,5000,10000"
COLOURS = {"strong": "tab:blue", "weak": "tab:orange"}
MARKERS = {"strong": "o", "weak": "s"}


# --- running -----------------------------------------------------------------------------------
def find_mpirun() -> str | None:
    """``mpirun`` next to ``sys.executable`` (a venv's MPICH wheel), else the one on PATH."""
    here = Path(sys.executable).parent / "mpirun"
    if here.is_file() and os.access(here, os.X_OK):
        return str(here)
    return shutil.which("mpirun")


def launched_by_mpirun() -> bool:
    """True when this process is itself one of several MPI ranks (it must launch, not be launched)."""
    for var in ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE", "PMIX_SIZE", "MPI_LOCALNRANKS"):
        try:
            if int(os.environ.get(var, "1")) > 1:
                return True
        except ValueError:
            pass
    return False


def _count(text) -> int:
    value = float(text)
    if not math.isfinite(value) or value < 1:
        raise SystemExit(f"scaling: expected a positive particle count, got {text!r}")
    return int(round(value))


def _ints(text: str) -> list[int]:
    return [int(float(t)) for t in text.split(",") if t.strip()]


class Runner:
    """Launches bench and probe runs (each under ``mpirun -n P`` with a timeout), keeps the
    fastest of ``repeat`` runs, and never runs the same (dim, ranks, particles) twice."""

    def __init__(self, args, out: Path):
        self.mpirun = find_mpirun()
        if self.mpirun is None:
            raise SystemExit("scaling: no mpirun next to this Python nor on PATH (pip install mpich)")
        self.args, self.out = args, out
        self.env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
        self.cache: dict[tuple, dict] = {}

    def _run(self, ranks: int, argv: list[str], what: str) -> None:
        cmd = [self.mpirun, "-n", str(ranks), sys.executable, *argv]
        print(f"$ mpirun -n {ranks} python {' '.join(argv)}", flush=True)
        try:
            proc = subprocess.run(cmd, cwd=ROOT, env=self.env, capture_output=True, text=True,
                                  timeout=self.args.timeout)
        except subprocess.TimeoutExpired:
            raise SystemExit(f"scaling: {what} on {ranks} rank(s) ran past --timeout "
                             f"{self.args.timeout:g} s") from None
        if proc.returncode != 0:
            raise SystemExit(f"scaling: {what} on {ranks} rank(s) failed (exit {proc.returncode}):\n"
                             f"{proc.stdout[-2000:]}{proc.stderr[-3000:]}")

    def bench(self, dim: int, ranks: int, particles: int, patch_size: int | None) -> dict:
        """The fastest of ``--repeat`` bench runs; the request is kept under ``"request"``."""
        a = self.args
        key = (dim, ranks, particles, patch_size)
        if key in self.cache:
            return self.cache[key]
        path = self.out / f"bench_{dim}d_P{ranks}_N{particles}.json"
        argv = ["-m", "parmpm", "bench", "--quiet", "--dim", str(dim), "--method", a.method,
                "--particles", str(particles), "--ppc", str(a.ppc), "--steps", str(a.steps),
                "--json", str(path)]
        if patch_size:
            argv += ["--patch-size", str(patch_size)]
        if a.speed is not None:
            argv += ["--speed", repr(a.speed)]
        runs = []
        for _ in range(max(1, a.repeat)):
            path.unlink(missing_ok=True)
            self._run(ranks, argv, "bench")
            runs.append(json.loads(path.read_text(encoding="utf-8")))
        best = min(runs, key=lambda r: r["seconds_per_step"])
        best["request"] = {"dim": dim, "method": a.method, "particles": particles, "ppc": a.ppc,
                           "steps": a.steps, "patch_size": patch_size,
                           "speed": 1.0 if a.speed is None else a.speed}
        path.write_text(json.dumps(best, indent=2) + "\n", encoding="utf-8")
        print(f"  {dim}D, {ranks} rank(s), {best['particles']:,} particles: "
              f"{best['seconds_per_step']:.4g} s/step (fastest of {len(runs)})", flush=True)
        self.cache[key] = best
        return best

    def probe(self, ranks: int, pingpong: bool) -> dict:
        path = self.out / f"probe_{ranks}.json"
        path.unlink(missing_ok=True)
        argv = ["run_scripts/benchmarks/comm_constants.py", "--json", str(path)]  # cwd: ROOT
        argv += ["--quick"] if self.args.quick else []
        argv += [] if pingpong else ["--no-pingpong"]
        self._run(ranks, argv, "probe")
        return json.loads(path.read_text(encoding="utf-8"))


# --- tables --------------------------------------------------------------------------------------
def scaling_rows(kind: str, results: list[dict], cores: int) -> list[dict]:
    """One CSV row per run; efficiency against the 1-rank run (see the module docstring)."""
    base = min(results, key=lambda r: r["ranks"])
    rows = []
    phases = []
    for r in results:
        phases += [k for k in r["phase_share"] if k not in phases]
    for r in results:
        P, T, N = r["ranks"], r["seconds_per_step"], r["particles"]
        # strong (N = N_1): T_1/(P·T_P); weak: per-rank throughput against the 1-rank run's
        eff = base["ranks"] * base["seconds_per_step"] * N / (base["particles"] * P * T)
        dec = r["decomposition"]
        row = {"kind": kind, "ranks": P, "oversubscribed": P > cores, "dim": r["dim"],
               "method": r["method"], "particles": N, "particles_per_rank": N / P,
               "seconds_per_step": T, "particle_steps_per_second": r["particle_steps_per_second"],
               "efficiency": eff, "imbalance": dec["imbalance"], "patches": dec["patches"],
               "halo_share": r["halo_share"], "halo_bytes_per_step": dec["halo_bytes_per_step"],
               "halo_bytes_model": r.get("halo_model", {}).get("total", 0.0),
               "particles_migrated": r["particles_migrated"],
               "jit_warmup_seconds": r["jit_warmup_seconds"],
               "peak_rss_mb_per_rank": r["peak_rss_mb_per_rank"]}
        row.update({f"share_{k}": r["phase_share"].get(k, math.nan) for k in phases})
        rows.append(row)
    return rows


def format_rows(rows: list[dict]) -> str:
    lines = [f"{'kind':>6} {'ranks':>5} {'particles':>10} {'s/step':>9} {'p-steps/s':>10} "
             f"{'eff.':>5} {'halo':>6} {'imbal.':>6} {'halo B meas.':>12} {'formula':>10}"]
    for r in rows:
        lines.append(f"{r['kind']:>6} {r['ranks']:>5} {r['particles']:>10,} {r['seconds_per_step']:>9.4f} "
                     f"{r['particle_steps_per_second']:>10.3e} {r['efficiency']:>5.2f} "
                     f"{100 * r['halo_share']:>5.1f}% {r['imbalance']:>6.3f} "
                     f"{r['halo_bytes_per_step']:>12,} {r['halo_bytes_model']:>10,.0f}"
                     + ("  (oversubscribed)" if r["oversubscribed"] else ""))
    return "\n".join(lines)


# --- charts --------------------------------------------------------------------------------------
def _points(ax, x, y, kind, hollow, **kw):
    x, y, hollow = np.asarray(x), np.asarray(y), np.asarray(hollow, bool)
    c, m = COLOURS[kind], MARKERS[kind]
    ax.plot(x, y, "-", color=c, lw=1.2, alpha=0.8)
    ax.plot(x[~hollow], y[~hollow], m, color=c, ms=7, label=kw.get("label"))
    if np.any(hollow):
        ax.plot(x[hollow], y[hollow], m, mfc="none", mec=c, ms=7, mew=1.5,
                label=(kw.get("label") or kind) + " (oversubscribed)")


def chart_scaling(rows: list[dict], checks: list[dict], cores: int, path: Path) -> Path:
    fig, axes = figure(1, 2, size=(10.5, 4.2))
    ax_e, ax_t = axes[0]
    ranks_all = sorted({r["ranks"] for r in rows})
    for kind in KINDS:
        rr = sorted((r for r in rows if r["kind"] == kind), key=lambda r: r["ranks"])
        if not rr:
            continue
        P = [r["ranks"] for r in rr]
        over = [r["oversubscribed"] for r in rr]
        n0 = rr[0]["particles"]
        lab = (f"strong: {n0:,} particles" if kind == "strong"
               else f"weak: {rr[0]['particles_per_rank']:,.0f} per rank")
        _points(ax_e, P, [r["efficiency"] for r in rr], kind, over, label=lab)
        _points(ax_t, P, [r["seconds_per_step"] for r in rr], kind, over, label=lab)
        T1 = rr[0]["seconds_per_step"] * rr[0]["ranks"]
        ideal = [T1 / p if kind == "strong" else rr[0]["seconds_per_step"] for p in P]
        ax_t.plot(P, ideal, ":", color=COLOURS[kind], lw=1, label=f"{kind}: ideal")
        ck = sorted((c for c in checks if c["kind"] == f"check_{kind}"), key=lambda c: c["ranks"])
        if ck:
            ax_e.plot([c["ranks"] for c in ck], [c["efficiency"] for c in ck], "x",
                      color=COLOURS[kind], ms=9, mew=1.5, label=f"{kind}: cost model")
    ax_e.axhline(1.0, color="k", ls="--", lw=0.8, label="ideal")
    for ax in (ax_e, ax_t):
        ax.set_xscale("log", base=2)
        ax.set_xticks(ranks_all, [str(p) for p in ranks_all])
        ax.set_xlabel("MPI ranks")
        if max(ranks_all) > cores:
            ax.axvline(cores + 0.5, color="0.6", ls="-.", lw=0.8)
        ax.grid(alpha=0.3)
    lo = min(r["efficiency"] for r in rows)
    ax_e.set_ylim(min(0.0, lo - 0.05), max(1.15, max(r["efficiency"] for r in rows) + 0.05))
    ax_e.set_ylabel("parallel efficiency E")
    ax_e.set_title("strong E = T1/(P·T_P), weak E = T1/T_P")
    ax_t.set_yscale("log")
    ax_t.set_ylabel("seconds per step")
    ax_t.set_title(f"time per step ({rows[0]['dim']}D {rows[0]['method']}, {cores} cores)")
    ax_e.legend(fontsize=7, loc="lower left")
    ax_t.legend(fontsize=7)
    return compact_png(save(fig, path))


# --- main ----------------------------------------------------------------------------------------
def parse_args(argv=None):
    p = parser(__doc__)
    p.add_argument("--ranks", default="1,2", help="comma-separated rank counts (default 1,2; 1 is always run)")
    p.add_argument("--kind", choices=("both", "strong", "weak"), default="both")
    p.add_argument("--dim", type=int, choices=(1, 2, 3), default=2)
    p.add_argument("--method", default="cpdi", choices=("mpm", "ugimp", "cpgimp", "cpdi"))
    p.add_argument("--particles", default="1e6", help="strong scaling: the problem size (default 1e6)")
    p.add_argument("--per-rank", default="5e5", help="weak scaling: particles per rank (default 5e5)")
    p.add_argument("--particles-3d", default="2e5",
                   help="the 1-rank 3D run that gives t_p in 3D (default 2e5; 0: skip, use --dim's)")
    p.add_argument("--ppc", type=int, default=2)
    p.add_argument("--steps", type=int, default=10)
    p.add_argument("--patch-size", type=int, default=None)
    p.add_argument("--speed", type=float, default=None)
    p.add_argument("--repeat", type=int, default=1, help="runs of each, the fastest kept (default 1)")
    p.add_argument("--timeout", type=float, default=1800, help="seconds per mpirun (default 1800)")
    p.add_argument("--alpha-net", type=float, default=ALPHA_NET, help="assumed inter-node latency, s")
    p.add_argument("--beta-net", type=float, default=BETA_NET, help="assumed inter-node bandwidth, bytes/s")
    p.add_argument("--predict-particles", default=PREDICT_PARTICLES)
    p.add_argument("--predict-ranks", default=PREDICT_RANKS)
    p.add_argument("--drift", type=float, default=0.01,
                   help="predicted migration: cells per step a particle moves (default 0.01)")
    args = p.parse_args(argv)
    if args.quick:
        args.particles, args.per_rank = QUICK["particles"], QUICK["per_rank"]
        args.particles_3d, args.steps = QUICK["particles_3d"], QUICK["steps"]
    args.ranks = sorted(set([1] + _ints(args.ranks)))
    if min(args.ranks) < 1:
        raise SystemExit("scaling: rank counts must be >= 1")
    args.particles, args.per_rank = _count(args.particles), _count(args.per_rank)
    args.particles_3d = 0 if float(args.particles_3d) == 0 else _count(args.particles_3d)
    return args


def main(argv=None) -> int:
    if launched_by_mpirun():
        raise SystemExit("scaling: run me with plain python; I launch mpirun myself")
    args = parse_args(argv)
    out, figs = folders(args, "scaling")
    out.mkdir(parents=True, exist_ok=True)
    cores = os.cpu_count() or 1
    run = Runner(args, out)
    t0 = time.perf_counter()
    kinds = KINDS if args.kind == "both" else (args.kind,)

    results = {k: [] for k in kinds}
    for kind in kinds:
        for P in args.ranks:
            N = args.particles if kind == "strong" else P * args.per_rank
            r = run.bench(args.dim, P, N, args.patch_size)
            r["halo_model"] = partition_halo(r, P)
            results[kind].append(r)
    t_p = {args.dim: {"t_p": cm.compute_time_per_particle(max(
        (r for rs in results.values() for r in rs if r["ranks"] == 1), key=lambda r: r["particles"])),
        "source": f"{args.dim}D {args.method} bench, 1 rank (largest measured)"}}
    if args.dim != 3 and args.particles_3d:
        r3 = run.bench(3, 1, args.particles_3d, None)
        t_p[3] = {"t_p": cm.compute_time_per_particle(r3),
                  "source": f"3D {args.method} bench, 1 rank, {r3['particles']:,} particles"}
    probes = {P: run.probe(P, pingpong=(P == 2)) for P in sorted(set([2] + [p for p in args.ranks if p > 2]))}

    rows = [row for kind in kinds for row in scaling_rows(kind, results[kind], cores)]
    write_csv(out / "scaling.csv", rows)
    first = rows[0]
    print(f"\n{first['dim']}D {first['method']}, {args.steps - 1} timed steps, {cores} cores")
    print(format_rows(rows))

    checks, model_png = model_study(args, results, rows, t_p, probes, out, figs)
    paths = [chart_scaling(rows, checks, cores, figs / "scaling.png"), model_png]
    print(f"\n{time.perf_counter() - t0:.0f} s in all")
    for p in (out / "scaling.csv", out / "cost_model.csv", out / "cost_model.json"):
        print(f"wrote {p}")
    for p in paths:
        print(wrote(p))
    return 0


if __name__ == "__main__":
    sys.exit(main())
