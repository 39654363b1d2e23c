"""Patch-box arithmetic, written once: which nodes a patch owns and holds, and which patch a
cell or a point lies in (no MPI, no physics, no numba).

Along one axis of ``cells`` cells (``cells + 1`` nodes) cut into patches of ``P`` cells, patch
``k`` owns nodes ``[k·P, (k+1)·P)`` and the last patch also the far node ``cells``; it holds them
in a local box widened by ``g`` ghost nodes on each side, whose node 0 (the *ghost base*) is the
global node ``k·P − g``. Cell ``c`` lies in patch ``⌊c/P⌋``. Patch coordinates flatten to a
patch id with axis 0 fastest.

The box functions take patch coordinates of any shape (``(..., 3)``, padded axes: one patch of
one node, no ghosts) and broadcast. The scalar ones (:func:`patch_of_cell` and below) are plain
Python that numba also compiles: :mod:`parmpm.grid.patch_index` wraps them for the kernels, so the
particle locators, the seeding and the fast G2P kernels share one formula.
"""
from __future__ import annotations

import numpy as np


def ghost_base(coords, psize, ghost):
    """Global node index of local node 0 of the patch at ``coords``: ``k·P − g``."""
    return coords * psize - ghost


def owned_box(coords, psize, patches, nodes):
    """Global node box ``[lo, hi)`` owned by the patch at ``coords`` (``patches`` per axis over
    ``nodes`` global nodes per axis): ``[k·P, (k+1)·P)``, up to the last node for the last patch."""
    lo = coords * psize
    return lo, np.where(coords == patches - 1, nodes, lo + psize)


def patch_cells(coords, psize, cells):
    """Cells ``[lo, hi)`` per axis of the patch at ``coords``: ``[k·P, min((k+1)·P, cells))``, the
    cells whose points :func:`patch_of_coordinate` gives patch ``k`` (``⌊u⌋`` in the range)."""
    lo = coords * psize
    return lo, np.minimum(lo + psize, cells)


def patches_holding_node(i, psize, ghost, patches):
    """``(lo, hi)``, inclusive: the patches along one axis whose local box (owned nodes and
    ghosts, ``k·P − g … (k+1)·P + g``) holds global node ``i``."""
    return max(0, (i - ghost - 1) // psize), min(patches - 1, (i + ghost) // psize)


def patch_id(k0, k1, k2, n0, n1):
    """Flat id of the patch at coordinates ``(k0, k1, k2)`` with ``n0``, ``n1`` patches along
    axes 0 and 1: axis 0 fastest."""
    return k0 + n0 * (k1 + n1 * k2)


def flat_patch_id(coords, patches):
    """:func:`patch_id` of ``(..., 3)`` patch coordinates (``patches`` per axis)."""
    return patch_id(coords[..., 0], coords[..., 1], coords[..., 2], patches[0], patches[1])


def patch_of_cell(c, psize, inv_psize):
    """``⌊c/P⌋`` of a cell ``c ≥ 0`` by a product with ``inv_psize = 1/P`` and one correction
    (no integer division in the particle loops)."""
    q = int(c * inv_psize)
    if q * psize > c:
        q -= 1
    elif (q + 1) * psize <= c:
        q += 1
    return q


def patch_of_coordinate(u, cells, psize, inv_psize):
    """Patch index along one axis of the cell ``⌊u⌋`` holding grid coordinate ``u`` (position
    minus origin, over the cell size), or -1 outside the grid (NaN too). A point on a patch edge
    belongs to the patch above it; the grid's far face (``u = cells``) is outside."""
    if not (u >= 0.0 and u < cells):
        return -1
    return patch_of_cell(int(u), psize, inv_psize)


def patch_of_point_1d(x0, origin, inv_h, loc, inv_ps):
    """Flat patch id of a 1D position, or -1 outside the grid. ``loc`` rows: the layout's cells,
    patch size and patches per axis (:meth:`PatchLayout.locator`); ``inv_ps``: 1 / patch size."""
    return patch_of_coordinate((x0 - origin[0]) * inv_h[0], loc[0, 0], loc[1, 0], inv_ps[0])


def patch_of_point_2d(x0, x1, origin, inv_h, loc, inv_ps):
    """:func:`patch_of_point_1d` in 2D."""
    q0 = patch_of_coordinate((x0 - origin[0]) * inv_h[0], loc[0, 0], loc[1, 0], inv_ps[0])
    q1 = patch_of_coordinate((x1 - origin[1]) * inv_h[1], loc[0, 1], loc[1, 1], inv_ps[1])
    if q0 < 0 or q1 < 0:
        return -1
    return patch_id(q0, q1, 0, loc[2, 0], loc[2, 1])


def patch_of_point_3d(x0, x1, x2, origin, inv_h, loc, inv_ps):
    """:func:`patch_of_point_1d` in 3D."""
    q0 = patch_of_coordinate((x0 - origin[0]) * inv_h[0], loc[0, 0], loc[1, 0], inv_ps[0])
    q1 = patch_of_coordinate((x1 - origin[1]) * inv_h[1], loc[0, 1], loc[1, 1], inv_ps[1])
    q2 = patch_of_coordinate((x2 - origin[2]) * inv_h[2], loc[0, 2], loc[1, 2], inv_ps[2])
    if q0 < 0 or q1 < 0 or q2 < 0:
        return -1
    return patch_id(q0, q1, q2, loc[2, 0], loc[2, 1])
