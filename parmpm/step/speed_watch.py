"""When a run with a fixed step (``time.dt``) measures the CFL speed.

Its G2P kernels leave the wave speed out (:mod:`parmpm.transfer.running_speed`) and report only
whether every particle stayed finite; the speed is still wanted, for the warning of a fixed step
past the CFL one (:class:`parmpm.driver.schedule.Clock`) and for what a checkpoint and the
summary record, but not every step: a pass of its own measures it at the first step and every
``every`` steps after it, the same steps on every rank. In 2D and 3D the pass is G2P's own
formula (:func:`parmpm.transfer.kernels2d.material.speed_pass`): 11.6 ns a particle in 2D and 16.9
in 3D, where the dimension-generic one took 16.7 and 27.7 (2026-11-30, 10⁶ particles): 0.6 ns a
step in 2D at every 20.
"""
from __future__ import annotations

import math

from parmpm.materials.passes import max_speed
from parmpm.transfer.kernels2d.material import speed_pass as speed_pass_2d
from parmpm.transfer.kernels3d.material import speed_pass as speed_pass_3d

#: the steps between two measurements
SPEED_EVERY = 20


class SpeedWatch:
    """The count of a fixed-step run's steps since the speed was last measured."""

    def __init__(self, every: int = SPEED_EVERY):
        if every < 1:
            raise ValueError(f"speed watch: expected a positive number of steps, got {every}")
        self.every = every
        self.since = 0

    def after_g2p(self, vmax: float, rows, params) -> tuple[float, bool]:
        """(this step's ``vmax``, whether it is the CFL speed): G2P's (0, or ``inf`` on a
        blow-up, kept as it is) and, on a measuring step, the largest ``c + |v|`` of every
        particle (``rows``: the physical rows)."""
        measured = self.since == 0
        self.since = (self.since + 1) % self.every
        if measured and math.isfinite(vmax):
            d = rows.v.shape[1]
            if d == 2:
                speed = speed_pass_2d(rows.v, rows.F, rows.mat, params)
            elif d == 3:
                speed = speed_pass_3d(rows.v, rows.F, rows.mat, params)
            else:
                speed = max_speed(d, rows.v, rows.F, rows.mat, params)
            vmax = max(vmax, speed)
        return vmax, measured
