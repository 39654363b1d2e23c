"""What counting the pieces of material costs beside the step it follows: the default scene (the
2D hanging bar, cpdi, ``l_cr = 2dx``) or its 3D twin (``--scene hanging_bar_3d``), whose metrics
count the connected pieces after every step (``metrics.stop_on_separation``), at several cell
sizes, one rank.

For each cell size it sets the scene up, steps it ``--warm`` times (compiling), then times
``--steps`` steps, each followed by a count (:func:`parmpm.driver.measures.components`: the
particles' rows put back in canonical order, every particle's support nodes, the union-find over
them), as a run whose metrics sample every step does; ``--repeat`` times, and prints the best
mean milliseconds of each and their ratio.

    python run_scripts/benchmarks/separation_cost.py --cells 0.05 0.02 0.01 --steps 10 --repeat 3
    python run_scripts/benchmarks/separation_cost.py --scene hanging_bar_3d --cells 0.2 0.1 0.0667
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from decomposition import world
from parmpm.core.errors import ParmpmError
from parmpm.driver import measures
from parmpm.driver.set_up import set_up
from parmpm.scene.load import load_scene

#: each scene's grid span (m) and its coarsest cell: the 2D bar's grid is 2 m x 3.2 m from
#: (-0.5, -3.0), the 3D bar's 1.8 m x 3.2 m x 1.8 m from (-0.4, -3.0, -0.4); the bar is the unit
#: square (cube) below y = 0 in both
SPANS = {"hanging_bar": ((2.0, 3.2), 0.1), "hanging_bar_3d": ((1.8, 3.2, 1.8), 0.2)}


def scene(cell: float, name: str = "hanging_bar"):
    """The scene ``name`` at ``cell`` (m), outputs off."""
    cells = [round(span / cell) for span in SPANS[name][0]]
    return load_scene(name, [f"grid.cell_size={cell}", f"grid.cells={cells}",
                             "output.snapshots=false", "output.figure=false",
                             "output.history.enabled=false"])


def measure(cell: float, warm: int, steps: int, repeat: int, name: str = "hanging_bar") -> dict:
    """Best ms per step and per count at ``cell``, the particle count and the pieces counted."""
    s = set_up(scene(cell, name), world())
    g = np.array([0.0, -1000.0, 0.0])
    dt = 0.4 * cell / 40.0  # about the scene's CFL step (cfl 0.4, c ~ 36 m/s)
    t = 0.0
    for _ in range(warm):
        s.stepper.step(dt, g, t)
        t += dt
    pieces = measures.components(s)  # compiled here, before the timing
    step_ms, count_ms = [], []
    for _ in range(repeat):
        stepping = counting = 0.0
        for _ in range(steps):  # as a run with metrics every step: a step, then a count
            t0 = time.perf_counter()
            s.stepper.step(dt, g, t)
            t1 = time.perf_counter()
            pieces = measures.components(s)
            counting += time.perf_counter() - t1
            stepping += t1 - t0
            t += dt
        step_ms.append(1e3 * stepping / steps)
        count_ms.append(1e3 * counting / steps)
    return {"particles": int(s.particles.n), "step": min(step_ms), "count": min(count_ms),
            "pieces": int(pieces)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", choices=sorted(SPANS), default="hanging_bar")
    ap.add_argument("--cells", type=float, nargs="+", default=[0.05, 0.02, 0.01])
    ap.add_argument("--warm", type=int, default=3)
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    coarsest = SPANS[a.scene][1]
    bad = [c for c in a.cells if not 0.0 < c <= coarsest]
    if min(a.warm, a.steps, a.repeat) < 1 or bad:
        raise SystemExit("separation_cost: --warm, --steps and --repeat must be at least 1 and "
                         f"every --cells in (0, {coarsest:g}] m for {a.scene} (got {a.warm}, "
                         f"{a.steps}, {a.repeat}, {a.cells})")
    print("cell (m)  particles  step (ms)  count (ms)  count/step  pieces")
    for cell in a.cells:
        try:
            r = measure(cell, a.warm, a.steps, a.repeat, a.scene)
        except ParmpmError as exc:
            raise SystemExit(f"separation_cost: {exc}") from None
        print(f"{cell:8g}  {r['particles']:9d}  {r['step']:9.3f}  {r['count']:10.3f}  "
              f"{r['count'] / r['step']:10.2f}  {r['pieces']:6d}")


if __name__ == "__main__":
    main()
