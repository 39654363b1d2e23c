"""Locate points in the cells of a patch's node box (the 2D kernels' building block).

Same rule as :func:`parmpm.shapes.hat.hat_axis`, as scalar functions: a point at grid coordinate
``ξ`` lies in cell ``j = ⌊ξ⌋`` at fraction ``f = ξ − j``; round-off on the first or last usable
node moves it into the cell inside. Usable cells are ``jlo ≤ j ≤ jhi`` with ``jlo = max(0, base)``
and ``jhi = min(nglob − 1, base + nloc − 1) − 1``: inside the grid and inside the patch's
ghost-inclusive box. Cells are returned *local to the box* (``j − base``); ``-1`` marks a point
whose nodes leave the box.
"""
import math

import numpy as np

from parmpm.core.jit import helper_kernel
from parmpm.shapes.hat import F_MIN, SNAP
from parmpm.transfer.sided import sided_node


@helper_kernel
def cell_of(xi, base, jlo, jhi):
    """(local cell, fraction) of one point along one axis, or ``(-1, 0)``. For ``ξ ≥ 0``
    truncation is the floor, and a usable floor is already the answer: one truncation and integer
    range test (a third of 2D MPM's P2G time went to ``floor`` and the round-off branches)."""
    tr = np.trunc(xi)  # the fraction from this float, not from j converted back (latency)
    j = int(tr)
    if xi >= 0.0 and j >= jlo and j <= jhi:
        return j - base, xi - tr
    c = math.floor(xi)
    f = xi - c
    j = int(c)
    if j > jhi and f < SNAP:
        j -= 1
        f = 1.0
    elif j < jlo and f > 1.0 - SNAP:
        j += 1
        f = 0.0
    if j < jlo or j > jhi:
        return -1, 0.0
    return j - base, f


@helper_kernel
def hat_cell_of(xi, base, jlo, jhi):
    """:func:`cell_of` for standard MPM, whose fraction is at least ``F_MIN``: a particle exactly on
    a node still gives the cell's other node some mass (:mod:`parmpm.shapes.hat`)."""
    j, f = cell_of(xi, base, jlo, jhi)
    return j, max(f, F_MIN)


@helper_kernel
def cells_of4(c0, c1, c2, c3, base, jlo, jhi):
    """:func:`cell_of` for a CPDI particle's four corners along one axis: the local cells, the
    fractions and whether all four are usable. The common case (every corner at ``ξ ≥ 0`` with a
    usable floor, so :func:`cell_of` would change nothing and truncation is the floor) takes one
    combined sign test of the cells and one of the fractions."""
    t0, t1, t2, t3 = np.trunc(c0), np.trunc(c1), np.trunc(c2), np.trunc(c3)
    j0, j1, j2, j3 = int(t0), int(t1), int(t2), int(t3)
    f0, f1, f2, f3 = c0 - t0, c1 - t1, c2 - t2, c3 - t3
    if ((((j0 - jlo) | (j1 - jlo) | (j2 - jlo) | (j3 - jlo)
            | (jhi - j0) | (jhi - j1) | (jhi - j2) | (jhi - j3)) >= 0)
            and f0 >= 0.0 and f1 >= 0.0 and f2 >= 0.0 and f3 >= 0.0):
        return (j0 - base, j1 - base, j2 - base, j3 - base, f0, f1, f2, f3, True)
    k0, f0 = cell_of(c0, base, jlo, jhi)
    k1, f1 = cell_of(c1, base, jlo, jhi)
    k2, f2 = cell_of(c2, base, jlo, jhi)
    k3, f3 = cell_of(c3, base, jlo, jhi)
    return k0, k1, k2, k3, f0, f1, f2, f3, min(k0, k1, k2, k3) >= 0


def usable_cells(base, nloc, nglob):
    """(jlo, jhi) per slot and axis for :func:`cell_of` from the patch boxes (numpy, at set-up)."""
    base = np.asarray(base, np.int64)
    jlo = np.maximum(0, base)
    jhi = np.minimum(np.asarray(nglob) - 1, base + np.asarray(nloc) - 1) - 1
    return jlo.astype(np.int64), jhi.astype(np.int64)


@helper_kernel
def note_patch(new_patch, i, pid, sp, moved, first_out):
    """Record particle ``i``'s next patch ``pid`` (``-1``: off the grid, it keeps its slot's
    patch ``sp``); returns the updated (moved count, first particle off the grid)."""
    if pid < 0:
        new_patch[i] = sp
        if first_out < 0:
            first_out = np.int64(i)
    else:
        new_patch[i] = pid
        if pid != sp:
            moved += 1
    return moved, first_out


@helper_kernel
def frame_2d(boxes):
    """The grid origin, ``1/Δx`` and the node-box row length of a rank's :class:`Boxes`
    (:mod:`parmpm.core.records`): ``(ox, oy, ihx, ihy, L0)``."""
    origin, inv_h = boxes.origin, boxes.inv_h
    return origin[0], origin[1], inv_h[0], inv_h[1], boxes.nloc[0]


@helper_kernel
def slot_2d(boxes, p):
    """Node-box origin and usable cells of slot ``p``: ``(bx, by, jlx, jly, jhx, jhy)``."""
    base, jlo, jhi = boxes.base, boxes.jlo, boxes.jhi
    return base[p, 0], base[p, 1], jlo[p, 0], jlo[p, 1], jhi[p, 0], jhi[p, 1]


@helper_kernel
def cell_nodes(side, i, L0, jx, jy):
    """Row ``i``'s copies of the four nodes of local cell ``(jx, jy)`` (the nodes themselves
    without crack faces: :func:`parmpm.transfer.sided.sided_node`)."""
    n0 = jx + L0 * jy
    n2 = n0 + L0
    return (sided_node(side, i, n0), sided_node(side, i, n0 + 1), sided_node(side, i, n2),
            sided_node(side, i, n2 + 1))
