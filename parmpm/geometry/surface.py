"""A body bounded by a closed triangulated surface (3D): its checks and its inside test.

The inside test is the generalised winding number (Jacobson, Kavan & Sorkine-Hornung 2013,
"Robust inside-outside segmentation using generalized winding numbers", ACM TOG 32(4)): the sum
of the triangles' signed solid angles seen from a point, over 4π. It is 1 inside and 0 outside a
closed, outward-oriented surface, and degrades gracefully where the surface is not watertight: a
small hole or a few flipped triangles change it only near them, so ``w >= 1/2`` still classifies
the points away from the defect — which a ray-parity test does not. A surface oriented inward
(every triangle flipped) gives -1 inside; it is recognised by its negative signed volume and turned.

Pure numpy apart from the compiled sum (:mod:`parmpm.geometry.winding`, imported when points are
classified, so checking a scene loads no numba; it holds the exact sum and the tree that makes
classifying a lattice O(points log triangles)). No file I/O: :func:`parmpm.io.surface_file.read_surface`
reads the vertices and triangles.
"""
from __future__ import annotations

from dataclasses import dataclass

import hashlib

import numpy as np

from parmpm.core.errors import SceneError

#: a surface whose |volume| is below this fraction of its bounding box's largest side cubed
#: encloses nothing (a flat or folded sheet); rounding leaves ~1e-16 for a truly flat one
FLAT = 1e-8
#: a triangle whose area is below this fraction of the largest side squared is degenerate
SLIVER = 1e-14


@dataclass(frozen=True)
class SurfaceSummary:
    """What :func:`check_surface` found; the counts are for the caller to warn about."""
    vertices: int
    triangles: int
    volume: float  #: enclosed volume (m^3, > 0 whatever the orientation)
    area: float  #: total triangle area (m^2)
    lo: tuple  #: bounding box
    hi: tuple
    inward: bool  #: the triangles face inward (they are turned before classifying)
    degenerate_triangles: int  #: zero area (repeated or collinear vertices)
    open_edges: int  #: edges of one triangle only: the surface has holes
    nonmanifold_edges: int  #: edges of three or more triangles
    misoriented_edges: int  #: edges of two triangles that run the same way: flipped triangles


def _arrays(vertices, triangles) -> tuple[np.ndarray, np.ndarray]:
    """The surface as float64 (n, 3) and int64 (m, 3), or a ValueError (a bug: the reader checks)."""
    V = np.ascontiguousarray(vertices, dtype=np.float64)
    T = np.ascontiguousarray(triangles, dtype=np.int64)
    if V.ndim != 2 or V.shape[1] != 3 or T.ndim != 2 or T.shape[1] != 3:
        raise ValueError(f"expected vertices (n, 3) and triangles (m, 3), got {V.shape}, {T.shape}")
    if T.size and (T.min() < 0 or T.max() >= len(V)):
        raise ValueError(f"triangle indices {T.min()}..{T.max()} outside 0..{len(V) - 1}")
    return V, T


def _frame(V: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, float]:
    """The centre and largest side of the used vertices' bounding box (1 if that is zero or not
    finite): the surface is measured as (V - centre) / side, so that a body of 1e-200 m or of
    1e200 m neither underflows nor overflows (the winding number is scale-free)."""
    used = V[T.ravel()] if T.size else V
    if not len(used):
        return np.zeros(3), 1.0
    lo, hi = used.min(axis=0), used.max(axis=0)
    side = float(np.max(hi - lo))
    return 0.5 * lo + 0.5 * hi, side if 0 < side < np.inf else 1.0


def _volume(U: np.ndarray, T: np.ndarray) -> float:
    """Σ a·(b×c)/6 over the triangles (divergence theorem): > 0 when they face outward."""
    a, b, c = (U[T[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->", a, np.cross(b, c)) / 6.0)


def signed_volume(vertices, triangles) -> float:
    """The volume the triangles enclose (m^3), > 0 when they face outward."""
    V, T = _arrays(vertices, triangles)
    mid, side = _frame(V, T)
    return _volume((V - mid) / side, T) * side ** 3


def _edges(T: np.ndarray) -> tuple[int, int, int]:
    """Counts of open, non-manifold and misoriented edges."""
    directed = np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]])
    undirected = np.sort(directed, axis=1)
    keys, inverse, count = np.unique(undirected, axis=0, return_inverse=True, return_counts=True)
    # on an edge of exactly two consistently oriented triangles, one runs low->high, one back
    forward = np.bincount(inverse.ravel(), weights=(directed[:, 0] < directed[:, 1]),
                          minlength=len(keys))
    pair = count == 2
    return (int(np.sum(count == 1)), int(np.sum(count > 2)),
            int(np.sum(pair & (forward != 1))))


def check_surface(vertices, triangles, name: str) -> SurfaceSummary:
    """The surface's summary, or a one-line SceneError naming ``name`` when it bounds no body:
    not finite, every triangle degenerate, or no enclosed volume (a flat sheet)."""
    V, T = _arrays(vertices, triangles)
    if len(T) == 0:
        raise SceneError(f"surface '{name}': no triangles; expected a closed triangulated surface")
    if not np.isfinite(V).all():
        raise SceneError(f"surface '{name}': vertex coordinates are not all finite; expected "
                         "finite coordinates")
    lo, hi = V[T.ravel()].min(axis=0), V[T.ravel()].max(axis=0)
    if not np.max(hi - lo) < 1e100:  # its volume must be a float too
        raise SceneError(f"surface '{name}': coordinates span {lo.tolist()} to {hi.tolist()}, "
                         "beyond floating point; expected a body of a sane size (metres)")
    mid, side = _frame(V, T)
    U = (V - mid) / side
    a, b, c = (U[T[:, k]] for k in range(3))
    areas = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)  # of the unit-size surface
    degenerate = int(np.sum(areas <= SLIVER))
    if degenerate == len(T):
        raise SceneError(f"surface '{name}': all {len(T)} triangles have zero area (bounding box "
                         f"size {np.max(hi - lo):g} m); expected a surface with area")
    volume = _volume(U, T)
    if abs(volume) <= FLAT:
        raise SceneError(f"surface '{name}': encloses no volume ({volume * side ** 3:.3g} m^3 in "
                         f"a bounding box of size {side:g} m, a flat or folded sheet?); expected "
                         "a closed surface around a solid")
    open_, nonmanifold, misoriented = _edges(T)
    return SurfaceSummary(len(V), len(T), abs(volume) * side ** 3, float(areas.sum()) * side ** 2,
                          tuple(lo.tolist()),
                          tuple(hi.tolist()), volume < 0, degenerate, open_, nonmanifold,
                          misoriented)


def winding_numbers(vertices, triangles, x) -> np.ndarray:
    """The generalised winding number (N,) of the triangles at the points ``x`` (N, 3), as
    oriented: ~1 inside an outward-facing closed surface, ~-1 inside an inward-facing one, ~0
    outside; O(N x triangles)."""
    from parmpm.geometry.winding import winding_sum

    V, T = _arrays(vertices, triangles)
    mid, side = _frame(V, T)
    x = (_points(x) - mid) / side
    out = np.zeros(len(x))
    if len(T):
        corners = ((V[T] - mid) / side).reshape(-1, 9)
        winding_sum(corners, x, np.ones(len(x), bool), out)
    return out


def inside_surface(vertices, triangles, x) -> np.ndarray:
    """Which points ``x`` (N, 3) lie inside the surface: winding number >= 1/2, with the
    triangles turned outward first when they face inward. Points outside the surface's bounding
    box are outside without the sum; the others are summed through a tree of the triangles
    (:func:`parmpm.geometry.winding.tree_winding`), O(N log triangles)."""
    from parmpm.geometry.winding import tree_winding

    V, T = _arrays(vertices, triangles)
    if len(T) == 0:
        return np.zeros(len(_points(x)), dtype=bool)
    mid, side, lo, hi, tree = _prepared(V, T)
    x = (_points(x) - mid) / side
    todo = np.all((x >= lo - 1e-9) & (x <= hi + 1e-9), axis=1)
    out = np.zeros(len(x))
    tree_winding(*tree, x, todo, out)
    return todo & (out >= 0.5)


#: the last few surfaces' frames and trees: seeding asks block by block for the same surface
_TREES: dict = {}


def _prepared(V: np.ndarray, T: np.ndarray):
    """The surface's frame (centre, size), its bounds in that frame and its tree, built once per
    surface (keyed by a digest of its arrays) rather than once per block of points."""
    from parmpm.geometry.winding import build_tree

    key = (hashlib.blake2b(V.tobytes(), digest_size=16).hexdigest(),
           hashlib.blake2b(T.tobytes(), digest_size=16).hexdigest(), V.shape, T.shape)
    if key not in _TREES:
        mid, side = _frame(V, T)
        U = (V - mid) / side
        if _volume(U, T) < 0:
            T = T[:, [0, 2, 1]]
        lo, hi = U[T.ravel()].min(axis=0), U[T.ravel()].max(axis=0)
        if len(_TREES) >= 4:
            _TREES.pop(next(iter(_TREES)))
        _TREES[key] = (mid, side, lo, hi, build_tree(U[T].reshape(-1, 9)))
    return _TREES[key]


def _points(x) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"expected points (N, 3), got shape {x.shape}")
    return np.ascontiguousarray(x)
