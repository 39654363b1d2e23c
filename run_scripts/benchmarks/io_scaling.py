"""Memory and checkpoint I/O per rank at fixed N, and the cost model extended with I/O.

What it measures, for N 2D particles (``--particles``, default 4·10⁶: ``parmpm bench``'s
translating neo-Hookean cpdi block, ppc 2) on P = 1, 2, 4, 8 ranks, each P one ``mpirun -n P``
of this script's ``--worker`` and one of ``run_scripts/benchmarks/checkpoint_io.py --json``:

* **peak memory per rank** above the rank's baseline (the interpreter, numpy, mpi4py, h5py and
  the compiled kernels, after a tiny warm-up run that also writes and restarts a checkpoint),
  Linux's high-water mark as in ``run_scripts/benchmarks/setup_memory.py`` (whose helpers it uses): after
  set-up, after the run and a checkpoint write (two steps, then ``write_checkpoint``), and
  through a restart from that checkpoint (the mark reset before it);
* **checkpoint write and restart time** (``checkpoint_io.py``): parts (``ranks_per_file =
  "auto"``, one file per rank) and one writer (``"all"``, rank 0 gathering everything);
* **bytes read per rank** at restart (the reader's count of particle rows, and the process's
  ``rchar``: every byte HDF5 read).

Expected: the largest rank's peak memory falls as ``a·N/P + b`` (``a`` bytes per particle, ``b``
a constant: the grid, the patches' descriptions, MPI and HDF5 buffers), bytes read per rank as
``S·N/P`` with ``S = 232`` B per 2D particle. Then **the cost model with I/O**
(``run_scripts/models/io_model.py``): the one-writer write and restart rates measured here as the
per-writer rates ``b_w``, ``b_r``; an *assumed* file-system aggregate ``B_fs`` (100 GB/s, a
Lustre-class system, and 10 GB/s); the step time of ``cost_model.py`` for the 3D cpdi cube (its
constants as measured by ``scaling.py``, from ``--cost-json`` when given, else the ones docs/results/scaling.md states);
gives the checkpoint time and the shortest checkpoint interval under 1 % of run time at 10²,
10³, 10⁴ ranks for 10⁸, 10⁹, 10¹⁰ particles, parts against the old one-writer strategy.

Runtime: ~3–5 minutes on two cores for 4·10⁶ particles (8 ranks oversubscribed: fine for memory
and bytes, only the trend of the times means anything); ``--quick`` (2·10⁴ particles, 1 and 2
ranks): ~30 seconds. It launches ``mpirun`` itself: run it with plain ``python``::

    python run_scripts/benchmarks/io_scaling.py --particles 4e6 --ranks 1,2,4,8 --figures docs/figures
    python run_scripts/benchmarks/io_scaling.py --quick

Output in ``--out`` (default ``run_scripts/out/io_scaling``): ``io_scaling.csv`` (one row per
rank count, with the fitted ``a``, ``b``), ``io_model.csv`` (the predictions), ``io_scaling.json``
(the constants, measured and assumed), and ``io_scaling.png`` (``--figures`` for the PNG).
"""
from __future__ import annotations

import gc
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py, the groups
from models import cost_model as cm
from models import io_model as im
import numpy as np
from benchmarks import setup_memory as sm

import study

DIM = 2
WARM = 2000  # particles of the warm-up run
HERE = Path(__file__).resolve().parent
#: the step-time model's constants as docs/results/scaling.md states them (scaling.py on the
#: 2-core machine) and its assumed network; --cost-json replaces the measured ones with a cost_model.json's
STEP_MODEL = {"t_p": 377e-9, "alpha": 1.6e-6, "beta": 10.5e9, "alpha_r": 3.8e-6,
              "alpha_net": 1.5e-6, "beta_net": 12.5e9, "ppc": 2, "patch_size": 16, "ghost": 2,
              "drift": 0.01}
#: assumed file-system aggregates (bytes/s) and metadata operation (s)
FILE_SYSTEMS = {"lustre_100GBs": 100e9, "small_10GBs": 10e9}
T_MD = 1e-4
PREDICT_PARTICLES = (1e8, 1e9, 1e10)
PREDICT_RANKS = (100, 1000, 10000)


#: a finished run's checkpoint is refused unless the restart is given steps to run: one more
#: (only the read is timed; the continued run is never stepped)
MORE = ("time.steps=3",)


# --- the worker: memory through set-up, a run, a checkpoint write and a restart ---------------
def worker(particles: int, out: Path) -> None:
    from decomposition import world
    from parmpm.cli.bench import build_bench_scene
    from parmpm.io.checkpoint import remove_checkpoint
    from parmpm.core.log import setup_logging
    from parmpm.driver.simulation import Simulation

    comm = world()
    rank = comm.Get_rank()
    setup_logging(rank, comm.Get_size(), quiet=True)

    def timed(f):
        comm.Barrier()
        t0 = time.perf_counter()
        value = f()
        comm.Barrier()
        return value, time.perf_counter() - t0

    with study.scratch_folder(comm, "parmpm-io-") as tmp:
        # warm-up: kernels, h5py, the writer and the reader; then a tiny checkpoint timed (t_0)
        sim = Simulation(build_bench_scene(DIM, "cpdi", WARM, 2, steps=2), tmp / "warm",
                         quiet=True, comm=comm)
        sim.run()
        path = sim.write_checkpoint()
        Simulation.from_checkpoint(path, MORE, out_dir=tmp / "warm_r0", quiet=True, comm=comm)
        if rank == 0:
            remove_checkpoint(path)
        path, t_0 = timed(sim.write_checkpoint)
        _, t_0r = timed(lambda: Simulation.from_checkpoint(path, MORE, out_dir=tmp / "warm_r1",
                                                           quiet=True, comm=comm))
        del sim
        gc.collect()
        comm.Barrier()
        hwm = sm._reset_peak()
        base = sm._status("VmRSS") if hwm else sm._peak(False)
        sim = Simulation(build_bench_scene(DIM, "cpdi", particles, 2, steps=2), tmp / "big",
                         quiet=True, comm=comm)
        setup = sm._peak(hwm)
        own, n = sim.particles.n, sim.state.n_total
        sim.run()
        step = sm._peak(hwm)
        path = sim.write_checkpoint()
        write = sm._peak(hwm)
        del sim
        gc.collect()
        comm.Barrier()
        sm._reset_peak()
        rs = Simulation.from_checkpoint(path, MORE, out_dir=tmp / "big_r", quiet=True, comm=comm)
        restart = sm._peak(hwm)
        restored = rs.particles.n
        del rs
    mb = 2**20
    rows = comm.gather({"rank": rank, "own": own, "restored": restored, "baseline_mb": base / mb,
                        "setup_mb": (setup - base) / mb, "step_mb": (step - base) / mb,
                        "write_mb": (write - base) / mb, "restart_mb": (restart - base) / mb,
                        "peak": "VmHWM" if hwm else "ru_maxrss"}, root=0)
    if rank == 0:
        out.write_text(json.dumps({"ranks": comm.Get_size(), "particles": n, "t_0": t_0,
                                   "t_0r": t_0r, "rows": rows}), encoding="utf-8")


# --- the driver ---------------------------------------------------------------------------------
def launch(ranks: int, args: list[str], out: Path, timeout: float = 3600) -> dict:
    """``mpirun -n ranks python <args> --json out``; the JSON it wrote."""
    launcher = sm_mpirun()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        filter(None, [str(study.ROOT), os.environ.get("PYTHONPATH")])))
    cmd = [launcher, "-n", str(ranks), sys.executable, *args, "--json", str(out)]
    proc = subprocess.run(cmd, cwd=study.ROOT, env=env, capture_output=True, text=True,
                          timeout=timeout)
    if proc.returncode != 0 or not out.exists():
        raise SystemExit(f"io_scaling: {' '.join(cmd)} failed:\n{proc.stdout[-2000:]}"
                         f"\n{proc.stderr[-3000:]}")
    return json.loads(out.read_text(encoding="utf-8"))


def sm_mpirun() -> str:
    launcher = study.mpirun()
    if launcher is None:
        raise SystemExit("io_scaling: no mpirun (install the mpich extra)")
    return launcher


def measure(ranks: int, particles: int) -> tuple[dict, dict]:
    with tempfile.TemporaryDirectory() as tmp:
        mem = launch(ranks, [str(Path(__file__).resolve()), "--worker",
                             "--particles", str(particles)], Path(tmp) / "mem.json")
        io = launch(ranks, [str(HERE / "checkpoint_io.py"), "--particles", str(particles),
                            "--dim", str(DIM), "--ranks-per-file", "auto", "all"],
                    Path(tmp) / "io.json")
    return mem, io


def summarise(results: list[tuple[dict, dict]]) -> list[dict]:
    rows = []
    S = im.row_bytes(DIM)
    for mem, io in sorted(results, key=lambda r: r[0]["ranks"]):
        P, N = mem["ranks"], mem["particles"]
        parts = next(s for s in io["settings"] if s["ranks_per_file"] == "auto")
        one = next(s for s in io["settings"] if s["ranks_per_file"] == "all")
        m = mem["rows"]
        peak = [max(x["write_mb"], x["restart_mb"]) for x in m]
        read = [x["bytes_read"] for x in parts["per_rank"]]
        rows.append({
            "ranks": P, "particles": N, "largest_own": max(x["own"] for x in m),
            "baseline_mb": max(x["baseline_mb"] for x in m),
            "max_setup_mb": max(x["setup_mb"] for x in m),
            "max_step_mb": max(x["step_mb"] for x in m),
            "max_write_mb": max(x["write_mb"] for x in m),
            "max_restart_mb": max(x["restart_mb"] for x in m),
            "max_peak_mb": max(peak), "mean_peak_mb": float(np.mean(peak)),
            "checkpoint_mb": parts["bytes"] / 1e6, "part_files": parts["files"],
            "write_s": parts["write_seconds"], "restart_s": parts["restart_seconds"],
            "one_writer_write_s": one["write_seconds"],
            "one_writer_restart_s": one["restart_seconds"],
            "max_read_mb": max(read) / 1e6, "min_read_mb": min(read) / 1e6,
            "ideal_read_mb": S * N / P / 1e6,
            "max_rchar_mb": max(x["rchar"] for x in parts["per_rank"]) / 1e6,
            "tiny_write_s": mem["t_0"], "tiny_restart_s": mem["t_0r"],
            "step_s": io["step_seconds"], "peak": m[0]["peak"]})
    return add_fits(rows)


def add_fits(rows: list[dict]) -> list[dict]:
    """The largest rank's memory above baseline fitted as ``a·N/P + b`` (``setup_memory.fit``),
    for each phase: ``fit_bytes_per_particle_<phase>`` (a), ``fit_constant_mb_<phase>`` (b)."""
    if len(rows) > 1:
        P = np.array([r["ranks"] for r in rows], float)
        for key in ("setup", "step", "write", "restart", "peak"):
            a, b = sm.fit(P, rows[0]["particles"], np.array([r[f"max_{key}_mb"] for r in rows]))
            for r in rows:
                r[f"fit_bytes_per_particle_{key}"], r[f"fit_constant_mb_{key}"] = a, b
    return rows


def table(rows: list[dict]) -> str:
    head = (f"{'P':>2} {'particles':>10} {'base MB':>7} {'set-up MB':>9} {'peak MB':>8} "
            f"{'(write/restart)':>15} {'read MB max':>11} {'S·N/P':>7} {'write s':>7} "
            f"{'restart s':>9} {'1 writer w/r s':>14}")
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(f"{r['ranks']:>2} {r['particles']:>10,} {r['baseline_mb']:>7.0f} "
                     f"{r['max_setup_mb']:>9.1f} {r['max_peak_mb']:>8.1f} "
                     f"{r['max_write_mb']:>7.0f}/{r['max_restart_mb']:<7.0f} "
                     f"{r['max_read_mb']:>11.1f} {r['ideal_read_mb']:>7.1f} {r['write_s']:>7.2f} "
                     f"{r['restart_s']:>9.2f} {r['one_writer_write_s']:>6.2f}/"
                     f"{r['one_writer_restart_s']:<7.2f}")
    r = rows[0]
    if "fit_bytes_per_particle_peak" in r:
        lines.append(f"largest rank's memory above baseline ≈ a·N/P + b: peak (run, checkpoint "
                     f"write, restart) a = {r['fit_bytes_per_particle_peak']:.0f} B/particle, "
                     f"b = {r['fit_constant_mb_peak']:.1f} MB; set-up a = "
                     f"{r['fit_bytes_per_particle_setup']:.0f} B/particle, "
                     f"b = {r['fit_constant_mb_setup']:.1f} MB; " + "; ".join(
                         f"{k} a = {r[f'fit_bytes_per_particle_{k}']:.0f}, "
                         f"b = {r[f'fit_constant_mb_{k}']:.1f}" for k in ("step", "write", "restart")))
    worst = max(x["max_read_mb"] / x["ideal_read_mb"] for x in rows)
    lines.append(f"bytes read per rank at restart: at most {worst:.4f} × S·N/P "
                 f"(S = {im.row_bytes(DIM)} B per {DIM}D particle)")
    return "\n".join(lines)


# --- the I/O cost model ------------------------------------------------------------------------
def step_model(cost_json: Path | None) -> dict:
    """The step-time constants: the documented values, or a ``cost_model.json`` written by scaling.py."""
    c = dict(STEP_MODEL)
    if cost_json is not None:
        rec = json.loads(Path(cost_json).read_text(encoding="utf-8"))
        m = rec["measured_machine"]
        geo = rec["geometry"]
        c.update(t_p=rec["t_p_used_for_prediction"], alpha=m["alpha"], beta=m["beta"],
                 alpha_r=m["alpha_r"], alpha_net=geo["alpha_net"], beta_net=geo["beta_net"],
                 ppc=geo["ppc"], patch_size=geo["patch_size"], ghost=geo["ghost"],
                 drift=geo["drift_cells_per_step"])
    return c


def step_seconds(c: dict, particles, ranks) -> dict:
    """``cost_model``'s T_step for the 3D cpdi cube, imbalance from a Morton split."""
    from models.scaling_model import morton_imbalance

    net = cm.network_machine(cm.Machine(c["alpha"], c["beta"], c["alpha_r"]),
                             c["alpha_net"], c["beta_net"])
    out = {}
    for N in particles:
        for P in ranks:
            imb = morton_imbalance(N, P, c["ppc"], c["patch_size"], c["ghost"])
            p = cm.predict_cube(N, P, c["t_p"], net, dim=3, ppc=c["ppc"], s=c["patch_size"],
                                ghost=c["ghost"], drift=c["drift"],
                                imbalance=imb if math.isfinite(imb) else None)
            out[N, P] = p["total"]
    return out


def model(rows: list[dict], c: dict) -> tuple[list[dict], dict]:
    """(io_model rows, the constants used) from the measured 1-rank rates."""
    one = min(rows, key=lambda r: r["ranks"])
    nbytes = one["checkpoint_mb"] * 1e6
    # on one rank both settings are the same single writer (reader): the faster of the two
    # (the slower had the disk busy with something else); the fixed costs t_0, t_0r are terms
    # of their own, so the rates are of what remains
    t_w = min(one["write_s"], one["one_writer_write_s"])
    t_r = min(one["restart_s"], one["one_writer_restart_s"])
    b_w = nbytes / max(t_w - one["tiny_write_s"], 0.5 * t_w)
    b_r = nbytes / max(t_r - one["tiny_restart_s"], 0.5 * t_r)
    storages = {label: im.Storage(b_w=b_w, b_r=b_r, B_fs=B, t_0=one["tiny_write_s"],
                                  t_0r=one["tiny_restart_s"], t_md=T_MD, beta=c["beta"],
                                  alpha_r=c["alpha_r"] + c["alpha_net"])
                for label, B in FILE_SYSTEMS.items()}
    T = step_seconds(c, PREDICT_PARTICLES, PREDICT_RANKS)
    return im.io_rows(PREDICT_PARTICLES, PREDICT_RANKS, T, storages, dim=3), {
        "b_w_bytes_per_second": b_w, "b_r_bytes_per_second": b_r,
        "measured_at": f"{one['ranks']} rank, {one['particles']:,} {DIM}D particles",
        "t_0_seconds": one["tiny_write_s"], "t_0r_seconds": one["tiny_restart_s"],
        "t_md_seconds_assumed": T_MD, "file_systems_assumed": FILE_SYSTEMS,
        "row_bytes": {"2": im.row_bytes(2), "3": im.row_bytes(3)}, "step_model": c}


def print_model(pred: list[dict], consts: dict) -> None:
    print(f"\nI/O model: b_w = {consts['b_w_bytes_per_second'] / 1e6:.0f} MB/s, b_r = "
          f"{consts['b_r_bytes_per_second'] / 1e6:.0f} MB/s (measured, {consts['measured_at']}), "
          f"t_0 = {consts['t_0_seconds'] * 1e3:.0f} ms, t_0r = {consts['t_0r_seconds'] * 1e3:.0f} ms"
          f" (tiny checkpoint); t_md = {T_MD * 1e3:g} ms assumed; S = {im.row_bytes(3)} B (3D)")
    for label, B in FILE_SYSTEMS.items():
        print(f"\n3D cpdi cube, B_fs = {B / 1e9:g} GB/s (assumed): checkpoint write (old: one "
              f"writer); shortest interval with checkpoints < 1 % of run time")
        print(im.io_table(pred, label))
        print("  restart: " + "; ".join(
            f"10^{round(math.log10(r['particles']))}/{r['ranks']}: {r['restart_seconds']:.3g} s "
            f"(old {r['old_restart_seconds']:.3g} s)"
            for r in pred if r["file_system"] == label))


# --- the figure ---------------------------------------------------------------------------------
def plot(rows: list[dict], pred: list[dict], path: Path) -> Path:
    fig, axes = study.figure(2, 2, size=(10.5, 8.0))
    (ax_m, ax_b), (ax_t, ax_p) = axes
    P = np.array([r["ranks"] for r in rows], float)
    N = rows[0]["particles"]
    Pf = np.geomspace(P.min(), P.max(), 50)
    for key, colour, label in (("setup", "C0", "after set-up"),
                               ("peak", "C1", "peak: run, checkpoint write, restart")):
        ax_m.plot(P, [r[f"max_{key}_mb"] for r in rows], "o", color=colour, label=f"largest rank, {label}")
        if f"fit_bytes_per_particle_{key}" in rows[0]:
            a, b = rows[0][f"fit_bytes_per_particle_{key}"], rows[0][f"fit_constant_mb_{key}"]
            ax_m.plot(Pf, a / 2**20 * N / Pf + b, "-", color=colour, lw=1,
                      label=f"{a:.0f} B·N/P + {b:.0f} MB")
    ax_m.plot(P, [r["mean_peak_mb"] for r in rows], "x", color="C1", alpha=0.6, label="mean rank, peak")
    ax_m.set_ylabel("memory above baseline per rank (MB)")
    ax_m.set_title(f"{N:,} {DIM}D particles: memory per rank", fontsize=9)
    ax_b.plot(P, [r["max_read_mb"] for r in rows], "o", color="C0", label="largest rank: particle rows")
    ax_b.plot(P, [r["min_read_mb"] for r in rows], "x", color="C0", label="smallest rank")
    ax_b.plot(P, [r["max_rchar_mb"] for r in rows], "+", color="C3", ms=9,
              label="largest rank: all file reads (rchar)")
    ax_b.plot(Pf, im.row_bytes(DIM) * N / Pf / 1e6, "-", color="grey", lw=1,
              label=f"S·N/P, S = {im.row_bytes(DIM)} B")
    ax_b.set_ylabel("MB read per rank at restart")
    ax_b.set_title("restart: bytes read per rank", fontsize=9)
    for key, colour, label in (("write_s", "C0", "write, parts"), ("restart_s", "C1", "restart, parts"),
                               ("one_writer_write_s", "C0", "write, one writer"),
                               ("one_writer_restart_s", "C1", "restart, one writer")):
        ax_t.plot(P, [r[key] for r in rows], "-o" if "one" not in key else "--s", ms=4,
                  color=colour, label=label)
    ax_t.set_ylabel("seconds")
    ax_t.set_title(f"checkpoint of {rows[0]['checkpoint_mb']:.0f} MB (2 cores: >2 ranks "
                   "oversubscribed)", fontsize=9)
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    plain = FuncFormatter(lambda v, _: f"{v:g}")
    for ax in (ax_m, ax_b, ax_t):
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xticks(P)
        ax.xaxis.set_major_formatter(plain)
        ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.yaxis.set_major_formatter(plain)
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("ranks P")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3, which="both")
    for i, Nm in enumerate(PREDICT_PARTICLES):
        c = f"C{i}"
        for label, ls in (("lustre_100GBs", "-o"), ("small_10GBs", ":^")):
            rr = sorted((r for r in pred if r["particles"] == Nm and r["file_system"] == label),
                        key=lambda r: r["ranks"])
            ax_p.plot([r["ranks"] for r in rr], [r["write_seconds"] for r in rr], ls, ms=4,
                      color=c, label=f"N = {Nm:.0e}, B_fs {FILE_SYSTEMS[label] / 1e9:g} GB/s")
        ax_p.plot([r["ranks"] for r in rr], [r["old_write_seconds"] for r in rr], "--", color=c,
                  lw=1, label=f"N = {Nm:.0e}, one writer (old)")
    ax_p.set_xscale("log")
    ax_p.set_yscale("log")
    ax_p.set_xlabel("ranks P")
    ax_p.set_ylabel("predicted checkpoint write (s)")
    ax_p.set_title(f"model: 3D cpdi cube, S = {im.row_bytes(3)} B, ≤ {im.MAX_PARTS} part files",
                   fontsize=9)
    ax_p.grid(alpha=0.3, which="both")
    ax_p.legend(fontsize=6, ncol=1)
    return study.compact_png(study.save(fig, path))


def _number(text: str):
    """A CSV cell back as an int, a float or the text."""
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def main() -> None:
    ap = study.parser(__doc__)
    ap.add_argument("--particles", type=float, default=None, help="2D particles (default 4e6; --quick 2e4)")
    ap.add_argument("--ranks", default=None, help="comma-separated (default 1,2,4,8; --quick 1,2)")
    ap.add_argument("--cost-json", type=Path, default=None,
                    help="a cost_model.json from scaling.py (default: the documented constants)")
    ap.add_argument("--measured", type=Path, default=None,
                    help="an io_scaling.csv from an earlier run: redo the model and the figure only")
    ap.add_argument("--worker", action="store_true", help=sm.argparse_hidden())
    ap.add_argument("--json", type=Path, help=sm.argparse_hidden())
    args = ap.parse_args()
    particles = int(args.particles or (2e4 if args.quick else 4e6))
    if args.worker:
        worker(particles, args.json)
        return
    ranks = [int(p) for p in (args.ranks or ("1,2" if args.quick else "1,2,4,8")).split(",")]
    from parmpm.io.checkpoint import MAX_PARTS, ranks_per_file
    assert MAX_PARTS == im.MAX_PARTS and all(
        ranks_per_file(P, "auto") == im.ranks_per_file(P) for P in (1, 256, 257, 1000, 10000))
    if args.measured is not None:
        rows = add_fits([{k: _number(v) for k, v in r.items()} for r in study.read_csv(args.measured)])
    else:
        results = []
        for P in ranks:
            t0 = time.perf_counter()
            results.append(measure(P, particles))
            print(f"{P} rank(s): {results[-1][0]['particles']:,} particles "
                  f"({time.perf_counter() - t0:.0f} s)", flush=True)
        rows = summarise(results)
    print(table(rows))
    pred, consts = model(rows, step_model(args.cost_json))
    print_model(pred, consts)
    out, figs = study.folders(args, "io_scaling")
    study.write_csv(out / "io_scaling.csv", rows)
    study.write_csv(out / "io_model.csv", pred)
    (out / "io_scaling.json").write_text(json.dumps(consts, indent=2) + "\n", encoding="utf-8")
    print(study.wrote(out / "io_scaling.csv"))
    print(study.wrote(out / "io_model.csv"))
    print(study.wrote(plot(rows, pred, figs / "io_scaling.png")))


if __name__ == "__main__":
    main()
