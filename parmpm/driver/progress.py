"""Progress of a run on stderr: a bar in a terminal, a plain log line every 30 s in a batch log.

The run loop creates one on every rank with ``enabled`` true on rank 0 only (and false under
``--quiet``), calls :meth:`Progress.update` after each step and :meth:`Progress.close` at the end;
a disabled one writes nothing at all. The progress is measured in simulated time when the run has
an end time, else in steps (a plain counter when neither is known).

* stderr is a terminal: a tqdm bar, redrawn at most 5 times a second (updating every step costs
  microseconds); log records are written above it, not through it.
* stderr is not a terminal (a batch job's log, a pipe — also ``mpirun``'s): no ``\\r`` redraws,
  but a log line every ``interval`` seconds and one at the end: step, t, % done,
  particle-steps/s, ETA. With ``--log-file``, the file gets these lines in both cases.

The remaining time is estimated from the steps after the first only: the first step pays for
compiling the kernels (tens of seconds on a cold numba cache), which would otherwise make the
estimate absurd for the whole run. Until a second step has run there is no estimate ("ETA --").
"""

from __future__ import annotations

import sys
import time as _time

from tqdm import tqdm

from parmpm.core.log import console_writes_around, get_logger, to_file_only

log = get_logger(__name__)

#: seconds between the plain progress lines (batch logs, log files)
LOG_INTERVAL = 30.0


class Progress:
    """Progress of a time-stepping run.

    Parameters
    ----------
    total_steps : the step at which the run stops, if it stops on a step count.
    end_time : the simulated time at which the run stops; when given it drives the progress.
    enabled : false gives an object whose methods do nothing.
    interactive : draw a bar (default: whether stderr is a terminal) rather than log lines.
    interval : seconds between log lines.
    """

    def __init__(self, total_steps: int | None = None, end_time: float | None = None,
                 enabled: bool = True, interactive: bool | None = None,
                 interval: float = LOG_INTERVAL):
        self.by_time = end_time is not None
        self.total = float(end_time) if self.by_time else total_steps
        self.enabled = enabled
        self.interval = interval
        self._bar = None
        self._warm = None        # (wall, progress) after the first update: the estimate's origin
        self._last = None        # (step, t, rate) of the last update
        self._next_line = _time.monotonic() + interval
        if not enabled:
            return
        self.interactive = sys.stderr.isatty() if interactive is None else interactive
        if not self.interactive:
            return
        common = dict(file=sys.stderr, dynamic_ncols=True, leave=True, mininterval=0.2)
        if self.by_time:
            fmt = "{l_bar}{bar}| t={n:.4g}/{total:.4g} [{elapsed}{postfix}]"
            self._bar = tqdm(total=self.total, bar_format=fmt, **common)
        elif total_steps is not None:
            fmt = "{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}{postfix}]"
            self._bar = tqdm(total=total_steps, unit="step", bar_format=fmt, **common)
        else:
            self._bar = tqdm(total=None, unit="step", bar_format="{n_fmt}step [{elapsed}{postfix}]",
                             **common)
        console_writes_around(lambda: tqdm.external_write_mode(file=sys.stderr))

    def _done(self, step: int, t: float) -> float:
        return float(t) if self.by_time else float(step)

    def eta(self, step: int, t: float, now: float | None = None) -> float | None:
        """Seconds left, from the progress made since the first update; None before that."""
        if self.total is None or self._warm is None:
            return None
        now = _time.monotonic() if now is None else now
        wall0, done0 = self._warm
        done = self._done(step, t)
        if done <= done0 or now <= wall0:
            return None
        return max(0.0, (self.total - done) * (now - wall0) / (done - done0))

    def line(self, step: int, t: float, rate: float) -> str:
        """The plain progress line: step, t, % done, particle-steps/s, ETA."""
        parts = [f"step {step:,}" + (f" of {self.total:,}" if not self.by_time and self.total
                                     else "")]
        parts.append(f"t = {t:.6g} s" + (f" of {self.total:g}" if self.by_time else ""))
        if self.total:
            parts[-1] += f" ({100.0 * min(1.0, self._done(step, t) / self.total):.0f} %)"
        parts.append(f"{tqdm.format_sizeof(rate, divisor=1000)} particle-steps/s")
        eta = self.eta(step, t)
        parts.append("ETA " + ("--" if eta is None else tqdm.format_interval(eta)))
        return ", ".join(parts)

    def update(self, step: int, time: float, particle_steps_per_second: float) -> None:
        """Show the state after ``step`` steps at simulated time ``time``."""
        if not self.enabled:
            return
        now = _time.monotonic()
        if self._warm is None:  # after the first step: what comes later is the real pace
            self._warm = (now, self._done(step, time))
        self._last = (step, time, particle_steps_per_second)
        if now >= self._next_line:
            self._next_line = now + self.interval
            text = self.line(step, time, particle_steps_per_second)
            if self._bar is None:
                log.info("%s", text)
            else:
                to_file_only(log, text)
        bar = self._bar
        if bar is None:
            return
        rate = tqdm.format_sizeof(particle_steps_per_second, divisor=1000)
        eta = self.eta(step, time, now)
        eta = "ETA --" if eta is None else f"ETA {tqdm.format_interval(eta)}"
        if self.by_time:
            bar.set_postfix_str(f"step {step}, {rate} particle-steps/s, {eta}", refresh=False)
            target = min(float(time), bar.total)
        else:
            bar.set_postfix_str(f"t={time:.4g}, {rate} particle-steps/s"
                                + (f", {eta}" if bar.total else ""), refresh=False)
            target = step if bar.total is None else min(step, bar.total)
        if target > bar.n:
            bar.update(target - bar.n)

    def close(self) -> None:
        """Draw (or log) the final state and release the bar (idempotent)."""
        if not self.enabled:
            return
        self.enabled = False
        if self._bar is not None:
            console_writes_around(None)
            self._bar.close()  # with leave=True this draws the final state, postfix included
            self._bar = None
            if self._last is not None:
                to_file_only(log, self.line(*self._last))
        elif self._last is not None:
            log.info("%s", self.line(*self._last))

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
