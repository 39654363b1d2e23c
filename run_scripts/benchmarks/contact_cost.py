"""What contact costs: two cpdi disks pressed together head on, one rank, stepped two ways in one
process, interleaved, each repeat's milliseconds per step kept:

* ``one field``: no ``[contact]`` (the disks share one velocity field, the specialised kernels);
* ``contact``: ``[contact]`` between the two disks (frictionless), each its own field.

The scene is the one the contact page's cost figures were taken on (docs/concepts/contact.md,
"What it costs"): disks of radius 0.15 m side by side and touching, closing at ±1 m/s, Δx = 5 mm,
2 × 2 particles per cell (22,608 particles; the page's first figures, on disks placed
slightly differently, had 22,620), neo-Hookean. After ``--warm`` steps (compiling, and
the disks pressed into each other), ``--repeat`` rounds of ``--steps`` steps each; the phases
(P2G, grid, G2P, ...) are summed over each case's fastest round.

    python run_scripts/benchmarks/contact_cost.py --steps 30 --repeat 3
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np

from decomposition import world
from parmpm.core.errors import ParmpmError
from parmpm.driver.set_up import set_up
from parmpm.scene.load import scene_from_toml

SCENE = """
name = "pressed_disks"
dim = 2
[grid]
origin = [-0.35, -0.2]
cell_size = {cell}
cells = [{nx}, {ny}]
{patch}[materials.rubber]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3
[[bodies]]
shape = "disk"
center = [-0.15, 0.0]
radius = 0.15
material = "rubber"
ppc = 2
seeding = "lattice"
velocity = [1.0, 0.0]
[[bodies]]
shape = "disk"
center = [0.15, 0.0]
radius = 0.15
material = "rubber"
ppc = 2
seeding = "lattice"
velocity = [-1.0, 0.0]
[time]
end = 1.0
[output]
snapshots = false
figure = false
history = false
"""


def scene(cell: float, contact: bool, patch: int = 0) -> str:
    """The scene at ``cell`` (m), with ``[contact]`` or one field; ``patch`` cells per patch side
    (0: the automatic size)."""
    text = SCENE.format(cell=cell, nx=round(0.7 / cell), ny=round(0.4 / cell),
                        patch=f"patch_size = [{patch}, {patch}]\n" if patch else "")
    return text + ("[contact]\nfriction = 0.0\n" if contact else "")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cell", type=float, default=0.005)
    ap.add_argument("--warm", type=int, default=60)
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--patch", type=int, default=0, help="cells per patch side (0: automatic)")
    a = ap.parse_args()
    if min(a.warm, a.steps, a.repeat) < 1 or a.patch < 0 or not 0.0 < a.cell < math.inf:
        raise SystemExit("contact_cost: --warm, --steps and --repeat must be at least 1, "
                         f"--patch >= 0 (0: automatic), --cell finite and > 0 "
                         f"(got {a.warm}, {a.steps}, {a.repeat}, {a.patch}, {a.cell})")
    try:
        states = {name: set_up(scene_from_toml(scene(a.cell, contact, a.patch), "<disks>"), world())
                  for name, contact in (("one field", False), ("contact", True))}
    except ParmpmError as exc:  # e.g. a cell too coarse for the 0.7 x 0.4 m grid: one line
        raise SystemExit(f"contact_cost: {exc}") from None
    n = states["contact"].particles.n
    g = np.zeros(3)
    dt = 0.2 * a.cell / 40.0  # cfl 0.2 at about the disks' wave speed
    clock = dict.fromkeys(states, 0.0)
    for name, s in states.items():
        for _ in range(a.warm):
            s.stepper.step(dt, g, clock[name])
            clock[name] += dt
    best = {name: (np.inf, None) for name in states}
    rounds = {name: [] for name in states}
    for _ in range(a.repeat):
        for name, s in states.items():
            T = s.stepper.timers
            for k in T:
                T[k] = 0.0
            t0 = time.perf_counter()
            for _ in range(a.steps):
                s.stepper.step(dt, g, clock[name])
                clock[name] += dt
            ms = 1e3 * (time.perf_counter() - t0) / a.steps
            rounds[name].append(ms)
            if ms < best[name][0]:
                best[name] = (ms, {k: 1e3 * v / a.steps for k, v in T.items()})
    lay = states["contact"].disc.layout
    print(f"{n} particles, cell {a.cell} m, patches of {tuple(int(c) for c in lay.psize3[:2])} cells, "
          f"{a.steps} steps x {a.repeat} repeats, one rank")
    base = best["one field"][0]
    for name in states:
        ms, phases = best[name]
        print(f"  {name:10s} {ms:7.3f} ms/step (repeats {', '.join(f'{m:.3f}' for m in rounds[name])}), "
              f"{ms / base:.2f}x; {n / ms / 1e3:.2f} M particle-steps/s")
        print("             " + ", ".join(f"{k} {v:.3f}" for k, v in phases.items() if v > 0) + " ms")


if __name__ == "__main__":
    main()
