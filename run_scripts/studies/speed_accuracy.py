"""Speed against accuracy: every method of the studies on two problems with exact solutions.

Physics. Two verification problems (docs/verification.md):

* ``manufactured`` — the 2D axis-aligned manufactured solution (Wallstedt & Guilkey 2008;
  Kamojjala et al. 2015; :func:`study.manufactured_scene`): a neo-Hookean unit square (E = 1e4,
  ν = 0.3, ρ0 = 1) driven by the body force that makes ``U = A sin(πX) sin(cπt)``,
  ``V = A sin(πY) sin(cπt + 2π/3)`` (A = 0.05) exact, one period (0.02 s), CFL 0.2, mirror
  (``"symmetry"``) faces, each method of ``study.METHODS`` (mpm, uGIMP, cpGIMP, CPDI, quadratic B-splines with
  FLIP and with APIC) with its default update (USL for cpdi, MUSL for the others), CPDI
  unscaled. **Error**: the largest over 41 equally spaced times of the RMS over particles of
  ``|x_p − φ(X_p, t)|`` (metres; :class:`study.ManufacturedError` — within 0.2 % of the
  every-step maximum ``rms_error_max``, at a fraction of the cost). Cells per axis 8, 16, 32, 64
  × particles per cell per axis 1, 2, 3.
* ``hanging_bar`` — the 1D self-weighted neo-Hookean bar (``hanging_bar_1d``: 1 m, E = 1 MPa,
  ν = 0, ρ0 = 1050 kg/m³, held at its top) brought to its *static* state: gravity 100 m/s²
  (not the seed's 1000: kL = 0.105, top stretch 1.11, so that every method has a chance)
  ramped up over 0.3 s, mass-proportional damping 60 1/s, end at 0.6 s (settled: 1.0 s runs
  agree to < 1 %). **Error**: ``max_p |u_p − u*(X_p)| / u*(L)`` at the end, over *all*
  particles, against the exact static displacement ``u*`` of the 1D NH law (docs/verification.md
  §2; :class:`StaticBarError`). The summary's tip-only ``relative_error_static`` is in the CSV
  as ``tip_error``; it changes sign under refinement and can cancel by accident (CPDI, 10
  cells, ppc 3: 6e-7), so it is not plotted. A run whose bar numerically separates
  (``metrics.stop_on_separation``) has no error: it is drawn in a band above the panel's
  points and left out of the Pareto front. Cells across the bar 10, 20, 40, 80
  (Δx = 0.1 … 0.0125 m) × ppc 1, 2, 3; CPDI unscaled (l_cr would not engage anyway).

**Cost.** ``step_seconds``: wall-clock seconds inside the time step's phases (the stepper's
timers: p2g, accumulate, grid, fill, g2p, migrate, reduce; ``summary.phase_seconds_per_step``)
per warm step — the first step, which loads or compiles the numba kernels, is excluded — times
the number of steps; metrics sampling, observers and setup are not included. The CSV also has
``loop_seconds = particles · steps / particle_steps_per_second`` (the whole warm loop, metrics
included: ≈ step_seconds for the manufactured runs, several times it for the tiny 1D bars)
and ``run_seconds`` (the case's wall time as :func:`study.run_case` measures it). With
``--repeat N`` every case runs N times and keeps its smallest times (the errors must agree bit
for bit). **particle_steps** = particles × steps: a machine-independent cost.

Found (a run of every case but the 64-cell ones, one core, shared machine):

* Manufactured: CPDI and cpGIMP converge at second order at every ppc (ppc 2: CPDI 6.9e-3,
  1.6e-3, 3.7e-4 m at 8, 16, 32 cells; cpGIMP 6.8e-3, 1.5e-3, 3.4e-4), cpGIMP a few per cent
  more accurate at the same particle-steps; uGIMP converges at 1.5–1.8 (ppc 2, 3) and is
  2.4–2.6× less accurate at 32 cells; at ppc 1 uGIMP and mpm lose accuracy under refinement
  (cell crossing: mpm 0.011 → 0.061 m from 8 to 32 cells). For CPDI and cpGIMP ppc 3 gains
  7–12 % over ppc 2 for ~2.2× the cost. The front's small-error end is cpGIMP's and CPDI's
  finest runs.
* Hanging bar: CPDI converges at exactly second order at every ppc (ppc 2: 1.7e-3, 4.1e-4,
  1.0e-4, 2.6e-5 from 10 to 80 cells) and never separates; cpGIMP is as accurate at 10 and 20
  cells (ppc ≥ 2) but loses accuracy at 40 cells (0.06–0.1) and separates at 80; uGIMP and mpm
  are worse and separate earlier (every non-CPDI ppc 1 run separates, except uGIMP's and
  cpGIMP's at 10 cells). Below an error of 4e-4 the front is CPDI's alone.
* Quadratic B-splines on the mirror faces (the manufactured rows re-run after
  ``parmpm.grid.symmetry``; with the slip planes before, both were first order, 15–16× CPDI's error
  at 32 cells): manufactured, ppc 2: FLIP 9.0e-3, 2.2e-3, 5.6e-4, 3.6e-4 m at 8 → 64 cells
  (orders 2.04, 1.97, 0.62: second order, then the stall of docs/results/convergence.md),
  APIC 5.0e-3, 1.2e-3, 3.2e-4, 2.1e-4 (2.07, 1.88, 0.64). APIC at ppc 1 is on the time front
  from 8 to 32 cells (3.6e-3, 1.1e-3, 3.8e-4 m: 2.3×, 2.2×, 1.6× below CPDI at the same
  resolution, 1.24–1.35× its step time) and not at 64 (3.1e-4 against CPDI's 1.4e-4). At ppc 1
  bspline *is* uGIMP (a quadratic B-spline is the hat averaged over a cell-wide box): the same
  errors to 1e-14 relative. Hanging bar: FLIP does not converge
  (ppc 2: 0.080, 0.041, 0.25, 4.6 at 10 → 80 cells; ppc 1 separates from 20 cells), APIC
  converges at first order (ppc 2: 0.087, 0.044, 0.022, 0.011; ppc 3 0.065 → 0.0082; ppc 1
  0.21 at 10 cells, then separates). Step cost on the 2D manufactured solution (specialised
  kernels): 0.22 µs (FLIP) and 0.23 µs (APIC) per particle-step at 32 cells ppc 2, against
  0.18 for CPDI in the same run.
* Step cost, 2D, 16–32 cells: ~1.0–1.5 µs per particle-step for all four methods alike (MUSL's
  second transfer included), within the noise of this shared 2-core machine (single runs
  up to 2–3 µs when it was busy); particle_steps is not noisy.

Outputs: ``speed_accuracy.csv`` (one row per case; ``on_front_time`` / ``on_front_psteps`` mark the
Pareto fronts of each problem) in ``--out`` (default ``run_scripts/out/speed_accuracy``) and
``speed_accuracy.png`` in ``--out`` too (``make figures`` passes ``--figures docs/figures``): error
against step_seconds (left) and against particle-steps (right), log-log, one row per problem, a
colour and marker per method, marker size by ppc, thin lines along refinement, the Pareto front as a
black staircase with ringed points.

Runtime, one core: full (144 cases, 2D up to 36 864 particles × 864 steps) ~6–9 min (all but
the 64-cell cases: 70 s for the first four methods, 2 min for all six on a busy machine);
``--quick`` (mpm, uGIMP, cpGIMP, CPDI only: manufactured 8 and 16 cells × ppc 1, 2; bar 10 and
20 cells × ppc 1, 2) ~10 s.
Errors and particle-steps are identical on any number of ranks::

    python run_scripts/studies/speed_accuracy.py                      # full study (the lead's run)
    python run_scripts/studies/speed_accuracy.py --quick              # the smoke test's mode
    mpirun -n 2 python run_scripts/studies/speed_accuracy.py --quick
    python run_scripts/studies/speed_accuracy.py --cases 'manufactured_cp*' --repeat 2 --out /tmp/sa
    python run_scripts/studies/speed_accuracy.py --cases '*_n8_*,*_n16_*,*_n32_*,hanging_bar_*'  # no 64
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py, the groups
from study import (METHOD_KEYS, METHODS as REGISTRY, ManufacturedError, compact_png, figure,
                   folders, is_root, main_guard, manufactured_sampling, manufactured_scene,
                   observed_orders, pareto_front, parser, run_case, save, scene_with,
                   scratch_folder, select_cases, world, write_csv, wrote)

METHODS = METHOD_KEYS  # every registered method (study.METHODS); ``--cases`` picks a subset
QUICK_METHODS = ("mpm", "ugimp", "cpgimp", "cpdi")  # --quick: the smoke test's methods
TITLES = {m: REGISTRY[m].label for m in METHODS}
COLOURS = {m: REGISTRY[m].colour for m in METHODS}
MARKERS = {m: REGISTRY[m].marker for m in METHODS}
PROBLEMS = ("manufactured", "hanging_bar")
MEASURES = {"manufactured": "max over t of RMS |x - phi(X,t)| (m)",
            "hanging_bar": "max over particles |u - u*(X)| / u*(L) (static)"}
SAMPLES = 40           # manufactured: error sampled at SAMPLES + 1 times in the period
BAR_G = 100.0          # m/s², the bar's gravity (kL = 0.105)
BAR = ["method.lcr=none", f"gravity.g=[{-BAR_G!r}]", "gravity.ramp_time=0.3",
       "damping.coefficient=60.0", "time.end=0.6", "metrics.stop_on_separation=true"]


@dataclass(frozen=True)
class Case:
    problem: str
    method: str
    cells: int   # cells per axis across the body (unit square / 1 m bar)
    ppc: int     # particles per cell per axis

    @property
    def id(self) -> str:
        return f"{self.problem}_{self.method}_n{self.cells}_ppc{self.ppc}"

    def scene_and_observers(self):
        """(scene or built-in name, overrides for run_case, observers)."""
        if self.problem == "manufactured":
            obs = ManufacturedError()
            scene = scene_with(manufactured_scene(2, self.cells, self.method, ppc=self.ppc),
                               manufactured_sampling(SAMPLES))
            return scene, [], [obs]
        n = round(3.2 * self.cells)  # the built-in grid's 3.2 m (origin −3 m), Δx = 1/cells
        over = BAR + [*REGISTRY[self.method].overrides(), f"bodies.0.ppc={self.ppc}",
                      f"grid.cell_size={1.0 / self.cells!r}", f"grid.cells={n}",
                      f"grid.patch_size={max(8, n // 4)}"]
        return "hanging_bar_1d", over, [StaticBarError()]


class StaticBarError:
    """Observer (collective) for the 1D hanging bar: at the end of the run, the largest
    ``|u_p − u*(X_p)|`` over all particles against the exact static displacement ``u*`` of the 1D
    neo-Hookean law (:func:`parmpm.exact.bars.hanging_bar_static_displacement`; ``X`` from the support),
    over the exact tip displacement ``u*(L)``. Gathered in global-id order: rank-independent."""

    def __init__(self):
        self.error = math.nan

    def __call__(self, sim) -> None:
        if not sim.done():
            return
        from parmpm.exact.bars import hanging_bar_static_displacement, nominal_stress_1d

        P = sim.particles
        g = sim.gather({"x": P.x[:, 0].copy(), "x0": P.x0[:, 0].copy()})
        err = None
        if g is not None:
            body = sim.state.data["bodies"][0]
            mat = sim.state.data["materials"][body["material"]]
            top, L = float(body["max"][0]), float(body["max"][0] - body["min"][0])
            law = nominal_stress_1d(mat["model"], mat["youngs_modulus"], mat["poisson_ratio"])
            grav = abs(float(sim.state.data["gravity"]["g"][0]))
            X = top - g["x0"]                      # distance from the support
            exact = hanging_bar_static_displacement(np.append(X, L), L, mat["density"], grav, law)
            u = g["x0"] - g["x"]                   # displacement along gravity
            err = float(np.max(np.abs(u - exact[:-1])) / exact[-1])
        self.error = sim.comm.bcast(err, root=0)


def full_cases() -> list[Case]:
    cases = [Case("manufactured", m, n, p) for m in METHODS for n in (8, 16, 32, 64) for p in (1, 2, 3)]
    cases += [Case("hanging_bar", m, n, p) for m in METHODS for n in (10, 20, 40, 80) for p in (1, 2, 3)]
    return cases


def quick_cases() -> list[Case]:
    cases = [Case("manufactured", m, n, p) for m in QUICK_METHODS for n in (8, 16) for p in (1, 2)]
    cases += [Case("hanging_bar", m, n, p) for m in QUICK_METHODS for n in (10, 20) for p in (1, 2)]
    return cases


def run_one(case: Case, comm, scratch: Path, repeat: int) -> dict:
    """Run ``case`` ``repeat`` times (collective); the CSV row, with the smallest times."""
    best = None
    for k in range(repeat):
        scene, overrides, observers = case.scene_and_observers()
        summary, wall = run_case(scene, overrides, comm=comm, observers=observers,
                                 out_dir=scratch / f"{case.id}_{k}")
        mets = summary["metrics"]
        if case.problem == "manufactured":
            separated, error, at_stop = False, observers[0].rms_max, observers[0].rms_max
            tip = math.nan
        else:
            separated = bool(mets["separated"])
            at_stop = observers[0].error  # NaN when it stopped early
            error = math.nan if separated else at_stop
            tip = mets["relative_error_static"]
        steps, n = summary["steps"], summary["particles"]
        phases = summary["phase_seconds_per_step"] or {}
        rate = summary["particle_steps_per_second"]
        r = {
            "case": case.id, "problem": case.problem, "method": case.method,
            "update": summary["update"], "cells": case.cells, "ppc": case.ppc,
            "cell_size": summary["grid"]["cell_size"][0], "particles": n, "steps": steps,
            "particle_steps": n * steps, "end_time": summary["time"], "separated": separated,
            "error": error, "tip_error": tip, "error_measure": MEASURES[case.problem],
            "step_seconds": sum(phases.values()) * steps,
            "loop_seconds": n * steps / rate if rate else math.nan,
            "run_seconds": wall, "ranks": summary["ranks"],
        }
        if best is None:
            best = r
        else:
            same_error = (r["error"] == best["error"]
                          or (math.isnan(r["error"]) and math.isnan(best["error"])))
            if (r["steps"], r["end_time"]) != (best["steps"], best["end_time"]) or not same_error:
                raise RuntimeError(f"{case.id}: repeat {k} differs from the first run")
            for key in ("step_seconds", "loop_seconds", "run_seconds"):
                best[key] = min(best[key], r[key])
    return best


def mark_fronts(rows: list[dict]) -> None:
    """``on_front_time`` / ``on_front_psteps``: on the Pareto front (cost, error) of its problem
    over all methods and resolutions; separated bars (no error) are never on it."""
    for r in rows:
        r["on_front_time"] = r["on_front_psteps"] = False
    for problem in PROBLEMS:
        ok = [r for r in rows if r["problem"] == problem and math.isfinite(r["error"])]
        if not ok:
            continue
        err = [r["error"] for r in ok]
        for key, cost in (("on_front_time", "step_seconds"), ("on_front_psteps", "particle_steps")):
            for i in pareto_front([r[cost] for r in ok], err):
                ok[i][key] = True


def chart(rows: list[dict], path: Path) -> Path:
    from matplotlib.lines import Line2D
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    problems = [p for p in PROBLEMS if any(r["problem"] == p for r in rows)]
    fig, axes = figure(len(problems), 2, size=(10.0, 3.9 * len(problems)))
    size = {1: 22, 2: 42, 3: 70}
    for i, problem in enumerate(problems):
        mine = [r for r in rows if r["problem"] == problem]
        good = [r for r in mine if math.isfinite(r["error"])]
        for j, (cost, front, xlabel) in enumerate((
                ("step_seconds", "on_front_time", "time-step wall clock (s), after JIT warm-up"),
                ("particle_steps", "on_front_psteps", "particle-steps (particles × steps)"))):
            ax = axes[i, j]
            ax.set_xscale("log")
            ax.set_yscale("log")
            for m in METHODS:
                pts = [r for r in good if r["method"] == m]
                for p in sorted({r["ppc"] for r in pts}):
                    line = sorted((r for r in pts if r["ppc"] == p), key=lambda r: r["cells"])
                    ax.plot([r[cost] for r in line], [r["error"] for r in line], "-",
                            color=COLOURS[m], lw=0.7, alpha=0.45)
                ax.scatter([r[cost] for r in pts], [r["error"] for r in pts],
                           s=[size.get(r["ppc"], 90) for r in pts], c=COLOURS[m], marker=MARKERS[m],
                           edgecolors="k", linewidths=0.3, zorder=3)
            fr = sorted((r for r in good if r[front]), key=lambda r: r[cost])
            if fr:
                xs = [r[cost] for r in fr]
                ys = [r["error"] for r in fr]
                ax.step(xs, ys, where="post", color="k", lw=1.0, zorder=2)
                ax.scatter(xs, ys, s=150, facecolors="none", edgecolors="k", linewidths=1.0, zorder=4)
            bad = [r for r in mine if not math.isfinite(r["error"])]
            if bad:  # separated: no error; drawn in a band above the largest error
                top = max(r["error"] for r in good) if good else 1.0
                ax.axhline(1.6 * top, color="0.5", lw=0.6, ls="--")
                for r in bad:
                    ax.scatter([r[cost]], [2.4 * top], s=size.get(r["ppc"], 90), facecolors="none",
                               edgecolors=COLOURS[r["method"]], marker=MARKERS[r["method"]],
                               linewidths=1.1, zorder=3)
                ax.text(0.01, 1.5 * top, " above: bar separated (no static error)",
                        transform=ax.get_yaxis_transform(), fontsize=7, ha="left", va="top",
                        color="0.3")
                ax.set_ylim(top=4.0 * top)
            ax.set_xlabel(xlabel, fontsize=8)
            ax.set_ylabel(("RMS position error, max over t (m)" if problem == "manufactured"
                           else "static error max |u − u*(X)| / u*(L)"), fontsize=8)
            title = ("2D manufactured solution, 1 period" if problem == "manufactured"
                     else f"1D hanging bar, static (g = {BAR_G:g} m/s², ramped, damped)")
            ax.set_title(title, fontsize=9)
            ax.tick_params(labelsize=7)
            ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
            ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
            ax.xaxis.set_minor_formatter(NullFormatter())
            ax.yaxis.set_minor_formatter(NullFormatter())
            ax.grid(True, which="major", lw=0.3, alpha=0.5)
    handles = [Line2D([], [], ls="", marker=MARKERS[m], color=COLOURS[m], markeredgecolor="k",
                      markeredgewidth=0.3, label=TITLES[m])
               for m in METHODS if any(r["method"] == m for r in rows)]
    handles += [Line2D([], [], ls="", marker="o", color="0.6", markersize=ms, label=f"ppc {p}")
                for p, ms in ((1, 4.5), (2, 6.5), (3, 8.5))]
    handles += [Line2D([], [], color="k", marker="o", markerfacecolor="none", markersize=9,
                       label="Pareto front")]
    axes[0, 0].legend(handles=handles, fontsize=7, loc="lower left", ncol=2, framealpha=0.9)
    return compact_png(save(fig, path))


def report(rows: list[dict]) -> None:
    """Observed orders per (problem, method, ppc) along refinement (rank 0's stdout)."""
    for problem in PROBLEMS:
        for m in METHODS:
            for p in (1, 2, 3):
                line = sorted((r for r in rows
                               if (r["problem"], r["method"], r["ppc"]) == (problem, m, p)),
                              key=lambda r: r["cells"])
                if len(line) < 2:
                    continue
                errs = [r["error"] for r in line]
                orders = (observed_orders([1.0 / r["cells"] for r in line], errs)
                          if all(math.isfinite(e) and e > 0 for e in errs) else [])
                print(f"  {problem:12s} {m:12s} ppc {p}: errors "
                      + " ".join("separated" if not math.isfinite(e) else f"{e:.3g}" for e in errs)
                      + ("; orders " + " ".join(f"{o:.2f}" for o in orders) if orders else ""))


def main() -> int:
    ap = parser(__doc__)
    ap.add_argument("--cases", default=None, help="comma-separated glob patterns over case ids "
                    "(<problem>_<method>_n<cells>_ppc<ppc>), e.g. 'manufactured_cpdi_*'")
    ap.add_argument("--repeat", type=int, default=1, help="runs per case; the smallest times are kept")
    args = ap.parse_args()
    comm = world()
    root = is_root(comm)
    out, figs = folders(args, "speed_accuracy")
    cases = quick_cases() if args.quick else full_cases()
    cases = select_cases(cases, args.cases)
    rows = []
    t0 = time.perf_counter()
    with scratch_folder(comm, "parmpm-speed-") as scratch:
        for case in cases:
            r = run_one(case, comm, scratch, max(1, args.repeat))
            rows.append(r)
            if root:
                err = "separated" if r["separated"] else f"{r['error']:.4g}"
                print(f"{case.id:40s} error {err:>10s}  {r['particles']:6d} particles × "
                      f"{r['steps']:5d} steps  step {r['step_seconds']:.3g} s, "
                      f"run {r['run_seconds']:.3g} s", flush=True)
    mark_fronts(rows)
    write_csv(out / "speed_accuracy.csv", rows, comm)
    if root:
        report(rows)
        path = chart(rows, figs / "speed_accuracy.png")
        print(f"{len(rows)} cases in {time.perf_counter() - t0:.0f} s on {comm.Get_size()} rank(s)")
        print(f"wrote {out / 'speed_accuracy.csv'}")
        print(wrote(path))
    return 0


if __name__ == "__main__":
    main_guard(main)
