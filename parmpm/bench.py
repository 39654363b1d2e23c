"""``parmpm bench``: time per step and where it goes, on a synthetic block, for scaling studies.

Why a separate command: a physics scene mixes solver cost with output, metrics and scene-specific
set-up, and its particle count is fixed. The benchmark block isolates the time-step loop at a
chosen size, so that time per step and parallel efficiency ``E(P) = T1 / (P · T_P)`` can be
measured at 1, 2, 4, ... ranks (``run_scripts/mpi_scaling.py`` drives it).

The scene: a neo-Hookean block (E = 1 MPa, ν = 0.3, ρ = 1050 kg/m³; the hanging bar's material)
of ``ppc`` particles per cell per axis on a grid of 0.01 m cells, square (cube) in 2D (3D) and
sized so that it holds about ``--particles`` particles, with at least 4 empty cells on every side
plus the farthest it can travel (< cfl·Δx per step). Free boundaries, no gravity, a uniform
velocity ``speed · (1, 0.5, 0.25)`` m/s: a rigid translation (F = I, zero stress) whose cost per
step is that of any elastic body, moving particles across patch and rank boundaries. At the
default speed a particle moves about 0.01Δx per step (the elastic wave speed, ~36 m/s, sets Δt),
so in a short run only the particles right at a boundary migrate; ``--speed 100`` moves them
about 0.3Δx per step.

    python -m parmpm bench --dim 2 --method cpdi --particles 1e6 --steps 10
    mpirun -n 2 python -m parmpm bench --particles 1e6 --json bench_2.json

The first step (JIT compilation) is excluded from every timing by ``Simulation``; it is reported
as ``jit_warmup_seconds`` together with the set-up time.
"""
from __future__ import annotations

import argparse
import json
import math
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

from parmpm.errors import ParmpmError
from parmpm.scene import Scene, scene_from_toml

__all__ = ["build_bench_scene", "run_bench", "add_arguments", "format_result"]

CELL = 0.01            # m
MARGIN = 4             # empty cells on every side, before the travel allowance
CFL = 0.4
VELOCITY = (1.0, 0.5, 0.25)  # m/s, times --speed
METHODS = ("mpm", "ugimp", "cpgimp", "cpdi")
HALO_PHASES = ("accumulate", "fill")


def build_bench_scene(dim: int, method: str = "cpdi", particles: int = 1_000_000, ppc: int = 2,
                      steps: int = 10, patch_size: int | None = None, speed: float = 1.0) -> Scene:
    """The benchmark block holding ``(n·ppc)^dim ≈ particles`` particles, n cells per axis."""
    if dim not in (1, 2, 3):
        raise ParmpmError(f"bench: --dim must be 1, 2 or 3, got {dim}")
    for flag, value, least in (("particles", particles, 1), ("ppc", ppc, 1), ("steps", steps, 2)):
        if value < least:
            why = " (the first step is JIT warm-up, not timed)" if flag == "steps" else ""
            raise ParmpmError(f"bench: --{flag} must be >= {least}{why}, got {value}")
    n = max(1, round(particles ** (1.0 / dim) / ppc))
    margin = MARGIN + math.ceil(steps * CFL)
    lo = [margin * CELL] * dim
    hi = [(margin + n) * CELL] * dim
    vel = [speed * v for v in VELOCITY[:dim]]
    grid = f"cells = {n + 2 * margin}\n" + (f"patch_size = {patch_size}\n" if patch_size else "")
    text = f"""\
description = "parmpm bench: translating neo-Hookean block"
dim = {dim}
[grid]
origin = 0.0
cell_size = {CELL}
{grid}
[materials.block]
model = "neo_hookean"
density = 1050.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3
[[bodies]]
shape = "box"
min = {lo}
max = {hi}
material = "block"
ppc = {ppc}
velocity = {vel}
[method]
interpolator = "{method}"
[time]
steps = {steps}
cfl = {CFL}
[output]
snapshots = false
figure = false
[metrics]
kind = "none"
"""
    return scene_from_toml(text, f"bench-{dim}d-{method}", default_name=f"bench_{dim}d_{method}")


def _particle_count(text: str) -> int:
    """``--particles``: an integer, also written as a float (``1e6``, ``2.5e5``)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number such as 1e6, got {text!r}") from None
    if not math.isfinite(value) or value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return int(round(value))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The bench options (shared by ``parmpm bench`` and anything that wraps it)."""
    parser.add_argument("--dim", type=int, choices=(1, 2, 3), default=2, help="dimension (default 2)")
    parser.add_argument("--method", choices=METHODS, default="cpdi", help="interpolator (default cpdi)")
    parser.add_argument("--particles", type=_particle_count, default=1_000_000, metavar="N",
                        help="about how many particles (default 1e6)")
    parser.add_argument("--ppc", type=int, default=2, help="particles per cell per axis (default 2)")
    parser.add_argument("--steps", type=int, default=10,
                        help="time steps, the first excluded from timings (default 10)")
    parser.add_argument("--patch-size", type=int, default=None, metavar="CELLS",
                        help="cells per patch per axis (default: the scene default, 32 in 1D/2D, 16 in 3D)")
    parser.add_argument("--speed", type=float, default=1.0,
                        help="scale of the block velocity (1, 0.5, 0.25) m/s (default 1)")
    parser.add_argument("--json", type=Path, default=None, metavar="FILE",
                        help="write the result as JSON (rank 0)")
    parser.add_argument("-o", "--out", type=Path, default=None, metavar="DIR",
                        help="folder for summary.json (default: a temporary folder, removed)")
    parser.add_argument("-q", "--quiet", action="store_true", help="no info messages")


def run_bench(args: argparse.Namespace, comm=None) -> dict:
    """Run the benchmark on every rank of ``comm`` (collective); every rank returns the result.

    Rank 0 prints the table and writes ``args.json`` if given.
    """
    from decomposition import SerialComm
    from parmpm.io.summary import to_jsonable
    from parmpm.simulation import Simulation

    comm = comm if comm is not None else SerialComm()
    rank = comm.Get_rank()
    scene = build_bench_scene(args.dim, args.method, args.particles, args.ppc, args.steps,
                              args.patch_size, getattr(args, "speed", 1.0))
    tmp = tempfile.mkdtemp(prefix="parmpm-bench-") if args.out is None and rank == 0 else None
    out_dir = Path(tmp) if tmp else args.out
    try:
        comm.Barrier()
        t0 = time.perf_counter()
        sim = Simulation(scene, out_dir, quiet=True, comm=comm)
        setup = time.perf_counter() - t0
        summary = sim.run()
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    rows = comm.allgather((setup, sim.stepper.migrated, _peak_rss_mb()))
    result = summarise(summary, max(r[0] for r in rows), sum(r[1] for r in rows),
                       max(r[2] for r in rows))
    if rank == 0:
        print(format_result(result), flush=True)
        if args.json is not None:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps(to_jsonable(result), indent=2) + "\n", encoding="utf-8")
    return result


def _peak_rss_mb() -> float:
    """Peak resident memory of this process in MiB (ru_maxrss: KiB on Linux, bytes on macOS)."""
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / 2**20 if sys.platform == "darwin" else rss / 2**10


def summarise(summary: dict, setup_seconds: float, migrated: int, peak_rss_mb: float) -> dict:
    """The bench result from a run summary: the timed steps exclude the first (JIT) step."""
    rate = summary["particle_steps_per_second"]
    phases = summary["phase_seconds_per_step"]
    if not rate or not phases:
        raise ParmpmError("bench: no timed steps (the run stopped after its first step)")
    n, timed = summary["particles"], summary["steps"] - 1
    per_step = n / rate
    share = {k: v / per_step for k, v in phases.items()}
    share["halo"] = sum(share[k] for k in HALO_PHASES)
    return {
        "ranks": summary["ranks"], "dim": summary["dim"], "method": summary["method"],
        "lcr": summary["lcr"], "update": summary["update"],
        "particles": n, "steps": summary["steps"], "timed_steps": timed,
        "seconds_per_step": per_step,
        "particle_steps_per_second": rate,
        "phase_seconds_per_step": dict(phases, halo=sum(phases[k] for k in HALO_PHASES)),
        "phase_share": share,
        "halo_share": share["halo"], "migrate_share": share["migrate"],
        "particles_migrated": migrated,
        "setup_seconds": setup_seconds,
        "jit_warmup_seconds": max(0.0, summary["wall_seconds"] - timed * per_step),
        "wall_seconds": summary["wall_seconds"],
        "peak_rss_mb_per_rank": peak_rss_mb,
        "grid": summary["grid"],
        "decomposition": summary["decomposition"],
    }


def format_result(r: dict) -> str:
    """The human-readable table of a bench result."""
    dec = r["decomposition"]
    lines = [
        f"parmpm bench: {r['dim']}D {r['method']} ({r['update']}), {r['particles']:,} particles, "
        f"{r['ranks']} rank(s), {r['timed_steps']} timed steps",
        f"  grid {' x '.join(map(str, r['grid']['cells']))} cells, patches "
        f"{' x '.join(map(str, r['grid']['patch_size']))}: {dec['patches']} occupied of "
        f"{dec['patches_dense']}, ghost {dec['ghost']}",
        f"  time per step        {r['seconds_per_step']:.4g} s",
        f"  particle-steps / s   {r['particle_steps_per_second']:.4g}",
        f"  set-up; first step   {r['setup_seconds']:.3g} s; {r['jit_warmup_seconds']:.3g} s (JIT)",
        f"  peak memory / rank   {r['peak_rss_mb_per_rank']:.0f} MiB",
        f"  imbalance            {dec['imbalance']:.3f} (particles per rank {dec['particles_per_rank']})",
        f"  halo traffic         {dec['halo_bytes_per_step'] / 2**20:.3g} MiB/step; "
        f"migrated {r['particles_migrated']} particles; rebalances {dec['rebalances']}",
        "  phase         s/step      share",
    ]
    for name, sec in r["phase_seconds_per_step"].items():
        label = "halo (a+f)" if name == "halo" else name
        lines.append(f"  {label:<12} {sec:10.4g}  {100 * r['phase_share'][name]:6.1f} %")
    return "\n".join(lines)
