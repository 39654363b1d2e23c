"""Constructive solid geometry: bodies made of primitives combined by union, difference and
intersection (an annulus is a disk minus a disk, a plate with a hole a box minus a disk).

A shape is a record (:class:`parmpm.scene.records.Body` or ``Part``) read by attribute:
``shape`` and that shape's fields. Primitives: ``box`` (``min``, ``max``, ``angle``), ``disk`` /
``sphere`` (``center``, ``radius``) — the same tests as :mod:`parmpm.geometry.primitives` —,
``cylinder`` (3D: ``axis`` "x" | "y" | "z", ``center`` its mid-point, ``radius``, ``length``
along the axis), ``polygon`` (2D: ``vertices``, a simple polygon of either orientation) and
``half_space`` (``point``, outward ``normal``: the points behind the plane). Combinators hold
``parts``: ``union`` (in any part), ``intersection`` (in every part), ``difference`` (in the
first part and in none of the others).

Inside tests are strict (a point on a primitive's surface is outside it: the convention of
:func:`parmpm.geometry.primitives.inside`) and vectorised over the points; bounds may be
infinite (a half-space), and a body's are finite when its unbounded parts are cut by bounded
ones. Pure numpy.
"""
from __future__ import annotations

import numpy as np

from parmpm.geometry import primitives

#: the shapes that combine others
COMBINATORS = ("union", "difference", "intersection")
#: the primitives a combination is made of
PRIMITIVES = ("box", "disk", "sphere", "cylinder", "polygon", "half_space")
AXES = "xyz"


def bounds(node, dim: int) -> tuple[list, list]:
    """Axis-aligned bounds of a shape (``±inf`` where it is unbounded): a union's span its
    parts', an intersection's their common box, a difference's its first part's."""
    shape = node.shape
    if shape in ("box", "disk", "sphere"):
        return primitives.body_bounds(node)
    if shape == "cylinder":
        k = AXES.index(node.axis)
        reach = [node.radius] * dim
        reach[k] = 0.5 * node.length
        return ([c - r for c, r in zip(node.center, reach)],
                [c + r for c, r in zip(node.center, reach)])
    if shape == "polygon":
        v = np.asarray(node.vertices, float)
        return v.min(axis=0).tolist(), v.max(axis=0).tolist()
    if shape == "half_space":
        return _half_space_bounds(node, dim)
    parts = [bounds(p, dim) for p in node.parts]
    if shape == "difference":
        return parts[0]
    lo, hi = np.array([p[0] for p in parts]), np.array([p[1] for p in parts])
    if shape == "union":
        return lo.min(axis=0).tolist(), hi.max(axis=0).tolist()
    return lo.max(axis=0).tolist(), hi.min(axis=0).tolist()


def unit_scale(v) -> np.ndarray:
    """``v`` divided by its largest component's size: the same direction, and a dot product with
    it neither overflows (a normal of 1e308) nor underflows (1e-320) to a wrong sign or zero."""
    v = np.asarray(v, float)
    return v / np.abs(v).max()


def _half_space_bounds(node, dim: int) -> tuple[list, list]:
    """Unbounded, except along a normal parallel to an axis: ``x_k < p_k`` (or ``> p_k``)."""
    lo, hi = [-np.inf] * dim, [np.inf] * dim
    n = np.asarray(node.normal, float)
    axis = np.flatnonzero(n)
    if axis.size == 1:
        k = int(axis[0])
        if n[k] > 0:
            hi[k] = float(node.point[k])
        else:
            lo[k] = float(node.point[k])
    return lo, hi


def inside(node, dim: int, x: np.ndarray) -> np.ndarray:
    """Which points ``x`` (n, dim) lie strictly inside the shape."""
    x = np.asarray(x, float).reshape(-1, dim)
    shape = node.shape
    if shape in ("box", "disk", "sphere"):
        return primitives.inside(node, dim, x)
    if shape == "cylinder":
        return _in_cylinder(node, x)
    if shape == "polygon":
        return in_polygon(np.asarray(node.vertices, float), x)
    if shape == "half_space":
        return (x - np.asarray(node.point, float)) @ unit_scale(node.normal) < 0.0
    first, *rest = node.parts
    out = inside(first, dim, x)
    for part in rest:
        if shape == "union":
            out |= inside(part, dim, x)
        elif shape == "intersection":
            out &= inside(part, dim, x)
        else:
            out &= ~inside(part, dim, x)
    return out


def _in_cylinder(node, x: np.ndarray) -> np.ndarray:
    """Within ``radius`` of the axis and ``length/2`` of the mid-point along it (strict, by
    1e-9 of each)."""
    k = AXES.index(node.axis)
    r = x - np.asarray(node.center, float)
    across = np.delete(r, k, axis=1)
    return ((np.sum(across * across, axis=1) < (node.radius * (1.0 - 1e-9)) ** 2)
            & (np.abs(r[:, k]) < 0.5 * node.length * (1.0 - 1e-9)))


def in_polygon(v: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Even-odd rule: a horizontal ray from each point crosses the polygon's edges (vertices
    ``v``, (m, 2), either orientation) an odd number of times (O'Rourke, *Computational Geometry
    in C*, 1998, §7.4). One pass per edge, vectorised over the points."""
    px, py = x[:, 0], x[:, 1]
    out = np.zeros(x.shape[0], bool)
    for (x1, y1), (x2, y2) in zip(v, np.roll(v, -1, axis=0)):
        if y1 == y2:  # a horizontal edge: the ray never crosses it
            continue
        crosses = (y1 > py) != (y2 > py)
        at = x1 + (py - y1) * ((x2 - x1) / (y2 - y1))
        out ^= crosses & (px < at)
    return out


def polygon_area(v) -> float:
    """Signed area (shoelace): > 0 counter-clockwise."""
    v = np.asarray(v, float)
    x, y = v[:, 0], v[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def polygon_crossing(v) -> tuple[int, int] | None:
    """The first two edges ``(i, j)`` of a polygon that cross or touch (not counting the shared
    vertex of neighbours), or None for a simple polygon. Edge ``i`` runs from vertex ``i`` to
    ``i + 1``."""
    v = np.asarray(v, float)
    m = v.shape[0]
    a, b = v, np.roll(v, -1, axis=0)
    scale = float(np.max(np.ptp(v, axis=0))) or 1.0
    tol = 1e-12 * scale * scale

    def orient(p, q, r):  # sign of the turn p -> q -> r, per row
        s = (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) \
            - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])
        return np.where(np.abs(s) <= tol, 0, np.sign(s))

    def on(p, q, r):  # r on segment p-q, given collinear
        return ((np.minimum(p[..., 0], q[..., 0]) <= r[..., 0])
                & (r[..., 0] <= np.maximum(p[..., 0], q[..., 0]))
                & (np.minimum(p[..., 1], q[..., 1]) <= r[..., 1])
                & (r[..., 1] <= np.maximum(p[..., 1], q[..., 1])))

    for i in range(m):
        j = np.arange(i + 1, m)
        j = j[(j != i + 1) & ~((i == 0) & (j == m - 1))]  # neighbours share a vertex
        if not j.size:
            continue
        p, q, r, s = a[i], b[i], a[j], b[j]
        o1, o2 = orient(p, q, r), orient(p, q, s)
        o3, o4 = orient(r, s, p), orient(r, s, q)
        hit = (o1 * o2 < 0) & (o3 * o4 < 0)
        hit |= (o1 == 0) & on(p, q, r) | (o2 == 0) & on(p, q, s)
        hit |= (o3 == 0) & on(r, s, p) | (o4 == 0) & on(r, s, q)
        if hit.any():
            return i, int(j[np.argmax(hit)])
    # neighbours folding back onto each other (a spike: edge i+1 returns along edge i)
    for i in range(m):
        p, q, r = a[i], b[i], b[(i + 1) % m]
        if orient(p[None], q[None], r[None])[0] == 0 and np.dot(q - p, r - q) < 0:
            return i, (i + 1) % m
    return None
