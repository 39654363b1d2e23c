"""Ghost-layer exchange between patches: ``accumulate`` (ghost → owner sum) and ``fill``
(owner → ghost copy).

A :class:`HaloPlan` lists, for every owner patch ``p`` and every other patch ``q`` in the fixed
neighbour-offset order, the box of nodes that ``p`` owns and ``q`` holds as ghosts. Accumulate adds
``q``'s partial sums into ``p`` in that order, so each node's total is
``own + Σ_{offsets in fixed order} neighbour`` — the same floating-point sum whichever process
hosts which patch (the key to rank-count-independent results). Fill copies the other way.
Here every patch is local; the MPI layer (later) replaces the reads of remote patches with
receive buffers in the same order.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from decomposition.layout import PatchLayout


class HaloPlan:
    """Copy boxes between patches of one layout.

    ``boxes`` is an int64 array (n_pairs, 11): owner p, other q, p-local offset (3),
    q-local offset (3), size (3); rows grouped by owner in patch order, then by neighbour offset.
    """

    def __init__(self, layout: PatchLayout, patch_ids=None):
        self.layout = layout
        coords = layout.patch_coords()
        ids = np.arange(layout.n_patches) if patch_ids is None else np.asarray(patch_ids)
        slot = {int(pid): s for s, pid in enumerate(ids)}
        nppa = layout.patches_per_axis
        rows = []
        for s, pid in enumerate(ids):
            c = coords[pid]
            own_lo, own_hi = layout.owned_box(c)
            p_base = layout.local_box(c)[0]
            for off in layout.neighbour_offsets():
                qc = c + np.array(off, dtype=np.int64)
                if np.any(qc < 0) or np.any(qc >= nppa):
                    continue
                q = slot.get(layout.patch_id(qc))
                if q is None:
                    continue
                q_lo, q_hi = layout.local_box(qc)
                lo, hi = np.maximum(own_lo, q_lo), np.minimum(own_hi, q_hi)
                if np.any(hi <= lo):
                    continue
                rows.append([s, q, *(lo - p_base), *(lo - q_lo), *(hi - lo)])
        self.boxes = np.array(rows, dtype=np.int64).reshape(-1, 11)
        self.local_nodes3 = layout.local_nodes3

    @property
    def ghost_nodes_per_exchange(self) -> int:
        """Nodes copied by one accumulate (or fill) of a one-component field."""
        return int(np.prod(self.boxes[:, 8:11], axis=1).sum()) if len(self.boxes) else 0


@njit(cache=True)
def _accumulate(field, boxes, L):
    for r in range(boxes.shape[0]):
        p, q = boxes[r, 0], boxes[r, 1]
        for k2 in range(boxes[r, 10]):
            for k1 in range(boxes[r, 9]):
                np0 = boxes[r, 2] + L[0] * (boxes[r, 3] + k1 + L[1] * (boxes[r, 4] + k2))
                nq0 = boxes[r, 5] + L[0] * (boxes[r, 6] + k1 + L[1] * (boxes[r, 7] + k2))
                for k0 in range(boxes[r, 8]):
                    for c in range(field.shape[2]):
                        field[p, np0 + k0, c] += field[q, nq0 + k0, c]


@njit(cache=True)
def _fill(field, boxes, L):
    for r in range(boxes.shape[0]):
        p, q = boxes[r, 0], boxes[r, 1]
        for k2 in range(boxes[r, 10]):
            for k1 in range(boxes[r, 9]):
                np0 = boxes[r, 2] + L[0] * (boxes[r, 3] + k1 + L[1] * (boxes[r, 4] + k2))
                nq0 = boxes[r, 5] + L[0] * (boxes[r, 6] + k1 + L[1] * (boxes[r, 7] + k2))
                for k0 in range(boxes[r, 8]):
                    for c in range(field.shape[2]):
                        field[q, nq0 + k0, c] = field[p, np0 + k0, c]


def accumulate(plan: HaloPlan, *fields: np.ndarray) -> None:
    """Add every ghost copy's partial sum into the owning node; fields are (patches, nodes, k)."""
    for f in fields:
        _accumulate(f, plan.boxes, plan.local_nodes3)


def fill(plan: HaloPlan, *fields: np.ndarray) -> None:
    """Copy every owned node's value into all of its ghost copies."""
    for f in fields:
        _fill(f, plan.boxes, plan.local_nodes3)
