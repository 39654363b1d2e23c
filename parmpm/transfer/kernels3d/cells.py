"""Locate a 3D CPDI particle's eight corners along one axis (the 3D kernels' building block).

The rule is :func:`parmpm.transfer.kernels2d.cells.cell_of` (that of :func:`parmpm.shapes.hat.hat_axis`):
a corner at grid coordinate ``ξ`` lies in cell ``j = ⌊ξ⌋`` at fraction ``f = ξ − j``, snapped into
the usable cells ``jlo ≤ j ≤ jhi`` within round-off; cells are local to the patch's box (``j −
base``), ``-1`` marks a corner whose nodes leave it. The common case, every floor already usable,
takes one combined sign test inline; the rest goes through one compiled call (not inlined: it is
rare, and inlining :func:`cell_of` 24 times per kernel multiplies numba's compile time).
"""
import numpy as np

from parmpm.core.jit import helper_kernel, kernel
from parmpm.transfer.kernels2d.cells import cell_of


@kernel
def cells_of8_slow(c0, c1, c2, c3, c4, c5, c6, c7, base, jlo, jhi):
    """:func:`cell_of` of each of eight points: ``(j0..7, f0..7, all usable)``."""
    k0, f0 = cell_of(c0, base, jlo, jhi)
    k1, f1 = cell_of(c1, base, jlo, jhi)
    k2, f2 = cell_of(c2, base, jlo, jhi)
    k3, f3 = cell_of(c3, base, jlo, jhi)
    k4, f4 = cell_of(c4, base, jlo, jhi)
    k5, f5 = cell_of(c5, base, jlo, jhi)
    k6, f6 = cell_of(c6, base, jlo, jhi)
    k7, f7 = cell_of(c7, base, jlo, jhi)
    return (k0, k1, k2, k3, k4, k5, k6, k7, f0, f1, f2, f3, f4, f5, f6, f7,
            min(k0, k1, k2, k3, k4, k5, k6, k7) >= 0)


@helper_kernel
def cells_of8(c0, c1, c2, c3, c4, c5, c6, c7, base, jlo, jhi):
    """:func:`cells_of8_slow`, with the common case (every floor usable) inline."""
    # floors as floats: the fractions from them, not from the cells converted back (latency)
    l0, l1, l2, l3 = np.floor(c0), np.floor(c1), np.floor(c2), np.floor(c3)
    l4, l5, l6, l7 = np.floor(c4), np.floor(c5), np.floor(c6), np.floor(c7)
    j0, j1, j2, j3 = int(l0), int(l1), int(l2), int(l3)
    j4, j5, j6, j7 = int(l4), int(l5), int(l6), int(l7)
    if ((j0 - jlo) | (j1 - jlo) | (j2 - jlo) | (j3 - jlo) | (j4 - jlo) | (j5 - jlo) | (j6 - jlo)
            | (j7 - jlo) | (jhi - j0) | (jhi - j1) | (jhi - j2) | (jhi - j3) | (jhi - j4)
            | (jhi - j5) | (jhi - j6) | (jhi - j7)) >= 0:
        return (j0 - base, j1 - base, j2 - base, j3 - base, j4 - base, j5 - base, j6 - base,
                j7 - base, c0 - l0, c1 - l1, c2 - l2, c3 - l3, c4 - l4, c5 - l5, c6 - l6, c7 - l7,
                True)
    return cells_of8_slow(c0, c1, c2, c3, c4, c5, c6, c7, base, jlo, jhi)


@helper_kernel
def frame_3d(boxes):
    """The grid origin, ``1/Δx`` and the node-box strides of a rank's :class:`Boxes`
    (:mod:`parmpm.core.records`): ``(ox, oy, oz, ihx, ihy, ihz, L0, L0·L1)``."""
    origin, inv_h, nloc = boxes.origin, boxes.inv_h, boxes.nloc
    return (origin[0], origin[1], origin[2], inv_h[0], inv_h[1], inv_h[2], nloc[0],
            nloc[0] * nloc[1])


@helper_kernel
def slot_3d(boxes, p):
    """Node-box origin and usable cells of slot ``p``: ``(bx, by, bz, jlx, …, jhz)``."""
    base, jlo, jhi = boxes.base, boxes.jlo, boxes.jhi
    return (base[p, 0], base[p, 1], base[p, 2], jlo[p, 0], jlo[p, 1], jlo[p, 2],
            jhi[p, 0], jhi[p, 1], jhi[p, 2])
