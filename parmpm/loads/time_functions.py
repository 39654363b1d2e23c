"""How a load or a moving wall follows time: ``f(t)`` scales its value, ``∫₀ᵗ f`` places a wall.

Four functions, all equal to 0 or their first value at ``t = 0`` and held at their last value
after their end:

* ``constant``: ``f = 1``;
* ``ramp``: ``f = min(t/T, 1)`` (a linear rise over ``duration`` ``T``);
* ``smooth_step``: ``f = s³(10 − 15s + 6s²)``, ``s = min(t/T, 1)``: rises from 0 to 1 with zero
  first and second derivatives at both ends, so a load or a plate starts without a shock wave;
* ``table``: piecewise linear through ``points`` ``[(t₀, f₀), (t₁, f₁), ...]`` (times
  increasing), ``f₀`` before ``t₀``.

The integral is exact for each (closed forms; trapezoids for the table), so a wall's position
``p(t) = p₀ + v ∫₀ᵗ f`` depends on ``t`` alone: the same on any number of ranks and after a
restart, with no state to carry.
"""
from __future__ import annotations

import bisect
from dataclasses import dataclass

FUNCTIONS = ("constant", "ramp", "smooth_step", "table")


@dataclass(frozen=True, slots=True)
class TimeFunction:
    """``function`` (one of :data:`FUNCTIONS`), its ``duration`` (ramp, smooth step) or its
    ``points`` (table, as ``((t, f), ...)``)."""

    function: str = "constant"
    duration: float | None = None
    points: tuple[tuple[float, float], ...] | None = None

    def value(self, t: float) -> float:
        """``f(t)``."""
        if self.function == "constant":
            return 1.0
        if self.function == "table":
            return _table_value(self.points, t)
        s = min(max(t / self.duration, 0.0), 1.0)
        if self.function == "ramp":
            return s
        return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))

    def integral(self, t: float) -> float:
        """``∫₀ᵗ f(τ) dτ`` (``t ≥ 0``)."""
        if t <= 0.0:
            return 0.0
        if self.function == "constant":
            return t
        if self.function == "table":
            return _table_integral(self.points, t)
        T = self.duration
        s = min(t / T, 1.0)
        if self.function == "ramp":
            head = 0.5 * s * s
        else:  # ∫ s³(10 − 15s + 6s²) ds = s⁴(5/2 − 3s + s²)
            head = s ** 4 * (2.5 + s * (-3.0 + s))
        return T * head + max(t - T, 0.0)


def _table_value(points, t: float) -> float:
    times = [p[0] for p in points]
    j = bisect.bisect_right(times, t)
    if j == 0:
        return points[0][1]
    if j == len(points):
        return points[-1][1]
    (t0, f0), (t1, f1) = points[j - 1], points[j]
    return f0 + (f1 - f0) * (t - t0) / (t1 - t0)


def _table_integral(points, t: float) -> float:
    """The table's integral from 0: its first value before its first time, the trapezoids
    between its points, its last value after."""
    total, prev_t, prev_f = 0.0, 0.0, points[0][1]
    for tk, fk in points:
        if tk <= 0.0:
            prev_f = fk
            continue
        if t <= tk:
            return total + 0.5 * (prev_f + _table_value(points, t)) * (t - prev_t)
        total += 0.5 * (prev_f + fk) * (tk - prev_t)
        prev_t, prev_f = tk, fk
    return total + prev_f * (t - prev_t)
