"""Linear hat ``S_i(x)`` of a grid node, per axis (standard MPM, and CPDI's corner evaluations).

In grid units (``ξ = (x − origin)/Δx``) the hat of node ``j`` is ``S(ξ − j) = max(0, 1 − |ξ − j|)``;
a point in cell ``⌊ξ⌋`` touches nodes ``⌊ξ⌋`` and ``⌊ξ⌋ + 1`` with weights ``1 − f`` and ``f``,
``f = ξ − ⌊ξ⌋``, and gradients ``∓1/Δx``.

Standard MPM gives a point exactly on node ``j`` (``f = 0``) the fraction ``F_MIN = 2⁻⁶⁰``
instead (:func:`mpm_axis`; :func:`parmpm.transfer.kernels2d.cells.hat_cell_of` in the 2D/3D kernels): node
``j + 1`` then gets a weight far below round-off (``1 − f`` still rounds to 1, so node ``j``'s
weight is unchanged) but not zero, so every node that the particle's gradient ``±1/Δx`` reaches
also holds some of its mass and the grid gives it the particle's velocity, not an empty node's
zero (which put ``−v/Δx`` into a rigidly translating body's velocity gradient). CPDI keeps the
exact hat: its gradient weights vanish with its weights.
"""
import math

from parmpm.core.jit import helper_kernel

SNAP = 1e-9  # grid units: round-off tolerance at the edge of the grid or of a patch's box
F_MIN = 2.0 ** -60  # smallest fraction in a cell: 1 − F_MIN == 1 (see the module doc)


@helper_kernel
def hat_axis(xi, base, nloc, nglob, inv_h, jk, wk, dwk, a):
    """Fill row ``a`` of (jk, wk, dwk) with the two nodes of the point ``xi`` (grid units) along
    one axis: local indices, weights, gradients. Returns 2, or -1 if a node falls outside the
    grid or outside the patch's local (ghost-inclusive) box. A point on (or within round-off of) the
    first/last node uses the cell inside, so a domain that ends on the grid's face stays inside."""
    c = math.floor(xi)
    f = xi - c
    j = int(c)
    if f < SNAP and (j + 1 > nglob - 1 or j + 1 - base > nloc - 1):
        j -= 1  # on (or round-off past) the last node of the box: use the cell below
        f = 1.0
    elif f > 1.0 - SNAP and (j < 0 or j - base < 0):
        j += 1  # round-off before the first node
        f = 0.0
    if j < 0 or j + 1 > nglob - 1 or j - base < 0 or j + 1 - base > nloc - 1:
        return -1
    jk[a, 0] = j - base
    jk[a, 1] = j + 1 - base
    wk[a, 0] = 1.0 - f
    wk[a, 1] = f
    dwk[a, 0] = -inv_h
    dwk[a, 1] = inv_h
    return 2


@helper_kernel
def mpm_axis(xi, base, nloc, nglob, inv_h, jk, wk, dwk, a):
    """:func:`hat_axis` for standard MPM: a point exactly on its cell's first node gives the
    other node the weight ``F_MIN`` (module doc), as the 2D/3D kernels'
    :func:`parmpm.transfer.kernels2d.cells.hat_cell_of` does."""
    n = hat_axis(xi, base, nloc, nglob, inv_h, jk, wk, dwk, a)
    if n > 0 and wk[a, 1] < F_MIN:
        wk[a, 1] = F_MIN
    return n
