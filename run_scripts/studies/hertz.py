"""Two equal elastic spheres meet head on: the contact's force history against Hertz's, refined.

Physics. Two neo-Hookean spheres (R = 0.1 m, E = 1 MPa, ν = 0.3, ρ = 1000 kg/m³, seeded in
shells) approach along x at ``v = ±V/2`` (``V`` = 0.5 m/s by default) with a gap ``GAP``
between their surfaces, and are separate velocity fields (``[contact]``, frictionless). Hertz
(1882; Johnson, *Contact Mechanics*, 1985, §4.2 and §11.4): with the overlap ``δ`` of the two
undeformed surfaces, ``R* = R/2``, ``E* = E/(2(1 − ν²))`` and ``m* = m/2``, the force is
``F = (4/3) E* √R* δ^{3/2}``, and ``m* δ'' = −F`` gives

* the largest overlap ``δ_max = (15 m* V² / (16 E* √R*))^{2/5}``,
* the peak force ``F_max = (4/3) E* √R* δ_max^{3/2}``,
* the contact's duration ``t_c = 2.868 (m*² / (R* E*² V))^{1/5}`` (the integral
  ``∫₀¹ dx/√(1 − x^{5/2})`` = 1.4716 times ``2 δ_max / V``).

At V = 0.5 m/s: ``δ_max`` = 6.9 mm, contact radius ``a = √(R* δ_max)`` = 18.6 mm (a/R =
0.19), ``F_max`` = 94.5 N, ``t_c`` = 40.8 ms; the peak pressure is 0.13 E, so the
neo-Hookean spheres are near, not inside, Hertz's small-strain assumptions.

Measured: the contact force on sphere 1 (history column ``contact1.force_x``, every step); when
it starts against when the surfaces touch (``onset_ms``: ``GAP/V`` after the start); its peak; its duration (the span where it exceeds 5 % of its peak, against the same span of
Hertz's force history, integrated here with RK4 — :func:`hertz_history`); the impulse
(``m V`` for an elastic rebound) and the rebound's restitution (sphere 1's mean velocity after
against before). ``--ppc``: particles per cell per axis (the shells' spacing Δx/ppc).

Outputs: ``hertz.csv`` (one row per R/Δx: duration, peak force and their ratios to Hertz's,
impulse, restitution, particles, steps, wall seconds) and ``hertz.png`` (force histories
against Hertz's) in ``--out`` (default ``run_scripts/out/hertz``).

    mpirun -n 2 python run_scripts/studies/hertz.py --resolutions 5 10 20
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

R = 0.1
E = 1.0e6
NU = 0.3
RHO = 1000.0
GAP = 0.002
THRESHOLD = 0.05  # the duration: the span where the force exceeds this share of its peak


def hertz_constants(speed: float, against: str = "sphere") -> dict:
    """Hertz's closed forms for two equal spheres meeting at relative ``speed``, or (``against``
    "wall") one sphere meeting a rigid plane: ``m* = m``, ``R* = R``, ``E* = E/(1 − ν²)``."""
    m = RHO * 4.0 / 3.0 * math.pi * R ** 3
    if against == "wall":
        ms, rs, es = m, R, E / (1.0 - NU ** 2)
    else:
        ms, rs, es = m / 2.0, R / 2.0, E / (2.0 * (1.0 - NU ** 2))
    stiff = 4.0 / 3.0 * es * math.sqrt(rs)
    dmax = (15.0 * ms * speed ** 2 / (16.0 * es * math.sqrt(rs))) ** 0.4
    return {"mass": m, "m_star": ms, "stiffness": stiff, "delta_max": dmax,
            "force_max": stiff * dmax ** 1.5, "radius_max": math.sqrt(rs * dmax),
            "duration": 2.868 * (ms ** 2 / (rs * es ** 2 * speed)) ** 0.2}


def hertz_history(speed: float, steps: int = 20000,
                  against: str = "sphere") -> tuple[np.ndarray, np.ndarray]:
    """Time from first touch and Hertz's force, ``m* δ'' = −k δ^{3/2}`` integrated with RK4
    from ``δ = 0``, ``δ' = speed`` until the spheres part."""
    c = hertz_constants(speed, against)
    k, ms = c["stiffness"], c["m_star"]
    dt = 1.2 * c["duration"] / steps

    def rate(y):
        return np.array([y[1], -k * max(y[0], 0.0) ** 1.5 / ms])

    y = np.array([0.0, speed])
    t, out = [0.0], [0.0]
    for i in range(steps):
        a = rate(y)
        b = rate(y + 0.5 * dt * a)
        cc = rate(y + 0.5 * dt * b)
        d = rate(y + dt * cc)
        y = y + dt / 6.0 * (a + 2 * b + 2 * cc + d)
        t.append((i + 1) * dt)
        out.append(k * max(y[0], 0.0) ** 1.5)
        if y[0] < 0.0:
            break
    return np.array(t), np.array(out)


def span_above(t: np.ndarray, f: np.ndarray, share: float = THRESHOLD) -> float:
    """How long ``f`` stays above ``share`` of its peak (first to last crossing, linearly
    interpolated)."""
    level = share * f.max()
    above = np.flatnonzero(f > level)
    i, j = above[0], above[-1]
    t0 = t[i - 1] + (level - f[i - 1]) / (f[i] - f[i - 1]) * (t[i] - t[i - 1]) if i else t[0]
    t1 = (t[j] + (level - f[j]) / (f[j + 1] - f[j]) * (t[j + 1] - t[j])
          if j + 1 < t.size else t[-1])
    return float(t1 - t0)


def scene_text(method: str, per_radius: int, speed: float, ppc: int,
               normal: str = "separating", gap: str = "column",
               material: str = "neo_hookean", against: str = "sphere") -> str:
    h = R / per_radius
    margin = 3 * h + 0.01
    half_yz = R + margin
    end = GAP / speed + 1.4 * hertz_constants(speed, against)["duration"]
    c = R + GAP / 2
    sphere = f"""[[bodies]]
shape = "sphere"
material = "rubber"
radius = {R}
ppc = [{ppc}, {ppc}, {ppc}]
"""
    if against == "wall":  # one sphere moving at V onto the plane x = 0
        lo = -(2 * R + GAP + margin)
        cells = [math.ceil((margin - lo) / h)] + [math.ceil(2 * half_yz / h)] * 2
        bodies = f"""{sphere}center = [{-(R + GAP)}, 0.0, 0.0]
velocity = [{speed}, 0.0, 0.0]
[[walls]]
name = "plane"
point = [0.0, 0.0, 0.0]
normal = [-1.0, 0.0, 0.0]
"""
        ball = 0
    else:
        lo = -(2 * R + GAP / 2 + margin)
        cells = [math.ceil(-2 * lo / h)] + [math.ceil(2 * half_yz / h)] * 2
        bodies = f"""{sphere}center = [{-c}, 0.0, 0.0]
velocity = [{speed / 2}, 0.0, 0.0]
{sphere}center = [{c}, 0.0, 0.0]
velocity = [{-speed / 2}, 0.0, 0.0]
[contact]
normal = "{normal}"
gap = "{gap}"
"""
        ball = 1
    return f"""
name = "hertz"
dim = 3
[grid]
cell_size = {h}
cells = {cells}
origin = [{lo}, {-cells[1] * h / 2}, {-cells[2] * h / 2}]
[method]
interpolator = "{method}"
[materials.rubber]
model = "{material}"
density = {RHO}
youngs_modulus = {E}
poisson_ratio = {NU}
{bodies}[time]
end = {end}
[output]
every = {end}
[output.history]
every_steps = 1
[[output.history.probes]]
name = "ball"
body = {ball}
field = "v.x"
stats = ["mean"]
"""


def measured(history: Path, speed: float, against: str = "sphere") -> dict:
    """Peak force, duration, impulse and restitution from a run's history (module doc)."""
    with open(history) as f:
        rows = list(csv.DictReader(f))
    column = "plane" if against == "wall" else "contact1"
    t = np.array([float(r["time"]) for r in rows])
    force = np.abs([float(r[f"{column}.force_x"]) for r in rows])
    v = np.array([float(r["ball.v.x.mean"]) for r in rows])
    c = hertz_constants(speed, against)
    t_h, f_h = hertz_history(speed, against=against)
    duration = span_above(t, force)
    impulse = abs(float(rows[-1][f"{column}.impulse_x"]))
    pushed = np.flatnonzero(force > 0.0)
    onset = float(t[pushed[0]]) - GAP / speed if pushed.size else math.nan
    return {"onset_ms": 1e3 * onset,
            "duration": duration, "duration_ratio": duration / span_above(t_h, f_h),
            "peak": float(force.max()), "peak_ratio": float(force.max()) / c["force_max"],
            "impulse_ratio": impulse / (2.0 * c["m_star"] * speed),
            "restitution": float(-v[-1] / v[0]) if v[0] else math.nan,
            "t": t, "force": force}


def run(method: str, per_radius: int, speed: float, ppc: int, runs: Path, comm,
        normal: str = "separating", gap: str = "column", material: str = "neo_hookean",
        against: str = "sphere") -> dict:
    from parmpm.scene.load import scene_from_toml

    out = runs / f"{method}_{against}_{normal}_{gap}_{material}_R{per_radius}_ppc{ppc}_v{speed}"
    text = scene_text(method, per_radius, speed, ppc, normal, gap, material, against)
    summary, wall = run_case(scene_from_toml(text), comm=comm, out_dir=out)
    m = measured(out / "history.csv", speed, against) if is_root(comm) else {}
    return {"method": method, "against": against, "normal": normal, "gap": gap,
            "material": material,
            "R_over_dx": per_radius, "ppc": ppc,
            "speed": speed,
            **{k: v for k, v in m.items() if k not in ("t", "force")},
            "particles": summary["particles"], "steps": summary["steps"], "wall_s": wall,
            "_t": m.get("t"), "_force": m.get("force")}


def plot(rows: list[dict], speed: float, against: str, path: Path) -> Path:
    fig, axes = figure(1, 1, size=(6.4, 4.2))
    ax = axes[0, 0]
    t_h, f_h = hertz_history(speed, against=against)
    ax.plot(1e3 * (t_h + GAP / speed), f_h, "k-", lw=2, label="Hertz")
    for r in rows:
        ax.plot(1e3 * r["_t"], r["_force"], lw=1,
                label=f"{r['method']} {r['material']} R/Δx = {r['R_over_dx']}")
    ax.set_xlabel("t (ms)")
    ax.set_ylabel("contact force (N)")
    ax.set_title(f"a sphere on a rigid wall, V = {speed} m/s" if against == "wall" else
                 f"two spheres, V = {speed} m/s")
    ax.legend(fontsize=8)
    return save(fig, path)


def main() -> int:
    p = parser(__doc__)
    p.add_argument("--methods", nargs="+", default=["cpdi"])
    p.add_argument("--resolutions", nargs="+", type=int, default=[5, 10])
    p.add_argument("--speed", type=float, default=0.5, help="closing speed V (m/s)")
    p.add_argument("--ppc", type=int, default=1)
    p.add_argument("--normals", nargs="+", default=["separating"], help="[contact] normal")
    p.add_argument("--gaps", nargs="+", default=["column"], help="[contact] gap")
    p.add_argument("--materials", nargs="+", default=["neo_hookean"],
                   help="the spheres' law: neo_hookean, linear_elastic (Hertz's)")
    p.add_argument("--against", choices=("sphere", "wall"), default="sphere",
                   help='"wall": one sphere onto a rigid frictionless [[walls]] plane')
    args = p.parse_args()
    if args.quick:
        args.resolutions = [4]
    out, figs = folders(args, "hertz")
    comm = world()
    rows = []
    cases = [(m, nm, g, law, n) for m in args.methods for nm in args.normals for g in args.gaps
             for law in args.materials for n in args.resolutions]
    for method, normal, gap, law, n in cases:
        rows.append(run(method, n, args.speed, args.ppc, out / "runs", comm, normal, gap, law,
                        args.against))
        if is_root(comm):
            r = rows[-1]
            print(f"{method:7s} {normal} {gap} {law} R/dx={n:<3d} onset={r['onset_ms']:+.2f} ms "
                  f"duration/Hertz={r['duration_ratio']:.4f} "
                  f"peak/Hertz={r['peak_ratio']:.4f} impulse/2m*V={r['impulse_ratio']:.4f} "
                  f"restitution={r['restitution']:.4f} ({r['particles']} particles, "
                  f"{r['steps']} steps, {r['wall_s']:.1f} s)", flush=True)
    if is_root(comm):
        write_csv(out / "hertz.csv", [{k: v for k, v in r.items() if not k.startswith("_")}
                                      for r in rows])
        print(wrote(out / "hertz.csv"))
        print(wrote(plot(rows, args.speed, args.against, figs / "hertz.png")))
    return 0


if __name__ == "__main__":
    main_guard(main)
