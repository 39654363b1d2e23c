"""A disk (2D) or sphere (3D) on a held block under tilted gravity: contact's acceleration against
Newton's, refined.

Physics. A neo-Hookean disk (R = 0.1 m, E = 1 MPa, ν = 0.3, ρ = 1000 kg/m³) rests on a
1.2 × 0.1 m block of the same material that the grid's bottom face holds (``y_min = "fixed"``);
gravity is tilted by θ = 30° (``g = [g sin θ, −g cos θ]``, applied at once, or with ``--ramp T``
over T seconds, the fit window then T later), and the two bodies
are separate velocity fields (``[contact]``, Coulomb friction μ). Only the contact acts between
them, so with ``k = I/(m R²)`` (½ for the disk, ⅖ for the sphere) the centre accelerates along
the block at

* μ = 0: ``g sin θ`` (slides, no spin);
* μ < k/(1 + k) tan θ: ``g (sin θ − μ cos θ)`` (slides and rolls);
* otherwise, or "stick": ``g sin θ/(1 + k)`` (rolls without slipping: ⅔ g sin θ for the
  disk, 5/7 g sin θ for the sphere).

``--dim 3``: the sphere (same radius and material) on a 0.48 × 0.1 × 0.2 m block in a grid
0.3 m deep. The acceleration is the slope of the body's mean velocity (a history probe on
body 1, mass-weighted) fitted over 0.05–0.15 s.

Cases: ``--methods`` × ``--normals`` (``[contact] normal``) × μ ∈ ``--frictions`` (default
0, 0.1, 0.3; "stick" for no slip at all) × R/Δx ∈
``--resolutions`` × ``--seedings`` ("conforming": rings or shells, the outline followed;
"lattice": the grid-aligned lattice masked by the circle, with flats). ``--quick``: cpdi,
μ = 0, R/Δx = 5, both seedings.

Outputs: ``disk_on_block.csv`` (one row per case: a/exact, the fitted acceleration, the
contact's friction over its normal push on the body (``mu_eff``: μ while it slides, whatever the
drop's bounce does to the push), particles, steps, wall seconds) and ``disk_on_block.png`` (a/exact against R/Δx, one panel per μ) in
``--out`` (default ``run_scripts/out/disk_on_block``).

    mpirun -n 2 python run_scripts/studies/disk_on_block.py --resolutions 10 20 --methods cpdi
"""
from __future__ import annotations

import csv
import math
import sys
from pathlib import Path

import numpy as np

if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py
from study import (figure, folders, is_root, main_guard, parser, read_csv, run_case,  # noqa: E402
                   save, world, write_csv, wrote)

G = 9.81
THETA = math.radians(30.0)
R = 0.1
FIT = (0.05, 0.15)


def fit_window(ramp: float = 0.0) -> tuple[float, float]:
    """The fit window: ``FIT`` after gravity has come in full (at once, or after its ramp)."""
    return ramp + FIT[0], ramp + FIT[1]
FRICTIONS = (0.0, 0.1, 0.3)


def exact(mu: float, dim: int = 2) -> float:
    """The body centre's acceleration along the block (module doc)."""
    k = 0.5 if dim == 2 else 0.4  # I / (m R²): disk, sphere
    if mu >= k / (1.0 + k) * math.tan(THETA):
        return G * math.sin(THETA) / (1.0 + k)
    return G * (math.sin(THETA) - mu * math.cos(THETA))


def friction_arg(text: str) -> float:
    """A ``--frictions`` item: μ ≥ 0, or "stick" (μ = ∞: the contact keeps every node's fields
    together while they push)."""
    return math.inf if text == "stick" else float(text)


def scene_text(method: str, per_radius: int, mu: float, seeding: str,
               normal: str = "separating", dim: int = 2, gap: str = "column",
               ramp: float = 0.0) -> str:
    h = R / per_radius
    end = fit_window(ramp)[1]
    friction = ('friction = "stick"' if math.isinf(mu) else
                f"friction = {mu}" if mu > 0 else "")
    if dim == 2:
        grid = f"cells = [{round(1.2 / h)}, {round(0.35 / h)}]"
        block = "min = [0.0, 0.0]\nmax = [1.2, 0.1]"
        body = f'shape = "disk"\ncenter = [0.2, {0.1 + R}]'
    else:
        grid = f"cells = [{round(0.5 / h)}, {round(0.35 / h)}, {round(0.3 / h)}]"
        block = "min = [0.0, 0.0, 0.05]\nmax = [0.48, 0.1, 0.25]"
        body = f'shape = "sphere"\ncenter = [0.15, {0.1 + R}, 0.15]'
    gravity = [G * math.sin(THETA), -G * math.cos(THETA)] + [0.0] * (dim - 2)
    return f"""
name = "disk_on_block"
dim = {dim}
[grid]
cell_size = {h}
{grid}
[method]
interpolator = "{method}"
[materials.rubber]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1e6
poisson_ratio = 0.3
[[bodies]]
shape = "box"
material = "rubber"
{block}
[[bodies]]
{body}
material = "rubber"
radius = {R}
seeding = "{seeding}"
[boundary]
y_min = "fixed"
[gravity]
g = {gravity}
ramp_time = {ramp}
[contact]
normal = "{normal}"
gap = "{gap}"
{friction}
[time]
end = {end}
[output]
every = {end}
[output.history]
every_steps = 5
[[output.history.probes]]
name = "disk"
body = 1
field = "v.x"
stats = ["mean"]
"""


def fitted_acceleration(history: Path, ramp: float = 0.0) -> tuple[float, float]:
    """The slope of the body's mean velocity over the fit window (least squares), and the
    contact's friction over its normal push on the body in that window (the change of its
    impulse along x over that along y): μ while it slides. The dropped body bounces on the block
    at about 16 Hz (gravity comes at once), so its normal push, and with friction its
    acceleration, swing by ±15 % within the window; the impulse ratio does not."""
    with open(history) as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["time"]) for r in rows])
    v = np.array([float(r["disk.v.x.mean"]) for r in rows])
    lo, hi = fit_window(ramp)
    keep = (t >= lo) & (t <= hi)
    i, j = np.flatnonzero(keep)[[0, -1]]
    jx, jy = (float(rows[j][f"contact1.impulse_{a}"]) - float(rows[i][f"contact1.impulse_{a}"])
              for a in "xy")
    return float(np.polyfit(t[keep], v[keep], 1)[0]), -jx / jy if jy else math.nan


def run(method: str, per_radius: int, mu: float, seeding: str, runs: Path, comm,
        normal: str = "separating", dim: int = 2, gap: str = "column", ramp: float = 0.0) -> dict:
    from parmpm.scene.load import scene_from_toml

    out = runs / f"{method}_{seeding}_{normal}_{gap}_{dim}d_R{per_radius}_mu{mu}_ramp{ramp}"
    text = scene_text(method, per_radius, mu, seeding, normal, dim, gap, ramp)
    summary, wall = run_case(scene_from_toml(text), comm=comm, out_dir=out)
    a, mu_eff = (fitted_acceleration(out / "history.csv", ramp) if is_root(comm)
                 else (math.nan, math.nan))
    return {"method": method, "seeding": seeding, "normal": normal, "gap": gap, "dim": dim,
            "ramp": ramp, "R_over_dx": per_radius, "mu": mu,
            "exact": exact(mu, dim), "a": a, "ratio": a / exact(mu, dim), "mu_eff": mu_eff,
            "particles": summary["particles"], "steps": summary["steps"], "wall_s": wall}


def stored(row: dict) -> dict:
    """A CSV row read back (strings) as :func:`run` made it, for ``--replot``."""
    return {**row, "mu": friction_arg(row["mu"]), "dim": int(row["dim"]),
            "R_over_dx": int(row["R_over_dx"]), "ratio": float(row["ratio"])}


def plot(rows: list[dict], path: Path) -> Path:
    frictions = sorted({r["mu"] for r in rows})
    fig, axes = figure(1, len(frictions), size=(4.2 * len(frictions), 3.8))
    axes = axes.ravel()
    for ax, mu in zip(axes, frictions):
        for key in sorted({(r["method"], r["seeding"], r["normal"], r["gap"]) for r in rows
                           if r["mu"] == mu}):
            pts = sorted((r["R_over_dx"], r["ratio"]) for r in rows
                         if (r["method"], r["seeding"], r["normal"], r["gap"]) == key
                         and r["mu"] == mu)
            ax.plot(*zip(*pts), "o-" if key[1] == "conforming" else "s--",
                    label=" ".join(key))
        ax.axhline(1.0, color="k", lw=0.8)
        ax.axhspan(0.98, 1.02, color="0.9")
        ax.set_xscale("log", base=2)
        ticks = sorted({r["R_over_dx"] for r in rows})
        ax.set_xticks(ticks, labels=[str(t) for t in ticks])
        ax.minorticks_off()
        ax.set_xlabel("R / Δx")
        name = "stick" if math.isinf(mu) else f"μ = {mu}"
        ax.set_title(f"{name}: exact {exact(mu, rows[0]['dim']):.4g} m/s²")
    axes[0].set_ylabel("a / exact")
    axes[0].legend(fontsize=8)
    return save(fig, path)


def main() -> int:
    p = parser(__doc__)
    p.add_argument("--methods", nargs="+", default=["cpdi"])
    p.add_argument("--resolutions", nargs="+", type=int, default=[10, 20])
    p.add_argument("--frictions", nargs="+", type=friction_arg, default=list(FRICTIONS),
                   help='Coulomb μ, or "stick"')
    p.add_argument("--seedings", nargs="+", default=["conforming", "lattice"])
    p.add_argument("--dim", type=int, choices=(2, 3), default=2)
    p.add_argument("--normals", nargs="+", default=["separating"],
                   help="[contact] normal: separating, heavy, centroids, gradient, average")
    p.add_argument("--gaps", nargs="+", default=["column"], help="[contact] gap: column, line")
    p.add_argument("--replot", nargs="+", type=Path, metavar="CSV",
                   help="no runs: the figure of these studies' CSV rows together")
    p.add_argument("--ramp", type=float, default=0.0,
                   help="gravity's ramp time (s; default 0: at once); the fit window follows it")
    args = p.parse_args()
    if args.quick:
        args.methods, args.resolutions, args.frictions = ["cpdi"], [5], [0.0]
    out, figs = folders(args, "disk_on_block")
    if args.replot:
        rows = [stored(r) for path in args.replot for r in read_csv(path)]
        print(wrote(plot(rows, figs / "disk_on_block.png")))
        return 0
    comm = world()
    rows = []
    cases = [(m, s, nm, g, mu, n) for m in args.methods for s in args.seedings
             for nm in args.normals for g in args.gaps for mu in args.frictions
             for n in args.resolutions]
    for method, seeding, normal, gap, mu, n in cases:
        rows.append(run(method, n, mu, seeding, out / "runs", comm, normal, args.dim, gap,
                        args.ramp))
        if is_root(comm):
            r = rows[-1]
            print(f"{method:7s} {seeding:10s} {normal:10s} {gap:6s} mu={mu:<4} R/dx={n:<3d} "
                  f"a/exact={r['ratio']:.4f} mu_eff={r['mu_eff']:.4f}  "
                  f"({r['particles']} particles, {r['steps']} steps, {r['wall_s']:.1f} s)",
                  flush=True)
    if is_root(comm):
        write_csv(out / "disk_on_block.csv",
                  [{**r, "mu": "stick" if math.isinf(r["mu"]) else r["mu"]} for r in rows])
        print(wrote(out / "disk_on_block.csv"))
        print(wrote(plot(rows, figs / "disk_on_block.png")))
    return 0


if __name__ == "__main__":
    main_guard(main)
