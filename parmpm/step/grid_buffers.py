"""The grid fields of a rank's patch slots: two node-interleaved blocks and their node-major views.

Rebuilt whenever the rank's patch set changes. P2G fills ``gsum`` (m, mv, f), the grid update
writes ``gnew`` (v, Δv) from it; the specialised kernels (``transfer/kernels2d``, ``kernels3d``)
take the blocks, everything else the node-major views (:func:`parmpm.grid.update.grid_block`).
"""
from __future__ import annotations

import numpy as np

from parmpm.grid.update import grid_block


class GridBuffers:
    """``gsum_block``/``gsum``: P2G's sums (m, mv, f); ``gnew_block``/``gnew``: the grid update's
    (v, Δv); ``gm, gmv, gf, gvel, gdv``: views of single fields; ``inside``: each slot's patch
    cells in grid coordinates (G2P's stay-in-patch test)."""

    def __init__(self, disc, local_ids: np.ndarray):
        n, nn, d = local_ids.size, disc.layout.n_local_nodes, disc.dim
        # views of two slots at least (spares never visited): numba types an array of 0 or 1 slot
        # as contiguous, and a rank with no or one patch compiled kernels of its own mid-run
        self.gsum_block, self.gsum = grid_block(max(n, 2), 1 + 2 * d, nn)
        self.gnew_block, self.gnew = grid_block(max(n, 2), 2 * d, nn)
        self.gsum_block, self.gnew_block = self.gsum_block[:n], self.gnew_block[:n]
        self.gm, self.gmv, self.gf = (self.gsum[:, :, :1], self.gsum[:, :, 1:1 + d],
                                      self.gsum[:, :, 1 + d:])
        self.gvel, self.gdv = self.gnew[:, :, :d], self.gnew[:, :, d:]
        lo, hi = disc.layout.patch_cells(disc.layout.patch_coords()[local_ids])
        self.inside = np.stack([lo, hi], axis=1).astype(np.float64)
