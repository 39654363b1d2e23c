"""The generalised winding number's sum over triangles, compiled: exact, and fast by a tree.

The exact sum is O(points x triangles), ~25 ns a pair: 1e6 lattice points against 1e4
triangles would take minutes. :func:`tree_winding` follows Barill, Dickson, Schmidt, Levin &
Jacobson (2018, "Fast winding numbers for soups and clouds", ACM TOG 37(4)): a bounding-volume
tree over the triangles, and a cluster farther than ``BETA`` times its radius from a point counts
by the Taylor expansion of its dipole field about its centre (the vector area term and the first
moment term), the near ones triangle by triangle. With ``BETA = 3`` its error is ~1e-3 typical,
~2-4e-2 at worst (icospheres of 320-20480 triangles; ``tests/geometry/test_surface_geometry.py`` holds it
under 0.05): ample for the inside test ``w >= 1/2``, not for the number itself, which
:func:`winding_sum` gives exactly.

Kept apart from :mod:`parmpm.geometry.surface` so that checking a scene's surface (pure numpy)
loads no numba; only classifying points imports this module.
"""
import math

import numpy as np

from parmpm.core.jit import helper_kernel, kernel

#: a cluster counts by its expansion beyond this many radii from the point
BETA = 3.0
#: triangles per leaf of the tree
LEAF = 8


@helper_kernel
def _solid_angle(c: np.ndarray, t: int, px: float, py: float, pz: float) -> float:
    """Triangle ``t``'s signed solid angle seen from p, by Van Oosterom & Strackee (1983, IEEE
    Trans. Biomed. Eng. 30, 125): tan(Ω/2) = a·(b×c) / (|a||b||c| + (a·b)|c| + (b·c)|a| + (c·a)|b|)."""
    ax, ay, az = c[t, 0] - px, c[t, 1] - py, c[t, 2] - pz
    bx, by, bz = c[t, 3] - px, c[t, 4] - py, c[t, 5] - pz
    cx, cy, cz = c[t, 6] - px, c[t, 7] - py, c[t, 8] - pz
    la = math.sqrt(ax * ax + ay * ay + az * az)
    lb = math.sqrt(bx * bx + by * by + bz * bz)
    lc = math.sqrt(cx * cx + cy * cy + cz * cz)
    det = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
    den = (la * lb * lc + (ax * bx + ay * by + az * bz) * lc
           + (bx * cx + by * cy + bz * cz) * la + (cx * ax + cy * ay + cz * az) * lb)
    return 2.0 * math.atan2(det, den)


@kernel
def winding_sum(corners: np.ndarray, x: np.ndarray, todo: np.ndarray, out: np.ndarray) -> None:
    """``out[p]`` = the winding number at ``x[p]`` of the triangles ``corners`` (m, 9): their
    solid angles summed over 4π (Jacobson, Kavan & Sorkine-Hornung 2013). Points with
    ``todo[p]`` false are left as given."""
    for p in range(x.shape[0]):
        if todo[p]:
            total = 0.0
            for t in range(corners.shape[0]):
                total += _solid_angle(corners, t, x[p, 0], x[p, 1], x[p, 2])
            out[p] = total / (4.0 * math.pi)


@kernel
def tree_winding(corners: np.ndarray, span: np.ndarray, child: np.ndarray, ball: np.ndarray,
                 moment: np.ndarray, x: np.ndarray, todo: np.ndarray, out: np.ndarray) -> None:
    """:func:`winding_sum` through the tree of :func:`build_tree` (``corners`` in its order):
    node k holds triangles ``span[k, 0]:span[k, 1]``, children ``child[k]`` (-1: a leaf), centre
    and radius ``ball[k]``, vector area N and first moment M (Σ A n ⊗ (ȳ - c)) in ``moment[k]``.
    A far node adds N·r/|r|³ + Σ M_ij (δ_ij/|r|³ - 3 r_i r_j/|r|⁵), r = centre - point."""
    stack = np.empty(256, dtype=np.int64)
    for p in range(x.shape[0]):
        if not todo[p]:
            continue
        px, py, pz = x[p, 0], x[p, 1], x[p, 2]
        total = 0.0
        stack[0] = 0
        top = 1
        while top > 0:
            top -= 1
            k = stack[top]
            rx, ry, rz = ball[k, 0] - px, ball[k, 1] - py, ball[k, 2] - pz
            d2 = rx * rx + ry * ry + rz * rz
            if d2 > (BETA * ball[k, 3]) ** 2:
                d = math.sqrt(d2)
                i3 = 1.0 / (d2 * d)
                m = moment[k]
                rMr = (rx * (m[3] * rx + m[4] * ry + m[5] * rz) + ry * (m[6] * rx + m[7] * ry
                       + m[8] * rz) + rz * (m[9] * rx + m[10] * ry + m[11] * rz))
                total += ((m[0] * rx + m[1] * ry + m[2] * rz) * i3
                          + (m[3] + m[7] + m[11]) * i3 - 3.0 * rMr * i3 / d2)
            elif child[k, 0] < 0:
                for t in range(span[k, 0], span[k, 1]):
                    total += _solid_angle(corners, t, px, py, pz)
            else:
                stack[top] = child[k, 0]
                stack[top + 1] = child[k, 1]
                top += 2
        out[p] = total / (4.0 * math.pi)


def build_tree(corners: np.ndarray) -> tuple[np.ndarray, ...]:
    """The triangles ``corners`` (m, 9) reordered and split at the median centroid along the
    longest side until ``LEAF`` remain: (corners, span, child, ball, moment), nodes depth first."""
    m = len(corners)
    P = corners.reshape(m, 3, 3)
    centroid = P.mean(axis=1)
    order = np.arange(m)
    spans, children, pending = [(0, m)], [[-1, -1]], [0]
    while pending:
        k = pending.pop()
        s, e = spans[k]
        if e - s <= LEAF:
            continue
        part = order[s:e]
        axis = int(np.argmax(np.ptp(centroid[part], axis=0)))
        order[s:e] = part[np.argsort(centroid[part, axis], kind="stable")]
        mid = (s + e) // 2
        children[k] = [len(spans), len(spans) + 1]
        spans += [(s, mid), (mid, e)]
        children += [[-1, -1], [-1, -1]]
        pending += [len(spans) - 1, len(spans) - 2]
    P, centroid = P[order], centroid[order]
    area = 0.5 * np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])  # A n
    first = np.einsum("ti,tj->tij", area, centroid).reshape(m, 9)
    sums = np.concatenate([np.zeros((1, 12)), np.cumsum(np.hstack([area, first]), axis=0)])
    ball = np.zeros((len(spans), 4))
    moment = np.zeros((len(spans), 12))
    for k, (s, e) in enumerate(spans):
        centre = centroid[s:e].mean(axis=0)
        ball[k, :3] = centre
        ball[k, 3] = np.sqrt(np.max(np.sum((P[s:e] - centre) ** 2, axis=2)))
        N, first_k = sums[e, :3] - sums[s, :3], sums[e, 3:] - sums[s, 3:]
        moment[k, :3] = N
        moment[k, 3:] = first_k - np.outer(N, centre).ravel()  # Σ A n ⊗ (ȳ - c)
    return (np.ascontiguousarray(P.reshape(m, 9)), np.array(spans, dtype=np.int64),
            np.array(children, dtype=np.int64), ball, moment)
