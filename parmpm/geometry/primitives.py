"""The bodies' primitive shapes as geometry: a box (turned about its centre in the x-y plane), a
disk or a sphere — their rotation, bounding boxes and inside tests.

Pure numpy, below the particles and the scene, so that seeding, the scene's checks (bounds, speed,
overlaps) and the kernels' node boxes share one definition of where a body is.
"""
from __future__ import annotations

import math

import numpy as np


def turn(d: int, degrees: float) -> np.ndarray:
    """Rotation by ``degrees`` counter-clockwise in the x-y plane (the identity on z)."""
    a = math.radians(degrees)
    Q = np.eye(d)
    Q[:2, :2] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
    return Q


def rotated_box_bounds(bmin: list, bmax: list, angle: float) -> tuple[list, list]:
    """Axis-aligned bounds of a box turned by ``angle`` degrees about its centre (x-y plane)."""
    a = math.radians(angle)
    cos, sin = abs(math.cos(a)), abs(math.sin(a))
    half = [0.5 * (b - a_) for a_, b in zip(bmin, bmax)]
    mid = [0.5 * (a_ + b) for a_, b in zip(bmin, bmax)]
    reach = [cos * half[0] + sin * half[1], sin * half[0] + cos * half[1]] + half[2:]
    return [m - r for m, r in zip(mid, reach)], [m + r for m, r in zip(mid, reach)]


def body_bounds(body) -> tuple[list, list]:
    """Axis-aligned bounds of a resolved body (a :class:`parmpm.scene.records.Body`: ``shape``,
    ``min``, ``max``, ``angle``, ``center``, ``radius``): a box's corners (a turned box's
    bounding box), a disk's or sphere's centre ± radius."""
    if body.shape == "box":
        if body.angle:
            return rotated_box_bounds(body.min, body.max, body.angle)
        return list(body.min), list(body.max)
    return [c - body.radius for c in body.center], [c + body.radius for c in body.center]


def inside(body, dim: int, x: np.ndarray) -> np.ndarray:
    """Which points ``x`` (n, dim) lie strictly inside ``body`` (by more than 1e-9 of its size:
    points on its surface are outside)."""
    x = np.asarray(x, float).reshape(-1, dim)
    if body.shape == "box":
        lo, hi = np.asarray(body.min, float), np.asarray(body.max, float)
        tol = 1e-9 * float(np.max(hi - lo))
        mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
        r = x - mid
        if body.angle:  # into the box's own axes: local = turnᵀ (x − mid)
            r = r @ turn(dim, body.angle)
        return np.all(np.abs(r) < half - tol, axis=1)
    c, radius = np.asarray(body.center, float), float(body.radius)
    return np.sum((x - c) ** 2, axis=1) < (radius * (1.0 - 1e-9)) ** 2
