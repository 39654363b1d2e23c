"""Large rotation: a freely spinning disk with every method of the studies (domains, stress, energy).

Physics. The built-in ``spinning_disk``: a neo-Hookean disk (R = 0.4 m, E = 1 MPa, ν = 0.3,
ρ0 = 1000 kg/m³, plane strain; 2 particles per cell per axis, Δx = 0.05 m) spins freely (no
gravity, no supports) with ω = 2π rad/s through one revolution (``metrics.kind = "rotation"``).
Exactly it turns rigidly apart from a small centrifugal stretch: the domains keep their size,
angular momentum and total energy are constant (the kinetic energy dips slightly and
periodically: started unstressed, the disk breathes), and the stress stays of the order of the
centrifugal scale ``ρ0 ω² R²`` (the ratio to it is ``stress_ratio``; a rigid rotation carries no
stress at all). cpGIMP sizes its domains by ``l0_k·|F_kk|``, and ``F_xx = F_yy = cos θ`` under
a rotation θ: its domains collapse as ``cos² θ`` towards 90° and 270° — the total domain area
``area_ratio`` (:func:`parmpm.domain_sizes`, summed, over its initial value) drops to ~0 — and
grow back. CPDI's domains ``R = F·R0`` rotate with the material and keep their area. uGIMP's
boxes never change, and mpm's nominal box is drawn for reference only (a point has no domain):
their area ratio is 1 by construction, but they do not rotate either, and their stress is as
noisy as cpGIMP's. Quadratic B-splines (``bspline``) are point methods like mpm (nominal box,
area ratio 1), with FLIP or with APIC transfers (``bspline_apic``): APIC's transfers and grid
update conserve the angular momentum ``Σ m (x × v + ε:(C D)ᵀ)`` exactly (the rotation metric's
``momentum_ratio`` includes the affine part), FLIP's do not. Each method with its default
update (USL for cpdi, MUSL for the others); CPDI with the scene's ``l_cr = 2·Δx``, which a
rotation never reaches (the cap bounds stretch, not turn). The methods are ``study.METHODS``.

Cases: each method at ω = 2π, Δx = 0.05 m (the scene); the full study adds ω = 4π (one
revolution in 0.5 s: twice the speed, the same centrifugal stress *ratio* expected) and
Δx = 0.025 m at ω = 2π (does the stress noise shrink under refinement?). ``--quick``: each
method at ω = 2π with Δx = 0.1 m (208 particles).

Expected and found (full run; the lead's earlier numbers for the first block reproduced):

    one revolution        area ratio          stress ratio max        KE (end)   L (end)
    ω = 2π, Δx = 0.05     min     near 90°    2π/.05  4π/.05  2π/.025   2π/.05     2π/.05
    CPDI                  1 ± 0.3 %*          1.61    1.24    1.28      0.965      0.982
    cpGIMP                0.0002  0.0002      6.25    2.39    3.34      0.966      0.973
    uGIMP                 1 (fixed box)       6.53    2.04    3.23      0.969      0.974
    mpm                   1 (nominal box)     6.31    2.74    5.88      0.956      0.968
    B-spline (FLIP)       1 (nominal box)     5.35    2.08    2.89      0.968      0.974
    B-spline APIC         1 (nominal box)     1.30    1.27    1.29      0.998      1 ± 2.7e-15
    (* the disk's own breathing: CPDI's total area stays within 0.32 % of 1 at ω = 2π, 1.3 %
    at ω = 4π where the centrifugal stretch is 4× larger; smallest single domain 0.997)

* cpGIMP's total domain area falls to ~2e-4 of its initial value near 90° and 270° and comes
  back to ~0.95 near 180°, in every case (2.5e-5 at Δx = 0.025 m). The minima sit a few degrees
  *after* ωt = 90°, 270° (277° at ω = 2π, Δx = 0.05 m), consistent with the material turning a
  little slower than ωt (the disk loses 2–3 % of its angular momentum and expands slightly).
* CPDI's stress stays near the centrifugal scale (ratio 1.2–1.6, oscillating as the disk
  breathes); the others' grows steadily with the angle turned (noise from cell crossing: 6.3–6.5
  after one revolution at ω = 2π). Refining to Δx = 0.025 m halves uGIMP's and cpGIMP's (3.2,
  3.3) but not mpm's (5.9); at ω = 4π every ratio is smaller because the scale ρ0ω²R² is 4×
  larger while the noise is not.
* Kinetic energy dips periodically (the disk, started unstressed, breathes: exact) and drifts
  down by 3–4 % (Δx = 0.05 m; 0.6–2 % at 0.025 m) for every FLIP method; mpm loses the most.
* B-splines with APIC: the angular momentum stays at 1 within 2.7e-15 over the revolution at
  Δx = 0.05 m (1.1e-15 at ω = 4π, 6.2e-14 at Δx = 0.025 m, 3963 steps), the kinetic energy
  within 0.4 % (end 0.998; 0.993 at ω = 4π, 1.000 at Δx = 0.025 m), and the largest stress
  ratio at 1.27–1.30 in all three cases, as low as CPDI's; with FLIP the same weights lose
  2.6 % of the angular momentum and their stress grows like mpm's (5.35).

Outputs: ``rotation.csv`` (one row per case: the summary figures plus the area ratio near 90°, 180°
and 270°) and ``rotation_history.csv`` (every metrics sample: angle, area ratio, smallest
single-domain ratio, stress, energy and momentum ratios) in ``--out`` (default
``run_scripts/out/rotation``); ``rotation.png`` in ``--out`` too (``make figures`` passes
``--figures docs/figures``): against the rotation angle (ω = 2π, Δx = 0.05 m), the total domain area
over its initial value (log scale; cpGIMP also at ω = 4π, dashed, and Δx = 0.025 m, dotted; thin:
its smallest single domain), the largest stress over ρ0ω²R², kinetic energy and angular momentum
over their initial values; and a bar chart of the largest stress ratio of every case; a colour per
method.

Seeding (``--seeding``). The figures above are the grid-aligned lattice's (``--seeding lattice``,
the disk's seeding when they were measured). The disk's default is now ``conforming``: rings
whose outer particles follow the circle (``parmpm.particles.seeding.polar``), which a disk in
contact needs (``docs/concepts/contact.md``). A free spin is where the rings cost something: a
ring's particles do not sit on the grid's lattice, so at Δx = 0.05 m (16 rings) the FLIP
transfers lose more angular momentum (end, conforming against lattice, 2026-11-29, 2 ranks:
mpm 0.928 / 0.968, uGIMP 0.924 / 0.974, cpGIMP 0.923 / 0.973, B-spline 0.945 / 0.974, CPDI
0.977 / 0.982) and the stress is noisier (largest ratio mpm 9.87 / 6.31, cpGIMP 10.3 / 6.25,
CPDI 2.13 / 1.61). At Δx = 0.025 m the two come within 0.5 % (momentum mpm 0.9949 / 0.9938,
uGIMP 0.9979 / 0.9954, cpGIMP 0.9958 / 0.9955, CPDI 0.9963 / 0.9969, B-spline 0.9913 / 0.9959),
and APIC keeps the angular
momentum to round-off with either. cpGIMP's domains collapse with either; on the coarse
``--quick`` grid (Δx = 0.1 m, 8 rings) the conforming disk turns slower, and its minimum near
270° falls at ωt ≈ 307° instead of 277°.

Runtime, one core: full (18 runs) ~30–75 s (the Δx = 0.025 m runs 2–15 s each); ``--quick``
(6 runs) ~3 s. Results are identical on any number of ranks (only ``wall_seconds`` differs)::

    python run_scripts/studies/rotation.py                   # full study, figure beside the CSV
    python run_scripts/studies/rotation.py --quick --seeding lattice  # the smoke test's mode
    mpirun -n 2 python run_scripts/studies/rotation.py --quick
    python run_scripts/studies/rotation.py --quick --methods cpdi,cpgimp
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py, the groups
from study import (METHOD_KEYS, METHODS as REGISTRY, compact_png, figure, folders, is_root,
                   main_guard, method_keys, parser, run_case, save, scratch_folder, world,
                   write_csv, wrote)

METHODS = METHOD_KEYS  # every registered method (study.METHODS); ``--methods`` picks a subset
TITLES = {m: REGISTRY[m].label for m in METHODS} | {"mpm": "MPM (nominal box)"}
COLOURS = {m: REGISTRY[m].colour for m in METHODS}
OMEGA = 2.0 * math.pi   # rad/s: one revolution per second (the scene)
DX = 0.05               # m, the scene's cell
EXTENT = 1.2            # m: the scene's grid, [-0.6, 0.6]², kept for every cell size
WINDOW = 10.0           # degrees either side of 90°, 180°, 270° for the "near" figures
HISTORY = ("area_ratio", "min_area_ratio", "stress_ratio", "energy_ratio", "momentum_ratio")


@dataclass(frozen=True)
class Case:
    method: str
    omega: float = OMEGA
    dx: float = DX
    seeding: str = "conforming"  # the disk's: rings (the default) or the grid's lattice

    @property
    def id(self) -> str:
        return f"{self.method}_w{self.omega / math.pi:g}pi_dx{self.dx:g}"

    @property
    def variant(self) -> str:
        if self.omega != OMEGA:
            return "omega"
        return "refined" if self.dx < DX else "base"

    def overrides(self) -> list[str]:
        n = round(EXTENT / self.dx)
        end = 2.0 * math.pi / self.omega  # one revolution
        return [*REGISTRY[self.method].overrides(), f"bodies.0.angular_velocity={self.omega!r}",
                f"grid.cell_size={self.dx!r}", f"grid.cells={n}", f"grid.patch_size={max(8, n // 2)}",
                f"time.end={end!r}", f"output.every={end / 8!r}",
                f"bodies.0.seeding={self.seeding}"]


def cases(quick: bool, methods, seeding: str = "conforming") -> list[Case]:
    if quick:
        return [Case(m, OMEGA, 0.1, seeding) for m in methods]
    out = [Case(m, OMEGA, DX, seeding) for m in methods]
    out += [Case(m, 2.0 * OMEGA, DX, seeding) for m in methods]
    out += [Case(m, OMEGA, DX / 2, seeding) for m in methods]
    return out


def near(angle, values, centre: float) -> float:
    """Smallest of ``values`` sampled within ``WINDOW`` degrees of ``centre``."""
    sel = np.abs(np.asarray(angle) - centre) <= WINDOW
    return float(np.min(np.asarray(values)[sel])) if np.any(sel) else math.nan


def run_one(case: Case, comm, scratch: Path):
    summary, wall = run_case("spinning_disk", case.overrides(), comm=comm, out_dir=scratch / case.id)
    m = summary["metrics"]
    h = m["history"]
    angle = np.degrees(case.omega * np.asarray(h["t"]))
    area = np.asarray(h["area_ratio"])
    stress = np.asarray(h["stress_ratio"])
    row = {
        "case": case.id, "method": case.method, "variant": case.variant,
        "update": summary["update"], "lcr": summary["lcr"],
        "omega": case.omega, "dx": case.dx, "particles": summary["particles"],
        "steps": summary["steps"], "end_time": summary["time"],
        "turns": case.omega * summary["time"] / (2.0 * math.pi), "samples": m["samples"],
        "stress_scale": m["stress_scale"],
        "area_ratio_min": m["area_ratio_min"], "angle_at_area_min": float(angle[np.argmin(area)]),
        "area_ratio_max_dev": float(np.max(np.abs(area - 1.0))),
        "area_ratio_near_90": near(angle, area, 90.0), "area_ratio_near_180": near(angle, area, 180.0),
        "area_ratio_near_270": near(angle, area, 270.0),
        "min_area_ratio": m["min_area_ratio"],
        "stress_ratio_max": m["stress_ratio_max"],
        "angle_at_stress_max": float(angle[np.argmax(stress)]),
        "energy_ratio_final": m["energy_ratio_final"], "momentum_ratio_final": m["momentum_ratio_final"],
        "energy_ratio_min": float(np.min(h["energy_ratio"])),
        "wall_seconds": wall,
    }
    hist = [{"case": case.id, "method": case.method, "omega": case.omega, "dx": case.dx,
             "t": float(t), "angle_deg": float(a), **{k: float(h[k][i]) for k in HISTORY}}
            for i, (t, a) in enumerate(zip(h["t"], angle))]
    return row, hist


def chart(rows: list[dict], hist: list[dict], path: Path) -> Path:
    from matplotlib.lines import Line2D

    fig, axes = figure(2, 2, size=(11.5, 7.6))
    ax_a, ax_s, ax_e, ax_b = axes[0, 0], axes[0, 1], axes[1, 0], axes[1, 1]
    styles = {"base": ("-", 1.4), "omega": ("--", 0.9), "refined": (":", 1.1)}
    base = [r for r in rows if r["variant"] == "base"]
    dx = base[0]["dx"] if base else rows[0]["dx"]
    labels = {"base": f"ω = 2π, Δx = {dx:g} m", "omega": "ω = 4π (½ s), Δx = 0.05 m",
              "refined": f"ω = 2π, Δx = {dx / 2:g} m"}

    def series(r, key):
        h = [x for x in hist if x["case"] == r["case"]]
        return [x["angle_deg"] for x in h], [x[key] for x in h]

    for r in rows:
        c = COLOURS[r["method"]]
        ls, lw = styles[r["variant"]]
        if r["variant"] == "base" or r["method"] == "cpgimp":  # cpGIMP collapses in every variant
            ax_a.plot(*series(r, "area_ratio"), ls, color=c, lw=lw)
        if r["variant"] != "base":
            continue
        a, mins = series(r, "min_area_ratio")
        if r["method"] == "cpgimp":
            ax_a.plot(a, np.maximum(mins, 1e-9), "-", color=c, lw=0.6, alpha=0.5)
        ax_s.plot(*series(r, "stress_ratio"), "-", color=c, lw=1.0)
        ax_e.plot(*series(r, "energy_ratio"), "-", color=c, lw=1.1)
        ax_e.plot(*series(r, "momentum_ratio"), "--", color=c, lw=0.9)
    ax_a.text(0.5, 0.45, "uGIMP: fixed boxes;\nMPM, B-spline: nominal box (drawn only):\n"
              "area ratio 1 by construction", transform=ax_a.transAxes,
              ha="center", va="center", fontsize=6.5, color="0.3")
    ax_a.set_yscale("log")
    ax_a.set_ylim(1e-5, 3.0)
    ax_a.set_ylabel("total domain area / initial", fontsize=8)
    ax_a.set_title("Particle domains (cpGIMP: |F_kk|-sized; thin: smallest single domain)", fontsize=9)
    ax_s.set_ylabel("max |σ|_F / (ρ0 ω² R²)", fontsize=8)
    ax_s.set_title("Largest stress over the centrifugal scale", fontsize=9)
    ax_e.set_ylabel("ratio to initial value", fontsize=8)
    ax_e.set_title("Kinetic energy (solid; dips: the disk breathes) and angular momentum (dashed)",
                   fontsize=9)
    for ax in (ax_a, ax_s, ax_e):
        ax.set_xlim(0, 360)
        ax.set_xticks(range(0, 361, 45))
        ax.set_xlabel("rotation angle ωt (degrees)", fontsize=8)
        for x in (90, 180, 270):
            ax.axvline(x, color="0.6", lw=0.5, zorder=0)
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.tick_params(labelsize=7)
    # the variants side by side: largest stress ratio per method
    variants = [v for v in ("base", "omega", "refined") if any(r["variant"] == v for r in rows)]
    methods = [m for m in METHODS if any(r["method"] == m for r in rows)]
    width = 0.8 / len(variants)
    hatches = {"base": "", "omega": "//", "refined": ".."}
    for k, v in enumerate(variants):
        for i, m in enumerate(methods):
            r = next((x for x in rows if x["method"] == m and x["variant"] == v), None)
            if r is None:
                continue
            xpos = i + (k - (len(variants) - 1) / 2) * width
            ax_b.bar(xpos, r["stress_ratio_max"], width * 0.92, color=COLOURS[m], hatch=hatches[v],
                     edgecolor="k", linewidth=0.4)
            ax_b.text(xpos, r["stress_ratio_max"], f"{r['stress_ratio_max']:.2g}", ha="center",
                      va="bottom", fontsize=6.5)
    ax_b.set_ylim(0, 1.3 * max(r["stress_ratio_max"] for r in rows))
    ax_b.set_xticks(range(len(methods)))
    ax_b.set_xticklabels([TITLES[m] for m in methods], fontsize=7)
    ax_b.set_ylabel("max over the revolution of |σ|_F / (ρ0 ω² R²)", fontsize=8)
    ax_b.set_title("Largest stress ratio per case", fontsize=9)
    ax_b.tick_params(labelsize=7)
    ax_b.grid(True, axis="y", lw=0.3, alpha=0.5)
    from matplotlib.patches import Patch
    ax_b.legend(handles=[Patch(facecolor="white", edgecolor="k", hatch=hatches[v], label=labels[v])
                         for v in variants], fontsize=7, loc="upper right")
    handles = [Line2D([], [], color=COLOURS[m], lw=1.5, label=TITLES[m]) for m in methods]
    if len(variants) > 1:
        handles += [Line2D([], [], color="tab:orange", ls=styles[v][0], lw=styles[v][1], label=labels[v])
                    for v in variants]
    ax_a.legend(handles=handles, fontsize=6.5, loc="lower left", ncol=2, framealpha=0.9)
    fig.suptitle("Spinning disk through one revolution "
                 f"(R = 0.4 m, ppc 2; {labels['base']} unless marked)", fontsize=10)
    return compact_png(save(fig, path))


def main() -> int:
    ap = parser(__doc__)
    ap.add_argument("--methods", default=",".join(METHODS),
                    help="comma-separated subset of " + ", ".join(METHODS))
    ap.add_argument("--seeding", default="conforming", choices=("conforming", "lattice"),
                    help="the disk's particles: rings that follow the circle (the scene's "
                         "default) or the grid-aligned lattice")
    args = ap.parse_args()
    methods = method_keys(args.methods, METHODS)
    comm = world()
    root = is_root(comm)
    out, figs = folders(args, "rotation")
    rows, hist = [], []
    t0 = time.perf_counter()
    with scratch_folder(comm, "parmpm-rotation-") as scratch:
        for case in cases(args.quick, methods, args.seeding):
            row, h = run_one(case, comm, scratch)
            rows.append(row)
            hist += h
            if root:
                print(f"{case.id:30s} area min {row['area_ratio_min']:.3g} at "
                      f"{row['angle_at_area_min']:.0f}°, near 90° {row['area_ratio_near_90']:.3g}; "
                      f"stress max {row['stress_ratio_max']:.3g}; energy "
                      f"{row['energy_ratio_final']:.3f}, momentum {row['momentum_ratio_final']:.6g}; "
                      f"{row['particles']} particles, {row['steps']} steps, {row['wall_seconds']:.1f} s",
                      flush=True)
    write_csv(out / "rotation.csv", rows, comm)
    write_csv(out / "rotation_history.csv", hist, comm)
    if root:
        path = chart(rows, hist, figs / "rotation.png")
        print(f"{len(rows)} runs in {time.perf_counter() - t0:.0f} s on {comm.Get_size()} rank(s)")
        print(f"wrote {out / 'rotation.csv'} and rotation_history.csv")
        print(wrote(path))
    return 0


if __name__ == "__main__":
    main_guard(main)
