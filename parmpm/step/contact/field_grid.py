"""A contact scene's per-field grids (:class:`FieldGrid`) and the two helpers every contact pass
uses: :func:`within` (the owned nodes of some slots only) and :func:`node_major` (a block's
node-major view). The passes call them through this module (``field_grid.within``), so a test can
swap :func:`within` for the whole node set in one place."""
from __future__ import annotations

import numpy as np


def within(nodes, slots: np.ndarray):
    """``nodes`` (:class:`parmpm.core.records.OwnedNodes`) with the boxes of the slots
    ``slots`` does not mark emptied: a pass over the nodes where fields meet visits those
    slots' only."""
    return nodes._replace(own_hi=np.where(slots[:, None], nodes.own_hi, nodes.own_lo))


def node_major(block: np.ndarray, nodes: int) -> np.ndarray:
    """The node-major view ``(slots, nodes, rows)`` of a ``(slots, rows, stride)`` block."""
    return block[:, :, :nodes].transpose(0, 2, 1)


class FieldGrid:
    """One field's grid fields, as :class:`~parmpm.step.grid_buffers.GridBuffers` names them."""

    def __init__(self, gsum_block, gnew_block, nodes: int, d: int, inside: np.ndarray):
        self.gsum_block, self.gnew_block = gsum_block, gnew_block
        self.gsum, self.gnew = node_major(gsum_block, nodes), node_major(gnew_block, nodes)
        self.gm, self.gmv, self.gf = (self.gsum[:, :, :1], self.gsum[:, :, 1:1 + d],
                                      self.gsum[:, :, 1 + d:])
        self.gvel, self.gdv = self.gnew[:, :, :d], self.gnew[:, :, d:]
        self.inside = inside
