"""The Taylor bar: a copper rod hits a rigid wall at 227 m/s; final length and mushroom radius.

Physics. Wilkins & Guinan (1973), Simo (1992, §7.2): L0 = 32.4 mm, R0 = 3.2 mm, 227 m/s onto a
rigid frictionless wall, E = 117 GPa, ν = 0.35, ρ = 8930 kg/m³, finite-strain J2 with linear
hardening σ_y = 0.4 GPa + 0.1 GPa·ε̄p, to 80 µs. The scene is ``docs/examples/taylor_bar.toml``
(a quarter bar, axis along y, mirrors at x = 0 and z = 0, the wall the mirror face y = 0,
B-spline/MUSL/FLIP, 2 particles per cell per axis, lattice-seeded CSG body), refined here to
``R0/Δx`` = n (``--resolutions``); the grid is 3 R0 wide and 11 R0 (35.2 mm) tall at every n.
References (docs/results/plasticity_references.md): R_f = 7.22 mm (Foulk et al. 2021; Simo
1992: 7.12; Zienkiewicz et al. 1998: 7.11), L_f = 21.43 mm (Carina.jl's converged FE runs, not a
published number).

Measured, at the end (particles gathered in global-id order; ``s`` a particle's spacing, the cube
root of its initial volume: Δx/2 on the lattice):

* a particle's half-extent along a unit vector ``n`` is ``(s/2) ‖Fᵀn‖``, the support function of
  a ball of diameter ``s`` carried by its deformation gradient ``F`` (``s/2`` at the start in
  every direction, so the lattice's orientation does not bias it);
* L_f = max over particles of ``y + half-extent along y``: the top of the bar;
* R_f = max over the impact-face particles (the first lattice layer, reference ``Y < s``) of
  ``r + half-extent along e_r``, ``r = √(x² + z²)``: the footprint's edge;
* ``*_centre``: the same without the half-extent (the particle centres): the two bracket the
  surface, so their difference is the measurement's own uncertainty;
* the same measures at t = 0 (``L0_measured``, ``R0_measured``): the seeded outline against the
  true 32.4 and 3.2 mm, and ``mass_error_pct`` the seeded mass against ρ π R0² L0 / 4;
* ``R_any``: the largest ``r + half-extent`` over all particles (the bulge, wherever it is);
* the largest ε̄p; the throughput ``particle_steps_per_second`` of the run's summary (steps
  after the first over their wall time, so compiling is not counted).

Two anvils (``--anvils``): a ``"slip"`` face (normal velocity held at 0 on the face's
nodes and on those beyond it) and the example's ``"symmetry"`` (the bar meets its mirror image: the face's
nodes hold the normal velocity at 0 and the nodes beyond mirror their twins), both the
references' frictionless wall that keeps the impact face on it. ``--seeding mesh`` seeds a
hexahedral mesh of the quarter bar instead (:func:`quarter_bar_mesh`); ``--ppc`` and ``--set``
are for diagnostics.

Outputs in ``--out`` (default ``run_scripts/out/taylor_bar``): ``taylor_bar.csv`` (one row per
anvil and resolution) and ``taylor_bar.png`` (the finest bars' sections near z = 0 coloured by
ε̄p, slip at x < 0 and symmetry at x > 0, and L_f, R_f against Δx with the references).

Runtime on the shared 2-core machine, ``mpirun -n 2``, per anvil: n = 2 a few seconds, n = 4
about 25 s, n = 8 about 2.5 min (docs/results/taylor-bar.md)::

    mpirun -n 2 python run_scripts/studies/taylor_bar.py                  # n = 2, 4, 8, both anvils
    python run_scripts/studies/taylor_bar.py --resolutions 4 --anvils slip --out DIR   # 1 rank
    python run_scripts/studies/taylor_bar.py --quick                      # n = 2, symmetry
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py
from parmpm.materials.plasticity.state import STATE_EPSP  # noqa: E402
from study import (ROOT, figure, folders, is_root, main_guard, parser, run_case, save,  # noqa: E402
                   scratch_folder, world, write_csv, wrote)

SCENE = ROOT / "docs" / "examples" / "taylor_bar.toml"
L0, R0, END = 0.0324, 0.0032, 80.0e-6
L_REF, R_REF = 0.02143, 0.00722          # Carina.jl's FE runs; Foulk et al. (2021)
R_OLDER = {"Simo 1992": 0.00712, "Zienkiewicz et al. 1998": 0.00711}


def overrides(n: int, ppc: int = 2, extra=()) -> list[str]:
    """The example scene at ``R0/Δx = n``: the same physical grid, 3 R0 × 11 R0 × 3 R0."""
    h = R0 / n
    return [f"grid.cell_size={h!r}", f"grid.cells=[{3 * n}, {11 * n}, {3 * n}]",
            f"bodies.0.ppc={ppc}", f"output.every={END!r}", "output.history=false", *extra]


def half_extent(F: np.ndarray, n: np.ndarray, s) -> np.ndarray:
    """Half-extent along the unit vectors ``n`` (k, 3) of each particle's share of the body, a
    ball of diameter ``s`` (a number, or one per particle) carried by ``F``: ``(s/2) ‖Fᵀn‖``.
    (The seeding cube's own support function would add up to √2 · s/2 along a diagonal of the
    lattice at t = 0.)"""
    return 0.5 * s * np.linalg.norm(np.einsum("kij,ki->kj", F, n), axis=1)


def measure(x: np.ndarray, x0: np.ndarray, F: np.ndarray, s) -> dict:
    """L and R of the bar (see the module docstring), with and without the half-extents; ``s``:
    the particles' spacing (one number, or one per particle)."""
    s_all = s = np.broadcast_to(np.asarray(s, float), (x.shape[0],))
    ey = np.tile([0.0, 1.0, 0.0], (x.shape[0], 1))
    top = x[:, 1] + half_extent(F, ey, s)
    face = x0[:, 1] < s
    s = s[face]
    r = np.hypot(x[face, 0], x[face, 2])
    er = np.zeros((int(face.sum()), 3))
    er[:, 0], er[:, 2] = x[face, 0] / np.maximum(r, 1e-300), x[face, 2] / np.maximum(r, 1e-300)
    edge = r + half_extent(F[face], er, s)
    r_all = np.hypot(x[:, 0], x[:, 2])
    e_all = np.zeros_like(x)
    e_all[:, 0], e_all[:, 2] = x[:, 0] / np.maximum(r_all, 1e-300), x[:, 2] / np.maximum(r_all, 1e-300)
    return {"L": float(top.max()), "L_centre": float(x[:, 1].max()),
            "R": float(edge.max()), "R_centre": float(r.max()),
            "R_any": float((r_all + half_extent(F, e_all, s_all)).max())}


class Ends:
    """Observer (collective): the particles' x, x0, F, V0 and ε̄p at the first and last output,
    gathered on rank 0 in global-id order."""

    def __init__(self):
        self.first = self.last = None

    def __call__(self, sim):
        P = sim.particles
        fields = {"x": P.x, "x0": P.x0, "F": P.F, "vol0": P.vol0,
                  "epsp": P.plastic[:, STATE_EPSP] if "plastic" in P.optional else np.zeros(P.n)}
        got = sim.gather(fields)
        if self.first is None:
            self.first = got
        self.last = got


def quarter_bar_mesh(path: Path, arc: int, layers: int) -> Path:
    """A hexahedral mesh of the quarter bar (meshio, .vtu): the unit square's ``arc × arc``
    grid mapped onto the quarter disk by the elliptical map ``(u √(1 − v²/2), v √(1 − u²/2))``
    (its edges u = 1 and v = 1 land on the circle, so every outer node is on the surface),
    extruded in ``layers`` layers over the length."""
    import meshio

    u, v = np.meshgrid(np.linspace(0.0, 1.0, arc + 1), np.linspace(0.0, 1.0, arc + 1),
                       indexing="ij")
    px = R0 * u * np.sqrt(1.0 - 0.5 * v * v)
    pz = R0 * v * np.sqrt(1.0 - 0.5 * u * u)
    ys = np.linspace(0.0, L0, layers + 1)
    nodes = np.column_stack([np.tile(px.ravel(), ys.size), np.repeat(ys, px.size),
                             np.tile(pz.ravel(), ys.size)])  # node k(i, j, m) below
    k = lambda i, j, m: (m * (arc + 1) + i) * (arc + 1) + j  # noqa: E731
    # VTK order: the base (z, then x: x × z = −y, so z first keeps the volume positive), then its top
    hexes = [[k(i, j, m), k(i, j + 1, m), k(i + 1, j + 1, m), k(i + 1, j, m),
              k(i, j, m + 1), k(i, j + 1, m + 1), k(i + 1, j + 1, m + 1), k(i + 1, j, m + 1)]
             for m in range(layers) for i in range(arc) for j in range(arc)]
    meshio.write(path, meshio.Mesh(nodes, [("hexahedron", np.array(hexes))]))
    return path


def mesh_overrides(n: int, comm, folder: Path) -> list[str]:
    """The bar as a mesh body at ``R0/Δx = n``: hexahedra about 1.5 Δx on a side, so their
    3×3×3 quadrature points are about as dense as the lattice's 2 per cell per axis."""
    h = R0 / n
    arc = max(2, round(R0 * np.sqrt(np.pi / 4.0) / (1.5 * h)))
    layers = round(L0 / (1.5 * h))
    path = folder / f"taylor_bar_{n}.vtu"
    if is_root(comm):
        quarter_bar_mesh(path, arc, layers)
    comm.Barrier()
    return [f'bodies=[{{shape = "mesh", material = "copper", file = "{path}", '
            f'velocity = [0.0, -227.0, 0.0]}}]']


def run(n: int, comm, ppc: int = 2, extra=(), seeding: str = "lattice",
        anvil: str = "symmetry") -> dict | None:
    """One resolution (``extra``: more scene overrides); the CSV row on rank 0 (None elsewhere)."""
    ends = Ends()
    with scratch_folder(comm, "taylor-mesh-") as folder:
        body = mesh_overrides(n, comm, folder) if seeding == "mesh" else []
        more = [*body, f'boundary.y_min="{anvil}"', *extra]
        summary, wall = run_case(SCENE, overrides(n, ppc, more), comm, [ends])
    if not is_root(comm):
        return None
    h = R0 / n
    # a particle's spacing: the side of its own volume (Δx/ppc on the lattice)
    start = measure(ends.first["x"], ends.first["x0"], ends.first["F"], np.cbrt(ends.first["vol0"]))
    end = measure(ends.last["x"], ends.last["x0"], ends.last["F"], np.cbrt(ends.last["vol0"]))
    exact = 8930.0 * np.pi * R0 ** 2 * L0 / 4.0
    row = {"anvil": anvil, "R0_over_dx": n, "dx_mm": h * 1e3, "seeding": seeding,
           "ppc": ppc if seeding == "lattice" else "", "overrides": " ".join(extra),
           "ranks": summary["ranks"],
           "particles": summary["particles"], "steps": summary["steps"],
           "time": summary["time"], "stopped": summary["stopped"],
           "L_f_mm": end["L"] * 1e3, "L_f_centre_mm": end["L_centre"] * 1e3,
           "R_f_mm": end["R"] * 1e3, "R_f_centre_mm": end["R_centre"] * 1e3,
           "R_any_mm": end["R_any"] * 1e3,
           "L_f_error_pct": 100.0 * (end["L"] / L_REF - 1.0),
           "R_f_error_pct": 100.0 * (end["R"] / R_REF - 1.0),
           "L0_measured_mm": start["L"] * 1e3, "R0_measured_mm": start["R"] * 1e3,
           "mass_error_pct": 100.0 * (summary["final"]["mass"] / exact - 1.0),
           "max_plastic_strain": float(ends.last["epsp"].max()),
           "wall_seconds": wall,
           "particle_steps_per_second": summary["particle_steps_per_second"]}
    row["_section"] = ends.last
    return row


def main() -> int:
    ap = parser(__doc__)
    ap.add_argument("--resolutions", type=int, nargs="+", default=None,
                    help="R0/dx values (default 2 4 8; --quick: 2)")
    ap.add_argument("--ppc", type=int, default=2, help="particles per cell per axis (default 2)")
    ap.add_argument("--anvils", nargs="+", choices=("slip", "symmetry"), default=None,
                    help='the wall face y = 0: "slip" and/or "symmetry" (a mirror, the '
                         "example's); default both (--quick: symmetry)")
    ap.add_argument("--seeding", choices=("lattice", "mesh"), default="lattice",
                    help="the example's CSG body on the lattice (default) or a hexahedral mesh")
    ap.add_argument("--set", dest="extra", action="append", default=[], metavar="KEY=VALUE",
                    help="another scene override, for a diagnostic (repeatable)")
    args = ap.parse_args()
    comm = world()
    out, figs = folders(args, "taylor_bar")
    ns = args.resolutions or ([2] if args.quick else [2, 4, 8])
    anvils = args.anvils or (["symmetry"] if args.quick else ["slip", "symmetry"])
    rows = []
    for anvil, n in [(a, n) for a in anvils for n in ns]:
        row = run(n, comm, args.ppc, args.extra, args.seeding, anvil)
        if row is not None:
            rows.append(row)
            print(f"{anvil}, R0/dx = {n}: {row['particles']} particles, {row['steps']} steps, "
                  f"L_f {row['L_f_mm']:.3f} mm ({row['L_f_error_pct']:+.2f} %), "
                  f"R_f {row['R_f_mm']:.3f} mm ({row['R_f_error_pct']:+.2f} %), "
                  f"max eps_p {row['max_plastic_strain']:.3f}, {row['wall_seconds']:.1f} s, "
                  f"{row['particle_steps_per_second']:.4g} particle-steps/s", flush=True)
    if not is_root(comm):
        return 0
    write_csv(out / "taylor_bar.csv", [{k: v for k, v in r.items() if k != "_section"}
                                       for r in rows])
    path = taylor_figure(rows, figs / "taylor_bar.png")
    print(wrote(out / "taylor_bar.csv"))
    print(wrote(path))
    return 0


ANVIL_STYLE = {"slip": ("tab:purple", "o"), "symmetry": ("tab:green", "s")}


def taylor_figure(rows: list[dict], path):
    """The finest bars' sections near z = 0 coloured by ε̄p (the first anvil's at x < 0, the
    second's at x > 0, or one mirrored), and L_f and R_f against Δx with the references."""
    fig, axes = figure(1, 3, size=(11.5, 4.8))
    anvils = list(dict.fromkeys(r["anvil"] for r in rows))
    finest = [max((r for r in rows if r["anvil"] == a), key=lambda r: r["R0_over_dx"])
              for a in anvils]
    halves = [(finest[0], -1.0), (finest[-1], 1.0)]
    top = max(float(r["_section"]["epsp"].max()) for r, _ in halves)
    ax = axes[0, 0]
    for row, sign in halves:
        sec = row["_section"]
        near = sec["x0"][:, 2] < np.cbrt(sec["vol0"])  # the first layer off the mirror z = 0
        im = ax.scatter(sign * sec["x"][near, 0] * 1e3, sec["x"][near, 1] * 1e3,
                        c=sec["epsp"][near], s=max(1.0, 60.0 / row["R0_over_dx"]),
                        cmap="viridis", vmin=0.0, vmax=top, linewidths=0)
    ax.axhline(L_REF * 1e3, color="tab:red", lw=0.8, ls="--", label="L_f = 21.43 mm (FE)")
    for sign in (-1, 1):
        ax.axvline(sign * R_REF * 1e3, color="tab:orange", lw=0.8, ls="--",
                   label="R_f = 7.22 mm" if sign > 0 else None)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(f"80 µs, R0/Δx = {finest[0]['R0_over_dx']}, near z = 0\n"
                 f"anvil {anvils[0]} (x < 0), {anvils[-1]} (x > 0)", fontsize=8)
    ax.legend(fontsize=6.5, loc="upper right")
    fig.colorbar(im, ax=ax, label="equivalent plastic strain")
    for ax, key, ref, name in ((axes[0, 1], "L_f", L_REF, "final length"),
                               (axes[0, 2], "R_f", R_REF, "mushroom radius")):
        for anvil in anvils:
            mine = [r for r in rows if r["anvil"] == anvil]
            dx = np.array([r["dx_mm"] for r in mine])
            colour, marker = ANVIL_STYLE[anvil]
            ax.plot(dx, [r[f"{key}_mm"] for r in mine], "-", marker=marker, color=colour,
                    label=f'anvil "{anvil}": centre + half-extent')
            ax.plot(dx, [r[f"{key}_centre_mm"] for r in mine], ":", marker=marker,
                    color=colour, alpha=0.5, label=f'anvil "{anvil}": particle centres')
        ax.axhline(ref * 1e3, color="k", lw=1.0, label=f"reference {ref * 1e3:.2f} mm")
        if key == "R_f":
            for (who, v), ls in zip(R_OLDER.items(), ("--", "-.")):
                ax.axhline(v * 1e3, color="0.5", lw=0.8, ls=ls, label=f"{who}: {v * 1e3:.2f} mm")
        dx = sorted({r["dx_mm"] for r in rows})
        ax.set_xscale("log")
        ax.minorticks_off()
        ax.set_xticks(dx, [f"{d:.2f}" for d in dx])
        ax.set_xlabel("Δx (mm)")
        ax.set_ylabel(f"{key} (mm)")
        ax.set_title(f"Taylor bar: {name} against Δx", fontsize=9)
        ax.grid(color="0.9")
        ax.legend(fontsize=6)
    return save(fig, path)


if __name__ == "__main__":
    main_guard(main)
