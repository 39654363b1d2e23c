"""Energy history of a user's scene: the colliding blocks of docs/examples, every term of the balance.

    python run_scripts/studies/energy_history.py                 # the runs and figures in run_scripts/out/
    python run_scripts/studies/energy_history.py --figures docs/figures      # the documentation's figure
    mpirun -n 2 python run_scripts/studies/energy_history.py     # the same numbers on any rank count
    python run_scripts/studies/energy_history.py --methods cpdi,bspline_apic

Runs ``docs/examples/colliding_blocks.toml`` (two neo-Hookean blocks thrown at each other under
gravity, landing on a fixed floor) and draws its ``history.csv``: the energies (kinetic, elastic,
gravitational, their sum) and where the energy went (the floor's constraints, the particle–grid
transfers, the integrator's residual; ``docs/energy.md``) in ``history.png`` (the scene as
written: CPDI, FLIP). Then the same scene with every method of ``--methods`` (default: all of
:data:`study.METHODS`, each at its default update; B-splines with FLIP, APIC and MLS) side by
side in ``history_methods.png``: the total K + Ψ + U_g, the transfer dissipation D_t, the
integrator residual R and the kinetic energy K, with one summary line per method and
``history_methods.csv`` (one row per method; also the angular momentum about the origin at the
start and the end, APIC's with the particles' affine spin — not conserved here: gravity and the
floor exert torques).

Found (full run, to 0.3 s; the blocks land at ~0.1 s and stick): K + Ψ + U_g starts at 90 J
and ends at 91.1 (mpm), 89.4 (uGIMP, cpGIMP), 89.3 (bspline FLIP), 67.3 (CPDI) and 23.8 J
(bspline APIC). With FLIP the transfer term D_t ends negative for every method but mpm
(uGIMP −21.7, cpGIMP −11.3, CPDI −70.2, bspline −119.8 J) and the floor takes the balance
(−W_bc 57.5, 52.4, 81.3, 137.2 J; mpm: D_t +38.9 J, −W_bc 36.0 J); APIC's transfers dissipate
60.2 J and the floor takes 12.6 J: the impact's energy leaves through the transfers (MLS: 24.4 J
at the end, 58.9 J through the transfers, 12.5 J to the floor). The
integrator residual's largest |R| is 2.4 % of the energy given with MLS, 2.7 % APIC, 4.7 % CPDI, 6.7 %
bspline FLIP, 14–16 % uGIMP and cpGIMP, 30 % mpm.

Runtime, one core: full (0.3 s, 6 runs, ~400 steps each) ~5 s; ``--quick`` (to 0.05 s, before
the blocks meet: the scene and the B-spline APIC run) a few seconds.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py, the groups
import study

from parmpm.io.history_file import read_history

SCENE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "colliding_blocks.toml"
QUICK_METHODS = ("bspline_apic",)  # --quick: besides the scene's own run


def plot(h: dict, png: Path) -> Path:
    fig, axes = study.figure(2, 1, size=(7.0, 6.4))
    top, low = axes[:, 0]
    t = h["time"]
    k, psi, ug = h["kinetic"], h["elastic"], h["gravity_potential"]
    top.plot(t, k, label="kinetic K")
    top.plot(t, psi, label="elastic Ψ")
    top.plot(t, ug, label="gravity U_g")
    top.plot(t, k + psi + ug, "k", lw=2, label="K + Ψ + U_g")
    top.set_ylabel("energy (J)")
    top.set_title("colliding blocks: energies (history.csv, every step)")
    top.legend(fontsize=8, ncol=2)
    lost = -(h["work_boundary"] - h["damping_dissipation"] - h["transfer_dissipation"])
    low.plot(t, -h["work_boundary"], ":", label="taken by the floor's constraints −W_bc")
    low.plot(t, h["transfer_dissipation"], "--", label="particle–grid transfers D_t (FLIP)")
    low.plot(t, lost, lw=2, label="their sum: energy the scheme took out")
    low.plot(t, h["energy_residual"], "r", label="integrator residual R")
    low.set_ylabel("energy (J)")
    low.set_xlabel("t (s)")
    low.legend(fontsize=8)
    for ax in (top, low):
        ax.grid(alpha=0.3)
    return study.save(fig, png)


def given_energy(h: dict) -> float:
    """K₀ + Ψ₀ + the largest work of gravity so far: the energy the run was given."""
    return float(h["kinetic"][0] + h["elastic"][0] + np.max(h["work_gravity"]))


def scene_method() -> str | None:
    """The key of :data:`study.METHODS` the scene runs as written (None if none matches)."""
    from parmpm import load_scene

    m = load_scene(SCENE).data["method"]
    return next((k for k, v in study.METHODS.items()
                 if (v.interpolator, v.transfer) == (m["interpolator"], m["transfer"])), None)


def summary_row(key: str, h: dict, wall: float) -> dict:
    given = given_energy(h)
    total = h["kinetic"] + h["elastic"] + h["gravity_potential"]
    lz = h["angular_momentum_z"]
    return {"method": key, "steps": int(h["step"][-1]), "energy_given": given,
            "total_start": float(total[0]), "total_end": float(total[-1]),
            "kinetic_end": float(h["kinetic"][-1]), "work_boundary_end": float(h["work_boundary"][-1]),
            "transfer_dissipation_end": float(h["transfer_dissipation"][-1]),
            "residual_end": float(h["energy_residual"][-1]),
            "residual_max_abs_over_given": float(np.max(np.abs(h["energy_residual"])) / given),
            "angular_momentum_z_start": float(lz[0]), "angular_momentum_z_end": float(lz[-1]),
            "wall_seconds": wall}


def plot_methods(hist: dict[str, dict], png: Path) -> Path:
    """2×2 against time, a colour per method: K + Ψ + U_g, D_t, R and K."""
    fig, axes = study.figure(2, 2, size=(10.0, 6.6))
    panels = ((axes[0, 0], "total K + Ψ + U_g (J)", lambda h: h["kinetic"] + h["elastic"]
               + h["gravity_potential"]),
              (axes[0, 1], "transfer dissipation D_t (J)", lambda h: h["transfer_dissipation"]),
              (axes[1, 0], "integrator residual R (J)", lambda h: h["energy_residual"]),
              (axes[1, 1], "kinetic energy K (J)", lambda h: h["kinetic"]))
    for ax, label, f in panels:
        for key, h in hist.items():
            m = study.METHODS[key]
            ax.plot(h["time"], f(h), color=m.colour, lw=1.2, label=m.label)
        ax.set_ylabel(label, fontsize=8)
        ax.set_xlabel("t (s)", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, ncol=2)
    fig.suptitle("colliding blocks (docs/examples), each method at its default update", fontsize=10)
    return study.save(fig, png)


def main() -> int:
    ap = study.parser(__doc__)
    ap.add_argument("--methods", default=None, help="comma-separated subset of "
                    + ", ".join(study.METHOD_KEYS) + " for history_methods.png (default: all;"
                    " --quick: " + ", ".join(QUICK_METHODS) + "; 'none' for the scene alone)")
    args = ap.parse_args()
    comm = study.world()
    root = study.is_root(comm)
    out, figures = study.folders(args, "energy_history")
    overrides = ["time.end=0.05"] if args.quick else []
    _, wall = study.run_case(SCENE, overrides, comm=comm, out_dir=out / "run")
    if root:
        h = read_history(out / "run" / "history.csv")
        given = given_energy(h)
        print(f"{int(h['step'][-1])} steps; energy given {given:.4g} J; at the end: taken by the "
              f"floor {-h['work_boundary'][-1]:.4g} J, transfers {h['transfer_dissipation'][-1]:.4g}"
              f" J, residual {h['energy_residual'][-1]:.4g} J "
              f"(max |R| = {np.max(np.abs(h['energy_residual'])) / given:.1%} of it)")
        print(study.wrote(plot(h, figures / "history.png")))
    if args.methods == "none":
        return 0
    keys = (study.method_keys(args.methods) if args.methods
            else QUICK_METHODS if args.quick else study.METHOD_KEYS)
    own = scene_method()
    walls = {own: wall}
    for key in keys:
        if key != own:  # the scene as written is that method's run
            _, walls[key] = study.run_case(SCENE, overrides + study.METHODS[key].overrides(),
                                           comm=comm, out_dir=out / f"run_{key}")
    if root:
        hist = {k: read_history(out / ("run" if k == own else f"run_{k}") / "history.csv")
                for k in study.METHOD_KEYS if k in keys or k == own}
        rows = [summary_row(k, h, walls[k]) for k, h in hist.items()]
        for r in rows:
            print(f"{r['method']:12s} {r['steps']:5d} steps: K+Ψ+U_g {r['total_start']:.4g} → "
                  f"{r['total_end']:.4g} J, D_t {r['transfer_dissipation_end']:.4g} J, "
                  f"−W_bc {-r['work_boundary_end']:.4g} J, R {r['residual_end']:.4g} J (max |R| "
                  f"{r['residual_max_abs_over_given']:.1%} of {r['energy_given']:.4g} J given), "
                  f"{r['wall_seconds']:.1f} s")
        study.write_csv(out / "history_methods.csv", rows)
        print(study.wrote(out / "history_methods.csv"))
        print(study.wrote(plot_methods(hist, figures / "history_methods.png")))
    return 0


if __name__ == "__main__":
    sys.exit(main())
