"""What crack faces cost: the broken bar in 2D (``docs/examples/broken_bar.toml`` made a 0.04 m
plate, ``tests/step/test_crack.py``'s ``bar_text``) at a finer cell, one rank, stepped three ways in
one process, interleaved, each repeat's milliseconds per step kept:

* ``one field``: no ``[contact]``, the specialised kernels (what such a scene runs);
* ``one field, generic``: the same with the generic transfer loops (what crack runs use: it
  separates the loops' cost from the crack's own);
* ``cracks``: ``[contact] cracks = true``.

Each is timed over ``--steps`` steps before the break (no node has a crack: what a crack run
pays for finding that out) and, continued from there, over the steps after it (the crack open,
the halves in two fields). The phases' shares (P2G, grid, G2P, ...) printed last are over each
run's whole life, its first steps' compiling included: a rough guide, not a measurement.

    python run_scripts/benchmarks/crack_cost.py --cell 0.0025 --steps 40 --repeat 3
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: the groups

from decomposition import world
from parmpm.driver.set_up import set_up
from parmpm.scene.load import scene_from_toml
from tools.broken_bar import BAR, bar_text


def scene(cell: float, cracks: bool) -> str:
    """The 2D bar at ``cell`` (the grid and the bar's width scaled with it: 4 cells across)."""
    text = bar_text(BAR.read_text(), 2)
    k = 0.01 / cell
    text = text.replace("cell_size = 0.01", f"cell_size = {cell}")
    text = text.replace("cells = [100, 8]", f"cells = [{round(100 * k)}, 8]")
    text = text.replace("origin = [-0.5, -0.04]", f"origin = [-0.5, {-4 * cell}]")
    for a, b in (("-0.02]", f"{-2 * cell}]"), ("0.02]", f"{2 * cell}]")):
        text = text.replace(a, b)
    text += '\n[output]\nsnapshots = false\nfigure = false\n'
    text = text.replace("[output]\nevery = 0.02\n", "")
    return text if cracks else text.replace("[contact]\ncracks = true\n", "")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cell", type=float, default=0.0025)
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    runs = {"one field": (False, "specialised"), "one field, generic": (False, "generic"),
            "cracks": (True, None)}
    states = {}
    for name, (cracks, kernels) in runs.items():
        s = set_up(scene_from_toml(scene(a.cell, cracks), "<bar>"), world())
        if kernels:
            s.stepper.use_kernels(kernels)
        states[name] = s
    n = states["cracks"].particles.n
    g = np.zeros(3)
    dt = 0.2 * a.cell / 10.0  # cfl 0.2 at c = 10 m/s
    # the break: about 0.016 s; before it, from 0.002 s; after it, from 0.03 s
    t_before, t_after = 0.002, 0.03
    best = {(name, when): [] for name in runs for when in ("before", "after")}
    clock = {name: 0.0 for name in runs}
    for name, s in states.items():  # warm up (compile) and move to the first window
        while clock[name] < t_before:
            s.stepper.step(dt, g, clock[name])
            clock[name] += dt
    for when, until in (("before", t_after), ("after", None)):
        for _ in range(a.repeat):
            for name, s in states.items():
                t0 = time.perf_counter()
                for _ in range(a.steps):
                    s.stepper.step(dt, g, clock[name])
                    clock[name] += dt
                best[(name, when)].append(1e3 * (time.perf_counter() - t0) / a.steps)
        if until is not None:
            for name, s in states.items():
                while clock[name] < until:
                    s.stepper.step(dt, g, clock[name])
                    clock[name] += dt
    dmax = float(states["cracks"].particles.damage.max())
    print(f"{n} particles, cell {a.cell} m, {a.steps} steps x {a.repeat} repeats "
          f"(the bar's largest damage at the end: {dmax:.3f})")
    for when in ("before", "after"):
        base = min(best[("one field", when)])
        for name in runs:
            ms = best[(name, when)]
            print(f"  {when:6s} {name:20s} {min(ms):7.3f} ms/step (repeats "
                  f"{', '.join(f'{m:.3f}' for m in ms)}), {min(ms) / base:.2f}x; "
                  f"{n / min(ms) / 1e3:.2f} M particle-steps/s")
    for name, s in states.items():
        T = s.stepper.timers
        total = sum(T.values())
        print(f"  phase shares over the run, compiling included ({name}): " + ", ".join(f"{k} {100 * v / total:.0f}%"
                                                  for k, v in T.items() if v > 0))


if __name__ == "__main__":
    main()
