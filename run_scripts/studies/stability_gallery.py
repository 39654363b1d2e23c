"""Numerical separation gallery: the self-weighted bar with mpm, uGIMP, cpGIMP and CPDI (± l_cr).

Physics. The self-weighted elastic bar of Sadeghirad, Brannon & Burghardt (2011): a 1 m × 1 m
neo-Hookean bar (E = 1 MPa, ν = 0.3, ρ = 1050 kg/m³; plane strain) hangs from grid nodes (y ≥ 0)
held vertically only (a roller, as published); gravity of 1000 m/s² is switched on at t = 0 and
the bar overshoots its static stretch, peaking (largest stretch ≈ 4.4, at the top) at t ≈ 0.09 s
(unscaled CPDI, ppc 3). Built-in scenes ``hanging_bar`` (2D), ``hanging_bar_1d``,
``hanging_bar_3d``. A bar is *numerically separated* (``metrics.kind = "hanging_bar"``) when the
graph "particles linked through grid nodes they both weight" has more than one component: the
pieces no longer exchange momentum. This script also notes when the bar *tears off its support*:
no particle's support (domain corners; the particle itself for mpm) reaches above ``−Δx``, so no
particle weights a held node.

Cases (``--cases`` picks by glob over the ids ``<dim>d_<method>_ppc<ppc>_dx<Δx>[_<support>_t<end>]``):
methods mpm, ugimp, cpgimp, cpdi (unscaled), cpdi with l_cr = 5.0·Δx/3, 1.8·Δx/3, 1.2·Δx/3 and
2·Δx (the default); 2D at ppc (particles per cell per axis) 2, 3, 4 with Δx = 0.1 m and 0.2 m; 1D
at ppc 2 (Δx = 0.1 m); 3D at ppc 2 with Δx = 0.2 m (the built-in 3D grid: 5 cells across the bar;
at 0.1 m a single 3D cpdi run to 0.3 s takes ~2 min, too long for this study). Every run goes to
0.3 s with ``metrics.stop_on_separation = true``: a separated piece falls freely at 1000 m/s²,
drops through the 2 m of grid below the bar within ~0.06 s and stops the run with "left the
grid" (which loses the summary); what this study measures is the *first* separation, and after it
the runs are no longer the bar of the paper. Runs that do not separate are unaffected and reach
0.3 s. Unscaled cpdi and cpgimp domains are unbounded: if one outgrows the ghost layer (the step's
reach check stops the run, or the observer sees a reach larger than ``grid.ghost`` at a sample),
the case is rerun with ``grid.ghost`` one cell beyond the reach (printed; the CSV's ``ghost``).

The l_cr series (ids ending ``_roller_t1`` / ``_clamped_t1``): CPDI with κ = 1.0, 1.2, 1.5, 1.8,
2.2, 2.6, 3.0, 4.0, 5.0, 6.0 (= 2·Δx) and unscaled, on the roller and clamped (both components of
the same nodes held), at (Δx, ppc) = (0.1 m, 3), (0.1 m, 2), (0.2 m, 3), each to 1 s; the CSV's
``corner_growth`` is the longest centre-to-corner vector seen (at the frames) over its rest
length, so an unscaled run gives κ* = 3·growth·√2/(2·ppc) below which a cap engages. Chart
``gallery_lcr_separation.png``: stretch at separation and separation time against κ.

How we read "l_cr = κ·Δx/3": ``method.lcr = "κdx/3"``, a cap of κ·Δx/3 metres on every
centre-to-corner vector of a CPDI domain (Δx the grid cell). At rest that vector is
√d·Δx/(2·ppc) long (2D, ppc 3: √2·Δx/6 = 0.707·Δx/3), so only κ < 3√d/(2·ppc) caps domains at
rest: κ < 0.71 in 2D at ppc 3 (1.06 at ppc 2, 0.53 at ppc 4; 0.75 in 1D, 1.30 in 3D at ppc 2).
None of κ = 5.0, 1.8, 1.2, 6 (= 2·Δx) does in 1D/2D — the CSV's ``lcr_over_rest_corner`` is
> 1 — so the cap engages only once the domain has stretched by that ratio (2D ppc 3: 1.70× for
1.2, 2.55× for 1.8, 7.07× for 5.0, 8.49× for 2dx); in 3D at ppc 2, κ = 1.2 (ratio 0.92) caps
every domain from the start. The bar's corner vectors grow by at most 3.7× (ppc 3, unscaled),
so at Δx = 0.1 m, ppc ≥ 3, l_cr = 5.0·Δx/3 and 2·Δx never engage: bit for bit the unscaled run.

Expected (the seed) and found, 2D, Δx = 0.1 m, roller; separation time in s (axial stretch then):

    method          ppc 2                         ppc 3             ppc 4
    mpm             0.030 (2.3)                   0.037 (2.9)       0.045 (4.6)
    ugimp           0.038 (2.4)                   0.043 (3.1)       0.062 (4.1)
    cpgimp          0.043 (2.4)                   0.057 (3.5)       0.073 (5.3)
    cpdi            tears off 0.095, splits 0.127 holds (max 4.42)  holds (max 4.46)
    cpdi 5.0·Δx/3   tears off 0.095, splits 0.127 holds = unscaled  holds = unscaled
    cpdi 1.8·Δx/3   0.053 (2.8)                   0.080 (4.1)       holds (max 4.46)
    cpdi 1.2·Δx/3   0.050 (2.8)                   0.063 (3.3)       holds (max 4.30)
    cpdi 2·Δx       = unscaled                    = unscaled        = unscaled

* mpm, uGIMP, cpGIMP separate — as the seed says — in every case (1D, 2D, 3D, every ppc and
  Δx), in 1D and 2D mpm first, then uGIMP (its fixed half-width bridges a wider gap between
  particle rows), then cpGIMP (its half-widths grow with F_yy); in 3D at Δx = 0.2 m uGIMP first
  (0.043 s), then mpm (0.049), cpGIMP (0.054); during the first stretch upswing.
* Unscaled CPDI holds at ppc 3 and 4 (and in 1D), as the seed says. At ppc 2 it does not split
  while hanging, but it does not hold either: at ~0.095 s no particle's domain reaches a held
  node any more, the bar tears off its support and the falling bar then splits (0.127 s). The
  seed's "holds at ppc 2" is not reproduced (on either support).
* Domain scaling, the seed's order (1.2 earliest, 1.8 later, 5.0 no or late) holds at ppc 2 and 3
  and in 1D and 3D; at ppc 4, 1.8·Δx/3 and 1.2·Δx/3 hold to 0.3 s.
* The l_cr series (full study, 1 s): on the roller at ppc 3 the unscaled bar's corner vectors
  grow at most 3.19× (Δx = 0.1 m; 3.12× at 0.2 m), κ* = 2.26 (2.20): κ ≤ 1.8 separates
  (0.062–0.080 s at stretch 3.3–4.1), κ ≥ 2.2 holds to 1 s. Clamped, the top corners keep
  straining (unscaled: stretch 11, corners 9.7× by 1 s): κ = 2.6, 3.0 separate at 0.59, 0.65 s,
  4.0 and 5.0 hold to 1 s; at Δx = 0.2 m clamped every κ ≥ 2.6 and the unscaled bar separate at
  0.30–0.31 s (after tearing off). At ppc 2 every κ separates on both supports, κ ≥ 4 as the
  unscaled bar. So κ = 5.0 separates where unscaled CPDI fails too (ppc 2, the coarse clamped
  bar), never through its cap on the published support at ppc 3.

Outputs: ``gallery.csv`` (one row per case) in ``--out`` (default
``run_scripts/out/stability_gallery``); figures in ``--out`` too (``make figures`` passes
``--figures docs/figures``): ``gallery_<method>.png`` — one row per ppc (2D, Δx = 0.1 m), four
frames each (t = 0, the first stretch peak, the loss of the support, separation or 0.2 s, the end),
particle domains as the interpolation sees them (mpm: its nominal box) coloured by axial stretch
|F e_y| on one colour scale for all figures — and ``gallery_summary.png``, separation time and
stretch at separation per method and (dim, Δx, ppc), hatched where the bar held to 0.3 s, ▼ where
it tore off. ``gallery_lcr_separation.png``: the l_cr series (stretch at separation and separation time
against κ; see :func:`lcr_figure`).

Runtime: full (64 gallery cases + 66 of the l_cr series) ~20 min on a core shared with other
jobs (the gallery ~2 min of it, the series' 1 s runs of the bars that hold ~10–45 s each);
``--quick`` (11 2D cases at Δx = 0.1 m: mpm, ugimp, cpgimp, cpdi at ppc 2 and 3, cpdi with
l_cr = 5.0, 1.8, 1.2·Δx/3 at ppc 3) ~30 s, ~35 s under ``mpirun -n 2`` on two busy cores. Results
are identical on any number of ranks (only ``wall_seconds`` differs)::

    python run_scripts/studies/stability_gallery.py                  # full study, figures beside the CSV
    python run_scripts/studies/stability_gallery.py --quick          # the smoke test's mode
    mpirun -n 2 python run_scripts/studies/stability_gallery.py --quick
    python run_scripts/studies/stability_gallery.py --cases '2d_cpdi*_ppc3_dx0.1' --out /tmp/g
    python run_scripts/studies/stability_gallery.py --cases '*_t1' --out /tmp/lcr   # the l_cr series only
"""
from __future__ import annotations

import math
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py, the groups
from study import (figure, folders, is_root, main_guard, parser, run_case, save, scratch_folder,
                   select_cases, world, write_csv, wrote)

END = 0.3             # s, the seed's end time
FRAME_EVERY = 0.0025  # s between observer calls (frames for the figures, the support check)
PEAK_WINDOW = 0.15    # s: the first stretch peak is the largest stretch before this time
PEAK_AFTER = 0.02     # s the run must go on after a stretch maximum for it to count as a peak
STRETCH_RANGE = (1.0, 5.0)  # the shared colour scale of every gallery figure
SCENES = {1: "hanging_bar_1d", 2: "hanging_bar", 3: "hanging_bar_3d"}
# the l_cr series: κ of l_cr = κ·Δx/3 (6.0 = 2·Δx; None = unscaled), run LCR_END s on the published
# (roller) support and clamped, at (Δx, ppc) = LCR_GROUPS, 2D
LCR_KAPPAS = (1.0, 1.2, 1.5, 1.8, 2.2, 2.6, 3.0, 4.0, 5.0, 6.0, None)
LCR_END = 1.0
LCR_GROUPS = ((0.1, 3), (0.1, 2), (0.2, 3))
SUPPORTS = ("roller", "clamped")


@dataclass(frozen=True)
class Method:
    label: str          # file and CSV name
    interpolator: str
    lcr: str            # method.lcr spec; "none" = no domain scaling
    transfer: str = "flip"  # method.transfer

    @property
    def title(self) -> str:
        if self.interpolator not in ("cpdi", "cpdi2"):
            name = {"mpm": "MPM", "ugimp": "uGIMP", "cpgimp": "cpGIMP",
                    "bspline": "B-spline"}[self.interpolator]
            return name + (f" + {self.transfer.upper()}" if self.transfer != "flip" else "")
        name = self.interpolator.upper()
        if self.lcr == "none":
            return f"{name}, unscaled"
        return f"{name}, l_cr = {self.lcr.replace('dx', '·Δx')}"


METHODS = (
    Method("mpm", "mpm", "none"),
    Method("ugimp", "ugimp", "none"),
    Method("cpgimp", "cpgimp", "none"),
    Method("cpdi", "cpdi", "none"),
    Method("cpdi_lcr5.0dx3", "cpdi", "5.0dx/3"),
    Method("cpdi_lcr1.8dx3", "cpdi", "1.8dx/3"),
    Method("cpdi_lcr1.2dx3", "cpdi", "1.2dx/3"),
    Method("cpdi_lcr2dx", "cpdi", "2dx"),
    Method("bspline", "bspline", "none"),
    Method("bspline_apic", "bspline", "none", "apic"),
    Method("bspline_mls", "bspline", "none", "mls"),
    Method("cpdi2", "cpdi2", "none"),
    Method("cpdi2_lcr2dx", "cpdi2", "2dx"),
)
BY_LABEL = {m.label: m for m in METHODS}


def lcr_method(kappa: float | None) -> Method:
    """CPDI with l_cr = κ·Δx/3 (``None``: unscaled)."""
    if kappa is None:
        return BY_LABEL["cpdi"]
    return Method(f"cpdi_lcr{kappa:.1f}dx3", "cpdi", f"{kappa:.1f}dx/3")


def kappa_of(lcr: str) -> float | None:
    """κ of a method.lcr spec ``"κdx/3"`` or ``"2dx"`` (= 6); None for "none"."""
    if lcr == "none":
        return None
    return 3.0 * float(lcr[:-2]) if lcr.endswith("dx") else float(lcr.split("dx")[0])


@dataclass(frozen=True)
class Case:
    dim: int
    method: Method
    ppc: int
    cell: float
    support: str = "roller"   # the published support; "clamped" holds both components
    end: float = END

    @property
    def id(self) -> str:
        tail = "" if (self.support, self.end) == ("roller", END) else f"_{self.support}_t{self.end:g}"
        return f"{self.dim}d_{self.method.label}_ppc{self.ppc}_dx{self.cell:g}{tail}"

    @property
    def rest_corner(self) -> float:
        """Undeformed centre-to-corner length of a particle domain, ``√d·Δx/(2·ppc)`` (m)."""
        return math.sqrt(self.dim) * self.cell / (2 * self.ppc)

    def overrides(self) -> list[str]:
        import parmpm

        base = parmpm.load_scene(SCENES[self.dim]).data["grid"]
        h0 = base["cell_size"][0]
        cells = [round(n * h0 / self.cell) for n in base["cells"]]  # the same extent
        if any(abs(n * self.cell - m * h0) > 1e-9 for n, m in zip(cells, base["cells"])):
            raise ValueError(f"{self.id}: cell {self.cell} does not divide the scene's grid")
        over = [f"method.interpolator={self.method.interpolator}", f"method.lcr={self.method.lcr}",
                f"method.transfer={self.method.transfer}",
                f"bodies.0.ppc={self.ppc}", f"grid.cell_size={self.cell}",
                f"grid.cells=[{', '.join(map(str, cells))}]", f"time.end={self.end}",
                "metrics.stop_on_separation=true", f"output.every={FRAME_EVERY}"]
        if self.method.interpolator == "bspline":  # held at the grid's face (module doc)
            return over + self._face_support(base, cells)
        if self.support == "clamped":  # the same nodes, both components held
            b = parmpm.load_scene(SCENES[self.dim]).data["boundary"]["slip_regions"][0]
            lo, hi = ", ".join(map(repr, b["min"])), ", ".join(map(repr, b["max"]))
            over += ["boundary.slip_regions=[]", f"boundary.fixed_regions=[{{min=[{lo}], max=[{hi}]}}]"]
        return over

    def _face_support(self, base: dict, cells: list) -> list[str]:
        """B-splines refuse held node regions (a spline leans on held nodes past the region's
        edge): the grid ends at the bar's top instead, whose face is a mirror, a roller
        ("symmetry") or clamped, as B-splines treat exactly."""
        import parmpm

        b = parmpm.load_scene(SCENES[self.dim]).data["boundary"]
        region = (b["slip_regions"] or b["fixed_regions"])[0]
        axis = 0 if self.dim == 1 else 1
        cells = list(cells)
        cells[axis] = round((region["min"][axis] - base["origin"][axis]) / self.cell)
        face = "clamped" if self.support == "clamped" or self.dim == 1 else "symmetry"
        return ["boundary.slip_regions=[]", "boundary.fixed_regions=[]",
                f"grid.cells=[{', '.join(map(str, cells))}]", f"boundary.{'xyz'[axis]}_max={face}"]


def full_cases() -> list[Case]:
    cases = [Case(2, m, p, 0.1) for p in (2, 3, 4) for m in METHODS]
    cases += [Case(2, m, p, 0.2) for p in (2, 3, 4) for m in METHODS]  # the 3D runs' resolution
    cases += [Case(1, m, 2, 0.1) for m in METHODS]
    cases += [Case(3, m, 2, 0.2) for m in METHODS]
    return cases + lcr_cases()


def lcr_cases() -> list[Case]:
    """The l_cr series: every κ, both supports, each (Δx, ppc) group, to LCR_END."""
    return [Case(2, lcr_method(k), ppc, cell, support, LCR_END)
            for cell, ppc in LCR_GROUPS for support in SUPPORTS for k in LCR_KAPPAS]


def quick_cases() -> list[Case]:
    cases = [Case(2, BY_LABEL[k], p, 0.1)
             for p in (2, 3) for k in ("mpm", "ugimp", "cpgimp", "cpdi")]
    cases += [Case(2, BY_LABEL[k], 3, 0.1)
              for k in ("cpdi_lcr5.0dx3", "cpdi_lcr1.8dx3", "cpdi_lcr1.2dx3")]
    return cases


# --- observers ---------------------------------------------------------------------------------
class Watch:
    """Observer (collective, at every output time): when the bar first loses its support, and on
    rank 0 the 2D frames (domain polygons and axial stretch of every particle) for the figures.

    The support is the held grid nodes at and above ``y_s`` (the lowest edge of the scene's fixed
    regions and of its slip regions normal to the bar's axis: the roller). Weights are hats, so a particle exchanges momentum with a held node only if its
    support reaches above ``y_s − Δx``: the domain corners (uGIMP, cpGIMP, CPDI), the particle
    itself (mpm). Below that for every particle, the bar hangs from nothing: it tore off."""

    def __init__(self, frames: bool):
        self.keep_frames = frames
        self.support_lost = None
        self.reach = 0.0  # the largest support reach seen, in cells from the particle, any axis
        self.corner = 0.0  # the largest centre-to-corner length of a domain seen (m; 0 for mpm)
        self.t, self.corners, self.stretch = [], [], []

    def __call__(self, sim) -> None:
        import parmpm
        from decomposition import allreduce_max

        P, d = sim.particles, sim.dim
        axis = sim.state.data["metrics"]["axis"]
        b = sim.state.data["boundary"]
        y_s = min(r["min"][axis] for r in b["fixed_regions"] + [
            r for r in b["slip_regions"] if r["normal"] == "xyz"[axis]])
        h = sim.state.data["grid"]["cell_size"][axis]
        if sim.state.interp.name == "mpm":
            tops, reach, corner = P.x[:, axis], np.zeros(1), np.zeros(1)
        else:
            corners = parmpm.domain_corners(d, sim.state.interp.code, sim.state.lcr, P.x, P.F, P.r0, P.lh0,
                                            corners=P.corners)
            tops = corners[:, :, axis].max(axis=1)
            reach = np.abs(corners - P.x[:, None, :]).max(axis=1) / sim.state.data["grid"]["cell_size"]
            corner = np.linalg.norm(corners - P.x[:, None, :], axis=2)
        top, reach, corner = allreduce_max(sim.comm, np.array([
            tops.max() if P.n else -np.inf, reach.max() if reach.size else 0.0,
            corner.max() if corner.size else 0.0]))
        if self.support_lost is None and top <= y_s - h:
            self.support_lost = float(sim.t)
        self.reach = max(self.reach, float(reach))
        self.corner = max(self.corner, float(corner))
        if self.keep_frames and d == 2:
            g = sim.gather({"corners": sim.domain_corners(), "stretch": sim.axial_stretch()})
            if g is not None:
                self.t.append(float(sim.t))
                self.corners.append(g["corners"].astype(np.float32))
                self.stretch.append(g["stretch"].astype(np.float32))

    def peak(self) -> int | None:
        """Frame of the first stretch peak: the largest stretch before ``PEAK_WINDOW``, if the
        stretch falls (by 2 %) after it before the last frame and the run goes on for at least
        ``PEAK_AFTER`` (else it is the run-up to a separation, not a peak)."""
        s = np.array([st.max() for st in self.stretch])
        early = np.flatnonzero(np.asarray(self.t) <= PEAK_WINDOW)
        i = int(early[np.argmax(s[early])])
        t = np.asarray(self.t)
        falls = np.any(s[i + 1:-1] < 0.98 * s[i])  # not just at the final (separation) frame
        return i if falls and t[-1] - t[i] >= PEAK_AFTER else None

    def pick(self, t_sep: float | None, n: int = 4) -> list[tuple[int, str]]:
        """(frame index, tag) for the figure: 0, the first stretch peak, the loss of the support,
        separation (else 0.2 s) and the end, those the run reached, at most ``n`` (0.2 s goes
        first); gaps filled by midpoints up to ``n`` panels."""
        t = np.asarray(self.t)
        peak = self.peak()
        marks = {0.0: ""}
        if t_sep is None:
            marks[0.2] = ""
            marks[END] = ""
        else:
            marks[t_sep] = "separated"
        if self.support_lost is not None:
            marks[self.support_lost] = "tore off support"
        if peak is not None:
            marks[float(t[peak])] = "first stretch peak"
        marks = {x: tag for x, tag in marks.items() if x <= t[-1] + 1e-12}
        if len(marks) > n and 0.2 in marks:
            del marks[0.2]
        targets = sorted(marks)[:n]
        while len(targets) < n:
            k = int(np.argmax(np.diff(targets)))
            targets.insert(k + 1, 0.5 * (targets[k] + targets[k + 1]))
        picked = {}
        for x in targets:
            i = int(np.argmin(np.abs(t - x)))
            picked[i] = picked.get(i) or marks.get(x, "")
        return sorted(picked.items())


# --- running -----------------------------------------------------------------------------------
GHOST_RE = re.compile(r"beyond the ghost layer.*= ([0-9.eE+-]+) cells, ghost width (\d+) cells")


def run_one(case: Case, comm, out_dir: Path, frames: bool):
    """Run ``case`` (collective). Unscaled CPDI and cpGIMP domains are unbounded: if one outgrows
    the ghost layer the run stops with the reach in cells; we rerun with a ghost width one cell
    beyond it. Returns (summary, wall seconds, watch)."""
    from parmpm import SimulationError

    extra: list[str] = []
    for _ in range(8):
        watch = Watch(frames)
        try:
            summary, wall = run_case(SCENES[case.dim], case.overrides() + extra, comm, [watch],
                                     out_dir=out_dir / case.id)
        except SimulationError as exc:  # raised on every rank with the same message
            m = GHOST_RE.search(str(exc))
            if not m:
                raise
            ghost = max(int(m[2]) + 1, math.ceil(float(m[1])) + 1)
            why = str(exc)
        else:
            ghost = summary["grid"]["ghost"]
            if watch.reach <= ghost:
                return summary, wall, watch
            # a support past the ghost layer at a metrics sample, before the next step's reach
            # check: its node list was cut short there, which can fake a separation
            why = f"support reach {watch.reach:.3g} cells > ghost width {ghost}"
            ghost = math.ceil(watch.reach) + 1
        if is_root(comm):
            print(f"  {case.id}: {why} -> rerun with grid.ghost={ghost}", flush=True)
        extra = [f"grid.ghost={ghost}"]
    raise RuntimeError(f"{case.id}: the domains keep outgrowing the ghost layer")


def row(case: Case, summary: dict, wall: float, watch: Watch) -> dict:
    m = summary["metrics"]
    lcr_m = summary["lcr"]
    return {
        "case": case.id, "dim": case.dim, "method": case.method.label,
        "interpolator": case.method.interpolator, "lcr": case.method.lcr,
        "lcr_m": lcr_m, "lcr_over_rest_corner": lcr_m / case.rest_corner if lcr_m else None,
        "ppc": case.ppc, "cell_size": case.cell, "support": case.support, "run_to": case.end,
        "kappa": kappa_of(case.method.lcr) if case.method.interpolator == "cpdi" else None,
        "corner_growth": watch.corner / case.rest_corner if watch.corner else None,
        "ghost": summary["grid"]["ghost"],
        "separated": bool(m["separated"]), "separation_time": m["separation_time"],
        "stretch_at_separation": m["stretch_at_separation"], "max_stretch": m["max_stretch"],
        "max_components": m["max_components"], "support_lost_time": watch.support_lost,
        "end_time": summary["time"], "particles": summary["particles"], "steps": summary["steps"],
        "wall_seconds": wall,
    }


def describe(r: dict) -> str:
    if r["separated"]:
        text = f"separated at {r['separation_time']:.4f} s (stretch {r['stretch_at_separation']:.2f})"
    else:
        text = f"held to {r['end_time']:.2f} s (max stretch {r['max_stretch']:.2f})"
    if r["support_lost_time"] is not None:
        text += f"; tore off its support by {r['support_lost_time']:.4f} s"
    return text


# --- figures -----------------------------------------------------------------------------------
def gallery_figure(method: Method, panels: dict, path: Path, extent) -> Path:
    """One row per ppc, four frames each: domains coloured by axial stretch (shared scale)."""
    from matplotlib import cm, colors
    from matplotlib.collections import PolyCollection

    rows = sorted(panels)
    fig, axes = figure(len(rows), 5, size=(6.6, 2.55 * len(rows) + 0.35))  # PNG < 300 KB
    axes[0, 0].get_gridspec().set_width_ratios([1, 1, 1, 1, 0.28])
    norm = colors.Normalize(*STRETCH_RANGE)
    (x0, x1), (y0, y1) = extent
    for i, ppc in enumerate(rows):
        r, frames = panels[ppc]
        for j in range(4):
            ax = axes[i, j]
            ax.set_xticks(np.arange(-0.5, x1 + 1e-9, 0.5))
            ax.set_yticks(np.arange(-3.0, y1 + 1e-9, 0.5))
            ax.set_xticks(np.arange(x0, x1 + 1e-9, r["cell_size"]), minor=True)
            ax.set_yticks(np.arange(y0, y1 + 1e-9, r["cell_size"]), minor=True)
            ax.grid(which="minor", color="0.85", lw=0.3)
            ax.tick_params(labelsize=6, which="both", length=2)
            ax.tick_params(which="minor", length=0)
            if j >= len(frames):
                ax.set_axis_off()
                continue
            t, corners, stretch, tag = frames[j]
            pc = PolyCollection(corners, array=stretch, cmap="viridis", norm=norm,
                                edgecolors="k", linewidths=0.1)
            ax.add_collection(pc)
            ax.axhline(0.0, color="0.3", lw=1.5)  # the support
            ax.set_xlim(x0, x1)
            ax.set_ylim(y0, y1)
            ax.set_aspect("equal")
            ax.set_title(f"t = {t:.3f} s" + (f"\n{tag}" if tag else ""), fontsize=7,
                         color="k" if tag in ("", "first stretch peak") else "C3")
            if j:
                ax.set_yticklabels([])
        axes[i, 0].set_ylabel(f"ppc {ppc}: {_short(r)}", fontsize=7)
        axes[i, 4].set_axis_off()
    cax = axes[len(rows) // 2, 4].inset_axes([0.1, 0.0, 0.3, 0.9])
    fig.colorbar(cm.ScalarMappable(norm, "viridis"), cax=cax, extend="max")
    cax.set_title("axial\nstretch\n|F e_y|", fontsize=7)
    cax.tick_params(labelsize=6)
    fig.suptitle(f"{method.title}: self-weighted bar, Δx = {panels[rows[0]][0]['cell_size']:g} m",
                 fontsize=9)
    return save(fig, path)


def _short(r: dict) -> str:
    if r["separated"]:
        return f"separated {r['separation_time']:.3f} s"
    return "held to 0.3 s"


SERIES = [  # (dim, cell, ppc) groups of the summary chart
    (2, 0.1, 2), (2, 0.1, 3), (2, 0.1, 4), (2, 0.2, 2), (1, 0.1, 2), (3, 0.2, 2)]


def summary_figure(rows: list[dict], path: Path) -> Path:
    """Separation time (hatched bar to 0.3 s: held) and stretch at separation (hatched: the
    largest stretch of a bar that held), per method and (dim, Δx, ppc) series."""
    from matplotlib.patches import Patch

    table = {(r["dim"], r["cell_size"], r["ppc"], r["method"]): r for r in rows
             if (r["support"], r["run_to"]) == ("roller", END)}
    series = [s for s in SERIES if any(k[:3] == s for k in table)]
    methods = [m for m in METHODS if any(k[3] == m.label for k in table)]
    fig, axes = figure(2, 1, size=(11.0, 6.8))
    width = 0.84 / len(series)
    for ax, which in zip(axes[:, 0], ("time", "stretch")):
        for k, s in enumerate(series):
            colour = f"C{k}"
            for i, m in enumerate(methods):
                r = table.get(s + (m.label,))
                if r is None:
                    continue
                x = i - 0.42 + (k + 0.5) * width
                sep = r["separated"]
                if which == "time":
                    y = r["separation_time"] if sep else r["end_time"]
                else:
                    y = r["stretch_at_separation"] if sep else r["max_stretch"]
                ax.bar(x, y, width * 0.92, color=colour if sep else "none", edgecolor=colour,
                       hatch=None if sep else "////", lw=0.8)
                if which == "time" and r["support_lost_time"] is not None:
                    ax.plot(x, r["support_lost_time"], "v", color="k", ms=5)
        ax.set_xticks(range(len(methods)))
        ax.set_xticklabels([m.title.replace(", ", "\n") for m in methods], fontsize=7)
        ax.set_xlim(-0.5, len(methods) - 0.5)
        ax.grid(axis="y", color="0.9")
        ax.set_axisbelow(True)
    axes[0, 0].set_ylabel("separation time (s)")
    axes[0, 0].set_ylim(0, END * 1.4)
    axes[0, 0].axhline(END, color="0.5", lw=0.6, ls=":")
    axes[1, 0].set_ylabel("axial stretch at separation")
    handles = [Patch(color=f"C{k}", label=f"{d}D, Δx = {h:g} m, ppc {p}") for k, (d, h, p) in enumerate(series)]
    handles += [Patch(facecolor="none", edgecolor="0.3", hatch="////",
                      label="no separation by 0.3 s (bottom: largest stretch)")]
    from matplotlib.lines import Line2D
    handles += [Line2D([], [], marker="v", color="k", ls="", label="bar tore off its support")]
    axes[0, 0].legend(handles=handles, fontsize=6.5, ncol=4, loc="upper left", framealpha=0.9)
    axes[0, 0].set_title("Self-weighted bar, g = 1000 m/s²: first numerical separation", fontsize=9)
    return save(fig, path)


def lcr_figure(rows: list[dict], path: Path) -> Path:
    """Stretch at separation (top) and separation time (bottom) against κ of l_cr = κ·Δx/3, per
    (Δx, ppc) group (colour) and support (marker); open markers: held to the end of the run
    (the largest stretch and the run's end); × marks a bar that tore off its support first. The
    unscaled run sits at the right; a dotted line per group marks κ* = 3·(largest centre-to-corner
    length of its unscaled roller run)/Δx: no cap above it engages on the published support."""
    from matplotlib.lines import Line2D

    cpdi = [r for r in rows if r["dim"] == 2 and r["interpolator"] == "cpdi"]
    if any(r["run_to"] == LCR_END for r in cpdi):  # the series; else (--quick) the 0.3 s runs
        cpdi = [r for r in cpdi if r["run_to"] == LCR_END]
    groups = sorted({(r["cell_size"], r["ppc"]) for r in cpdi}, key=lambda g: (g[0], -g[1]))
    kappas = sorted({r["kappa"] for r in cpdi if r["kappa"] is not None})
    k_free = (max(kappas) if kappas else 6.0) + 1.0  # where the unscaled runs are drawn
    fig, axes = figure(2, 1, size=(7.6, 6.6))
    marker = {"roller": "o", "clamped": "s"}
    for g, (cell, ppc) in enumerate(groups):
        colour = f"C{g}"
        mine = [r for r in cpdi if (r["cell_size"], r["ppc"]) == (cell, ppc)]
        free = [r["corner_growth"] * math.sqrt(2) * cell / (2 * ppc) for r in mine
                if r["kappa"] is None and r["corner_growth"] and r["support"] == "roller"]
        for support in SUPPORTS:
            pts = sorted(((k_free if r["kappa"] is None else r["kappa"], r) for r in mine
                          if r["support"] == support), key=lambda p: p[0])
            for ax, key in zip(axes[:, 0], ("stretch", "time")):
                for x, r in pts:
                    sep = r["separated"]
                    if key == "stretch":
                        y = r["stretch_at_separation"] if sep else r["max_stretch"]
                    else:
                        y = r["separation_time"] if sep else r["end_time"]
                    x_at = x + (0.04 if support == "clamped" else -0.04)
                    ax.plot(x_at, y, marker[support], ms=5, color=colour, mfc=colour if sep else "none")
                    if r["support_lost_time"] is not None:
                        ax.plot(x_at, y, "x", color="k", ms=4, mew=0.8)
                xs = [x for x, r in pts if r["separated"]]
                ys = [(r["stretch_at_separation"] if key == "stretch" else r["separation_time"])
                      for x, r in pts if r["separated"]]
                ax.plot(xs, ys, "-" if support == "roller" else "--", color=colour, lw=0.7)
        if free:
            for ax in axes[:, 0]:
                ax.axvline(3.0 * max(free) / cell, color=colour, lw=0.8, ls=":")
    for ax in axes[:, 0]:
        ax.set_xticks(kappas + [k_free])
        ax.set_xticklabels([f"{k:g}" for k in kappas] + ["none"], fontsize=7)
        ax.grid(color="0.9")
        ax.set_axisbelow(True)
    axes[0, 0].set_ylabel("axial stretch at separation")
    axes[1, 0].set_ylabel("separation time (s)")
    axes[1, 0].set_xlabel("κ of l_cr = κ·Δx/3 (6 = 2·Δx)")
    handles = [Line2D([], [], color=f"C{g}", lw=3, label=f"Δx = {c:g} m, ppc {p}")
               for g, (c, p) in enumerate(groups)]
    handles += [Line2D([], [], marker=marker[s], color="0.3", ls="-" if s == "roller" else "--",
                       label=f"{s} support" + (" (published)" if s == "roller" else ""))
                for s in SUPPORTS]
    handles += [Line2D([], [], marker="o", mfc="none", color="0.3", ls="",
                       label="held (largest stretch; end of run)"),
                Line2D([], [], marker="x", color="k", ls="", label="tore off its support first"),
                Line2D([], [], color="0.3", ls=":", label="κ* (roller): a cap engages only below")]
    axes[0, 0].legend(handles=handles, fontsize=6.5, ncol=2, loc="upper left", framealpha=0.9)
    axes[0, 0].set_title("Self-weighted bar, CPDI with domain scaling: separation against l_cr",
                         fontsize=9)
    return save(fig, path)


# --- main --------------------------------------------------------------------------------------
def main() -> int:
    ap = parser(__doc__)
    ap.add_argument("--cases", default=None,
                    help="comma-separated glob patterns over case ids, e.g. '2d_mpm_*,2d_cpdi_ppc3_*'")
    args = ap.parse_args()
    comm = world()
    root = is_root(comm)
    out, figs = folders(args, "stability_gallery")
    cases = quick_cases() if args.quick else full_cases()
    cases = select_cases(cases, args.cases)
    rows, panels, by_dim = [], {}, {}
    t_start = time.perf_counter()
    with scratch_folder(comm, "parmpm-gallery-") as scratch:
        for case in cases:
            want_frames = (case.dim == 2 and (case.support, case.end) == ("roller", END)
                           and case.cell == min(c.cell for c in cases if c.dim == 2))
            summary, wall, watch = run_one(case, comm, scratch, want_frames)
            r = row(case, summary, wall, watch)
            rows.append(r)
            by_dim[case.dim] = by_dim.get(case.dim, 0.0) + wall
            if root:
                print(f"{case.id:32s} {describe(r)}; {r['particles']} particles, {r['steps']} steps, "
                      f"{wall:.1f} s", flush=True)
                if want_frames:
                    frames = [(watch.t[i], watch.corners[i], watch.stretch[i], tag)
                              for i, tag in watch.pick(r["separation_time"])]
                    panels.setdefault(case.method.label, {})[case.ppc] = (r, frames)
    total = time.perf_counter() - t_start
    write_csv(out / "gallery.csv", rows, comm)
    if root:
        import parmpm

        g = parmpm.load_scene(SCENES[2]).data["grid"]
        extent = [(o, o + n * h) for o, n, h in zip(g["origin"], g["cells"], g["cell_size"])]
        written = [gallery_figure(BY_LABEL[k], v, figs / f"gallery_{k}.png", extent)
                   for k, v in panels.items()]
        if any((r["support"], r["run_to"]) == ("roller", END) for r in rows):
            written.append(summary_figure(rows, figs / "gallery_summary.png"))
        if any(r["interpolator"] == "cpdi" and r["dim"] == 2 for r in rows):
            written.append(lcr_figure(rows, figs / "gallery_lcr_separation.png"))
        print(f"{len(rows)} cases in {total:.0f} s on {comm.Get_size()} rank(s) ("
              + ", ".join(f"{d}D {s:.0f} s" for d, s in sorted(by_dim.items())) + ")")
        print(f"wrote {out / 'gallery.csv'}")
        for p in written:
            print(wrote(p))
    return 0


if __name__ == "__main__":
    main_guard(main)
