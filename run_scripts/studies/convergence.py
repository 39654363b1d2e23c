"""Verification against exact solutions: manufactured-solution convergence and the 1D bars.

Physics. Three problems with exact solutions (``docs/verification.md``):

* **Axis-aligned manufactured solution** (Wallstedt & Guilkey 2008; Kamojjala et al. 2015; §3):
  a unit line/square/cube of neo-Hookean material (E = 10⁴, ν = 0.3, ρ0 = 1, so one period
  T = 0.02 s) is driven by the body force that makes ``U_k = A sin(πX_k) sin(cπt + φ_k)``
  (A = 0.05, stretches 0.84–1.16) the exact motion; mirror (``"symmetry"``) faces, 2 particles
  per cell per axis, CFL 0.2, one period. The error is the RMS over particles of
  ``|x_p − φ(X_p, t)|``, maximised over 41 equally spaced times in [0, T] (the built-in
  ``manufactured`` metric, sampled at those times). Every method of ``study.METHODS`` (mpm,
  uGIMP, cpGIMP, CPDI, quadratic B-splines with FLIP and with APIC transfers) at its default
  update (``auto``: USL for cpdi, MUSL for the others), and cpdi/cpGIMP also at the other
  update; 1D at 16→128 cells, 2D at 8→64, 3D at 4, 8, 12, 16. CPDI runs unscaled (``lcr = "none"``):
  the motion is smooth and no domain ever reaches a cap.
* **Axially vibrating bar** (Sulsky et al. 1995; Bardenhagen 2002; §1): built-in
  ``vibrating_bar`` (1D, E = 100, ρ = 1, L = 25, first mode, v0 = 0.1, 4 periods, ppc 2, CFL 0.4);
  error = relative L2 norm over the (every-step) samples of the centre-of-mass velocity against
  ``v0/(β1 L)·cos(ω1 t)``. Every method with USL and MUSL at 16 cells; cpdi at 8→64 cells.
* **Hanging (self-weighted) bar in 1D** (§2), built-in ``hanging_bar_1d`` (L = 1 m, E = 1 MPa,
  ρ0 = 1050 kg/m³, neo-Hookean ν = 0, ppc 3, CFL 0.4), at 10, 20, 40, 80 cells over the bar:
  (a) *static, large deformation*: g = 1000 m/s² ramped over 0.2 s, mass-proportional damping
  40 1/s, run to 1 s (residual motion ~1e-7 of the tip displacement); the tip particle's
  displacement against the exact static solution ``P(λ) = ρ0 g (L − X)`` at its reference
  position (top stretch 2.5, elongation 0.6863 m); (b) *dynamic, small strain*: g = 1 m/s²
  switched on at t = 0 (strain ~1e-3), two periods 8L/c; relative L2 error of the tip history
  against the d'Alembert solution (the mode series at the tip particle's reference position,
  which the closed form ``hanging_bar_dynamic_tip`` at X = L gives to within 0.4 % of the
  error).

Expected (the literature) and found (full study, RMS error / relative error; orders are
``log(e_i/e_{i+1}) / log(h_i/h_{i+1})`` between successive resolutions):

* manufactured: second order for cpdi and cpGIMP in 1D, 2D and 3D, USL and MUSL alike (the
  order expected of these smooth-weight methods on a smooth solution). Found: 1D 1.4e-3 →
  2.5e-5 (orders 1.97, 1.95, 1.90), 2D 6.9e-3 → 8.4e-5 (2.08, 2.13, 2.13), 3D 2.5e-2 → 1.7e-3
  at 4 → 16 cells (1.85, 2.05, 2.01); cpGIMP within 10 % of cpdi. uGIMP degrades as particles
  cross cells (its fixed-size domains do not follow the ±16 % stretch): 2D orders 1.80, 1.48,
  1.08, and in 1D the error grows again at 128 cells; mpm does not converge at all (its
  cell-crossing error grows as h shrinks).
  Quadratic B-splines (``bspline``): C¹ weights, second order expected on this smooth
  solution, provided the faces are mirrors: a B-spline particle within half a cell of a face
  weights the node beyond it, whose velocity is the mirror of its twin's (``parmpm.grid.symmetry``;
  the slip planes used before held it at zero and gave first order: 2D 1.14, 1.13, 1.16).
  Found, mirror faces: FLIP 1D 1.85e-3, 5.13e-4, 2.96e-4, 7.82e-4 at 16 → 128 cells (orders
  1.85, 0.79, −1.40), 2D 8.99e-3, 2.19e-3, 5.57e-4, 3.61e-4 (2.04, 1.97, 0.62), 3D 4.2e-2 →
  2.27e-3 (2.21, 1.96, 2.08); APIC 1D (1.73, 0.74, −0.65), 2D (2.07, 1.88, 0.64), 3D (1.96,
  2.04, 1.97). Second order until the particles travel a few cells (3.2 cells at 64 cells),
  then a stall, as uGIMP's (1D 1.67, 0.76, −2.04 here); at A = 0.01 the 1D B-spline stays
  second order to 128 cells (2.04, 2.01, 1.91). Likely the grid-crossing error of particle
  quadrature, not isolated (1 ppc diverges as uGIMP's does, 2.6e-3, 2.3e-2, 5.3e-2 at 32, 64,
  128 cells; 4 ppc did not lower it; CFL 0.1 halved it at 128 cells).
* vibrating bar: a few per cent at 16 cells, converging (Bardenhagen 2002). Found (the scene's
  ``"clamped"`` face): 1.5–2.2 % at 16 cells for every method, USL and MUSL alike, but FLIP
  B-splines 3.5 % (APIC 1.8 %; with the held nodes used before 31 % and 29 %: a first-order
  clamp); cpdi 7.9 % → 0.17 % at 8 → 64 cells (orders 1.9, 1.8, 1.8; the lumped-mass phase
  error accumulating over 4 periods).
* hanging bar, static (large deformation, top stretch 2.5): cpdi with USL converges at second
  order, 2.7e-4 → 4.2e-6 of the tip displacement at 10 → 80 cells. cpGIMP with USL reaches
  1.7e-3 → 2.2e-4, then stalls (2.4e-4 at 80 cells) and separates at 160 cells: its box
  centre moves with the *mean* grid velocity over the box and its length with the velocity
  *difference*, so with a kinked (piecewise-linear) grid velocity inside a box the box edges do
  not follow the material and neighbouring boxes slowly open gaps; CPDI's corners move exactly
  with the grid velocity at the corners, so in 1D USL its domains keep tiling the bar. Under
  MUSL the position increment and the deformation increment come from two different grid
  velocities (before and after the momentum re-map), so CPDI and cpGIMP domains stop tiling
  too (the gaps between neighbouring domains grow, a particle-to-particle zig-zag in F grows
  near the support once the stretch passes ~1.8) and the bar separates during the ramp
  (cpdi: at 0.17 s at CFL 0.4; 0.37 s at CFL 0.1 — a smaller step delays it, it does not
  cure it). mpm and uGIMP separate (MUSL) or end far from
  the static state (uGIMP USL: tip 0.94 m against 0.686 m). bspline (MUSL, 20 cells) separates
  at 0.146 s (stretch 1.97), with APIC at 0.193 s (2.55). These rows carry a ``note``.
* hanging bar, dynamic (small strain): the tip history follows d'Alembert's two-parabola
  solution, peak twice the static tip displacement (1.050e-3 m, matched to 0.1 %); the L2 error
  of the history is 1.5–1.7 % at 10 cells for every method and converges at first order (the
  strain has a travelling jump: 1.5e-3 at 80 cells); mpm is slower (2.8e-3 at 80 cells), the
  B-splines ten times worse at 10 cells and first order too (FLIP 1.33e-1 → 1.53e-2, APIC
  1.18e-1 → 1.50e-2 at 10 → 80 cells; peak 6 % high at 10 cells: the clamp).

Outputs: ``convergence.csv`` (manufactured; one row per run: problem, dim, method, update,
cells, h, ppc, error, order against the previous resolution of its series, error at t = T,
steps, wall_seconds) and ``verification.csv`` (the bars: one row per run; ``error`` as above)
in ``--out`` (default ``run_scripts/out/convergence``); PNGs in ``--out`` too (``make figures``
passes ``--figures docs/figures``): ``convergence_manufactured.png`` (error against h, one panel
per dimension) and ``verification_bars.png`` (the bars against their exact solutions, and their
errors against h).

Runtime, one core: full ~5 min (2D at 64 cells ~1.5 min, 3D ~2 min; the two B-spline methods
alone, ``--methods bspline,bspline_apic``, 30 s); ``--quick`` (1D cpdi/cpGIMP/bspline at 16,
32, 64 cells, 2D at 8, 16, 32, the vibrating bar USL/MUSL with cpdi at 16 cells, the hanging
bar at 10 and 20 cells) ~10 s. Results are identical on any number of
ranks (only ``wall_seconds`` differs)::

    python run_scripts/studies/convergence.py                 # full study, figures beside the CSV
    python run_scripts/studies/convergence.py --quick         # the smoke test's mode
    mpirun -n 2 python run_scripts/studies/convergence.py --quick
    python run_scripts/studies/convergence.py --only manufactured-2d,vibrating-bar --out /tmp/c
    python run_scripts/studies/convergence.py --methods bspline,bspline_apic --out /tmp/c
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py, the groups
from study import (METHOD_KEYS, METHODS as REGISTRY, figure, folders, is_root, main_guard,
                   manufactured_scene, method_keys, observed_orders, parser, run_case, save,
                   scene_with, scratch_folder, world, write_csv, wrote)

GROUPS = ("manufactured-1d", "manufactured-2d", "manufactured-3d", "vibrating-bar",
          "hanging-static", "hanging-dynamic")
METHODS = METHOD_KEYS  # every registered method (study.METHODS); ``--methods`` picks a subset
DEFAULT_UPDATE = {m: REGISTRY[m].update for m in METHODS}  # what "auto" resolves to
OTHER = {"usl": "musl", "musl": "usl"}
LABEL = {m: REGISTRY[m].label for m in METHODS}
COLOUR = {m: REGISTRY[m].colour for m in METHODS}
QUICK_METHODS = ("cpgimp", "cpdi", "bspline")  # manufactured 1D/2D in --quick

PERIOD = 0.02       # s, manufactured solution: T = 2/c, c = sqrt(1e4 / 1)
SAMPLES = 40        # error samples per period (the built-in metric at these times)
MANUFACTURED_CELLS = {1: (16, 32, 64, 128), 2: (8, 16, 32, 64), 3: (4, 8, 12, 16)}
QUICK_CELLS = {1: (16, 32, 64), 2: (8, 16, 32)}

BAR_L, BAR_RHO, BAR_E = 1.0, 1050.0, 1.0e6      # hanging_bar_1d (neo-Hookean, ν = 0)
BAR_CELLS = (10, 20, 40, 80)                    # cells over the 1 m bar
STATIC = ["gravity.ramp_time=0.2", "damping.coefficient=40", "time.end=1.0"]
SMALL_G = 1.0                                   # m/s², the small-strain dynamic check
VIB_L = 25.0                                    # vibrating_bar length
VIB_CELLS = (8, 16, 32, 64)


def lcr(method: str) -> list[str]:
    return ["method.lcr=none"] if REGISTRY[method].interpolator in ("cpdi", "cpdi2") else []


def chosen(method: str, methods) -> bool:
    return methods is None or method in methods


class KeepMetrics:
    """Observer: keeps the run's metrics object (its histories: every step, every rank alike)
    and, if ``profile``, rank 0's last gathered particle state (x, x0, F along the bar)."""

    def __init__(self, profile: bool = False):
        self.metrics, self.profile, self.state = None, profile, None

    def __call__(self, sim) -> None:
        self.metrics = sim.state.metrics
        if self.profile:
            P = sim.particles
            g = sim.gather({"x": P.x[:, 0], "x0": P.x0[:, 0], "F": P.F[:, 0, 0]})
            if g is not None:
                self.state = g


def series_orders(rows: list[dict], keys: tuple[str, ...]) -> None:
    """Fill ``order`` in ``rows`` (in place): within each series (equal ``keys``), sorted by
    decreasing h, the observed order against the previous (coarser) resolution; runs with a
    ``note`` (the bar separated) get none and are skipped."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault(tuple(r[k] for k in keys), []).append(r)
    for rs in groups.values():
        rs.sort(key=lambda r: -r["h"])
        for r in rs:
            r["order"] = None
        ok = [r for r in rs if r["error"] and math.isfinite(r["error"]) and r["error"] > 0
              and not r.get("note")]  # a separated bar is no resolution of the series
        orders = observed_orders([r["h"] for r in ok], [r["error"] for r in ok])
        for r, p in zip(ok[1:], orders):
            r["order"] = p


# --- manufactured solution ---------------------------------------------------------------------
def manufactured_runs(dim: int, quick: bool, methods=None) -> list[tuple[str, str, int]]:
    """(method, update, cells) of one dimension's study (``methods``: a subset of keys)."""
    if quick:  # no 3D
        series = [(m, DEFAULT_UPDATE[m]) for m in QUICK_METHODS]
        cells = QUICK_CELLS.get(dim, ())
    else:
        series = [(m, DEFAULT_UPDATE[m]) for m in METHODS]
        series += [(m, OTHER[DEFAULT_UPDATE[m]]) for m in ("cpgimp", "cpdi")]
        cells = MANUFACTURED_CELLS[dim]
    return [(m, u, n) for m, u in series for n in cells if chosen(m, methods)]


def manufactured_case(dim: int, method: str, update: str, cells: int, comm, scratch: Path) -> dict:
    """One manufactured run; the built-in metric is sampled at ``SAMPLES + 1`` equally spaced
    times (the observer) instead of every step (whose connectivity count would cost 3×)."""
    scene = manufactured_scene(dim, cells, method, update, ppc=2, lcr="none")
    scene = scene_with(scene, [f"output.every={PERIOD / SAMPLES!r}",
                                   "metrics.every_steps=1000000000"])
    summary, wall = run_case(scene, comm=comm, observers=[lambda sim: sim.sample_metrics()],
                             out_dir=scratch / f"m{dim}d_{method}_{update}_{cells}")
    m = summary["metrics"]
    return {"problem": "manufactured", "dim": dim, "method": method, "update": summary["update"],
            "cells": cells, "h": 1.0 / cells, "ppc": 2, "error": m["rms_error_max"], "order": None,
            "error_end": m["rms_error"], "steps": summary["steps"], "wall_seconds": wall}


# --- vibrating bar -----------------------------------------------------------------------------
def vibrating_runs(quick: bool, methods=None) -> list[tuple[str, str, int]]:
    if quick:
        runs = [("cpdi", u, 16) for u in ("usl", "musl")]
    else:
        runs = [(m, u, 16) for m in METHODS for u in ("usl", "musl") if m != "cpdi"]
        runs += [("cpdi", u, n) for u in ("usl", "musl") for n in VIB_CELLS]
    return [r for r in runs if chosen(r[0], methods)]


def vibrating_case(method, update, cells, comm, scratch: Path):
    h = VIB_L / cells
    # the scene's clamped face at X = 0 (the odd mirror beyond it), 4 cells beyond the free end
    ov = [*REGISTRY[method].overrides(), f"method.update={update}", f"grid.cell_size={h!r}",
          f"grid.cells={cells + 4}"] + lcr(method)
    keep = KeepMetrics()
    summary, wall = run_case("vibrating_bar", ov, comm, [keep],
                             out_dir=scratch / f"vib_{method}_{update}_{cells}")
    M = keep.metrics
    row = {"problem": "vibrating_bar", "method": method, "update": update, "cells": cells, "h": h,
           "ppc": 2, "cfl": 0.4, "quantity": "com velocity, relative L2 error over 4 periods",
           "error": summary["metrics"]["com_velocity_rel_l2_error"], "order": None,
           "numerical": M.com_velocity[-1], "exact": M.com_velocity_exact[-1], "note": "",
           "steps": summary["steps"], "wall_seconds": wall}
    return row, {"t": np.array(M.times), "v": np.array(M.com_velocity),
                 "exact": np.array(M.com_velocity_exact)}


# --- hanging bar -------------------------------------------------------------------------------
def bar_grid(cells: int) -> list[str]:
    """hanging_bar_1d's grid (x from −3 to 0.2 m) at ``cells`` cells over the 1 m bar."""
    h = BAR_L / cells
    n = round(3.2 / h)
    return [f"grid.cell_size={h!r}", f"grid.cells={n}", f"grid.patch_size={max(8, n // 2)}"]


def static_runs(quick: bool, methods=None) -> list[tuple[str, str, int, float]]:
    """(method, update, cells, cfl): the USL refinement series, then single runs that document
    the MUSL time-step sensitivity and the non-CP methods (``note`` says what happened)."""
    if quick:
        return [("cpdi", "usl", n, 0.4) for n in BAR_CELLS[:2] if chosen("cpdi", methods)]
    runs = [(m, "usl", n, 0.4) for m in ("cpdi", "cpgimp") for n in BAR_CELLS]
    runs += [("cpgimp", "usl", 2 * BAR_CELLS[-1], 0.4)]  # cpGIMP's domains drift apart: it separates
    runs += [("cpdi", "musl", 20, 0.4), ("cpdi", "musl", 20, 0.1), ("cpdi", "musl", 10, 0.1),
             ("cpgimp", "musl", 20, 0.4), ("cpgimp", "musl", 20, 0.1),
             ("ugimp", "usl", 20, 0.4), ("ugimp", "musl", 20, 0.4), ("mpm", "musl", 20, 0.4)]
    # the methods without domains beyond these (bspline, ...): one run each at their default update
    runs += [(m, DEFAULT_UPDATE[m], 20, 0.4) for m in METHODS
             if m not in ("cpdi", "cpgimp", "ugimp", "mpm")]
    return [r for r in runs if chosen(r[0], methods)]


def static_case(method, update, cells, cfl, comm, scratch: Path, profile: bool):
    ov = [*REGISTRY[method].overrides(), f"method.update={update}", f"time.cfl={cfl}",
          "output.every=0.05", *STATIC, *bar_grid(cells)] + lcr(method)
    keep = KeepMetrics(profile)
    summary, wall = run_case("hanging_bar_1d", ov, comm, [keep],
                             out_dir=scratch / f"static_{method}_{update}_{cells}_{cfl}")
    m = summary["metrics"]
    note = ""
    if m["separated"]:
        note = f"separated at t = {m['separation_time']:.3f} s (stretch {m['stretch_at_separation']:.2f})"
    row = {"problem": "hanging_bar_static", "method": method, "update": update, "cells": cells,
           "h": BAR_L / cells, "ppc": 3, "cfl": cfl,
           "quantity": "tip displacement, relative error against the exact static state",
           "error": m["relative_error_static"], "order": None, "numerical": -m["tip_displacement"],
           "exact": m["exact_static_tip_displacement"], "note": note, "steps": summary["steps"],
           "wall_seconds": wall}
    return row, keep.state


def dynamic_runs(quick: bool, methods=None) -> list[tuple[str, str, int]]:
    if quick:
        series = [("cpdi", "usl")]
        return [(m, u, n) for m, u in series for n in BAR_CELLS[:2] if chosen(m, methods)]
    series = [(m, DEFAULT_UPDATE[m]) for m in METHODS] + [("cpdi", "musl"), ("cpgimp", "usl")]
    return [(m, u, n) for m, u in series for n in BAR_CELLS if chosen(m, methods)]


def dynamic_case(method, update, cells, comm, scratch: Path):
    from parmpm.exact.bars import hanging_bar_dynamic_series

    c = math.sqrt(BAR_E / BAR_RHO)
    end = 8.0 * BAR_L / c  # two periods
    ov = [*REGISTRY[method].overrides(), f"method.update={update}", f"gravity.g=[{-SMALL_G}]",
          f"time.end={end!r}", f"output.every={end / 4!r}", "metrics.stop_on_separation=false",
          *bar_grid(cells)] + lcr(method)
    keep = KeepMetrics()
    summary, wall = run_case("hanging_bar_1d", ov, comm, [keep],
                             out_dir=scratch / f"dyn_{method}_{update}_{cells}")
    M = keep.metrics
    t, u = np.array(M.times), -np.array(M.tip_history)  # positive along gravity
    exact = hanging_bar_dynamic_series(M.X_tip, t, BAR_L, BAR_RHO, SMALL_G, BAR_E, n_modes=4000)
    err = math.sqrt(float(np.sum((u - exact) ** 2) / np.sum(exact ** 2)))
    row = {"problem": "hanging_bar_dynamic", "method": method, "update": update, "cells": cells,
           "h": BAR_L / cells, "ppc": 3, "cfl": 0.4,
           "quantity": "tip history over two periods, relative L2 error (d'Alembert)",
           "error": err, "order": None, "numerical": float(u.max()), "exact": float(exact.max()),
           "note": "", "steps": summary["steps"], "wall_seconds": wall}
    return row, {"t": t, "u": u, "exact": exact, "X_tip": M.X_tip}


# --- figures -----------------------------------------------------------------------------------
def slope_guides(ax, h, err, slopes=(1, 2)) -> None:
    """Reference lines ``e ∝ h^p`` starting half the smallest error below the finest h."""
    h, err = np.asarray(h, float), np.asarray(err, float)
    hs = np.array([h.min(), h.max()])
    anchor = err.min() * 0.5
    for p, ls in zip(slopes, (":", "--")):
        ax.plot(hs, anchor * (hs / hs[0]) ** p, color="0.45", ls=ls, lw=0.9, label=f"slope {p}")


def manufactured_figure(rows: list[dict], path: Path) -> Path:
    dims = sorted({r["dim"] for r in rows})
    fig, axes = figure(1, len(dims), size=(3.6 * len(dims) + 1.3, 3.7))
    for ax, d in zip(axes[0], dims):
        mine = [r for r in rows if r["dim"] == d]
        for m in METHODS:
            for u in ("usl", "musl"):
                s = sorted((r for r in mine if r["method"] == m and r["update"] == u),
                           key=lambda r: r["h"])
                if not s:
                    continue
                default = u == DEFAULT_UPDATE[m]
                ax.loglog([r["h"] for r in s], [r["error"] for r in s],
                          ("o-" if default else "s--"), color=COLOUR[m], ms=4 if default else 3,
                          lw=1.2 if default else 0.9, mfc=None if default else "none",
                          label=f"{LABEL[m]} {u.upper()}")
        slope_guides(ax, [r["h"] for r in mine], [r["error"] for r in mine])
        cells = sorted({r["cells"] for r in mine})
        ax.set_xticks([1.0 / n for n in cells], labels=[f"1/{n}" for n in cells])
        ax.set_xticks([], minor=True)
        ax.set_xlabel("cell size h (unit body)")
        ax.set_title(f"{d}D", fontsize=10)
        ax.grid(which="both", color="0.92", lw=0.5)
    axes[0, 0].set_ylabel("RMS position error, max over one period")
    axes[0, -1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    fig.suptitle("Axis-aligned manufactured solution (A = 0.05, ppc 2, CFL 0.2): error against h",
                 fontsize=10)
    return save(fig, path)


def bars_figure(vib: dict, dyn: dict, profile, vrows, srows, drows, path: Path) -> Path:
    """2×2: vibrating bar com velocity; small-strain tip history; static profile; errors vs h."""
    from parmpm.exact.bars import (hanging_bar_dynamic_tip, hanging_bar_static,
                              hanging_bar_static_displacement, nominal_stress_1d)

    fig, axes = figure(2, 2, size=(10.0, 7.4))
    ax = axes[0, 0]
    if vib:
        key0 = next(iter(vib))
        t = np.linspace(0.0, vib[key0]["t"][-1], 800)
        from parmpm.exact.bars import vibrating_bar_com_velocity
        ax.plot(t, vibrating_bar_com_velocity(t, 0.1, VIB_L, 100.0, 1.0), color="k", lw=1.0,
                label="exact")
        for k, ((m, u), d) in enumerate(vib.items()):
            sl = slice(2 * k, None, 8)
            ax.plot(d["t"][sl], d["v"][sl], "o" if u == "usl" else "x", ms=3, mew=0.8,
                    color=COLOUR[m] if u == "usl" else "C4", mfc="none",
                    label=f"{LABEL[m]} {u.upper()}, 16 cells")
        ax.set_xlabel("t (s)")
        ax.set_ylabel("centre-of-mass velocity (m/s)")
        ax.set_title("Vibrating bar (E = 100, L = 25, mode 1)", fontsize=9)
        ax.legend(fontsize=7, loc="upper right")
    else:
        ax.set_axis_off()
    ax = axes[0, 1]
    if dyn:
        key0 = next(iter(dyn))
        t = np.linspace(0.0, dyn[key0]["t"][-1], 1000)
        ax.plot(t, 1e3 * hanging_bar_dynamic_tip(t, BAR_L, BAR_RHO, SMALL_G, BAR_E), color="k",
                lw=1.0, label="exact (d'Alembert, X = L)")
        for k, ((m, u, n), d) in enumerate(dyn.items()):
            sl = slice(3 * k, None, 6)
            ax.plot(d["t"][sl], 1e3 * d["u"][sl], "o" if k == 0 else "x", ms=3, mew=0.8, mfc="none",
                    color=COLOUR[m], label=f"{LABEL[m]} {u.upper()}, {n} cells")
        static_tip = SMALL_G * BAR_RHO * BAR_L ** 2 / (2 * BAR_E)
        ax.axhline(1e3 * static_tip, color="0.5", ls=":", lw=0.8, label="static tip")
        ax.set_xlabel("t (s)")
        ax.set_ylabel("tip displacement (mm, downward)")
        ax.set_title("Hanging bar, g = 1 m/s² switched on at t = 0 (small strain)", fontsize=9)
        ax.legend(fontsize=7, loc="lower right")
    else:
        ax.set_axis_off()
    ax = axes[1, 0]
    if profile is not None:
        (m, n), g = profile
        law = nominal_stress_1d("neo_hookean", BAR_E, 0.0)
        X = -g["x0"]  # from the support (the bar's top, x = 0)
        order = np.argsort(X)
        X, u, F = X[order], -(g["x"] - g["x0"])[order], g["F"][order]
        ex = hanging_bar_static(BAR_L, BAR_RHO, 1000.0, law)
        Xs = np.linspace(0.0, BAR_L, 200)
        ax.plot(Xs, hanging_bar_static_displacement(Xs, BAR_L, BAR_RHO, 1000.0, law), color="k",
                lw=1.0, label="exact u(X)")
        ax.plot(X, u, "o", ms=3, color=COLOUR[m], mfc="none", label=f"{LABEL[m]} u, {n} cells")
        ax.set_xlabel("reference distance from the support X (m)")
        ax.set_ylabel("displacement u (m, downward)")
        tw = ax.twinx()
        tw.plot(ex["X"], ex["stretch"], color="0.4", lw=1.0, ls="--", label="exact stretch λ(X)")
        tw.plot(X, F, "s", ms=2.5, color="C1", label=f"{LABEL[m]} stretch F")
        tw.set_ylabel("stretch λ")
        h1, l1 = ax.get_legend_handles_labels()
        h2, l2 = tw.get_legend_handles_labels()
        ax.legend(h1 + h2, l1 + l2, fontsize=7, loc="center right")
        ax.set_title("Hanging bar, g = 1000 m/s², static (ramped, damped)", fontsize=9)
    else:
        ax.set_axis_off()
    ax = axes[1, 1]
    curves = []
    shown = (("vibrating bar", vrows, "o", VIB_L, (("cpdi", "usl"), ("cpdi", "musl"))),
             ("static bar", srows, "s", BAR_L, (("cpdi", "usl"), ("cpgimp", "usl"))),
             ("dynamic bar", drows, "^", BAR_L, (("cpdi", "usl"), ("mpm", "musl"), ("bspline", "musl"))))
    for name, rows, marker, L, pairs in shown:
        for m, u in pairs:
            rs = sorted((r for r in rows if (r["method"], r["update"]) == (m, u) and r["cfl"] == 0.4
                         and r["error"] is not None), key=lambda r: r["h"])
            if len(rs) < 2:
                continue
            ax.loglog([r["h"] / L for r in rs], [r["error"] for r in rs], marker + ("-" if u == "usl" else "--"),
                      color=COLOUR[m], ms=4, lw=1.0, mfc="none" if u == "musl" else None,
                      label=f"{name}: {LABEL[m]} {u.upper()}")
            for r in rs:
                if r["note"]:
                    ax.annotate("separated", (r["h"] / L, r["error"]), fontsize=6, color=COLOUR[m],
                                xytext=(4, -2), textcoords="offset points")
            curves += [(r["h"] / L, r["error"]) for r in rs]
    if curves:
        hh, ee = zip(*curves)
        slope_guides(ax, hh, ee)
        ticks = [v for v in (0.005, 0.01, 0.02, 0.05, 0.1, 0.2) if min(hh) / 1.5 <= v <= max(hh) * 1.5]
        ax.set_xticks(ticks, labels=[f"{v:g}" for v in ticks])
        ax.set_xticks([], minor=True)
        ax.set_ylim(top=max(ee) * 300)
        ax.set_xlabel("h / L")
        ax.set_ylabel("relative error")
        ax.set_title("Bars: relative error against h", fontsize=9)
        ax.grid(which="major", color="0.92", lw=0.5)
        ax.legend(fontsize=6.5, loc="upper right", ncol=2, framealpha=0.9)
    else:
        ax.set_axis_off()
    return save(fig, path)


# --- main --------------------------------------------------------------------------------------
def main() -> int:
    ap = parser(__doc__)
    ap.add_argument("--only", default=None,
                    help="comma-separated groups to run: " + ", ".join(GROUPS))
    ap.add_argument("--methods", default=None,
                    help="comma-separated subset of " + ", ".join(METHODS) + " (default: all)")
    args = ap.parse_args()
    methods = method_keys(args.methods, METHODS) if args.methods else None
    groups = GROUPS if not args.only else tuple(g.strip() for g in args.only.split(",") if g.strip())
    bad = [g for g in groups if g not in GROUPS]
    if bad:
        raise SystemExit(f"--only: unknown group(s) {', '.join(bad)} (choose from {', '.join(GROUPS)})")
    comm = world()
    root = is_root(comm)
    out, figs = folders(args, "convergence")
    say = (lambda *a: print(*a, flush=True)) if root else (lambda *a: None)
    mrows, vrows, srows, drows = [], [], [], []
    vib, dyn, profile, seconds = {}, {}, None, {}
    t_start = time.perf_counter()
    with scratch_folder(comm, "parmpm-convergence-") as scratch:
        for d in (1, 2, 3):
            if f"manufactured-{d}d" not in groups:
                continue
            t0 = time.perf_counter()
            for m, u, n in manufactured_runs(d, args.quick, methods):
                r = manufactured_case(d, m, u, n, comm, scratch)
                mrows.append(r)
                say(f"manufactured {d}D {m:12s} {r['update']:4s} {n:4d} cells: error {r['error']:.3e} "
                    f"(at T {r['error_end']:.3e}), {r['steps']} steps, {r['wall_seconds']:.1f} s")
            if any(r["dim"] == d for r in mrows):
                seconds[f"manufactured-{d}d"] = time.perf_counter() - t0
        if "vibrating-bar" in groups:
            t0 = time.perf_counter()
            for m, u, n in vibrating_runs(args.quick, methods):
                r, hist = vibrating_case(m, u, n, comm, scratch)
                vrows.append(r)
                if n == 16 and m == "cpdi":
                    vib[(m, u)] = hist
                say(f"vibrating bar {m:12s} {u:4s} {n:3d} cells: com velocity error {r['error']:.3e}")
            seconds["vibrating-bar"] = time.perf_counter() - t0
        if "hanging-static" in groups:
            t0 = time.perf_counter()
            for m, u, n, cfl in static_runs(args.quick, methods):
                want = m == "cpdi" and u == "usl" and n == BAR_CELLS[0]
                r, state = static_case(m, u, n, cfl, comm, scratch, want)
                srows.append(r)
                if want and state is not None:
                    profile = ((m, n), state)
                say(f"hanging bar static {m:12s} {u:4s} {n:3d} cells, CFL {cfl}: tip {r['numerical']:.5f} "
                    f"m (exact {r['exact']:.5f}), error {r['error']:.3e} {r['note']}")
            seconds["hanging-static"] = time.perf_counter() - t0
        if "hanging-dynamic" in groups:
            t0 = time.perf_counter()
            for m, u, n in dynamic_runs(args.quick, methods):
                r, hist = dynamic_case(m, u, n, comm, scratch)
                drows.append(r)
                if n == BAR_CELLS[0] and u == DEFAULT_UPDATE[m] and m in ("cpdi", "mpm"):
                    dyn[(m, u, n)] = hist
                say(f"hanging bar dynamic {m:12s} {u:4s} {n:3d} cells: tip history error {r['error']:.3e}, "
                    f"peak {r['numerical']:.4e} m (exact {r['exact']:.4e})")
            seconds["hanging-dynamic"] = time.perf_counter() - t0
    total = time.perf_counter() - t_start

    series_orders(mrows, ("problem", "dim", "method", "update"))
    # the bars: a series is a method, update and CFL; the single MUSL / non-CP runs stay alone
    vbs = vrows + srows + drows
    series_orders(vbs, ("problem", "method", "update", "cfl"))
    if root:
        written = []
        if mrows:
            write_csv(out / "convergence.csv", mrows)
            written.append(out / "convergence.csv")
            written.append(manufactured_figure(mrows, figs / "convergence_manufactured.png"))
            say("\nmanufactured solution, RMS error (max over one period) and observed orders:")
            for key in sorted({(r["dim"], r["method"], r["update"]) for r in mrows}):
                s = sorted((r for r in mrows if (r["dim"], r["method"], r["update"]) == key),
                           key=lambda r: -r["h"])
                say(f"  {key[0]}D {key[1]:12s} {key[2]:4s}: "
                    + "  ".join(f"{r['cells']}:{r['error']:.3e}" for r in s) + "  orders "
                    + ", ".join(f"{r['order']:.2f}" for r in s if r["order"] is not None))
        if vbs:
            write_csv(out / "verification.csv", vbs)
            written.append(out / "verification.csv")
            written.append(bars_figure(vib, dyn, profile, vrows, srows, drows,
                                       figs / "verification_bars.png"))
        say(f"\n{len(mrows) + len(vbs)} runs in {total:.0f} s on {comm.Get_size()} rank(s) ("
            + ", ".join(f"{k} {v:.0f} s" for k, v in seconds.items()) + ")")
        for p in written:
            say(wrote(p))
    return 0


if __name__ == "__main__":
    main_guard(main)
