"""Problems found inside a step, remembered rather than raised.

A support reaching past the ghost layer, a domain turned inside out or a particle leaving the
grid is noted here; the step runs to its end on every rank (no rank is left waiting in an
exchange) and the stepper's end-of-step agreement raises the first one on every rank at once.
"""
from __future__ import annotations

import numpy as np

from parmpm.shapes.cpdi2 import INVERTED
from parmpm.transfer.reach import inverted_message, reach_message


class StepFaults:
    """``err``: the kernels' flag (first particle row in error, its support's code), -1 when
    none; ``error``: the first problem's one-line message; ``error_key``: the (patch, id) of the
    particle it names (how ranks agree on which message is the first)."""

    def __init__(self):
        self.err = np.full(2, -1, np.int64)
        self.error: str | None = None
        self.error_key: tuple[int, int] | None = None

    def fail(self, rows, i: int, message: str) -> None:
        """Note the first problem of this step (physical row ``i`` of ``rows``)."""
        if self.error is None:
            self.error = message
            self.error_key = (int(rows.patch[i]), int(rows.gid[i]))

    def check(self, phase: str, disc, rows, bc: np.ndarray) -> None:
        """Turn the kernels' flag, if set, into a message naming the particle and the fix."""
        i, code = (int(c) for c in self.err)
        if i >= 0:
            self.err[:] = -1
            self.fail(rows, i, inverted_message(disc, rows, i, phase) if code == INVERTED
                      else reach_message(disc, rows, bc, i, phase))
