"""Quadratic B-spline weights per axis (Steffen, Kirby & Berzins 2008).

In grid units (``ξ = (x − origin)/Δx``, ``s = ξ − j`` from node ``j``) the weight of node ``j`` is

    N(s) = 3/4 − s²            for |s| ≤ 1/2,
    N(s) = ½ (3/2 − |s|)²      for 1/2 ≤ |s| ≤ 3/2,
    N(s) = 0                   beyond,

C¹ across ``|s| = 1/2`` and ``3/2``, so a particle crossing a cell face sees no jump in its
gradient weights (the cell-crossing error of linear MPM). A point touches the three nodes
around its nearest node ``c``: with ``t = ξ − c ∈ [−1/2, 1/2)``,

    N_{c−1} = ½ (1/2 − t)²,   N_c = 3/4 − t²,   N_{c+1} = ½ (1/2 + t)²,
    N'_{c−1} = t − 1/2,       N'_c = −2t,       N'_{c+1} = t + 1/2   (per grid unit),

which sum to 1 and 0 and reproduce linear fields: ``Σ N_j j = c + t = ξ``.

Round-off: ``t`` comes from the exact fraction ``f = ξ − ⌊ξ⌋`` (``t = f`` or ``t = f − 1``, both
exact), and the two outer weights are the same expression in ``±t``. A point exactly at a half
cell (``t = −1/2``) gives its nodes ``c−1, c`` the weights ``1/2, 1/2`` exactly and ``c+1`` the
weight 0 and gradient 0, bit for bit what the other rounding (``c − 1``, ``t = +1/2``) would give
the same nodes, so its contribution does not depend on which way ``ξ`` rounded. (No ``F_MIN``
fix as in :mod:`parmpm.shapes.hat`: every node the gradient reaches with a nonzero weight also
has a nonzero weight; only the zero-gradient node at ``|s| = 3/2`` is empty.)

Ghost width: a particle owned by a patch has its centre in a patch cell ``[a, a+1]``; its
nearest node is ``a`` or ``a + 1``, so its nodes ``c ± 1`` lie at most one cell outside the patch's
nodes (support half-width 3/2 cells → 1 ghost cell). The nodes must lie on the grid: a particle
within half a cell of the grid's face has a node outside it and the run stops with the reach
message (pad the grid, as for uGIMP domains).
"""

import numpy as np

from parmpm.core.jit import helper_kernel


@helper_kernel
def nearest_node(xi):
    """``(c, t)``: the nearest node ``c`` of the point ``xi`` (grid units) and ``t = xi − c`` in
    ``[−1/2, 1/2)``, from the exact fraction (module doc: the same bits either way at a half
    cell)."""
    fl = np.floor(xi)  # a float: math.floor's integer would be converted back for f (latency)
    f = xi - fl
    c = int(fl)
    t = f
    if f >= 0.5:
        c += 1
        t = f - 1.0  # exact (Sterbenz)
    return c, t


@helper_kernel
def spline_weights(t, inv_h):
    """The weights of nodes ``c − 1, c, c + 1`` and their gradients (physical units) at offset
    ``t`` from the nearest node: ``(N0, N1, N2, N0', N1', N2')``."""
    m = 0.5 - t
    p = 0.5 + t
    return 0.5 * (m * m), 0.75 - t * t, 0.5 * (p * p), -m * inv_h, -2.0 * t * inv_h, p * inv_h


@helper_kernel
def bspline_axis(xi, base, nloc, nglob, inv_h, jk, wk, dwk, a):
    """Fill row ``a`` of (jk, wk, dwk) with the three nodes ``c − 1, c, c + 1`` of the point
    ``xi`` (grid units) along one axis: local indices, weights, gradients (physical units).
    Returns 3, or -1 if a node falls outside the grid or the patch's local (ghost-inclusive) box."""
    c, t = nearest_node(xi)
    lo = c - 1
    if lo < 0 or c + 1 > nglob - 1 or lo - base < 0 or c + 1 - base > nloc - 1:
        return -1
    for k in range(3):
        jk[a, k] = lo + k - base
    wk[a, 0], wk[a, 1], wk[a, 2], dwk[a, 0], dwk[a, 1], dwk[a, 2] = spline_weights(t, inv_h)
    return 3
