"""A finite-element reference for the self-weighted bar, and the MPM bar against it.

Physics. The bar of Sadeghirad, Brannon & Burghardt (2011): 1 m × 1 m, neo-Hookean
(E = 1 MPa, ν = 0.3, ρ0 = 1050 kg/m³; Kirchhoff stress ``τ = μ(b − I) + λ ln J I``), plane
strain, gravity of 1000 m/s² switched on at t = 0. The top edge (y = 0) is held vertically only,
a roller, as published (``--support clamped`` holds both components). Mirror symmetry about
x = 0.5 leaves no sideways rigid-body mode to pin. The reference is a total-Lagrangian finite
element model of the same bar: bilinear quadrilaterals (Q1, 2×2 Gauss points) on an n × n mesh,
lumped (row-sum) mass, explicit central-difference integration (Belytschko, Liu & Moran 2000,
§6.2), with the time step ``Δt = cfl·h / c`` recomputed every step from the largest reference-
configuration wave speed ``c² = [μ(1 + s⁻²) + λ(1 + |ln J|) s⁻²]/ρ0`` over the Gauss points (s the
smallest principal stretch; this bounds the neo-Hookean acoustic tensor, which stiffens where
the bar contracts sideways). Numpy-vectorised over elements: no Python loop over elements or
nodes.

Measured: the vertical displacement of the bar's bottom corner, at the reference position of
the MPM run's bottom-left particle (Δx/6 in from the corner at 3 particles per cell; the FE
field is interpolated there), its first peak (value, time) and rebound (the highest point of the
following upswing, :func:`parmpm.output.metrics.bars.first_peak_and_rebound` on both). The FE model
converges by refinement (n = 20, 40, 80 in the full study); the MPM runs are the
built-in ``hanging_bar`` scene (cpdi, Δx = 0.1 m, 3 particles per cell per axis) and the same
at Δx = 0.05 m, both with the roller and clamped support.

Found (full study; FE sampled at the Δx = 0.1 m corner particle (1/60, −59/60); m, s)::

    model                       first peak  at       rebound  at
    FE 20 x 20, roller          -1.6757     0.0900   +0.041   0.185
    FE 40 x 40                  -1.6765     0.0900   +0.045   0.184
    FE 80 x 80                  -1.6767     0.0899   +0.045   0.185
    MPM cpdi dx 0.1, roller     -1.6640     0.0925   -0.023   0.184
    MPM cpdi dx 0.05 (own pt)   -1.6753     0.0903   +0.023   0.186   (FE 80 there: -1.6760)
    FE 80 x 80, clamped         -1.5880     0.0896
    MPM cpdi dx 0.1, clamped    -1.5806     0.0910   -0.031   0.180

The FE peak changes 0.05 % (20 -> 40) and 0.01 % (40 -> 80); halving the time step at 40 x 40
changes it by 2e-6 m. cpdi is within 0.8 % (Δx = 0.1 m) and 0.05 % (0.05 m) of it.

Outputs: ``fe_bar.csv`` (one row per run: model, support, resolution, first peak, its time,
rebound, its time) in ``--out`` (default ``run_scripts/out/fe_bar``) and ``fe_bar.png`` (the
corner histories) in ``--out`` too (``make figures`` passes ``--figures docs/figures``).

Runtime: full ~10 min on a core shared with other jobs (FE 80 × 80 ~3–4 min per support, MPM
Δx = 0.05 m ~1 min per support); ``--quick`` (FE n = 10 and 20 to 0.12 s, MPM Δx = 0.1 m roller
to 0.12 s) ~20 s::

    python run_scripts/studies/fe_bar.py            # full study, figure beside the CSV
    python run_scripts/studies/fe_bar.py --quick    # the smoke test's mode
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py, the groups
from study import (figure, folders, is_root, main_guard, parser, run_case, save, world, write_csv,
                   wrote)

E, NU, RHO, G = 1.0e6, 0.3, 1050.0, 1000.0
LAM = E * NU / ((1 + NU) * (1 - 2 * NU))
MU = E / (2 * (1 + NU))
GAUSS = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]) / np.sqrt(3.0)
CORNERS = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])  # Q1 node order


def q1_shape(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear shape functions ``N_a(ξ) = (1 + ξ ξ_a)(1 + η η_a)/4`` and their ξ-gradients at the
    points ``xi`` (k, 2): (k, 4) and (k, 4, 2)."""
    a = 1.0 + xi[:, None, 0] * CORNERS[None, :, 0]
    b = 1.0 + xi[:, None, 1] * CORNERS[None, :, 1]
    N = 0.25 * a * b
    dN = 0.25 * np.stack([CORNERS[None, :, 0] * b, a * CORNERS[None, :, 1]], axis=-1)
    return N, dN


def mesh(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (m, 2) and Q1 connectivity (n², 4) of the bar [0, 1] × [−1, 0] cut into n × n squares."""
    s = np.linspace(0.0, 1.0, n + 1)
    X = np.stack(np.meshgrid(s, s - 1.0, indexing="xy"), axis=-1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="xy")
    k = (j * (n + 1) + i).ravel()
    return X, np.stack([k, k + 1, k + n + 2, k + n + 1], axis=1)


def sampler(X: np.ndarray, n: int, points) -> tuple[np.ndarray, np.ndarray]:
    """(node ids (k, 4), weights (k, 4)) that interpolate a nodal field of ``mesh(n)`` at the
    reference ``points`` (k, 2)."""
    h = 1.0 / n
    p = np.asarray(points, dtype=float)
    i = np.clip(np.floor(p[:, 0] / h).astype(int), 0, n - 1)
    j = np.clip(np.floor((p[:, 1] + 1.0) / h).astype(int), 0, n - 1)
    xi = np.stack([2.0 * (p[:, 0] / h - i) - 1.0, 2.0 * ((p[:, 1] + 1.0) / h - j) - 1.0], axis=1)
    k = j * (n + 1) + i
    N, _ = q1_shape(xi)
    return np.stack([k, k + 1, k + n + 2, k + n + 1], axis=1), N


def fe_bar(n: int, end: float, support: str = "roller", cfl: float = 0.3, points=((0.0, -1.0),)):
    """Run the FE bar on an n × n mesh to ``end`` s; returns (times (s,), vertical displacement
    (s, k) at the reference ``points``, steps). Raises ``RuntimeError`` if an element inverts."""
    X, conn = mesh(n)
    h = 1.0 / n
    N, dN = q1_shape(GAUSS)
    dNdX = dN * (2.0 / h)                   # (4 gauss, 4 nodes, 2): the same for every square
    wdet = (h / 2.0) ** 2                  # Gauss weight 1 × det dX/dξ
    mass = np.bincount(conn.ravel(), minlength=X.shape[0]) * (RHO * h * h / 4.0)
    top = np.flatnonzero(np.abs(X[:, 1]) < 1e-12)
    held = [1] if support == "roller" else [0, 1]
    ids, weights = sampler(X, n, points)
    f_ext = np.zeros_like(X)
    f_ext[:, 1] = -G * mass
    u, v = np.zeros_like(X), np.zeros_like(X)
    flat = conn.ravel()

    D = dNdX.transpose(1, 0, 2).reshape(4, 8)  # (node a, gauss g × axis j)

    def accel(u):
        """Nodal accelerations at displacement ``u`` and the stable Δt. Per Gauss point:
        ``F = Σ_a x_a ⊗ ∇_X N_a``, ``P = τ F⁻ᵀ``; nodal internal force ``Σ_g P ∇_X N_a w det``."""
        xe = (X + u)[conn]                                   # (elements, 4 nodes, 2)
        (f00, f01), (f10, f11) = [(r[:, 0::2], r[:, 1::2]) for r in (xe[:, :, 0] @ D, xe[:, :, 1] @ D)]
        J = f00 * f11 - f01 * f10
        if np.any(J <= 0.0):
            raise RuntimeError(f"FE bar n={n}: an element inverted")
        lnJ = np.log(J)
        b00, b01, b11 = f00 * f00 + f01 * f01, f00 * f10 + f01 * f11, f10 * f10 + f11 * f11
        t00, t01, t11 = MU * (b00 - 1.0) + LAM * lnJ, MU * b01, MU * (b11 - 1.0) + LAM * lnJ
        # P = τ F⁻ᵀ with F⁻ᵀ = [[f11, −f10], [−f01, f00]] / J
        p00, p01 = (t00 * f11 - t01 * f01) / J, (t01 * f00 - t00 * f10) / J
        p10, p11 = (t01 * f11 - t11 * f01) / J, (t11 * f00 - t01 * f10) / J
        P0 = np.empty((conn.shape[0], 8))
        P1 = np.empty((conn.shape[0], 8))
        P0[:, 0::2], P0[:, 1::2], P1[:, 0::2], P1[:, 1::2] = p00, p01, p10, p11
        f = f_ext.copy()
        for c, Pc in enumerate((P0, P1)):
            f[:, c] -= np.bincount(flat, weights=((Pc @ D.T) * wdet).ravel(), minlength=X.shape[0])
        a = f / mass[:, None]
        a[np.ix_(top, held)] = 0.0
        c00, c11 = f00 * f00 + f10 * f10, f01 * f01 + f11 * f11  # C = FᵀF: s_min² from tr, det
        tr = c00 + c11
        s2 = 0.5 * (tr - np.sqrt(np.maximum(tr * tr - 4.0 * J * J, 0.0)))
        c2 = (MU * (1.0 + 1.0 / s2) + LAM * (1.0 + np.abs(lnJ)) / s2) / RHO
        return a, cfl * h / np.sqrt(c2.max())

    t, steps = 0.0, 0
    a, dt = accel(u)
    v += 0.5 * dt * a
    times, hist = [0.0], [np.zeros(len(points))]
    while t < end - 1e-12:
        dt = min(dt, end - t)
        u += dt * v
        t += dt
        steps += 1
        a, dt_next = accel(u)
        v += 0.5 * (dt + dt_next) * a
        dt = dt_next
        times.append(t)
        hist.append(np.sum(u[ids, 1] * weights, axis=1))
    return np.array(times), np.array(hist), steps


def peaks(t: np.ndarray, u: np.ndarray) -> dict:
    """First peak and rebound of the history ``u(t)`` (None where not reached)."""
    from parmpm.output.metrics.bars import first_peak_and_rebound

    i, j = first_peak_and_rebound(u)
    return {"first_peak": None if i is None else float(u[i]),
            "first_peak_time": None if i is None else float(t[i]),
            "rebound": None if j is None else float(u[j]),
            "rebound_time": None if j is None else float(t[j])}


CLAMPED = ["boundary.slip_regions=[]", "boundary.fixed_regions=[{min=[-0.5, 0.0], max=[1.5, 0.2]}]"]


def mpm_bar(cell: float, end: float, support: str, comm):
    """The built-in hanging_bar (cpdi) at cell size ``cell``; returns (summary, corner history)."""
    cells = [round(2.0 / cell), round(3.2 / cell)]
    over = [f"grid.cell_size={cell}", f"grid.cells=[{cells[0]}, {cells[1]}]", f"time.end={end}",
            "metrics.stop_on_separation=false"] + (CLAMPED if support == "clamped" else [])
    import parmpm

    scene = parmpm.load_scene("hanging_bar", over)
    sim_hist = {}

    class Keep:
        def __call__(self, sim):
            sim_hist["metrics"] = sim.state.metrics

    summary, wall = run_case(scene, ["output.every_steps=1000000"], comm, [Keep()])
    m = sim_hist["metrics"]
    return summary, np.asarray(m.times), np.asarray(m.corner_history), wall


def main() -> int:
    ap = parser(__doc__)
    args = ap.parse_args()
    comm = world()
    root = is_root(comm)
    out, figs = folders(args, "fe_bar")
    end = 0.12 if args.quick else 0.3
    fe_sizes = (10, 20) if args.quick else (20, 40, 80)
    mpm_cells = (0.1,) if args.quick else (0.1, 0.05)
    supports = ("roller",) if args.quick else ("roller", "clamped")
    points = [(0.0, -1.0)] + [(c / 6, -1.0 + c / 6) for c in mpm_cells]
    rows, curves = [], {}
    for support in supports:
        for n in fe_sizes:
            t0 = time.perf_counter()
            if root:
                t, hist, steps = fe_bar(n, end, support, points=points)
            wall = time.perf_counter() - t0
            if not root:
                continue
            for k, p in enumerate(points):
                where = "corner node" if k == 0 else f"particle of dx={mpm_cells[k - 1]:g}"
                rows.append({"model": "fe_q1", "support": support, "resolution": 1.0 / n,
                             "point": where, "x": p[0], "y": p[1], "steps": steps,
                             "wall_seconds": wall, **peaks(t, hist[:, k])})
            curves[("fe", support, n)] = (t, hist[:, 1])
            print(f"FE n={n:4d} {support:7s} {steps:6d} steps {wall:6.1f} s  "
                  + "  ".join(f"{r['point']}: peak {r['first_peak']} at {r['first_peak_time']}"
                              for r in rows[-len(points):]), flush=True)
        for k, cell in enumerate(mpm_cells):
            summary, t, u, wall = mpm_bar(cell, end, support, comm)
            if root:
                p = points[k + 1]
                rows.append({"model": "mpm_cpdi", "support": support, "resolution": cell,
                             "point": f"particle of dx={cell:g}", "x": p[0], "y": p[1],
                             "steps": summary["steps"], "wall_seconds": wall, **peaks(t, u)})
                curves[("mpm", support, cell)] = (t, u)
                print(f"MPM dx={cell:g} {support:7s} {summary['steps']:6d} steps {wall:6.1f} s  "
                      f"peak {rows[-1]['first_peak']} at {rows[-1]['first_peak_time']}, "
                      f"rebound {rows[-1]['rebound']} at {rows[-1]['rebound_time']}", flush=True)
    write_csv(out / "fe_bar.csv", rows, comm)
    if root:
        path = corner_figure(curves, figs / "fe_bar.png")
        print(wrote(out / "fe_bar.csv"))
        print(wrote(path))
    return 0


def corner_figure(curves: dict, path):
    fig, axes = figure(1, 1, size=(7.0, 4.2))
    ax = axes[0, 0]
    styles = {"roller": "-", "clamped": "--"}
    for (model, support, res), (t, u) in sorted(curves.items(), key=lambda kv: str(kv[0])):
        if model == "fe":
            label = f"FE Q1 {res}×{res}, {support}"
            ax.plot(t, u, styles[support], color="0.3", lw=0.6 + 1.2 * (res == max(
                k[2] for k in curves if k[0] == "fe")), label=label)
        else:
            ax.plot(t, u, styles[support], lw=1.0, label=f"MPM cpdi Δx = {res:g} m, {support}")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("bottom-corner vertical displacement (m)")
    ax.grid(color="0.9")
    ax.legend(fontsize=6.5, ncol=2)
    ax.set_title("Self-weighted bar (Sadeghirad et al. 2011): bottom corner, MPM vs FE", fontsize=9)
    return save(fig, path)


if __name__ == "__main__":
    main_guard(main)
