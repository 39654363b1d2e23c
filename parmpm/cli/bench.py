"""``parmpm bench``: time per step and where it goes, on a synthetic block, for scaling studies.

Why a separate command: a physics scene mixes solver cost with output, metrics and scene-specific
set-up, and its particle count is fixed. The benchmark block isolates the time-step loop at a
chosen size, so that time per step and parallel efficiency ``E(P) = T1 / (P · T_P)`` can be
measured at 1, 2, 4, ... ranks (``run_scripts/benchmarks/scaling.py`` drives it).

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
    python -m parmpm bench --dim all --method all --particles 1e5 --csv bench.csv
    mpirun -n 2 python -m parmpm bench --particles 1e6 --json bench_2.json

Each case first runs a tiny block of the same dimension and method (``jit_warmup_seconds``: the
kernels compiled, or loaded from numba's on-disk cache), then the measured block, whose first step
is excluded from the timings too. Phases (seconds per step; ``reduce`` is the one end-of-step
``Allreduce`` that agrees on the next Δt, errors and patch changes; ``sort`` regroups particles
into (patch, id) order after some changed patch or rank: :mod:`parmpm.particles.order`'s index
merge, plus now and then a copy of the fields into that order; the stress update is fused into ``g2p`` and
reported beside it as the time the same work takes on its own). Memory per particle is the
growth of this process's resident set from just before the block is built to its peak (grid,
particles and every buffer; the interpreter and compiled code excluded), divided by the
particles on the rank.
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

import numpy as np

from parmpm.transfer.affine import TRANSFERS
from parmpm.cli.bench_report import format_result, format_summary, summarise, write_csv
from parmpm.core.errors import ParmpmError
from parmpm.io.summary import to_jsonable
from parmpm.scene.load import Scene, scene_from_toml
from parmpm.scene.schema import UPDATES
from parmpm.shapes import INTERPOLATORS

# The solver (numba, the kernels, mpi-aware decomposition) is imported by the functions that
# run it: ``parmpm --help`` builds this module's options and must not pay a second for numba.

__all__ = ["build_bench_scene", "run_bench", "run_benches", "add_arguments", "format_result"]

CELL = 0.01            # m
MARGIN = 4             # empty cells on every side, before the travel allowance
CFL = 0.4
VELOCITY = (1.0, 0.5, 0.25)  # m/s, times --speed
METHODS = tuple(INTERPOLATORS)
WARMUP_PARTICLES = {1: 200, 2: 2000, 3: 4000}


def build_bench_scene(dim: int, method: str = "cpdi", particles: int = 1_000_000, ppc: int = 2,
                      steps: int = 10, patch_size: int | None = None, speed: float = 1.0,
                      update: str = "auto", transfer: str = "flip", dt: float | None = None
                      ) -> Scene:
    """The benchmark block holding ``(n·ppc)^dim ≈ particles`` particles, n cells per axis;
    ``transfer``: "flip", "apic" or "mls" (bspline only); ``dt``: a fixed step (``time.dt``,
    s) instead of the CFL one."""
    if dim not in (1, 2, 3):
        raise ParmpmError(f"bench: --dim must be 1, 2 or 3, got {dim}")
    if update not in UPDATES:
        raise ParmpmError(f"bench: --update must be one of {', '.join(UPDATES)}, got {update!r}")
    if dt is not None and not (isinstance(dt, float) and math.isfinite(dt) and dt > 0):
        raise ParmpmError(f"bench: --dt must be a positive number of seconds, got {dt!r}")
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
update = "{update}"
transfer = "{transfer}"
[time]
steps = {steps}
cfl = {CFL}
{"" if dt is None else f"dt = {dt!r}"}
[output]
snapshots = false
figure = false
history = false
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


def _positive(cast):
    """An option that must be a positive (finite) number of type ``cast``."""
    def parse(text: str):
        try:
            value = cast(text)
        except ValueError:
            value = None
        if value is None or not math.isfinite(value) or value <= 0:
            kind = "integer" if cast is int else "number"
            raise argparse.ArgumentTypeError(f"expected a positive {kind}, got {text!r}")
        return value
    return parse


def _choices(allowed, cast=str):
    """A comma-separated list of ``allowed`` values, or ``all``."""
    def parse(text: str) -> list:
        if text.strip() == "all":
            return list(allowed)
        try:
            values = [cast(t.strip()) for t in text.split(",") if t.strip()]
        except ValueError:
            values = []
        bad = [v for v in values if v not in allowed]
        if not values or bad:
            raise argparse.ArgumentTypeError(
                f"expected 'all' or a comma-separated list of {', '.join(map(str, allowed))}, got {text!r}")
        return values
    return parse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The bench options (shared by ``parmpm bench`` and anything that wraps it)."""
    parser.add_argument("--dim", type=_choices((1, 2, 3), int), default=[2],
                        help="dimension(s): 1, 2, 3, a list such as 2,3, or all (default 2)")
    parser.add_argument("--method", type=_choices(METHODS), default=["cpdi"],
                        help="interpolator(s): a list such as mpm,cpdi, or all (default cpdi)")
    parser.add_argument("--update", choices=UPDATES, default="auto",
                        help="USL or MUSL (default auto: usl for cpdi, musl for the others)")
    parser.add_argument("--transfer", choices=TRANSFERS, default="flip",
                        help="FLIP/PIC, APIC or MLS (affine; --method bspline only) "
                             "transfers (default flip)")
    parser.add_argument("--particles", type=_particle_count, default=1_000_000, metavar="N",
                        help="about how many particles (default 1e6)")
    parser.add_argument("--ppc", type=_positive(int), default=2, help="particles per cell per axis (default 2)")
    parser.add_argument("--steps", type=_positive(int), default=10,
                        help="time steps, the first excluded from timings (default 10)")
    parser.add_argument("--patch-size", type=_positive(int), default=None, metavar="CELLS",
                        help="cells per patch per axis (default: what a run of the block would use, "
                             "grid.patch_size = auto: 64 in 1D/2D, 16 in 3D, halved for blocks "
                             "covering fewer than 16 such patches)")
    parser.add_argument("--speed", type=_positive(float), default=1.0,
                        help="scale of the block velocity (1, 0.5, 0.25) m/s (default 1)")
    parser.add_argument("--dt", type=_positive(float), default=None, metavar="SECONDS",
                        help="a fixed time step (time.dt; the block's CFL step is about 1.1e-4 s "
                             "at the default cell) instead of the CFL step: G2P then leaves out "
                             "the wave speed (default: the CFL step)")
    parser.add_argument("--json", type=Path, default=None, metavar="FILE",
                        help="write the result as JSON (rank 0; a list when several cases run)")
    parser.add_argument("--csv", type=Path, default=None, metavar="FILE",
                        help="write one CSV row per case (rank 0)")
    parser.add_argument("-o", "--out", type=Path, default=None, metavar="DIR",
                        help="folder for the runs' output, one subfolder per case named after its "
                        "scene (default: a temporary folder, removed)")
    parser.add_argument("-q", "--quiet", action="store_true", help="no info messages")


def run_benches(args: argparse.Namespace, comm=None) -> list[dict]:
    """Every (dim, method) case of ``args`` in turn (collective); rank 0 prints each table, a
    summary when there are several, and writes ``--json`` / ``--csv``."""
    from decomposition import SerialComm

    comm = comm if comm is not None else SerialComm()
    dims = args.dim if isinstance(args.dim, list) else [args.dim]
    methods = args.method if isinstance(args.method, list) else [args.method]
    results = []
    for dim in dims:
        for method in methods:
            one = argparse.Namespace(**vars(args))
            one.dim, one.method, one.json, one.csv = dim, method, None, None
            results.append(run_bench(one, comm))
    if comm.Get_rank() == 0:
        if len(results) > 1:
            print(format_summary(results), flush=True)
        if args.json is not None:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            data = results[0] if len(results) == 1 else results
            args.json.write_text(json.dumps(to_jsonable(data), indent=2) + "\n", encoding="utf-8")
        if args.csv is not None:
            write_csv(args.csv, results)
    return results


def run_bench(args: argparse.Namespace, comm=None) -> dict:
    """Run one benchmark case on every rank of ``comm`` (collective); every rank returns the
    result. Rank 0 prints the table and writes ``args.json`` if given."""
    from decomposition import SerialComm
    from parmpm.driver.simulation import Simulation
    from parmpm.driver.warm_up import compile_first

    comm = comm if comm is not None else SerialComm()
    rank = comm.Get_rank()
    args = argparse.Namespace(**vars(args))
    for key in ("dim", "method"):  # one case: a one-element list from the parser is fine
        value = getattr(args, key)
        if isinstance(value, list):
            if len(value) != 1:
                raise ParmpmError(f"bench: run_bench takes one --{key}, got {value}; use run_benches")
            setattr(args, key, value[0])
    update = getattr(args, "update", "auto")
    transfer = getattr(args, "transfer", "flip")
    dt = getattr(args, "dt", None)
    scene = build_bench_scene(args.dim, args.method, args.particles, args.ppc, args.steps,
                              args.patch_size, getattr(args, "speed", 1.0), update, transfer, dt)
    warmup = _warm_up(args.dim, args.method, update, comm, transfer, dt)
    tmp = tempfile.mkdtemp(prefix="parmpm-bench-") if args.out is None and rank == 0 else None
    out_dir = Path(tmp) if tmp else (args.out / scene.name if args.out is not None else None)
    try:
        _reset_peak_rss()
        rss0 = _rss_mb()
        comm.Barrier()
        t0 = time.perf_counter()
        sim = Simulation(scene, out_dir, quiet=True, comm=comm, warm_up=compile_first)
        setup = time.perf_counter() - t0
        summary = sim.run()
        stress = _time_stress(sim)
        grown = max(0.0, _peak_rss_mb() - rss0) * 2**20 / max(1, sim.particles.n)
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    rows = comm.allgather((setup, sim.state.stepper.moves.migrated, _peak_rss_mb(), grown, stress))
    result = summarise(summary, max(r[0] for r in rows), sum(r[1] for r in rows),
                       max(r[2] for r in rows))
    result.update(jit_warmup_seconds=warmup, bytes_per_particle=max(r[3] for r in rows),
                  stress_in_g2p_seconds_per_step=max(r[4] for r in rows), ppc=args.ppc,
                  speed=getattr(args, "speed", 1.0), fixed_dt=dt)
    if rank == 0:
        print(format_result(result), flush=True)
        if getattr(args, "json", None) is not None:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps(to_jsonable(result), indent=2) + "\n", encoding="utf-8")
    return result


def _warm_up(dim: int, method: str, update: str, comm, transfer: str = "flip",
             dt: float | None = None) -> float:
    """Wall time (slowest rank) of a tiny run of the same case: JIT compilation, or loading the
    compiled kernels from numba's cache, which the measured run then no longer pays."""
    from parmpm.driver.simulation import Simulation
    from parmpm.driver.warm_up import compile_first

    tmp = tempfile.mkdtemp(prefix="parmpm-warmup-")
    try:
        comm.Barrier()
        t0 = time.perf_counter()
        scene = build_bench_scene(dim, method, WARMUP_PARTICLES[dim], 2, 3, update=update,
                                  transfer=transfer, dt=dt)
        sim = Simulation(scene, tmp, quiet=True, comm=comm, warm_up=compile_first)
        sim.state.stepper.compile_lazy_order()  # the measured steps must not compile it
        sim.run()
        wall = time.perf_counter() - t0
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return max(comm.allgather(wall))


def _time_stress(sim, repeats: int = 3) -> float:
    """Seconds one stress update of this rank's particles takes on its own (fastest of
    ``repeats``), on a copy of the stress so the run's state is untouched."""
    from parmpm.transfer.kernels2d.material import stress_pass as stress_pass_2d
    from parmpm.transfer.kernels3d.material import stress_pass as stress_pass_3d
    from parmpm.materials.passes import stress_pass

    P, st = sim.particles, sim.state.stepper
    out = np.empty_like(P.stress)
    if st.transfers.kernels is not None and P.dim in (2, 3):
        fast = stress_pass_2d if P.dim == 2 else stress_pass_3d
        run = lambda: fast(P.F, P.mat, st.params, out)  # noqa: E731
    else:
        run = lambda: stress_pass(P.dim, P.F, P.mat, st.params, P.damage, out)  # noqa: E731
    run()
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - t0)
    return best


def _rss_mb() -> float:
    """Current resident memory of this process in MiB (Linux; 0 elsewhere)."""
    try:
        with open("/proc/self/statm", encoding="ascii") as f:
            return int(f.read().split()[1]) * resource.getpagesize() / 2**20
    except OSError:
        return 0.0


def _reset_peak_rss() -> None:
    """Reset the kernel's peak-RSS mark (Linux ≥ 4.0), so each case measures its own peak."""
    try:
        with open("/proc/self/clear_refs", "w", encoding="ascii") as f:
            f.write("5")
    except OSError:
        pass


def _peak_rss_mb() -> float:
    """Peak resident memory in MiB since the last reset (VmHWM), else since the process began."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 2**10
    except OSError:
        pass
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / 2**20 if sys.platform == "darwin" else rss / 2**10
