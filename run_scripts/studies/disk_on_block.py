"""A disk on a held block under tilted gravity: contact's acceleration against Newton's, refined.

Physics. A neo-Hookean disk (R = 0.1 m, E = 1 MPa, ν = 0.3, ρ = 1000 kg/m³) rests on a
1.2 × 0.1 m block of the same material that the grid's bottom face holds (``y_min = "fixed"``);
gravity is tilted by θ = 30° (``g = [g sin θ, −g cos θ]``, applied at once), and the two bodies
are separate velocity fields (``[contact]``, Coulomb friction μ). Only the contact acts between
them, so the disk's centre accelerates along the block at

* μ = 0: ``g sin θ`` (slides, no spin);
* μ < tan θ / 3: ``g (sin θ − μ cos θ)`` (slides and rolls);
* μ ≥ tan θ / 3, or "stick": ``(2/3) g sin θ`` (rolls without slipping, ``I = ½ m R²``).

The acceleration is the slope of the disk's mean velocity (a history probe on body 1,
mass-weighted) fitted over 0.05–0.15 s.

Cases: ``--methods`` × μ ∈ {0, 0.1, 0.3} × R/Δx ∈ ``--resolutions`` × ``--seedings``
("conforming": the disk in rings, its outline followed; "lattice": the grid-aligned lattice
masked by the circle, with flats). ``--quick``: cpdi, μ = 0, R/Δx = 5, both seedings.

Outputs: ``disk_on_block.csv`` (one row per case: a/exact, the fitted acceleration, particles,
steps, wall seconds) and ``disk_on_block.png`` (a/exact against R/Δx, one panel per μ) in
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
from study import (figure, folders, is_root, main_guard, parser, run_case, save, world,  # noqa: E402
                   write_csv, wrote)

G = 9.81
THETA = math.radians(30.0)
R = 0.1
FIT = (0.05, 0.15)
FRICTIONS = (0.0, 0.1, 0.3)


def exact(mu: float) -> float:
    """The disk centre's acceleration along the block (module doc)."""
    if mu >= math.tan(THETA) / 3.0:
        return 2.0 / 3.0 * G * math.sin(THETA)
    return G * (math.sin(THETA) - mu * math.cos(THETA))


def scene_text(method: str, per_radius: int, mu: float, seeding: str) -> str:
    h = R / per_radius
    friction = f"friction = {mu}" if mu > 0 else ""
    return f"""
name = "disk_on_block"
dim = 2
[grid]
cell_size = {h}
cells = [{round(1.2 / h)}, {round(0.35 / h)}]
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
min = [0.0, 0.0]
max = [1.2, 0.1]
[[bodies]]
shape = "disk"
material = "rubber"
center = [0.2, {0.1 + R}]
radius = {R}
seeding = "{seeding}"
[boundary]
y_min = "fixed"
[gravity]
g = [{G * math.sin(THETA)}, {-G * math.cos(THETA)}]
[contact]
{friction}
[time]
end = {FIT[1]}
[output]
every = {FIT[1]}
[output.history]
every_steps = 5
[[output.history.probes]]
name = "disk"
body = 1
field = "v.x"
stats = ["mean"]
"""


def fitted_acceleration(history: Path) -> float:
    """The slope of the disk's mean velocity over the fit window (least squares)."""
    with open(history) as f:
        rows = [(float(r["time"]), float(r["disk.v.x.mean"])) for r in csv.DictReader(f)]
    t, v = np.array(rows).T
    keep = (t >= FIT[0]) & (t <= FIT[1])
    return float(np.polyfit(t[keep], v[keep], 1)[0])


def run(method: str, per_radius: int, mu: float, seeding: str, runs: Path, comm) -> dict:
    from parmpm.scene.load import scene_from_toml

    out = runs / f"{method}_{seeding}_R{per_radius}_mu{mu}"
    summary, wall = run_case(scene_from_toml(scene_text(method, per_radius, mu, seeding)),
                             comm=comm, out_dir=out)
    a = fitted_acceleration(out / "history.csv") if is_root(comm) else math.nan
    return {"method": method, "seeding": seeding, "R_over_dx": per_radius, "mu": mu,
            "exact": exact(mu), "a": a, "ratio": a / exact(mu),
            "particles": summary["particles"], "steps": summary["steps"], "wall_s": wall}


def plot(rows: list[dict], path: Path) -> Path:
    frictions = sorted({r["mu"] for r in rows})
    fig, axes = figure(1, len(frictions), size=(4.2 * len(frictions), 3.8))
    axes = axes.ravel()
    for ax, mu in zip(axes, frictions):
        for key in sorted({(r["method"], r["seeding"]) for r in rows if r["mu"] == mu}):
            pts = sorted((r["R_over_dx"], r["ratio"]) for r in rows
                         if (r["method"], r["seeding"]) == key and r["mu"] == mu)
            ax.plot(*zip(*pts), "o-" if key[1] == "conforming" else "s--",
                    label=f"{key[0]} {key[1]}")
        ax.axhline(1.0, color="k", lw=0.8)
        ax.axhspan(0.98, 1.02, color="0.9")
        ax.set_xscale("log", base=2)
        ax.set_xticks(sorted({r["R_over_dx"] for r in rows}), labels=None)
        ax.set_xlabel("R / Δx")
        ax.set_title(f"μ = {mu}: exact {exact(mu):.4g} m/s²")
    axes[0].set_ylabel("a / exact")
    axes[0].legend(fontsize=8)
    return save(fig, path)


def main() -> int:
    p = parser(__doc__)
    p.add_argument("--methods", nargs="+", default=["cpdi"])
    p.add_argument("--resolutions", nargs="+", type=int, default=[10, 20])
    p.add_argument("--frictions", nargs="+", type=float, default=list(FRICTIONS))
    p.add_argument("--seedings", nargs="+", default=["conforming", "lattice"])
    args = p.parse_args()
    if args.quick:
        args.methods, args.resolutions, args.frictions = ["cpdi"], [5], [0.0]
    out, figs = folders(args, "disk_on_block")
    comm = world()
    rows = []
    for method in args.methods:
        for seeding in args.seedings:
            for mu in args.frictions:
                for n in args.resolutions:
                    rows.append(run(method, n, mu, seeding, out / "runs", comm))
                    if is_root(comm):
                        r = rows[-1]
                        print(f"{method:7s} {seeding:10s} mu={mu:<4} R/dx={n:<3d} "
                              f"a/exact={r['ratio']:.4f}  ({r['particles']} particles, "
                              f"{r['steps']} steps, {r['wall_s']:.1f} s)", flush=True)
    if is_root(comm):
        write_csv(out / "disk_on_block.csv", rows)
        print(wrote(out / "disk_on_block.csv"))
        print(wrote(plot(rows, figs / "disk_on_block.png")))
    return 0


if __name__ == "__main__":
    main_guard(main)
