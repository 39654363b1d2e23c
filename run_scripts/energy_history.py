"""Energy history of a user's scene: the colliding blocks of docs/examples, every term of the balance.

    python run_scripts/energy_history.py                 # the run and history.png in run_scripts/out/
    python run_scripts/energy_history.py --figures docs/figures      # the README's figure
    mpirun -n 2 python run_scripts/energy_history.py     # the same numbers on any rank count

Runs ``docs/examples/colliding_blocks.toml`` (two neo-Hookean blocks thrown at each other under
gravity, landing on a fixed floor) and draws its ``history.csv``: the energies (kinetic, elastic,
gravitational, their sum) and where the energy went (the floor's constraints, the particle–grid
transfers, the integrator's residual; ``docs/energy.md``).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import study  # noqa: E402

from parmpm.io.history_file import read_history  # noqa: E402

SCENE = Path(__file__).resolve().parent.parent / "docs" / "examples" / "colliding_blocks.toml"


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


def main() -> int:
    args = study.parser(__doc__).parse_args()
    comm = study.world()
    out, figures = study.folders(args, "energy_history")
    overrides = ["time.end=0.05"] if args.quick else []
    study.run_case(SCENE, overrides, comm=comm, out_dir=out / "run")
    if study.is_root(comm):
        h = read_history(out / "run" / "history.csv")
        given = h["kinetic"][0] + h["elastic"][0] + np.max(h["work_gravity"])
        print(f"{int(h['step'][-1])} steps; energy given {given:.4g} J; at the end: taken by the "
              f"floor {-h['work_boundary'][-1]:.4g} J, transfers {h['transfer_dissipation'][-1]:.4g}"
              f" J, residual {h['energy_residual'][-1]:.4g} J "
              f"(max |R| = {np.max(np.abs(h['energy_residual'])) / given:.1%} of it)")
        print(study.wrote(plot(h, figures / "history.png")))
    return 0


if __name__ == "__main__":
    sys.exit(main())
