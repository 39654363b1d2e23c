"""USL against MUSL: accuracy, the CFL stability limit, and whether CPDI domains still tile a 1D bar.

Physics. The explicit MPM step maps particle momentum to the grid, solves the grid momentum
equation and maps back. *Update stress last* (USL) updates F and the stress with the velocity
gradient of that grid solution; *modified USL* (MUSL; Sulsky et al. 1995) first updates the
particle velocities and positions, maps the new particle momentum to the grid again and takes the
velocity gradient from that second grid field. parmpm's default (``method.update = "auto"``,
:mod:`parmpm.driver.simulation`) is USL for cpdi and MUSL for mpm, uGIMP, cpGIMP and bspline (FLIP or
APIC). Four checks, each method of ``study.METHODS`` with both updates (CPDI unscaled,
``method.lcr = none``):

1. **Accuracy.** (a) The 2D axis-aligned manufactured solution (:func:`study.manufactured_scene`,
   Uintah's parameters, one period, CFL 0.2, ppc 2, 8 → 64 cells); error: the largest over 41
   times of the RMS position error (m, :class:`study.ManufacturedError`). (b) The 1D vibrating bar
   (built-in ``vibrating_bar``: L = 25, E = 100, ρ = 1, v0 = 0.1, mode 1, 4 periods, CFL 0.4,
   ppc 2, 16 → 64 cells); error: the relative L2 error of the centre-of-mass velocity over time
   against the exact small-strain mode (``com_velocity_rel_l2_error``).
2. **Stability limit on CFL** (Δt = CFL·Δx / max(c + |v|)): ``time.cfl`` scanned upward from
   0.3 to 0.99 on the vibrating bar (16 cells) and the manufactured solution (16 cells, ppc 2).
   A run that blows up stops with a ``SimulationError`` (non-finite velocity or stress, or a
   particle or domain running off its patch), raised on every rank together: it is recorded
   "unstable". A finished run is *bounded* unless (vibrating bar, which starts with all its
   energy kinetic) its kinetic energy ever exceeds 1.05× the initial one (``energy_growth``),
   and *accurate* when it is bounded and its error is at most twice that of the same method and
   update at CFL 0.3. The limits reported are the largest scanned CFL below the first unbounded
   (resp. first unbounded-or-inaccurate) one.
3. **CPDI tiling in 1D** (docs/verification.md §4): with USL the domain corners move with the grid
   velocity interpolated at the corners, neighbours share corners, so the domain lengths
   ``2·a_p`` (:func:`parmpm.domain_sizes`) sum to the bar's length. The bar's length is measured
   from the discrete bar itself, ``(x + a)`` of the last particle minus ``(x − a)`` of the first
   (material order): comparing with the exact motion would mix the discretisation error in.
   Because a sum can hide a gap cancelled by an overlap, the largest gap or overlap between
   neighbouring domains, ``max |(x_{p+1} − a_{p+1}) − (x_p + a_p)|``, is reported too (in
   cells). Observed at every output time on the vibrating bar (16 cells, 4 periods) and the
   seed's 1D hanging bar (``hanging_bar_1d``: g = 1000 m/s² suddenly, stretch up to ~4.6,
   0.3 s). The deviation of the measured length from the exact vibrating-bar motion is in
   the CSV for context (``length_vs_exact_max``: discretisation error, not tiling).
4. **The seed's 2D hanging bar** (``hanging_bar``: g = 1000 m/s² suddenly, ppc 3, Δx = 0.1 m,
   unscaled, to 0.3 s, stopping at numerical separation): does the update change the outcome?

Found (full run, one core):

* Accuracy: where both are stable, USL and MUSL are equally accurate — the same error to 1–3 %
  for every method and resolution. Manufactured, ppc 2, 8 → 64 cells: CPDI 6.85e-3 → 8.44e-5 m
  (USL) and 6.94e-3 → 8.46e-5 (MUSL), cpGIMP 6.68e-3 → 7.73e-5 and 6.76e-3 → 7.74e-5 (order
  ~2.1), uGIMP 8.4e-3 → 3.9e-4 (both), mpm does not converge (1.1e-2, 8.7e-3, 1.7e-2, 2.8e-2).
  Vibrating bar, 16 → 64 cells: 2.1e-2 → 1.6–1.9e-3 for CPDI, cpGIMP, uGIMP, either update;
  mpm reaches 2.8e-3 at 32 cells, and at 64 cells blows up with USL (step 71) and gives 0.12
  with MUSL.
* CFL, vibrating bar (16 cells): MUSL stays bounded and accurate up to 0.99 (the top of the
  scan) for every method; its error even falls with Δt. USL's limit: CPDI 0.8 (at 0.85 the
  kinetic energy grows to 3× its initial value, at 0.99 to 25×), cpGIMP and uGIMP 0.6 (energy
  ×5 at 0.7), mpm 0.75 (blows up from 0.8). CPDI behaves the same on a bar held at both ends
  (bounded at 0.8, energy ×15 at 0.9; checked by hand): not a free-end effect. Manufactured
  (16 cells, one period): both updates bounded and accurate to 0.99 for CPDI, cpGIMP, uGIMP (to
  0.99 over four periods too, checked by hand); mpm with USL is inaccurate beyond 0.85.
* Tiling: with USL the CPDI domain lengths sum to the bar's length to round-off (relative
  1.7e-15 and 1.4e-15 at worst; neighbouring domains meet to 8e-14 Δx) on both bars. With MUSL
  they do not: 2.5e-6 relative (gaps or overlaps of 1.3e-4 Δx) on the vibrating bar, and on
  the seed's 1D bar the mismatch grows to 22 % with gaps of 1.5 Δx until the bar separates
  (0.138 s; with USL it holds). The position comes from the first grid solve, the domain
  stretch from the second.
* The seed's 2D bar: CPDI with USL holds (largest stretch 4.6); with MUSL it does not separate
  but runs away — stretch 5.9 at 0.12 s, 8.0 at 0.26 s, when a particle reaches the grid's
  bottom 2 m below the bar. uGIMP and cpGIMP separate with either update, MUSL 17–23 % sooner;
  mpm separates with MUSL (0.038 s) and blows up with USL (0.049 s).
* Quadratic B-splines (FLIP ``bspline``, APIC ``bspline_apic``; default MUSL): USL and MUSL
  equally accurate to 32 cells (manufactured, mirror faces: FLIP 8.99e-3 → 5.57e-4 MUSL,
  8.90e-3 → 5.58e-4 USL; APIC 4.9e-3 → 3.3e-4), apart at 64 cells where the B-spline stalls
  (FLIP 3.61e-4 MUSL, 2.35e-4 USL; APIC USL 2.18e-4); vibrating bar (clamped face) 16 → 64
  cells 0.035 → 0.0021 FLIP, 0.018 → 0.0011 APIC, second order, USL and MUSL within 1 %; with
  the held nodes used before 0.31 → 0.072 and 0.29 → 0.071, first order). CFL: FLIP with USL is bounded to 0.9
  on the vibrating bar and blows up from 0.95; FLIP MUSL and APIC with either update are
  bounded and accurate to 0.99 on both problems (APIC's largest KE growth 1.0004). The seed's
  2D bar separates with every B-spline run: FLIP 0.049 s (USL) / 0.079 s (MUSL), APIC
  0.052 / 0.081 s, at stretch 3.3–3.8 — MUSL later, unlike uGIMP and cpGIMP.
  In the run that measured these (issue 18, parmpm/ under concurrent change), two older rows
  differ from the text above: mpm USL on the seed's 2D bar separated at 0.039 s instead of blowing up, and
  CPDI MUSL separated at 0.215 s (stretch 5.1) instead of running
  off the grid.
* Defaults: the evidence supports the current ones. MUSL for mpm, uGIMP, cpGIMP: as accurate,
  and stable to CFL 0.99 where USL needs ≤ 0.6–0.75. USL for CPDI: the exact 1D tiling, and the
  seed's bar holding, depend on it; MUSL would lift CPDI's CFL limit from 0.8 to 0.99 but lets
  the large-deformation bar separate (1D) or run away (2D). The default CFL 0.4 is inside
  USL-CPDI's limit; a scene that raises ``time.cfl`` above 0.8 with CPDI should expect
  trouble.

Outputs: ``update_order.csv`` (one row per run, ``study`` = accuracy | cfl | tiling | seed_bar, plus
``cfl_limit`` rows) in ``--out`` (default ``run_scripts/out/update_order``) and ``update_order.png``
in ``--out`` too (``make figures`` passes ``--figures docs/figures``): accuracy against resolution
(manufactured, vibrating bar), the tiling residual against time, the two CFL scans, and a table of
the CFL limits, tiling residuals and 2D-bar outcomes; solid lines USL, dashed MUSL, a colour per
method.

Runtime, one core: full ~3 min (accuracy up to 64 cells, 2 × 132 CFL runs, 4 tiling runs, 12
2D bars; with the B-splines 95 s, 2 min 47 s with the other core busy); ``--quick`` (mpm, uGIMP, cpGIMP,
CPDI only: manufactured 8, 16 cells; bar 16, 32 cells; CFL scans of 6 values, the
manufactured one at 8 cells; tiling; the 2D bar with cpGIMP and CPDI) ~15 s;
``--methods bspline,bspline_apic`` runs those alone (no tiling cases). Results are
identical on any number of ranks (only ``wall_seconds`` differs)::

    python run_scripts/studies/update_order.py                   # full study, figure beside the CSV
    python run_scripts/studies/update_order.py --quick           # the smoke test's mode
    mpirun -n 2 python run_scripts/studies/update_order.py --quick
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
                   method_keys, parser, run_case, save, scene_with, scratch_folder, world,
                   write_csv, wrote)

METHODS = METHOD_KEYS  # every registered method (study.METHODS); ``--methods`` picks a subset
QUICK_METHODS = ("mpm", "ugimp", "cpgimp", "cpdi")  # --quick: the smoke test's methods
UPDATES = ("usl", "musl")
TITLES = {m: REGISTRY[m].label for m in METHODS}
COLOURS = {m: REGISTRY[m].colour for m in METHODS}
STYLE = {"usl": "-", "musl": "--"}
DEFAULT = {m: REGISTRY[m].update for m in METHODS}  # what method.update = "auto" gives
CFL_FULL = (0.3, 0.4, 0.5, 0.6, 0.7, 0.75, 0.8, 0.85, 0.9, 0.95, 0.99)
CFL_QUICK = (0.3, 0.5, 0.7, 0.8, 0.9, 0.99)
ACCURATE = 2.0   # accurate: error <= ACCURATE x the error at the scan's smallest CFL
BOUNDED = 1.05   # bounded (vibrating bar): max_t KE(t) <= BOUNDED x KE(0)
BAR_LEN = 25.0   # the vibrating bar's length (built-in scene)
HANG_END = 0.3   # s, the seed's hanging bar
# the scenes' own CFL numbers
SCENE_CFL = {"manufactured": 0.2, "vibrating_bar": 0.4, "hanging_bar": 0.4, "hanging_bar_2d": 0.4}
BAR_SAMPLE_EVERY = 5  # vibrating bar: metrics every 5 steps (each sample also counts pieces)
KEYS = ("study", "case", "problem", "method", "update", "default_update", "cells", "ppc", "cfl",
        "status", "failure", "error", "energy_growth", "error_ratio", "error_measure",
        "cfl_bounded_limit", "cfl_accurate_limit", "tiling_sum_rel_max", "tiling_gap_max_cells",
        "length_vs_exact_max", "outcome", "separation_time", "max_stretch", "particles", "steps",
        "end_time", "wall_seconds")
MEASURES = {"manufactured": "max over t of RMS |x - phi(X,t)| (m)",
            "vibrating_bar": "relative L2 error of the centre-of-mass velocity"}


@dataclass(frozen=True)
class Case:
    study: str      # accuracy | cfl | tiling | seed_bar
    problem: str    # manufactured | vibrating_bar | hanging_bar (1D) | hanging_bar_2d
    method: str
    update: str
    cells: int
    ppc: int = 2
    cfl: float | None = None  # None: the problem's default (manufactured 0.2, bars 0.4)

    @property
    def id(self) -> str:
        c = f"_cfl{self.cfl:g}" if self.cfl is not None else ""
        return f"{self.study}_{self.problem}_{self.method}_{self.update}_n{self.cells}{c}"

    def scene_and_observers(self):
        """(scene or built-in name, overrides for run_case, observers)."""
        common = [*REGISTRY[self.method].overrides(), f"method.update={self.update}",
                  "method.lcr=none"]
        if self.cfl is not None:
            common.append(f"time.cfl={self.cfl!r}")
        chosen = len(REGISTRY[self.method].overrides())  # the scene below has the method already
        observers = [Tiling(self.problem)] if self.study == "tiling" else []
        if self.problem == "vibrating_bar":
            observers.append(Energy())
        if self.problem == "manufactured":
            observers.append(ManufacturedError())
            base = manufactured_scene(2, self.cells, self.method, ppc=self.ppc)
            return scene_with(base, common[chosen:] + manufactured_sampling(40)), [], observers
        if self.problem == "vibrating_bar":
            h = BAR_LEN / self.cells
            over = common + [f"bodies.0.ppc={self.ppc}", f"grid.cell_size={h!r}",
                             f"grid.cells={self.cells + 4}",  # the scene's clamped face at X = 0
                             f"grid.patch_size={max(8, (self.cells + 6) // 3)}", "output.every=0.25",
                             f"metrics.every_steps={BAR_SAMPLE_EVERY}"]
            return "vibrating_bar", over, observers
        over = common + [f"bodies.0.ppc={self.ppc}", f"time.end={HANG_END}", "output.every=0.005",
                         "metrics.stop_on_separation=true"]
        if self.problem == "hanging_bar_2d":
            return "hanging_bar", over, [Stretch()]
        return "hanging_bar_1d", over, observers


class Energy:
    """Observer (collective): the total kinetic energy at every output time (ordered sums: the
    same on any number of ranks). The vibrating bar starts with all its energy kinetic, so
    ``max_t KE(t) / KE(0) > 1`` means the scheme created energy."""

    def __init__(self):
        self.ke: list[float] = []

    def __call__(self, sim) -> None:
        self.ke.append(sim.totals()["kinetic_energy"])

    @property
    def growth(self) -> float:
        return max(self.ke) / self.ke[0]


class Stretch:
    """Observer (collective): output times and the largest axial stretch over all ranks (the last
    time a run was seen alive, and how far it had stretched, when it stops with an error)."""

    def __init__(self):
        self.t: list[float] = []
        self.stretch: list[float] = []

    def __call__(self, sim) -> None:
        from decomposition import allreduce_max

        s = sim.axial_stretch()
        self.t.append(float(sim.t))
        self.stretch.append(float(allreduce_max(sim.comm, np.array([s.max() if s.size else 0.0]))[0]))


class Tiling:
    """Observer (collective; 1D CPDI): at every output time, the sum of the particle domain
    lengths ``2a_p`` against the discrete bar's length ``(x + a)_last − (x − a)_first`` (material
    order) and the largest gap or overlap between neighbouring domains; gathered in global-id
    order on rank 0, so the numbers are the same on any number of ranks."""

    def __init__(self, problem: str):
        self.problem = problem
        self.end = math.nan  # the scheduled end time
        self.t: list[float] = []
        self.sum_rel: list[float] = []
        self.gap: list[float] = []
        self.vs_exact: list[float] = []

    def __call__(self, sim) -> None:
        import parmpm

        P = sim.particles
        self.end = sim.state.data["time"]["end"]
        a = 0.5 * parmpm.domain_sizes(1, sim.state.disc.method, sim.state.disc.lcr, P.F, P.r0, P.lh0,
                                      corners=P.corners)
        g = sim.gather({"x": P.x[:, 0].copy(), "x0": P.x0[:, 0].copy(), "a": a})
        out = None
        if g is not None:
            order = np.argsort(g["x0"], kind="stable")
            x, a = g["x"][order], g["a"][order]
            total = float(np.sum(2.0 * a))
            length = float((x[-1] + a[-1]) - (x[0] - a[0]))
            gaps = (x[1:] - a[1:]) - (x[:-1] + a[:-1])
            h = float(sim.state.disc.h[0])
            exact = math.nan
            if self.problem == "vibrating_bar":
                vib = sim.state.data["bodies"][0]["vibration"]
                mat = next(iter(sim.state.data["materials"].values()))
                c = math.sqrt(mat["youngs_modulus"] / mat["density"])
                beta = (2 * vib["mode"] - 1) * math.pi / (2 * BAR_LEN)
                w = c * beta
                exact = BAR_LEN + vib["amplitude"] / w * math.sin(w * sim.t) * math.sin(beta * BAR_LEN)
            out = (abs(total - length) / length, float(np.max(np.abs(gaps))) / h,
                   abs(length - exact) / BAR_LEN if math.isfinite(exact) else math.nan)
        out = sim.comm.bcast(out, root=0)
        self.t.append(float(sim.t))
        self.sum_rel.append(out[0])
        self.gap.append(out[1])
        self.vs_exact.append(out[2])


def cases(quick: bool, methods=None) -> list[Case]:
    """Every case of the study (``methods``: a subset of method keys; the CPDI tiling cases run
    when cpdi is among them)."""
    methods = methods or (QUICK_METHODS if quick else METHODS)
    out = []
    man_cells = (8, 16) if quick else (8, 16, 32, 64)
    bar_cells = (16, 32) if quick else (16, 32, 64)
    for m in methods:
        for u in UPDATES:
            out += [Case("accuracy", "manufactured", m, u, n) for n in man_cells]
            out += [Case("accuracy", "vibrating_bar", m, u, n) for n in bar_cells]
    cfls = CFL_QUICK if quick else CFL_FULL
    for m in methods:
        for u in UPDATES:
            out += [Case("cfl", "vibrating_bar", m, u, 16, cfl=c) for c in cfls]
            out += [Case("cfl", "manufactured", m, u, 8 if quick else 16, cfl=c) for c in cfls]
    for u in UPDATES if "cpdi" in methods else ():
        out.append(Case("tiling", "vibrating_bar", "cpdi", u, 16))
        out.append(Case("tiling", "hanging_bar", "cpdi", u, 10, ppc=3))
    for m in (tuple(m for m in methods if m in ("cpgimp", "cpdi")) if quick else methods):
        out += [Case("seed_bar", "hanging_bar_2d", m, u, 10, ppc=3) for u in UPDATES]
    return out


def run_one(case: Case, comm, scratch: Path) -> dict:
    from parmpm import SimulationError

    r = dict.fromkeys(KEYS)
    r.update(study=case.study, case=case.id, problem=case.problem, method=case.method,
             update=case.update, default_update=DEFAULT[case.method], cells=case.cells,
             ppc=case.ppc, cfl=case.cfl if case.cfl is not None else SCENE_CFL[case.problem],
             error_measure=MEASURES.get(case.problem))
    scene, overrides, observers = case.scene_and_observers()
    try:
        summary, wall = run_case(scene, overrides, comm=comm, observers=observers,
                                 out_dir=scratch / case.id)
    except SimulationError as exc:  # raised on every rank together, with the same message
        r.update(status="unstable" if case.study in ("cfl", "accuracy") else "stopped",
                 failure=str(exc).split(";")[0][:120])
        st = [o for o in observers if isinstance(o, Stretch)]
        if st and st[0].t:
            r.update(outcome="failed", end_time=st[0].t[-1], max_stretch=max(st[0].stretch))
        return r
    if summary["update"] != case.update:
        raise RuntimeError(f"{case.id}: ran {summary['update']}, asked for {case.update}")
    r.update(status="ok", particles=summary["particles"], steps=summary["steps"],
             end_time=summary["time"], wall_seconds=wall)
    man = [o for o in observers if isinstance(o, ManufacturedError)]
    if man:
        r["error"] = man[0].rms_max
    elif case.problem == "vibrating_bar":
        r["error"] = summary["metrics"]["com_velocity_rel_l2_error"]
        r["energy_growth"] = next(o for o in observers if isinstance(o, Energy)).growth
    if r["error"] is not None and not math.isfinite(r["error"]):
        r.update(status="unstable", failure="non-finite error")
    if summary["metrics"].get("separated") is not None:  # the hanging bars
        mets = summary["metrics"]
        r.update(outcome="separated" if mets["separated"] else "held",
                 separation_time=mets["separation_time"], max_stretch=mets["max_stretch"])
    tiles = [o for o in observers if isinstance(o, Tiling)]
    if tiles:
        tl = tiles[0]
        r.update(tiling_sum_rel_max=max(tl.sum_rel), tiling_gap_max_cells=max(tl.gap),
                 length_vs_exact_max=max(tl.vs_exact) if case.problem == "vibrating_bar" else None)
        r["_history"] = tl
    return r


def cfl_limits(rows: list[dict]) -> list[dict]:
    """Per (problem, method, update) of the CFL scan: ``error_ratio`` on each row, and one
    ``cfl_limit`` row with the largest stable and the largest accurate CFL (below the first
    failure, scanning upward)."""
    out = []
    scan = [r for r in rows if r["study"] == "cfl"]
    for problem in ("vibrating_bar", "manufactured"):
        for m in METHODS:
            for u in UPDATES:
                mine = sorted((r for r in scan
                               if (r["problem"], r["method"], r["update"]) == (problem, m, u)),
                              key=lambda r: r["cfl"])
                if not mine:
                    continue
                ref = mine[0]["error"] if mine[0]["status"] == "ok" else None
                stable = accurate = None
                stable_open = accurate_open = True
                for r in mine:
                    ok = r["status"] == "ok"
                    if ok and ref:
                        r["error_ratio"] = r["error"] / ref
                    bounded = ok and (r["energy_growth"] is None or r["energy_growth"] <= BOUNDED)
                    stable_open = stable_open and bounded
                    accurate_open = (accurate_open and bounded and ref is not None
                                     and r["error"] <= ACCURATE * ref)
                    if stable_open:
                        stable = r["cfl"]
                    if accurate_open:
                        accurate = r["cfl"]
                lim = dict.fromkeys(KEYS)
                lim.update(study="cfl_limit", case=f"cfl_limit_{problem}_{m}_{u}", problem=problem,
                           method=m, update=u, default_update=DEFAULT[m], cells=mine[0]["cells"],
                           ppc=mine[0]["ppc"], cfl_bounded_limit=stable, cfl_accurate_limit=accurate,
                           error_measure=(f"bounded: no blow-up and (bar) max KE <= {BOUNDED:g} KE(0);"
                                          f" accurate: bounded and error <= {ACCURATE:g} x error at"
                                          f" CFL {mine[0]['cfl']:g}"))
                out.append(lim)
    return out


# --- figure ------------------------------------------------------------------------------------
def chart(rows: list[dict], histories: dict, path: Path) -> Path:
    from matplotlib.lines import Line2D

    fig, axes = figure(2, 3, size=(11.8, 7.0))
    for k, problem in enumerate(("manufactured", "vibrating_bar")):
        ax = axes[0, k]
        acc = [r for r in rows
               if r["study"] == "accuracy" and r["problem"] == problem and r["status"] == "ok"]
        for m in METHODS:
            for u in UPDATES:
                line = sorted((r for r in acc if (r["method"], r["update"]) == (m, u)),
                              key=lambda r: r["cells"])
                if line:
                    ax.plot([r["cells"] for r in line], [r["error"] for r in line], STYLE[u],
                            color=COLOURS[m], marker="o", ms=3.5, lw=1.2)
        failed = [r for r in rows if r["study"] == "accuracy" and r["problem"] == problem
                  and r["status"] != "ok"]
        if failed:
            top = max(r["error"] for r in acc)
            ax.plot([r["cells"] for r in failed], [1.5 * top] * len(failed), "x", ms=7, mew=1.5,
                    color="k")
            for r in failed:
                ax.annotate(f"{TITLES[r['method']]} {r['update'].upper()} blew up",
                            (r["cells"], 1.5 * top), textcoords="offset points", xytext=(-4, -3),
                            ha="right", va="top", fontsize=6.5)
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("cells across the body", fontsize=8)
        ax.set_ylabel(("RMS position error, max over t (m)" if problem == "manufactured"
                       else "centre-of-mass velocity, rel. L2 error"), fontsize=8)
        ax.set_title("2D manufactured solution (CFL 0.2, ppc 2)" if problem == "manufactured"
                     else "1D vibrating bar, 4 periods (CFL 0.4, ppc 2)", fontsize=9)
        ax.grid(True, which="major", lw=0.3, alpha=0.5)
        ax.tick_params(labelsize=7)
        # the CFL scans
        ax = axes[1, k]
        scan = [r for r in rows if r["study"] == "cfl" and r["problem"] == problem]
        top = max((r["error"] for r in scan if r["status"] == "ok"), default=1.0)
        for m in METHODS:
            for u in UPDATES:
                line = sorted((r for r in scan if (r["method"], r["update"]) == (m, u)),
                              key=lambda r: r["cfl"])
                ok = [r for r in line if r["status"] == "ok"]
                ax.plot([r["cfl"] for r in ok], [r["error"] for r in ok], STYLE[u], color=COLOURS[m],
                        marker="o", ms=3, lw=1.2)
                bad = [r for r in line if r["status"] != "ok"]
                if bad:
                    ax.plot([r["cfl"] for r in bad], [2.5 * top] * len(bad), "x", color=COLOURS[m],
                            ms=7, mew=1.5 if u == "usl" else 0.8)
        ax.set_yscale("log")
        if any(r["status"] != "ok" for r in scan):
            ax.axhline(1.6 * top, color="0.5", lw=0.6, ls=":")
            ax.text(0.01, 1.7 * top, "× unstable (run stopped)", transform=ax.get_yaxis_transform(),
                    fontsize=7, color="0.3")
            ax.set_ylim(top=4 * top)
        ax.set_xlabel("CFL number (Δt = CFL·Δx / max(c + |v|))", fontsize=8)
        ax.set_ylabel("error (as above)", fontsize=8)
        cells = scan[0]["cells"] if scan else 0
        ax.set_title(f"CFL scan: {'manufactured' if problem == 'manufactured' else 'vibrating bar'},"
                     f" {cells} cells", fontsize=9)
        ax.grid(True, which="major", lw=0.3, alpha=0.5)
        ax.tick_params(labelsize=7)
    # tiling
    ax = axes[0, 2]
    tiny = 1e-17  # log axis: exact zeros drawn at this floor
    for (problem, u), tl in sorted(histories.items()):
        colour = "tab:blue" if problem == "vibrating_bar" else "tab:brown"
        t = np.asarray(tl.t) / tl.end
        ax.plot(t, np.maximum(tl.sum_rel, tiny), STYLE[u], color=colour, lw=1.2)
        ax.plot(t, np.maximum(tl.gap, tiny), STYLE[u], color=colour, lw=0.6, alpha=0.6)
    ax.set_yscale("log")
    ax.set_xlabel("t / end time (vibrating bar 40 s, hanging bar 0.3 s)", fontsize=8)
    ax.set_ylabel("|Σ 2a_p − L| / L (thick), max gap / Δx (thin)", fontsize=8)
    ax.set_title("1D CPDI tiling: domain lengths vs bar length", fontsize=9)
    ax.grid(True, which="major", lw=0.3, alpha=0.5)
    ax.tick_params(labelsize=7)
    ax.legend(handles=[Line2D([], [], color="tab:blue", label="vibrating bar (16 cells)"),
                       Line2D([], [], color="tab:brown",
                              label="hanging bar, g = 1000 (10 cells, ppc 3)"),
                       Line2D([], [], color="k", ls="-", label="USL"),
                       Line2D([], [], color="k", ls="--", label="MUSL")], fontsize=7, loc="center right")
    # table of limits
    ax = axes[1, 2]
    ax.axis("off")
    shown = [m for m in METHODS if any(r["method"] == m for r in rows)]
    w = max(len(TITLES[m]) for m in shown)
    lims = [r for r in rows if r["study"] == "cfl_limit"]
    text = ["largest CFL bounded / accurate (* = default;",
            " 0.99 = top of the scan; bounded: no blow-up and bar",
            " KE ≤ 1.05 KE(0); accurate: also error ≤ 2× at 0.3)"]
    for problem in ("vibrating_bar", "manufactured"):
        text.append("vibrating bar:" if problem == "vibrating_bar" else "manufactured 2D:")
        for m in shown:
            cells = []
            for u in UPDATES:
                r = next((x for x in lims
                          if (x["problem"], x["method"], x["update"]) == (problem, m, u)), None)
                if r is None:
                    continue
                def f(v):
                    return "<0.3" if v is None else f"{v:g}"
                star = "*" if DEFAULT[m] == u else " "
                cells.append(f"{u.upper():4s}{star} {f(r['cfl_bounded_limit']):>5s}/"
                             f"{f(r['cfl_accurate_limit']):<5s}")
            text.append(f"  {TITLES[m]:{w}s} " + "   ".join(cells))
    tiles = [r for r in rows if r["study"] == "tiling" and r["status"] == "ok"]
    text.append("1D CPDI tiling, max_t |Σ2a − L|/L (max gap):")
    for r in tiles:
        sep = ", separated" if r["outcome"] == "separated" else ""
        text.append(f"  {r['problem'].replace('_', ' '):13s} {r['update'].upper():4s} "
                    f"{r['tiling_sum_rel_max']:.1e} ({r['tiling_gap_max_cells']:.1e} Δx){sep}")
    seed = [r for r in rows if r["study"] == "seed_bar"]
    if seed:
        text.append("2D hanging bar (seed), ppc 3, to 0.3 s:")
        for r in seed:
            if r["outcome"] == "separated":
                what = f"separated {r['separation_time']:.3f} s"
            elif r["outcome"] == "held":
                what = "held"
            elif (r["failure"] or "").startswith("non-finite"):
                what = f"blew up {r['end_time']:.3f} s"
            else:
                what = f"off grid {r['end_time']:.3f} s"
            text.append(f"  {TITLES[r['method']]:{w}s} {r['update'].upper():5s}{what:19s} "
                        f"stretch {r['max_stretch']:.2g}")
    ax.text(-0.05, 1.02, "\n".join(text), va="top", ha="left", family="monospace",
            fontsize=6.8 if len(text) <= 30 else 6.8 * 30 / len(text), transform=ax.transAxes)
    handles = [Line2D([], [], color=COLOURS[m], marker="o", ms=3.5, label=TITLES[m]) for m in shown]
    handles += [Line2D([], [], color="k", ls=STYLE[u], label=u.upper()) for u in UPDATES]
    axes[0, 0].legend(handles=handles, fontsize=7, loc="lower left", ncol=2)
    return compact_png(save(fig, path))


def main() -> int:
    ap = parser(__doc__)
    ap.add_argument("--methods", default=None, help="comma-separated subset of "
                    + ", ".join(METHODS) + " (default: all; --quick: " + ", ".join(QUICK_METHODS) + ")")
    args = ap.parse_args()
    methods = method_keys(args.methods, METHODS) if args.methods else None
    comm = world()
    root = is_root(comm)
    out, figs = folders(args, "update_order")
    rows, histories = [], {}
    t0 = time.perf_counter()
    with scratch_folder(comm, "parmpm-update-") as scratch:
        for case in cases(args.quick, methods):
            r = run_one(case, comm, scratch)
            hist = r.pop("_history", None)
            if hist is not None:
                histories[(case.problem, case.update)] = hist
            rows.append(r)
            if root:
                what = (f"error {r['error']:.4g}" if r["status"] == "ok" and r["error"] is not None
                        else r["status"] if r["status"] != "ok" else "")
                if r["tiling_sum_rel_max"] is not None:
                    what += (f" tiling |Σ2a-L|/L {r['tiling_sum_rel_max']:.2e}, "
                             f"gap {r['tiling_gap_max_cells']:.2e} cells")
                if r["outcome"]:
                    what += f" {r['outcome']}, max stretch {r['max_stretch']:.3g}"
                if r["failure"]:
                    what += f" ({r['failure'][:50]})"
                print(f"{case.id:50s} {what}", flush=True)
    rows += cfl_limits(rows)
    write_csv(out / "update_order.csv", rows, comm)
    if root:
        print("CFL limits (bounded / accurate), * = default:")
        for r in rows:
            if r["study"] == "cfl_limit":
                star = "*" if r["update"] == r["default_update"] else " "
                print(f"  {r['problem']:13s} {r['method']:12s} {r['update']:4s}{star} "
                      f"{r['cfl_bounded_limit']} / {r['cfl_accurate_limit']}")
        path = chart(rows, histories, figs / "update_order.png")
        print(f"{len(rows)} rows in {time.perf_counter() - t0:.0f} s on {comm.Get_size()} rank(s)")
        print(f"wrote {out / 'update_order.csv'}")
        print(wrote(path))
    return 0


if __name__ == "__main__":
    main_guard(main)
