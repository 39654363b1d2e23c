"""The step's rigid walls on this rank: where each plane is and how fast it moves at a time, and
the grid correction after every nodal update (:func:`parmpm.grid.walls.apply_walls`).

A wall's position is ``p(t) = p₀ + v_w ∫₀ᵗ f`` and its velocity ``v_w f(t)``
(:mod:`parmpm.loads.time_functions`): functions of time alone, so nothing needs carrying across a
restart or between ranks. The corrections of a step use the wall at the step's end, ``t + Δt``,
where the updated grid velocities belong. ``sums`` keeps the last force update's per-slot impulse
and work for the energy ledger (:class:`parmpm.output.energy.EnergyLedger`), which adds them in
patch order.
"""
from __future__ import annotations

import numpy as np

from decomposition import accumulate
from parmpm.grid.walls import apply_walls, touching


class WallPhase:
    """``walls``: the scene's wall records (``point``, ``normal``, ``velocity``, ``mu``,
    ``time``), in order."""

    def __init__(self, walls, dim: int):
        n = len(walls)
        self.walls = tuple(walls)
        self.names = tuple(w.name for w in walls)
        self.point0 = np.zeros((n, 3))
        self.normal = np.zeros((n, 3))
        self.speed = np.zeros((n, 3))
        self.mu = np.array([w.mu for w in walls], float)
        for i, w in enumerate(walls):
            self.point0[i, :dim] = w.point
            self.normal[i, :dim] = w.normal
            self.speed[i, :dim] = w.velocity
        self.moves = any(w.moves for w in walls)
        self.sums: np.ndarray | None = None  # (slots, walls, 6) of the last force update
        self.touch = np.zeros((0, 0, 1))      # nodes near a particle touching a wall

    def mark(self, disc, P, grid, plan, t: float) -> None:
        """Mark the nodes near particles touching a wall at ``t`` (the step's start), summed over
        the ghost layers (collective)."""
        slots, nodes = grid.gsum.shape[0], grid.gsum.shape[1]
        if self.touch.shape[:2] != (slots, nodes):
            self.touch = np.zeros((slots, nodes, 1))
        self.touch[:] = 0.0
        point, _ = self.at(t)
        R = P.rows
        touching(disc.dim, P.start, P.order(), R.x, R.F, R.r0, point, self.normal, disc.origin3,
                 disc.h3, disc.base, disc.nloc, self.touch[:, :, 0])
        accumulate(plan, self.touch)

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Every wall's point and velocity at time ``t``."""
        fs = np.array([w.time.value(t) for w in self.walls])
        Fs = np.array([w.time.integral(t) for w in self.walls])
        return self.point0 + self.speed * Fs[:, None], self.speed * fs[:, None]

    def apply(self, disc, nodes, grid, dt: float, gravity: np.ndarray, heavy: float,
              t_end: float, momentum_only: bool, add: bool = False) -> None:
        """Correct the grid velocities of ``grid`` (after the nodal update of the step ``dt``)
        for every wall as it is at ``t_end``; ``heavy``: the lightest node whose force counts;
        ``add``: add to the sums of another field's grid this step (contact's fields)."""
        point, velocity = self.at(t_end)
        g = np.zeros(3)
        g[:disc.dim] = gravity[:disc.dim]
        sums = apply_walls(disc.dim, nodes, disc.origin3, disc.h3, point, self.normal,
                           velocity, self.mu, dt, g, heavy, self.touch[:, :, 0],
                           grid.gsum_block, grid.gnew_block, momentum_only)
        if not momentum_only:
            self.sums = sums if not add else self.sums + sums
