"""A 3D yardstick for one core: a bare numba MPM step, written for this comparison.

The 2D yardsticks that parmpm's throughput is held against live outside this repository and have
no 3D case, so this is one written here, independently, to the same brief: one explicit USL step
on structure-of-arrays float64 data, ``@njit``, fastmath off, one thread, four kernel
calls per step (zero the grid, P2G, grid update, G2P), no patches, no MPI, no bounds checks, no
Δt computation, no boundary conditions. The scene is ``parmpm bench``'s: a neo-Hookean block
(E = 1 MPa, ν = 0.3, ρ = 1050) of 2×2×2 particles per cell translating at (1, 0.5, 0.25) m/s,
free boundaries, no gravity, so every particle does the full work of a step whatever its state.

* ``cpdi``: CPDI1 (Sadeghirad et al. 2011). Each particle's domain is the parallelepiped
  ``x_p + s1 r1 + s2 r2 + s3 r3`` (s = ±1), ``r_k = F r0_k``; ``S_ip = ⅛ Σ_c N_i(x_c)`` and
  ``∇S_ip = (1/V_p) Σ_c N_i(x_c) α_c`` with ``α_c = s1 r2×r3 + s2 r3×r1 + s3 r1×r2`` and
  ``V_p = 8 r1·(r2×r3)``: 8 corners × 8 nodes per particle, scattered and gathered corner by
  corner.
* ``hat``: standard MPM, trilinear weights and gradients at the particle: 8 nodes.

G2P blends FLIP and PIC (``--flip``, default 0.95, so both are computed), moves the particle with
the PIC velocity, updates ``F ← (I + Δt L) F`` and the Cauchy stress
``σ = (μ/J)(b − I) + (λ ln J / J) I``.

    python run_scripts/benchmarks/yardstick3d.py --method cpdi --n 2e5 --steps 10 --reps 3
    python run_scripts/benchmarks/yardstick3d.py --compare --n 2e5 --reps 3

Prints one ``RESULT`` line (JSON): particles, steps, best seconds per step, particle-steps/s.
``--compare`` runs ``parmpm bench --dim 3 --update usl`` (cpdi, and mpm against ``hat``) and
this step alternately in fresh processes, ``--reps`` times each, and prints the fastest of each
and their ratio (the 3D table of ``docs/results/throughput.md``; ~3 minutes at 2·10⁵ particles).
"""
from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np
from numba import njit

#: not cached: the script runs as ``__main__`` and is imported by its test as a module, and
#: numba's cache entries name the module they were compiled in (each run compiles, untimed)
JIT = dict(cache=False, fastmath=False, nogil=True)
CELL = 0.01
RHO, E, NU = 1050.0, 1.0e6, 0.3
MU = E / (2.0 * (1.0 + NU))
LAM = E * NU / ((1.0 + NU) * (1.0 - 2.0 * NU))
VELOCITY = (1.0, 0.5, 0.25)
MARGIN = 4  # empty cells around the block
G_ROWS = 8  # a node's record: m, mv (3), f (3), pad / v (3), Δv (3), pad (2)


def setup(n_target: float, ppc: int = 2):
    """The block's particles (SoA) and the grid around it."""
    n = max(1, round(n_target ** (1.0 / 3.0) / ppc))  # cells per axis
    side = n * ppc
    h = CELL / ppc
    t = (np.arange(side) + 0.5) * h + MARGIN * CELL
    X, Y, Z = np.meshgrid(t, t, t, indexing="ij")
    x = np.stack([X.ravel(), Y.ravel(), Z.ravel()])  # (3, N)
    N = x.shape[1]
    v = np.empty((3, N))
    v[:] = np.array(VELOCITY)[:, None]
    F = np.zeros((9, N))
    F[0] = F[4] = F[8] = 1.0
    r0 = np.zeros((9, N))  # r0_k as columns: r0[3k + a] = component a of r_k
    r0[0] = r0[4] = r0[8] = 0.5 * h
    r = r0.copy()
    stress = np.zeros((6, N))  # xx, yy, zz, xy, yz, zx
    vol = h ** 3
    mass = np.full(N, RHO * vol)
    V0 = np.full(N, vol)
    nodes = n + 2 * MARGIN + 1
    gsum = np.zeros((nodes ** 3, G_ROWS))
    gnew = np.zeros((nodes ** 3, G_ROWS))
    return dict(x=x, v=v, F=F, r0=r0, r=r, stress=stress, mass=mass, V0=V0, gsum=gsum,
                gnew=gnew, nodes=nodes)


@njit(**JIT)
def zero_grid(g):
    g[:] = 0.0


@njit(inline="always")
def _cell(c, inv_h):
    i = int(math.floor(c * inv_h))
    return i, c * inv_h - i


@njit(inline="always")
def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(inline="always")
def _domain(r, p):
    """Particle p's domain vectors r1, r2, r3 and their cross products r2×r3, r3×r1, r1×r2."""
    r1 = (r[0, p], r[1, p], r[2, p])
    r2 = (r[3, p], r[4, p], r[5, p])
    r3 = (r[6, p], r[7, p], r[8, p])
    return r1, r2, r3, _cross(r2, r3), _cross(r3, r1), _cross(r1, r2)


@njit(inline="always")
def _add(g, node, w, m, mx, my, mz, fx, fy, fz):
    g[node, 0] += w * m
    g[node, 1] += w * mx
    g[node, 2] += w * my
    g[node, 3] += w * mz
    g[node, 4] += w * fx
    g[node, 5] += w * fy
    g[node, 6] += w * fz


@njit(inline="always")
def _scatter(g, b, nodes, x0, x1, y0, y1, z0, z1, m, mx, my, mz, fx, fy, fz):
    """One point's trilinear scatter into the 8 nodes of its cell (``b``: the first)."""
    s = nodes * nodes
    for k, wz in ((0, z0), (s, z1)):
        _add(g, b + k, x0 * y0 * wz, m, mx, my, mz, fx, fy, fz)
        _add(g, b + k + 1, x1 * y0 * wz, m, mx, my, mz, fx, fy, fz)
        _add(g, b + k + nodes, x0 * y1 * wz, m, mx, my, mz, fx, fy, fz)
        _add(g, b + k + nodes + 1, x1 * y1 * wz, m, mx, my, mz, fx, fy, fz)


@njit(inline="always")
def _gather(g, b, nodes, x0, x1, y0, y1, z0, z1):
    """The trilinear interpolation of a cell's 8 nodes' v and Δv at one point."""
    s = nodes * nodes
    u0 = u1 = u2 = d0 = d1 = d2 = 0.0
    for k, wz in ((0, z0), (s, z1)):
        for n, w in ((b + k, x0 * y0 * wz), (b + k + 1, x1 * y0 * wz),
                     (b + k + nodes, x0 * y1 * wz), (b + k + nodes + 1, x1 * y1 * wz)):
            u0 += w * g[n, 0]
            u1 += w * g[n, 1]
            u2 += w * g[n, 2]
            d0 += w * g[n, 3]
            d1 += w * g[n, 4]
            d2 += w * g[n, 5]
    return u0, u1, u2, d0, d1, d2


@njit(**JIT)
def p2g_cpdi(x, v, r, stress, mass, g, nodes, inv_h):
    for p in range(x.shape[1]):
        r1, r2, r3, c23, c31, c12 = _domain(r, p)
        sxx, syy, szz = stress[0, p], stress[1, p], stress[2, p]
        sxy, syz, szx = stress[3, p], stress[4, p], stress[5, p]
        m8 = 0.125 * mass[p]
        vx, vy, vz = v[0, p], v[1, p], v[2, p]
        for c in range(8):
            s1 = 1.0 if c & 1 else -1.0
            s2 = 1.0 if c & 2 else -1.0
            s3 = 1.0 if c & 4 else -1.0
            ax = s1 * c23[0] + s2 * c31[0] + s3 * c12[0]
            ay = s1 * c23[1] + s2 * c31[1] + s3 * c12[1]
            az = s1 * c23[2] + s2 * c31[2] + s3 * c12[2]
            fx = -(sxx * ax + sxy * ay + szx * az)
            fy = -(sxy * ax + syy * ay + syz * az)
            fz = -(szx * ax + syz * ay + szz * az)
            i, fx0 = _cell(x[0, p] + s1 * r1[0] + s2 * r2[0] + s3 * r3[0], inv_h)
            j, fy0 = _cell(x[1, p] + s1 * r1[1] + s2 * r2[1] + s3 * r3[1], inv_h)
            k, fz0 = _cell(x[2, p] + s1 * r1[2] + s2 * r2[2] + s3 * r3[2], inv_h)
            base = i + nodes * (j + nodes * k)
            _scatter(g, base, nodes, 1.0 - fx0, fx0, 1.0 - fy0, fy0, 1.0 - fz0, fz0,
                     m8, m8 * vx, m8 * vy, m8 * vz, fx, fy, fz)


@njit(**JIT)
def p2g_hat(x, v, F, stress, mass, V0, g, nodes, inv_h):
    for p in range(x.shape[1]):
        i, fx0 = _cell(x[0, p], inv_h)
        j, fy0 = _cell(x[1, p], inv_h)
        k, fz0 = _cell(x[2, p], inv_h)
        J = (F[0, p] * (F[4, p] * F[8, p] - F[5, p] * F[7, p])
             - F[1, p] * (F[3, p] * F[8, p] - F[5, p] * F[6, p])
             + F[2, p] * (F[3, p] * F[7, p] - F[4, p] * F[6, p]))
        V = J * V0[p]
        sxx, syy, szz = stress[0, p], stress[1, p], stress[2, p]
        sxy, syz, szx = stress[3, p], stress[4, p], stress[5, p]
        m, vx, vy, vz = mass[p], v[0, p], v[1, p], v[2, p]
        for dk in range(2):
            wz, gz = (fz0, inv_h) if dk else (1.0 - fz0, -inv_h)
            for dj in range(2):
                wy, gy = (fy0, inv_h) if dj else (1.0 - fy0, -inv_h)
                base = i + nodes * (j + dj + nodes * (k + dk))
                for di in range(2):
                    wx, gx = (fx0, inv_h) if di else (1.0 - fx0, -inv_h)
                    w = wx * wy * wz
                    ax, ay, az = gx * wy * wz, wx * gy * wz, wx * wy * gz
                    node = base + di
                    mw = m * w
                    g[node, 0] += mw
                    g[node, 1] += mw * vx
                    g[node, 2] += mw * vy
                    g[node, 3] += mw * vz
                    g[node, 4] -= V * (sxx * ax + sxy * ay + szx * az)
                    g[node, 5] -= V * (sxy * ax + syy * ay + syz * az)
                    g[node, 6] -= V * (szx * ax + syz * ay + szz * az)


@njit(**JIT)
def grid_update(gsum, gnew, dt):
    for n in range(gsum.shape[0]):
        m = gsum[n, 0]
        if m > 1e-14:
            for a in range(3):
                vo = gsum[n, 1 + a] / m
                dv = dt * gsum[n, 4 + a] / m
                gnew[n, a] = vo + dv
                gnew[n, 3 + a] = dv
        else:
            for a in range(6):
                gnew[n, a] = 0.0


@njit(inline="always")
def _finish(p, x, v, F, stress, L, vpic, dvp, Fn, dt, flip):
    """FLIP/PIC velocity, position, F ← (I + Δt L) F and the neo-Hookean stress of particle p."""
    for a in range(3):
        x[a, p] += dt * vpic[a]
        v[a, p] = flip * (v[a, p] + dvp[a]) + (1.0 - flip) * vpic[a]
    for a in range(3):
        for b in range(3):
            s = F[3 * a + b, p]
            for c in range(3):
                s += dt * L[3 * a + c] * F[3 * c + b, p]
            Fn[3 * a + b] = s
    for q in range(9):
        F[q, p] = Fn[q]
    J = (Fn[0] * (Fn[4] * Fn[8] - Fn[5] * Fn[7]) - Fn[1] * (Fn[3] * Fn[8] - Fn[5] * Fn[6])
         + Fn[2] * (Fn[3] * Fn[7] - Fn[4] * Fn[6]))
    bxx = Fn[0] * Fn[0] + Fn[1] * Fn[1] + Fn[2] * Fn[2]
    byy = Fn[3] * Fn[3] + Fn[4] * Fn[4] + Fn[5] * Fn[5]
    bzz = Fn[6] * Fn[6] + Fn[7] * Fn[7] + Fn[8] * Fn[8]
    bxy = Fn[0] * Fn[3] + Fn[1] * Fn[4] + Fn[2] * Fn[5]
    byz = Fn[3] * Fn[6] + Fn[4] * Fn[7] + Fn[5] * Fn[8]
    bzx = Fn[6] * Fn[0] + Fn[7] * Fn[1] + Fn[8] * Fn[2]
    a1, a2 = MU / J, LAM * math.log(J) / J
    stress[0, p] = a1 * (bxx - 1.0) + a2
    stress[1, p] = a1 * (byy - 1.0) + a2
    stress[2, p] = a1 * (bzz - 1.0) + a2
    stress[3, p] = a1 * bxy
    stress[4, p] = a1 * byz
    stress[5, p] = a1 * bzx


@njit(**JIT)
def g2p_cpdi(x, v, F, r0, r, stress, g, nodes, inv_h, dt, flip):
    L, Fn = np.empty(9), np.empty(9)
    vpic = np.empty(3)
    dvp = np.empty(3)
    for p in range(x.shape[1]):
        r1, r2, r3, c23, c31, c12 = _domain(r, p)
        inv_V = 1.0 / (8.0 * (r1[0] * c23[0] + r1[1] * c23[1] + r1[2] * c23[2]))
        L[:] = 0.0
        vpic[:] = 0.0
        dvp[:] = 0.0
        for c in range(8):
            s1 = 1.0 if c & 1 else -1.0
            s2 = 1.0 if c & 2 else -1.0
            s3 = 1.0 if c & 4 else -1.0
            i, fx0 = _cell(x[0, p] + s1 * r1[0] + s2 * r2[0] + s3 * r3[0], inv_h)
            j, fy0 = _cell(x[1, p] + s1 * r1[1] + s2 * r2[1] + s3 * r3[1], inv_h)
            k, fz0 = _cell(x[2, p] + s1 * r1[2] + s2 * r2[2] + s3 * r3[2], inv_h)
            base = i + nodes * (j + nodes * k)
            ux, uy, uz, dx, dy, dz = _gather(g, base, nodes, 1.0 - fx0, fx0, 1.0 - fy0, fy0,
                                             1.0 - fz0, fz0)
            ax = (s1 * c23[0] + s2 * c31[0] + s3 * c12[0]) * inv_V
            ay = (s1 * c23[1] + s2 * c31[1] + s3 * c12[1]) * inv_V
            az = (s1 * c23[2] + s2 * c31[2] + s3 * c12[2]) * inv_V
            L[0] += ux * ax
            L[1] += ux * ay
            L[2] += ux * az
            L[3] += uy * ax
            L[4] += uy * ay
            L[5] += uy * az
            L[6] += uz * ax
            L[7] += uz * ay
            L[8] += uz * az
            vpic[0] += 0.125 * ux
            vpic[1] += 0.125 * uy
            vpic[2] += 0.125 * uz
            dvp[0] += 0.125 * dx
            dvp[1] += 0.125 * dy
            dvp[2] += 0.125 * dz
        _finish(p, x, v, F, stress, L, vpic, dvp, Fn, dt, flip)
        for k in range(3):  # CPDI1: r_k = F r0_k
            for a in range(3):
                s = 0.0
                for b in range(3):
                    s += F[3 * a + b, p] * r0[3 * k + b, p]
                r[3 * k + a, p] = s


@njit(**JIT)
def g2p_hat(x, v, F, stress, g, nodes, inv_h, dt, flip):
    L, Fn = np.empty(9), np.empty(9)
    vpic = np.empty(3)
    dvp = np.empty(3)
    for p in range(x.shape[1]):
        i, fx0 = _cell(x[0, p], inv_h)
        j, fy0 = _cell(x[1, p], inv_h)
        k, fz0 = _cell(x[2, p], inv_h)
        L[:] = 0.0
        vpic[:] = 0.0
        dvp[:] = 0.0
        for dk in range(2):
            wz, gz = (fz0, inv_h) if dk else (1.0 - fz0, -inv_h)
            for dj in range(2):
                wy, gy = (fy0, inv_h) if dj else (1.0 - fy0, -inv_h)
                base = i + nodes * (j + dj + nodes * (k + dk))
                for di in range(2):
                    wx, gx = (fx0, inv_h) if di else (1.0 - fx0, -inv_h)
                    w = wx * wy * wz
                    grad = (gx * wy * wz, wx * gy * wz, wx * wy * gz)
                    node = base + di
                    for a in range(3):
                        u = g[node, a]
                        vpic[a] += w * u
                        dvp[a] += w * g[node, 3 + a]
                        for b in range(3):
                            L[3 * a + b] += u * grad[b]
        _finish(p, x, v, F, stress, L, vpic, dvp, Fn, dt, flip)


def step(s: dict, method: str, dt: float, flip: float) -> None:
    inv_h = 1.0 / CELL
    zero_grid(s["gsum"])
    if method == "cpdi":
        p2g_cpdi(s["x"], s["v"], s["r"], s["stress"], s["mass"], s["gsum"], s["nodes"], inv_h)
    else:
        p2g_hat(s["x"], s["v"], s["F"], s["stress"], s["mass"], s["V0"], s["gsum"], s["nodes"],
                inv_h)
    grid_update(s["gsum"], s["gnew"], dt)
    if method == "cpdi":
        g2p_cpdi(s["x"], s["v"], s["F"], s["r0"], s["r"], s["stress"], s["gnew"], s["nodes"],
                 inv_h, dt, flip)
    else:
        g2p_hat(s["x"], s["v"], s["F"], s["stress"], s["gnew"], s["nodes"], inv_h, dt, flip)


def fixed_dt() -> float:
    """The step this yardstick takes: what a CFL of 0.4 gives the block at rest, fixed."""
    return 0.4 * CELL / (math.sqrt((LAM + 2.0 * MU) / RHO) + 1.2)


def compare(n: float, reps: int, steps: int, fixed: bool = False) -> None:
    """parmpm's 3D USL step (cpdi; mpm against ``hat``) beside this one, alternately; ``fixed``:
    parmpm at this one's fixed step (``--dt``: G2P without the wave speed)."""
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    for method, mine in (("cpdi", "cpdi"), ("mpm", "hat")):
        best = {"parmpm": 0.0, "yardstick": 0.0}
        for _ in range(reps):
            with tempfile.TemporaryDirectory() as tmp:
                out = Path(tmp) / "bench.json"
                subprocess.run([sys.executable, "-m", "parmpm", "bench", "--quiet", "--dim", "3",
                                "--method", method, "--update", "usl", "--particles", f"{n:g}",
                                "--steps", str(steps), "--json", str(out)]
                               + (["--dt", repr(fixed_dt())] if fixed else []), cwd=root,
                               check=True, timeout=1800)
                best["parmpm"] = max(best["parmpm"],
                                     json.loads(out.read_text())["particle_steps_per_second"])
            proc = subprocess.run([sys.executable, __file__, "--method", mine, "--n", f"{n:g}",
                                   "--steps", str(steps), "--reps", "1"], check=True,
                                  capture_output=True, text=True, timeout=1800)
            line = next(x for x in proc.stdout.splitlines() if x.startswith("RESULT "))
            best["yardstick"] = max(best["yardstick"], json.loads(line[7:])["rate"])
        print(f"3D {method:5s} USL: parmpm {best['parmpm'] / 1e6:.2f} M particle-steps/s, "
              f"yardstick ({mine}) {best['yardstick'] / 1e6:.2f} M, ratio "
              f"{best['parmpm'] / best['yardstick']:.2f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", choices=("cpdi", "hat"), default="cpdi")
    ap.add_argument("--n", type=float, default=2e5, help="about how many particles")
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--flip", type=float, default=0.95)
    ap.add_argument("--compare", action="store_true", help="parmpm bench beside this step")
    ap.add_argument("--fixed-dt", action="store_true",
                    help="with --compare: parmpm at this step's fixed Δt (time.dt)")
    a = ap.parse_args()
    if not (math.isfinite(a.n) and 1 <= a.n <= 1e9) or a.steps < 1 or a.reps < 1:
        ap.error(f"--n {a.n:g}, --steps {a.steps}, --reps {a.reps}: expected 1 <= n <= 1e9 "
                 "particles and at least one step and one repeat")
    if not 0.0 <= a.flip <= 1.0:
        ap.error(f"--flip {a.flip:g}: expected a number in [0, 1]")
    if a.compare:
        compare(a.n, a.reps, a.steps, a.fixed_dt)
        return
    dt = fixed_dt()
    best = math.inf
    for _ in range(a.reps):
        s = setup(a.n)
        step(s, a.method, dt, a.flip)  # compile or load, and the first step
        t0 = time.perf_counter()
        for _ in range(a.steps):
            step(s, a.method, dt, a.flip)
        best = min(best, (time.perf_counter() - t0) / a.steps)
    n = s["x"].shape[1]
    drift = float(np.abs(s["F"][[0, 4, 8]] - 1.0).max())
    print("RESULT " + json.dumps({"method": a.method, "particles": n, "steps": a.steps,
                                  "seconds_per_step": best, "rate": n / best,
                                  "max_abs_F_minus_I": drift}))


if __name__ == "__main__":
    main()
