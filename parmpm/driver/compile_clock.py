"""Seconds spent compiling kernels while a run steps, so that its wall time and rate are its own.

On one rank numba compiles each kernel where it is first called: the stepper's in the first step,
and the rest (the ordering of particles, the energy watch, outputs) wherever the run first needs
them, inside the timed loop. A first run's summary then read "wall time 59.2 s, 68,468
particle-steps/s" for 7 s of steps and 52 s of compiling. Under MPI, rank 0 compiles before the
run starts (:func:`parmpm.driver.warm_up.compile_first`), so its times were already the run's own.

:class:`CompileClock` listens to numba's compile events (as :class:`parmpm.driver.warm_up.CompileNotice`
does for the notice) and adds up the top-level compilations; the run loop
(:mod:`parmpm.driver.simulation`) takes them out of its wall time and rate and reports them apart
(``compile_seconds`` in summary.json). Reading ``seconds`` costs nothing; with the cache warm
no event fires.
"""
from __future__ import annotations

import contextlib
import time


class CompileClock:
    """``seconds``: the time numba spent compiling (top-level compilations only: a kernel
    compiled inside another's compile is counted once, in its caller's) since :meth:`listen`
    began."""

    def __init__(self):
        self.seconds = 0.0
        self._stack: list[float] = []

    def _start(self) -> None:
        self._stack.append(time.perf_counter())

    def _end(self) -> None:
        if self._stack:
            took = time.perf_counter() - self._stack.pop()
            if not self._stack:
                self.seconds += took

    @contextlib.contextmanager
    def listen(self):
        """Count the compilations of the block (the clock keeps counting across blocks)."""
        from numba.core import event

        clock = self

        class _Listener(event.Listener):
            def on_start(self, ev):
                clock._start()

            def on_end(self, ev):
                clock._end()

        with event.install_listener("numba:compile", _Listener()):
            yield self
