"""The run's clock and its schedules: when the run ends, and when a periodic action (a snapshot,
a checkpoint, a metrics sample, the energy watch) is due.

Every schedule answers ``due(t, step)`` at the end of a step and hears ``advance(t)`` when its
action ran; :class:`Schedule` (simulated time, step count), :class:`WallTime` (minutes of wall
time, agreed by all ranks), :class:`AtEnd` (the last step) and :class:`AnyOf` (any of these) are
the kinds a run needs, and "simulated time has reached t" has one tolerance, ``REL_TOL``, for
all of them and for the end of the run.

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
import time

import numpy as np

from decomposition import allreduce_max
from parmpm.core.log import get_logger

log = get_logger(__name__)

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


class WallTime:
    """Due when ``minutes`` of wall time have passed since the action last ran, on the slowest
    rank (collective: every rank must ask at every step, so that all agree)."""

    def __init__(self, minutes: float, comm):
        self.seconds, self.comm = 60.0 * minutes, comm
        self.since = time.monotonic()

    def due(self, t: float, step: int) -> bool:
        waited = allreduce_max(self.comm, np.array([time.monotonic() - self.since]))[0]
        return waited >= self.seconds

    def advance(self, t: float) -> None:
        self.since = time.monotonic()


class AtEnd:
    """Due at the run's last step (its ``clock`` is done)."""

    def __init__(self, clock: Clock):
        self.clock = clock

    def due(self, t: float, step: int) -> bool:
        return self.clock.done()

    def advance(self, t: float) -> None:
        pass


class AnyOf:
    """Due when any of ``parts`` is (each is asked, as a collective one must be)."""

    def __init__(self, *parts):
        self.parts = parts

    def due(self, t: float, step: int) -> bool:
        return any([part.due(t, step) for part in self.parts])  # noqa: C419 (ask every part)

    def advance(self, t: float) -> None:
        for part in self.parts:
            part.advance(t)


class Clock:
    """Simulated time and step count, the CFL step and the end of the run (the scene's ``time``
    record, ``tm``: :class:`parmpm.scene.records.Time`; ``h_min``: the smallest cell size).
    ``vmax`` is the largest wave speed plus particle speed, which sets the next step.

    With ``time.dt`` every step is that long (the last one shortened to end on ``time.end``),
    whatever the CFL step: a user's choice, e.g. to compare with a code or a paper at its Δt. The
    CFL step is still computed from ``vmax``, which the stepper then measures every few steps
    rather than in every G2P (:meth:`parmpm.step.stepper.Stepper.fix_step`; the same on every
    rank), and the first step longer than it is one warning line naming both, said by rank 0
    (``speaks``; the energy watch stops a run that then blows up)."""

    def __init__(self, tm, h_min: float, vmax: float, t: float = 0.0, nstep: int = 0,
                 last_dt: float = 0.0, speaks: bool = True):
        self.tm, self.h_min, self.speaks = tm, h_min, speaks
        self.t, self.nstep, self.last_dt, self.vmax = t, nstep, last_dt, vmax
        self.dt_limit = "time.cfl"  # the key that set the last step: the one a blow-up names
        self.warned = False         # time.dt past the CFL step, said once

    def next_dt(self) -> float:
        """The CFL step, capped by ``time.dt_max`` and the end time; or ``time.dt``."""
        tm = self.tm
        dt = tm.cfl * self.h_min / self.vmax
        self.dt_limit = "time.cfl"
        if tm.dt is not None:
            if tm.dt > dt and not self.warned:
                self.warned = True
                if self.speaks:
                    log.warning("time.dt = %.4g s is longer than the CFL step (time.cfl = %g: "
                                "%.4g s) at step %d (t = %.6g s); the run may turn unstable",
                                tm.dt, tm.cfl, dt, self.nstep, self.t)
            dt, self.dt_limit = tm.dt, "time.dt"
        elif tm.dt_max and tm.dt_max < dt:
            dt, self.dt_limit = tm.dt_max, "time.dt_max"
        if tm.end is not None:
            dt = min(dt, tm.end - self.t)
        return dt

    def tick(self, dt: float, vmax: float, measured: bool = True) -> None:
        """A step of ``dt`` was taken; ``vmax`` sets the next one. Not ``measured`` (a fixed
        step between two measurements of the speed), a finite ``vmax`` is no speed and the last
        measured one stays; a non-finite one is kept (the run is stopped)."""
        if measured or not math.isfinite(vmax):
            self.vmax = vmax
        self.t += dt
        self.nstep += 1
        self.last_dt = dt

    def done(self) -> bool:
        tm = self.tm
        if tm.steps is not None and self.nstep >= tm.steps:
            return True
        return tm.end is not None and self.t >= tm.end * (1.0 - REL_TOL)

    def unstable_hint(self) -> str:
        """What to lower when the run blew up: the key that set the step."""
        tm = self.tm
        if self.dt_limit == "time.dt":
            return f"Δt = {self.last_dt:.3g} s was fixed by time.dt: try a smaller time.dt"
        if self.dt_limit == "time.dt_max":
            return (f"Δt = {self.last_dt:.3g} s was set by time.dt_max, below the CFL step: try a "
                    f"smaller time.dt_max (now {tm.dt_max:.3g} s)")
        return f"try a smaller time.cfl (now {tm.cfl:g})"
