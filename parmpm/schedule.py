"""Schedules: when a periodic action (a snapshot, a checkpoint) is due.

One rule for every schedule of a run, so that none can loop or drift: an action is due at the end
of a step when the step count is a multiple of ``every_steps``, or when simulated time has reached
the next multiple of ``every`` (within a relative 1e-12, so that a time that lands on a multiple up
to round-off counts as there). After it fires, the next due time is computed, not accumulated:

    next = every · (⌊t / every · (1 + 1e-12)⌋ + 1)

which is one multiple past ``t`` however small ``every`` is. A period shorter than a time step
(or shorter than the round-off of ``t``) therefore fires once per step, never more: a schedule
advances at least one step. The next due time is part of the run's state (it is checkpointed), so
a restart continues the same series.
"""
from __future__ import annotations

import math

#: relative tolerance of "simulated time has reached a scheduled time"
REL_TOL = 1e-12


class Schedule:
    """Due every ``every`` simulated seconds and/or every ``every_steps`` steps (either may be
    None or 0 = off). ``next_time`` restores a checkpointed schedule; by default the first time
    due is the first multiple of ``every`` after ``t``."""

    def __init__(self, every: float | None = None, every_steps: int | None = None,
                 t: float = 0.0, next_time: float | None = None):
        self.every = float(every) if every else None
        self.every_steps = int(every_steps) if every_steps else None
        if next_time is not None:
            self.next_time = float(next_time)
        else:
            self.next_time = self._after(t)

    def _after(self, t: float) -> float:
        """The first multiple of ``every`` past ``t`` (inf when there is no time period)."""
        if self.every is None:
            return math.inf
        k = math.floor(t / self.every * (1.0 + REL_TOL)) + 1.0
        return k * self.every

    def due(self, t: float, step: int) -> bool:
        """Whether the action is due at the end of step ``step`` at time ``t``."""
        if self.every_steps and step % self.every_steps == 0:
            return True
        return t >= self.next_time * (1.0 - REL_TOL)

    def advance(self, t: float) -> None:
        """The action ran at time ``t``: move the next time due past ``t`` (no loop)."""
        if self.every is not None and t >= self.next_time * (1.0 - REL_TOL):
            self.next_time = self._after(t)
