"""The granular column collapse of Bui et al. (2008) against the measured final surface.

Physics. ``docs/examples/column_collapse.toml``: a 0.2 m × 0.1 m column of aluminium rods
(Drucker–Prager, plane-strain match, φ = 19.8°, c = 0, ψ = 0, with the volume correction and
μ(I): φ_2 = 31.7°, I_0 = 0.279, d = 1.25 mm, ρ_s = 2700 kg/m³; ρ = 2650 kg/m³, K = 0.7 MPa,
ν = 0.3) against a frictionless wall at x = 0 (``x_min = "slip"``) on a no-slip floor
(``y_min = "fixed"``), gravity applied at once, as the public reproductions run it
(docs/results/plasticity_references.md, section 2). Each case runs to ``--end`` (1 s, the
references' duration) at Δx = 0.1 m / n for n in ``--resolutions`` (cells across the column's
height, 2 particles per cell per axis), for each interpolator in ``--methods``; the grid is
1.2 m long so that nothing leaves it.

Measured at each output time (an observer gathering the particles on rank 0), and at the end:

* the free surface: in bins one cell wide, the highest particle top: centre plus ``√J ℓ/2``,
  half the side of a square of the particle's current area (``ℓ = Δx/2`` the initial spacing;
  not ``F``'s own extent, which for the toe's sheared particles is several cells long);
* the run-out: the far edge (``x + √J ℓ/2``) of the last particle of the deposit, the deposit
  being the bins occupied without a gap from the wall (a particle thrown ahead of a gap is not
  the toe); uncertain by ± ℓ, the particle spacing. Without the volume correction a sheet one
  or two particles thick runs ahead of the deposit on the finer grids (gaps come and go in it),
  so also ``x99``: the x behind which 99 % of the mass lies (the particles' masses are equal);
* against the measured surface (``tests/data/bui2008_final_surface.csv``): the run-out error
  against the last measured point (0.4423 m), and the RMS of simulated minus measured height at
  the 23 measured x (an empty bin counts as height 0);
* how the deposit's mass ends: ``beyond_toe``, the share of its area (``Σ J V₀``) beyond the
  last measured point, and ``thin_at_m``, the start of the first 1 cm bin past 0.3 m whose mean
  thickness (area per unit length) is under ``THIN`` (3 mm: two rods of the experiment's 1.5 and
  2 mm; its last point is 1.5 mm high). Unlike the edge these do not follow a sheet:
  2026-11-30, n = 20, 30, 40, 60: ``beyond_toe`` 0, 0.03, 0, 0 %, ``thin_at_m`` 0.42, 0.44,
  0.42, 0.42 m (without μ(I) 0.22, 0.47, 0.15, 0.44 % and 0.45, 0.44, 0.45, 0.45 m; without
  the volume correction too 0.71, 1.76, 2.13, 2.22 % and 0.47, 0.48, 0.47, 0.48 m);
* the failure line: in the initial configuration, the top of the particles that moved less than
  1 mm horizontally (per column of particles), its least-squares angle against the measured
  32.9°;
* the kinetic energy's fraction of its peak at the end (history.csv), which says whether the
  deposit has come to rest, and the deposit's volume over the column's (``Σ J V₀ / Σ V₀``, the
  particles' volumes being equal): the experiment's surface encloses 1.5 % more area than
  the column.

Outputs (``--out``, default ``run_scripts/out/column_collapse``; figures in ``--figures``):
``column_collapse.csv`` (one row per case), ``column_collapse_deposit.png`` (the finest
run's final deposit coloured by equivalent plastic strain, with the measured surface and failure
line over it), ``column_collapse_surfaces.png`` (the surfaces at each resolution, and the
kinetic energy and run-out in time), and per case ``runs/<method>_n<n>/`` with its
``history.csv`` and ``final_state.npz`` (the final particles). ``--quick``: n = 10, B-spline
APIC, to 0.3 s (seconds; the smoke test's mode).

``--set KEY=VALUE`` (repeatable) overrides the scene in every case, as ``parmpm run``'s does
(``--set materials.rods.inertial_number_0=0.56``: the results page's sensitivity rows).

Methods: ``--methods`` (default ``bspline_apic``) at every resolution, ``--compare`` (default
``bspline``, FLIP) at ``--compare-resolutions`` (default the coarsest): under FLIP the flowing
layer stays loose and the column runs on (docs/results/column-collapse.md); cpdi (USL) gave a
non-finite velocity at 0.13 s at n = 20.

Runtime (2 ranks on a 2-core machine, 2026-11-30, with μ(I)): n = 20, 30, 40, 60 take 14, 33,
73 and 202 s, FLIP at n = 20 13 s; n = 80 and 100 about 15 min each::

    mpirun -n 2 python run_scripts/studies/column_collapse.py
"""
from __future__ import annotations

import csv
import math
import sys
from pathlib import Path

import numpy as np

if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py
from study import (METHODS, ROOT, figure, folders, is_root, main_guard, parser,  # noqa: E402
                   read_csv, run_case, save, world, write_csv, wrote)

SCENE = ROOT / "docs" / "examples" / "column_collapse.toml"
MEASURED = ROOT / "tests" / "data" / "bui2008_final_surface.csv"
WIDTH, HEIGHT, LENGTH = 0.2, 0.1, 1.2  # the column, and the grid's length (m: without the volume
#                                        correction a thin sheet runs to 0.78 m at Δx = 2.5 mm)
PPC = 2
MOVED = 1e-3  # m: a particle that moved less than this horizontally is in the static wedge
THIN, THIN_BIN = 3e-3, 0.01  # m: the mean thickness under which the deposit has ended, its bins
FAILURE_ANGLE = 32.9  # degrees, the least-squares line of the measured failure points


def measured() -> dict[str, np.ndarray]:
    """The experiment's ``surface`` and ``failure`` points, (n, 2) arrays in metres."""
    lines = [ln for ln in MEASURED.read_text(encoding="utf-8").splitlines() if not ln.startswith("#")]
    rows = list(csv.DictReader(lines))
    return {c: np.array([[float(r["x"]), float(r["y"])] for r in rows if r["curve"] == c])
            for c in ("surface", "failure")}


def overrides(method: str, n: int, end: float) -> list[str]:
    dx = HEIGHT / n
    m = METHODS[method]
    return [f"grid.cell_size={dx!r}", f"grid.cells=[{round(LENGTH / dx)}, {round(1.2 * n)}]",
            f"method.interpolator={m.interpolator}", f"method.transfer={m.transfer}",
            f"time.end={end!r}", f"output.every={end / 20!r}", "output.history.every_steps=10"]


def surface(x: np.ndarray, F: np.ndarray, dx: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(bin centres, highest particle top per bin (0 where empty), run-out) of one state: the
    module docstring's definitions."""
    half = 0.5 * dx / PPC * np.sqrt(np.abs(np.linalg.det(F)))
    top, right = x[:, 1] + half, x[:, 0] + half
    nbins = int(math.ceil(LENGTH / dx))
    k = np.clip((x[:, 0] // dx).astype(int), 0, nbins - 1)
    height = np.zeros(nbins)
    np.maximum.at(height, k, top)
    empty = np.flatnonzero(height == 0.0)
    last = (empty[0] if empty.size else nbins) - 1  # the deposit: occupied bins from the wall
    return (np.arange(nbins) + 0.5) * dx, height, float(right[k <= last].max())


def mass_end(x: np.ndarray, F: np.ndarray, dx: float, toe: float) -> tuple[float, float]:
    """(share of the deposit's area beyond ``toe``, start of the first :data:`THIN_BIN` bin past
    0.3 m whose mean thickness is under :data:`THIN`) of one state: the module docstring's
    definitions."""
    area = np.abs(np.linalg.det(F)) * (dx / PPC) ** 2
    edges = np.arange(0.0, LENGTH + THIN_BIN, THIN_BIN)
    thick = np.histogram(x[:, 0], edges, weights=area)[0] / THIN_BIN
    k0 = int(round(0.3 / THIN_BIN))
    thin = np.flatnonzero(thick[k0:] < THIN)
    end = round(float(edges[k0 + thin[0]]), 9) if thin.size else math.inf
    return float(area[x[:, 0] > toe].sum() / area.sum()), end


def failure_line(x0: np.ndarray, x: np.ndarray, dx: float) -> tuple[np.ndarray, float]:
    """The top of the static particles (moved < 1 mm in x) per initial column of particles, in
    the initial configuration, and the angle (degrees) of its least-squares line."""
    static = np.abs(x[:, 0] - x0[:, 0]) < MOVED
    cols = np.round(x0[:, 0] / (dx / PPC) - 0.5).astype(int)
    pts = []
    for c in np.unique(cols):  # set-up-sized loop over columns of particles, after the run
        on = (cols == c) & static
        if on.any():
            pts.append((x0[cols == c, 0][0], x0[on, 1].max() + 0.5 * dx / PPC))
    pts = np.array(pts)
    inside = (pts[:, 1] < 0.98 * HEIGHT) & (pts[:, 1] > 0.5 * dx / PPC + 1e-12)
    angle = (math.degrees(math.atan(-np.polyfit(pts[inside, 0], pts[inside, 1], 1)[0]))
             if inside.sum() >= 3 else math.nan)
    return pts, angle


class Watch:
    """Observer (collective): the particles at each output time, gathered on rank 0, reduced to
    the run-out; keeps the last state whole."""

    def __init__(self, dx: float):
        self.dx = dx
        self.t: list[float] = []
        self.runout: list[float] = []
        self.last = None

    def __call__(self, sim) -> None:
        from parmpm.materials.plasticity.state import STATE_EPSP

        P = sim.particles
        g = sim.gather({"x": P.x, "x0": P.x0, "F": P.F, "epsp": P.plastic[:, STATE_EPSP]})
        if g is None:
            return
        self.t.append(float(sim.t))
        self.runout.append(surface(g["x"], g["F"], self.dx)[2])
        self.last = g


def kinetic(history: Path) -> tuple[np.ndarray, np.ndarray]:
    rows = read_csv(history)
    return (np.array([float(r["time"]) for r in rows]), np.array([float(r["kinetic"]) for r in rows]))


def run(method: str, n: int, end: float, runs: Path, comm, extra=()) -> dict:
    dx = HEIGHT / n
    watch = Watch(dx)
    out = runs / f"{method}_n{n}"
    summary, wall = run_case(SCENE, [*overrides(method, n, end), *extra], comm=comm,
                             observers=[watch], out_dir=out)
    row = {"method": method, "cells_per_height": n, "dx": dx, "particles": summary["particles"],
           "steps": summary["steps"], "end": end, "wall_s": wall}
    if not is_root(comm):
        return row
    meas = measured()
    g = watch.last
    np.savez_compressed(out / "final_state.npz", **g)  # for a re-analysis without the run
    xc, h, runout = surface(g["x"], g["F"], dx)
    bins = np.clip((meas["surface"][:, 0] // dx).astype(int), 0, len(h) - 1)
    rms = float(np.sqrt(np.mean((h[bins] - meas["surface"][:, 1]) ** 2)))
    pts, angle = failure_line(g["x0"], g["x"], dx)
    t, ke = kinetic(out / "history.csv")
    target = float(meas["surface"][-1, 0])
    beyond, thin_at = mass_end(g["x"], g["F"], dx, target)
    row.update({"runout_m": runout, "runout_unc_m": dx / PPC, "runout_beyond_toe_m": runout - WIDTH,
                "runout_error": (runout - target) / target,
                "runout_error_beyond_toe": (runout - target) / (target - WIDTH),
                "x99_m": float(np.quantile(g["x"][:, 0], 0.99)),
                "beyond_toe": beyond, "thin_at_m": thin_at,
                "rms_surface_m": rms, "rms_surface_rel_height": rms / HEIGHT,
                "height_at_wall_m": float(h[0]), "failure_angle_deg": angle,
                "max_plastic_strain": float(g["epsp"].max()),
                "volume_ratio": float(np.mean(np.linalg.det(g["F"]))),
                "ke_end_over_peak": float(ke[-1] / ke.max()) if ke.max() > 0 else math.nan,
                "t_ke_peak": float(t[np.argmax(ke)])})
    row["_plot"] = {"xc": xc, "h": h, "x": g["x"], "epsp": g["epsp"], "failure": pts,
                    "t": np.array(watch.t), "runout_t": np.array(watch.runout), "ke_t": t, "ke": ke}
    return row


def plot_deposit(row: dict, path: Path) -> Path:
    meas, d = measured(), row["_plot"]
    fig, axes = figure(1, 1, size=(10.0, 3.6))
    ax = axes[0, 0]
    size = 0.8 * (0.5 * row["dx"] * 1440.0) ** 2  # points²: one particle spacing at 1440 pt/m
    sc = ax.scatter(d["x"][:, 0], d["x"][:, 1], c=d["epsp"], s=size, lw=0, cmap="viridis",
                    vmin=0.0, vmax=float(np.percentile(d["epsp"], 98)), rasterized=True)
    fig.colorbar(sc, ax=ax, label="equivalent plastic strain", pad=0.01, shrink=0.7)
    ax.plot(*meas["surface"].T, "o", mfc="none", color="tab:red", ms=5, label="measured surface")
    ax.plot(*meas["failure"].T, "s", mfc="none", color="tab:orange", ms=5,
            label="measured failure line")
    f = d["failure"]
    ax.plot(f[:, 0], f[:, 1], "-", color="k", lw=1.0,
            label=f"simulated failure line ({row['failure_angle_deg']:.1f}°)")
    ax.plot([0, WIDTH, WIDTH], [HEIGHT, HEIGHT, 0], ":", color="0.4", lw=1, label="initial column")
    ax.set_xlim(0.0, max(0.5, row["runout_m"] + 0.02))
    ax.set_ylim(0.0, 0.11)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{row['method']}, Δx = {row['dx'] * 1e3:.2f} mm, t = {row['end']:g} s: "
                 f"run-out {row['runout_m']:.3f} m (measured 0.442 m)", fontsize=10)
    ax.legend(fontsize=7, loc="upper right")
    return save(fig, path)


def plot_surfaces(rows: list[dict], path: Path) -> Path:
    meas = measured()
    fig, axes = figure(1, 3, size=(15.0, 3.8))
    a, b, c = axes[0]
    a.plot(*meas["surface"].T, "o", mfc="none", color="k", label="measured")
    for r in rows:
        d = r["_plot"]
        style = "-" if r["method"] == "bspline_apic" else "--"
        lab = f"{r['method']} Δx {r['dx'] * 1e3:.2f} mm"
        a.step(d["xc"], d["h"], style, where="mid", label=lab, lw=1)
        b.semilogy(d["ke_t"], np.maximum(d["ke"] / d["ke"].max(), 1e-8), style, label=lab, lw=1)
        c.plot(d["t"], d["runout_t"], style, label=lab, lw=1)
    a.set_xlim(0, 0.6)
    a.set_xlabel("x (m)")
    a.set_ylabel("surface height (m)")
    a.set_title("final free surface")
    b.set_xlabel("t (s)")
    b.set_ylabel("kinetic energy / its peak")
    c.axhline(float(meas["surface"][-1, 0]), color="k", lw=0.8, label="measured run-out")
    c.set_xlabel("t (s)")
    c.set_ylabel("run-out (m)")
    for ax in (a, b, c):
        ax.legend(fontsize=7)
    return save(fig, path)


def main() -> int:
    p = parser(__doc__)
    p.add_argument("--methods", nargs="+", default=["bspline_apic"],
                   help="study.METHODS keys run at every resolution")
    p.add_argument("--resolutions", nargs="+", type=int, default=[20, 30, 40, 60],
                   help="cells across the column's height (Δx = 0.1 m / n)")
    p.add_argument("--compare", nargs="*", default=["bspline"],
                   help="methods run at --compare-resolutions only (default: B-spline FLIP)")
    p.add_argument("--compare-resolutions", nargs="+", type=int, default=None,
                   help="resolutions of the --compare methods (default: the coarsest)")
    p.add_argument("--end", type=float, default=1.0, help="simulated time (s)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="a scene override for every case, as parmpm run's --set (repeatable)")
    args = p.parse_args()
    if args.quick:
        args.methods, args.resolutions, args.compare, args.end = ["bspline_apic"], [10], [], 0.3
    bad = [m for m in args.methods + args.compare if m not in METHODS]
    if bad:
        raise SystemExit(f"--methods/--compare: unknown {', '.join(bad)} (choose from {', '.join(METHODS)})")
    out, figs = folders(args, "column_collapse")
    comm = world()
    coarse = args.compare_resolutions or sorted(args.resolutions)[:1]
    cases = [(m, n) for m in args.methods + [c for c in args.compare if c not in args.methods]
             for n in (args.resolutions if m in args.methods else coarse)]
    cases.sort(key=lambda c: c[1])  # coarse first: a long study has its cheap rows early
    rows = []
    for method, n in cases:
        r = run(method, n, args.end, out / "runs", comm, args.set)
        rows.append(r)
        if is_root(comm):
            print(f"{method:12s} dx={r['dx'] * 1e3:.2f} mm  run-out {r['runout_m']:.4f} m "
                  f"({100 * r['runout_error']:+.1f} %), RMS surface {r['rms_surface_m'] * 1e3:.2f} mm, "
                  f"failure {r['failure_angle_deg']:.1f} deg, KE end/peak "
                  f"{r['ke_end_over_peak']:.2e}  ({r['particles']} particles, {r['steps']} steps, "
                  f"{r['wall_s']:.1f} s)", flush=True)
            write_csv(out / "column_collapse.csv", [{k: v for k, v in r.items() if k != "_plot"}
                                                    for r in rows])  # after every case, with
            finest = max(rows, key=lambda r: (r["method"] == args.methods[0],  # the figures
                                              r["cells_per_height"]))
            plot_deposit(finest, figs / "column_collapse_deposit.png")
            plot_surfaces(rows, figs / "column_collapse_surfaces.png")
    if is_root(comm):
        for name in ("column_collapse.csv", "column_collapse_deposit.png", "column_collapse_surfaces.png"):
            print(wrote((out if name.endswith(".csv") else figs) / name))
    return 0


if __name__ == "__main__":
    main_guard(main)
