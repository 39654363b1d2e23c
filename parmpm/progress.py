"""Progress bar for a run: steps, simulated time and particle-steps per second, on stderr.

A thin wrapper around tqdm. The run loop creates one on every rank with ``enabled`` true on rank 0
only (and false under ``--quiet``), calls :meth:`Progress.update` after each step and
:meth:`Progress.close` at the end; a disabled bar writes nothing at all. The bar is driven by
simulated time when the run has an end time, else by the step count (or is a plain counter when
neither is known). Throttled by tqdm: updating every step costs microseconds, not a redraw.
"""

from __future__ import annotations

import sys

from tqdm import tqdm


class Progress:
    """Progress of a time-stepping run.

    Parameters
    ----------
    total_steps : the step at which the run stops, if it stops on a step count.
    end_time : the simulated time at which the run stops; when given it drives the bar.
    enabled : false gives an object whose methods do nothing.
    """

    def __init__(self, total_steps: int | None = None, end_time: float | None = None, enabled: bool = True):
        self.by_time = end_time is not None
        self._bar = None
        if not enabled:
            return
        interactive = sys.stderr.isatty()
        common = dict(
            file=sys.stderr,
            dynamic_ncols=True,
            leave=True,
            # a log file (batch job) gets a line every 30 s rather than a stream of redraws
            mininterval=0.2 if interactive else 30.0,
        )
        if self.by_time:
            self._bar = tqdm(
                total=float(end_time),
                bar_format="{l_bar}{bar}| t={n:.4g}/{total:.4g} [{elapsed}<{remaining}{postfix}]",
                **common,
            )
        else:
            self._bar = tqdm(total=total_steps, unit="step", **common)

    @property
    def enabled(self) -> bool:
        return self._bar is not None

    def update(self, step: int, time: float, particle_steps_per_second: float) -> None:
        """Show the state after ``step`` steps at simulated time ``time``."""
        bar = self._bar
        if bar is None:
            return
        rate = tqdm.format_sizeof(particle_steps_per_second, divisor=1000)
        if self.by_time:
            bar.set_postfix_str(f"step {step}, {rate} particle-steps/s", refresh=False)
            target = min(float(time), bar.total)
        else:
            bar.set_postfix_str(f"t={time:.4g}, {rate} particle-steps/s", refresh=False)
            target = step if bar.total is None else min(step, bar.total)
        if target > bar.n:
            bar.update(target - bar.n)

    def close(self) -> None:
        """Draw the final state and release the bar (idempotent)."""
        if self._bar is not None:
            self._bar.close()  # with leave=True this draws the final state, postfix included
            self._bar = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
