"""CPDI domains as ParaView shows them, drawn from a run's snapshot files: the hanging bar with
domains that tile it, and with domains capped at too small an l_cr.

    python run_scripts/tools/domains_picture.py                          # runs + domains.png in run_scripts/out/
    python run_scripts/tools/domains_picture.py --figures docs/figures   # the documentation's figure
    mpirun -n 2 python run_scripts/tools/domains_picture.py              # the same picture on 2 ranks

Runs the built-in ``hanging_bar`` (CPDI, 2D, 1000 m/s² gravity switched on at t = 0) to
t = 0.06 s twice, with snapshots on: with the scene's ``l_cr = 2Δx`` and with
``l_cr = 0.8Δx/3`` (0.8 particle spacings). It reads the series back with
:func:`parmpm.io.load_snapshots`, as any user can, and draws every particle's domain — the
``domains`` of the snapshots: the parallelogram ``x_p + R ξ`` the interpolation uses, after the
``l_cr`` cap — coloured by the axial stretch ``|F e_y|``, over the grid. In ParaView: open
``hanging_bar.xdmf``, pick the ``domains`` block, colour by ``stretch``.

Expected: with ``l_cr = 2Δx`` no domain reaches the cap; the domains tile the bar (their areas
sum to its area Σ V₀ det F), long and thin near the support, stretched to 3.7. With
``l_cr = 0.8Δx/3`` every domain stretched by more than ~1.25 is capped (622 of 900 at 0.06 s);
the capped domains leave gaps (they cover 70 % of the bar) and the bar separates numerically
below the support at t = 0.056 s. The script prints, per case, the covered fraction at t = 0
(1) and at the end, how many domains are capped, and the separation time.
Runtime: ~4 s on one core (after compilation); ``--quick``: 2 particles per cell, ~2 s.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py, the groups
import study

CASES = (("2dx", "l_cr = 2Δx (the scene's)"), ("0.8dx/3", "l_cr = 0.8Δx/3"))


def run(lcr: str, folder: Path, quick: bool, comm) -> dict:
    """The hanging bar to t = 0.06 s with snapshots (and their domains) on, into ``folder``;
    its summary."""
    import parmpm

    overrides = [f"method.lcr={lcr}", "time.end=0.06", "output.every=0.03",
                 "output.figure=false", "output.history=false", "metrics.stop_on_separation=false"]
    if quick:
        overrides.append("bodies.0.ppc=2")
    scene = parmpm.load_scene("hanging_bar", overrides)
    return parmpm.Simulation(scene, folder, quiet=True, comm=comm, overwrite=True).run()


def polygon_areas(corners: np.ndarray) -> np.ndarray:
    """Areas of (N, 4, 2) polygons (shoelace)."""
    x, y = corners[..., 0], corners[..., 1]
    return 0.5 * np.abs(np.sum(x * np.roll(y, -1, axis=1) - y * np.roll(x, -1, axis=1), axis=1))


def draw(panels: list[tuple[str, dict]], png: Path) -> Path:
    from matplotlib.collections import PolyCollection
    from matplotlib.colors import Normalize

    fig, axes = study.figure(1, len(panels), size=(4.0 * len(panels) + 0.8, 6.4))
    norm = Normalize(1.0, 3.0)
    low = min(float(snap["domains"][..., 1].min()) for _, snap in panels)
    for ax, (title, snap) in zip(axes[0], panels):
        stretch = np.linalg.norm(snap["F"][:, :, 1], axis=1)
        cells = PolyCollection(snap["domains"], array=stretch, cmap="viridis", norm=norm,
                               edgecolors="k", linewidths=0.15)
        ax.add_collection(cells)
        for v in np.arange(-0.5, 1.51, 0.1):  # the grid
            ax.axvline(v, color="0.85", lw=0.4, zorder=0)
        for h in np.arange(-3.0, 0.21, 0.1):
            ax.axhline(h, color="0.85", lw=0.4, zorder=0)
        ax.axhline(0.0, color="0.3", lw=1.2)  # the support
        ax.set_xlim(-0.2, 1.2)
        ax.set_ylim(low - 0.05, 0.1)
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("x (m)")
    axes[0, 0].set_ylabel("y (m)")
    cax = axes[0, -1].inset_axes([1.06, 0.15, 0.05, 0.7])
    fig.colorbar(cells, cax=cax, label="axial stretch |F e_y|")
    return study.compact_png(study.save(fig, png))


def main() -> int:
    args = study.parser(__doc__).parse_args()
    comm = study.world()
    out, figures = study.folders(args, "domains_picture")
    panels = []
    for lcr, label in CASES:
        folder = out / f"lcr_{lcr.replace('/', '_')}"
        metrics = run(lcr, folder, args.quick, comm)["metrics"]
        if not study.is_root(comm):
            continue
        from parmpm.io import load_snapshots

        s = load_snapshots(folder / "hanging_bar.xdmf")
        first, last = s.at(0), s.at(-1)
        tiled = polygon_areas(first["domains"]).sum() / first["volume"].sum()
        areas = polygon_areas(last["domains"])
        covered = areas.sum() / last["volume"].sum()
        capped = areas < last["volume"] * (1 - 1e-9)  # a capped domain is smaller than V0 det F
        least = f"{last['stretch'][capped].min():.2f}" if capped.any() else "-"
        parted = (f", separated at {metrics['separation_time']:.3f} s" if metrics["separated"]
                  else "")
        print(f"{label}: t = {s.times[-1]:.3f} s, max stretch {last['stretch'].max():.2f}, "
              f"domains cover {tiled:.6f} of the bar at t = 0 and {covered:.4f} at the end; "
              f"{capped.sum()} of {capped.size} capped (least stretch among them {least})"
              f"{parted or ', whole'}")
        panels.append((f"{label}, t = {s.times[-1]:.2f} s\ndomains cover {covered:.1%} of the "
                       f"bar{parted}", last))
    if study.is_root(comm):
        print(study.wrote(draw(panels, figures / "domains.png")))
    return 0


if __name__ == "__main__":
    study.main_guard(main)
