"""A metric's record that does not grow with the run: a bounded trace of its samples for
figures, and the streaming updates its summary is made of.

A metric is sampled every ``metrics.every_steps`` steps (default: every step), so a history held
as lists grows without bound: ~0.1 kB per step for the vibrating bar (issue 28: 118 MB over
215,000 steps), gigabytes for a 10⁷-step run, and the whole of it went into every checkpoint.
What a summary reports needs no history: sums, extrema, the last value and the first turning
points are updated sample by sample (:func:`nanmax`, :func:`first_max`, ... below;
:class:`parmpm.output.metrics.bars.TurningPoints`). What figures need is the shape of the series:
:class:`Trace` keeps at most ``capacity`` samples, evenly spaced in sample index — every sample
until it is full, then every second one, every fourth, ... — and always shows the latest. A
run's every sample is in ``history.csv`` when it asks for one (``output.history``).

Everything here is deterministic and JSON-ready (:meth:`Trace.state`), so a restarted run keeps
the same trace and the same summary, bit for bit, as the run it continues.
"""
from __future__ import annotations

import math

import numpy as np

#: the most samples a trace keeps (between half of it and all of it once it has filled)
CAPACITY = 8192


class Trace:
    """The samples of named ``columns`` (floats), at most ``capacity`` of them: those whose
    index (0, 1, 2, ... in the order added) is a multiple of :attr:`stride`, which doubles each
    time the trace is full; :meth:`column` adds the latest sample."""

    def __init__(self, columns: tuple[str, ...], capacity: int = CAPACITY):
        if capacity < 2 or capacity % 2:
            raise ValueError(f"a trace's capacity must be even and >= 2, got {capacity}")
        self.columns = tuple(columns)
        self.capacity = int(capacity)
        self.count = 0   # samples added
        self.stride = 1  # the kept samples' index spacing
        self._rows = np.empty((0, len(self.columns)))
        self._kept = 0
        self._last = None  # the latest sample, kept or not

    def add(self, *values) -> None:
        """One sample: a value per column, in order."""
        if len(values) != len(self.columns):
            raise ValueError(f"a trace of {self.columns} takes {len(self.columns)} values, "
                             f"got {len(values)}")
        k = self.count
        self.count += 1
        self._last = [float(v) for v in values]
        if k % self.stride:
            return
        if self._kept == self.capacity:  # full: keep every second sample, from the first
            half = self._kept // 2
            self._rows[:half] = self._rows[0:self._kept:2]
            self._kept, self.stride = half, 2 * self.stride
            if k % self.stride:
                return
        if self._kept == self._rows.shape[0]:  # grow the buffer (doubling, up to capacity)
            rows = np.empty((min(self.capacity, max(64, 2 * self._kept)), len(self.columns)))
            rows[:self._kept] = self._rows[:self._kept]
            self._rows = rows
        self._rows[self._kept] = self._last
        self._kept += 1

    def indices(self) -> np.ndarray:
        """The sample indices :meth:`column` gives values of."""
        idx = np.arange(self._kept, dtype=np.int64) * self.stride
        if self.count and (self.count - 1) % self.stride:
            idx = np.append(idx, self.count - 1)
        return idx

    def column(self, name: str) -> np.ndarray:
        """The kept samples of column ``name``, then the latest sample if it was not kept."""
        j = self.columns.index(name)
        out = self._rows[:self._kept, j]
        if self.count and (self.count - 1) % self.stride:
            out = np.append(out, self._last[j])
        return out.copy()

    def state(self) -> dict:
        """JSON-ready (bounded: at most ``capacity`` rows)."""
        return {"columns": list(self.columns), "capacity": self.capacity, "count": self.count,
                "stride": self.stride, "rows": self._rows[:self._kept].tolist(),
                "last": self._last}

    def restore(self, state: dict) -> None:
        """Continue the trace :meth:`state` saved."""
        if tuple(state["columns"]) != self.columns:
            raise ValueError(f"a saved trace of {tuple(state['columns'])} cannot continue a "
                             f"trace of {self.columns}")
        self.capacity, self.count = int(state["capacity"]), int(state["count"])
        self.stride = int(state["stride"])
        rows = np.asarray(state["rows"], float).reshape(-1, len(self.columns))
        self._kept = rows.shape[0]
        self._rows = np.empty((max(self._kept, 1), len(self.columns)))
        self._rows[:self._kept] = rows
        self._last = None if state["last"] is None else [float(v) for v in state["last"]]


# --- streaming updates: each the value a whole-history reduction gave, one sample at a time --
def nanmax(current: float, value: float) -> float:
    """``numpy.nanmax`` of the samples so far (start from NaN): NaN samples are skipped."""
    return float(np.fmax(current, value))


def first_max(current, value):
    """Python's ``max`` of the samples so far (start from None): a NaN first sample stays."""
    return value if current is None or value > current else current


def first_min(current, value):
    """Python's ``min`` of the samples so far (start from None)."""
    return value if current is None or value < current else current


def max_or_nan(current: float, value: float) -> float:
    """``numpy.max`` of the samples so far (start from -inf): a NaN sample makes it NaN."""
    if math.isnan(current) or math.isnan(value):
        return math.nan
    return max(current, value)
